"""`solve_axisymmetric`: a frictionless axisymmetric scene solved on rings.

A sphere, a cone, a blunted cone or any tip of revolution (`_indenter.py`)
pressed without friction on any material of the library is axisymmetric: its pressure
depends on the radius only. On `n` rings (`RingOperator`: closed-form influence of
annuli, a dense `(n, n)` matrix) a step costs a few `(n, n)` products instead of FFTs
of a 2-D grid. The time stepping is `jc.solve`'s: `lax.scan` over the scene's times,
the hereditary integral of `_history.py` on ring pressures (one compliance number and
one history displacement a step), a warm start extrapolated from the last two steps;
each step by `RingPolonskyKeer` with implicit derivatives (`_solver/rings.py`:
`jax.grad`, `jax.jvp`, `jax.jacfwd` alike).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from . import _validate
from ._history import check_time_options, history_for
from ._indenter import AbstractAxisymmetricIndenter
from ._loading import Force
from ._ring_operator import RingOperator, rings_to_grid
from ._scene import Scene, check_targets, normal_targets
from ._solution import RESULTS, Solution, stick_ratio
from ._solver.base import StepGuess
from ._solver.rings import RingPolonskyKeer, RingProblem, ring_step


# Rings of `solve_axisymmetric` by default.
DEFAULT_RINGS = 128


class RingSolution(eqx.Module):
    """Result of `solve_axisymmetric`. Leading axis: the scene's `times` (`nt`).

    - `times`: `(nt,)` [time]; `edges`: `(n + 1,)` ring edges [length].
    - `pressure`: `(nt, n)` ring pressures `p >= 0` [stress]; `contact`: `(nt, n)`.
    - `normal_force`: `(nt,)` `W = sum_i area_i p_i` [force]; `approach`: `(nt,)`
      rigid-body approach `delta_z` [length].
    - `contact_radius`: `(nt,)` outer edge of the outermost ring in contact [length]
      (0 without contact; the true radius lies within one ring width below it).
    - `converged`, `iterations`, `residual`, `result`: `(nt,)` per-step solver
      status, as in `jc.Solution`.
    - `edge_contact` (property): `(nt,)` the outermost ring is in contact (the contact
      may extend beyond the rings: enlarge `radius`).

    `to_solution(grid)` maps it onto a grid as a `jc.Solution`.
    """

    times: Float[Array, " nt"]
    edges: Float[Array, " n1"]
    pressure: Float[Array, "nt n"]
    contact: Bool[Array, "nt n"]
    normal_force: Float[Array, " nt"]
    approach: Float[Array, " nt"]
    contact_radius: Float[Array, " nt"]
    converged: Bool[Array, " nt"]
    iterations: Int[Array, " nt"]
    residual: Float[Array, " nt"]
    result: RESULTS

    @property
    def centres(self) -> Float[Array, " n"]:
        """Mid radii of the rings [length]."""
        return 0.5 * (self.edges[1:] + self.edges[:-1])

    @property
    def edge_contact(self) -> Bool[Array, " nt"]:
        """`(nt,)`: the outermost ring carries pressure."""
        return self.contact[..., -1]

    def to_solution(self, grid, centre=(0.0, 0.0), friction=0.0) -> Solution:
        """This solution on the cells of `grid` (a `jc.Grid`) as a `jc.Solution`
        (`method="rings"`): each cell takes the pressure of the ring holding its
        centre's distance from `centre` [length] (the indenter's axis). The forces,
        approaches and status are the rings' (not re-summed on the grid); no shear,
        no sliding; the contact sticks where `friction > 0` (nothing drives a slip),
        as in `jc.solve`'s frictionless steps."""
        dtype = self.pressure.dtype
        pressure = rings_to_grid(self.edges, self.pressure, grid, centre)
        nt = self.times.shape[0]
        contact = pressure > 0
        stick = contact & (jnp.asarray(friction) > 0)
        return Solution(
            times=self.times, pressure=pressure,
            shear=jnp.zeros((nt, 2) + grid.shape, dtype), contact=contact,
            stick=stick,
            normal_force=self.normal_force,
            approach=self.approach, tangential_force=jnp.zeros((nt, 2), dtype),
            tangential_displacement=jnp.zeros((nt, 2), dtype),
            stick_ratio=stick_ratio(contact, stick).astype(dtype),
            sliding=jnp.zeros((nt,), bool),
            converged=self.converged, iterations=self.iterations,
            rounds=jnp.ones((nt,), jnp.int32), residual=self.residual,
            result=self.result, fallbacks=jnp.zeros((nt,), jnp.int32),
            method="rings")


