r"""The hereditary integral, step by step.

With a constant Poisson ratio the surface displacement is

    u(t_k) = K1 [ sum_{n <= k} J(t_k - t_n) (tau_n - tau_{n-1}) ]     (paper Eqs. 12-13)

with `tau = (q_x, q_y, p)` the traction field, `K1` the elastic operator for unit shear
modulus and `J` the shear creep compliance. The sum is POINTWISE in space, so each step
needs one convolution of a combined "history traction", never one per past step. Each
step is an elastic problem for `tau_k` with compliance `J_step` and the known history
displacement `K1 [history traction]`.

Schemes (all carry the traction of the previous step):

- `ElasticHistory`: `J` constant: no history at all.
- `RecursiveHistory`: `J(t) = J_g + sum_i J_i (1 - exp(-t / lambda_i)) + f t` (every
  Maxwell, Zener and Prony material). Internal variables
  `H_i(k) = sum_{n<=k} exp(-(t_k - t_n)/lambda_i) w_i(n) (tau_n - tau_{n-1})` and
  `L(k) = sum_{n<=k} c(n) (tau_n - tau_{n-1})` are updated recursively: O(Nt) time and
  O(m) fields of memory, exactly equal to the direct sum.
  `scheme="constant"`: tractions piecewise constant (jumps at the `t_n`): the paper's
  scheme, `w_i = 1`, `c = t_k - t_n`. `scheme="linear"`: tractions piecewise linear
  in each step (the increment applied at a uniform rate over `(t_{n-1}, t_n]`):
  `w_i = lambda_i (1 - exp(-dt_n / lambda_i)) / dt_n`, `c = t_k - t_n + dt_n / 2`, and
  `J_step = (1 / dt) int_0^dt J`. The first entry is always a jump (nothing before it).
- `DirectHistory`: any `J(t)` (`material.creep`), piecewise-constant scheme, the
  O(Nt^2) sum over a buffer of all past increments. Used when a material has no
  exponential series, and as the reference for the recursion.

`history_for` picks the scheme of a material.
"""

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from . import _validate
from ._material.elastic import Elastic


class StepHistory(NamedTuple):
    compliance: jnp.ndarray  # J_step, scalar
    traction: jnp.ndarray | None  # (3, nx, ny) history traction, or None (no history)


class ElasticHistory:
    def __init__(self, compliance):
        self.compliance = compliance

    def init(self, shape, dtype):
        return ()

    def prepare(self, state, tau_prev, k, dt):
        return StepHistory(self.compliance, None)

    def update(self, state, tau_prev, tau_new, k, dt):
        return state


class RecursiveHistory:
    def __init__(self, series, scheme: str):
        self.glassy = series.glassy
        self.strengths = series.strengths
        self.times = series.times
        self.fluidity = series.fluidity
        self.linear = scheme == "linear"

    def init(self, shape, dtype):
        m = self.strengths.shape[0]
        return (jnp.zeros((m, *shape), dtype), jnp.zeros(shape, dtype))

    def _weights(self, dt):
        decay = jnp.exp(-dt / self.times)
        if not self.linear:
            return decay, jnp.ones_like(decay)
        safe = jnp.where(dt > 0, dt, 1.0)
        # lambda (1 - exp(-dt/lambda)) / dt, -> 1 as dt -> 0 (a jump).
        phi = jnp.where(dt > 0, -self.times * jnp.expm1(-dt / self.times) / safe, 1.0)
        return decay, phi

    def prepare(self, state, tau_prev, k, dt):
        h, lin = state
        decay, phi = self._weights(dt)
        compliance = self.glassy + jnp.sum(self.strengths * (1 - phi))
        expand = (-1,) + (1,) * tau_prev.ndim
        hist = jnp.einsum("i,i...->...", self.strengths,
                          phi.reshape(expand) * tau_prev[None]
                          - decay.reshape(expand) * h)
        half = 0.5 * dt if self.linear else 0.0
        compliance = compliance + self.fluidity * half
        hist = hist + self.fluidity * (lin + (dt - half) * tau_prev)
        return StepHistory(compliance, hist)

    def update(self, state, tau_prev, tau_new, k, dt):
        h, lin = state
        decay, phi = self._weights(dt)
        increment = tau_new - tau_prev
        expand = (-1,) + (1,) * tau_prev.ndim
        h = decay.reshape(expand) * h + phi.reshape(expand) * increment[None]
        half = 0.5 * dt if self.linear else 0.0
        lin = lin + dt * tau_prev + half * increment
        return (h, lin)


class DirectHistory:
    def __init__(self, creep_fn, times):
        self.creep_fn = creep_fn
        self.times = times
        self.j0 = creep_fn(jnp.zeros((), times.dtype))

    def init(self, shape, dtype):
        return jnp.zeros((self.times.shape[0], *shape), dtype)

    def prepare(self, buffer, tau_prev, k, dt):
        n = jnp.arange(self.times.shape[0])
        lag = jnp.where(n < k, self.times[k] - self.times, 0.0)
        weights = jnp.where(n < k, self.creep_fn(lag), 0.0)
        hist = jnp.tensordot(weights, buffer, axes=1) - self.j0 * tau_prev
        return StepHistory(self.j0, hist)

    def update(self, buffer, tau_prev, tau_new, k, dt):
        return buffer.at[k].set(tau_new - tau_prev)


