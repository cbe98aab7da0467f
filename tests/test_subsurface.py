"""Subsurface stresses (`jc.subsurface_stress`): closed-form cell coefficients against
quadrature, the Hertz axis (Huber / Johnson eq. 3.45), tau_1 = 0.31 p0 at z = 0.48 a,
a sliding Hertz contact (Hamilton & Goodman 1966 surface stresses; Cerruti quadrature
on the axis), Holl's rectangle, boundary conditions at z = 0, traced and float32
paths."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import quad

import jaxcontact as jc
from jaxcontact._subsurface import cell_stress


NU = 0.3


def _hertz_grid(n, mu=0.0, a=1.0, p0=1.0, half_width=1.5):
    grid = jc.Grid(shape=(n, n), size=(2 * half_width, 2 * half_width))
    x, y = grid.coordinates()
    p = p0 * jnp.sqrt(jnp.clip(1 - (x * x + y * y) / a**2, 0.0, None))
    shear = jnp.stack([mu * p, jnp.zeros_like(p)])
    return grid, p, shear


# -- cell coefficients against quadrature ----------------------------------------------


def _displacement(load, x, y, z, nu):
    """Boussinesq / Cerruti displacements per unit force, unit shear modulus
    (Johnson 1985, eqs. 3.19 and 3.86-3.87, z into the body)."""
    r = np.sqrt(x * x + y * y + z * z)
    f = 1 / (4 * np.pi)
    if load == "p":
        c = (1 - 2 * nu) / (r * (r + z))
        return np.stack(
            [
                f * (x * z / r**3 - c * x),
                f * (y * z / r**3 - c * y),
                f * (z * z / r**3 + 2 * (1 - nu) / r),
            ]
        )
    if load == "qx":
        d = (1 - 2 * nu) / (r * (r + z) ** 2)
        return np.stack(
            [
                f * (1 / r + x * x / r**3 + (1 - 2 * nu) / (r + z) - d * x * x),
                f * (x * y / r**3 - d * x * y),
                f * (x * z / r**3 + (1 - 2 * nu) * x / (r * (r + z))),
            ]
        )
    ux, uy, uz = _displacement("qx", y, x, z, nu)
    return np.stack([uy, ux, uz])


def _quadrature_stress(load, point, dx, dy, nu, h=1e-4, order=120):
    """Stress from Gauss quadrature of the displacement over the cell + central
    differences + Hooke's law (unit shear modulus)."""
    g, w = np.polynomial.legendre.leggauss(order)
    xi, eta = np.meshgrid(g * dx / 2, g * dy / 2, indexing="ij")
    weight = np.outer(w, w) * dx * dy / 4

    def u(p):
        return np.sum(
            _displacement(load, p[0] - xi, p[1] - eta, p[2], nu) * weight, axis=(1, 2)
        )

    grad = np.zeros((3, 3))
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        grad[:, k] = (u(point + e) - u(point - e)) / (2 * h)
    eps = 0.5 * (grad + grad.T)
    s = 2 * nu / (1 - 2 * nu) * np.trace(eps) * np.eye(3) + 2 * eps
    return {
        "sxx": s[0, 0],
        "syy": s[1, 1],
        "szz": s[2, 2],
        "sxy": s[0, 1],
        "sxz": s[0, 2],
        "syz": s[1, 2],
    }


@pytest.mark.parametrize(
    "point",
    [
        (0.0, 0.0, 0.5),
        (1.0, 0.0, 0.5),
        (0.3, -1.2, 0.7),
        (-2.5, 1.5, 1.0),
        (3.0, 2.0, 3.0),
        (-1.0, -1.0, 0.6),
    ],
)
def test_cell_coefficients_match_quadrature(point):
    dx, dy = 1.0, 1.3
    x, y, z = point
    c = cell_stress(np.array(x), np.array(y), z, dx, dy, NU, xp=np)
    for load in ("p", "qx", "qy"):
        ref = _quadrature_stress(load, np.array(point), dx, dy, NU)
        for name, value in ref.items():
            # quadrature + finite differences: ~1e-8 absolute (stress per unit traction)
            assert abs(float(c[load][name]) - value) < 1e-6, (load, name)


