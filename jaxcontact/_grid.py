"""The surface mesh: a uniform grid of rectangular cells centred on the origin."""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from . import _validate


class Grid(eqx.Module):
    """A uniform `nx x ny` grid of rectangular cells covering `size = (Lx, Ly)`.

    Cell centres sit at `x_i = (i - (nx - 1) / 2) * dx`, `i = 0 .. nx - 1` (and the
    same in y), so the grid is centred on the origin. Tractions are uniform on each
    cell; displacements are collocated at the cell centres.

    **Arguments:**

    - `shape`: `(nx, ny)`, the number of cells along x and y (static: changing it
      recompiles). Each must be an integer >= 2.
    - `size`: `(Lx, Ly)`, the side lengths of the domain [length]. A scalar means a
      square domain. Stored as a JAX array (a dynamic leaf).
    - `periodic`: `False` (default) for an isolated contact on an infinite half-space
      (non-periodic DC-FFT, zero padding to `2nx x 2ny`); `True` for a doubly periodic
      surface (e.g. a patch of a rough surface). Static.
    """

    shape: tuple[int, int] = eqx.field(static=True)
    size: Float[Array, "2"]
    periodic: bool = eqx.field(static=True)

    def __init__(self, shape, size, periodic: bool = False):
        try:
            shape = tuple(shape)
        except TypeError:
            shape = (shape, shape)
        if len(shape) != 2 or not all(
            hasattr(s, "__index__") and not isinstance(s, (bool, np.bool_))
            for s in shape
        ):
            raise ValueError(f"shape must be two integers (nx, ny), got {shape!r}")
        shape = tuple(int(s) for s in shape)
        if min(shape) < 2:
            raise ValueError(f"shape must be at least (2, 2), got {shape!r}")
        size = _validate.as_float_array("size", size)
        if size.ndim == 0:
            size = jnp.stack([size, size])
        if size.shape != (2,):
            raise ValueError(
                f"size must be a scalar or (Lx, Ly), got shape {size.shape}")
        self.shape = shape
        self.size = _validate.positive("size", size)
        if not isinstance(periodic, (bool, np.bool_)):
            raise TypeError(f"periodic must be True or False, got {periodic!r}")
        self.periodic = bool(periodic)

    @property
    def spacing(self) -> Float[Array, "2"]:
        """Cell sizes `(dx, dy)` [length]."""
        return self.size / jnp.asarray(self.shape, dtype=self.size.dtype)

    @property
    def cell_area(self) -> Float[Array, ""]:
        """Area of one cell, `dx * dy` [length^2]."""
        dx, dy = self.spacing
        return dx * dy

    @property
    def x(self) -> Float[Array, " nx"]:
        """Cell-centre x coordinates [length]."""
        nx = self.shape[0]
        return (jnp.arange(nx, dtype=self.size.dtype) - (nx - 1) / 2) * self.spacing[0]

    @property
    def y(self) -> Float[Array, " ny"]:
        """Cell-centre y coordinates [length]."""
        ny = self.shape[1]
        return (jnp.arange(ny, dtype=self.size.dtype) - (ny - 1) / 2) * self.spacing[1]

    def coordinates(self) -> tuple[Float[Array, "nx ny"], Float[Array, "nx ny"]]:
        """Cell-centre coordinates `(X, Y)`, each `(nx, ny)` (`indexing="ij"`)."""
        return jnp.meshgrid(self.x, self.y, indexing="ij")
