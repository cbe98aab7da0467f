r"""Normal contact: the Polonsky-Keer constrained conjugate gradient method.

Problem (one elastic step): find the pressure `p >= 0` on the grid such that the gap

    g = h + C K p - delta

is `>= 0` everywhere and `0` where `p > 0`, with either the load `A sum(p) = W`
prescribed (load control: the approach `delta` is the Lagrange multiplier of the load
constraint) or the approach `delta` prescribed (displacement control). `K` is the
unit-modulus operator (`HalfSpace.apply_normal`), `C` the compliance (`1 / G` for an
elastic body, `J(0)` in a viscoelastic step), `h` the initial gap plus any displacement
from other sources (tangential tractions through coupling, the loading history), `A`
the cell area.

Differences from the textbook algorithm (Polonsky & Keer 1999, Wear 231, 206-219):

- ONE operator application per iteration. The displacement `u = C K p` is updated by
  linearity (`u <- u - tau C K t`) instead of being recomputed from `p`. It is
  recomputed exactly only when the projection onto `p >= 0` or the re-entry of
  penetrating cells has changed `p` outside the search direction (early iterations,
  while the contact set settles), every `resync_every` iterations against round-off
  drift, and before convergence is declared.
- Convergence is tested on the contact conditions themselves, not on the change of
  `p`: `residual = ||gap violation||_2 / ||u||_2`, where the violation is the gap on
  contact cells and the penetration `min(g, 0)` elsewhere. Under load control the load
  balance holds exactly at every iteration (the pressure is rescaled).
- Preconditioned (optional, the default in `jc.solve_normal` and `jc.solve`): the
  search direction is built from `z = M g` instead of the gap `g`, where `M` applies
  the INVERSE of the full-plane operator, restricted to the contact set and, under
  load control, made mean-free on it. The operator restricted to a contact disc of
  `m` cells across has a condition number growing like `m` (its symbol is `1 /
  |k|`); `M` removes that growth up to edge effects. Measured with `M` on the padded
  grid: 4-5x fewer iterations for half the FFT pairs (`benchmarks/notes/solvers.md`).
  `inverse_preconditioner` builds
  `M`: `1 / spectrum` on the padded grid (one more padded pair per iteration), or, as
  the solvers use it, on the UNPADDED grid with the wrapped spectrum raised to
  Boussinesq's continuous symbol (a quarter of the transform, no more iterations).
  The idea is Vollebregt's (2014), whose CONTACT uses an FFT-based preconditioner
  for its normal CG solver; his also adds deflation.
- Mixed precision (float64 solves, by default on grids of 256 cells a side or more):
  while the residual is above `1e-5` the operator is applied in float32 (its
  round-off, ~6e-8 of `||u||`, is then < 1 % of the residual), the preconditioner
  always; then the displacement is recomputed in float64, the conjugacy restarted,
  and the float64 iteration certifies convergence as above. Measured: the same
  iterations and errors, 1.2-1.3x faster.
- Bounded: at most `max_steps` iterations; a solve that does not reach `rtol` is
  returned with `converged=False`, never silently.
"""

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from .._results import RESULTS
from .base import AbstractStepSolver, StepGuess, StepProblem, loop, make_result, run
from .base import safe_div as _safe_div
from .precondition import continuum_symbols, padded_inverse, unpadded_inverse
from .residual import gap_residual


def inverse_preconditioner(operator, spectrum, poisson=None):
    """`g -> F^-1[F[g] / spectrum]`: the full-plane inverse of the convolution with the
    real, even `spectrum` (any positive scale), inverted by
    `precondition.inverse_symbol` (near-zero modes dropped).

    Without `poisson`, on the operator's (padded) FFT grid. With `poisson`, `spectrum`
    must be the operator's `normal_spectrum(poisson)` (unit compliance), and on a
    non-periodic grid the inverse runs on the UNPADDED grid
    (`precondition.unpadded_inverse`: the wrapped spectrum raised to Boussinesq's
    continuous symbol where that is larger), a quarter of the transform, with fewer
    iterations than the padded inverse (`benchmarks/notes/solvers.md`).
    """
    if poisson is not None and not operator.grid.periodic:
        continuum = continuum_symbols(operator.grid, poisson, 0)[0]
        return unpadded_inverse(operator.grid, spectrum, continuum)
    return padded_inverse(operator, spectrum)


