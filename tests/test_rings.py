"""The axisymmetric ring solver (`_ring_operator`, `_solver/rings`, `_solve_rings`):
its operator against the disc's closed form, its solutions against Hertz, Sneddon's
cone, Lee & Radok, Ting (unloading) and the 2-D grid solver, its gradients against
central differences, float32, jit and vmap.

Nondimensional units: sphere radius 1, shear moduli of order 1, ring radius 0.5. The
convergence studies in the number of rings and of the grid are `slow`
(benchmarks/notes/rings.md records their orders).
"""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq
from scipy.special import ellipe, ellipk

import jaxcontact as jc
from jaxcontact import AxisymmetricProfile, BluntedCone, Cone
from jaxcontact._ring_operator import RingOperator, disc_integral
from jaxcontact._solve_rings import solve_axisymmetric
from jaxcontact._solver.base import StepGuess, run
from jaxcontact._solver.rings import RingPolonskyKeer, RingProblem


R, G, NU = 1.0, 1.0, 0.3
E_STAR = 2 * G / (1 - NU)
GRID = jc.Grid((32, 32), 1.2)  # the scenes' grid: only its dtype matters to rings


def disc_displacement(r, a):
    """Johnson (1985) Eq. 3.39, unit shear modulus without `1 - nu`: the normal
    displacement at `r` of a unit pressure on the disc of radius `a`."""
    if r <= a:
        return 2 * a / np.pi * ellipe((r / a) ** 2)
    m = (a / r) ** 2
    return 2 * r / np.pi * (ellipe(m) - (1 - m) * ellipk(m))


def hertz_scene(force, rings_grid=GRID, material=None, times=None):
    times = jnp.zeros(1) if times is None else times
    material = jc.Elastic(G, NU) if material is None else material
    return jc.Scene(rings_grid, jc.Sphere(R), material, times, jc.Force(force))


def ting_force(t, nu, mu_inf, mu_0, tau, d_max, t_m):
    """Ting (1966): the force on a rigid paraboloid (radius `R`) whose approach rises
    at a constant rate to `d_max` at `t_m` and falls back at the same rate, on a Zener
    solid. Loading: Lee & Radok, `P = c int_0^t G(t - s) d(delta^3/2)`, `c = 8 R^1/2 /
    (3 (1 - nu))`; unloading: the same integral up to `t1 <= t_m` given by
    `int_t1^t G(t - s) d delta(s) = 0`, and no contact when no such `t1 >= 0`."""
    tr = tau * mu_0 / mu_inf
    rate = d_max / t_m

    def relaxation(s):
        return mu_0 + (mu_inf - mu_0) * np.exp(-s / tr)

    def integral(a, b):  # int_a^b G(t - s) ds
        return mu_0 * (b - a) + (mu_inf - mu_0) * tr * (
            np.exp(-(t - b) / tr) - np.exp(-(t - a) / tr))

    t1 = t
    if t > t_m:
        def balance(t1):
            return integral(t1, t_m) - integral(t_m, t)

        if balance(0.0) <= 0:
            return 0.0
        t1 = brentq(balance, 0.0, t_m, xtol=1e-14)
    value = quad(lambda s: relaxation(t - s) * 1.5 * rate**1.5 * np.sqrt(s), 0, t1,
                 limit=200)[0]
    return 8 * np.sqrt(R) / (3 * (1 - nu)) * value


# ---- the operator -----------------------------------------------------------------


def test_disc_integral_matches_quadrature_of_johnson():
    """`D(a, b)` (closed form) equals the integral of Johnson's disc displacement over
    the disc `b`, to quadrature accuracy, for discs inside, equal and outside."""
    for a, b in [(1.0, 0.3), (1.0, 1.0), (0.5, 2.0), (1.0, 0.999)]:
        numeric = quad(lambda r: disc_displacement(r, a) * 2 * np.pi * r, 0, b,
                       limit=200)[0]
        assert float(disc_integral(a, b)) == pytest.approx(numeric, rel=1e-10)


