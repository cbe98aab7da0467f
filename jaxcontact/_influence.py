r"""Closed-form influence coefficients of a uniformly loaded rectangular cell.

A uniform unit traction acts on the cell `[-dx/2, dx/2] x [-dy/2, dy/2]` of the
surface of a half-space with unit shear modulus. The displacement at a surface point
`(x, y)` is the integral of the point-force kernels (Boussinesq and Cerruti; Johnson,
*Contact Mechanics*, eqs. 3.19 and 3.86-3.87, z pointing into the body) over the
cell. With `u = x - x'` and `v = y - y'` each integral is a "corner sum"
`F(x+a, y+b) - F(x-a, y+b) - F(x+a, y-b) + F(x-a, y-b)` of an antiderivative `F` with
`d^2 F / du dv = kernel` (Love 1929; Liu, Wang & Liu 2000):

| kernel          | antiderivative `F(u, v)`                      |
|-----------------|-----------------------------------------------|
| `1 / r`         | `A(u, v) + A(v, u)`, `A(u, v) = u asinh(v/|u|)` |
| `x^2 / r^3`     | `A(v, u)`                                     |
| `x y / r^3`     | `-r`                                          |
| `x / r^2`       | `v ln r + u atan(v / u)`                      |

Terms such as `u ln|u|` that cancel in the corner sum are dropped, which keeps every
term bounded. Collocation points (cell centres) never lie on a cell edge, so the
formulas are never evaluated at a singular point on the grid.

The coefficients are returned as a `(3, 3, ...)` array `C[i, j]`: displacement
component `i` due to traction component `j`, in the order `(x, y, z)`. Units: per unit
traction and unit shear modulus, `C` has units of length; for a material with shear
modulus `G` divide by `G`.
"""

import jax.numpy as jnp
import numpy as np


def _a(u, v, xp=jnp):
    """`u asinh(v / |u|)`, continuous with value 0 at `u = 0`."""
    zero = u == 0
    den = xp.where(zero, 1.0, xp.abs(u))
    return xp.where(zero, 0.0, u * xp.arcsinh(v / den))


def _c(u, v, xp=jnp):
    """`v ln r + u atan(v / u)`: antiderivative of `x / r^2`, bounded at `r = 0`."""
    r2 = u * u + v * v
    log_r = 0.5 * xp.log(xp.where(r2 == 0, 1.0, r2))
    first = xp.where(v == 0, 0.0, v * log_r)
    zero = u == 0
    second = xp.where(zero, 0.0, u * xp.arctan(v / xp.where(zero, 1.0, u)))
    return first + second


def _minus_r(u, v, xp=jnp):
    return -xp.sqrt(u * u + v * v)


def _corner_sum(fn, x, y, a, b, xp):
    return (
        fn(x + a, y + b, xp) - fn(x - a, y + b, xp) - fn(x + a, y - b, xp)
        + fn(x - a, y - b, xp)
    )


def base_integrals(x, y, dx, dy, xp=jnp):
    """Poisson-independent cell integrals, each `/ (2 pi)` (shapes of `x`, `y`).

    Returns `(s1, s2, sxy, szx, szy)`:

    - `s1 = corner[A(u, v)] / 2pi`, `s2 = corner[A(v, u)] / 2pi`
      (so `∫∫ 1/r / 2pi = s1 + s2` and `∫∫ x^2/r^3 / 2pi = s2`);
    - `sxy = corner[-r] / 2pi` (`∫∫ x y / r^3`);
    - `szx = corner[v ln r + u atan(v/u)] / 2pi` (`∫∫ x / r^2`), and `szy` the same
      with x and y swapped.

    `xp` is the array namespace: `jax.numpy` (traceable) or `numpy` (float64 even when
    JAX runs in float32: far from the load the corner sums cancel to a small fraction
    of their terms, so they need double precision).
    """
    a, b = dx / 2, dy / 2
    two_pi = 2 * np.pi
    s1 = _corner_sum(_a, x, y, a, b, xp) / two_pi
    s2 = _corner_sum(lambda u, v, xp: _a(v, u, xp), x, y, a, b, xp) / two_pi
    sxy = _corner_sum(_minus_r, x, y, a, b, xp) / two_pi
    szx = _corner_sum(_c, x, y, a, b, xp) / two_pi
    szy = _corner_sum(lambda u, v, xp: _c(v, u, xp), x, y, a, b, xp) / two_pi
    return s1, s2, sxy, szx, szy


def combine(base, poisson):
    """Assemble the `(3, 3, ...)` coefficient array from `base_integrals` and `poisson`.

    `C[i, j]` is displacement `i` due to traction `j`, order `(x, y, z)`, unit shear
    modulus:

    - `zz = (1 - nu)(s1 + s2)`; `xx = (1 - nu) s1 + s2`; `yy = s1 + (1 - nu) s2`;
    - `xy = yx = nu sxy`;
    - `zx = (1 - 2nu)/2 szx = -xz`; `zy = (1 - 2nu)/2 szy = -yz`.
    """
    s1, s2, sxy, szx, szy = base
    nu = poisson
    c = 0.5 * (1 - 2 * nu)
    xx = (1 - nu) * s1 + s2
    yy = s1 + (1 - nu) * s2
    zz = (1 - nu) * (s1 + s2)
    xy = nu * sxy
    zx, zy = c * szx, c * szy
    return jnp.stack(
        [
            jnp.stack([xx, xy, -zx]),
            jnp.stack([xy, yy, -zy]),
            jnp.stack([zx, zy, zz]),
        ]
    )


def influence_coefficients(x, y, dx, dy, poisson):
    """Displacements at `(x, y)` due to unit uniform tractions on the cell at the
    origin.

    **Arguments:**

    - `x`, `y`: field-point coordinates relative to the loaded cell's centre [length],
      any broadcastable shapes.
    - `dx`, `dy`: cell side lengths [length].
    - `poisson`: Poisson's ratio of the half-space.

    **Returns:** `C` of shape `(3, 3) + shape`, `C[i, j]` = displacement `i` (x, y, z;
    z into the body) per unit traction `j` for unit shear modulus [length].
    """
    x, y = jnp.broadcast_arrays(jnp.asarray(x), jnp.asarray(y))
    return combine(base_integrals(x, y, dx, dy), poisson)
