"""Analytic reference solutions (library objects, used by tests, benchmarks and
examples)."""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from . import _validate


class Hertz(eqx.Module):
    """Hertz contact of a rigid sphere (paraboloid) on an elastic half-space.

    **Arguments:** `radius` R [length], `force` W [force], `shear_modulus` G [stress],
    `poisson` nu. The plane-strain modulus is `E* = 2 G / (1 - nu)`.

    Contact radius `a = (3 W R / (4 E*))^(1/3)`, peak pressure
    `p0 = 3 W / (2 pi a^2)`, approach `delta = a^2 / R`,
    pressure `p(r) = p0 sqrt(1 - r^2 / a^2)` (Johnson 1985, section 4.2).
    """

    radius: Float[Array, ""]
    force: Float[Array, ""]
    shear_modulus: Float[Array, ""]
    poisson: Float[Array, ""]

    def __init__(self, radius, force, shear_modulus, poisson):
        # Arrays broadcast (e.g. a Hertz solution per load); bad values raise here.
        self.radius = _validate.positive("radius", radius)
        self.force = _validate.non_negative("force", force)
        self.shear_modulus = _validate.positive("shear_modulus", shear_modulus)
        self.poisson = _validate.poisson_ratio("poisson", poisson)

    @property
    def effective_modulus(self):
        return 2 * self.shear_modulus / (1 - self.poisson)

    @property
    def contact_radius(self):
        return (3 * self.force * self.radius / (4 * self.effective_modulus)) ** (1 / 3)

    @property
    def peak_pressure(self):
        a = self.contact_radius
        return 3 * self.force / (2 * jnp.pi * a * a)

    @property
    def approach(self):
        return self.contact_radius**2 / self.radius

    def pressure(self, r):
        a = self.contact_radius
        return self.peak_pressure * jnp.sqrt(jnp.maximum(1 - (r / a) ** 2, 0.0))


class LeeRadok:
    """Lee & Radok (1960): a rigid paraboloid on a viscoelastic half-space, contact
    radius non-decreasing (loading).

    **Arguments:**

    - `radius`: sphere radius `R` [length]; `poisson`: `nu` (constant).
    - `material`: a jaxcontact material (its `creep(t)` and `relaxation(t)` are used).
    - `load`: callable `W(t)` [force], non-decreasing, `W(t < 0) = 0`; a jump at
      `t = 0` is allowed.
    - `samples`: number of sub-intervals of the Stieltjes sums (accuracy ~ 1/samples).

    Formulas (true shear moduli; `E* = 2 G / (1 - nu)` in the elastic limit):

    - `a(t)^3 = 3 R (1 - nu) / 8 * int_0^t J(t - s) dW(s)`;
    - `p(r, t) = 4 / (pi R (1 - nu)) * int_0^t G(t - s) d/ds sqrt(a(s)^2 - r^2)_+ ds`
      (paper Eq. 24 with its modulus `2 G`);
    - approach `delta(t) = a(t)^2 / R`.

    Computed with NumPy in float64 (a reference, not a differentiable function).
    """

    def __init__(self, radius, poisson, material, load, samples: int = 4000):
        import numpy as np

        self._np = np
        self.radius = float(radius)
        self.poisson = float(poisson)
        self.creep = lambda t: np.asarray(material.creep(jnp.asarray(t)), dtype=float)
        self.relaxation = lambda t: np.asarray(material.relaxation(jnp.asarray(t)),
                                               dtype=float)
        self.load = load
        self.samples = samples

    def _radius_history(self, t):
        """`(s, a(s))` on `samples + 1` points of `[0, t]` (one O(samples^2) sum)."""
        np = self._np
        n = self.samples
        s = np.linspace(0.0, float(t), n + 1)
        w = self._loads(s)
        dw = np.diff(w)
        # On the uniform points the lag s_i - mid_j = (i - j - 1/2) ds depends on i - j
        # only: the sum over j < i is a convolution with J at (k - 1/2) ds, k = 1..n
        # (n creep values instead of an (n+1, n) matrix of them).
        ds = float(t) / n
        kernel = self.creep((np.arange(1, n + 1) - 0.5) * ds)
        integral = self.creep(s) * w[0] + np.r_[0.0, np.convolve(kernel, dw)[:n]]
        a = (3 * self.radius * (1 - self.poisson) / 8
             * np.clip(integral, 0.0, None)) ** (1 / 3)
        return s, a

    def _loads(self, s):
        """`W(s)` [force] at the points `s`: one call on the whole array where `load`
        takes one (same shape back), else a call per point."""
        np = self._np
        try:
            w = np.asarray(self.load(s), dtype=float)
        except Exception:  # a load written for one time at a time
            w = None
        if w is None or w.shape != s.shape:
            w = np.asarray([float(self.load(x)) for x in s])
        return w

    def contact_radius(self, t):
        return float(self._radius_history(t)[1][-1])

    def approach(self, t):
        return self.contact_radius(t) ** 2 / self.radius

    def pressure(self, r, t):
        """Pressure at radii `r` (array) and time `t`."""
        np = self._np
        s, a = self._radius_history(t)
        r = np.atleast_1d(np.asarray(r, dtype=float))
        f = np.sqrt(np.clip(a[None, :] ** 2 - r[:, None] ** 2, 0.0, None))  # (nr, ns)
        mid = 0.5 * (s[1:] + s[:-1])
        g_mid = self.relaxation(float(t) - mid)
        total = self.relaxation(np.asarray(float(t))) * f[:, 0] + np.sum(
            g_mid[None] * np.diff(f, axis=1), axis=1)
        return 4 / (np.pi * self.radius * (1 - self.poisson)) * total
