"""`jc.surface_displacement`: the surface displacements of a solved scene.

Physical facts checked (float64; tolerances are stated against the measured errors):

- Elastic Hertz contact: `u_z(r)` against the closed-form profile inside AND outside
  the contact (Johnson 1985, eqs. 3.41b, 3.42b), which in terms of the contact radius
  `a` and the sphere radius `R` alone reads

      u_z(r) = [(2 a^2 - r^2) asin(min(1, a / r)) + a sqrt(max(r^2 - a^2, 0))] / (pi R)

  (inside: `(2 a^2 - r^2) / (2 R) = delta - r^2 / (2 R)`); and, with the full
  coupling blocks, the inward radial displacement (Johnson eq. 3.41a).
- Viscoelastic step load (Lee & Radok): `p(t) = int G(t - s) dp_e(s)` with `p_e(s)` the
  Hertz pressure of a unit-compliance body of contact radius `a(s)`, so the hereditary
  integral gives `u(t) = int J(t - s) dp(s) = K1 p_e(t)` (`J * dG = 1`): at every time
  the surface is the ELASTIC Hertz profile above with the Lee-Radok radius `a(t)`,
  inside and outside the contact. Outside the contact nothing in the solve constrains
  `u_z`, so this checks the hereditary integral itself.
- What the solver held: the gap `h = h0 + u_z - approach` (paper Eq. 15) is zero in the
  contact and positive outside; under the total slip law (Eq. 16) the stick cells have
  `u_x = delta_x`, `u_y = delta_y`.
- The recursion equals the direct O(Nt^2) sum (paper Eqs. 12-13).
"""

import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxcontact as jc


P = jc.presets


def hertz_profile(r, a, radius):
    """Closed-form surface displacement `u_z(r)` [length] of a Hertz contact of radius
    `a` under a rigid sphere of `radius` (inside and outside the contact)."""
    s = np.arcsin(np.minimum(1.0, a / np.maximum(r, 1e-300)))
    return ((2 * a * a - r * r) * s + a * np.sqrt(np.maximum(r * r - a * a, 0.0))) / (
        np.pi * radius)


def radii(scene):
    x, y = (np.asarray(c) for c in scene.grid.coordinates())
    return x, y, np.hypot(x, y)


@pytest.fixture(scope="module")
def hertz():
    scene = P.hertz(n=64)
    sol = jc.solve(scene, solver=jc.Rounds())  # on the grid: its cells' displacements
    return scene, sol, np.asarray(jc.surface_displacement(scene, sol))


def test_shape_and_dtype(hertz):
    scene, sol, u = hertz
    assert u.shape == (1, 3, 64, 64)
    assert u.dtype == np.float64


def test_elastic_hertz_profile_inside_and_outside(hertz):
    scene, sol, u = hertz
    _, _, r = radii(scene)
    ref = jc.Hertz(scene.indenter.radius, 0.15, scene.material.shear_modulus,
                   scene.material.poisson)
    a, delta = float(ref.contact_radius), float(ref.approach)
    radius = float(scene.indenter.radius)
    err = np.abs(u[0, 2] - hertz_profile(r, a, radius)) / delta
    contact = np.asarray(sol.contact[0])
    # 64^2 over 4a (32 cells across the contact): measured 2.3e-4 inside, 7.5e-4
    # outside (the piecewise-constant pressure of the edge cells); 32^2: 1.1e-3, 1.7e-3.
    assert err[contact].max() < 1e-3
    assert err[~contact].max() < 2e-3
    # no normal-tangential coupling in this scene: no in-plane displacement
    assert np.abs(u[0, :2]).max() == 0.0


def test_elastic_gap_closes_in_contact(hertz):
    scene, sol, u = hertz
    h0 = np.asarray(scene.indenter.gap(scene.grid))
    gap = h0 + u[0, 2] - float(sol.approach[0])
    contact = np.asarray(sol.contact[0])
    delta = float(sol.approach[0])
    assert np.abs(gap[contact]).max() < 1e-6 * delta  # 9e-9 measured (solver rtol 1e-8)
    assert gap[~contact].min() > 0