def test_ring_operator_is_the_mean_disc_displacement():
    """A unit pressure on every ring is the disc of the outer radius: each ring's mean
    displacement (a row sum of the matrix) is Johnson's, averaged over the ring by
    quadrature; the energy matrix `areas U` is symmetric positive definite."""
    op = RingOperator.uniform(1.0, 12)
    rows = np.asarray(op.matrix).sum(axis=1)
    e = np.asarray(op.edges)
    for j in range(12):
        area = np.pi * (e[j + 1] ** 2 - e[j] ** 2)
        mean = quad(lambda r: disc_displacement(r, 1.0) * 2 * np.pi * r, e[j],
                    e[j + 1])[0] / area
        assert rows[j] == pytest.approx(mean, rel=1e-10)
    energy = np.asarray(op.areas)[:, None] * np.asarray(op.matrix)
    np.testing.assert_allclose(energy, energy.T, rtol=1e-12, atol=0)
    assert np.linalg.eigvalsh(energy).min() > 0


def test_traced_radius_scales_the_unit_operator():
    """Inside `jit` the radius is traced: the operator is the unit radius's, scaled
    (matrix x s, areas x s^2, inverse x s^-3), equal to the one built in NumPy at
    that radius to round-off."""
    built = RingOperator.uniform(2.5, 16)
    traced = jax.jit(lambda r: RingOperator.uniform(r, 16))(2.5)
    for name in ("edges", "areas", "matrix", "inverse"):
        want = np.asarray(getattr(built, name))
        # the inverse's small entries carry the inversion's round-off (~1e-13 of
        # its largest): compared relative to the largest entry
        np.testing.assert_allclose(getattr(traced, name), want, rtol=0,
                                   atol=1e-12 * np.abs(want).max(), err_msg=name)


def test_ring_operator_bad_input():
    with pytest.raises(ValueError, match="start at 0"):
        RingOperator(np.array([0.1, 0.2, 0.3]))
    with pytest.raises(ValueError, match="radius"):
        RingOperator.uniform(-1.0, 4)
    with pytest.raises(ValueError, match="rings"):
        RingOperator.uniform(1.0, 0)


# ---- elastic closed forms ---------------------------------------------------------


def test_hertz_force_control():
    """Hertz under load control, contact radius 0.25 of a ring radius 0.5 (32 of 64
    rings in contact): approach within 1e-4 (the ring discretisation, second order:
    `test_ring_convergence_order_hertz_and_cone`), contact radius within one ring
    width, and the pressure within 2 % of the peak inside 0.8 of the contact."""
    rings = 64
    hertz = jc.Hertz(R, 4 / 3 * E_STAR * 0.25**3 / R, G, NU)
    sol = solve_axisymmetric(hertz_scene(hertz.force), rings=rings, radius=0.5)
    assert bool(sol.converged[0])
    assert float(sol.approach[0]) == pytest.approx(float(hertz.approach), rel=1e-4)
    width = 0.5 / rings
    a = float(sol.contact_radius[0])
    assert float(hertz.contact_radius) <= a + 1e-12 <= float(
        hertz.contact_radius) + width + 1e-12
    inner = sol.centres < 0.8 * hertz.contact_radius
    error = jnp.where(inner, sol.pressure[0] - hertz.pressure(sol.centres), 0)
    assert float(jnp.max(jnp.abs(error))) < 0.02 * float(hertz.peak_pressure)


def test_cone_sneddon_displacement_control():
    """Sneddon's cone: `W = (2 / pi) E* tan(alpha) delta^2`, contact radius
    `(2 / pi) delta tan(alpha)`; 100 rings, contact radius 0.3 of 0.5."""
    alpha = np.deg2rad(70.0)
    a = 0.3
    delta = np.pi / 2 * a / np.tan(alpha)
    scene = jc.Scene(GRID, Cone(alpha), jc.Elastic(G, NU), jnp.zeros(1),
                     jc.Displacement(delta))
    sol = solve_axisymmetric(scene, rings=100, radius=0.5)
    force = 2 / np.pi * E_STAR * np.tan(alpha) * delta**2
    assert float(sol.normal_force[0]) == pytest.approx(force, rel=1e-3)
    assert a <= float(sol.contact_radius[0]) + 1e-12 <= a + 0.5 / 100 + 1e-12


