r"""The axisymmetric compliance operator: ring pressures -> ring displacements.

The surface is cut into `n` coaxial rings (annuli) `edges[i] <= r < edges[i + 1]`, the
pressure uniform on each. The normal displacement of a half-space of unit shear
modulus under a uniform pressure `p` on a disc of radius `a` is (Johnson 1985, Eq.
3.39, with the Boussinesq kernel `(1 - nu) / (2 pi r)` of `HalfSpace`)

    u(r) = (1 - nu) (2 a / pi) E(r / a) p                            r <= a
    u(r) = (1 - nu) (2 r / pi) [E(a / r) - (1 - a^2 / r^2) K(a / r)] p   r >= a

(`K`, `E`: complete elliptic integrals of modulus `k`), and an annulus is a disc less
a disc. The operator is a Galerkin one: its entry `(j, i)` is the displacement due to
ring `i`, AVERAGED over ring `j` (area weighted). The integral of `u` over a disc `b`
has a closed form (from `int t E(t) dt = [(1 + t^2) E - (1 - t^2) K] / 3`):

    D(a, b) = (4 hi^3 / 3) [(1 + k^2) E(k) - (1 - k^2) K(k)],  k = lo / hi

(`hi`, `lo` the larger and smaller of `a`, `b`; times `1 - nu`), symmetric in `a`,
`b` (reciprocity), so `areas[:, None] * matrix` is symmetric and positive definite:
the ring contact problem is a convex quadratic programme, solved by the same
projected conjugate gradients as the grid (`_solver/rings.py`). The contact
condition is the mean gap of each ring (`RingOperator.mean` of the profile).

Conventions match `HalfSpace`: unit shear modulus, the Poisson-independent part
stored (`apply_normal` multiplies by `1 - nu`), displacement positive into the body.
The rings only discretise the pressure: the half-space is infinite (no domain edge
but the outermost ring, beyond which the pressure is zero).

Scaling the edges by `s` scales `matrix` by `s` (`D` is cubic in the radii, the areas
quadratic), `areas` by `s^2` and `inverse` by `s^-3`: a traced radius (a scene built
inside `jit`) scales the operator of the unit radius, built in NumPy once per ring
count (`RingOperator.scaled`).
"""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float
from scipy.special import ellipe, ellipk

from . import _validate


# Gauss-Legendre points per ring of `RingOperator.mean` (exact for a profile that is
# a polynomial of degree <= 2 * 8 - 2 in r on each ring).
MEAN_POINTS = 8


