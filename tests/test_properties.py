"""Property-based tests (hypothesis): physical laws that hold for every admissible
input.

Every test draws a few parameter sets (`max_examples` is small, `deadline=None`: the
first example compiles) and checks a law with a stated tolerance:

- load balance (`A sum p = W`; tangential force = target under load control),
- complementarity (`p >= 0`, `gap >= 0`, `p gap = 0`),
- Coulomb (`|q| <= mu p`; slip cells `|q| = mu p`),
- symmetry (a y-load gives the x-load result rotated by 90 degrees; mirror images),
- scaling laws of the DISCRETE problem, which are exact (not only Hertz's): all loads
  and moduli scaled together; the grid stretched by `L` with the load by `L^3`
  (a ~ W^(1/3) at fixed R); metres vs millimetres,
- the elastic limit of every viscoelastic material.

All on one 16 x 16 grid and a few fixed scene structures, so that the compiled programs
are shared between the tests (parameters are traced values; only structure recompiles).
"""

import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st


# hypothesis imports this module (libcst) only to report a failure, and libcst triggers
# a DeprecationWarning that filterwarnings=error turns into a pytest INTERNALERROR which
# hides the failure. Import it once here, with that warning silenced.
with warnings.catch_warnings():
    warnings.simplefilter("ignore", DeprecationWarning)
    try:
        import hypothesis.extra._patching  # noqa: F401
    except ImportError:  # pragma: no cover - libcst absent: nothing to patch
        pass

import jaxcontact as jc


G0, NU0, R, W0 = 1e6, 0.3, 1e-2, 0.05
N = 16
A0 = float(jc.Hertz(R, W0, G0, NU0).contact_radius)  # ~0.43 mm
SIZE = 4 * A0
FEW = settings(max_examples=6, deadline=None, derandomize=True)


def log_uniform(lo, hi):
    return st.floats(np.log(lo), np.log(hi)).map(np.exp)


def grid(scale=1.0):
    return jc.Grid((N, N), SIZE * scale)


def normal(w, g, nu, scale=1.0, radius=R):
    """One frictionless elastic solve (the compiled program is shared)."""
    return jc.solve_normal(grid(scale), jc.Sphere(radius), jc.Elastic(g, nu), force=w)


def assert_complementarity(sol, w, rtol=1e-8):
    p, gap = np.asarray(sol.pressure), np.asarray(sol.gap)
    delta = float(sol.approach)
    assert bool(sol.converged)
    assert not bool(sol.edge_contact)
    np.testing.assert_allclose(float(sol.normal_force), w, rtol=1e-10)  # A sum p = W
    assert p.min() >= 0.0
    assert gap.min() >= -1e-7 * delta
    # p * gap ~ 0: the work of the gap against the pressure, relative to W * delta.
    assert np.sum(p * np.abs(gap)) * float(grid().cell_area) <= 10 * rtol * w * delta


# --------------------------------------------------------------------------------------
# Normal contact: complementarity, balance, scaling laws.


@FEW
@given(
    load=st.floats(0.05, 1.5),
    g=log_uniform(1e4, 1e9),
    nu=st.floats(-0.5, 0.5),
)
def test_normal_complementarity_and_hertz(load, g, nu):
    # W chosen so that the Hertz radius is load^(1/3) A0 (fits on the grid).
    e_star = 2 * g / (1 - nu)
    w = load * W0 * e_star / (2 * G0 / (1 - NU0))
    sol = normal(w, g, nu)
    assert_complementarity(sol, w)
    # Discretisation: the approach is within 3 % of Hertz even at ~3.5 cells per radius.
    hertz = jc.Hertz(R, w, g, nu)
    np.testing.assert_allclose(float(sol.approach), float(hertz.approach), rtol=0.03)
    # Mirror symmetry of a centred sphere on a square grid: x -> -x, y -> -y, x <-> y.
    p = np.asarray(sol.pressure)
    scale = 1e-7 * p.max()
    np.testing.assert_allclose(p, p[::-1, :], atol=scale)
    np.testing.assert_allclose(p, p[:, ::-1], atol=scale)
    np.testing.assert_allclose(p, p.T, atol=scale)


@FEW
@given(lam=log_uniform(1e-6, 1e6), load=st.floats(0.1, 1.5))
def test_scaling_loads_and_moduli_together(lam, load):
    # (W, G) -> (lam W, lam G): the strains are unchanged, so p / lam and the approach
    # are invariant (up to the solver tolerance).
    base = normal(load * W0, G0, NU0)
    scaled = normal(lam * load * W0, lam * G0, NU0)
    p0 = np.asarray(base.pressure)
    np.testing.assert_allclose(np.asarray(scaled.pressure) / lam, p0,
                               atol=1e-6 * p0.max())
    np.testing.assert_allclose(float(scaled.approach), float(base.approach), rtol=1e-7)
    np.testing.assert_array_equal(np.asarray(scaled.contact), np.asarray(base.contact))