def test_blunted_cone_between_its_limits():
    """A blunted cone: at a contact inside the cap it is the sphere of the tip radius
    (Hertz, within the cap's departure from the paraboloid); beyond it its profile
    lies between the sharp cone's and the sharp cone's lowered by
    `R (1 - sin alpha) / sin alpha` (the apex it replaces), so its force lies between
    theirs (a lower profile carries more), and nears the lowered cone's as the
    approach grows."""
    alpha, tip = np.deg2rad(60.0), 1.0
    blunt = BluntedCone(alpha, tip)
    material = jc.Elastic(G, NU)
    small = 0.01  # approach: contact radius 0.1, transition at 0.5
    sol = solve_axisymmetric(jc.Scene(GRID, blunt, material, jnp.zeros(1),
                                      jc.Displacement(small)), rings=100, radius=0.5)
    hertz = 4 / 3 * E_STAR * np.sqrt(tip) * small**1.5
    assert float(sol.normal_force[0]) == pytest.approx(hertz, rel=5e-3)
    offset = tip * (1 - np.sin(alpha)) / np.sin(alpha)
    op = RingOperator.uniform(5.0, 100)

    def force(indenter, approach):
        scene = jc.Scene(GRID, indenter, material, jnp.zeros(1),
                         jc.Displacement(approach))
        return float(solve_axisymmetric(scene, operator=op).normal_force[0])

    large = 2.0
    f_blunt = force(blunt, large)
    f_cone, f_lowered = force(Cone(alpha), large), force(Cone(alpha), large + offset)
    assert f_cone < f_blunt < f_lowered
    assert f_blunt > 0.98 * f_lowered


# ---- viscoelastic closed forms ----------------------------------------------------


def lee_radok_approach(t, creep_integral, nu=NU):
    """Lee & Radok (contact radius non-decreasing): `a^3 = 3 R (1 - nu) / 8 int_0^t
    J(t - s) dW(s)`, approach `a^2 / R`; `creep_integral` is the integral [force /
    stress]."""
    return (3 * R * (1 - nu) / 8 * creep_integral) ** (2 / 3) / R


def test_lee_radok_zener_creep_ramp_and_hold():
    """Lee & Radok: a Zener sphere under a load ramp (rate `c` to `t = 1`) then hold:
    `int_0^t J(t - s) dW = c int_0^min(t, 1) J(t - s) ds`, in closed form for the
    Zener creep. The approach within 1e-3 (time discretisation: 41 steps,
    piecewise-linear scheme; 64 rings)."""
    mu_inf, mu_0, tau = 1.0, 0.3, 0.5
    times = jnp.linspace(0.0, 2.0, 41)
    rate = 0.05
    scene = jc.Scene(GRID, jc.Sphere(R), jc.Zener(mu_inf, mu_0, tau, NU), times,
                     jc.Force(rate * jnp.minimum(times, 1.0)))
    sol = solve_axisymmetric(scene, rings=64, radius=0.5, scheme="linear")
    for k in (5, 10, 20, 30, 40):
        t = float(times[k])
        t1 = min(t, 1.0)
        integral = rate * (t1 / mu_0 - (1 / mu_0 - 1 / mu_inf) * tau
                           * (np.exp(-(t - t1) / tau) - np.exp(-t / tau)))
        assert float(sol.approach[k]) == pytest.approx(
            lee_radok_approach(t, integral), rel=1e-3)


def test_lee_radok_prony_step_load():
    """A two-arm Prony solid given by its creep compliance `J(t) = 3 - exp(-t / 0.1)
    - 0.8 exp(-t)` (`jc.Prony.from_creep`: the solver sees its relaxation series)
    under a step load (a jump, then creep): the approach is Lee & Radok's
    `(3 R (1 - nu) J(t) W / 8)^(2/3) / R` at every time, within 1e-3 (64 rings)."""
    material = jc.Prony.from_creep(3.0, jnp.array([1.0, 0.8]), jnp.array([0.1, 1.0]),
                                   NU)
    times = np.linspace(0.0, 3.0, 31)
    scene = jc.Scene(GRID, jc.Sphere(R), material, jnp.asarray(times), jc.Force(0.01))
    sol = solve_axisymmetric(scene, rings=64, radius=0.5)
    creep = 3 - np.exp(-times / 0.1) - 0.8 * np.exp(-times)
    np.testing.assert_allclose(sol.approach, lee_radok_approach(times, 0.01 * creep),
                               rtol=1e-3)


