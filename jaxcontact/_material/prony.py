"""Generalized Wiechert (Prony series) half-space, and the conversions between a
relaxation series and a creep series.

Laplace transforms (`^`, variable `s`) of a relaxation series
`G(t) = g_inf + sum_i g_i exp(-t / tau_i)` and a creep series
`J(t) = J(0) + sum_j c_j (1 - exp(-t / lambda_j)) + phi t` obey `s^2 G^(s) J^(s) = 1`:

    s G^(s) = g_inf + sum_i g_i s tau_i / (1 + s tau_i)            (= Q(s))
    s J^(s) = J(0) + sum_j c_j / (1 + s lambda_j) + phi / s         (= 1 / Q(s))

so the retardation rates `1 / lambda_j` are the roots `u = -s > 0` of `Q(-u) = 0`, and
the strengths the residues of `1 / Q` there. With the rates `r_i = 1 / tau_i`,

    h(u) = Q(-u) = g_inf + sum_i g_i u / (u - r_i)

decreases strictly between consecutive poles `r_i` (from +inf to -inf), so exactly one
root lies between each pair of consecutive poles, and one in `[0, r_min)` (at `u = 0`
exactly when `g_inf = 0`: a fluid, `phi = 1 / sum_i g_i tau_i`). The strengths are
`c_j = 1 / (u_j S(u_j))` with `S(u) = -h'(u) = sum_i g_i r_i / (u - r_i)^2 > 0`.

The creep -> relaxation direction is the same problem with the roles exchanged:
`h(u) = J(0) - sum_i w_i / (u - r_i)` with poles at the retardation rates (weights
`w_i = j_i r_i`, plus a pole at `u = 0` of weight `phi` for a fluid) increases between
its poles; one relaxation rate lies above each pole, and the relaxation strengths are
again `1 / (u S(u))` with `S = h'`.

The roots are found to machine precision by a bracketed (safeguarded) Newton iteration
with a fixed number of steps on gradient-stopped inputs; the derivatives then come from
the implicit function theorem (`du/dp = -h_p / h_u`), so first derivatives (`jax.grad`,
`jax.jvp`) are exact and cheap. Second derivatives of the roots are not (they would need
the implicit formula differentiated once more).
A pole of zero weight (`g_i = 0`) carries no root: its mode has strength zero, with the
first-order dependence on its weight (`g_i / h(r_i)^2`) kept so that gradients at
`g_i = 0` are right as well (see `_amplitudes`, which also handles a root closer to its
pole than rounding resolves).
"""

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax
from jaxtyping import Array, ArrayLike, Float

from .. import _validate
from .base import AbstractMaterial, CreepSeries
from .checks import check_arg, check_scalar, promote, require


_ITERATIONS = 100


def _series_arrays(names, values, checks):
    """Validate a scalar and two matching 1-D arrays; promote to one float dtype."""
    n0, n1, n2 = names
    v0, v1, v2 = (check_arg(check, name, v)
                  for check, name, v in zip(checks, names, values))
    check_scalar(n0, v0)
    if v1.ndim != 1 or v2.ndim != 1 or v1.shape != v2.shape:
        raise ValueError(
            f"{n1} and {n2} must be 1-D arrays of the same length, got {n1}.shape="
            f"{v1.shape} and {n2}.shape={v2.shape}"
        )
    return promote(v0, v1, v2)


# Two times closer than this many units of rounding (relative) are the same time.
_DISTINCT_ULPS = 16


def _distinct(name: str, tau: jax.Array) -> jax.Array:
    """Pairwise distinct times [time], beyond rounding: `tau = [1.0, 1.000000000000001]`
    (4.5 units of float64 rounding apart) is one time repeated, not two arms; such a
    pair must differ by more than `_DISTINCT_ULPS` units of rounding of the dtype
    (relative: 3.6e-15 in float64, 1.9e-6 in float32). Merge repeated arms into one."""
    if tau.shape[0] < 2:
        return tau
    rel = _DISTINCT_ULPS * float(jnp.finfo(tau.dtype).eps)

    def ok(tau):
        srt = jnp.sort(tau)
        return srt[1:] - srt[:-1] > rel * srt[1:]

    return require(
        name,
        tau,
        (tau,),
        ok,
        f"pairwise distinct beyond rounding (relative separation > {rel:.2g} in "
        f"{tau.dtype.name}; merge repeated arms into one)",
        lambda: np.array2string(np.asarray(tau), precision=17),
    )


# --------------------------------------------------------------------------------------
# The secular equation.


