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


def _half_angle(value) -> Float[Array, ""]:
    """A half-angle [rad] in `(0, pi/2)`, validated."""
    return _validate.scalar("half_angle", _validate.open_interval(
        "half_angle", value, 0.0, np.pi / 2,
        " radians (the angle between the axis and the flank)"))


def _centre(centre, dtype) -> Float[Array, "2"]:
    if not hasattr(centre, "dtype"):
        centre = jnp.asarray(centre, dtype=dtype)
    centre = _validate.finite("centre", centre)
    if centre.shape != (2,):
        raise ValueError(f"centre must be (x_c, y_c), got shape {centre.shape}")
    return centre


class AbstractAxisymmetricIndenter(AbstractIndenter):
    """A rigid indenter of revolution about the vertical axis through `centre`: its
    initial gap is a function of the distance `r` to the axis alone, `profile(r)`.
    Frictionless indentation by one is an axisymmetric problem."""

    centre: eqx.AbstractVar[Float[Array, "2"]]

    @abc.abstractmethod
    def profile(self, r: Float[Array, "..."]) -> Float[Array, "..."]:
        """Initial gap `h0(r) >= 0` [length] at the distances `r >= 0` [length] from
        the axis, `h0(0) = 0`."""

    def gap(self, grid: Grid) -> Float[Array, "nx ny"]:
        x, y = grid.coordinates()
        dx, dy = x - self.centre[0], y - self.centre[1]
        square = dx * dx + dy * dy
        # A cell centred on the axis: no NaN in the derivative of |r| there.
        positive = square > 0
        r = jnp.where(positive, jnp.sqrt(jnp.where(positive, square, 1.0)), 0.0)
        return self.profile(r)


class Sphere(AbstractAxisymmetricIndenter):
    """A rigid sphere of radius `R`, in the Hertz (paraboloidal) approximation.

    `h0(x, y) = ((x - x_c)^2 + (y - y_c)^2) / (2 R)`, i.e. `h0(r) = r^2 / (2 R)`, valid
    while the contact radius is small compared with `R` (as in Hertz theory and in
    the paper).

    **Arguments:**

    - `radius`: `R` [length], > 0.
    - `centre`: `(x_c, y_c)` [length], default the origin.
    """

    radius: Float[Array, ""]
    centre: Float[Array, "2"]

    def __init__(self, radius, centre=(0.0, 0.0)):
        self.radius = _validate.scalar("radius", _validate.positive("radius", radius))
        self.centre = _centre(centre, self.radius.dtype)

    def profile(self, r):
        return r * r / (2 * self.radius)

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


class Cone(AbstractAxisymmetricIndenter):
    """A rigid cone with a sharp tip: `h0(r) = r / tan(alpha)`.

    Sneddon (1965): at the depth `d` the contact radius is `a = 2 d tan(alpha) / pi`
    and the load `W = (2 / pi) E* d^2 tan(alpha)`, `E* = 2 G / (1 - nu)`; the pressure
    has a logarithmic singularity at the tip, so a grid resolves the load to first
    order in the cell size.

    **Arguments:**

    - `half_angle`: `alpha` [rad], the angle between the axis and the flank, in
      `(0, pi/2)` (an AFM cone: about 0.3-0.4 rad).
    - `centre`: `(x_c, y_c)` [length], default the origin.
    """

    half_angle: Float[Array, ""]
    centre: Float[Array, "2"]

    def __init__(self, half_angle, centre=(0.0, 0.0)):
        self.half_angle = _half_angle(half_angle)
        self.centre = _centre(centre, self.half_angle.dtype)

    def profile(self, r):
        return r / jnp.tan(self.half_angle)


class BluntedCone(AbstractAxisymmetricIndenter):
    """A cone of half-angle `alpha` whose apex is a spherical cap of radius `R`,
    joined tangentially at `b = R cos(alpha)` (Briscoe, Sebastian & Adams 1994):
    `h0(r) = R - sqrt(R^2 - r^2)` for `r <= b`, and the cone `h0(b) + (r - b) /
    tan(alpha)` beyond. The cap is the exact sphere, not `jc.Sphere`'s paraboloid
    (they agree to `O(r^4 / R^3)`).

    **Arguments:** `half_angle` `alpha` [rad] in `(0, pi/2)`, `tip_radius` `R`
    [length] > 0, `centre` `(x_c, y_c)` [length] (default the origin).
    """

    half_angle: Float[Array, ""]
    tip_radius: Float[Array, ""]
    centre: Float[Array, "2"]

    def __init__(self, half_angle, tip_radius, centre=(0.0, 0.0)):
        self.half_angle = _half_angle(half_angle)
        self.tip_radius = _validate.scalar(
            "tip_radius", _validate.positive("tip_radius", tip_radius))
        self.centre = _centre(centre, self.half_angle.dtype)

    @property
    def transition(self) -> Float[Array, ""]:
        """`b = R cos(alpha)` [length], where the cap meets the flanks."""
        return self.tip_radius * jnp.cos(self.half_angle)

    def profile(self, r):
        radius, b = self.tip_radius, self.transition
        inside = jnp.minimum(r, b)
        # R - sqrt(R^2 - r^2), written without the cancellation near r = 0.
        cap = inside * inside / (radius + jnp.sqrt(radius * radius - inside * inside))
        return cap + jnp.maximum(r - b, 0) / jnp.tan(self.half_angle)