def hertzian_guess(h, load, effective_modulus, cell_area, steps: int = 60):
    """A Hertz-shaped initial pressure `p0 = sqrt(max(c - h, 0))` (unscaled).

    For a paraboloid `h = r^2 / 2R` this is the exact Hertz shape when the level `c`
    is `a^2 / 2R` (the contact is `{h < c}`, and the approach is `2 (c - min h)`).
    `c` is found by bisection on the Hertz relation `W = 4/3 E* a_eff delta` with
    `a_eff = sqrt(area{h < c} / pi)` and `delta = 2 (c - min h)`, which is monotone in
    `c`. For other surfaces it is only a bearing-area guess that starts the CG close to
    the final contact set.
    """
    h_min = jnp.min(h)
    e = effective_modulus

    def excess(level):
        area = cell_area * jnp.sum(h < level)
        return 4 / 3 * e * jnp.sqrt(area / jnp.pi) * 2 * (level - h_min) - load

    a_cell = jnp.sqrt(cell_area / jnp.pi)
    hi = h_min + jnp.maximum(load / (8 / 3 * e * a_cell), jnp.max(h) - h_min)
    lo = h_min

    def body(_, bounds):
        lo, hi = bounds
        mid = 0.5 * (lo + hi)
        up = excess(mid) > 0
        return jnp.where(up, lo, mid), jnp.where(up, mid, hi)

    lo, hi = jax.lax.fori_loop(0, steps, body, (lo, hi))
    return jnp.sqrt(jnp.maximum(hi - h, 0))


# The preconditioned CG restarts its conjugacy when more than this fraction of the
# contact re-enters in one iteration (the textbook algorithm: when any cell does);
# benchmarks/notes/normal_reentry.md.
REENTRY_RESTART_FRACTION = 0.01

# A float64 solve applies the operator in float32 while its residual is above this
# (float32's operator is accurate to ~6e-8 of ||u||, so the residual it reports is
# then exact to < 1 %); convergence is always certified in float64.
LOW_PRECISION_ABOVE = 1e-5
# ... on grids with at least this many cells a side, by default: below, the transforms
# do not dominate an iteration (measured: <= 2 % faster at 64^2, 2-14 % at 128^2,
# 15-20 % at 256^2, 20-30 % at 512^2 and up), and float64 throughout keeps two paths
# to one answer (a batch and its members) together to round-off, not to the tolerance.
MIXED_PRECISION_MIN = 256


class NormalState(NamedTuple):
    """Raw result of a normal solve (all arrays)."""

    pressure: Float[Array, "nx ny"]
    displacement: Float[Array, "nx ny"]  # C K p
    gap: Float[Array, "nx ny"]
    approach: Float[Array, ""]
    iterations: Int[Array, ""]
    residual: Float[Array, ""]
    converged: Bool[Array, ""]
    # Operator applications (padded FFT convolutions) used; the preconditioner's
    # transforms (an unpadded pair per iteration when given `poisson`) are not counted.
    applications: Int[Array, ""]


def _in_dtype(fn, dtype):
    """`fn` applied in `dtype`, its result in its argument's dtype."""
    return lambda x: fn(x.astype(dtype)).astype(x.dtype)


def _evaluate(h, u, p, target, load_control):
    """Gap, approach and residual for the pressure `p` with displacement `u`
    (`residual.gap_residual`, scaled by the displacement `||u||`)."""
    return gap_residual(h + u, p > 0, load_control, target, jnp.sqrt(jnp.sum(u * u)))