def _inverse_distances(u, r):
    """`1 / (u_k - r_i)`, shape (m, n); 0 where `u_k == r_i` (a pole of zero weight
    evaluated at its own rate: the term is left out)."""
    d = u[:, None] - r[None, :]
    nonzero = d != 0
    return jnp.where(nonzero, 1 / jnp.where(nonzero, d, 1), 0)


def _secular(u, c, alpha, beta, kappa, r):
    """`h(u) = c + sum_i (alpha_i u + beta_i) / (u - r_i)` and `S(u) = |h'(u)|`
    `= sum_i kappa_i / (u - r_i)^2`. Poles of zero weight contribute zero (but their
    weights still carry derivatives)."""
    inv = _inverse_distances(u, r)
    h = c + jnp.sum((alpha[None, :] * u[:, None] + beta[None, :]) * inv, axis=1)
    s = jnp.sum(kappa[None, :] * inv**2, axis=1)
    return h, s


def _roots(params, r, lo, hi, increasing: bool):
    """One root of the secular function in each bracket `(lo_k, hi_k)`.

    `params = (c, alpha, beta, kappa)`. The iteration runs on gradient-stopped values;
    the returned roots carry the implicit derivative `-h_p / h_u`.
    """
    sign = 1.0 if increasing else -1.0
    stopped = [lax.stop_gradient(p) for p in params]
    r_s = lax.stop_gradient(r)
    lo, hi = lax.stop_gradient(lo), lax.stop_gradient(hi)

    def body(_, state):
        lo, hi, x, dx, dx_old = state
        h, s = _secular(x, *stopped, r_s)
        dh = sign * s
        zero = h == 0
        up = sign * h < 0  # the root lies above x
        lo = jnp.where(up | zero, x, lo)
        hi = jnp.where(up & ~zero, hi, x)
        dh_safe = jnp.where(dh == 0, 1, dh)
        step = jnp.where(dh == 0, jnp.inf, h / dh_safe)
        xn = x - step
        mid = lo + 0.5 * (hi - lo)
        newton = (xn > lo) & (xn < hi) & (2 * jnp.abs(step) <= jnp.abs(dx_old))
        mid_ok = (mid > lo) & (mid < hi)
        x_new = jnp.where(newton, xn, jnp.where(mid_ok, mid, x))
        return lo, hi, x_new, x_new - x, dx

    x0 = lo + 0.5 * (hi - lo)
    width = hi - lo
    state = (lo, hi, x0, width, width)
    _, _, x, _, _ = lax.fori_loop(0, _ITERATIONS, body, state)
    x = lax.stop_gradient(x)
    # Implicit function theorem: the value stays x, the derivative is -h_p / h_u.
    h_live, _ = _secular(x, *params, r)
    _, s = _secular(x, *stopped, r_s)
    dh = sign * jnp.where(s == 0, 1, s)
    return x - (h_live - lax.stop_gradient(h_live)) / dh


def _safe_reciprocal(x, ok):
    return jnp.where(ok, 1 / jnp.where(ok, x, 1), 0)


def _amplitudes(u, params, r, dummy):
    """Mode strengths at the roots `u`: the residue `1 / (u S(u))`, evaluated stably.

    With `k` the pole nearest to `u` (among the active ones, or the pole `u` sits on),
    write `h(u) = H_k(u) + omega_k / (u - r_k)`; at a root `omega_k / (u - r_k) = -H_k`,
    so `S = S_rest + H_k^2 / w_k` and the strength is
    `w_k / (u (w_k S_rest + H_k^2))`. This stays accurate when the root lies closer to
    its pole than rounding resolves, and at an inert pole (`w_k = 0`, `u = r_k`) gives
    strength 0 with the right first derivative `1 / (r_k H_k^2)` per unit `w_k`.
    `dummy` modes get 0.
    """
    c, alpha, beta, kappa = params
    n = r.shape[0]
    inv = _inverse_distances(u, r)
    dist = jnp.abs(u[:, None] - r[None, :])
    candidate = (kappa[None, :] > 0) | (dist == 0)
    k = jnp.argmin(jnp.where(candidate, dist, jnp.inf), axis=1)
    near = jnp.arange(n)[None, :] == k[:, None]
    terms = (alpha[None, :] * u[:, None] + beta[None, :]) * inv
    h_rest = c + jnp.sum(jnp.where(near, alpha[None, :], 0), axis=1)
    h_rest = h_rest + jnp.sum(jnp.where(near, 0, terms), axis=1)
    s_rest = jnp.sum(jnp.where(near, 0, kappa[None, :] * inv**2), axis=1)
    w_k = jnp.sum(jnp.where(near, kappa[None, :], 0), axis=1)
    denom = u * (w_k * s_rest + h_rest**2)
    ok = ~dummy & (denom > 0)
    return jnp.where(ok, w_k / jnp.where(ok, denom, 1), 0)