def ring_operator(scene: Scene, rings: int = DEFAULT_RINGS,
                  radius=None) -> RingOperator:
    """The `RingOperator` of `solve_axisymmetric` for `scene`: `rings` rings of equal
    width over `[0, radius]`, `radius` by default half the smaller side of the scene's
    grid (the domain the grid solver would use); in the grid's dtype. A traced radius
    or grid size scales the operator of the unit radius (`RingOperator.uniform`)."""
    if radius is None:
        size = scene.grid.size
        radius = (jnp.min(size) / 2 if _validate.is_traced(size)
                  else float(np.min(np.asarray(size))) / 2)
    return RingOperator.uniform(radius, rings, dtype=scene.grid.size.dtype)


def axisymmetric_support(scene: Scene) -> str | None:
    """`None` if the ring solver can solve `scene`, else why not (one sentence): it
    needs an axisymmetric indenter (`jc.AbstractAxisymmetricIndenter`), no
    tangential solve (`scene.tangential_directions == 0`) and a non-periodic grid."""
    if scene.tangential_directions != 0:
        return ("the scene has a tangential solve (friction with a tangential input "
                "or coupling); the ring solver is frictionless")
    if scene.grid.periodic:
        return "the grid is periodic; the ring solver is for an isolated contact"
    if not isinstance(scene.indenter, AbstractAxisymmetricIndenter):
        return (f"the indenter ({type(scene.indenter).__name__}) is not axisymmetric "
                "(a jc.Sphere, jc.Cone, jc.BluntedCone or jc.AxisymmetricProfile is)")
    return None


@eqx.filter_jit
def _solve_rings(scene: Scene, operator: RingOperator, solver: RingPolonskyKeer,
                 history_kind: str, scheme: str, runtime_checks: bool,
                 progress=None) -> RingSolution:
    dtype = scene.grid.size.dtype
    n = operator.rings
    times = scene.times.astype(dtype)
    material = jax.tree_util.tree_map(
        lambda leaf: leaf.astype(dtype)
        if isinstance(leaf, (jax.Array, np.ndarray))
        and jnp.issubdtype(leaf.dtype, jnp.floating) else leaf,
        scene.material)
    poisson = jnp.asarray(material.poisson, dtype)
    load_control = isinstance(scene.normal, Force)
    targets = normal_targets(scene, runtime_checks).astype(dtype)
    profile = scene.indenter.profile
    h0 = operator.mean(lambda r: profile(r).astype(dtype))
    hereditary = history_for(material, times, history_kind, scheme)
    steps_dt = jnp.concatenate([jnp.zeros((1,), dtype), jnp.diff(times)])
    no_shear = jnp.zeros((0, n), dtype)

    def step(carry, inputs):
        p_prev, p_prev2, h_state = carry
        target, k, dt = inputs
        prepared = hereditary.prepare(h_state, p_prev, k, dt)
        compliance = jnp.asarray(prepared.compliance, dtype)
        if prepared.traction is None:
            history = jnp.zeros((n,), dtype)
        else:
            history = operator.apply_normal(prepared.traction, poisson)
        # Warm start: the last two steps extrapolated, on the last contact.
        have_two = jnp.sum(p_prev2) > 0
        p_start = jnp.where(have_two, jnp.maximum(2 * p_prev - p_prev2, 0), p_prev)
        p_start = jnp.where(p_prev > 0, p_start, 0)
        problem = RingProblem(operator, compliance, poisson, h0, history, target,
                              load_control)
        res = ring_step(solver, problem, StepGuess(p_start, no_shear))
        h_state = hereditary.update(h_state, p_prev, res.pressure, k, dt)
        if progress is not None:
            jax.debug.callback(progress, k, times.shape[0], ordered=True)
        return (res.pressure, p_prev, h_state), res

    zeros = jnp.zeros((n,), dtype)
    init = (zeros, zeros, hereditary.init((n,), dtype))
    index = jnp.arange(times.shape[0])
    _, res = jax.lax.scan(step, init, (targets, index, steps_dt))
    contact = res.pressure > 0
    outer = jnp.where(contact, operator.edges[None, 1:], 0.0)
    return RingSolution(
        times=times, edges=operator.edges, pressure=res.pressure, contact=contact,
        normal_force=operator.force(res.pressure), approach=res.approach,
        contact_radius=jnp.max(outer, axis=-1), converged=res.converged,
        iterations=res.iterations, residual=res.residual, result=res.result)


