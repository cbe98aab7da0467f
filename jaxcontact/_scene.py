"""`jc.Scene`: everything that defines a contact problem over time."""

import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from . import _validate
from ._grid import Grid
from ._indenter import AbstractIndenter, Sphere, Surface, as_indenter
from ._loading import Displacement, Force
from ._material.base import AbstractMaterial, check_in_dtype


_COUPLINGS = ("none", "x", "full")
_SLIP_LAWS = ("incremental", "total")


def _check_program(name, program, allow_none):
    if program is None and allow_none:
        return None
    if not isinstance(program, (Force, Displacement)):
        raise TypeError(
            f"{name} must be jc.Force(...) or jc.Displacement(...)"
            + (" or None" if allow_none else "")
            + f", got {program!r}"
        )
    return program


def _concrete_values(name, program, times):
    """The program's `(nt,)` values, checked; `None` when they are traced.

    The shape is checked always (it is static); finiteness only for concrete values
    (a traced callable's output cannot be inspected here).
    """
    if program is None:
        return None
    eager = not _validate.is_traced((times, program.value))
    try:
        if eager:
            with jax.ensure_compile_time_eval():
                values = program.values(times)
        else:
            values = program.values(times)
    except ValueError as exc:
        raise ValueError(f"{name}: {exc}") from None
    if _validate.is_traced(values):
        return None
    values = np.asarray(values)
    if not np.isfinite(values).all():
        raise ValueError(
            f"{name} must be finite (no NaN or inf) at every time, got {values!r}")
    return values


def expected_contact_radius(indenter, grid, material, times, normal, values):
    """Upper estimate of the largest contact radius of a `Sphere` [length], or `None`.

    Displacement control: `a = sqrt(R delta_max)` (Hertz and Lee-Radok alike). Load
    control: Hertz with the largest load and the compliance `J(t_end - t_0)` (for a
    non-negative load and a non-decreasing `J`, `(J * dW)(t) <= J(t - t_0) W_max`, so
    this bounds the Lee-Radok radius). `None` when the inputs are traced or the
    indenter is not a sphere.
    """
    if not isinstance(indenter, Sphere) or values is None:
        return None
    leaves = (indenter, material, times, grid.size)
    if _validate.is_traced(leaves):
        return None
    radius = float(indenter.radius)
    peak = float(np.max(values)) if values.size else 0.0
    if peak <= 0:
        return 0.0
    if isinstance(normal, Displacement):
        return float(np.sqrt(radius * peak))
    with jax.ensure_compile_time_eval():
        span = jnp.asarray(times[-1] - times[0])
        compliance = float(material.creep(span))
        poisson = float(material.poisson)
    effective_modulus = 2 / (compliance * (1 - poisson))
    return float((3 * peak * radius / (4 * effective_modulus)) ** (1 / 3))


def warn_if_too_large(indenter, grid, radius_estimate, stacklevel=3):
    """Warn (`jc.EdgeContactWarning`) when a sphere's contact cannot fit on the grid.

    The room is the distance from the sphere's centre to the nearest edge of a
    non-periodic grid, less one cell (the outer ring).
    """
    if radius_estimate is None or grid.periodic:
        return
    half = np.asarray(grid.size) / 2
    spacing = np.asarray(grid.spacing)
    room = float(np.min(half - np.abs(np.asarray(indenter.centre)) - spacing))
    if radius_estimate > room:
        warnings.warn(
            _validate.EdgeContactWarning(
                f"the expected contact radius {radius_estimate:.4g} exceeds the room "
                f"{room:.4g} between the sphere's centre and the outer ring of cells "
                f"of the grid (size {half * 2}): the contact will reach the domain "
                "edge and the solution will be truncated. Enlarge grid.size or lower "
                "the load."
            ),
            stacklevel=stacklevel,
        )


# Largest relative change of a time step [1] that the cast of `times` to the grid's
# dtype may cause: beyond it the solve's steps are not the ones asked for.
_STEP_RTOL = 1e-2