def test_ting_unloading_zener_with_loss_of_contact():
    """Ting's closed form for an approach up and down (`ting_force`): the force within
    1e-3 of its peak at every time (piecewise-linear scheme, 81 steps, 100 rings), and
    contact lost exactly at the same steps (the surface recovers slower than the
    indenter withdraws)."""
    mu_inf, mu_0, tau = 1.0, 0.25, 1.0
    d_max, t_m = 0.04, 1.0
    times = np.linspace(0, 2 * t_m, 81)
    approach = np.where(times <= t_m, times, 2 * t_m - times) * d_max / t_m
    scene = jc.Scene(GRID, jc.Sphere(R), jc.Zener(mu_inf, mu_0, tau, NU),
                     jnp.asarray(times), jc.Displacement(jnp.asarray(approach)))
    sol = solve_axisymmetric(scene, rings=100, radius=0.5, scheme="linear")
    ref = np.array([ting_force(t, NU, mu_inf, mu_0, tau, d_max, t_m) for t in times])
    force = np.asarray(sol.normal_force)
    assert np.max(np.abs(force - ref)) < 1e-3 * ref.max()
    assert (ref == 0).sum() > 10  # the history does lose contact
    np.testing.assert_array_equal(force == 0, ref == 0)
    assert not bool(jnp.any(sol.contact[ref == 0]))


def _unload_reload(dtype):
    """A Zener sphere under load control, loaded, unloaded to zero, reloaded, in
    `dtype` (64 rings over 0.5)."""
    grid = jc.Grid((32, 32), jnp.asarray(1.2, dtype))
    material = jc.Zener(*(jnp.asarray(v, dtype) for v in (1.0, 0.3, 0.5, NU)))
    step = np.arange(31)
    times = jnp.asarray(step / 10, dtype)
    load = np.where(step <= 10, 0.05, np.where(step < 20, 0.0, 0.03))
    scene = jc.Scene(grid, jc.Sphere(jnp.asarray(R, dtype)), material, times,
                     jc.Force(jnp.asarray(load, dtype)))
    return step / 10, solve_axisymmetric(scene, rings=64, radius=0.5)


def test_load_control_unload_to_zero_and_reload():
    """Load control down to zero and back: no pressure at zero load, the approach
    there is the recovering surface's highest point (the centre's history
    displacement: positive, below the last loaded approach, decreasing), and the
    reload converges to its load."""
    times, sol = _unload_reload(jnp.float64)
    off = (times > 1.0) & (times < 2.0)
    assert bool(jnp.all(sol.converged))
    assert not bool(jnp.any(sol.contact[off]))
    lifted = np.asarray(sol.approach)[off]
    assert np.all(lifted > 0) and np.all(lifted < float(sol.approach[10]))
    assert np.all(np.diff(lifted) < 0)  # the surface recovers
    assert float(sol.normal_force[-1]) == pytest.approx(0.03, rel=1e-10)


def test_float32_matches_float64():
    """The load, unload and reload history in float32: converged at float32's default
    tolerance, the approach within 1e-4 (relative to its peak) of float64's, and the
    same steps without contact."""
    _, low = _unload_reload(jnp.float32)
    _, high = _unload_reload(jnp.float64)
    assert low.pressure.dtype == jnp.float32
    assert bool(jnp.all(low.converged))
    peak = float(jnp.max(high.approach))
    np.testing.assert_allclose(low.approach, high.approach, atol=1e-4 * peak, rtol=0)
    np.testing.assert_array_equal(jnp.any(low.contact, axis=1),
                                  jnp.any(high.contact, axis=1))


# ---- against the grid -------------------------------------------------------------


def test_equals_grid_solver_viscoelastic_sphere():
    """A Zener sphere under an approach up and down (unloading, no loss of contact),
    on a 48^2 grid (contact radius 10 cells) and on 100 rings: the forces agree within
    1 % of the peak, the grid's discretisation error at this size (the slow study
    shows the difference shrinking as the grid refines)."""
    material = jc.Zener(1.0, 0.5, 0.5, NU)
    times = jnp.linspace(0.0, 1.0, 9)
    approach = 0.0625 * jnp.where(times <= 0.5, 0.2 + times, 1.2 - times)
    grid = jc.Grid((48, 48), 1.2)
    scene = jc.Scene(grid, jc.Sphere(R), material, times, jc.Displacement(approach))
    rings = solve_axisymmetric(scene, rings=100, radius=0.6)
    on_grid = jc.solve(scene, solver=jc.Rounds())  # jc.solve's default: the rings
    assert on_grid.method == "grid"
    peak = float(jnp.max(rings.normal_force))
    np.testing.assert_allclose(rings.normal_force, on_grid.normal_force,
                               atol=0.01 * peak, rtol=0)
    # The ring pressure mapped onto the grid carries the same force (to the grid's
    # quadrature of the rings).
    mapped = rings.to_solution(grid)
    np.testing.assert_allclose(grid.cell_area * jnp.sum(mapped.pressure, axis=(1, 2)),
                               rings.normal_force, atol=0.02 * peak, rtol=0)


