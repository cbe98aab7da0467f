"""Tests of `jc.influence_coefficients` against quadrature of the point-force kernels.

`C[i, j](x, y)` is the displacement `i` (x, y, z; z into the body) at the surface point
`(x, y)` due to a uniform unit traction `j` on the cell `[-dx/2, dx/2] x [-dy/2, dy/2]`
of a half-space with unit shear modulus. The reference values below integrate the
Boussinesq/Cerruti point-force kernels of Johnson (1985) (written out here
independently of the library) numerically over the cell with `scipy.integrate`.
"""

import functools

import numpy as np
import pytest
from scipy.integrate import quad_vec

import jaxcontact as jc


POISSONS = (0.0, 0.3, 0.5, -0.4)
CELLS = {"square": (1.0, 1.0), "rect": (1.0, 0.6)}

# Quadrature tolerance (far below the test tolerance of 1e-10).
_QUAD = dict(epsabs=1e-15, epsrel=1e-13, norm="max")


# --------------------------------------------------------------------------------------
# Reference: point-force kernels (Johnson 1985, eqs. 3.19, 3.86-3.87)
# --------------------------------------------------------------------------------------


def point_force_kernels(x, y, nu):
    """`K[..., i, j]`: displacement i at `(x, y)` per unit point force j at the origin.

    Unit shear modulus, order (x, y, z), z into the body; `nu` is a 1-D array of
    Poisson's ratios (leading axis of the result). `x`, `y` are scalars.
    """
    nu = np.asarray(nu, dtype=float)
    r2 = x * x + y * y
    r = np.sqrt(r2)
    r3 = r2 * r
    two_pi = 2 * np.pi
    four_pi = 4 * np.pi
    K = np.empty(nu.shape + (3, 3))
    # Tangential force Q_x (column 0).
    K[..., 0, 0] = ((1 - nu) / r + nu * x * x / r3) / two_pi
    K[..., 1, 0] = nu * x * y / (two_pi * r3)
    K[..., 2, 0] = (1 - 2 * nu) * x / (four_pi * r2)
    # Tangential force Q_y (column 1): Q_x with x and y swapped.
    K[..., 0, 1] = nu * x * y / (two_pi * r3)
    K[..., 1, 1] = ((1 - nu) / r + nu * y * y / r3) / two_pi
    K[..., 2, 1] = (1 - 2 * nu) * y / (four_pi * r2)
    # Normal force P (column 2).
    K[..., 0, 2] = -(1 - 2 * nu) * x / (four_pi * r2)
    K[..., 1, 2] = -(1 - 2 * nu) * y / (four_pi * r2)
    K[..., 2, 2] = (1 - nu) / (two_pi * r)
    return K


# Gauss-Legendre rule on [0, 1] for the radial integrals (see `_polar_cell_integral`).
_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(8)
_GL_NODES = 0.5 * (_GL_NODES + 1)
_GL_WEIGHTS = 0.5 * _GL_WEIGHTS


def _polar_cell_integral(px, py, dx, dy, nus):
    """Integral of the kernels over the cell for a field point inside it or on its edge.

    Polar coordinates centred on the field point P: the rectangle is split into four
    triangles (P, edge). In each, a source point is `P + rho (cos t, sin t)`, so the
    kernel argument is `P - source = -rho (cos t, sin t)` and the area element
    `rho drho dt` cancels the 1/r singularity: the integrand `K rho` is bounded (the
    odd kernels x/r^2 become bounded functions of the angle). The angular integral is
    adaptive (`quad_vec`); the radial one, from 0 to the edge, uses an 8-point
    Gauss-Legendre rule, which is exact here: every kernel is homogeneous of degree -1,
    so `K rho` does not depend on `rho`.
    """
    a, b = dx / 2, dy / 2
    corners = [(a, b), (-a, b), (-a, -b), (a, -b)]  # counter-clockwise
    total = np.zeros((len(nus), 3, 3))
    for k in range(4):
        (x1, y1), (x2, y2) = corners[k], corners[(k + 1) % 4]
        # Outward unit normal of the edge and distance from P to its line.
        nx, ny = y2 - y1, -(x2 - x1)
        norm = np.hypot(nx, ny)
        nx, ny = nx / norm, ny / norm
        h = nx * (x1 - px) + ny * (y1 - py)
        if h <= 0:  # P lies on this edge: the triangle is empty.
            continue
        t1 = np.arctan2(y1 - py, x1 - px)
        t2 = np.arctan2(y2 - py, x2 - px)
        if t2 < t1:
            t2 += 2 * np.pi

        def over_rho(t, nx=nx, ny=ny, h=h):
            c, s = np.cos(t), np.sin(t)
            rho_max = h / (nx * c + ny * s)
            out = np.zeros((len(nus), 3, 3))
            for node, weight in zip(_GL_NODES, _GL_WEIGHTS):
                rho = node * rho_max
                kernel = point_force_kernels(-rho * c, -rho * s, nus)
                out += weight * rho_max * rho * kernel
            return out

        total += quad_vec(over_rho, t1, t2, **_QUAD)[0]
    return total