@jax.jit
def retardation_series(g_inf, g, tau) -> CreepSeries:
    """The creep series of `G(t) = g_inf + sum_i g_i exp(-t / tau_i)`.

    Requires `g_inf >= 0`, `g >= 0`, `g_inf + sum(g) > 0`, `tau > 0` pairwise distinct.
    Returns `m = len(g)` modes; a pole with `g_i = 0`, and for a fluid (`g_inf = 0`) the
    slowest mode, have strength 0.
    """
    g0 = g_inf + jnp.sum(g)
    glassy = 1 / g0
    n = g.shape[0]
    if n == 0:
        empty = jnp.zeros((0,), glassy.dtype)
        return CreepSeries(glassy, empty, empty, jnp.zeros((), glassy.dtype))
    r = 1 / tau
    active = g > 0
    below = active[None, :] & (r[None, :] < r[:, None])  # [k, i]: active pole i below k
    lo = jnp.max(jnp.where(below, r[None, :], 0), axis=1)
    hi = r
    mid = lo + 0.5 * (hi - lo)
    fluid = g_inf == 0
    fluid_mode = fluid & active & ~jnp.any(below, axis=1)  # its root is u = 0
    params = (g_inf, g, jnp.zeros_like(g), g * r)
    u = _roots(params, r, lo, hi, increasing=False)
    # Inert poles sit at their own rate; the fluid mode is a dummy of strength 0.
    u = jnp.where(active & ~fluid_mode, u, jnp.where(active, mid, r))
    strengths = _amplitudes(u, params, r, fluid_mode)
    times = 1 / u
    fluidity = _safe_reciprocal(jnp.sum(g * tau), fluid)
    return CreepSeries(glassy, strengths, times, fluidity)


@jax.jit
def relaxation_series(j_inf, j, tau, fluidity=None):
    """The relaxation series `(g_inf, g, tau_relax)` of
    `J(t) = j_inf - sum_i j_i exp(-t / tau_i) (+ fluidity t)`.

    Requires `j >= 0`, `J(0) = j_inf - sum(j) > 0`, `tau > 0` pairwise distinct,
    `fluidity >= 0`. Returns `len(j)` modes (one more when `fluidity` is given); a pole
    of zero weight gives a mode of zero strength.
    """
    j0 = j_inf - jnp.sum(j)
    r = 1 / tau
    w = j * r
    if fluidity is not None:
        r = jnp.concatenate([jnp.zeros((1,), r.dtype), r])
        w = jnp.concatenate([jnp.reshape(fluidity, (1,)), w])
        fluid = fluidity > 0
        g_inf = jnp.where(fluid, 0, 1 / jnp.where(fluid, 1, j_inf))
    else:
        g_inf = 1 / j_inf
    n = r.shape[0]
    if n == 0:
        return g_inf, jnp.zeros((0,), r.dtype), jnp.zeros((0,), r.dtype)
    active = w > 0
    above = active[None, :] & (r[None, :] > r[:, None])  # [k, i]: active pole i above k
    total = jnp.sum(jnp.where(active, w, 0))
    top = jnp.max(r) + 2 * total / j0  # h > 0 beyond: bounds the fastest rate
    hi = jnp.min(jnp.where(above, r[None, :], top), axis=1)
    lo = r
    mid = lo + 0.5 * (hi - lo)
    params = (j0, jnp.zeros_like(w), -w, w)
    u = _roots(params, r, lo, hi, increasing=True)
    # Inert poles sit at their own rate; an inert fluid pole (rate 0) is a dummy.
    dummy = ~active & (r == 0)
    u = jnp.where(active, u, jnp.where(dummy, mid, r))
    g = _amplitudes(u, params, r, dummy)
    tau_relax = 1 / u
    return g_inf, g, tau_relax


# --------------------------------------------------------------------------------------
# The material.