class NormalOperator:
    """What a normal solve holds fixed: `apply_fn` (`p -> C K p`, pressure [stress] to
    displacement [length]), the effective gap `h` [length], the `target` (load [force]
    or approach [length]), `cell_area`, `load_control`, the `self_compliance` (the
    diagonal of `apply_fn`) and the preconditioner (`None` or `g -> M g`)."""

    def __init__(self, apply_fn, h, target, cell_area, *, load_control, rtol,
                 self_compliance, precondition=None, apply_low=None, low=False):
        self.apply_fn = apply_fn
        self.apply_low = apply_low  # `apply_fn` in float32 (mixed precision) or None
        self.low = low  # this phase steps with `apply_low`
        self.h = h
        self.target = jnp.asarray(target, h.dtype)
        self.cell_area = cell_area
        self.load_control = load_control
        self.rtol = rtol
        self.k00 = jnp.asarray(self_compliance, h.dtype)
        self.precondition = precondition

    @classmethod
    def of(cls, solver: "PolonskyKeer", problem) -> "NormalOperator":
        """From a `StepProblem`: `C K_zz`, `h = gap + history_z`, its normal target."""
        operator = problem.operator
        spectrum = problem.compliance * operator.normal_spectrum(problem.poisson)
        # Mixed precision (a float64 solve): float32 operator applications while the
        # residual is large (`run_loop`), a float32 preconditioner throughout (it only
        # shapes the search directions; same iterations to rtol 1e-11, measured).
        mixed = solver.mixed_precision
        if mixed is None:
            mixed = min(operator.grid.shape) >= MIXED_PRECISION_MIN
        mixed = mixed and jnp.dtype(problem.dtype) == jnp.float64
        low_dtype = jnp.float32 if mixed else problem.dtype
        precondition = None
        if solver.precondition:
            precondition = _in_dtype(inverse_preconditioner(
                operator, operator.normal_spectrum(problem.poisson).astype(low_dtype),
                problem.poisson.astype(low_dtype)), low_dtype)
        apply_low = None
        if mixed:
            spectrum_low = spectrum.astype(low_dtype)
            apply_low = _in_dtype(lambda p: operator.convolve(p, spectrum_low),
                                  low_dtype)
        return cls(
            lambda p: operator.convolve(p, spectrum),
            problem.gap + problem.history[2], problem.normal_target,
            operator.grid.cell_area, load_control=problem.normal_force_control,
            rtol=solver.tolerance(problem.dtype),
            self_compliance=operator.diagonal(spectrum), precondition=precondition,
            apply_low=apply_low)

    def with_gap(self, h, low=None) -> "NormalOperator":
        """The same operator for another effective gap (a coupled round's), in the
        float32 phase if `low` (default: this one's phase)."""
        return NormalOperator(
            self.apply_fn, h, self.target, self.cell_area,
            load_control=self.load_control, rtol=self.rtol, self_compliance=self.k00,
            precondition=self.precondition, apply_low=self.apply_low,
            low=self.low if low is None else low)

    def rescale(self, p):
        total = self.cell_area * jnp.sum(p)
        return jnp.where(total > 0, self.target / jnp.where(total > 0, total, 1), 0.0)

    def evaluate(self, u, p):
        return _evaluate(self.h, u, p, self.target, self.load_control)


class _NormalCGState(eqx.Module):
    p: Float[Array, "nx ny"]
    u: Float[Array, "nx ny"]
    g: Float[Array, "nx ny"]
    t: Float[Array, "nx ny"]  # search direction
    g_norm_old: Float[Array, ""]
    restart: Bool[Array, ""]
    it: Int[Array, ""]
    residual: Float[Array, ""]
    applications: Int[Array, ""]
    p_start: Float[Array, "nx ny"]  # the pressure to restart from if all of it clips
    inexact: Bool[Array, ""]  # `u` carries float32 round-off (mixed precision)


