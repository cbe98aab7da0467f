"""The elastic indentation law of an AFM probe, `F = C G d^m`: what the closed-form
parts of the AFM fitting chain (contact point, Lee & Radok fit and start, apparent
modulus, contact radius) need to know of the tip.

Sneddon (1965), in the library's shear-modulus convention `E* = 2 G / (1 - nu)`:

- sphere of radius `R` (Hertz, the paraboloid of `jc.Sphere`):
  `F = (4/3) sqrt(R) E* d^(3/2) = (8 sqrt(R) / (3 (1 - nu))) G d^(3/2)`, contact
  radius `a = sqrt(R d)`;
- cone of half-angle `alpha` (`jc.Cone`, the angle between the axis and the flank):
  `F = (2 / pi) tan(alpha) E* d^2 = (4 tan(alpha) / (pi (1 - nu))) G d^2`, contact
  radius `a = 2 d tan(alpha) / pi`.

Both are `F = k E* d^m` (`factor` `k`, `exponent` `m`), so their Lee & Radok
hereditary forms are one (`jaxcontact._lee_radok`, `u = d^m`) while the contact
radius does not shrink. Plain floats: a `Probe` pickles (a Dask task) and goes into
JSON.

??? cite "References"

    Sneddon, I. N. (1965). The relation between load and penetration in the
    axisymmetric Boussinesq problem for a punch of arbitrary profile. Int. J. Eng.
    Sci. 3(1), 47-57.
"""

import dataclasses
import math

import numpy as np


TIPS = ("sphere", "cone")


@dataclasses.dataclass(frozen=True)
class Probe:
    """A spherical or conical probe of the closed-form indentation law (module notes).

    - `tip`: `"sphere"` or `"cone"`.
    - `size`: the sphere's radius `R` [m] (> 0), or the cone's half-angle `alpha`
      [rad] (in `(0, pi/2)`: the angle between the axis and the flank).

    Made by `Probe.sphere(radius)`, `Probe.cone(half_angle)` or `Probe.of(x)` (a
    radius, a `jc.Sphere`, a `jc.Cone` or a `Probe`).
    """

    tip: str
    size: float

    def __post_init__(self):
        if self.tip not in TIPS:
            raise ValueError(f"tip must be 'sphere' or 'cone', got {self.tip!r}")
        s = self.size
        ok = (not isinstance(s, bool) and isinstance(s, (int, float, np.floating))
              and math.isfinite(s))
        if self.tip == "sphere" and not (ok and s > 0):
            raise ValueError(f"radius must be a finite number > 0 [m], got {s!r}")
        if self.tip == "cone" and not (ok and 0 < s < math.pi / 2):
            raise ValueError(
                f"half_angle must be in (0, pi/2) radians (the angle between the "
                f"axis and the flank), got {s!r}"
                + (f" (degrees? {s!r} deg = {math.radians(s):.6g} rad)"
                   if ok and math.pi / 2 <= s < 90 else ""))
        object.__setattr__(self, "size", float(s))

    @classmethod
    def sphere(cls, radius) -> "Probe":
        """A sphere of `radius` [m]."""
        return cls("sphere", radius)

    @classmethod
    def cone(cls, half_angle) -> "Probe":
        """A cone of half-angle `half_angle` [rad]."""
        return cls("cone", half_angle)

    @classmethod
    def of(cls, probe) -> "Probe":
        """`probe` as a `Probe`: a number is a sphere's radius [m] (the AFM chain's
        historical argument); a `jc.Sphere` or a `jc.Cone` gives its own (concrete)
        radius or half-angle. **Raises:** `ValueError` for any other indenter (a
        `jc.BluntedCone`, a pyramid, a surface: no closed-form law here)."""
        from ._indenter import AbstractIndenter, Cone, Sphere

        if isinstance(probe, Probe):
            return probe
        if isinstance(probe, Sphere):
            return cls.sphere(float(probe.radius))
        if isinstance(probe, Cone):
            return cls.cone(float(probe.half_angle))
        if isinstance(probe, AbstractIndenter):
            raise ValueError(
                f"the closed-form indentation law (contact point, Lee & Radok, "
                f"apparent modulus) is known for a jc.Sphere or a jc.Cone, not a "
                f"{type(probe).__name__}")
        return cls.sphere(probe)

    @property
    def exponent(self) -> float:
        """`m` of `F ~ d^m`: 3/2 (sphere), 2 (cone)."""
        return 1.5 if self.tip == "sphere" else 2.0

    @property
    def factor(self) -> float:
        """`k` of `F = k E* d^m` [m^(2 - m)]: `4 sqrt(R) / 3` (sphere),
        `2 tan(alpha) / pi` (cone)."""
        if self.tip == "sphere":
            return 4 * math.sqrt(self.size) / 3
        return 2 * math.tan(self.size) / math.pi

    def prefactor(self, poisson) -> float:
        """`C` of `F = C G d^m` at Poisson's ratio `poisson`: `2 k / (1 - nu)`
        (`8 sqrt(R) / (3 (1 - nu))`, `4 tan(alpha) / (pi (1 - nu))`)."""
        return 2 * self.factor / (1 - poisson)

    def contact_radius(self, depth):
        """Elastic contact radius [m] at the depth `depth` [m] (>= 0; array or
        number): `sqrt(R d)` (sphere), `2 d tan(alpha) / pi` (cone)."""
        if self.tip == "sphere":
            return np.sqrt(self.size * depth)
        return 2 * depth * math.tan(self.size) / math.pi

    def indenter(self):
        """The `jc.Sphere(R)` or `jc.Cone(alpha)` of the contact model."""
        from ._indenter import Cone, Sphere

        return Sphere(self.size) if self.tip == "sphere" else Cone(self.size)

    @property
    def law(self) -> str:
        """The elastic law's name: `"Hertz"` (sphere), `"Sneddon"` (cone)."""
        return "Hertz" if self.tip == "sphere" else "Sneddon"

    def parameters(self) -> dict:
        """JSON-ready: `{"shape": "sphere", "radius_m": R}` or `{"shape": "cone",
        "half_angle_rad": alpha, "half_angle_deg": alpha in degrees}`."""
        if self.tip == "sphere":
            return {"shape": "sphere", "radius_m": self.size}
        return {"shape": "cone", "half_angle_rad": self.size,
                "half_angle_deg": math.degrees(self.size)}

    def text(self) -> str:
        """One line: `sphere R = 5e-06 m` or `cone, half-angle 20 deg (0.349 rad)`."""
        if self.tip == "sphere":
            return f"sphere R = {self.size:g} m"
        return (f"cone, half-angle {math.degrees(self.size):.4g} deg "
                f"({self.size:.4g} rad)")

    def scaling_note(self) -> str:
        """How the absolute moduli depend on the tip's parameter (an input):
        `SPHERE_NOTE` or `CONE_NOTE`."""
        return SPHERE_NOTE if self.tip == "sphere" else CONE_NOTE


SPHERE_NOTE = ("the probe radius is an input (not in the file): absolute moduli scale "
               "as radius^(-1/2); relaxation times and modulus ratios do not depend "
               "on it")
CONE_NOTE = ("the cone's half-angle is an input (not in the file): absolute moduli "
             "scale as 1 / tan(half-angle); relaxation times and modulus ratios do "
             "not depend on it. The cone is Sneddon's sharp cone on a linear "
             "half-space: a real tip's rounded apex is not modelled")
