"""The step-solver protocol: one contact step as a problem, a solver and one driver.

Every contact solver of the package (normal, uncoupled tangential, coupled rounds, the
joint coupled iteration, and the wrappers that compose them) solves one `StepProblem`
and returns one `StepResult`, through the same four methods, as optimistix's
`AbstractRootFinder` does:

- `setup(problem)`: what stays fixed during the iteration (spectra, preconditioners,
  the effective gap); computed once, closed over by the loop body;
- `init(problem, setup, guess)`: the first iterate, from a `StepGuess`;
- `step(problem, setup, state)`: one iteration;
- `terminate(problem, setup, state)`: `(done, result)`: whether to stop, and why
  (`successful`, or the failure the solver gave up with, e.g. `stalled`);
- `postprocess(problem, setup, state, result)`: the output (a `StepResult`).

`run` is the ONE driver and the one way into a solver: it owns the `while_loop`,
counts the steps, bounds them by `solver.step_limit()` and, when the bound stops a
solver that had not terminated, hands `postprocess` `RESULTS.max_steps_reached`. A
solver never runs its own loop; a wrapper (`Fallback`, `LoadByDisplacement`,
`Rounds`) is a solver whose `init` or `step` runs other solvers through `run`. A
sub-solver may solve its own kind of problem (`TangentialCG`: a
`TangentialOperator`, at a known pressure) and return its own output; the driver is
the same.

All displacements in a step are `C K traction + history`, with `C` the step's
compliance (`1/G` elastic, `J(0)` or an effective one in a viscoelastic step) and
`history` a known field (zero for an elastic body).
"""

import abc
from typing import Any, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from .._results import RESULTS


class StepProblem(eqx.Module):
    """One contact step (elastic, or one viscoelastic step at a known history).

    **Arrays** (units in brackets):

    - `operator`: the `HalfSpace` (unit modulus) of the scene's coupling mode;
    - `compliance` [1/stress]: `C`; `poisson`, `friction`: scalars;
    - `gap`: `(nx, ny)` initial gap `h0` [length];
    - `history`: `(3, nx, ny)` known displacements `(u_x, u_y, u_z)` [length];
    - `normal_target`: the load `W` [force] or the approach [length];
    - `tangential_target`: `(nd,)` forces [force] or rigid tangential displacements
      [length] per direction;
    - `previous_slip`: `(nd, nx, ny)` slip before the step [length] (zeros for the total
      slip law).

    **Static**: `nd` (shear components solved: 0, 1 or 2), `coupled` (the coupling
    blocks are in use), `normal_force_control`, `tangential_force_control` (one bool
    per direction).
    """

    operator: Any
    compliance: Float[Array, ""]
    poisson: Float[Array, ""]
    friction: Float[Array, ""]
    gap: Float[Array, "nx ny"]
    history: Float[Array, "3 nx ny"]
    normal_target: Float[Array, ""]
    tangential_target: Float[Array, " nd"]
    previous_slip: Float[Array, "nd nx ny"]
    nd: int = eqx.field(static=True)
    coupled: bool = eqx.field(static=True)
    normal_force_control: bool = eqx.field(static=True)
    tangential_force_control: tuple[bool, ...] = eqx.field(static=True)

    @property
    def dtype(self):
        return self.gap.dtype

    def normal_part(self) -> "StepProblem":
        """The frictionless step of the same gap, history and normal target."""
        nx, ny = self.gap.shape
        return StepProblem(
            self.operator, self.compliance, self.poisson, self.friction, self.gap,
            self.history, self.normal_target, jnp.zeros((0,), self.dtype),
            jnp.zeros((0, nx, ny), self.dtype), 0, False, self.normal_force_control, ())

    def with_tangential(self, target, force_control) -> "StepProblem":
        """The same step with other tangential targets and controls."""
        return StepProblem(
            self.operator, self.compliance, self.poisson, self.friction, self.gap,
            self.history, self.normal_target, target, self.previous_slip, self.nd,
            self.coupled, self.normal_force_control, tuple(force_control))


class StepGuess(eqx.Module):
    """Warm start of a step: `pressure` `(nx, ny)` and `shear` `(nd, nx, ny)` [stress],
    `normal` (the pressure the normal solve starts from; defaults to `pressure`) and
    `delta_t` `(nd,)` (rigid tangential displacements [length]; zeros by default: the
    start of `LoadByDisplacement`'s search)."""

    pressure: Float[Array, "nx ny"]
    shear: Float[Array, "nd nx ny"]
    normal: Float[Array, "nx ny"]
    delta_t: Float[Array, " nd"]

    def __init__(self, pressure, shear, normal=None, delta_t=None):
        self.pressure = pressure
        self.shear = shear
        self.normal = pressure if normal is None else normal
        self.delta_t = (jnp.zeros(shear.shape[:1], shear.dtype) if delta_t is None
                        else delta_t)

    @classmethod
    def from_result(cls, result: "StepResult") -> "StepGuess":
        """Start where an earlier attempt at the same step ended."""
        return cls(result.pressure, result.shear, delta_t=result.delta_t)