def test_jc_solve_runs_the_rings_when_asked():
    """`jc.solve(scene, solver=jc.RingPolonskyKeer())`: `solve_axisymmetric` with its
    defaults (128 rings over half the grid's side), mapped onto the grid, the method
    said; the contact sticks under friction with no tangential input (as on the
    grid); a scene that does not qualify, or a grid operator, is refused by name."""
    material = jc.Zener(1.0, 0.5, 0.5, NU)
    times = jnp.linspace(0.0, 1.0, 5)
    grid = jc.Grid((24, 24), 1.2)
    scene = jc.Scene(grid, jc.Sphere(R), material, times,
                     jc.Force(0.05 * (1 + times)), friction=0.3)
    calls = []
    sol = jc.solve(scene, solver=jc.RingPolonskyKeer(),
                   progress=lambda k, n: calls.append(int(k)))
    rings = solve_axisymmetric(scene)
    assert sol.method == "rings"  # the grid's "grid": tests/test_dataset.py
    np.testing.assert_allclose(sol.normal_force, rings.normal_force, rtol=1e-12)
    np.testing.assert_allclose(sol.approach, rings.approach, rtol=1e-12)
    assert bool(jnp.all(sol.converged)) and sorted(calls) == list(range(5))
    np.testing.assert_array_equal(sol.stick, sol.contact)
    assert bool(jnp.all(jnp.any(sol.contact, axis=(1, 2))))
    x, y = grid.coordinates()
    bowl = jc.Surface((x * x + y * y) / (2 * R))  # the sphere's gap, as an array
    flat = jc.Scene(grid, bowl, material, times, jc.Force(0.05))
    with pytest.raises(ValueError, match="RingPolonskyKeer cannot solve this scene"):
        jc.solve(flat, solver=jc.RingPolonskyKeer())
    with pytest.raises(TypeError, match="lays its own rings"):
        jc.solve(scene, solver=jc.RingPolonskyKeer(), operator=jc.HalfSpace(grid))
    # A grid size traced under `jit` (a scene built inside it): the same rings,
    # scaled from the unit radius's.
    traced = jax.jit(lambda side: jc.solve(
        eqx.tree_at(lambda s: s.grid.size, scene, jnp.stack([side, side])),
        solver=jc.RingPolonskyKeer()).approach)(1.2)
    np.testing.assert_allclose(traced, rings.approach, rtol=1e-10)