def disc_integral(a, b):
    """`D(a, b)`: the integral over the disc of radius `b` of the normal displacement
    [length^3] due to a unit pressure on the disc of radius `a` (unit shear modulus,
    without the factor `1 - nu`; module docs). NumPy, float64, broadcasting."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    hi, lo = np.maximum(a, b), np.minimum(a, b)
    k = np.divide(lo, hi, out=np.zeros(np.broadcast(lo, hi).shape), where=hi > 0)
    m = k * k
    inside = m < 1  # at k = 1, (1 - k^2) K(k) -> 0
    kk = np.where(inside, ellipk(np.where(inside, m, 0.0)), 0.0)
    return (4 * hi**3 / 3) * ((1 + m) * ellipe(m) - np.where(inside, (1 - m) * kk, 0))


def ring_matrix(edges) -> np.ndarray:
    """`(n, n)` float64: entry `(j, i)` the mean normal displacement [length] over ring
    `j` due to a unit pressure on ring `i` (unit shear modulus, without `1 - nu`).
    Each entry is the second difference of `disc_integral` over the ring edges, divided
    by the area of ring `j`."""
    e = np.asarray(edges, np.float64)
    outer, inner = e[1:], e[:-1]

    def d(b, a):  # b: rows (the ring averaged over), a: columns (the loaded ring)
        return disc_integral(a[None, :], b[:, None])

    energy = d(outer, outer) - d(outer, inner) - d(inner, outer) + d(inner, inner)
    energy = 0.5 * (energy + energy.T)  # symmetric to round-off already
    areas = np.pi * (outer**2 - inner**2)
    return energy / areas[:, None]


@functools.lru_cache(maxsize=16)
def _build(edges: tuple, dtype: str):
    e = np.asarray(edges, np.float64)
    matrix = ring_matrix(e)
    areas = np.pi * (e[1:] ** 2 - e[:-1] ** 2)
    energy = areas[:, None] * matrix
    inverse = np.linalg.inv(energy)
    inverse = 0.5 * (inverse + inverse.T)
    return matrix.astype(dtype), areas.astype(dtype), inverse.astype(dtype)


class RingOperator(eqx.Module):
    """Galerkin influence matrix of `n` coaxial rings on a half-space of unit shear
    modulus (see the module docs).

    **Arguments:**

    - `edges`: `(n + 1,)` concrete, strictly increasing ring edges [length], from 0.
      `RingOperator.uniform(radius, rings)` builds `rings` rings of equal width.
    - `dtype`: the arrays' dtype (default: float64 if enabled, else float32). Built
      in float64 NumPy and cast (cached for recent edges).

    **Fields** (arrays): `edges` `(n + 1,)` [length]; `areas` `(n,)` [length^2];
    `matrix` `(n, n)` [length / stress at unit modulus]: mean displacement over ring
    `j` per unit pressure on ring `i`, without `1 - nu`; `inverse` `(n, n)`: the
    inverse of the symmetric `areas[:, None] * matrix` (the conjugate-gradient
    preconditioner). Applying it costs one dense `(n, n)` product.
    """

    edges: Float[Array, " n1"]
    areas: Float[Array, " n"]
    matrix: Float[Array, "n n"]
    inverse: Float[Array, "n n"]

    def __init__(self, edges, dtype=None):
        if _validate.is_traced(edges):
            raise TypeError("RingOperator needs concrete edges (built once, in NumPy); "
                            "got traced values")
        e = np.asarray(edges, np.float64)
        if e.ndim != 1 or e.size < 2:
            raise ValueError(f"edges must be a 1-D array of at least 2 radii, got "
                             f"shape {e.shape}")
        if e[0] != 0 or not np.all(np.diff(e) > 0) or not np.all(np.isfinite(e)):
            raise ValueError("edges must be finite, strictly increasing and start at "
                             f"0, got {e!r}")
        if dtype is None:
            dtype = jnp.zeros(()).dtype
        dtype = np.dtype(dtype).name
        matrix, areas, inverse = _build(tuple(e.tolist()), dtype)
        self.edges = jnp.asarray(e, dtype)
        self.areas = jnp.asarray(areas)
        self.matrix = jnp.asarray(matrix)
        self.inverse = jnp.asarray(inverse)

    @classmethod
    def uniform(cls, radius, rings: int, dtype=None) -> "RingOperator":
        """`rings` rings of equal width covering `[0, radius]` [length]. A traced
        `radius` (inside `jit`, `grad`, `vmap`) scales the unit operator
        (`scaled`); a concrete one must be finite and > 0."""
        rings = _validate.check_int("rings", rings, 1)
        if _validate.is_traced(radius):
            unit = cls(np.linspace(0.0, 1.0, rings + 1), dtype=dtype)
            return unit.scaled(jnp.asarray(radius, unit.edges.dtype))
        radius = float(radius)
        if not (np.isfinite(radius) and radius > 0):
            raise ValueError(f"radius must be finite and > 0, got {radius!r}")
        return cls(np.linspace(0.0, radius, rings + 1), dtype=dtype)

    def scaled(self, factor) -> "RingOperator":
        """This operator with every edge multiplied by `factor` > 0 (a scalar,
        traced or not): the influences follow in closed form (module docs)."""
        f = jnp.asarray(factor, self.edges.dtype)
        return eqx.tree_at(
            lambda op: (op.edges, op.areas, op.matrix, op.inverse), self,
            (self.edges * f, self.areas * f**2, self.matrix * f, self.inverse / f**3))

    @property
    def rings(self) -> int:
        """The number of rings `n`."""
        return self.areas.shape[0]

    @property
    def centres(self) -> Float[Array, " n"]:
        """Mid radii of the rings [length]."""
        return 0.5 * (self.edges[1:] + self.edges[:-1])

    def apply_normal(self, pressure: Float[Array, " n"], poisson) -> Float[Array, " n"]:
        """Mean normal displacement [length] of each ring under the ring `pressure`
        [stress], unit shear modulus (as `HalfSpace.apply_normal`)."""
        return (1 - poisson) * (self.matrix @ pressure)

    def force(self, pressure: Float[Array, "... n"]) -> Float[Array, "..."]:
        """The normal force `sum_i areas_i p_i` [force] of ring pressures."""
        return pressure @ self.areas

    def mean(self, profile) -> Float[Array, " n"]:
        """Area-weighted mean over each ring of the radial function `profile(r)`
        [length] (a `jax.numpy` function, so that its parameters may be traced):
        `MEAN_POINTS` Gauss-Legendre points per ring in `r`, weight `r`."""
        x, wt = np.polynomial.legendre.leggauss(MEAN_POINTS)
        lo, hi = self.edges[:-1, None], self.edges[1:, None]
        x = jnp.asarray(x, self.edges.dtype)[None, :]
        r = 0.5 * (hi + lo) + 0.5 * (hi - lo) * x
        weight = jnp.asarray(wt, self.edges.dtype)[None, :] * r * (hi - lo) * 0.5
        values = profile(r)
        return jnp.sum(weight * values, axis=1) / jnp.sum(weight, axis=1)

    def to_grid(self, values: Float[Array, "... n"], grid, centre=(0.0, 0.0)):
        """`rings_to_grid` with this operator's edges."""
        return rings_to_grid(self.edges, values, grid, centre)


def rings_to_grid(edges, values: Float[Array, "... n"], grid, centre=(0.0, 0.0)):
    """Ring `values` (e.g. pressure, `(..., n)`, rings of `edges` `(n + 1,)`) on the
    cells of a `jc.Grid`: at each cell centre's distance `r` from `centre`, the values
    interpolated linearly between the rings' mid-radii (second order where the field
    is smooth, as the rings), on the cells whose ring carries a non-zero value (the
    contact set of the rings), zero elsewhere and beyond the outermost ring.
    **Returns:** `(..., nx, ny)`."""
    x, y = grid.coordinates()
    centre = jnp.asarray(centre, x.dtype)
    r = jnp.sqrt((x - centre[0]) ** 2 + (y - centre[1]) ** 2)
    index = jnp.searchsorted(edges, r, side="right") - 1
    inside = index < values.shape[-1]
    held = jnp.take(values, jnp.where(inside, index, 0), axis=-1)
    held = jnp.where(jnp.broadcast_to(inside, held.shape), held,
                     jnp.zeros((), values.dtype))
    mids = 0.5 * (edges[1:] + edges[:-1])
    flat = values.reshape((-1, values.shape[-1]))
    linear = jax.vmap(lambda v: jnp.interp(r, mids, v, right=0.0))(flat)
    linear = linear.reshape(values.shape[:-1] + r.shape)
    return jnp.where(held != 0, linear, jnp.zeros((), values.dtype))