def _raise_on_failure(sol: RingSolution) -> RingSolution:
    """`sol`, raising the message of its first failed step (concrete), or at run time
    (`error_if`) under a transformation."""
    failed = ~sol.converged
    first = jnp.argmax(failed)
    item = jax.tree.map(lambda v: v[first], sol.result)
    if _validate.is_traced(sol):
        return item.error_if(sol, jnp.any(failed))
    if bool(jnp.any(failed)):
        raise ValueError(f"{RESULTS[item]}\n(time step {int(first)} of "
                         f"{sol.times.shape[0]}; solve_axisymmetric(..., throw=False) "
                         "returns the flags instead)")
    return sol


def solve_axisymmetric(
    scene: Scene,
    *,
    rings: int = DEFAULT_RINGS,
    radius=None,
    operator: RingOperator | None = None,
    solver: RingPolonskyKeer | None = None,
    throw: bool = True,
    history: str = "auto",
    scheme: str = "constant",
    progress=None,
) -> RingSolution:
    """Solve a frictionless axisymmetric scene over its time axis on rings.

    **Main arguments:**

    - `scene`: a `jc.Scene` whose indenter is axisymmetric (`jc.Sphere`, whose
      `centre` only places it on the grid, `jc.Cone`, `jc.BluntedCone`,
      `jc.AxisymmetricProfile`)
      and with no tangential solve (`axisymmetric_support`). Any material, any normal
      program (force or approach; unloading and loss of contact included).

    **Other arguments:**

    - `rings`: the number of rings (default `DEFAULT_RINGS`, 128), of equal width over
      `[0, radius]`; `radius` [length]: default half the smaller side of the scene's
      grid. The contact must stay inside it (`RingSolution.edge_contact`). Or
    - `operator`: a prebuilt `RingOperator` (its edges and dtype are used as given).
    - `solver`: a `RingPolonskyKeer` (tolerance, iteration bound).
    - `throw`: raise on a step that did not converge (`True`, default), else return
      the flags.
    - `history`, `scheme`: as in `jc.solve` (the hereditary integral's form and the
      piecewise-constant or piecewise-linear time scheme); `progress`: `None` or a
      callable `f(step_index, n_steps)` called after each step.

    **Returns:** a `RingSolution` in the grid's dtype (`to_solution(grid)` maps it onto
    a grid). Jitted: new values of the same shapes reuse the compiled program.
    Derivatives with respect to every array of the scene (material, indenter, loads)
    are implicit (exact on the contact set), in forward and reverse mode.
    """
    if not isinstance(scene, Scene):
        raise TypeError(f"scene must be a jc.Scene, got {scene!r}")
    why = axisymmetric_support(scene)
    if why is not None:
        raise ValueError(f"solve_axisymmetric cannot solve this scene: {why}")
    if operator is None:
        operator = ring_operator(scene, rings, radius)
    elif not isinstance(operator, RingOperator):
        raise TypeError(f"operator must be a RingOperator, got {operator!r}")
    if solver is None:
        solver = RingPolonskyKeer()
    elif not isinstance(solver, RingPolonskyKeer):
        raise TypeError(f"solver must be a RingPolonskyKeer, got {solver!r}")
    check_time_options(throw, history, scheme)
    with _validate.clear_runtime_errors():
        runtime_checks = not check_targets(scene) and _validate.checks_traced_inputs()
        # Traced with its checks; a caller's trusted context arrives as runtime_checks.
        with _validate.trusted_inputs(False):
            sol = _solve_rings(scene, operator, solver, history, scheme,
                               runtime_checks, progress)
    return _raise_on_failure(sol) if throw else sol
