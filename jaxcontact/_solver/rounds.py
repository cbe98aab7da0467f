r"""`Rounds`: a step by alternating normal and tangential solves (block Gauss-Seidel).

The normal and tangential problems interact through the coupling blocks of the
half-space operator (`(1 - 2 nu)` terms): the shear changes the normal displacement and
the pressure the tangential one. A round is a full Polonsky-Keer normal solve with the
latest shear, then a full tangential CG solve (`tangential.tangential_cg`) with the
latest pressure, each warm-started from the previous round, as in the paper and
Panagiotopoulos' process. The rounds stop when a whole round changes nothing (both
solvers accept their start with zero iterations). Without coupling one round is exact;
without a tangential solve (`nd = 0`) it is the normal solve alone.

Under tangential load control with `|F| >= mu W` (to `rtol / 2`,
`tangential.gross_sliding`; `F` the load of the load-controlled directions,
`base.applied_load`) the indenter slides: `q = mu p F/|F|`, reported, never iterated on
(`RESULTS.tangential_load_above_friction_limit` when `|F| > mu W`).
"""

import equinox as eqx
import jax
import jax.numpy as jnp

from .._results import RESULTS
from .base import (
    AbstractStepSolver,
    StepGuess,
    applied_load,
    make_result,
    run,
    step_outcome,
)
from .normal import NormalOperator, PolonskyKeer
from .precondition import shear_x_preconditioner
from .tangential import TangentialState, gross_sliding
from .tangential_cg import tangential_cg


