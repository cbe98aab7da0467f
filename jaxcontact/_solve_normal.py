"""`jc.solve_normal`: frictionless normal indentation of an elastic half-space."""

import contextlib
import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from . import _validate
from ._grid import Grid
from ._indenter import AbstractIndenter, Sphere, as_indenter
from ._loading import Displacement, Force
from ._material.base import AbstractMaterial, check_in_dtype
from ._operator import HalfSpace
from ._results import RESULTS
from ._scene import (
    check_finite_in_dtype,
    expected_contact_radius,
    expected_surface_contact,
    warn_if_surface_too_large,
    warn_if_too_large,
)
from ._solution import edge_ring
from ._solver.base import StepGuess, StepProblem, run
from ._solver.normal import PolonskyKeer, hertzian_guess


class NormalSolution(eqx.Module):
    """Result of `jc.solve_normal`.

    - `pressure`: `(nx, ny)` contact pressure `p >= 0` [stress].
    - `gap`: `(nx, ny)` gap `h0 + u_z - delta` after deformation [length] (`~0` in
      contact, `>= 0` outside).
    - `contact`: `(nx, ny)` boolean mask, `p > 0`.
    - `approach`: rigid-body approach `delta` of the indenter [length].
    - `normal_force`: total load `W = A sum(p)` [force].
    - `displacement`: `(nx, ny)` normal surface displacement `u_z` [length].
    - `iterations`, `residual`, `converged`: solver statistics (see `jc.PolonskyKeer`).
    - `result`: how the solve ended, a `jc.RESULTS` (`successful`, or
      `max_steps_reached` with its message), as `jc.Solution.result` for one step.
    - `applications`: number of operator applications (padded FFT convolutions) used;
      the preconditioner's transforms (one unpadded pair per iteration, a quarter of
      the size) are not counted.
    - `edge_contact` (property): contact reaches the outer ring of cells (on a
      non-periodic grid: the contact is truncated by the domain; enlarge the grid).
    """

    pressure: Float[Array, "nx ny"]
    gap: Float[Array, "nx ny"]
    contact: Bool[Array, "nx ny"]
    approach: Float[Array, ""]
    normal_force: Float[Array, ""]
    displacement: Float[Array, "nx ny"]
    iterations: Int[Array, ""]
    residual: Float[Array, ""]
    converged: Bool[Array, ""]
    applications: Int[Array, ""]
    result: RESULTS

    @property
    def edge_contact(self) -> Bool[Array, ""]:
        """Some contact cell lies in the outer ring of cells of the grid."""
        return edge_ring(self.contact)

    def to_xarray(self, grid, *, material=None, indenter=None, units=None, attrs=None):
        """This solution as a labelled `xarray.Dataset` (see `jc.Solution.to_xarray`).

        **Arguments:**

        - `grid`: the `jc.Grid` that was solved (for the `x`, `y` coordinates).
        - `material`, `indenter`: optional, recorded as JSON attributes.
        - `units`: unit labels, `None` / `"SI"` (m, N, Pa) or a dict (see
          `jc.Solution.to_xarray`); nothing is converted.
        - `attrs`: extra global attributes.

        **Returns:** a Dataset with dimensions `x`, `y` (cell centres [length]); the
        fields `pressure`, `gap`, `contact`, `displacement` on `(x, y)` and the
        scalars `approach`, `normal_force`, `iterations`, `residual`, `converged`,
        `applications`, `edge_contact` and `result` (the `jc.RESULTS` code, its
        names in `flag_meanings`), each with `units` and `long_name`.
        """
        from ._dataset import normal_dataset

        return normal_dataset(self, grid, material=material, indenter=indenter,
                              units=units, attrs=attrs)


# A nested start: the coarsest level has at least this many cells a side, and the
# coarse levels are solved to this tolerance (benchmarks/notes/normal_reentry.md).
NESTED_COARSEST = 128
NESTED_RTOL = 1e-4
_STARTS = ("auto", "hertz", "nested")


def nested_levels(shape) -> int:
    """How many times a nested start halves the grid `shape`: while both sides are
    even and the halved grid keeps `NESTED_COARSEST` cells a side."""
    nx, ny = shape
    levels = 0
    while nx % 2 == 0 and ny % 2 == 0 and min(nx, ny) // 2 >= NESTED_COARSEST:
        nx, ny = nx // 2, ny // 2
        levels += 1
    return levels