def test_elastic_radial_displacement_full_coupling(hertz):
    """A pressure pulls the surface of a compressible body inward: Johnson eq. 3.41a,
    `u_r = -(1 - 2 nu) / (6 G) p0 a^2 / r [1 - (1 - r^2/a^2)^(3/2)_+]`."""
    scene, sol, u = hertz
    full = np.asarray(jc.surface_displacement(scene, sol, coupling="full"))
    np.testing.assert_array_equal(full[0, 2], u[0, 2])  # q = 0: u_z unchanged
    x, y, r = radii(scene)
    g, nu = float(scene.material.shear_modulus), float(scene.material.poisson)
    ref = jc.Hertz(scene.indenter.radius, 0.15, g, nu)
    a, p0 = float(ref.contact_radius), float(ref.peak_pressure)
    ur = -(1 - 2 * nu) / (6 * g) * p0 * a * a / r * (
        1 - np.maximum(1 - r * r / (a * a), 0.0) ** 1.5)
    scale = np.abs(ur).max()
    # measured 6.6e-3 of the peak (inside the contact, where u_r varies fastest)
    np.testing.assert_array_less(np.abs(full[0, 0] - ur * x / r), 1.5e-2 * scale)
    np.testing.assert_array_less(np.abs(full[0, 1] - ur * y / r), 1.5e-2 * scale)
    assert (full[0, 0][x > 0] < 0).all()  # inward


@pytest.mark.parametrize("case", ["zener10", "maxwell"])
def test_viscoelastic_step_load_is_hertz_profile_of_lee_radok_radius(case):
    if case == "zener10":
        scene = P.zener(ratio=10, n=48, steps=31)
        load = 0.15
    else:  # a fluidity term in the creep series (J = 1/G + t/eta)
        scene = P.maxwell(n=48, steps=21)
        load = 100.0
    sol = jc.solve(scene, solver=jc.Rounds())  # the grid's (not the rings')
    u = np.asarray(jc.surface_displacement(scene, sol))
    assert u.shape == (scene.times.shape[0], 3, 48, 48)
    _, _, r = radii(scene)
    radius = float(scene.indenter.radius)
    lee_radok = jc.LeeRadok(radius, float(scene.material.poisson), scene.material,
                            lambda t: load * (t >= 0))
    h0 = np.asarray(scene.indenter.gap(scene.grid))
    worst = 0.0
    for k in range(0, scene.times.shape[0], 5):
        a = lee_radok.contact_radius(float(sol.times[k]))
        delta = a * a / radius
        worst = max(worst, np.abs(u[k, 2] - hertz_profile(r, a, radius)).max() / delta)
        # what the solver held: inside the contact u_z = approach - h0 (gap zero)
        gap = h0 + u[k, 2] - float(sol.approach[k])
        contact = np.asarray(sol.contact[k])
        assert np.abs(gap[contact]).max() < 1e-6 * delta
        assert gap[~contact].min() > 0
    # measured (64^2, 61 points): 1.4e-3 of delta(t) for Zener 2 and 10 at every time
    # (the edge cells, as for the elastic profile); the Lee-Radok sums are ~1e-4.
    assert worst < 4e-3, worst
    # the surface creeps: u_z at the centre follows the approach, which grows
    centre = u[:, 2].max(axis=(1, 2))
    assert (np.diff(centre) > 0).all()


def test_recursion_equals_direct_sum():
    scene = P.zener(ratio=4, n=16, steps=9)
    sol = jc.solve(scene)
    rec = np.asarray(jc.surface_displacement(scene, sol))
    direct = np.asarray(jc.surface_displacement(scene, sol, history="direct"))
    np.testing.assert_allclose(direct, rec, rtol=0, atol=1e-12 * np.abs(rec).max())
    # the direct hereditary sum written out: K1 sum_n J(t_k - t_n) (p_n - p_{n-1})
    k = 5
    t = np.asarray(sol.times)
    creep = np.asarray(scene.material.creep(jnp.asarray(t[k] - t[: k + 1])))
    dp = np.diff(np.asarray(sol.pressure[: k + 1]), axis=0, prepend=0.0)
    hist = np.tensordot(creep, dp, axes=(0, 0))
    op = jc.HalfSpace(scene.grid, "normal")
    uz = np.asarray(op.apply_normal(jnp.asarray(hist), scene.material.poisson))
    np.testing.assert_allclose(rec[k, 2], uz, rtol=0, atol=1e-12 * np.abs(uz).max())