def test_holl_uniform_rectangle_under_centre():
    """Holl (1940): s_zz below the centre of a uniformly loaded 2A x 2B rectangle."""
    dx, dy = 2.0, 3.0
    a, b = dx / 2, dy / 2
    for z in (0.1, 0.7, 2.0, 5.0):
        r = np.sqrt(a * a + b * b + z * z)
        ref = -(2 / np.pi) * (
            np.arctan(a * b / (z * r))
            + a * b * z / r * (1 / (a * a + z * z) + 1 / (b * b + z * z))
        )
        c = cell_stress(np.array(0.0), np.array(0.0), z, dx, dy, 0.25, xp=np)
        assert abs(float(c["p"]["szz"]) - ref) < 1e-12


# -- Hertz ---------------------------------------------------------------------------


def test_hertz_axis_huber():
    """Along the axis of a Hertz contact (Johnson 1985, eq. 3.45):
    s_z = -p0 / (1 + z^2/a^2),
    s_r = -p0 [(1+nu)(1 - (z/a) atan(a/z)) - 1/(2(1+z^2/a^2))].
    Odd n puts a cell centre on the axis."""
    n = 129
    grid, p, _ = _hertz_grid(n)
    z = np.array([0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0, 1.5, 2.0])
    s = jc.subsurface_stress(grid, p, poisson=NU, depth=z)
    c = n // 2
    assert float(grid.x[c]) == 0.0
    sz_ref = -1 / (1 + z**2)
    sr_ref = -((1 + NU) * (1 - z * np.arctan(1 / z)) - 0.5 / (1 + z**2))
    np.testing.assert_allclose(np.asarray(s.szz[:, c, c]), sz_ref, rtol=0, atol=1e-3)
    np.testing.assert_allclose(np.asarray(s.sxx[:, c, c]), sr_ref, rtol=0, atol=1e-3)
    np.testing.assert_allclose(np.asarray(s.syy[:, c, c]), sr_ref, rtol=0, atol=1e-3)
    # axisymmetry: no shear stresses on the axis
    for comp in (s.sxy, s.sxz, s.syz):
        assert np.max(np.abs(np.asarray(comp[:, c, c]))) < 1e-10