def _block_mean(a):
    """The mean over 2 x 2 blocks of cells: `(nx, ny) -> (nx / 2, ny / 2)`."""
    nx, ny = a.shape
    return a.reshape(nx // 2, 2, ny // 2, 2).mean(axis=(1, 3))


def _repeat(p):
    """Each cell's value on its 2 x 2 finer cells (the same pressure, the same load)."""
    return jnp.repeat(jnp.repeat(p, 2, axis=0), 2, axis=1)


def coarse_grids(grid: Grid, levels: int) -> tuple[Grid, ...]:
    """The grids of a nested start on `grid`: halved `levels` times (the same domain),
    coarsest first."""
    nx, ny = grid.shape
    shapes = [(nx >> k, ny >> k) for k in range(levels, 0, -1)]
    # A concrete size stays concrete under a jit (so its operators can be cached).
    concrete = (contextlib.nullcontext() if _validate.is_traced(grid.size)
                else jax.ensure_compile_time_eval())
    with concrete:
        return tuple(Grid(shape, grid.size, periodic=grid.periodic) for shape in shapes)


def normal_operator(grid: Grid) -> HalfSpace:
    """`HalfSpace(grid, "normal")`, cached for concrete grids (its spectra cost about
    one solve iteration to build: 23 ms at 256^2, 93 ms at 512^2 on 2 cores)."""
    if _validate.is_traced(grid.size):
        return HalfSpace(grid, "normal")
    size = np.asarray(grid.size)
    return _cached_operator(grid.shape, grid.periodic, tuple(size.tolist()),
                            str(size.dtype))


@functools.lru_cache(maxsize=8)
def _cached_operator(shape, periodic, size, dtype):
    # Concrete arrays even when called while tracing (a grid closed over by a jit).
    with jax.ensure_compile_time_eval():
        grid = Grid(shape, jnp.asarray(size, dtype), periodic=periodic)
        return HalfSpace(grid, "normal")


def _nested_start(coarse_ops, h, compliance, poisson, target, load_control, solver):
    """A start for the solve on the grid of `h`: the same problem on the coarser
    grids of `coarse_ops` (`HalfSpace`s, coarsest first; the gap averaged over
    2 x 2 blocks), solved to `NESTED_RTOL` from the default start, its pressure
    repeated 2 x 2 as the start of the next finer level, up to this grid's."""
    gaps = [h]
    for _ in coarse_ops:
        gaps.append(_block_mean(gaps[-1]))
    coarse = PolonskyKeer(
        rtol=max(NESTED_RTOL, solver.tolerance(h.dtype)), max_steps=solver.max_steps,
        resync_every=solver.resync_every, precondition=solver.precondition,
        mixed_precision=solver.mixed_precision)
    p = None
    for level, gap in zip(coarse_ops, gaps[:0:-1]):  # coarsest first
        state, _ = _solve_state(level, gap, compliance, poisson, target,
                                load_control, coarse, p)
        p = _repeat(state.pressure)
    return p


def _solve_state(operator, h, compliance, poisson, target, load_control, solver,
                 p0=None, coarse_ops=()):
    """The solve's `(NormalState, RESULTS)`, through the solver driver; `p0`: the
    starting pressure, default a nested start over the coarser grids of `coarse_ops`
    if any, else the Hertzian guess under load control and zero (the local
    interference) under displacement control."""
    grid = operator.grid
    nx, ny = grid.shape
    dtype = h.dtype
    problem = StepProblem(
        operator, compliance, poisson, jnp.zeros((), dtype), h,
        jnp.zeros((3, nx, ny), dtype), target, jnp.zeros((0,), dtype),
        jnp.zeros((0, nx, ny), dtype), 0, False, load_control, ())
    if p0 is None and coarse_ops:
        p0 = _nested_start(coarse_ops, h, compliance, poisson, target, load_control,
                           solver)
    if p0 is None:
        p0 = jnp.zeros_like(h)  # displacement control: the local interference
        if load_control:
            effective_modulus = 2 / (compliance * (1 - poisson))
            p0 = hertzian_guess(h, target, effective_modulus, grid.cell_area)
    setup = solver.setup(problem)
    out = run(solver, problem, StepGuess(p0, jnp.zeros((0, nx, ny), dtype)),
              setup=setup)
    return solver.normal_state(setup, out.state), out.result


@eqx.filter_jit
def _solve(operator, h, compliance, poisson, target, load_control, solver, p0=None,
           coarse_ops=()):
    """The jitted solve (`_solve_state`) as a `NormalSolution`."""
    grid = operator.grid
    state, result = _solve_state(operator, h, compliance, poisson, target,
                                 load_control, solver, p0, coarse_ops)
    return NormalSolution(
        pressure=state.pressure,
        gap=state.gap,
        contact=state.pressure > 0,
        approach=state.approach,
        normal_force=grid.cell_area * jnp.sum(state.pressure),
        displacement=state.displacement,
        iterations=state.iterations,
        residual=state.residual,
        converged=state.converged,
        applications=state.applications,
        result=result,
    )


def solve_normal(
    grid: Grid,
    indenter: AbstractIndenter | Float[Array, "nx ny"],
    material: AbstractMaterial,
    *,
    force=None,
    approach=None,
    solver: PolonskyKeer = PolonskyKeer(),
    operator: HalfSpace | None = None,
    start: str = "auto",
    throw: bool = True,
) -> NormalSolution:
    """Frictionless indentation of a half-space by a rigid indenter (one elastic step).

    **Main arguments:**

    - `grid`: the `jc.Grid`.
    - `indenter`: a `jc.Sphere`, a `jc.Surface`, or an `(nx, ny)` array of initial gaps
      [length].
    - `material`: the half-space. A viscoelastic material responds with its
      instantaneous compliance `J(0)` (a load applied at once).
    - `force`: the normal load `W >= 0` [force] (load control), or
    - `approach`: the rigid-body approach `delta` [length] (displacement control).
      Give exactly one.

    **Other arguments:**

    - `solver`: a `jc.PolonskyKeer` (tolerance, iteration bound).
    - `operator`: a prebuilt `jc.HalfSpace(grid)`, to reuse its kernel spectra across
      calls. If omitted, the operator of a concrete grid is kept in a small cache of
      recent grids (as are the nested start's coarse operators), else built here.
    - `start`: the CG's starting pressure. `"hertz"`: the Hertzian guess under load
      control (`p = 0`, the local interference, under displacement control).
      `"nested"`: the same problem solved first on grids halved down to at least 128
      cells a side (the gap averaged over 2 x 2 cells, each level to rtol `1e-4`,
      its pressure repeated 2 x 2 on the next), which needs sides that halve at
      least once to 128 or more (e.g. 256, 384, 512, 1024). `"auto"` (default):
      `"hertz"` for a `jc.Sphere` under load control (the guess is nearly its
      answer: 1-7 iterations) and where the grid does not halve, else `"nested"` (on
      a rough sphere, float64, rtol 1e-6, measured: load control 1.0x at 256^2, 1.3x
      at 512^2; displacement control 1.5x at 256^2, 1.9x at 512^2;
      `benchmarks/notes/normal_reentry.md`). The start changes the path, not the
      solution: the fine solve meets the same tolerance. `iterations` and
      `applications` count the fine grid's solve only. It compiles one solve per
      level.
    - `throw`: `True` (default, as in `jc.solve`): raise a `ValueError` when the solve
      does not reach its tolerance within `max_steps` (at once for concrete inputs, at
      run time under `jit`/`vmap`/`grad`); `False`: return the solution with
      `converged=False` (and its `residual`, `iterations`) instead.

    **Warns:** `jc.EdgeContactWarning` when the indenter is a `jc.Sphere` whose Hertz
    contact radius (or `sqrt(R delta)`) does not fit inside the grid less its outer ring
    of cells, or a `jc.Surface` whose estimated contact (`jc.Scene`'s, a bearing-area
    estimate) reaches the outer ring of a non-periodic grid or covers it;
    `NormalSolution.edge_contact` flags the solved contact exactly.

    **Returns:** a `jc.NormalSolution` in the grid's dtype (the solve's, as in
    `jc.solve`: a float64 indenter, material or load on a float32 grid is cast). The
    solve is jitted: a second call with new values of the same shapes reuses the
    compiled program.
    """
    if not isinstance(grid, Grid):
        raise TypeError(f"grid must be a jc.Grid, got {grid!r}")
    if (force is None) == (approach is None):
        raise ValueError("give exactly one of force= (load control) or approach= "
                         f"(displacement control); got force={force!r}, "
                         f"approach={approach!r}")
    if not isinstance(material, AbstractMaterial):
        raise TypeError(f"material must be a jaxcontact material, got {material!r}")
    if not isinstance(solver, PolonskyKeer):
        raise TypeError(f"solver must be a jc.PolonskyKeer, got {solver!r}")
    if not isinstance(throw, bool):
        raise TypeError(f"throw must be a bool, got {throw!r}")
    if start not in _STARTS:
        raise ValueError(f"start must be one of {_STARTS}, got {start!r}")
    levels = nested_levels(grid.shape)
    if start == "nested" and levels == 0:
        raise ValueError(
            f"start='nested' needs a grid whose sides halve to >= {NESTED_COARSEST} "
            f"cells (both even, at least {2 * NESTED_COARSEST}); "
            f"got shape {grid.shape}")
    if start == "hertz" or (start == "auto" and force is not None
                            and isinstance(indenter, Sphere)):
        levels = 0
    indenter = as_indenter(indenter)
    h = indenter.gap(grid)
    if h.shape != grid.shape:
        raise ValueError(
            f"the indenter's gap has shape {h.shape}, the grid is {grid.shape}")
    if operator is None:
        operator = normal_operator(grid)
    elif not isinstance(operator, HalfSpace):
        raise TypeError(f"operator must be a jc.HalfSpace, got {operator!r}")
    elif operator.grid.shape != grid.shape or operator.grid.periodic != grid.periodic:
        raise ValueError("operator was built for a different grid")
    if force is not None:
        target = _validate.non_negative("force", force)
        load_control = True
    else:
        target = _validate.finite("approach", approach)
        load_control = False
    if target.shape != ():
        raise ValueError(f"force/approach must be a scalar, got shape {target.shape}")
    if not _validate.is_traced((target, material, grid.size)):
        # As in `jc.Scene`: checked in the dtype the solve uses (the grid's).
        check_in_dtype(material, grid.size.dtype, 0.0)
        check_finite_in_dtype("force" if load_control else "approach", target,
                               grid.size.dtype)
        program = Force(target) if load_control else Displacement(target)
        times = jnp.zeros((1,), dtype=target.dtype)  # one instantaneous step: J(0)
        estimate = expected_contact_radius(
            indenter, grid, material, times, program, np.asarray(target).reshape(1)
        )
        warn_if_too_large(indenter, grid, estimate)
        contact = expected_surface_contact(
            indenter, grid, material, times, program, np.asarray(target).reshape(1)
        )
        warn_if_surface_too_large(grid, contact)
    # The grid's dtype is the solve's, as in `jc.solve` (a float64 indenter or material
    # on a float32 grid is cast).
    dtype = grid.size.dtype
    compliance = material.instantaneous_compliance
    sol = _solve(
        operator,
        h.astype(dtype),
        compliance.astype(dtype),
        material.poisson.astype(dtype),
        target.astype(dtype),
        load_control,
        solver,
        None,
        tuple(normal_operator(g) for g in coarse_grids(grid, levels)),
    )
    return _raise_on_failure(sol, solver) if throw else sol


def _raise_on_failure(sol: NormalSolution, solver: PolonskyKeer) -> NormalSolution:
    """`sol`, or the message of its `result` (`jc.RESULTS`) if it did not converge, as
    `jc.solve` does: at once for a concrete solution, at run time (`error_if`) under
    a transformation."""
    failed = sol.result != RESULTS.successful
    if _validate.is_traced(sol):
        return sol.result.error_if(sol, failed)
    if bool(failed):
        raise ValueError(
            f"{RESULTS[sol.result]}\njc.solve_normal did not converge: residual "
            f"{float(sol.residual):.3g} after {int(sol.iterations)} of max_steps="
            f"{solver.max_steps}, rtol={solver.tolerance(sol.pressure.dtype):.3g}; "
            "jc.solve_normal(..., throw=False) returns the flags instead")
    return sol