def check_times_in_dtype(times, dtype):
    """Check concrete `times` [time] as the solve sees them: cast to `dtype`.

    `jc.solve` steps over `times.astype(grid dtype)`. float64 times late on the clock
    (`1e5 + linspace(0, 0.02, 5)`) collapse to repeated values in float32 (its spacing
    near 1e5 is 0.0078): the creep then came out 13 % off without a word. Raises a
    `ValueError` when the cast times are not strictly increasing, or when a step changes
    by more than `_STEP_RTOL` (1 %) relative to its value in the given precision.
    """
    if _validate.is_traced(times) or times.shape[0] < 2:
        return
    given = np.asarray(times)
    cast = given.astype(dtype)
    name = np.dtype(dtype).name
    advice = (
        "measure times from the start of the scene (times - times[0]) or solve in "
        "float64"
    )
    if not (np.diff(cast) > 0).all():
        raise ValueError(
            f"times are not strictly increasing in {name} (the grid's dtype, which the "
            f"solve uses): {given!r} becomes {cast!r}; {advice}"
        )
    steps = np.diff(given.astype(np.float64))
    error = np.abs(np.diff(cast.astype(np.float64)) - steps) / steps
    if error.max() > _STEP_RTOL:
        k = int(np.argmax(error))
        raise ValueError(
            f"times lose precision in {name} (the grid's dtype, which the solve uses): "
            f"the step {steps[k]:.6g} from t = {given[k]!r} becomes "
            f"{float(cast[k + 1]) - float(cast[k]):.6g} ({error[k]:.1%} off, more than "
            f"{_STEP_RTOL:.0%}); {advice}"
        )


def check_finite_in_dtype(name, value, dtype):
    """A concrete floating array that stays finite once cast to `dtype`."""
    if value is None or callable(value) or _validate.is_traced(value):
        return
    arr = np.asarray(value)
    if arr.dtype.kind != "f":
        return
    with np.errstate(over="ignore"):
        cast = arr.astype(dtype)
    if not np.isfinite(cast).all():
        shown = arr.item() if arr.size == 1 else np.array2string(arr)
        raise ValueError(
            f"{name} {shown} overflows in {np.dtype(dtype).name} (the grid's dtype, "
            "which the solve uses): restate the scene in other units or solve in "
            "float64"
        )


def expected_surface_contact(indenter, grid, material, times, normal, values):
    """Estimated largest contact set `(nx, ny)` of a `jc.Surface`, or `None`.

    With `h = heights - min(heights)` [length] and the approach `delta` measured from
    the lowest point, the contact lies inside `h <= delta` (the surface only moves into
    the body under pressure) and its edge is estimated at `h = delta / 2` (exact for a
    paraboloid: Hertz's `a^2 / 2R = delta / 2`). Displacement control: `delta` is the
    largest prescribed approach less `min(heights)` (the solver's gap is
    `heights - delta_z + u_z`). Load control: the bearing-area estimate of the normal
    solver's start (`_solver.normal.hertzian_guess`; exact for a paraboloid): the level
    `c` at which `W = 4/3 E* sqrt(area{h <= c} / pi) 2 c`, with the largest load and the
    compliance `J(t_end - t_0)` (the largest). A flat surface is in contact everywhere.
    `None` when the inputs are traced or the indenter is not a `Surface`.
    """
    if not isinstance(indenter, Surface) or values is None:
        return None
    if _validate.is_traced((indenter, material, times, grid.size)):
        return None
    heights = np.asarray(indenter.heights, dtype=np.float64)
    h = heights - heights.min()
    peak = float(np.max(values)) if values.size else 0.0
    if isinstance(normal, Displacement):
        delta = peak - float(heights.min())
        return h <= delta / 2 if delta > 0 else None
    if peak <= 0:
        return None
    with jax.ensure_compile_time_eval():
        span = jnp.asarray(times[-1] - times[0])
        compliance = float(material.creep(span))
        poisson = float(material.poisson)
    effective_modulus = 2 / (compliance * (1 - poisson))
    cell_area = float(np.prod(np.asarray(grid.size, dtype=np.float64) / grid.shape))
    levels = np.sort(h.ravel())
    # The load carried at the level c: grows with c; between two heights the area is
    # that of the lower one. The contact is {h <= c} at the first c carrying the peak.
    cells = np.arange(1, levels.size + 1)
    reach = 4 / 3 * effective_modulus * np.sqrt(cells * cell_area / np.pi) * 2
    upper = reach * np.append(levels[1:], np.inf)  # the load just below the next height
    k = int(np.searchsorted(upper, peak))  # first k whose area carries the peak
    return h <= levels[min(k, levels.size - 1)]