def test_hertz_max_shear_031_at_048a():
    """Johnson (1985) section 3.3: tau_1 = 0.31 p0 at z = 0.48 a for nu = 0.3."""
    n = 65
    grid, p, _ = _hertz_grid(n)
    z = np.linspace(0.40, 0.56, 9)
    s = jc.subsurface_stress(grid, p, poisson=NU, depth=z)
    tau = np.asarray(s.max_shear[:, n // 2, n // 2])
    k = int(np.argmax(tau))
    assert abs(tau[k] - 0.31) < 0.003
    assert abs(z[k] - 0.48) <= 0.021 and 0 < k < len(z) - 1  # an interior maximum
    # the maximum over the whole plane sits on the axis (within a cell)
    plane = np.asarray(s.max_shear[k])
    assert plane.max() <= tau[k] + 2e-3


@pytest.mark.slow
def test_hertz_from_solve_normal():
    """Pressure from the contact solver (not the analytic one): same axis stresses."""
    n = 65
    hertz = jc.Hertz(
        radius=jnp.asarray(10.0),
        force=jnp.asarray(1.0),
        shear_modulus=jnp.asarray(1.0),
        poisson=jnp.asarray(NU),
    )
    a, p0 = float(hertz.contact_radius), float(hertz.peak_pressure)
    grid = jc.Grid(shape=(n, n), size=(3 * a, 3 * a))
    sol = jc.solve_normal(
        grid,
        jc.Sphere(radius=10.0),
        jc.Elastic(shear_modulus=1.0, poisson=NU),
        force=1.0,
    )
    assert bool(sol.converged)
    z = np.array([0.25, 0.5, 1.0]) * a
    s = jc.subsurface_stress(grid, sol.pressure, poisson=NU, depth=z)
    c = n // 2
    np.testing.assert_allclose(
        np.asarray(s.szz[:, c, c]) / p0, -1 / (1 + (z / a) ** 2), atol=1e-2
    )


# -- sliding Hertz contact -------------------------------------------------------------


def test_sliding_hertz_surface_and_axis():
    """q = mu p along x. Inside the contact, on y = 0 at the surface, Hamilton &
    Goodman (1966) (Johnson 1985 section 7.1) give the friction part
    s_x = -pi (4 + nu) mu p0 x / (8 a), s_y = -3 pi nu mu p0 x / (8 a), added to the
    Hertz surface stresses (Johnson eq. 3.41). On the axis the friction part is
    s_xz(z) = -(3/2) mu p0 z int_0^a sqrt(1 - r^2/a^2) r^3 / (r^2 + z^2)^(5/2) dr
    (Cerruti's point-force s_xz = -3 Q x^2 z / (2 pi rho^5) integrated by
    quadrature)."""
    n, mu = 129, 0.25
    grid, p, shear = _hertz_grid(n, mu=mu)
    depths = np.array([0.0, 0.25, 0.5, 1.0])
    s = jc.subsurface_stress(grid, p, shear, poisson=NU, depth=depths)
    c = n // 2
    x = np.asarray(grid.x)
    inside = (np.abs(x) < 0.9) & (x != 0)  # (x = 0: the 0/0 limit of b)
    r = np.abs(x[inside])
    t = np.sqrt(1 - r**2)
    b = (1 - 2 * NU) / 3 * (1 - t**3) / r**2
    sxx_ref = (b - t) - np.pi * (4 + NU) * mu * x[inside] / 8
    syy_ref = -(b + 2 * NU * t) - 3 * np.pi * NU * mu * x[inside] / 8
    np.testing.assert_allclose(np.asarray(s.sxx[0, inside, c]), sxx_ref, atol=6e-3)
    np.testing.assert_allclose(np.asarray(s.syy[0, inside, c]), syy_ref, atol=6e-3)
    for k, z in enumerate(depths[1:], start=1):
        integral = quad(
            lambda q: np.sqrt(1 - q * q) * q**3 / (q * q + z * z) ** 2.5, 0.0, 1.0
        )[0]
        ref = -1.5 * mu * z * integral
        assert abs(float(s.sxz[k, c, c]) - ref) < 2e-4
    # friction breaks the symmetry (Hamilton 1983): the largest surface tension is at
    # the trailing edge x = -a, the subsurface von Mises peak moves ahead (x > 0)
    assert abs(x[np.argmax(np.asarray(s.sxx[0, :, c]))] + 1.0) < 0.05
    assert x[np.argmax(np.asarray(s.von_mises[1, :, c]))] > 0.05


# -- limits, boundary conditions, paths -----------------------------------------------


def test_surface_tractions_are_reproduced_at_z0():
    """At z = 0 below every loaded cell: s_zz = -p, s_xz = -q_x, s_yz = -q_y."""
    key = jax.random.PRNGKey(0)
    k1, k2 = jax.random.split(key)
    grid = jc.Grid(shape=(12, 10), size=(1.0, 0.8))
    p = jax.random.uniform(k1, (12, 10), dtype=jnp.float64)
    q = jax.random.normal(k2, (2, 12, 10), dtype=jnp.float64)
    s = jc.subsurface_stress(grid, p, q, poisson=0.25, depth=0.0)
    np.testing.assert_allclose(np.asarray(s.szz), -np.asarray(p), atol=1e-12)
    np.testing.assert_allclose(np.asarray(s.sxz), -np.asarray(q[0]), atol=1e-12)
    np.testing.assert_allclose(np.asarray(s.syz), -np.asarray(q[1]), atol=1e-12)


def test_uniform_pressure_large_patch():
    """A uniform pressure on a patch much larger than the depth: s_zz = -p under its
    centre (equilibrium); deeper, s_zz lies between the values of the inscribed and
    circumscribed uniformly loaded discs (Johnson 1985, section 3.4)."""
    n, pressure = 64, 2.5
    grid = jc.Grid(shape=(n, n), size=(1.0, 1.0))
    p = jnp.full((n, n), pressure)
    s = jc.subsurface_stress(grid, p, poisson=NU, depth=jnp.array([1e-3, 0.02]))
    c = n // 2
    centre = np.asarray(s.szz[:, c - 1 : c + 1, c - 1 : c + 1]).mean(axis=(1, 2))
    np.testing.assert_allclose(centre, -pressure, rtol=2e-3)
    # a uniform disc of radius R (Johnson 3.4): s_z = -p (1 - z^3 / (R^2 + z^2)^1.5);
    # the square of side 1 lies between the discs R = 0.5 and R = 0.5 sqrt(2)
    z = 0.4
    s = jc.subsurface_stress(grid, p, poisson=NU, depth=z)
    val = float(np.asarray(s.szz[c - 1 : c + 1, c - 1 : c + 1]).mean())
    bounds = [
        -pressure * (1 - z**3 / (r * r + z * z) ** 1.5) for r in (0.5, 0.5 * 2**0.5)
    ]
    assert bounds[1] < val < bounds[0]


def test_traced_path_and_depth_map_match_concrete():
    n = 16
    grid, p, shear = _hertz_grid(n, mu=0.3)
    z = jnp.array([0.0, 0.2, 0.6])
    ref = jc.subsurface_stress(grid, p, shear, poisson=NU, depth=z)
    traced = jax.jit(
        lambda g, p, q, z: jc.subsurface_stress(g, p, q, poisson=NU, depth=z)
    )(grid, p, shear, z)
    for name in ("sxx", "syy", "szz", "sxy", "sxz", "syz"):
        np.testing.assert_allclose(
            getattr(traced, name), getattr(ref, name), atol=1e-12
        )
    one = jc.subsurface_stress(grid, p, shear, poisson=NU, depth=0.2)
    assert one.sxx.shape == (n, n)
    np.testing.assert_allclose(one.von_mises, ref.von_mises[1], atol=1e-12)


@pytest.mark.slow
def test_gradients_match_finite_differences():
    """d/d(poisson) and d/d(depth) by jax.grad (traced kernel path) against central
    differences of the concrete path; vmap over depths."""
    grid, p, shear = _hertz_grid(10, mu=0.3)

    def f(nu, z):
        s = jc.subsurface_stress(grid, p, shear, poisson=nu, depth=z)
        return jnp.sum(s.von_mises**2)

    g_nu, g_z = jax.grad(f, argnums=(0, 1))(0.3, 0.4)
    # vmap over scalar depths = one call with an array of depths
    z = jnp.array([0.0, 0.4])
    single = jax.vmap(
        lambda z: jc.subsurface_stress(grid, p, shear, poisson=0.3, depth=z).sxx
    )(z)
    np.testing.assert_allclose(
        single,
        jc.subsurface_stress(grid, p, shear, poisson=0.3, depth=z).sxx,
        atol=1e-12,
    )
    h = 1e-5
    fd_nu = (f(0.3 + h, 0.4) - f(0.3 - h, 0.4)) / (2 * h)
    fd_z = (f(0.3, 0.4 + h) - f(0.3, 0.4 - h)) / (2 * h)
    np.testing.assert_allclose(float(g_nu), float(fd_nu), rtol=1e-6)
    np.testing.assert_allclose(float(g_z), float(fd_z), rtol=1e-6)


def test_incompressible_and_float32():
    n = 33
    grid, p, shear = _hertz_grid(n, mu=0.2)
    s64 = jc.subsurface_stress(grid, p, shear, poisson=0.5, depth=jnp.array([0.3, 0.8]))
    assert all(
        np.isfinite(np.asarray(getattr(s64, c))).all()
        for c in ("sxx", "syy", "szz", "sxy", "sxz", "syz")
    )
    grid32 = jc.Grid(shape=(n, n), size=jnp.asarray([3.0, 3.0], dtype=jnp.float32))
    s32 = jc.subsurface_stress(
        grid32,
        p.astype(jnp.float32),
        shear.astype(jnp.float32),
        poisson=0.5,
        depth=jnp.array([0.3, 0.8], dtype=jnp.float32),
    )
    assert s32.sxx.dtype == jnp.float32
    for name in ("sxx", "syy", "szz", "sxy", "sxz", "syz"):
        np.testing.assert_allclose(
            np.asarray(getattr(s32, name)), np.asarray(getattr(s64, name)), atol=2e-5
        )


def test_bad_input():
    grid, p, shear = _hertz_grid(8)
    with pytest.raises(ValueError, match="depth"):
        jc.subsurface_stress(grid, p, poisson=NU, depth=-0.1)
    with pytest.raises(ValueError, match="pressure"):
        jc.subsurface_stress(grid, p[:4], poisson=NU, depth=0.1)
    with pytest.raises(ValueError, match="shear"):
        jc.subsurface_stress(grid, p, shear[:1], poisson=NU, depth=0.1)
    with pytest.raises(ValueError, match="poisson"):
        jc.subsurface_stress(grid, p, poisson=0.7, depth=0.1)
    with pytest.raises(ValueError, match="periodic"):
        jc.subsurface_stress(
            jc.Grid((8, 8), 1.0, periodic=True), p, poisson=NU, depth=0.1
        )
    with pytest.raises(TypeError, match="grid"):
        jc.subsurface_stress("grid", p, poisson=NU, depth=0.1)
    with pytest.raises(ValueError, match="depth"):
        jc.subsurface_stress(grid, p, poisson=NU, depth=jnp.ones((2, 2)))