class StepResult(eqx.Module):
    """The solution of one step.

    - `pressure` `(nx, ny)`, `shear` `(nd, nx, ny)` [stress];
    - `approach` [length], `delta_t` `(nd,)` rigid tangential displacements [length];
    - `slip` `(nd, nx, ny)`: total slip `u_t - delta_t` after the step [length];
    - `stick` `(nx, ny)`; `sliding`: contact but no stick cell; `gross_sliding`: the
      step was solved as gross sliding under tangential load control (the load at the
      friction limit, every cell's shear `mu p` along it; `tangential.gross_sliding`).
      A step can slip everywhere below the limit (two shear components: the slip
      directions fan out) and be `sliding` but not `gross_sliding`;
    - `iterations` (inner iterations, all solvers of a composition summed), `rounds`
      (normal/tangential rounds, or friction-bound updates of the joint iteration),
      `fallbacks` (secondary solvers run);
    - `residual`: the contact residual (relative; loads included); `converged`: the
      contact conditions hold at the solver's `rtol` (checked with exact
      displacements); `result`: a `RESULTS` value saying why not, or what was not met.
    """

    pressure: Float[Array, "nx ny"]
    shear: Float[Array, "nd nx ny"]
    approach: Float[Array, ""]
    delta_t: Float[Array, " nd"]
    slip: Float[Array, "nd nx ny"]
    stick: Bool[Array, "nx ny"]
    sliding: Bool[Array, ""]
    gross_sliding: Bool[Array, ""]
    iterations: Int[Array, ""]
    rounds: Int[Array, ""]
    residual: Float[Array, ""]
    converged: Bool[Array, ""]
    result: RESULTS
    fallbacks: Int[Array, ""]

    def replace(self, **changes) -> "StepResult":
        """A copy with the named fields changed."""
        names = list(changes)
        return eqx.tree_at(lambda r: [getattr(r, n) for n in names], self,
                           [changes[n] for n in names])


def make_result(*, pressure, shear, approach, delta_t, slip, stick, sliding, iterations,
                rounds, residual, converged, result=None,
                gross_sliding=False) -> StepResult:
    """A `StepResult`, its `result` `successful` / `max_steps_reached` from
    `converged` unless given; no fallback used."""
    if result is None:
        result = RESULTS.where(converged, RESULTS.successful, RESULTS.max_steps_reached)
    return StepResult(
        pressure=pressure, shear=shear, approach=jnp.asarray(approach),
        delta_t=delta_t, slip=slip, stick=stick, sliding=jnp.asarray(sliding),
        gross_sliding=jnp.asarray(gross_sliding),
        iterations=jnp.asarray(iterations, jnp.int32),
        rounds=jnp.asarray(rounds, jnp.int32), residual=jnp.asarray(residual),
        converged=jnp.asarray(converged), result=result,
        fallbacks=jnp.zeros((), jnp.int32))


class AbstractStepSolver(eqx.Module):
    """A contact step solver: `setup / init / step / terminate / postprocess`, run by
    `iterate` (see the module docs). Subclasses are final `eqx.Module`s whose fields
    are their options (tolerance, bounds, tuned constants with their defaults)."""

    def __check_init__(self):
        # The options common to the solvers, checked once here for every one of them.
        rtol = getattr(self, "rtol", None)
        if rtol is not None and not (0 < rtol < 1):
            raise ValueError(f"rtol must be in (0, 1), got {rtol!r}")
        for name in ("max_steps", "max_rounds", "resync_every", "evaluations"):
            value = getattr(self, name, 1)
            if isinstance(value, bool) or not (isinstance(value, int) and value >= 1):
                raise ValueError(f"{name} must be a positive integer, got {value!r}")
        precondition = getattr(self, "precondition", True)
        if not isinstance(precondition, bool):
            raise TypeError(f"precondition must be a bool, got {precondition!r}")

    @abc.abstractmethod
    def setup(self, problem: StepProblem) -> Any:
        """Loop invariants of the iteration (any Python object; closed over)."""

    @abc.abstractmethod
    def init(self, problem: StepProblem, setup, guess: StepGuess) -> Any:
        """The first iterate's state (a pytree)."""

    @abc.abstractmethod
    def step(self, problem: StepProblem, setup, state) -> Any:
        """One iteration: the next state."""

    @abc.abstractmethod
    def terminate(self, problem: StepProblem, setup,
                  state) -> tuple[Bool[Array, ""], RESULTS]:
        """`(done, result)`: `done` when the iteration should stop, `result` why:
        `successful`, or the failure the solver gave up with. The step bound is the
        driver's (`step_limit`): a solver does not test it."""

    @abc.abstractmethod
    def postprocess(self, problem: StepProblem, setup, state,
                    result: RESULTS) -> StepResult:
        """The output from the final state; `result`: the driver's verdict
        (`terminate`'s, or `max_steps_reached` when the step bound stopped it)."""

    @abc.abstractmethod
    def step_limit(self) -> int:
        """The most calls of `step` the driver makes."""

    def tolerance(self, dtype) -> float:
        """The relative tolerance in `dtype`: the solver's `rtol` field, or by default
        `1e-8` in float64 and `1e-5` in float32."""
        rtol = getattr(self, "rtol", None)
        if rtol is not None:
            return rtol
        return 1e-8 if jnp.finfo(dtype).bits >= 64 else 1e-5

    def supports(self, problem: StepProblem) -> str | None:
        """`None` if this solver can solve `problem`, else why not (one sentence)."""
        return None

    def run_loop(self, problem: StepProblem, setup, state):
        """`(final state, steps)`: the iteration from `state`, by default one `loop`
        (a solver with phases runs one `loop` a phase, the count carried on)."""
        return loop(self, problem, setup, state)

    def solve(self, problem: StepProblem, guess: StepGuess) -> StepResult:
        """Solve one step: `run(self, problem, guess).output`."""
        return run(self, problem, guess).output