def test_jc_solve_runs_the_rings_by_default_where_the_scene_allows():
    """With no `solver` and no `operator`, `jc.solve` runs a frictionless scene with an
    axisymmetric indenter on a non-periodic grid on rings: the same answer as
    `solver=jc.RingPolonskyKeer()` (`rtol`, `max_steps`, `precondition` passed on),
    in float32 too, and `jc.sweep` likewise. Anything else runs on the grid: a grid
    solver or an `operator` given, a tangential solve, a periodic grid, a surface or
    a pyramid. The grid's own options (`adjoint`, `max_rounds`, `resync_every`) are
    refused on rings by name, never ignored."""
    material = jc.Zener(1.0, 0.5, 0.5, NU)
    times = jnp.linspace(0.0, 1.0, 4)
    grid = jc.Grid((16, 16), 1.2)
    load = jc.Force(0.05 * (1 + times))
    scene = jc.Scene(grid, jc.Sphere(R), material, times, load)
    default = jc.solve(scene, rtol=1e-6, max_steps=50)
    asked = jc.solve(scene, solver=jc.RingPolonskyKeer(rtol=1e-6, max_steps=50))
    assert default.method == "rings"
    np.testing.assert_array_equal(default.approach, asked.approach)
    np.testing.assert_array_equal(default.pressure, asked.pressure)
    cone = jc.Scene(grid, jc.Cone(1.2), material, times, jc.Displacement(0.02 * times))
    assert jc.solve(cone).method == "rings"
    single = jc.Scene(jc.Grid((16, 16), jnp.float32(1.2)), jc.Sphere(R), material,
                      times, load)
    low = jc.solve(single)
    assert low.method == "rings" and low.approach.dtype == jnp.float32
    np.testing.assert_allclose(low.approach, asked.approach, rtol=1e-4)
    # The grid: asked for, or where the rings do not apply.
    assert jc.solve(scene, solver=jc.Rounds()).method == "grid"
    assert jc.solve(scene, operator=jc.HalfSpace(grid)).method == "grid"
    x, y = grid.coordinates()
    not_on_rings = [
        jc.Scene(grid, jc.Sphere(R), material, times, load,
                 x=jc.Force(0.1 * load.values(times)), friction=0.3),
        jc.Scene(grid, jc.Sphere(R), material, times, load, friction=0.3,
                 coupling="full"),
        jc.Scene(jc.Grid((16, 16), 1.2, periodic=True), jc.Sphere(R), material, times,
                 load),
        jc.Scene(grid, jc.Surface((x * x + y * y) / (2 * R)), material, times, load),
        jc.Scene(grid, jc.Pyramid(1.2), material, times, jc.Displacement(0.02 * times)),
    ]
    for other in not_on_rings:
        assert jc.solve(other, throw=False).method == "grid"
    for option in (dict(adjoint=jc.ImplicitAdjoint()), dict(max_rounds=3),
                   dict(resync_every=5)):
        (name,) = option
        with pytest.raises(TypeError, match=f"{name} configures the grid solver.*"
                                            r"solver=jc\.Rounds\(\)"):
            jc.solve(scene, **option)
    with pytest.raises(TypeError, match="has its own implicit derivatives"):
        jc.solve(scene, solver=jc.RingPolonskyKeer(), adjoint=jc.ImplicitAdjoint())
    # jc.sweep: on rings, each member as jc.solve solves it; a grid solver keeps the
    # grid.
    forces = jnp.array([0.04, 0.06])
    swept = jc.sweep(scene, normal=jc.Force(forces))
    assert swept.method == "rings"
    for k, w in enumerate((0.04, 0.06)):
        one = jc.solve(jc.Scene(grid, jc.Sphere(R), material, times, jc.Force(w)))
        np.testing.assert_allclose(swept.approach[k], one.approach, rtol=1e-10)
    on_grid = jc.sweep(scene, normal=jc.Force(forces),
                       solve_options={"solver": jc.Rounds()})
    assert on_grid.method == "grid"


@pytest.mark.slow
def test_annular_contact_equals_grid():
    """A tip of revolution with a central dip (a ring-shaped ridge at r = 0.2): the
    contact is an annulus; rings and a 64^2 grid agree on the force within 1.5 %,
    and the centre ring carries no pressure."""
    radii = jnp.linspace(0.0, 0.6, 61)
    heights = (radii - 0.2) ** 2 / (2 * 0.3)
    tip = AxisymmetricProfile(radii, heights)
    grid = jc.Grid((64, 64), 1.2)
    scene = jc.Scene(grid, tip, jc.Elastic(G, NU), jnp.zeros(1),
                     jc.Displacement(0.02))
    rings = solve_axisymmetric(scene, rings=120, radius=0.6)
    on_grid = jc.solve(scene, solver=jc.Rounds())  # jc.solve's default: the rings
    assert not bool(rings.contact[0, 0])
    assert bool(jnp.any(rings.contact[0]))
    assert float(rings.normal_force[0]) == pytest.approx(
        float(on_grid.normal_force[0]), rel=1.5e-2)


# ---- precision, transformations, gradients ----------------------------------------


@functools.partial(jax.jit, static_argnums=1)
def _curve(params, control):
    """The force (displacement control) or approach (load control) curve of a Zener
    sphere, for `(mu_inf, mu_0, tau, radius)`, on 48 rings."""
    mu_inf, mu_0, tau, radius = params
    times = jnp.linspace(0.0, 1.0, 9)
    if control == "force":
        program = jc.Force(0.1 * jnp.minimum(times, 0.5))
    else:
        program = jc.Displacement(0.05 * jnp.where(times < 0.6, times, 1.2 - times))
    scene = jc.Scene(GRID, jc.Sphere(radius), jc.Zener(mu_inf, mu_0, tau, NU), times,
                     program)
    sol = solve_axisymmetric(scene, rings=48, radius=0.5)
    return sol.approach if control == "force" else sol.normal_force


