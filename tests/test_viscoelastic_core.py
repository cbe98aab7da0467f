"""Core viscoelastic checks of `jc.solve` (Lee-Radok creep, relaxation, history
paths)."""

import jax.numpy as jnp
import numpy as np
import pytest

import jaxcontact as jc


# Paper Table 1 converted to TRUE shear moduli (the paper lists 2 G): G = 40.96 GPa,
# eta = 40.96 GPa s (tau = 1 s), nu = 0.5, R = 3.5 mm, W = 100 N; a0 = 117 um.
R1, W1, NU1 = 3.5e-3, 100.0, 0.5
MAXWELL = jc.Maxwell(shear_modulus=81.92e9 / 2, viscosity=81.92e9 / 2, poisson=NU1)


def test_table1_conversion_gives_paper_a0_p0():
    hz = jc.Hertz(R1, W1, MAXWELL.shear_modulus, NU1)
    assert abs(float(hz.contact_radius) / 117e-6 - 1) < 2e-3
    assert abs(float(hz.peak_pressure) / 3487e6 - 1) < 1e-3


# Redundant: test_viscoelastic's Maxwell radius / profile vs Lee-Radok tests (quick).
@pytest.mark.slow  # redundant with test_viscoelastic's Maxwell tests
def test_lee_radok_maxwell_contact_radius_and_spike():
    n = 96
    grid = jc.Grid((n, n), 512e-6)
    times = jnp.linspace(0.0, 2.0, 21)
    scene = jc.Scene(grid, jc.Sphere(R1), MAXWELL, times=times, normal=jc.Force(W1))
    sol = jc.solve(scene)
    assert bool(sol.converged.all())
    reference = jc.LeeRadok(R1, NU1, MAXWELL, lambda t: W1, samples=400)
    dx = float(grid.spacing[0])
    a_num = np.sqrt(np.asarray(sol.contact.sum((1, 2))) * float(grid.cell_area) / np.pi)
    a_ref = np.array([reference.contact_radius(float(t)) for t in times])
    # Contact radius within one cell at every step (measured <= 0.2 cells).
    assert np.abs(a_num - a_ref).max() <= dx
    # The load is carried exactly; the contact grows monotonically (creep).
    np.testing.assert_allclose(sol.normal_force, W1, rtol=1e-10)
    assert (np.diff(np.asarray(sol.contact.sum((1, 2)))) >= 0).all()
    # Edge spike (paper Fig. 5): at t = 2 tau the pressure peaks off-centre.
    row = np.asarray(sol.pressure[-1, :, n // 2])
    assert np.argmax(np.abs(np.arange(n) - (n - 1) / 2) * (row == row.max())) > 0
    centre = row[n // 2]
    assert row.max() > 1.01 * centre
    # ... and the centre pressure follows Lee-Radok within 3 % of p0.
    p0 = float(jc.Hertz(R1, W1, MAXWELL.shear_modulus, NU1).peak_pressure)
    x = np.asarray(grid.x)
    p_ref = reference.pressure(np.abs(x[n // 2]), 2.0)[0]
    assert abs(centre - p_ref) < 3e-2 * p0


def test_relaxation_force_follows_relaxation_modulus():
    material = jc.Zener(mu_inf=1.93e6, mu_0=1.93e6 / 4, tau=0.01, poisson=0.3)
    grid = jc.Grid((64, 64), 3e-3)
    times = jnp.linspace(0.0, 0.05, 26)
    scene = jc.Scene(grid, jc.Sphere(10e-3), material, times=times,
                     normal=jc.Displacement(2e-5))
    sol = jc.solve(scene)
    assert bool(sol.converged.all())
    # A step indentation: the contact stays the same and the pressure is
    # p_el(x) phi(t). In the continuum phi = G(t) / G(0); in the paper's discrete scheme
    # (piecewise-constant tractions) phi solves the discrete Volterra equation
    # sum_{n<=k} J(t_k - t_n) (phi_n - phi_{n-1}) = J(0), solved here independently.
    assert (np.asarray(sol.contact) == np.asarray(sol.contact[0])).all()
    ratio = np.asarray(sol.normal_force / sol.normal_force[0])
    t = np.asarray(times)
    creep = lambda x: np.asarray(material.creep(jnp.asarray(x)))  # noqa: E731
    phi = [1.0]
    for k in range(1, t.size):
        known = sum(creep(t[k] - t[n]) * (phi[n] - (phi[n - 1] if n else 0.0))
                    for n in range(k))
        phi.append(phi[-1] + (creep(0.0) - known) / creep(0.0))
    np.testing.assert_allclose(ratio, phi, rtol=1e-6)
    # ... which tends to G(t) / G(0): at t >= 10 relaxation times both are G_0 / G_inf.
    relaxed = float(material.mu_0 / material.mu_inf)
    assert abs(ratio[-1] / relaxed - 1) < 1e-3


# Redundant: test_viscoelastic::test_recursive_and_direct_history_agree_through_full_
# solves (quick); the recursion treats the 3 traction components alike.
@pytest.mark.slow  # redundant: recursion vs direct sum, quick in test_viscoelastic
def test_recursive_and_direct_history_agree_through_solves():
    material = jc.Prony(g_inf=1.93e6, g=jnp.array([3.86e6, 1e6]),
                        tau=jnp.array([0.1, 0.02]), poisson=0.3)
    grid = jc.Grid((48, 48), 3e-3)
    times = jnp.linspace(0.0, 0.3, 16)
    scene = jc.Scene(grid, jc.Sphere(10e-3), material, times=times,
                     normal=jc.Force(0.15 * jnp.minimum(1.0, times / 0.1 + 0.1)),
                     x=jc.Force(0.02 * times / 0.3), friction=0.3, coupling="full")
    rec = jc.solve(scene)
    direct = jc.solve(scene, history="direct")
    assert bool(rec.converged.all()) and bool(direct.converged.all())
    for a, b in [(rec.pressure, direct.pressure), (rec.shear, direct.shear)]:
        assert float(jnp.abs(a - b).max() / jnp.abs(b).max()) < 1e-6
    np.testing.assert_allclose(rec.approach, direct.approach, rtol=1e-7)


# Redundant: test_viscoelastic::test_zener_without_creep_equals_elastic (to 1e-12) and
# test_properties::test_zener_with_equal_moduli_is_elastic (quick).
@pytest.mark.slow  # redundant: Zener mu_0 = mu_inf is elastic, quick elsewhere
def test_zener_without_relaxation_is_elastic():
    grid = jc.Grid((40, 40), 3e-3)
    times = jnp.linspace(0.0, 1.0, 5)
    common = dict(times=times, normal=jc.Force(0.15))
    zener = jc.Zener(mu_inf=1.93e6, mu_0=1.93e6, tau=0.01, poisson=0.3)
    elastic = jc.Elastic(1.93e6, 0.3)
    sz = jc.solve(jc.Scene(grid, jc.Sphere(10e-3), zener, **common))
    se = jc.solve(jc.Scene(grid, jc.Sphere(10e-3), elastic, **common))
    np.testing.assert_allclose(sz.pressure, se.pressure, rtol=0,
                               atol=1e-7 * float(se.pressure.max()))
