"""Cones, blunted cones, tabulated tips and pyramids on the grid solver.

Closed forms (E* = 2 G / (1 - nu), a rigid indenter on one elastic half-space):
Sneddon (1965) for a cone of half-angle alpha at the depth d: contact radius
a = 2 d tan(alpha) / pi, load W = (2 / pi) E* d^2 tan(alpha); Hertz for a paraboloid of
radius R: W = (4 / 3) E* sqrt(R) d^(3/2). A pyramid has no closed form: it is compared
with its equal-area cone, whose load it exceeds by a few percent (King 1987; Larsson
et al. 1996 for a four-sided pyramid: 1.01-1.05).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxcontact as jc


G, NU = 1e3, 0.5  # Pa: a soft cell-like solid, incompressible
E_STAR = 2 * G / (1 - NU)
ALPHA = 0.35  # rad: an AFM cone
DEPTH = 1e-6  # m
A_SNEDDON = 2 * DEPTH * np.tan(ALPHA) / np.pi
W_SNEDDON = 2 / np.pi * E_STAR * DEPTH**2 * np.tan(ALPHA)


def sneddon_load(alpha, depth):
    return 2 / np.pi * E_STAR * depth**2 * np.tan(alpha)


@pytest.mark.parametrize("dtype", [jnp.float64, jnp.float32])
def test_cone_follows_sneddon_under_both_controls(dtype):
    # 64^2 over 3 a: measured 7e-5 (load), 3e-5 (approach) and 0.4 % (contact area)
    # in float64; the tip's logarithmic pressure singularity sits in one cell.
    grid = jc.Grid((64, 64), jnp.asarray(3 * A_SNEDDON, dtype))
    material = jc.Elastic(jnp.asarray(G, dtype), jnp.asarray(NU, dtype))
    cone = jc.Cone(jnp.asarray(ALPHA, dtype))
    tol = 5e-4 if dtype == jnp.float64 else 2e-3
    by_depth = jc.solve_normal(grid, cone, material, approach=DEPTH)
    assert float(by_depth.normal_force) / W_SNEDDON == pytest.approx(1, abs=tol)
    area = float(jnp.sum(by_depth.contact)) * float(grid.cell_area)
    assert area / (np.pi * A_SNEDDON**2) == pytest.approx(1, abs=0.02)
    by_load = jc.solve_normal(grid, cone, material, force=W_SNEDDON)
    assert float(by_load.approach) / DEPTH == pytest.approx(1, abs=tol)
    assert by_load.pressure.dtype == dtype


def test_blunted_cone_is_a_sphere_below_its_cap_and_a_cone_far_beyond():
    radius = 2e-6
    tip = jc.BluntedCone(ALPHA, radius)
    # Shallow (a / R = 0.03): the contact stays on the spherical cap, Hertz to
    # O(a^2 / R^2) (measured 2e-4), and the paraboloid of jc.Sphere alike.
    shallow = 1e-3 * radius
    a_hertz = np.sqrt(radius * shallow)
    grid = jc.Grid((64, 64), 3 * a_hertz)
    sol = jc.solve_normal(grid, tip, jc.Elastic(G, NU), approach=shallow)
    hertz = 4 / 3 * E_STAR * np.sqrt(radius) * shallow**1.5
    assert float(sol.normal_force) / hertz == pytest.approx(1, abs=2e-3)
    sphere = jc.solve_normal(grid, jc.Sphere(radius), jc.Elastic(G, NU),
                             approach=shallow)
    assert float(sol.normal_force) == pytest.approx(float(sphere.normal_force),
                                                    rel=1e-3)
    # The profile is continuous with a continuous slope where the cap meets the
    # flanks, at b = R cos(alpha).
    b = radius * np.cos(ALPHA)
    r = jnp.array([b * (1 - 1e-9), b * (1 + 1e-9)])
    h = tip.profile(r)
    assert float(h[1] - h[0]) == pytest.approx(2e-9 * b / np.tan(ALPHA), rel=1e-3)
    # Deep (20 x offset): between the sharp cone whose apex is the tip's and the one
    # whose apex is the flanks' (offset = R (1 - sin(alpha)) / sin(alpha) below it).
    offset = radius * (1 - np.sin(ALPHA)) / np.sin(ALPHA)
    deep = 20 * offset
    a_cone = 2 * (deep + offset) * np.tan(ALPHA) / np.pi
    grid = jc.Grid((64, 64), 3 * a_cone)
    sol = jc.solve_normal(grid, tip, jc.Elastic(G, NU), approach=deep)
    load = float(sol.normal_force)
    assert sneddon_load(ALPHA, deep) < load < sneddon_load(ALPHA, deep + offset)


def test_a_tabulated_profile_is_its_interpolant():
    r = jnp.linspace(0.0, 5e-6, 11)
    tip = jc.AxisymmetricProfile(r, r / np.tan(ALPHA))
    grid = jc.Grid((33, 33), 6e-6)  # odd: a cell centred on the axis
    np.testing.assert_allclose(tip.gap(grid), jc.Cone(ALPHA).gap(grid), rtol=1e-12,
                               atol=1e-20)
    # Beyond the table: along the last segment's slope.
    assert float(tip.profile(jnp.asarray(8e-6))) == pytest.approx(
        8e-6 / np.tan(ALPHA), rel=1e-12)


def test_a_pyramid_carries_a_few_percent_more_than_its_equal_area_cone():
    # Measured: 1.0275 at 64^2 and 1.0270 at 128^2 (the grid's error is below the
    # difference); the cone on the same grid equals Sneddon to 1e-4.
    pyramid = jc.Pyramid(ALPHA, sides=4)
    cone = pyramid.equivalent_cone()
    tan_ratio = np.tan(float(cone.half_angle)) / np.tan(ALPHA)
    assert tan_ratio**2 == pytest.approx(4 / np.pi, rel=1e-12)  # equal areas
    a_cone = 2 * DEPTH * np.tan(float(cone.half_angle)) / np.pi
    grid = jc.Grid((64, 64), 3.5 * a_cone)
    sol = jc.solve_normal(grid, pyramid, jc.Elastic(G, NU), approach=DEPTH)
    ratio = float(sol.normal_force) / sneddon_load(float(cone.half_angle), DEPTH)
    assert 1.01 < ratio < 1.05
    # Its level sets are squares: the gap is d / tan(alpha) all along the side x = d,
    # and a quarter turn of rotation / 2 puts a corner on the x axis.
    one = jc.Grid((3, 3), 3e-9)  # the centre cell at the origin
    d = 1e-6
    for y in (0.0, 0.5 * d, -d):
        gap = jc.Pyramid(ALPHA, centre=(-d, -y)).gap(one)[1, 1]
        assert float(gap) == pytest.approx(d / np.tan(ALPHA), rel=1e-9)
    turned = jc.Pyramid(ALPHA, rotation=np.pi / 4, centre=(-d, 0.0)).gap(one)[1, 1]
    assert float(turned) == pytest.approx(d * np.cos(np.pi / 4) / np.tan(ALPHA),
                                          rel=1e-9)


def test_gradient_of_the_cone_load_with_respect_to_its_angle():
    # dW/dalpha = (2 / pi) E* d^2 / cos(alpha)^2 (Sneddon), through `jc.solve` (the
    # implicit gradient) on a grid with a cell centred on the apex.
    grid = jc.Grid((33, 33), 3 * A_SNEDDON)
    material = jc.Elastic(G, NU)

    def load(alpha):
        scene = jc.Scene(grid=grid, indenter=jc.Cone(alpha), material=material,
                         times=jnp.array([0.0]), normal=jc.Displacement(DEPTH))
        # The grid's (the rings': tests/test_rings.py)
        return jc.solve(scene, solver=jc.Rounds()).normal_force[-1]

    slope = float(jax.grad(load)(jnp.asarray(ALPHA)))
    exact = 2 / np.pi * E_STAR * DEPTH**2 / np.cos(ALPHA) ** 2
    assert slope / exact == pytest.approx(1, abs=0.01)  # the grid's: 0.64 % measured
    h = 1e-5
    central = (float(load(ALPHA + h)) - float(load(ALPHA - h))) / (2 * h)
    assert slope == pytest.approx(central, rel=1e-5)


@pytest.mark.parametrize("make, fragment", [
    (lambda: jc.Cone(0.0), "half_angle must be in (0, 1.5708)"),
    (lambda: jc.Cone(np.pi / 2), "half_angle must be in (0, 1.5708)"),
    (lambda: jc.Cone(float("nan")), "half_angle must be in"),
    (lambda: jc.BluntedCone(0.3, -1e-6), "tip_radius must be finite and > 0"),
    (lambda: jc.Pyramid(0.3, sides=2), "sides must be >= 3, got 2"),
    (lambda: jc.AxisymmetricProfile([1e-6, 2e-6], [0.0, 1e-6]),
     "radii must start at 0 (the axis) and increase"),
    (lambda: jc.AxisymmetricProfile([0.0, 2e-6, 1e-6], [0.0, 1e-6, 2e-6]),
     "radii must start at 0 (the axis) and increase"),
    (lambda: jc.AxisymmetricProfile([0.0, 1e-6], [0.0, float("nan")]),
     "heights must be finite"),
])
def test_bad_tips_are_refused_by_name(make, fragment):
    with pytest.raises(ValueError, match=fragment.replace("(", r"\(").replace(
            ")", r"\)")):
        make()