class AxisymmetricProfile(AbstractAxisymmetricIndenter):
    """Any tip of revolution, tabulated (a measured tip): `h0(r)` interpolated
    linearly between the given points, continued beyond the last point along the
    last segment's slope.

    **Arguments:**

    - `radii`: `(m,)` distances from the axis [length], `m >= 2`, from 0, increasing.
    - `heights`: `(m,)` initial gaps there [length], finite. Any offset and shape
      (a tip with a central dip touches on an annulus); under displacement control
      the approach counts from height 0, as for `jc.Surface`.
    - `centre`: `(x_c, y_c)` [length].
    """

    radii: Float[Array, " m"]
    heights: Float[Array, " m"]
    centre: Float[Array, "2"]

    def __init__(self, radii, heights, centre=(0.0, 0.0)):
        radii = _validate.finite("radii", radii)
        heights = _validate.finite("heights", heights)
        if radii.ndim != 1 or radii.shape != heights.shape or radii.shape[0] < 2:
            raise ValueError(
                "radii and heights must be 1-D arrays of the same length >= 2, got "
                f"shapes {radii.shape} and {heights.shape}")
        if not _validate.is_traced(radii):
            r = np.asarray(radii)
            if r[0] != 0 or np.any(np.diff(r) <= 0):
                raise ValueError(
                    f"radii must start at 0 (the axis) and increase, got {r!r}")
        self.radii, self.heights = radii, heights
        self.centre = _centre(centre, radii.dtype)

    def profile(self, r):
        inside = jnp.interp(r, self.radii, self.heights)
        slope = ((self.heights[-1] - self.heights[-2])
                 / (self.radii[-1] - self.radii[-2]))
        beyond = self.heights[-1] + slope * (r - self.radii[-1])
        return jnp.where(r <= self.radii[-1], inside, beyond)


class Pyramid(AbstractIndenter):
    """A rigid pyramid with `sides` flat faces and a sharp apex (an AFM tip: 4 sides;
    Berkovich: 3): `h0 = max_k (x' cos(t_k) + y' sin(t_k)) / tan(alpha)`, `t_k =
    rotation + 2 pi k / sides`, `(x', y')` from the centre. Not axisymmetric: solved
    on the grid.

    **Arguments:**

    - `half_angle`: `alpha` [rad], the angle between the axis and a face (measured in
      the plane through the axis normal to the face), in `(0, pi/2)`.
    - `sides`: the number of faces, an integer >= 3 (default 4).
    - `centre`: `(x_c, y_c)` [length]; `rotation`: `t_0` [rad] (default 0: a face
      normal along +x).

    `equivalent_cone()`: the cone with the same cross-section area at every depth
    (`tan(alpha_c)^2 = sides tan(pi / sides) tan(alpha)^2 / pi`), the usual
    axisymmetric stand-in for a pyramid (4 sides: its load at a depth within a few
    percent, King 1987).
    """

    half_angle: Float[Array, ""]
    centre: Float[Array, "2"]
    rotation: Float[Array, ""]
    sides: int = eqx.field(static=True)

    def __init__(self, half_angle, sides=4, centre=(0.0, 0.0), rotation=0.0):
        self.half_angle = _half_angle(half_angle)
        self.sides = _validate.check_int("sides", sides, 3)
        self.centre = _centre(centre, self.half_angle.dtype)
        self.rotation = _validate.scalar("rotation", _validate.finite(
            "rotation", _validate.as_float_array("rotation", rotation,
                                                 self.half_angle.dtype)))

    def gap(self, grid: Grid) -> Float[Array, "nx ny"]:
        x, y = grid.coordinates()
        dx, dy = x - self.centre[0], y - self.centre[1]
        angles = self.rotation + 2 * np.pi * jnp.arange(self.sides) / self.sides
        faces = (dx[..., None] * jnp.cos(angles)[None, None]
                 + dy[..., None] * jnp.sin(angles)[None, None])
        return jnp.max(faces, axis=-1) / jnp.tan(self.half_angle)

    def equivalent_cone(self) -> Cone:
        """The cone of equal cross-section area at every depth (see the class docs)."""
        n = self.sides
        ratio = n * np.tan(np.pi / n) / np.pi
        return Cone(jnp.arctan(jnp.sqrt(ratio) * jnp.tan(self.half_angle)),
                    centre=self.centre)


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