def warn_if_surface_too_large(grid, contact, stacklevel=3):
    """Warn (`jc.EdgeContactWarning`) when an estimated contact set reaches the outer
    ring of cells of a non-periodic grid (or covers every cell)."""
    if contact is None or grid.periodic:
        return
    ring = contact[0, :].any() | contact[-1, :].any()
    ring = ring | contact[:, 0].any() | contact[:, -1].any()
    if not ring:
        return
    what = (
        "covers every cell"
        if contact.all()
        else f"reaches the outer ring of cells ({int(contact.sum())} of {contact.size} "
        "cells)"
    )
    warnings.warn(
        _validate.EdgeContactWarning(
            f"the expected contact of the surface indenter {what} of the grid (size "
            f"{np.asarray(grid.size)}): the solution will be truncated by the domain. "
            "Enlarge grid.size, lower the load, or use a periodic grid for a patch of "
            "a rough surface."
        ),
        stacklevel=stacklevel,
    )


class Scene(eqx.Module):
    """A rigid indenter against a half-space, loaded over time.

    **Arguments:**

    - `grid`: the `jc.Grid` of the surface.
    - `indenter`: a `jc.Sphere`, a `jc.Surface`, or an `(nx, ny)` array of initial gaps
      [length].
    - `material`: the half-space material (`jc.Elastic`, ...).
    - `times`: `(nt,)` strictly increasing times [time]. Consecutive entries are steps
      of one quasi-static loading path: the friction state carries over.
    - `normal`: `jc.Force(W)` (load control) or `jc.Displacement(delta_z)`.
    - `x`, `y`: tangential inputs, `jc.Force(F)` or `jc.Displacement(delta)`, or `None`
      (no tangential input). A direction with no input that is solved (y under
      `coupling="full"`, x under any coupling) is held: its rigid tangential
      displacement is zero, as CONTACT poses it (its F = 1: F_x and the y shift given);
      give `jc.Force(0.0)` for an indenter free to move in it. A direction that is not
      solved (y under `"none"` or `"x"`) carries no shear. On a scene symmetric about
      that direction's axis (a sphere loaded along x) held and free are the same
      solution.
    - `friction`: Coulomb friction coefficient `mu >= 0`.
    - `coupling`: `"none"` (pressure and shear independent), `"x"` (semi-coupled: `p`
      and `q_x` interact, `q_y = 0`), or `"full"` (`p`, `q_x`, `q_y` all interact).
    - `slip`: `"incremental"` (default; Coulomb on the slip increment between steps:
      friction is path dependent) or `"total"` (the paper's Eq. 16, on the total slip
      since t = 0).

    All arguments are stored as fields of the same name.

    **Raises:** `TypeError` for arguments of the wrong kind; `ValueError` (naming the
    argument and the bad value) for NaN/inf, negative friction, non-scalar friction,
    empty or non-increasing `times`, a load program whose length differs from `times`
    (or a callable returning NaN), a negative normal force, a surface whose shape
    differs from the grid, an unknown `coupling` or `slip`. The values are also checked
    as a solve in the grid's dtype sees them (`jc.solve` casts to it): `times` must stay
    strictly increasing once cast, each step within 1 %; loads, friction, size and the
    indenter must stay finite; the material must pass its own checks in that dtype and
    its creep compliance `J(0)`, `J(t_end - t_0)` [1/stress] lie within
    `[sqrt(tiny), 1 / sqrt(tiny)]` of it (float32: about `[1.1e-19, 9.2e18]`). Traced
    values (a scene built inside `jit`/`vmap`) are checked with `eqx.error_if` where the
    check can be staged (times strictly increasing, a non-negative normal force: these
    two are checked again when `jc.solve` reads them, which covers callables and scenes
    changed with `eqx.tree_at`).

    **Warns:** `jc.EdgeContactWarning` on a non-periodic grid when the contact is
    expected to reach the edge of the domain: for a `jc.Sphere`, when an upper estimate
    of its largest contact radius (Hertz with the largest normal force and the
    compliance `J(t_end - t_0)`, or `sqrt(R delta_max)` under displacement control) does
    not fit inside the grid less its outer ring of cells; for a `jc.Surface`, when a
    bearing-area estimate of its largest contact (`expected_surface_contact`: exact for
    a paraboloid) reaches the outer ring of cells or covers every cell. A warning, not
    an error: these are estimates, and a solved scene carries the exact flag
    `Solution.edge_contact`.
    """

    grid: Grid
    indenter: AbstractIndenter
    material: AbstractMaterial
    times: Float[Array, " nt"]
    normal: Force | Displacement
    x: Force | Displacement | None
    y: Force | Displacement | None
    friction: Float[Array, ""]
    coupling: str = eqx.field(static=True)
    slip: str = eqx.field(static=True)

    def __init__(
        self,
        grid: Grid,
        indenter,
        material: AbstractMaterial,
        times,
        normal,
        x=None,
        y=None,
        friction=0.0,
        coupling: str = "none",
        slip: str = "incremental",
    ):
        if not isinstance(grid, Grid):
            raise TypeError(f"grid must be a jc.Grid, got {grid!r}")
        if not isinstance(material, AbstractMaterial):
            raise TypeError(f"material must be a jaxcontact material, got {material!r}")
        if coupling not in _COUPLINGS:
            raise ValueError(f"coupling must be one of {_COUPLINGS}, got {coupling!r}")
        if slip not in _SLIP_LAWS:
            raise ValueError(f"slip must be one of {_SLIP_LAWS}, got {slip!r}")
        times = _validate.finite("times", times)
        if times.ndim == 0:
            times = times[None]
        if times.ndim != 1:
            raise ValueError(f"times must be a 1-D array, got shape {times.shape}")
        if times.shape[0] == 0:
            raise ValueError("times must hold at least one time, got an empty array")
        if not _validate.is_traced(times) and times.shape[0] > 1:
            steps = np.diff(np.asarray(times))
            if not (steps > 0).all():
                raise ValueError(
                    f"times must be strictly increasing, got {np.asarray(times)!r}")
        dtype = grid.size.dtype  # the solve's dtype: validate what it will see
        check_times_in_dtype(times, dtype)
        if _validate.is_traced(times) and times.shape[0] > 1:
            times = eqx.error_if(
                times,
                ~jnp.all(jnp.diff(times.astype(dtype)) > 0),
                "times must be strictly increasing (in the grid's dtype)",
            )
        self.grid = grid
        self.indenter = as_indenter(indenter)
        if (isinstance(self.indenter, Surface)
                and self.indenter.heights.shape != grid.shape):
            raise ValueError(
                "indenter: the surface heights have shape "
                f"{self.indenter.heights.shape} but the grid is {grid.shape}"
            )
        self.material = material
        self.times = times
        self.normal = _check_program("normal", normal, allow_none=False)
        self.x = _check_program("x", x, allow_none=True)
        self.y = _check_program("y", y, allow_none=True)
        if coupling == "x" and y is not None:
            raise ValueError(
                'coupling="x" is semi-coupled (q_y = 0): it takes no y input')
        self.friction = _validate.scalar(
            "friction", _validate.non_negative("friction", friction)
        )
        self.coupling = coupling
        self.slip = slip
        normal_values = _concrete_values("normal", self.normal, times)
        _concrete_values("x", self.x, times)
        _concrete_values("y", self.y, times)
        if isinstance(self.normal, Force):
            if not callable(self.normal.value):
                # Traced: the error_if must be kept, so the checked value is stored.
                checked = _validate.non_negative("normal force", self.normal.value)
                self.normal = eqx.tree_at(lambda f: f.value, self.normal, checked)
            elif normal_values is not None:
                _validate.non_negative("normal force", normal_values)
        def program_value(program):
            return None if program is None else program.value

        def kind(program):
            return "force" if isinstance(program, Force) else "displacement"

        for name, leaf in (
            (f"normal {kind(self.normal)}", program_value(self.normal)),
            (f"x {kind(self.x)}", program_value(self.x)),
            (f"y {kind(self.y)}", program_value(self.y)),
            ("friction", self.friction),
            ("grid size", grid.size),
        ):
            check_finite_in_dtype(name, leaf, dtype)
        for leaf in jax.tree_util.tree_leaves(self.indenter):
            check_finite_in_dtype("indenter", leaf, dtype)
        check_in_dtype(material, dtype, times[-1] - times[0])
        estimate = expected_contact_radius(
            self.indenter, grid, material, times, self.normal, normal_values
        )
        warn_if_too_large(self.indenter, grid, estimate)
        warn_if_surface_too_large(
            grid,
            expected_surface_contact(
                self.indenter, grid, material, times, self.normal, normal_values
            ),
        )

    @property
    def tangential_directions(self) -> int:
        """Number of shear components solved: 0, 1 (x only) or 2 (x and y).

        Decided from the scene: no tangential solve when the friction coefficient is a
        concrete zero, or when there is no tangential input and no coupling; no y solve
        unless there is a y input or the coupling is `"full"`.
        """
        if not _validate.is_traced(self.friction) and float(self.friction) == 0.0:
            return 0
        if self.x is None and self.y is None and self.coupling == "none":
            return 0
        if self.y is not None or self.coupling == "full":
            return 2
        return 1