class Run(NamedTuple):
    """What the driver returns: the solver's `output` (a `StepResult` for a step
    solver), its final `state` (for tests and benchmarks that read a solver's own
    statistics), the `steps` taken and the `result` handed to `postprocess`."""

    output: Any
    state: Any
    steps: Int[Array, ""]
    result: RESULTS


def run(solver: AbstractStepSolver, problem, guess, *, setup=None) -> Run:
    """THE driver: `setup` (unless given: the loop invariants already built, e.g. one
    operator for several gaps), `init`, then `step` while not `terminate` and fewer
    than `solver.step_limit()` steps, then `postprocess` with the result:
    `terminate`'s, or `max_steps_reached` if the bound stopped the loop first.

    A `while_loop` rather than a `scan` or a `cond`: under `vmap` the batched loop runs
    its body only while some member needs it, and a wrapper whose `init` already
    converged (e.g. `Fallback`) costs nothing more.
    """
    why = solver.supports(problem)
    if why is not None:
        raise ValueError(f"{type(solver).__name__} cannot solve this step: {why}")
    if setup is None:
        setup = solver.setup(problem)
    state, steps = solver.run_loop(problem, setup, solver.init(problem, setup, guess))
    done, result = solver.terminate(problem, setup, state)
    result = RESULTS.where(done, result, RESULTS.max_steps_reached)
    return Run(solver.postprocess(problem, setup, state, result), state, steps, result)


def loop(solver: AbstractStepSolver, problem, setup, state, steps=0):
    """The driver's `while_loop`: `step` while not `terminate` and fewer than
    `solver.step_limit()` steps in all (`steps` already taken by an earlier phase);
    `(final state, steps)`."""
    limit = solver.step_limit()

    def cond(carry):
        state, n = carry
        return (~solver.terminate(problem, setup, state)[0]) & (n < limit)

    def body(carry):
        state, n = carry
        return solver.step(problem, setup, state), n + 1

    return jax.lax.while_loop(cond, body, (state, jnp.asarray(steps, jnp.int32)))


def step_outcome(problem: StepProblem, pressure, converged, rtol,
                 failure=RESULTS.max_steps_reached) -> RESULTS:
    """The `RESULTS` value of a step: `failure` if not `converged`; a converged step
    whose load (that of its load-controlled directions, `applied_load`)
    exceeds the friction limit `mu W` (beyond the `rtol / 2` of
    `tangential.gross_sliding`) carries `mu W`, not the load asked for:
    `tangential_load_above_friction_limit`; else `successful`."""
    result = RESULTS.where(converged, RESULTS.successful, failure)
    if problem.nd > 0 and any(problem.tangential_force_control):
        area = problem.operator.grid.cell_area
        limit = area * jnp.sum(problem.friction * pressure)
        load, _ = applied_load(problem.tangential_target,
                               problem.tangential_force_control)
        above = load > limit * (1 + 0.5 * rtol)
        result = RESULTS.where(
            converged & above, RESULTS.tangential_load_above_friction_limit, result)
    return result


def applied_load(target, force_control):
    """`(magnitude, direction)` of the tangential load asked for: the `(nd,)` targets of
    the load-controlled directions [force] (a displacement-controlled direction adds
    nothing), its norm and unit vector (zeros for no load). The norm is safe at zero
    (no NaN derivative for a load program that starts at zero).

    Gross sliding is decided on this load alone: as a load-controlled direction drives
    the indenter without bound, the slip of every cell turns along it, whatever the
    displacement-controlled directions hold."""
    load = jnp.where(jnp.asarray(force_control), target, 0.0)
    square = jnp.sum(load * load)
    positive = square > 0
    magnitude = jnp.where(positive, jnp.sqrt(jnp.where(positive, square, 1.0)), 0.0)
    direction = jnp.where(positive, load / jnp.where(positive, magnitude, 1.0), 0.0)
    return magnitude, direction


def safe_div(a, b):
    """`a / b`, and 0 where `b = 0` (no NaN in either branch's gradient)."""
    ok = b != 0
    return jnp.where(ok, a / jnp.where(ok, b, 1), jnp.zeros_like(a))
