"""`jc.Scene`: everything that defines a contact problem over time."""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from . import _validate
from ._grid import Grid
from ._indenter import AbstractIndenter, as_indenter
from ._loading import Displacement, Force
from ._material.base import AbstractMaterial


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


class Scene(eqx.Module):
    """A rigid indenter against a half-space, loaded over time.

    **Arguments:**

    - `grid`: the `jc.Grid` of the surface.
    - `indenter`: a `jc.Sphere`, a `jc.Surface`, or an `(nx, ny)` array of initial gaps
      [length].
    - `material`: the half-space material (`jc.Elastic`, ...).
    - `times`: `(nt,)` strictly increasing times [time]. Consecutive entries are steps of
      one quasi-static loading path: the friction state carries over.
    - `normal`: `jc.Force(W)` (load control) or `jc.Displacement(delta_z)`.
    - `x`, `y`: tangential inputs, `jc.Force(F)` or `jc.Displacement(delta)`, or `None`
      (no tangential input: the tangential force is zero in that direction).
    - `friction`: Coulomb friction coefficient `mu >= 0`.
    - `coupling`: `"none"` (pressure and shear independent), `"x"` (semi-coupled: `p`
      and `q_x` interact, `q_y = 0`), or `"full"` (`p`, `q_x`, `q_y` all interact).
    - `slip`: `"incremental"` (default; Coulomb on the slip increment between steps:
      friction is path dependent) or `"total"` (the paper's Eq. 16, on the total slip
      since t = 0).

    All arguments are stored as fields of the same name.
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
        if not _validate.is_traced(times) and times.shape[0] > 1:
            steps = np.diff(np.asarray(times))
            if not (steps > 0).all():
                raise ValueError(f"times must be strictly increasing, got {np.asarray(times)!r}")
        self.grid = grid
        self.indenter = as_indenter(indenter)
        self.material = material
        self.times = times
        self.normal = _check_program("normal", normal, allow_none=False)
        self.x = _check_program("x", x, allow_none=True)
        self.y = _check_program("y", y, allow_none=True)
        if coupling == "x" and y is not None:
            raise ValueError('coupling="x" is semi-coupled (q_y = 0): it takes no y input')
        self.friction = _validate.non_negative("friction", friction)
        self.coupling = coupling
        self.slip = slip
        if isinstance(self.normal, Force) and not callable(self.normal.value):
            _validate.non_negative("normal force", self.normal.value)

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


def normal_targets(scene: Scene):
    return scene.normal.values(scene.times)


def tangential_targets(scene: Scene, nd: int):
    """`(nt, nd)` targets and the per-direction force-control flags."""
    programs = (scene.x, scene.y)[:nd]
    values, force_control = [], []
    for program in programs:
        if program is None:
            values.append(jnp.zeros_like(scene.times))
            force_control.append(True)
        else:
            values.append(program.values(scene.times))
            force_control.append(isinstance(program, Force))
    if nd == 0:
        return jnp.zeros(scene.times.shape + (0,), scene.times.dtype), ()
    return jnp.stack(values, axis=-1), tuple(force_control)
