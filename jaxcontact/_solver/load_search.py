r"""`LoadByDisplacement`: meet a tangential load by a root search on its displacement.

Under tangential LOAD control the coupled iterations can fail where the same step
under DISPLACEMENT control converges (e.g. the paper's total slip law on a viscoelastic
body). The load of one direction `d` (x if it is load-controlled, else y) is then met
by a safeguarded, bracketed root search on the rigid tangential displacement
`delta_d`, each evaluation a displacement-controlled step solved by the wrapped solver
(warm-started from the last evaluation). `F_d(delta_d)` is non-decreasing (the
tangential operator is positive definite; the force saturates at `+-mu W` in gross
sliding), so a bracket is grown geometrically from the start's `delta_d` and then
shrunk by the Illinois variant of regula falsi with bisection safeguards, until the
load error is below `rtol mu W`. The best converged evaluation is the answer.
"""

import equinox as eqx
import jax
import jax.numpy as jnp

from .._results import RESULTS
from .base import AbstractStepSolver, StepGuess, StepResult


class _SearchState(eqx.Module):
    a: jax.Array  # the other end of the bracket once there is one
    fa: jax.Array
    b: jax.Array  # the latest point and its load error F_d - target [force]
    fb: jax.Array
    last: StepResult
    best: StepResult
    best_err: jax.Array  # load error / mu W of the best converged evaluation (or inf)
    best_raw: jax.Array  # its load error, converged or not
    n: jax.Array  # evaluations
    bracketed: jax.Array
    step: jax.Array  # the geometric growth step [length]
    iterations: jax.Array
    rounds: jax.Array
    fallbacks: jax.Array


