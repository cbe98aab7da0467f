"""`jc.solve`: the entry point. Time stepping over the scene's `times` with
`lax.scan`."""

import sys
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from . import _validate
from ._history import check_time_options, history_for, worst_time_step
from ._loading import Force
from ._operator import HalfSpace
from ._scene import Scene, check_targets, normal_targets, tangential_targets
from ._solution import RESULTS, Solution, stick_ratio
from ._solve_rings import axisymmetric_support, solve_axisymmetric
from ._solver.base import AbstractStepSolver, StepGuess, StepProblem
from ._solver.fallback import Fallback
from ._solver.implicit import ImplicitAdjoint, differentiable_step, empty_seed
from ._solver.joint import JointPCG
from ._solver.load_search import LoadByDisplacement
from ._solver.normal import hertzian_guess
from ._solver.rings import RingPolonskyKeer
from ._solver.rounds import Rounds


class _Controls(eqx.Module):
    """What a scene asks of every step (static): shear components solved, coupling,
    and which targets are loads."""

    nd: int = eqx.field(static=True)
    coupled: bool = eqx.field(static=True)
    normal_force_control: bool = eqx.field(static=True)
    tangential_force_control: tuple[bool, ...] = eqx.field(static=True)


def default_solver(controls: _Controls, **options) -> AbstractStepSolver:
    """The step solver `jc.solve` compiles when none is given, from what the scene
    needs: `Rounds` without a coupled tangential solve (one round is exact); `JointPCG`
    with one. The fallbacks of `robust_solver` are compiled only for a concrete
    solution that still has a failed step. `options`: `rtol`, `max_steps`,
    `max_rounds`, `resync_every`, `precondition` as given to `jc.solve` (those left
    out: the solvers' own defaults)."""
    if controls.nd == 0 or not controls.coupled:
        return Rounds(**options)
    return JointPCG(**{name: value for name, value in options.items()
                       if name != "max_rounds"})


def robust_solver(controls: _Controls, **options) -> AbstractStepSolver | None:
    """What a concrete coupled solution with a failed step is solved again with, whole:
    the default `JointPCG` falling back on `Rounds` (started where the joint iteration
    gave up) and, under tangential load control, on `LoadByDisplacement(JointPCG())`
    (a root search on the displacement); `None` without a coupled tangential solve
    (nothing more to try). `options`: those of `default_solver`."""
    joint = default_solver(controls, **options)
    if not isinstance(joint, JointPCG):
        return None
    solver = Fallback(joint, Rounds(**options))
    if not any(controls.tangential_force_control):
        return solver
    return Fallback(solver, LoadByDisplacement(joint))


def operator_for(scene: Scene, nd: int) -> HalfSpace:
    if nd == 0:
        return HalfSpace(scene.grid, "normal")
    coupling = scene.coupling
    return HalfSpace(scene.grid, coupling, tangential_y=nd == 2)


def history_displacement(operator, poisson, traction, nd):
    """`K1 traction` for the history traction `(q_x, q_y, p)` (unit modulus)."""
    if nd == 0:
        uz = operator.apply_normal(traction[2], poisson)
        zeros = jnp.zeros_like(uz)
        return jnp.stack([zeros, zeros, uz])
    return operator.apply(traction, poisson)