@FEW
@given(length=log_uniform(0.2, 5.0), load=st.floats(0.1, 1.5))
def test_cube_root_law_is_exact_on_the_grid(length, load):
    # a ~ W^(1/3) holds exactly on the grid: with R fixed, stretch the grid by L and
    # the load by L^3. The gap r^2 / 2R grows as L^2; a pressure p on cells of size L
    # displaces the surface by ~ p L / G: so p x L, the same contact cells (a x L), the
    # approach x L^2.
    base = normal(load * W0, G0, NU0)
    big = normal(load * W0 * length**3, G0, NU0, scale=length)
    p0 = np.asarray(base.pressure)
    np.testing.assert_allclose(np.asarray(big.pressure) / length, p0,
                               atol=1e-6 * p0.max())
    np.testing.assert_allclose(float(big.approach) / length**2, float(base.approach),
                               rtol=1e-7)
    np.testing.assert_array_equal(np.asarray(big.contact), np.asarray(base.contact))


@FEW
@given(load=st.floats(0.1, 1.5), nu=st.floats(0.0, 0.5))
def test_hertz_radius_cube_root_in_load(load, nu):
    # a ~ W^(1/3) at FIXED geometry: the number of contact cells follows pi a^2 / A
    # within a ring of cells (coarse grid), for loads spanning a factor 15.
    w = load * W0
    sol = normal(w, G0, nu)
    a = float(jc.Hertz(R, w, G0, nu).contact_radius)
    dx = SIZE / N
    cells = int(np.sum(np.asarray(sol.contact)))
    assert np.pi * (a - dx) ** 2 / dx**2 <= cells <= np.pi * (a + dx) ** 2 / dx**2


@FEW
@given(load=st.floats(0.1, 1.5), g=log_uniform(1e5, 1e8))
def test_unit_invariance_metres_millimetres(load, g):
    # SI (m, N, Pa) against (mm, N, MPa = N/mm^2): lengths x 1e3, stresses x 1e-6.
    w = load * W0 * g / G0
    si = normal(w, g, NU0)
    mm = normal(w, g * 1e-6, NU0, scale=1e3, radius=R * 1e3)
    p = np.asarray(si.pressure)
    np.testing.assert_allclose(np.asarray(mm.pressure) * 1e6, p, atol=1e-6 * p.max())
    np.testing.assert_allclose(float(mm.approach) * 1e-3, float(si.approach), rtol=1e-7)
    np.testing.assert_allclose(float(mm.normal_force), float(si.normal_force),
                               rtol=1e-12)


# --------------------------------------------------------------------------------------
# Friction: one coupled ("full") scene structure, loaded in x or in y.

TIMES = jnp.arange(3.0)
RAMP = np.array([0.0, 0.5, 1.0])


def frictional(nu, mu, ratio, direction):
    """Constant W0, tangential force ramped to ratio * mu * W0 along x or y."""
    force = ratio * mu * W0 * RAMP
    zero = np.zeros(3)
    fx, fy = (force, zero) if direction == "x" else (zero, force)
    scene = jc.Scene(
        grid(), jc.Sphere(R), jc.Elastic(G0, nu), TIMES,
        normal=jc.Force(np.full(3, W0)), x=jc.Force(fx), y=jc.Force(fy),
        friction=mu, coupling="full",
    )
    return jax.tree_util.tree_map(np.asarray, jc.solve(scene)), np.stack([fx, fy], -1)


def rotate(f):
    """`f` rotated by +90 degrees about the centre of the square grid:
    `g(x, y) = f(y, -x)`, i.e. `g[i, j] = f[j, n - 1 - i]`."""
    return np.swapaxes(f, -1, -2)[..., ::-1, :]


# nu >= 0.1 and mu >= 0.2: the coupled first step (W applied at once, F = 0) with
# nu = 0, mu = 0.1 does not converge in max_rounds = 100 rounds (~60 s at n = 16;
# flagged, see test_stress.py::test_coupled_one_step_low_friction_is_flagged).
FRICTION_CASES = dict(
    nu=st.floats(0.1, 0.5), mu=st.floats(0.2, 0.6), ratio=st.floats(0.0, 0.85)
)