def _cartesian_cell_integral(px, py, dx, dy, nus):
    """Integral of the kernels over the cell for a field point outside it (smooth)."""
    a, b = dx / 2, dy / 2

    def over_y(xs):
        return quad_vec(
            lambda ys: point_force_kernels(px - xs, py - ys, nus), -b, b, **_QUAD
        )[0]

    return quad_vec(over_y, -a, a, **_QUAD)[0]


@functools.cache
def reference(px, py, dx, dy):
    """Quadrature reference `(len(POISSONS), 3, 3)` at the field point `(px, py)`."""
    inside = abs(px) <= dx / 2 and abs(py) <= dy / 2
    integral = _polar_cell_integral if inside else _cartesian_cell_integral
    return integral(px, py, dx, dy, np.asarray(POISSONS))


# Field points in units of the cell sides (dx, dy), relative to the loaded cell centre.
POINTS = {
    "centre": (0.0, 0.0),
    "inside": (0.3, -0.15),
    "inside_near_corner": (-0.45, 0.4),
    "on_edge": (0.5, 0.2),
    "on_corner": (0.5, -0.5),
    "edge_neighbour_x": (1.0, 0.0),
    "edge_neighbour_-x": (-1.0, 0.0),
    "edge_neighbour_y": (0.0, 1.0),
    "corner_neighbour": (1.0, 1.0),
    "corner_neighbour_2": (-1.0, -1.0),
    "near": (2.0, -1.0),
    "far": (7.0, -4.0),
    "very_far": (-30.0, 20.0),
}


@pytest.mark.parametrize("poisson", POISSONS)
@pytest.mark.parametrize("cell", list(CELLS), ids=list(CELLS))
@pytest.mark.parametrize("point", list(POINTS), ids=list(POINTS))
def test_matches_quadrature_of_point_force_kernels(point, cell, poisson):
    """All nine coefficients agree with quadrature to 1e-10 of the largest one.

    Measured: <= 1.1e-15 for points within two cells of the load, 3e-14 at 7 cells and
    4e-13 at 30 cells (rounding: the closed-form corner sums cancel more and more with
    distance).
    """
    dx, dy = CELLS[cell]
    fx, fy = POINTS[point]
    px, py = fx * dx, fy * dy
    ref = reference(px, py, dx, dy)[POISSONS.index(poisson)]
    got = np.asarray(jc.influence_coefficients(px, py, dx, dy, poisson))
    assert got.shape == (3, 3)
    assert np.all(np.isfinite(got))
    err = np.max(np.abs(got - ref)) / np.max(np.abs(ref))
    assert err < 1e-10, (point, cell, poisson, err)


def test_vectorised_call_matches_scalar_calls():
    """Array arguments broadcast to `(3, 3) + shape`, equal to scalar calls (1e-15)."""
    dx, dy, nu = 1.0, 0.6, 0.3
    x = np.arange(-3, 4, dtype=float)[:, None] * dx
    y = np.arange(-2, 3, dtype=float)[None, :] * dy
    C = np.asarray(jc.influence_coefficients(x, y, dx, dy, nu))
    assert C.shape == (3, 3, 7, 5)
    scale = np.max(np.abs(C))
    for i, j in [(0, 0), (3, 2), (4, 1), (6, 4)]:
        c = np.asarray(jc.influence_coefficients(x[i, 0], y[0, j], dx, dy, nu))
        assert np.max(np.abs(C[:, :, i, j] - c)) <= 1e-15 * scale


# --------------------------------------------------------------------------------------
# Reciprocity, symmetry, and signs
# --------------------------------------------------------------------------------------