_NOT_INCREASING = "times must be strictly increasing (in the grid's dtype)"
_TENSION = ("normal force must be finite and >= 0 at every time (a tension cannot be "
            "carried)")


def check_targets(scene: Scene) -> bool:
    """Check the normal targets of a concrete scene in Python (a ValueError for what
    `normal_targets` would reject at run time), so that the solve's compiled program
    holds no host callback and can go into JAX's persistent cache. Returns `False`,
    checking nothing, when the targets are traced (the solve checks them then)."""
    if _validate.is_traced((scene.times, scene.grid.size)):
        return False
    with jax.ensure_compile_time_eval():
        values = scene.normal.values(scene.times)
        times = scene.times.astype(scene.grid.size.dtype)
    if _validate.is_traced(values):
        return False
    values, times = np.asarray(values), np.asarray(times)
    if times.shape[0] > 1 and not np.all(np.diff(times) > 0):
        raise ValueError(f"{_NOT_INCREASING}, got {times!r}")
    if isinstance(scene.normal, Force) and not np.all(values >= 0):
        raise ValueError(f"{_TENSION}, got {values!r}")
    return True


def normal_targets(scene: Scene, runtime_checks: bool = True):
    """The `(nt,)` normal force or approach targets, as the solve reads them.

    With `runtime_checks`, checked inside the solve with `eqx.error_if` (a run-time
    error under `jit`): a scene built inside `jit`/`vmap`, changed with `eqx.tree_at`,
    or with a callable program could otherwise carry a tension (negative normal force)
    or times that are not strictly increasing (in the grid's dtype) past the
    constructor's checks. A concrete scene is checked by `check_targets` instead.
    """
    values = scene.normal.values(scene.times)
    if not runtime_checks:
        return values
    times = scene.times.astype(scene.grid.size.dtype)
    if times.shape[0] > 1:
        values = eqx.error_if(values, ~jnp.all(jnp.diff(times) > 0), _NOT_INCREASING)
    if isinstance(scene.normal, Force):
        values = eqx.error_if(values, jnp.any(values < 0), _TENSION)
    return values


def tangential_targets(scene: Scene, nd: int):
    """`(nt, nd)` targets and the per-direction force-control flags. A solved
    direction with no input is held (displacement control at zero): it adds no load
    to meet, so no root search and no gross-sliding test run on it."""
    programs = (scene.x, scene.y)[:nd]
    values, force_control = [], []
    for program in programs:
        if program is None:
            values.append(jnp.zeros_like(scene.times))
            force_control.append(False)
        else:
            values.append(program.values(scene.times))
            force_control.append(isinstance(program, Force))
    if nd == 0:
        return jnp.zeros(scene.times.shape + (0,), scene.times.dtype), ()
    return jnp.stack(values, axis=-1), tuple(force_control)