class _RoundsOperator:
    """The step's normal and tangential operators and their inner solves."""

    def __init__(self, solver: "Rounds", problem):
        operator = problem.operator
        grid = operator.grid
        self.problem = problem
        self.area = grid.cell_area
        dtype = self.dtype = problem.dtype
        self.nd = nd = problem.nd
        self.nx, self.ny = grid.shape
        compliance, poisson = problem.compliance, problem.poisson
        self.rtol = solver.tolerance(dtype)
        self.solver = solver
        self.operator = operator
        # The normal half of every round: one setup, its gap replaced per round.
        self.normal_solver = PolonskyKeer(
            rtol=solver.rtol, max_steps=solver.max_steps,
            resync_every=solver.resync_every, precondition=solver.precondition)
        self.normal_problem = problem.normal_part()
        self.normal_setup = NormalOperator.of(self.normal_solver, self.normal_problem)
        self.h = self.normal_setup.h
        if nd == 0:
            return
        xx, xy, yy = operator.tangential_blocks(poisson)
        self.blocks = (compliance * xx, None if xy is None else compliance * xy,
                       None if yy is None else compliance * yy)
        self.self_compliance = operator.diagonal(self.blocks[0])  # A_xx at offset 0
        self.precondition_t = None
        if solver.precondition and nd == 1 and not grid.periodic:
            # The xx spectrum floored by the normal one, on the unpadded grid.
            self.precondition_t = shear_x_preconditioner(operator, poisson)
        self.zx, self.zy = operator.coupling_spectra(poisson)
        self.any_force = any(problem.tangential_force_control)

    def apply_tangential(self, q):
        return self.operator.apply_tangential(q, self.problem.poisson,
                                              blocks=self.blocks)

    def solve_normal(self, h_eff, p_start):
        p_start = jnp.asarray(p_start, self.dtype)
        guess = StepGuess(p_start, jnp.zeros((0,) + p_start.shape, self.dtype))
        setup = self.normal_setup.with_gap(h_eff)
        state = run(self.normal_solver, self.normal_problem, guess, setup=setup).state
        return self.normal_solver.normal_state(setup, state)

    def uz_from_shear(self, q):
        pr, op = self.problem, self.operator
        if not pr.coupled:
            return jnp.zeros((self.nx, self.ny), self.dtype)
        hat = 1j * pr.compliance * self.zx * op.forward(q[0])
        if self.zy is not None and self.nd == 2:
            hat = hat + 1j * pr.compliance * self.zy * op.forward(q[1])
        return op.inverse(hat)

    def ut_from_pressure(self, p):
        pr, op, nd = self.problem, self.operator, self.nd
        if not pr.coupled:
            return jnp.zeros((nd, self.nx, self.ny), self.dtype)
        p_hat = op.forward(p)
        ux = op.inverse(-1j * pr.compliance * self.zx * p_hat)
        if nd == 1:
            return ux[None]
        uy = (op.inverse(-1j * pr.compliance * self.zy * p_hat) if self.zy is not None
              else jnp.zeros_like(ux))
        return jnp.stack([ux, uy])

    def solve_tangential(self, p, q_start):
        s, pr, area = self.solver, self.problem, self.area
        bound = pr.friction * p
        b = self.ut_from_pressure(p) + pr.history[:self.nd] - pr.previous_slip
        target = pr.tangential_target

        def cg(skip=False):
            return tangential_cg(
                self.apply_tangential, b, bound, pr.tangential_force_control, target,
                area, self.self_compliance, q0=q_start, rtol=self.rtol,
                max_steps=s.max_steps, resync_every=s.resync_every,
                precondition=self.precondition_t, skip=skip)

        if not self.any_force:
            return cg()
        # Gross sliding under load control: q = mu p along F (reported, not iterated).
        limit = area * jnp.sum(bound)
        f_norm, direction = applied_load(target, pr.tangential_force_control)

        def slide():
            q = bound[None] * direction[:, None, None]
            w = self.apply_tangential(q) + b
            contact = bound > 0
            n = jnp.maximum(jnp.sum(contact), 1)
            # The rigid drift of a load-controlled direction has no stick cell to fix
            # it: the mean over the contact; a displacement-controlled one is given.
            mean = jnp.sum(jnp.where(contact[None], w, 0), axis=(1, 2)) / n
            delta = jnp.where(jnp.asarray(pr.tangential_force_control), mean, target)
            return TangentialState(
                shear=q, displacement=w - b, slip=w - delta[:, None, None], delta=delta,
                stick=jnp.zeros_like(contact), iterations=jnp.array(0),
                residual=jnp.zeros((), self.dtype), converged=jnp.array(True),
                applications=jnp.array(1))

        sliding = gross_sliding(f_norm, limit, self.rtol)
        # Under `vmap` the `cond` runs both branches for every member: the CG of a
        # sliding member (no static solution) stops at its first iterate (`skip`)
        # instead of running to `max_steps`. Unbatched, only one branch runs.
        return jax.lax.cond(sliding, slide, lambda: cg(skip=sliding))

    def round_(self, p, q, iterations, rounds):
        normal = self.solve_normal(self.h + self.uz_from_shear(q), p)
        tang = self.solve_tangential(normal.pressure, q)
        done = (normal.iterations == 0) & (tang.iterations == 0)
        ok = normal.converged & tang.converged
        return _RoundsState(
            pressure=normal.pressure, shear=tang.shear, normal=normal, tangential=tang,
            done=done & ok, iterations=iterations + normal.iterations + tang.iterations,
            rounds=rounds + 1, ok=ok)


class _RoundsState(eqx.Module):
    pressure: jax.Array
    shear: jax.Array
    normal: object  # normal.NormalState of the last round
    tangential: object  # tangential.TangentialState of the last round (or None)
    done: jax.Array  # the last round changed nothing
    iterations: jax.Array
    rounds: jax.Array
    ok: jax.Array  # both solves of the last round converged