@pytest.mark.slow  # one coupled compile (~30 s CPU); test_partial_slip covers Coulomb
@settings(max_examples=3, deadline=None, derandomize=True)
@given(**FRICTION_CASES)
def test_friction_balance_coulomb_and_rotation(nu, mu, ratio):
    sx, fx = frictional(nu, mu, ratio, "x")
    sy, fy = frictional(nu, mu, ratio, "y")
    for sol, target in ((sx, fx), (sy, fy)):
        assert sol.converged.all()
        assert not sol.edge_contact.any()
        np.testing.assert_allclose(sol.normal_force, W0, rtol=1e-8)
        np.testing.assert_allclose(sol.tangential_force, target, atol=1e-6 * mu * W0)
        p = sol.pressure
        q = np.hypot(sol.shear[:, 0], sol.shear[:, 1])
        assert p.min() >= 0
        assert np.all(q <= mu * p * (1 + 1e-6) + 1e-12 * p.max())  # Coulomb cone
        slip = sol.contact & ~sol.stick
        # slip: on the cone
        np.testing.assert_allclose(q[slip], mu * p[slip], rtol=1e-5)
        assert np.all(q[~sol.contact] == 0)
    # A y-load gives the x-load result rotated by 90 degrees (the shear vector rotates
    # with it: (q_x, q_y) -> (-q_y, q_x)).
    scale = 1e-5 * sx.pressure.max()
    np.testing.assert_allclose(sy.pressure, rotate(sx.pressure), atol=scale)
    np.testing.assert_allclose(sy.shear[:, 0], -rotate(sx.shear[:, 1]), atol=scale)
    np.testing.assert_allclose(sy.shear[:, 1], rotate(sx.shear[:, 0]), atol=scale)
    np.testing.assert_array_equal(sy.stick_ratio, sx.stick_ratio)
    # Mirror y -> -y of the x-load solution: p and q_x even, q_y odd.
    np.testing.assert_allclose(sx.pressure, sx.pressure[..., ::-1], atol=scale)
    np.testing.assert_allclose(sx.shear[:, 0], sx.shear[:, 0, :, ::-1], atol=scale)
    np.testing.assert_allclose(sx.shear[:, 1], -sx.shear[:, 1, :, ::-1], atol=scale)


# --------------------------------------------------------------------------------------
# Elastic limit of every viscoelastic material (the normal-only time stepper).

VISCO_TIMES = jnp.linspace(0.0, 1.0, 11)  # nt = 11 as in test_stress (shared program)


def visco(material, loads):
    scene = jc.Scene(grid(), jc.Sphere(R), material, VISCO_TIMES,
                     normal=jc.Force(loads))
    # On the grid, as the elastic reference (jc.solve's default: the rings).
    return jax.tree_util.tree_map(np.asarray, jc.solve(scene, solver=jc.Rounds()))


def elastic_reference(loads, g, nu):
    """Each step of an elastic body is an independent elastic solve."""
    return np.stack([np.asarray(normal(float(w), g, nu).pressure) for w in loads])


LOADS = dict(
    loads=st.lists(st.floats(0.1, 1.2), min_size=11, max_size=11).map(
        lambda v: W0 * np.asarray(v)
    ),
    g=log_uniform(1e5, 1e7),
    nu=st.floats(0.0, 0.5),
)


def assert_elastic(sol, loads, g, nu, rtol):
    assert sol.converged.all()
    ref = elastic_reference(loads, g, nu)
    np.testing.assert_allclose(sol.pressure, ref, atol=rtol * ref.max())


@settings(max_examples=3, deadline=None, derandomize=True)
@given(tau=log_uniform(1e-3, 1e3), **LOADS)
def test_zener_with_equal_moduli_is_elastic(tau, loads, g, nu):
    sol = visco(jc.Zener(g, g, tau, nu), loads * g / G0)
    assert_elastic(sol, loads * g / G0, g, nu, 1e-6)


@pytest.mark.slow  # its own compiled program (~10 s)
@settings(max_examples=3, deadline=None, derandomize=True)
@given(**LOADS)
def test_prony_with_zero_arms_is_elastic(loads, g, nu):
    sol = visco(jc.Prony(g, np.zeros(2), np.array([0.1, 3.0]), nu), loads * g / G0)
    assert_elastic(sol, loads * g / G0, g, nu, 1e-6)


@pytest.mark.slow  # its own compiled program (~10 s)
@settings(max_examples=3, deadline=None, derandomize=True)
@given(log_ratio=st.floats(6.0, 12.0), **LOADS)
def test_stiff_maxwell_over_a_short_time_is_elastic(log_ratio, loads, g, nu):
    # tau = eta / G = 10^k t_end: creep adds t / eta = (t / tau) / G, a relative change
    # of at most t_end / tau = 10^-k in the compliance (and so in the pressure's shape).
    eta = g * 10.0**log_ratio
    sol = visco(jc.Maxwell(g, eta, nu), loads * g / G0)
    assert_elastic(sol, loads * g / G0, g, nu, 10 * 10.0**-log_ratio + 1e-6)


@pytest.mark.parametrize(
    "material",
    ["zener", pytest.param("prony", marks=pytest.mark.slow),
     pytest.param("maxwell", marks=pytest.mark.slow)],
)
def test_elastic_limit_is_not_trivially_true(material):
    # Guard against a vacuous limit test: away from the limit the same comparison fails.
    g, nu, loads = G0, NU0, W0 * np.repeat([0.5, 1.0], [5, 6])
    mat = {
        "zener": jc.Zener(g, g / 2, 0.5, nu),
        "prony": jc.Prony(g, np.array([g, 0.0]), np.array([0.1, 3.0]), nu),
        "maxwell": jc.Maxwell(g, g * 1.0, nu),
    }[material]
    with pytest.raises(AssertionError):
        assert_elastic(visco(mat, loads), loads, g, nu, 1e-3)