def _check_gradients(control, modes):
    """Reverse mode (`jax.grad` of the curve's sum of squares) and / or forward mode
    (`jax.jacfwd` of the curve) against central differences (relative step 1e-6),
    within 1e-6 relative, with respect to the moduli, the time constant and the
    sphere radius."""
    x = jnp.array([1.0, 0.4, 0.3, 1.0])
    curve = _curve(x, control)
    grad = jacobian = None
    if "reverse" in modes:
        grad = jax.grad(lambda x: jnp.sum(_curve(x, control) ** 2))(x)
    if "forward" in modes:
        jacobian = jax.jacfwd(lambda x: _curve(x, control))(x)
    for i in range(4):
        h = 1e-6 * float(x[i])
        e = jnp.zeros(4).at[i].set(h)
        up, down = _curve(x + e, control), _curve(x - e, control)
        if grad is not None:
            fd = float(jnp.sum(up**2) - jnp.sum(down**2)) / (2 * h)
            assert float(grad[i]) == pytest.approx(fd, rel=1e-6)
        if jacobian is not None:
            fd_curve = (up - down) / (2 * h)
            scale = float(jnp.max(jnp.abs(fd_curve)))
            np.testing.assert_allclose(jacobian[:, i], fd_curve, atol=1e-6 * scale)
        if grad is not None and jacobian is not None:
            assert float(jnp.sum(2 * curve * jacobian[:, i])) == pytest.approx(
                float(grad[i]), rel=1e-8)


def test_gradients_force_control_reverse_mode():
    """Reverse mode through a creep curve (load ramp and hold: a fit's case) matches
    central differences (`_check_gradients`)."""
    _check_gradients("force", ("reverse",))


def test_gradients_displacement_control_forward_mode():
    """Forward mode through an approach up and down (the contact shrinks while the
    force falls) matches central differences (`_check_gradients`)."""
    _check_gradients("displacement", ("forward",))


@pytest.mark.slow
@pytest.mark.parametrize("control", ["force", "displacement"])
def test_gradients_both_modes(control):
    """Both modes on both controls, and `grad` equal to the Jacobian's product with
    the curve (`_check_gradients`)."""
    _check_gradients(control, ("reverse", "forward"))


def test_jit_and_vmap_over_materials():
    """`jax.vmap` over the instantaneous modulus of a batch of elastic scenes inside
    `jax.jit`: each member equals its own solve, and Hertz's scaling `delta ~ G^-2/3`
    holds between members to the ring discretisation (the same rings)."""
    op = RingOperator.uniform(0.5, 64)

    @jax.jit
    def approaches(moduli):
        def one(g):
            scene = hertz_scene(0.05, material=jc.Elastic(g, NU))
            return solve_axisymmetric(scene, operator=op).approach[0]
        return jax.vmap(one)(moduli)

    moduli = jnp.array([0.8, 1.0, 1.25])
    batch = approaches(moduli)
    single = solve_axisymmetric(hertz_scene(0.05, material=jc.Elastic(1.0, NU)),
                                operator=op).approach[0]
    assert float(batch[1]) == pytest.approx(float(single), rel=1e-10)
    ratio = np.asarray(batch / batch[1])
    np.testing.assert_allclose(ratio, np.asarray(moduli) ** (-2 / 3), rtol=2e-3)


# ---- the protocol and bad input ---------------------------------------------------


def test_solver_through_the_step_protocol():
    """`RingPolonskyKeer` runs through the one driver (`base.run`): stopped by its
    step bound before converging, it reports `max_steps_reached` (`solve_axisymmetric`
    runs every step through the same driver)."""
    op = RingOperator.uniform(0.5, 40)
    gap = op.mean(lambda r: r * r / (2 * R))
    problem = RingProblem(op, jnp.asarray(1 / G), jnp.asarray(NU), gap,
                          jnp.zeros(40), jnp.asarray(0.02), False)
    guess = StepGuess(jnp.zeros(40), jnp.zeros((0, 40)))
    cut = eqx.filter_jit(run)(RingPolonskyKeer(max_steps=1), problem, guess)
    assert int(cut.steps) == 1
    assert not bool(cut.output.converged)
    assert cut.output.result == jc.RESULTS.max_steps_reached