class Rounds(AbstractStepSolver):
    """Alternating normal and tangential solves (see the module docs); any step.

    **Arguments:**

    - `rtol`: relative tolerance of both solves; `None`: `1e-8` in float64, `1e-5` in
      float32.
    - `max_steps`: iteration bound of each inner CG solve.
    - `max_rounds`: bound on the rounds of a coupled step.
    - `resync_every`: recompute displacements exactly this often in the CG solves.
    - `precondition`: the full-plane inverse preconditioner for the normal CG (and the
      x tangential CG on non-periodic grids); `False`: diagonal.
    """

    rtol: float | None = eqx.field(static=True, default=None)
    max_steps: int = eqx.field(static=True, default=2000)
    max_rounds: int = eqx.field(static=True, default=100)
    resync_every: int = eqx.field(static=True, default=25)
    precondition: bool = eqx.field(static=True, default=True)

    def step_limit(self) -> int:
        return self.max_rounds - 1  # the first round is `init`'s

    def setup(self, problem) -> _RoundsOperator:
        return _RoundsOperator(self, problem)

    def init(self, problem, k: _RoundsOperator, guess):
        if problem.nd == 0:
            normal = k.solve_normal(k.h, guess.normal)
            return _RoundsState(
                pressure=normal.pressure, shear=guess.shear, normal=normal,
                tangential=None, done=jnp.array(True), iterations=normal.iterations,
                rounds=jnp.array(1), ok=normal.converged)
        return k.round_(guess.normal, guess.shear, jnp.array(0), jnp.array(0))

    def terminate(self, problem, k, state):
        if problem.nd == 0 or not problem.coupled:
            return jnp.array(True), RESULTS.successful  # one round is exact
        return state.done, RESULTS.successful

    def step(self, problem, k: _RoundsOperator, state):
        if problem.nd == 0:
            return state  # never run: `terminate` is True
        return k.round_(state.pressure, state.shear, state.iterations, state.rounds)

    def postprocess(self, problem, k: _RoundsOperator, state, result):
        normal, tang = state.normal, state.tangential
        p = state.pressure
        if problem.nd == 0:
            return make_result(
                pressure=p, shear=state.shear, approach=normal.approach,
                delta_t=jnp.zeros((0,), k.dtype), slip=jnp.zeros_like(state.shear),
                stick=(p > 0) & (problem.friction > 0), sliding=jnp.array(False),
                iterations=state.iterations, rounds=state.rounds,
                residual=normal.residual, converged=normal.converged,
                result=RESULTS.where(normal.converged, result,
                                     RESULTS.max_steps_reached))
        approach, normal_residual = normal.approach, normal.residual
        if problem.coupled:
            # The normal conditions at the returned (p, q): the last normal solve saw
            # the shear before the last tangential solve (the same when `done`).
            setup = k.normal_setup.with_gap(k.h + k.uz_from_shear(state.shear))
            _, approach, normal_residual = setup.evaluate(normal.displacement, p)
        residual = jnp.maximum(normal_residual, tang.residual)
        converged = state.ok & (residual <= k.rtol) if problem.coupled else state.ok
        contact = p > 0
        stick = tang.stick
        sliding = jnp.any(contact) & ~jnp.any(stick)
        # The last round's tangential solve decided gross sliding on this pressure.
        gross = jnp.array(False)
        if any(problem.tangential_force_control):
            f_norm, _ = applied_load(problem.tangential_target,
                                     problem.tangential_force_control)
            limit = problem.operator.grid.cell_area * jnp.sum(problem.friction * p)
            gross = gross_sliding(f_norm, limit, k.rtol)
        # Rounds that changed nothing with an inner solve short of its tolerance:
        # that solve's steps ran out.
        failure = RESULTS.where(result == RESULTS.successful,
                                RESULTS.max_steps_reached, result)
        result = step_outcome(problem, p, converged, k.rtol, failure)
        return make_result(
            pressure=p, shear=state.shear, approach=approach,
            delta_t=tang.delta, slip=tang.slip + problem.previous_slip, stick=stick,
            sliding=sliding, gross_sliding=gross, iterations=state.iterations,
            rounds=state.rounds,
            residual=residual, converged=converged,
            result=result)