class PolonskyKeer(AbstractStepSolver):
    """Polonsky-Keer conjugate gradient solver for the normal contact problem (see the
    module docs). Solves frictionless steps (`nd = 0`); `jc.Rounds` uses it for the
    normal half of every round.

    **Arguments:**

    - `rtol`: relative tolerance on the contact conditions (see module docs). `None`
      (default) picks `1e-8` in float64 and `1e-5` in float32 (whose round-off floor
      is about `5e-7`).
    - `max_steps`: maximum number of CG iterations (default 2000).
    - `resync_every`: recompute the displacement exactly every this many iterations
      (default 25).
    - `precondition`: build the search directions from the full-plane inverse of the
      operator (default `True`: about 4x fewer iterations for half the FFT pairs;
      see the module docs). `False` is the textbook algorithm.
    - `mixed_precision`: in a float64 solve, apply the operator in float32 while the
      residual is above `LOW_PRECISION_ABOVE` (`1e-5`), and the preconditioner in
      float32 throughout. The answer is float64's: the first float64 iteration
      recomputes the displacement in float64 and restarts the conjugacy, and
      convergence is certified in float64. The same iterations and errors on the
      rough sphere at 256^2-1024^2, rtol 1e-4 to 1e-11, 1.2-1.3x faster on 2 CPU
      cores (`benchmarks/notes/normal_reentry.md`). `None` (default): on grids of at
      least `MIXED_PRECISION_MIN` (256) cells a side. No effect in float32.

    ??? cite "References"

        Polonsky, I. A. & Keer, L. M. (1999). A numerical method for solving rough
        contact problems based on the multi-level multi-summation and conjugate gradient
        techniques. Wear 231, 206-219.

        Vollebregt, E. A. H. (2014). A new solver for the elastic normal contact problem
        using conjugate gradients, deflation, and an FFT-based preconditioner. J.
        Comput. Phys. 257, 333-351.
    """

    rtol: float | None = eqx.field(static=True, default=None)
    max_steps: int = eqx.field(static=True, default=2000)
    resync_every: int = eqx.field(static=True, default=25)
    precondition: bool = eqx.field(static=True, default=True)
    mixed_precision: bool | None = eqx.field(static=True, default=None)

    def __check_init__(self):
        if self.mixed_precision is not None and not isinstance(self.mixed_precision,
                                                               bool):
            raise TypeError("mixed_precision must be a bool or None, got "
                            f"{self.mixed_precision!r}")

    def supports(self, problem):
        if problem.nd != 0:
            return ("it solves frictionless (normal) steps only; use jc.Rounds() or "
                    "jc.JointPCG() for a step with shear")
        return None

    def step_limit(self) -> int:
        return self.max_steps

    def setup(self, problem) -> NormalOperator:
        return NormalOperator.of(self, problem)

    def init(self, problem, k: NormalOperator, guess) -> _NormalCGState:
        h = k.h
        # Local compliance: the displacement of a cell under its own unit pressure. It
        # gives a pressure that closes an interference locally: the start of a
        # displacement-controlled solve from p = 0, and the step for re-entering cells.
        p0 = jnp.asarray(guess.normal, h.dtype)
        if not k.load_control:
            local = jnp.maximum(k.target - h, 0) / k.k00
            p0 = jnp.where(jnp.sum(p0) > 0, p0, local)
        p0 = jnp.maximum(p0, 0)
        if k.load_control:
            p0 = jnp.where(jnp.sum(p0) > 0, p0, jnp.ones_like(p0))
            p0 = p0 * k.rescale(p0)
        u0 = k.apply_fn(p0)
        g0, _, res0 = k.evaluate(u0, p0)
        return _NormalCGState(
            p=p0, u=u0, g=g0, t=jnp.zeros_like(h), g_norm_old=jnp.ones((), h.dtype),
            restart=jnp.array(True), it=jnp.array(0), residual=res0,
            applications=jnp.array(1), p_start=p0, inexact=jnp.array(False))

    def terminate(self, problem, k, s):
        # The float32 phase ends where float64 takes over.
        stop = max(k.rtol, LOW_PRECISION_ABOVE) if k.low else k.rtol
        return s.residual <= stop, RESULTS.successful

    def run_loop(self, problem, k: NormalOperator, state):
        """The float32 phase (mixed precision), then the float64 one: two loops, so
        that under `vmap` each applies the operator in one precision; both count
        towards `max_steps`."""
        steps = 0
        if k.apply_low is not None:
            state, steps = loop(self, problem, k.with_gap(k.h, low=True), state)
        return loop(self, problem, k.with_gap(k.h, low=False), state, steps)

    def step(self, problem, k: NormalOperator, s: _NormalCGState) -> _NormalCGState:
        load_control, rtol = k.load_control, k.rtol
        p, u, g = s.p, s.u, s.g
        low = k.low
        apply_fn = k.apply_low if low else k.apply_fn
        overlap = (p <= 0) & (g < 0)
        if k.precondition is None:
            contact = p > 0
        else:  # penetrating cells join the active set of this step's direction
            contact = (p > 0) | overlap
        n_contact = jnp.sum(contact)
        gc = jnp.where(contact, g, 0)
        if k.precondition is None:
            z = gc
        else:
            z = jnp.where(contact, k.precondition(gc), 0)
            if load_control:  # keep the load: a mean-free direction on the contact
                z = jnp.where(contact, z - _safe_div(jnp.sum(z), n_contact), 0)
        g_norm = jnp.sum(gc * z)  # (g, M g); (g, g) without preconditioner
        if k.precondition is None:
            reentered = jnp.any(overlap)
            restart = s.restart
        else:
            reentered = jnp.sum(overlap) > REENTRY_RESTART_FRACTION * n_contact
            restart = s.restart | reentered
        beta = jnp.where(restart, 0.0, _safe_div(g_norm, s.g_norm_old))
        t = jnp.where(contact, z + beta * s.t, 0)
        r_raw = apply_fn(t)
        r = r_raw
        if load_control:
            r = r - _safe_div(jnp.sum(jnp.where(contact, r, 0)), n_contact)
        tau = _safe_div(jnp.sum(gc * t), jnp.sum(jnp.where(contact, r * t, 0)))
        p_step = p - tau * t
        u_new = u - tau * r_raw
        clipped = p_step < 0
        p_new = jnp.maximum(p_step, 0)
        # Re-entry: cells out of contact that penetrate get pressure.
        if k.precondition is None:
            tau_overlap = jnp.where(tau > 0, tau, 1 / k.k00)
            p_new = jnp.where(overlap, p_new - tau_overlap * g, p_new)
        else:  # those the direction did not lift: the local closure
            p_new = jnp.where(overlap & (p_new <= 0), -g / k.k00, p_new)
        changed = jnp.any(clipped & contact) | jnp.any(overlap)
        if load_control:
            p_new = jnp.where(jnp.sum(p_new) > 0, p_new, s.p_start)
            scale = k.rescale(p_new)
            p_new = p_new * scale
            u_new = u_new * scale
        it = s.it + 1
        # Leaving float32: recompute `u` in float64 and restart the conjugacy.
        switched = jnp.array(False) if low else s.inexact
        need_exact = changed | (it % self.resync_every == 0) | switched
        u_new = jax.lax.cond(need_exact, lambda: apply_fn(p_new), lambda: u_new)
        g_new, _, res = k.evaluate(u_new, p_new)

        # Certify convergence with an exact displacement.
        def exact():
            u_e = k.apply_fn(p_new)
            g_e, _, res_e = k.evaluate(u_e, p_new)
            return u_e, g_e, res_e

        certify = ((~need_exact) | low) & (res <= rtol)
        u_new, g_new, res = jax.lax.cond(certify, exact, lambda: (u_new, g_new, res))
        applications = s.applications + 1 + need_exact + certify
        return _NormalCGState(
            p=p_new, u=u_new, g=g_new, t=t, g_norm_old=g_norm,
            # A failed certification changes the residual discontinuously: restart.
            restart=reentered | (certify & (res > rtol)) | switched,
            it=it, residual=res, applications=applications, p_start=s.p_start,
            inexact=(~certify) if low else jnp.array(False))

    def normal_state(self, k: NormalOperator, s: _NormalCGState) -> NormalState:
        """The final state as a `NormalState` (gap, approach, residual re-evaluated)."""
        g, delta, residual = k.evaluate(s.u, s.p)
        return NormalState(
            pressure=s.p, displacement=s.u, gap=g, approach=delta, iterations=s.it,
            residual=residual, converged=residual <= k.rtol,
            applications=s.applications)

    def postprocess(self, problem, k: NormalOperator, s: _NormalCGState, result):
        st = self.normal_state(k, s)
        empty = jnp.zeros((0,) + st.pressure.shape, st.pressure.dtype)
        return make_result(
            pressure=st.pressure, shear=empty, approach=st.approach,
            delta_t=jnp.zeros((0,), st.pressure.dtype), slip=empty,
            stick=(st.pressure > 0) & (problem.friction > 0), sliding=False,
            iterations=st.iterations, rounds=1, residual=st.residual,
            converged=st.converged, result=result)