OFFSETS = [
    (0, 0),
    (1, 0),
    (0, 1),
    (1, 1),
    (-1, 2),
    (3, -2),
    (7, 5),
    (-12, 9),
    (40, -25),
]


@pytest.mark.parametrize("poisson", POISSONS)
@pytest.mark.parametrize(
    "cell", [(1.0, 1.0), (1.0, 0.6), (2e-5, 1.3e-5)], ids=["square", "rect", "rect_SI"]
)
def test_reciprocal_theorem(cell, poisson):
    """Betti: `C[i, j](d) == C[j, i](-d)` for all i, j.

    Tolerance 1e-14 of the largest coefficient (the self-term C(0)); offsets up to 40
    cells. Measured: <= 2.5e-15.
    """
    dx, dy = cell
    scale = np.max(
        np.abs(np.asarray(jc.influence_coefficients(0.0, 0.0, dx, dy, poisson)))
    )
    for mx, my in OFFSETS:
        x, y = mx * dx, my * dy
        plus = np.asarray(jc.influence_coefficients(x, y, dx, dy, poisson))
        minus = np.asarray(jc.influence_coefficients(-x, -y, dx, dy, poisson))
        err = np.max(np.abs(plus - minus.T)) / scale
        assert err < 1e-14, ((mx, my), err)


def test_incompressible_coupling_vanishes_exactly():
    """For nu = 0.5 the four normal-tangential coefficients are exactly zero."""
    dx, dy = 1.0, 0.6
    mx, my = np.meshgrid(np.arange(-5, 6), np.arange(-4, 5), indexing="ij")
    x, y = mx * dx, my * dy
    # Also an off-centre point and a point on an edge of the loaded cell.
    x = np.concatenate([x.ravel(), [0.3 * dx, 0.5 * dx]])
    y = np.concatenate([y.ravel(), [-0.15 * dy, 0.2 * dy]])
    C = np.asarray(jc.influence_coefficients(x, y, dx, dy, 0.5))
    for i, j in [(0, 2), (1, 2), (2, 0), (2, 1)]:
        assert np.all(C[i, j] == 0.0), (i, j)
    # ...while the other blocks do not vanish.
    assert np.all(C[2, 2] > 0) and np.all(C[0, 0] > 0) and np.all(C[1, 1] > 0)
    # ...and for nu < 0.5 the coupling does not vanish off the axes.
    C3 = np.asarray(jc.influence_coefficients(x, y, dx, dy, 0.3))
    off_axis = (x != 0) & (y != 0)
    assert np.all(np.abs(C3[2, 0][off_axis]) > 0) and np.all(
        np.abs(C3[0, 2][off_axis]) > 0
    )


@pytest.mark.parametrize("poisson", [0.0, 0.3, 0.49, -0.4])
def test_physical_signs(poisson):
    """Under pressure the surface moves radially inward and into the body.

    u_x(p) < 0 at x > 0 (> 0 at x < 0), u_y(p) < 0 at y > 0, u_z(p) > 0 everywhere;
    u_x(q_x) > 0 everywhere; u_z(q_x) > 0 at x > 0 (the reciprocal pair of u_x(p)).
    Strict inequalities off the axes of symmetry.
    """
    dx, dy = 1.0, 0.6
    mx, my = np.meshgrid(np.arange(-6, 7), np.arange(-5, 6), indexing="ij")
    x, y = mx * dx, my * dy
    C = np.asarray(jc.influence_coefficients(x, y, dx, dy, poisson))
    assert np.all(C[0, 2][x > 0] < 0) and np.all(C[0, 2][x < 0] > 0)
    assert np.all(C[1, 2][y > 0] < 0) and np.all(C[1, 2][y < 0] > 0)
    # On the axes of symmetry the in-plane response vanishes (to rounding, 1e-15).
    scale = np.max(np.abs(C))
    assert np.max(np.abs(C[0, 2][x == 0])) <= 1e-15 * scale
    assert np.max(np.abs(C[1, 2][y == 0])) <= 1e-15 * scale
    assert np.all(C[2, 2] > 0)
    assert np.all(C[0, 0] > 0) and np.all(C[1, 1] > 0)
    assert np.all(C[2, 0][x > 0] > 0) and np.all(C[2, 1][y > 0] > 0)
    # Displacement decays away from the load: the self-term is the largest u_z.
    assert np.argmax(C[2, 2]) == np.flatnonzero((x == 0) & (y == 0))[0]