def history_for(material, times, history: str, scheme: str):
    """Pick the history scheme from the material: `ElasticHistory` for an
    `Elastic` one, `DirectHistory` for `history="direct"` or a material without a
    creep series, `RecursiveHistory` otherwise (`scheme`: "constant" or "linear")."""
    if isinstance(material, Elastic):
        return ElasticHistory(material.instantaneous_compliance)
    series = getattr(material, "creep_series", None)
    if history == "direct" or series is None:
        if scheme == "linear":
            raise ValueError('scheme="linear" needs a material with a creep series')
        return DirectHistory(material.creep, times)
    return RecursiveHistory(series(), scheme)


def constant_scheme_amplification(series, dt: float) -> float:
    """Spectral radius of the step-to-step map of the piecewise-constant scheme over
    a step `dt`, for a creep series with concrete values (NumPy, not traced).

    Holding the displacement of a linear body fixed, `sum_n J(t_k - t_n) dp_n` is the
    same at every step; differencing consecutive steps gives `J_g dp_k = -sum_i c_i
    S_i(k)` with `S_i(k+1) = q_i S_i(k) + dp_k`, `q_i = exp(-dt / lambda_i)`,
    `c_i = J_i (1 - q_i)` (a fluid term adds `q = 1`, `c = f dt`). So `S` evolves by
    `M = diag(q) - 1 c^T / J_g`; for one arm its eigenvalue is `1 - (J_inf / J_g)
    (1 - q)`. A radius above 1 is an alternating mode that grows from step to step:
    the scheme is then unstable (the contact problem oscillates instead of creeping).
    The piecewise-linear scheme has no such limit.
    """
    glassy = float(series.glassy)
    strengths = np.asarray(series.strengths, np.float64)
    q = np.exp(-dt / np.asarray(series.times, np.float64))
    c = strengths * (1 - q)
    fluidity = float(series.fluidity)
    if fluidity > 0:
        q, c = np.append(q, 1.0), np.append(c, fluidity * dt)
    if q.size == 0:
        return 0.0
    m = np.diag(q) - np.outer(np.ones_like(q), c) / glassy
    return float(np.max(np.abs(np.linalg.eigvals(m))))


def worst_time_step(material, times) -> tuple[float, float]:
    """`(amplification, dt)`: the largest `constant_scheme_amplification` over the
    distinct steps of `times` and the step that has it; `(0.0, 0.0)` for an elastic
    material, one without a creep series, or fewer than two times."""
    series = getattr(material, "creep_series", None)
    if series is None or isinstance(material, Elastic) or np.shape(times)[0] < 2:
        return 0.0, 0.0
    if _validate.is_traced(times) or _validate.is_traced(material):
        raise TypeError("time_step_amplification needs concrete material and times, "
                        "not traced ones (call it outside jit / grad / vmap)")
    steps = np.unique(np.diff(np.asarray(times, np.float64)))
    # concrete even inside `jit` (whose trace would stage the series' arithmetic)
    with jax.ensure_compile_time_eval():
        series = series()
    return max((constant_scheme_amplification(series, float(dt)), float(dt))
               for dt in steps)


def time_step_amplification(material, times) -> float:
    """How far the time steps of `times` are from the stability limit of the
    piecewise-constant (paper's) time scheme with `material`.

    **Arguments:**

    - `material`: a `jc.Elastic`, `jc.Maxwell`, `jc.Zener` or `jc.Prony` (concrete).
    - `times`: shape `(nt,)` [time], the scene's time points (concrete).

    **Returns:** the largest spectral radius of the scheme's step-to-step map over
    the distinct steps (dimensionless). Above 1 the scheme is unstable: the solution
    oscillates from step to step, and `jc.solve` warns `jc.TimeStepWarning`
    (`scheme="linear"` has no such limit). 0 for an elastic material, a material
    without a creep series, or fewer than two times. Lets a caller know ahead of a
    solve (e.g. before solving in threads, where recording warnings is not safe).
    """
    return worst_time_step(material, times)[0]


def check_time_options(throw, history: str, scheme: str) -> None:
    """The options of a time-stepping solve (`jc.solve`, `solve_axisymmetric`):
    `throw` a bool (`TypeError`), `history` "auto" / "recursive" / "direct" and
    `scheme` "constant" / "linear" (`ValueError` naming the value)."""
    if not isinstance(throw, bool):
        raise TypeError(f"throw must be a bool, got {throw!r}")
    if history not in ("auto", "recursive", "direct"):
        raise ValueError(
            f'history must be "auto", "recursive" or "direct", got {history!r}')
    if scheme not in ("constant", "linear"):
        raise ValueError(f'scheme must be "constant" or "linear", got {scheme!r}')