def test_coupled_total_slip_stick_cells_follow_rigid_displacement():
    """Under the total slip law (Eq. 16) a stick cell has zero total slip: `u_x =
    delta_x`, `u_y = delta_y` there; and the coupled `u_z` (shear contributes) closes
    the gap in the contact."""
    scene = P.dc(ratio=4, n=24, steps=9, duration=0.5)
    sol = jc.solve(scene)
    u = np.asarray(jc.surface_displacement(scene, sol))
    h0 = np.asarray(scene.indenter.gap(scene.grid))
    dx = float(np.asarray(scene.x.values(scene.times))[0])
    for k in range(scene.times.shape[0]):
        stick, contact = np.asarray(sol.stick[k]), np.asarray(sol.contact[k])
        assert stick.any()
        delta_t = np.asarray(sol.tangential_displacement[k])
        assert abs(delta_t[0] - dx) < 1e-12 * dx
        np.testing.assert_allclose(u[k, 0][stick], delta_t[0], rtol=0, atol=1e-6 * dx)
        np.testing.assert_allclose(u[k, 1][stick], delta_t[1], rtol=0, atol=1e-6 * dx)
        # slip cells have moved relative to the indenter
        slip = contact & ~stick
        assert np.abs(u[k, 0][slip] - delta_t[0]).max() > 1e-3 * dx
        gap = h0 + u[k, 2] - float(sol.approach[k])
        assert np.abs(gap[contact]).max() < 1e-6 * float(sol.approach[k])
    # the shear matters for u_z: without the coupling blocks the gap does not close
    none = np.asarray(jc.surface_displacement(scene, sol, coupling="none"))
    k = scene.times.shape[0] - 1
    gap = h0 + none[k, 2] - float(sol.approach[k])
    assert np.abs(gap[np.asarray(sol.contact[k])]).max() > 1e-4 * float(sol.approach[k])


def test_linear_scheme_matches_a_linear_solve():
    scene = P.zener(ratio=10, n=16, steps=9)
    sol = jc.solve(scene, solver=jc.Rounds(), scheme="linear")  # the grid's
    h0 = np.asarray(scene.indenter.gap(scene.grid))
    lin = np.asarray(jc.surface_displacement(scene, sol, scheme="linear"))
    const = np.asarray(jc.surface_displacement(scene, sol))  # the wrong scheme
    k = scene.times.shape[0] - 1
    contact = np.asarray(sol.contact[k])
    delta = float(sol.approach[k])
    assert np.abs((h0 + lin[k, 2] - delta)[contact]).max() < 1e-6 * delta
    assert np.abs((h0 + const[k, 2] - delta)[contact]).max() > 1e-3 * delta


def test_under_jit_and_with_a_prebuilt_operator(hertz):
    scene, sol, u = hertz
    op = jc.HalfSpace(scene.grid, "none")
    np.testing.assert_array_equal(
        np.asarray(jc.surface_displacement(scene, sol, operator=op)), u)
    jitted = jax.jit(lambda s: jc.surface_displacement(scene, s))(sol)
    np.testing.assert_allclose(np.asarray(jitted), u, rtol=1e-14, atol=0)


def test_bad_input(hertz):
    scene, sol, _ = hertz
    with pytest.raises(TypeError, match="scene"):
        jc.surface_displacement(sol, sol)
    with pytest.raises(TypeError, match="solution"):
        jc.surface_displacement(scene, scene)
    with pytest.raises(ValueError, match="coupling"):
        jc.surface_displacement(scene, sol, coupling="normal")
    with pytest.raises(ValueError, match="scheme"):
        jc.surface_displacement(scene, sol, scheme="cubic")
    with pytest.raises(ValueError, match="history"):
        jc.surface_displacement(scene, sol, history="fast")
    with pytest.raises(ValueError, match="not both"):
        jc.surface_displacement(scene, sol, coupling="full",
                                operator=jc.HalfSpace(scene.grid, "full"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        other = P.hertz(n=32)
    with pytest.raises(ValueError, match="grid"):
        jc.surface_displacement(scene, sol, operator=jc.HalfSpace(other.grid))
    with pytest.raises(ValueError, match="shape|needs"):
        jc.surface_displacement(other, sol)