def polonsky_keer(apply_fn, h, target, cell_area, *, load_control: bool, rtol: float,
                  max_steps: int, resync_every: int = 25, self_compliance, p0=None,
                  precondition=None) -> NormalState:
    """`PolonskyKeer` on a raw operator: `apply_fn` (`p -> C K p`), the effective gap
    `h` [length], `target` (load [force] or approach [length]), the `cell_area`, the
    `self_compliance` (diagonal of `apply_fn`), an optional start `p0` and
    preconditioner (`g -> M g`). For tests and benchmarks of the preconditioners."""
    solver = PolonskyKeer(rtol=rtol, max_steps=max_steps, resync_every=resync_every,
                          precondition=precondition is not None)
    k = NormalOperator(apply_fn, h, target, cell_area, load_control=load_control,
                       rtol=rtol, self_compliance=self_compliance,
                       precondition=precondition)
    p0 = jnp.zeros_like(h) if p0 is None else p0
    nx, ny = h.shape
    zero = jnp.zeros((), h.dtype)
    # The step around the raw operator (its fields other than the gap and target are
    # unused: `k` is the setup).
    problem = StepProblem(
        None, zero, zero, zero, h, jnp.zeros((3, nx, ny), h.dtype), k.target,
        jnp.zeros((0,), h.dtype), jnp.zeros((0, nx, ny), h.dtype), 0, False,
        load_control, ())
    guess = StepGuess(p0, jnp.zeros((0,) + h.shape, h.dtype))
    return solver.normal_state(k, run(solver, problem, guess, setup=k).state)