class Prony(AbstractMaterial):
    """A generalized Wiechert half-space: a Prony series for the shear relaxation
    modulus,

        G(t) = g_inf + sum_i g[i] exp(-t / tau[i]).

    **Arguments:**

    - `g_inf`: long-time shear modulus [stress], `>= 0` (`0`: a fluid).
    - `g`: shape `(n,)`, the spring moduli of the Maxwell arms [stress], `>= 0`.
    - `tau`: shape `(n,)`, their relaxation times [time], `> 0`, pairwise distinct.
    - `poisson`: Poisson's ratio, in `(-1, 0.5]`.

    `g_inf + sum(g)` (the instantaneous modulus) must be `> 0`. `n` may be 0 (elastic).

    `creep(t)` is the exact creep compliance, a constant plus `n` exponentials (plus
    `t / sum(g * tau)` for a fluid): see `creep_series()`. Build one from a creep series
    with `Prony.from_creep`.

    Everything is differentiable with respect to `g_inf`, `g` and `tau` (also at
    `g[i] = 0`), except with respect to `g_inf` exactly AT `g_inf = 0`: there the creep
    series changes form (a fluid's creep grows like `t`; the one-sided derivative grows
    like `t^2`, which no creep series can carry), and the gradient returned for `g_inf`
    there is not that one-sided derivative.
    """

    g_inf: Float[Array, ""]
    g: Float[Array, " n"]
    tau: Float[Array, " n"]
    poisson: Float[Array, ""]

    def __init__(self, g_inf, g, tau, poisson):
        g_inf, g, tau = _series_arrays(
            ("g_inf", "g", "tau"),
            (g_inf, g, tau),
            (_validate.non_negative, _validate.non_negative, _validate.positive),
        )
        tau = _distinct("tau", tau)
        g_inf = require(
            "g_inf + sum(g) (the instantaneous modulus G(0))",
            g_inf,
            (g_inf, g),
            lambda g_inf, g: g_inf + jnp.sum(g) > 0,
            "> 0",
            lambda: f"g_inf={np.asarray(g_inf).item()!r}, g={np.asarray(g)!r}",
        )
        self.g_inf = g_inf
        self.g = g
        self.tau = tau
        self.poisson = check_scalar(
            "poisson", check_arg(_validate.poisson_ratio, "poisson", poisson))

    @classmethod
    def from_creep(cls, j_inf, j, tau, poisson, fluidity=None) -> "Prony":
        """The Prony series of a creep compliance given as

            J(t) = j_inf - sum_i j[i] exp(-t / tau[i])  (+ fluidity * t)

        (the convention of the paper's Eqs. 28 and 31: Eq. 28 is `j_inf = 0.699`,
        `j = (0.0838, 0.06174)`, `tau = (133.869, 9.9404)` in 1/GPa and s).

        **Arguments:**

        - `j_inf`: [1/stress]; for a solid, the long-time compliance `J(inf)`.
        - `j`: shape `(n,)`, `>= 0` [1/stress].
        - `tau`: shape `(n,)`, the retardation times [time], `> 0`, pairwise distinct.
        - `poisson`: Poisson's ratio, in `(-1, 0.5]`.
        - `fluidity`: optional, `>= 0`, one over the viscosity [1/(stress time)]. When
          given, the result has `n + 1` relaxation modes (and `g_inf = 0` when it is
          `> 0`); when `None`, `n` modes.

        The instantaneous compliance `J(0) = j_inf - sum(j)` must be `> 0`. The result
        is exact (to rounding) and differentiable with respect to every argument (except
        with respect to `fluidity` exactly at `fluidity = 0`, where the form changes).
        """
        j_inf, j, tau = _series_arrays(
            ("j_inf", "j", "tau"),
            (j_inf, j, tau),
            (_validate.finite, _validate.non_negative, _validate.positive),
        )
        tau = _distinct("tau", tau)
        j_inf = require(
            "j_inf - sum(j) (the instantaneous compliance J(0))",
            j_inf,
            (j_inf, j),
            lambda j_inf, j: j_inf - jnp.sum(j) > 0,
            "> 0 for a valid solid or fluid with J(t) = j_inf - sum(j exp(-t/tau))",
            lambda: f"j_inf={np.asarray(j_inf).item()!r}, j={np.asarray(j)!r}",
        )
        if fluidity is not None:
            fluidity = check_scalar(
                "fluidity", check_arg(_validate.non_negative, "fluidity", fluidity))
            (fluidity,) = promote(fluidity.astype(j_inf.dtype))
        check_arg(_validate.poisson_ratio, "poisson", poisson)
        g_inf, g, tau_relax = relaxation_series(j_inf, j, tau, fluidity)
        return cls(g_inf, g, tau_relax, poisson)

    def relaxation(self, t: ArrayLike) -> Float[Array, "..."]:
        t = jnp.asarray(t)
        t = t.astype(jnp.result_type(t, self.g_inf))
        shape = (1,) * t.ndim + self.tau.shape
        terms = self.g.reshape(shape) * jnp.exp(-t[..., None] / self.tau.reshape(shape))
        return self.g_inf + jnp.sum(terms, axis=-1)

    def creep(self, t: ArrayLike) -> Float[Array, "..."]:
        return self.creep_series()(t)

    def creep_series(self) -> CreepSeries:
        return retardation_series(self.g_inf, self.g, self.tau)