def _print_progress(step, n_steps):
    step = int(step)
    every = max(1, n_steps // 20)
    if step % every == 0 or step == n_steps - 1:
        print(f"jaxcontact: step {step + 1}/{n_steps}", file=sys.stderr, flush=True)


@eqx.filter_jit
def _solve(scene: Scene, operator: HalfSpace, controls: _Controls,
           solver: AbstractStepSolver, adjoint: ImplicitAdjoint, throw: bool,
           history_kind: str, scheme: str, progress=None,
           runtime_checks: bool = True) -> Solution:
    grid = scene.grid
    dtype = grid.size.dtype
    nd = controls.nd
    nx, ny = grid.shape
    times = scene.times.astype(dtype)
    h0 = scene.indenter.gap(grid).astype(dtype)
    # The grid's dtype is the solve's: a float64 material (or any floating leaf) on a
    # float32 grid is cast, so the time-stepping carry keeps one dtype.
    material = jax.tree_util.tree_map(
        lambda leaf: leaf.astype(dtype)
        if isinstance(leaf, (jax.Array, np.ndarray))
        and jnp.issubdtype(leaf.dtype, jnp.floating)
        else leaf,
        scene.material,
    )
    poisson = material.poisson
    friction = scene.friction.astype(dtype)
    area = grid.cell_area

    w_targets = normal_targets(scene, runtime_checks).astype(dtype)
    t_targets, _ = tangential_targets(scene, nd)
    t_targets = t_targets.astype(dtype)
    use_total_slip = scene.slip == "total"
    hereditary = history_for(material, times, history_kind, scheme)
    steps_dt = jnp.concatenate([jnp.zeros((1,), dtype), jnp.diff(times)])
    if controls.coupled and nd > 0:
        # The joint solver's layout, built once here rather than in every step.
        operator = operator.with_transposed_spectra()

    def step(carry, inputs):
        p_prev, q_prev, s_prev, p_prev2, q_prev2, h_state, seed = carry
        w_target, t_target, k, dt = inputs
        tau_prev = jnp.zeros((3, nx, ny), dtype).at[:nd].set(q_prev).at[2].set(p_prev)
        prepared = hereditary.prepare(h_state, tau_prev, k, dt)
        compliance = prepared.compliance.astype(dtype)
        if prepared.traction is None:
            history = jnp.zeros((3, nx, ny), dtype)
        else:
            history = history_displacement(operator, poisson, prepared.traction, nd)
        # Warm start: linear extrapolation of the last two steps (exact for a
        # solution that changes linearly along the path), clipped to p >= 0.
        have_two = jnp.sum(p_prev2) > 0
        p_start = jnp.where(have_two, jnp.maximum(2 * p_prev - p_prev2, 0), p_prev)
        p_start = jnp.where(p_prev > 0, p_start, 0)
        q_start = jnp.where(have_two, 2 * q_prev - q_prev2, q_prev)
        guess = p_start
        if controls.normal_force_control:
            # A `cond`: the Hertz guess (a 60-step bisection, ~0.9 ms at 105^2) is only
            # needed while there is no pressure to start from.
            e_star = 2 / (compliance * (1 - poisson))
            guess = jax.lax.cond(
                jnp.sum(p_start) > 0, lambda: p_start,
                lambda: hertzian_guess(h0 + history[2], w_target, e_star, area))
        previous_slip = jnp.zeros_like(s_prev) if use_total_slip else s_prev
        problem = StepProblem(
            operator, compliance, jnp.asarray(poisson, dtype), friction, h0, history,
            w_target, t_target, previous_slip, nd, controls.coupled,
            controls.normal_force_control, controls.tangential_force_control)
        res, seed = differentiable_step(
            solver, problem, StepGuess(p_start, q_start, normal=guess), seed,
            adjoint=adjoint, throw=throw)
        if progress is not None:
            jax.debug.callback(progress, k, times.shape[0], ordered=True)
        tau_new = (jnp.zeros((3, nx, ny), dtype).at[:nd].set(res.shear)
                   .at[2].set(res.pressure))
        h_state = hereditary.update(h_state, tau_prev, tau_new, k, dt)
        return (res.pressure, res.shear, res.slip, p_prev, q_prev, h_state, seed), res

    zeros_p = jnp.zeros((nx, ny), dtype)
    zeros_q = jnp.zeros((nd, nx, ny), dtype)
    init = (zeros_p, zeros_q, zeros_q, zeros_p, zeros_q,
            hereditary.init((3, nx, ny), dtype), empty_seed(zeros_p, zeros_q))
    steps = jnp.arange(times.shape[0])
    _, res = jax.lax.scan(step, init, (w_targets, t_targets, steps, steps_dt))

    nt = times.shape[0]
    shear = jnp.zeros((nt, 2, nx, ny), dtype).at[:, :nd].set(res.shear)
    delta_t = jnp.zeros((nt, 2), dtype).at[:, :nd].set(res.delta_t)
    contact = res.pressure > 0
    sol = Solution(
        times=times,
        pressure=res.pressure,
        shear=shear,
        contact=contact,
        stick=res.stick,
        normal_force=area * jnp.sum(res.pressure, axis=(1, 2)),
        approach=res.approach,
        tangential_force=area * jnp.sum(shear, axis=(2, 3)),
        tangential_displacement=delta_t,
        stick_ratio=stick_ratio(contact, res.stick).astype(dtype),
        # No friction: no tangential traction, nothing slides (as for a concrete zero,
        # which solves no tangential step, when `friction` is traced).
        sliding=res.sliding & (nd > 0) & (friction > 0),
        converged=res.converged,
        iterations=res.iterations,
        rounds=res.rounds,
        residual=res.residual,
        result=res.result,
        fallbacks=res.fallbacks,
    )
    return sol


def _raise_on_failure(sol: Solution) -> Solution:
    """`sol`, raising the message of the first step's failure (`RESULTS`) if any step
    did not converge: at once for a concrete solution (no host callback in the
    compiled program), at run time (`eqx.error_if`) under `jit`, `vmap` or `grad`."""
    failed = ~sol.converged
    first = jnp.argmax(failed)
    item = jax.tree.map(lambda v: v[first], sol.result)
    if _validate.is_traced(sol):
        return item.error_if(sol, jnp.any(failed))
    if bool(jnp.any(failed)):
        raise ValueError(f"{RESULTS[item]}\n(time step {int(first)} of "
                         f"{sol.times.shape[0]}; jc.solve(..., throw=False) returns "
                         "the flags instead)")
    return sol


def warn_unstable_steps(material, times):
    """`jc.TimeStepWarning` when a step makes the piecewise-constant scheme unstable
    (`jc.time_step_amplification` > 1). Concrete inputs only: nothing is checked
    inside a transformation."""
    if _validate.is_traced(times) or _validate.is_traced(material):
        return
    radius, worst = worst_time_step(material, times)
    if radius > 1.0:
        warnings.warn(
            f"a time step of {worst:.3g} is too long for the piecewise-constant scheme "
            f"with this material (its step-to-step amplification is {radius:.3g} > 1): "
            f'the solution oscillates from step to step. Use scheme="linear" or '
            f"shorter steps.", _validate.TimeStepWarning, stacklevel=3)


def _ring_solver(scene: Scene, solver, operator, adjoint, options: dict
                 ) -> RingPolonskyKeer | None:
    """The ring solver `jc.solve` runs `scene` with, or `None`: the grid. A
    `jc.RingPolonskyKeer` given as `solver` (the scene must qualify,
    `axisymmetric_support`), or by default (no `solver`, no `operator`) a qualifying
    scene's, configured by `rtol`, `max_steps` and `precondition` in `options`.
    An `operator` selects the grid; what configures the grid only (`adjoint`,
    `max_rounds`, `resync_every`) is refused on rings rather than ignored."""
    if isinstance(solver, RingPolonskyKeer):
        why = axisymmetric_support(scene)
        if why is not None:
            raise ValueError(f"jc.RingPolonskyKeer cannot solve this scene: {why}")
        if operator is not None:
            raise TypeError("operator= is a grid's jc.HalfSpace; "
                            "jc.RingPolonskyKeer lays its own rings")
        if adjoint is not None:
            raise TypeError("adjoint= configures the grid's implicit adjoint; "
                            "jc.RingPolonskyKeer has its own implicit derivatives "
                            "(reverse and forward mode alike): leave adjoint out")
        return solver
    if solver is not None or operator is not None:
        return None
    if axisymmetric_support(scene) is not None:
        return None
    grid_only = [name for name, value in (("adjoint", adjoint),
                                          ("max_rounds", options["max_rounds"]),
                                          ("resync_every", options["resync_every"]))
                 if value is not None]
    if grid_only:
        raise TypeError(
            f"{', '.join(grid_only)} configure{'s' if len(grid_only) == 1 else ''} "
            f"the grid solver; this scene "
            f"(frictionless, axisymmetric indenter) runs on rings by default, with "
            f"implicit derivatives of their own (reverse and forward mode alike): "
            f"leave {'it' if len(grid_only) == 1 else 'them'} out, or pass "
            f"solver=jc.Rounds() to solve it on the grid")
    return RingPolonskyKeer(**{name: options[name]
                               for name in ("rtol", "max_steps", "precondition")
                               if options[name] is not None})


def solve(
    scene: Scene,
    *,
    solver: AbstractStepSolver | None = None,
    adjoint: ImplicitAdjoint | None = None,
    throw: bool = True,
    rtol: float | None = None,
    max_steps: int | None = None,
    max_rounds: int | None = None,
    resync_every: int | None = None,
    precondition: bool | None = None,
    history: str = "auto",
    scheme: str = "constant",
    operator: HalfSpace | None = None,
    progress=None,
) -> Solution:
    """Solve a contact scene over its time axis.

    **Main arguments:**

    - `scene`: a `jc.Scene`.

    **Other arguments:**

    - `solver`: the step solver, an object (`jc.JointPCG()`, `jc.Rounds()`,
      `jc.Fallback(primary, secondary)`, `jc.LoadByDisplacement(solver)`,
      `jc.RingPolonskyKeer()`, ...). `None` (default): chosen from the scene.
      A frictionless scene (no tangential solve) with an axisymmetric indenter
      (`jc.Sphere`, `jc.Cone`, `jc.BluntedCone`, `jc.AxisymmetricProfile`) on a
      non-periodic grid runs on rings (`jc.RingPolonskyKeer`, `sol.method ==
      "rings"`): `DEFAULT_RINGS` rings over half the grid's smaller side, second
      order in the ring width, milliseconds a history, the pressures interpolated
      onto the grid's cells; its derivatives are its own implicit ones, not
      `adjoint`'s. Any other scene runs on the grid (`sol.method == "grid"`): the
      rounds (exact in one) without coupling; with coupling the joint iteration. A
      grid solver given as `solver` (e.g. `jc.Rounds()`) or an `operator` solves an
      axisymmetric scene on the grid (`adjoint`, `max_rounds` and `resync_every`,
      the grid's only, raise for a scene on rings). A concrete coupled solution
      that still has a failed step is solved again, whole, with the rounds as a
      fallback and, under tangential load control, a root search over the
      displacement (`robust_solver`), compiled only then; under `jit`, `vmap` or
      `grad` there is no second solve (the flags, or `throw`, report the failure).
    - `rtol`, `max_steps`, `max_rounds`, `resync_every`, `precondition`: options of
      the default solver (only without `solver`; a solver object carries its own):
      relative tolerance of every contact solve (`None`: `1e-8` in float64, `1e-5` in
      float32), the iteration bound of each CG solve (2000 on the grid, 1000 on
      rings), the bound on the normal/tangential rounds (100), exact displacements
      every this many iterations (25), the preconditioners (`True`: the full-plane
      inverses on the grid, the rings' exact inverse). `max_rounds` and
      `resync_every` are the grid's only: given for a scene that runs on rings by
      default, they raise (pass `solver=jc.Rounds(...)`).
    - `adjoint`: how the grid's gradients are computed, a `jc.ImplicitAdjoint`
      (default one); the rings differentiate themselves and refuse it.
    - `throw`: `True` (default): raise when a step does not converge, with the
      `jc.RESULTS` message of the first such step (at run time, also under `jit`);
      `False`: return the flags (`converged`, `result`) and carry on. A
      non-converged adjoint raises with `throw=True` and gives NaN gradients with
      `False`.
    - `history`: `"auto"` (default: none for an elastic material, the O(Nt) recursion
      for a material with a creep series, the direct sum otherwise), `"recursive"` or
      `"direct"` (the O(Nt^2) sum of the paper, Eqs. 12-13; a reference).
    - `scheme`: `"constant"` (default; tractions piecewise constant in time, the
      paper's scheme) or `"linear"` (piecewise linear within each step: higher order
      in the time step).
    - `operator`: a prebuilt `jc.HalfSpace` to reuse across calls (must match the
      coupling the scene needs; built here if omitted). Given, the scene is solved
      on the grid.
    - `progress`: `None` (default: silent), `True` (print `step k/nt` to stderr about
      every 5 % of the steps, as the steps complete), or a callable
      `f(step_index, n_steps)` called after each step (through `jax.debug.callback`).

    **Returns:** a `jc.Solution`; `result` says per step how it ended (`jc.RESULTS`:
    `successful`, or why not, or `tangential_load_above_friction_limit` for a load
    beyond `mu W`, which slides and is not raised).

    The scene decides what runs: no tangential solve when `friction` is zero or there is
    no tangential input and no coupling; no y solve unless there is a y input or the
    coupling is `"full"`; an elastic material carries no history.
    """
    if not isinstance(scene, Scene):
        raise TypeError(f"scene must be a jc.Scene, got {scene!r}")
    options = dict(rtol=rtol, max_steps=max_steps, max_rounds=max_rounds,
                   resync_every=resync_every, precondition=precondition)
    given = [name for name, value in options.items() if value is not None]
    if solver is not None:
        if not isinstance(solver, AbstractStepSolver):
            raise TypeError(f"solver must be a jaxcontact step solver (e.g. "
                            f"jc.JointPCG()), got {solver!r}")
        if given:
            raise TypeError(
                f"{', '.join(given)} configure the default solver; with solver= pass "
                f"them to the solver object (e.g. jc.JointPCG(rtol=...))")
    for name in ("max_steps", "max_rounds", "resync_every"):
        if options[name] is not None:
            _validate.positive_int(name, options[name])  # TypeError / ValueError
    if precondition is not None and not isinstance(precondition, bool):
        raise TypeError(f"precondition must be a bool, got {precondition!r}")
    if adjoint is not None and not isinstance(adjoint, ImplicitAdjoint):
        raise TypeError(f"adjoint must be a jc.ImplicitAdjoint, got {adjoint!r}")
    check_time_options(throw, history, scheme)
    if rtol is not None:
        _validate.tolerance("rtol", rtol)
    if scheme == "constant":
        warn_unstable_steps(scene.material, scene.times)
    if progress is True:
        progress = _print_progress
    elif progress is False:
        progress = None
    elif progress is not None and not callable(progress):
        raise TypeError(
            f"progress must be None, a bool or a callable, got {progress!r}")
    ring_solver = _ring_solver(scene, solver, operator, adjoint, options)
    if adjoint is None:
        adjoint = ImplicitAdjoint()
    if ring_solver is not None:
        rings = solve_axisymmetric(scene, solver=ring_solver, throw=False,
                                   history=history, scheme=scheme, progress=progress)
        sol = rings.to_solution(scene.grid, scene.indenter.centre, scene.friction)
        return _raise_on_failure(sol) if throw else sol
    if operator is not None:
        if not isinstance(operator, HalfSpace):
            raise TypeError(f"operator must be a jc.HalfSpace, got {operator!r}")
        g_op, g_sc = operator.grid, scene.grid
        if g_op.shape != g_sc.shape or g_op.periodic != g_sc.periodic:
            raise ValueError(
                f"operator was built for a {g_op.shape} grid "
                f"(periodic={g_op.periodic}), the scene's grid is {g_sc.shape} "
                f"(periodic={g_sc.periodic})"
            )
        n_dir = scene.tangential_directions
        if n_dir > 0 and (operator.coupling != scene.coupling
                          or (n_dir == 2 and not operator.tangential_y)):
            raise ValueError(
                f"operator has coupling={operator.coupling!r}, tangential_y="
                f"{operator.tangential_y}; the scene needs coupling={scene.coupling!r}"
                f"{' with tangential_y=True' if n_dir == 2 else ''}"
            )
    nd = scene.tangential_directions
    _, force_control = tangential_targets(scene, nd)
    # An incompressible body (nu = 0.5 exactly, concrete) has no normal-tangential
    # coupling (the blocks scale with 1 - 2 nu): solved as uncoupled, where one round
    # is exact (the joint iteration ran to its step bound on such steps).
    poisson = scene.material.poisson
    incompressible = not _validate.is_traced(poisson) and float(poisson) == 0.5
    controls = _Controls(
        nd=nd,
        coupled=nd > 0 and scene.coupling != "none" and not incompressible,
        normal_force_control=isinstance(scene.normal, Force),
        tangential_force_control=tuple(bool(f) for f in force_control),
    )
    retry = None
    if solver is None:
        defaults = {name: value for name, value in options.items() if value is not None}
        solver = default_solver(controls, **defaults)
        retry = robust_solver(controls, **defaults)
    if operator is None:
        operator = operator_for(scene, nd)
    # A failed run-time check (traced bad input, or a step that did not converge with
    # `throw`) raises a ValueError whose first line is its message. The compiled solve
    # is traced with its checks (`trusted_inputs(False)`): a caller's trusted context
    # reaches it only as the static `runtime_checks`.
    with _validate.clear_runtime_errors():
        runtime_checks = not check_targets(scene) and _validate.checks_traced_inputs()
        args = (scene, operator, controls, solver, adjoint, throw, history, scheme,
                progress, runtime_checks)
        with _validate.trusted_inputs(False):
            sol = _solve(*args)
            if not _validate.is_traced(sol):
                jax.block_until_ready(sol)
                if retry is not None and not bool(np.all(sol.converged)):
                    # Compiled only now: the root search doubles the compile time.
                    sol = jax.block_until_ready(_solve(*args[:3], retry, *args[4:]))
    return _raise_on_failure(sol) if throw else sol