class LoadByDisplacement(AbstractStepSolver):
    """Wraps a solver: the tangential load of one direction by a root search on its
    displacement (see the module docs). For steps with a load-controlled direction.

    **Arguments:**

    - `solver`: solves each displacement-controlled evaluation.
    - `evaluations`: the most evaluations (bracketing and Illinois steps together).
    - `rtol`: the load tolerance relative to `mu W`; `None`: `solver`'s.
    """

    solver: AbstractStepSolver
    evaluations: int = eqx.field(static=True, default=40)
    rtol: float | None = eqx.field(static=True, default=None)

    def supports(self, problem):
        if problem.nd == 0 or not any(problem.tangential_force_control):
            return "no tangential direction is load-controlled"
        return self.solver.supports(
            self._subproblem(problem, problem.tangential_target))

    def step_limit(self) -> int:
        return self.evaluations - 1  # the first evaluation is `init`'s

    def _direction(self, problem) -> int:
        return problem.tangential_force_control.index(True)

    def _subproblem(self, problem, targets):
        d = self._direction(problem)
        fc = problem.tangential_force_control
        return problem.with_tangential(
            targets, tuple(f if i != d else False for i, f in enumerate(fc)))

    def tolerance(self, dtype) -> float:
        return self.rtol if self.rtol is not None else self.solver.tolerance(dtype)

    def setup(self, problem):
        return None

    def _evaluate(self, problem, delta, start):
        d = self._direction(problem)
        dtype = problem.dtype
        area = problem.operator.grid.cell_area
        target = jnp.asarray(problem.tangential_target, dtype)
        sub = self._subproblem(problem, target.at[d].set(delta))
        # One solver per evaluation: a failed one still steers the bracket.
        r = self.solver.solve(sub, StepGuess(start.pressure, start.shear))
        force = area * jnp.sum(r.shear[d])
        scale = area * problem.friction * jnp.sum(r.pressure)  # mu W
        # The load residual as the tangential solver defines it (relative to mu W).
        raw = jnp.abs(force - target[d]) / jnp.where(scale > 0, scale, 1)
        raw = jnp.where(jnp.isfinite(raw), raw, jnp.inf)
        # Only a converged evaluation can be the answer.
        err = jnp.where(r.converged, raw, jnp.inf)
        return r, force - target[d], err, raw

    def init(self, problem, setup, guess) -> _SearchState:
        d = self._direction(problem)
        area = problem.operator.grid.cell_area
        d0 = guess.delta_t[d]
        d0 = jnp.where(jnp.isfinite(d0), d0, 0.0)
        r0, f0, e0, raw0 = self._evaluate(problem, d0, guess)
        # First growth step: the force error over the stiffness of a stuck contact of
        # the current size L (~ L / C), floored at 1e-3 of the full slip mu W C / L.
        n_contact = jnp.maximum(jnp.sum(r0.pressure > 0), 1)
        size = jnp.sqrt(n_contact * area)
        mu_w = area * problem.friction * jnp.sum(r0.pressure)
        compliance = problem.compliance
        step0 = compliance * jnp.maximum(jnp.abs(f0), 1e-3 * mu_w) / size
        step0 = jnp.where(jnp.isfinite(step0) & (step0 > 0), step0, compliance / size)
        return _SearchState(
            a=d0, fa=f0, b=d0, fb=f0, last=r0, best=r0, best_err=e0, best_raw=raw0,
            n=jnp.array(1), bracketed=f0 == 0, step=step0, iterations=r0.iterations,
            rounds=r0.rounds, fallbacks=r0.fallbacks)

    def terminate(self, problem, setup, s: _SearchState):
        return s.best_err <= self.tolerance(problem.dtype), RESULTS.successful

    def step(self, problem, setup, s: _SearchState) -> _SearchState:
        a, fa, b, fb = s.a, s.fa, s.b, s.fb
        # Not bracketed yet: step from b towards the root (F non-decreasing).
        grow = b - jnp.sign(fb) * s.step
        # Bracketed: regula falsi, bisection when the secant point falls outside the
        # inner 90 % of the bracket.
        denom = fb - fa
        ok = denom != 0
        secant = b - fb * (b - a) / jnp.where(ok, denom, 1)
        lo, hi = jnp.minimum(a, b), jnp.maximum(a, b)
        margin = 0.05 * (hi - lo)
        inside = ok & (secant > lo + margin) & (secant < hi - margin)
        x = jnp.where(s.bracketed, jnp.where(inside, secant, 0.5 * (a + b)), grow)
        r, fx, ex, rawx = self._evaluate(problem, x, s.last)
        # Better: a smaller converged load error, or, while nothing has converged, a
        # smaller overall residual (a failure reports its best attempt).
        better = (ex < s.best_err) | (
            jnp.isinf(s.best_err) & jnp.isinf(ex)
            & (jnp.maximum(r.residual, rawx)
               < jnp.maximum(s.best.residual, s.best_raw)))
        best = jax.tree_util.tree_map(lambda n, o: jnp.where(better, n, o), r, s.best)
        flipped = jnp.sign(fx) != jnp.sign(fb)
        # Bracketed: a sign change moves a to the old b; otherwise a is kept and its
        # value halved (Illinois). Not bracketed: a sign change closes [b, x].
        a_new = jnp.where(flipped, b, a)
        fa_new = jnp.where(flipped, fb, jnp.where(s.bracketed, 0.5 * fa, fa))
        return _SearchState(
            a=a_new, fa=fa_new, b=x, fb=fx, last=r, best=best,
            best_err=jnp.minimum(ex, s.best_err),
            best_raw=jnp.where(better, rawx, s.best_raw), n=s.n + 1,
            bracketed=s.bracketed | flipped, step=2 * s.step,
            iterations=s.iterations + r.iterations, rounds=s.rounds + r.rounds,
            fallbacks=s.fallbacks + r.fallbacks)

    def postprocess(self, problem, setup, s: _SearchState, result):
        best = s.best
        converged = best.converged & (s.best_err <= self.tolerance(problem.dtype))
        # Not met: the best evaluation's own failure, or the evaluations ran out.
        failure = RESULTS.where(best.converged, result, best.result)
        return best.replace(
            iterations=s.iterations, rounds=s.rounds, fallbacks=s.fallbacks,
            residual=jnp.maximum(best.residual, s.best_raw), converged=converged,
            result=RESULTS.where(converged, best.result, failure))
