"""Rigid indenters: the initial gap between the indenter and the undeformed surface."""

import abc

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from . import _validate
from ._grid import Grid


class AbstractIndenter(eqx.Module):
    """A rigid indenter, described by its initial gap `h0(x, y)` to the flat surface."""

    @abc.abstractmethod
    def gap(self, grid: Grid) -> Float[Array, "nx ny"]:
        """Initial gap `h0 >= 0` [length] at the cell centres of `grid`."""


class Sphere(AbstractIndenter):
    """A rigid sphere of radius `R`, in the Hertz (paraboloidal) approximation.

    `h0(x, y) = ((x - x_c)^2 + (y - y_c)^2) / (2 R)`, valid while the contact radius is
    small compared with `R` (as in Hertz theory and in the paper).

    **Arguments:**

    - `radius`: `R` [length], > 0.
    - `centre`: `(x_c, y_c)` [length], default the origin.
    """

    radius: Float[Array, ""]
    centre: Float[Array, "2"]

    def __init__(self, radius, centre=(0.0, 0.0)):
        self.radius = _validate.scalar("radius", _validate.positive("radius", radius))
        if not hasattr(centre, "dtype"):
            centre = jnp.asarray(centre, dtype=self.radius.dtype)
        centre = _validate.finite("centre", centre)
        if centre.shape != (2,):
            raise ValueError(f"centre must be (x_c, y_c), got shape {centre.shape}")
        self.centre = centre

    def gap(self, grid: Grid) -> Float[Array, "nx ny"]:
        x, y = grid.coordinates()
        dx, dy = x - self.centre[0], y - self.centre[1]
        return (dx * dx + dy * dy) / (2 * self.radius)


class Surface(AbstractIndenter):
    """An arbitrary rigid surface given by its initial gap on the grid.

    **Arguments:**

    - `heights`: `(nx, ny)` array of initial gaps [length] (any offset under load
      control; under displacement control the approach counts from height 0, the gap
      being `heights - delta_z + u_z`). Must be finite.

    A `jc.Scene` (and `jc.solve_normal`) warns `jc.EdgeContactWarning` when the
    surface's estimated contact reaches the edge of a non-periodic grid. Scene files
    read one from a file: `[indenter] type = "surface"`, `file = "heights.npy"`.
    """

    heights: Float[Array, "nx ny"]

    def __init__(self, heights):
        heights = _validate.finite("heights", heights)
        if heights.ndim != 2:
            raise ValueError(
                f"heights must be an (nx, ny) array, got shape {heights.shape}")
        self.heights = heights

    def gap(self, grid: Grid) -> Float[Array, "nx ny"]:
        if self.heights.shape != grid.shape:
            raise ValueError(
                f"heights has shape {self.heights.shape} but the grid is {grid.shape}"
            )
        return self.heights


def as_indenter(indenter) -> AbstractIndenter:
    """Accept an indenter or an `(nx, ny)` array of initial gaps."""
    if isinstance(indenter, AbstractIndenter):
        return indenter
    if (isinstance(indenter, (jnp.ndarray, np.ndarray))
            or hasattr(indenter, "__array__")):
        return Surface(indenter)
    raise TypeError(
        "indenter must be a jc.Sphere, jc.Surface or an (nx, ny) array, got "
        f"{indenter!r}"
    )