def test_bad_scenes_are_refused():
    """A non-axisymmetric indenter, a tangential solve, a periodic grid: each a
    ValueError saying why."""
    x, y = GRID.coordinates()
    heights = (x * x + 2 * y * y) / (2 * R)  # an elliptic paraboloid
    with pytest.raises(ValueError, match="is not axisymmetric"):
        solve_axisymmetric(jc.Scene(GRID, jc.Surface(heights), jc.Elastic(G, NU),
                                    jnp.zeros(1), jc.Force(0.01)))
    with pytest.raises(ValueError, match="tangential"):
        solve_axisymmetric(jc.Scene(GRID, jc.Sphere(R), jc.Elastic(G, NU),
                                    jnp.zeros(1), jc.Force(0.01), x=jc.Force(0.001),
                                    friction=0.3))
    periodic = jc.Grid((32, 32), 1.2, periodic=True)
    with pytest.raises(ValueError, match="periodic"):
        solve_axisymmetric(jc.Scene(periodic, jc.Sphere(R), jc.Elastic(G, NU),
                                    jnp.zeros(1), jc.Force(0.01)))
    with pytest.raises(ValueError, match="half_angle"):
        Cone(2.0)


# ---- convergence studies (slow) ---------------------------------------------------


@pytest.mark.slow
def test_ring_convergence_order_hertz_and_cone():
    """The approach error against Hertz (load control) and the force error against
    Sneddon (cone, displacement control) fall at second order in the ring width
    (contact radius 0.25 of 0.5; each halving at least 3.4x, measured order ~2)."""
    hertz = jc.Hertz(R, 4 / 3 * E_STAR * 0.25**3 / R, G, NU)
    alpha = np.deg2rad(70.0)
    delta = np.pi / 2 * 0.25 / np.tan(alpha)
    sneddon = 2 / np.pi * E_STAR * np.tan(alpha) * delta**2
    cone = jc.Scene(GRID, Cone(alpha), jc.Elastic(G, NU), jnp.zeros(1),
                    jc.Displacement(delta))
    errors = {"hertz": [], "cone": []}
    for rings in (32, 64, 128, 256, 512):
        sol = solve_axisymmetric(hertz_scene(hertz.force), rings=rings, radius=0.5)
        errors["hertz"].append(abs(float(sol.approach[0]) / float(hertz.approach) - 1))
        sol = solve_axisymmetric(cone, rings=rings, radius=0.5)
        errors["cone"].append(abs(float(sol.normal_force[0]) / sneddon - 1))
    for name, err in errors.items():
        ratios = np.asarray(err[:-1]) / np.asarray(err[1:])
        assert np.all(ratios > 3.4), (name, err)


@pytest.mark.slow
def test_grid_converges_to_rings():
    """The grid solver's force on a Zener sphere (approach up and down) converges to
    the rings' (800) as the grid refines (32^2 .. 128^2 over the same domain), the
    difference shrinking at least 1.7x per halving of the cell (measured 3.3x,
    4.9x), while the rings' own change from 400 to 800 rings is a quarter of the
    finest grid's difference or less (measured 0.12)."""
    material = jc.Zener(1.0, 0.5, 0.5, NU)
    times = jnp.linspace(0.0, 1.0, 9)
    approach = 0.0625 * jnp.where(times <= 0.5, 0.2 + times, 1.2 - times)

    def scene(n):
        return jc.Scene(jc.Grid((n, n), 1.2), jc.Sphere(R), material, times,
                        jc.Displacement(approach))

    fine = solve_axisymmetric(scene(32), rings=800, radius=0.6).normal_force
    coarse = solve_axisymmetric(scene(32), rings=400, radius=0.6).normal_force
    peak = float(jnp.max(fine))
    ring_change = float(jnp.max(jnp.abs(fine - coarse))) / peak
    differences = []
    for n in (32, 64, 128):
        grid = jc.solve(scene(n), solver=jc.Rounds()).normal_force
        differences.append(float(jnp.max(jnp.abs(grid - fine))) / peak)
    assert all(a / b > 1.7 for a, b in zip(differences, differences[1:])), differences
    assert ring_change < 0.25 * differences[-1]
