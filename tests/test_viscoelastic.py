r"""Viscoelastic validation: full `jc.solve` runs against Lee & Radok (1960), Ting
(1966), exact relaxation, the paper's constant-input cases (section 4.2.1), the
observed order of both time schemes, and the equivalence of the history paths.

Every test states a physical or numerical fact and its tolerance; the numbers measured
when the tolerances were set are quoted next to them (float64, rtol 1e-8).

These validate the grid solver (the paper's method): a frictionless scene passes
`solver=jc.Rounds()`, since `jc.solve` would run it on rings (their validation:
`test_rings.py`).

Units and conversions (docs/conventions.md): moduli are TRUE shear moduli. The
paper's tables list twice the shear modulus (its a0 and p0 come out only with
E* = G_paper / (1 - nu)), so every paper value is halved here:

- Table 1 (Maxwell, paper Eqs. 22-23): G = 81.92 / 2 = 40.96 GPa, eta = 81.92 / 2 =
  40.96 GPa s (tau = eta / G = 1 s is unchanged), nu = 0.5, R = 3.5 mm, W = 100 N:
  a0 = 117 um, p0 = 3487 MPa (checked below).
- Table 2 (Zener, paper Eqs. 29-30): mu_inf = 3.86 / 2 = 1.93 MPa, mu_0 = mu_inf /
  ratio, tau = 0.01 s (the RETARDATION time of Eq. 30; the relaxation time is
  tau mu_0 / mu_inf), nu = 0.3, R = 10 mm, W = 0.15 N: a0 = 588.7 um, p0 = 0.2067 MPa.
- PMMA (paper Eq. 27, from Chen et al. 2011): G_paper(t) = 1429.71 + 184.62 e^{-t/8.93}
  + 191.06 e^{-t/117.96} MPa, so `jc.Prony(g_inf=714.855e6, g=[92.31e6, 95.53e6],
  tau=[8.93, 117.96], poisson=0.38)`. Its exact creep series, back in the paper's
  convention (J_paper = J / 2), is 0.699 - 0.0838 e^{-t/133.87} - 0.0617 e^{-t/9.936}
  1/GPa: the paper's Eq. 28 (checked below).

References. Lee & Radok: `jc.LeeRadok` (a^3 = 3R(1-nu)/8 J*dW, p from G*d sqrt(a^2-r^2),
delta = a^2/R while the contact radius grows). Ting (1966) for the unloading branch of
the triangular load: `TingTriangle` below, derived here from the exact reduction of the
axisymmetric problem to a one-dimensional one (the Abel transform pair of the method of
dimensionality reduction, valid for any linear viscoelastic J with constant nu): with
t_m the time of the largest contact radius and, for t > t_m, t1(t) < t_m the earlier
time with a(t1) = a(t),

    W(t) = 8 / (3 R (1 - nu)) int_0^{t1} G(t - s) d[a^3(s)]             (load)
    int_{t1}^{t} G(t - s) d delta(s) = 0                          (edge condition)

The first gives a(t) from the prescribed load alone; the second gives the approach
delta(t) (a Volterra equation on [t_m, t]). NOTE: Ting's condition for t1 involves the
APPROACH delta, not a^3: `int_{t1}^{t} G d(a^3) = 0` is not the right condition (the two
agree only while delta = a^2 / R, i.e. during loading). The derivation, in short: the
Abel map q(x) = 2 int_x^inf r p(r) / sqrt(r^2 - x^2) dr turns the surface problem into
pointwise-in-x relations w(x, t) = (1 - nu)/2 (J * dq)(x, t), with w = delta - x^2 / R
where x < a(t) and q = 0 where x > a(t) (q(a) = 0: bounded pressure). A point x enters
contact at t_in(x) with w = 0 and q(x, t) = 2/(1 - nu) int_{t_in}^{t} G(t - s) d delta;
the edge condition is q(a(t), t) = 0, and W = 2 int_0^a q dx gives the load formula.
Checked against the solver below to 1e-4 of delta_max, including the residual
indentation at W = 0.

Cost: each new (grid, nt, material structure, scheme, coupling) compiles once
(3-6 s); solutions are cached and shared. Longer variants are `@pytest.mark.slow`.
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import as_np, check_converged, equivalent_radius, radii, zener

import jaxcontact as jc
from jaxcontact._history import ElasticHistory, RecursiveHistory
from jaxcontact._history import history_for as _history_for


# The tests share cached solutions and their compiled programs (functools.cache):
# one test process runs them all (an xdist group, see tests/conftest.py).
pytestmark = pytest.mark.xdist_group("viscoelastic")

RTOL = 1e-8  # jc.solve's default in float64

# ---- Paper parameters (converted to true shear moduli, see module docs) --------------

# Table 1: Maxwell, step load.
T1_R, T1_W, T1_NU = 3.5e-3, 100.0, 0.5
T1_G = 81.92e9 / 2
T1_ETA = 81.92e9 / 2  # Pa s; tau = eta / G = 1 s
T1_TAU = 1.0
T1_DOMAIN = 512e-6

# Table 2: Zener, step load.
T2_R, T2_W, T2_NU = 10e-3, 0.15, 0.3
T2_MU_INF = 3.86e6 / 2
T2_TAU = 0.01  # retardation time (paper Eq. 30)
T2_A0 = 588.7e-6

# PMMA (paper Eqs. 26-27), triangular load.
PMMA_R, PMMA_NU = 3.5e-3, 0.38
PMMA_G_INF = 1429.71e6 / 2
PMMA_G = np.array([184.62e6, 191.06e6]) / 2
PMMA_TAU = np.array([8.93, 117.96])
PMMA_DOMAIN = 1280e-6


def maxwell():
    return jc.Maxwell(T1_G, T1_ETA, T1_NU)


def pmma():
    return jc.Prony(PMMA_G_INF, jnp.asarray(PMMA_G), jnp.asarray(PMMA_TAU), PMMA_NU)


def t2_hertz():
    return jc.Hertz(T2_R, T2_W, T2_MU_INF, T2_NU)


# ---- Helpers -------------------------------------------------------------------------


def centre_pressure(sol, grid):
    """Mean pressure of the 4 cells around the origin (r = dx / sqrt(2)), per step."""
    nx, ny = grid.shape
    p = np.asarray(sol.pressure)[
        :, nx // 2 - 1 : nx // 2 + 1, ny // 2 - 1 : ny // 2 + 1
    ]
    return p.mean(axis=(1, 2))


def ring_profile(grid, pressure, a):
    """Ring averages of a pressure field over annuli of width dx inside r < a - dx:
    (mean radius, mean pressure) per ring."""
    _, _, r = radii(grid)
    dx = float(grid.spacing[0])
    ring = np.floor(r / dx).astype(int)
    out_r, out_p = [], []
    for k in range(int((a - dx) / dx)):
        sel = ring == k
        out_r.append(r[sel].mean())
        out_p.append(np.asarray(pressure)[sel].mean())
    return np.asarray(out_r), np.asarray(out_p)


def edge_bump(profile):
    """Height of an off-centre local maximum of a radial profile: the largest rise
    `P_i - min_{j <= i} P_j` (0 for a non-increasing profile)."""
    return float(np.max(profile - np.minimum.accumulate(profile)))


def discrete_relaxation(material, times, scheme):
    """The factor g_k of the exact solution of the DISCRETE scheme for a step
    displacement with a fixed contact: tau_k = g_k tau_0, where
    sum_n w_{k,n} (g_n - g_{n-1}) = J(0) (g_{-1} = 0) keeps the surface displacement at
    its value of step 0. Weights (see `_history`): `constant`: w_{k,n} = J(t_k - t_n);
    `linear`: w_{k,0} = J(t_k - t_0) (the first entry is a jump), and for n >= 1 the
    mean of J(t_k - s) over s in (t_{n-1}, t_n], in closed form from the creep
    series."""
    s = material.creep_series()
    j0, c, lam, f = (
        np.asarray(v, float) for v in (s.glassy, s.strengths, s.times, s.fluidity)
    )

    def creep(x):
        x = np.asarray(x, float)[..., None]
        return j0 + np.sum(c * -np.expm1(-x / lam), -1) + f * x[..., 0]

    def creep_integral(x):  # int_0^x J
        x = np.asarray(x, float)[..., None]
        return (
            j0 * x[..., 0]
            + np.sum(c * (x + lam * np.expm1(-x / lam)), -1)
            + 0.5 * f * x[..., 0] ** 2
        )

    t = np.asarray(times, float)
    nt = t.shape[0]
    w = np.zeros((nt, nt))
    for k in range(nt):
        w[k, 0] = creep(t[k] - t[0])
        for n in range(1, k + 1):
            if scheme == "constant":
                w[k, n] = creep(t[k] - t[n])
            else:
                dt = t[n] - t[n - 1]
                w[k, n] = (
                    creep_integral(t[k] - t[n - 1]) - creep_integral(t[k] - t[n])
                ) / dt
    g = np.zeros(nt)
    for k in range(nt):
        prev = g[k - 1] if k else 0.0
        inc = np.diff(np.concatenate([[0.0], g[:k]]))
        g[k] = prev + (j0 - np.dot(w[k, :k], inc)) / w[k, k]
    return g


# ---- Presets -------------------------------------------------------------------------


def test_paper_presets_reproduce_published_hertz_scales():
    # Table 1: a0 = 117 um, p0 = 3487 MPa; Table 2: a0 = 588.7 um, p0 = 0.2067 MPa.
    h1 = jc.Hertz(T1_R, T1_W, T1_G, T1_NU)
    assert abs(float(h1.contact_radius) / 117e-6 - 1) < 1e-3
    assert abs(float(h1.peak_pressure) / 3487e6 - 1) < 1e-3
    assert abs(float(maxwell().relaxation_time) - T1_TAU) < 1e-12
    h2 = t2_hertz()
    assert abs(float(h2.contact_radius) / 588.7e-6 - 1) < 1e-3
    assert abs(float(h2.peak_pressure) / 0.2067e6 - 1) < 1e-3
    # PMMA: the exact creep series of the converted Eq. 27, in the paper's convention
    # (J_paper = J / 2, in 1/GPa), is Eq. 28: J(inf) = 0.699, strengths 0.0838 and
    # 0.06174 at retardation times 133.869 s and 9.9404 s.
    s = pmma().creep_series()
    paper_j = lambda v: 0.5 * np.asarray(v) * 1e9  # noqa: E731
    assert abs(paper_j(s.glassy + jnp.sum(s.strengths)) - 0.699) < 1e-3
    order = np.argsort(np.asarray(s.times))
    np.testing.assert_allclose(
        paper_j(s.strengths)[order], [0.06174, 0.0838], rtol=2e-3
    )
    np.testing.assert_allclose(np.asarray(s.times)[order], [9.9404, 133.869], rtol=2e-3)


# ---- Lee & Radok, Maxwell (paper section 3, Table 1) ---------------------------------

MAXWELL_N, MAXWELL_NT, MAXWELL_T = (
    128,
    41,
    2.0,
)  # dt = 0.05 tau: t = 0.5, 1, 1.5, 2 on it


@functools.cache
def maxwell_case():
    grid = jc.Grid((MAXWELL_N, MAXWELL_N), T1_DOMAIN)
    times = jnp.linspace(0.0, MAXWELL_T * T1_TAU, MAXWELL_NT)
    scene = jc.Scene(grid, jc.Sphere(T1_R), maxwell(), times, normal=jc.Force(T1_W))
    sol = as_np(jc.solve(scene, solver=jc.Rounds()))  # the grid (the rings' own tests)
    ref = jc.LeeRadok(T1_R, T1_NU, maxwell(), lambda t: T1_W * (t >= 0), samples=1000)
    return grid, np.asarray(times), sol, ref


def test_maxwell_contact_radius_and_approach_follow_lee_radok():
    grid, times, sol, ref = maxwell_case()
    check_converged(sol)
    dx = float(grid.spacing[0])
    a_ref = np.array([ref.contact_radius(t) for t in times])
    a_num = equivalent_radius(sol.contact, grid.cell_area)
    # Within one cell at every step (measured: <= 0.21 cells; a grows 117 -> 169 um,
    # 29 -> 42 cells).
    assert np.max(np.abs(a_num - a_ref)) <= dx, (a_num - a_ref) / dx
    # Approach delta = a^2 / R: relative error <= 1e-3 (measured < 1e-4: the load-
    # controlled approach is insensitive to the discretisation).
    np.testing.assert_allclose(sol.approach, a_ref**2 / T1_R, rtol=1e-3)
    np.testing.assert_allclose(sol.normal_force, T1_W, rtol=1e-10)


@pytest.mark.parametrize("t", [0.5, 1.0, 2.0])
def test_maxwell_pressure_profile_matches_lee_radok(t):
    grid, times, sol, ref = maxwell_case()
    k = int(np.argmin(np.abs(times - t)))
    p0 = float(jc.Hertz(T1_R, T1_W, T1_G, T1_NU).peak_pressure)
    _, _, r = radii(grid)
    p_ref = ref.pressure(r.ravel(), times[k]).reshape(r.shape)
    err = np.abs(sol.pressure[k] - p_ref) / p0
    a = ref.contact_radius(times[k])
    # Away from the edge (r < 0.8 a): <= 1.5 % p0. The error is the first-order time
    # error of the piecewise-constant scheme (measured 0.55-0.72 % at dt = 0.05 tau,
    # 1.1-1.5 % at dt = 0.1 tau) plus the spatial one (~0.1 %).
    assert err[r < 0.8 * a].max() <= 0.015, err[r < 0.8 * a].max()
    # Everywhere, including the edge cells where the profile has an infinite slope and
    # a one-cell shift of the edge costs ~ p sqrt(2 dx / a): <= 6 % p0 (measured
    # 4.3 %, 2.7 %, 2.1 %).
    assert err.max() <= 0.06, err.max()


def test_maxwell_edge_spike_appears_after_one_relaxation_time():
    """Paper section 3 / 4.1: "the spikes on the contacting edges appear ... after a
    relatively long time (t >= 1.0 tau)". Lee & Radok makes this precise: the radial
    profile is monotone at 0.5 tau, becomes non-monotone (a local maximum near 0.8 a)
    at about t = 1.0 tau (onset: flat shoulder, rise ~5e-4 p0), has a clear off-centre
    local maximum at 1.5 tau (rise 0.03 p0), and a GLOBAL maximum off the centre from
    about 1.6 tau (at 2 tau: at r = 0.89 a, 1.23 x the centre pressure). The solver
    reproduces each stage."""
    grid, times, sol, ref = maxwell_case()
    p0 = float(jc.Hertz(T1_R, T1_W, T1_G, T1_NU).peak_pressure)
    dx = float(grid.spacing[0])
    bumps = {}
    for t in (0.5, 1.0, 1.5, 2.0):
        k = int(np.argmin(np.abs(times - t)))
        a = ref.contact_radius(times[k])
        r_ring, p_ring = ring_profile(grid, sol.pressure[k], a)
        p_lr = ref.pressure(r_ring, times[k])
        num, lr = edge_bump(p_ring) / p0, edge_bump(p_lr) / p0
        bumps[t] = (num, lr)
        # The size of the off-centre rise agrees with Lee & Radok within 1 % p0
        # (measured |diff| <= 0.005).
        assert abs(num - lr) <= 0.01, (t, num, lr)
    assert bumps[0.5][0] <= 0.002 and bumps[0.5][1] <= 1e-4, bumps
    assert bumps[1.0][0] <= 0.01, bumps
    assert bumps[1.5][0] >= 0.02 and bumps[2.0][0] >= 0.05, bumps
    # Location of the global maximum: at the centre at 0.5 tau and 1 tau, near the edge
    # at 2 tau (Lee & Radok: r = 0.89 a; within 2 cells). At 2 tau the peak and centre
    # pressures each match Lee & Radok within 1.5 % p0 (measured 0.5 % and 0.6 %), and
    # the peak is > 1.15 x the centre pressure (Lee & Radok 1.225, measured 1.266).
    _, _, r = radii(grid)
    for t, off_centre in ((0.5, False), (1.0, False), (2.0, True)):
        k = int(np.argmin(np.abs(times - t)))
        a = ref.contact_radius(times[k])
        r_max = r.ravel()[np.argmax(sol.pressure[k])]
        if not off_centre:
            assert r_max <= 2 * dx, (t, r_max / dx)
        else:
            grid_r = np.linspace(0, a, 2001)
            p_lr = ref.pressure(grid_r, times[k])
            r_lr = grid_r[np.argmax(p_lr)]
            assert abs(r_max - r_lr) <= 2 * dx, (r_max / a, r_lr / a)
            p_c = centre_pressure(sol, grid)[k]
            p_c_lr = ref.pressure([dx / np.sqrt(2)], times[k])[0]
            assert abs(sol.pressure[k].max() - p_lr.max()) <= 0.015 * p0
            assert abs(p_c - p_c_lr) <= 0.015 * p0
            assert sol.pressure[k].max() > 1.15 * p_c


# ---- Lee & Radok, Zener (paper section 4.1, Table 2) ---------------------------------

ZENER_N, ZENER_NT = 128, 31  # T = 3 tau (paper), dt = 0.1 tau
ZENER_RATIOS = (2, 4, 10)


@functools.cache
def zener_case(ratio, scheme):
    a0 = float(t2_hertz().contact_radius)
    grid = jc.Grid((ZENER_N, ZENER_N), 5.5 * a0)  # the paper's 5.5 a0 square
    times = jnp.linspace(0.0, 3 * T2_TAU, ZENER_NT)
    scene = jc.Scene(
        grid, jc.Sphere(T2_R), zener(ratio=ratio), times, normal=jc.Force(T2_W)
    )
    sol = as_np(jc.solve(scene, solver=jc.Rounds(), scheme=scheme))
    ref = jc.LeeRadok(
        T2_R, T2_NU, zener(ratio=ratio), lambda t: T2_W * (t >= 0), samples=1000
    )
    return grid, np.asarray(times), sol, ref


@pytest.mark.parametrize("scheme", ["constant", "linear"])
@pytest.mark.parametrize("ratio", ZENER_RATIOS)
def test_zener_step_load_follows_lee_radok(ratio, scheme):
    grid, times, sol, ref = zener_case(ratio, scheme)
    check_converged(sol)
    dx = float(grid.spacing[0])
    p0 = float(t2_hertz().peak_pressure)
    a_ref = np.array([ref.contact_radius(t) for t in times])
    a_num = equivalent_radius(sol.contact, grid.cell_area)
    # a(t): within one cell (measured <= 0.21 cells; a grows by ratio^(1/3) at most).
    assert np.max(np.abs(a_num - a_ref)) <= dx, (a_num - a_ref) / dx
    # delta(t) = a(t)^2 / R: relative error <= 1e-3 (measured <= 8.3e-5).
    np.testing.assert_allclose(sol.approach, a_ref**2 / T2_R, rtol=1e-3)
    # p(0, t) (the 4 centre cells, at r = dx / sqrt(2)).
    r_c = dx / np.sqrt(2)
    p_c = centre_pressure(sol, grid)
    p_ref = np.array([ref.pressure([r_c], t)[0] for t in times])
    err = np.abs(p_c - p_ref) / p0
    if scheme == "linear":
        # Everywhere <= 2 % p0 (measured max 0.05 %, 0.18 %, 1.6 % for ratios 2, 4,
        # 10; the largest at the first step after the jump, where dt = 0.1 tau is one
        # relaxation time tau mu_0 / mu_inf for ratio 10).
        assert err.max() <= 0.02, err
    else:
        # The paper's piecewise-constant scheme is first order and resolves the
        # relaxation only once dt << tau mu_0 / mu_inf: early errors are large for
        # ratio 10 (measured 0.7 %, 3.6 %, 21 % at the first steps: the "oscillating
        # results ... during the early period" of the paper's Fig. 8d). After one
        # retardation time: <= 1 % p0 (measured 0.54 %, 0.72 %, 0.09 %).
        late = times >= T2_TAU
        assert err[late].max() <= 0.01, err


# ---- Relaxation under a step displacement --------------------------------------------

RELAX_N, RELAX_NT = 64, 41  # T = 3 tau


def relaxation_material(name):
    if name == "zener":
        return zener(ratio=4)
    # A 2-term Prony solid: G(t) = mu (1/4 + 1/4 e^{-t/0.002} + 1/2 e^{-t/0.01}).
    return jc.Prony(
        T2_MU_INF / 4,
        jnp.asarray([T2_MU_INF / 4, T2_MU_INF / 2]),
        jnp.asarray([0.002, 0.01]),
        T2_NU,
    )


# |F/F0 - G/G0| measured at nt = 41 (dt = 0.075 retardation times), with the order
# observed from nt = 21, 41, 81: constant ~1 (0.079, 0.035, 0.016 for the Zener),
# linear 2 (0.0063, 0.0016, 0.00039).
RELAX_TOL = {
    ("zener", "constant"): 0.05,
    ("zener", "linear"): 0.003,
    ("prony", "constant"): 0.02,
    ("prony", "linear"): 0.001,
}


@pytest.mark.parametrize("scheme", ["constant", "linear"])
@pytest.mark.parametrize("name", ["zener", "prony"])
def test_step_displacement_relaxes_force_like_relaxation_modulus(name, scheme):
    """A rigid sphere pushed to a fixed depth: the contact stays put and every traction
    relaxes by one factor. In the continuum F(t)/F(0) = G(t)/G(0) exactly; the discrete
    scheme gives exactly the factor g_k of its own scalar Volterra recursion
    (`discrete_relaxation`), which tends to G(t)/G(0) at the scheme's order."""
    material = relaxation_material(name)
    a0 = float(t2_hertz().contact_radius)
    grid = jc.Grid((RELAX_N, RELAX_N), 5.5 * a0)
    times = jnp.linspace(0.0, 3 * T2_TAU, RELAX_NT)
    delta = float(t2_hertz().approach)
    scene = jc.Scene(
        grid, jc.Sphere(T2_R), material, times, normal=jc.Displacement(delta)
    )
    sol = as_np(jc.solve(scene, solver=jc.Rounds(), scheme=scheme))
    check_converged(sol)
    np.testing.assert_allclose(sol.approach, delta, rtol=1e-12)
    assert (sol.contact == sol.contact[0]).all()
    force = sol.normal_force / sol.normal_force[0]
    g = discrete_relaxation(material, times, scheme)
    # The discrete solution: exactly g_k, to the solver tolerance (measured 1e-8 for
    # the constant scheme).
    np.testing.assert_allclose(force, g, atol=1e-6)
    p_scaled = g[:, None, None] * sol.pressure[0]
    assert (
        np.abs(sol.pressure - p_scaled).max()
        <= 2 * RTOL * RELAX_N * sol.pressure[0].max()
    )
    # The continuum: G(t)/G(0) to the measured discretisation error.
    exact = np.asarray(material.relaxation(times)) / float(material.relaxation(0.0))
    err = np.abs(force - exact).max()
    print(f"{name} {scheme}: max |F/F0 - G/G0| = {err:.3g}")
    assert err <= RELAX_TOL[name, scheme], err


# ---- PMMA triangular load: Lee & Radok, then Ting (paper section 3, Eqs. 26-27) ------


class TingTriangle:
    """Lee-Radok / Ting (1966) contact radius and approach of a rigid paraboloid on a
    Prony half-space under a piecewise-linear load `W(t) = sum_j rate_j (t - kink_j)_+`
    that rises and then falls (one maximum of the contact radius). See the module docs
    for the formulas. Stieltjes midpoint sums with exact increments on `samples`
    intervals of [0, t_m] and `steps` intervals of [t_m, t_end]."""

    def __init__(
        self,
        radius,
        poisson,
        g_inf,
        g,
        tau,
        creep_series,
        kinks,
        rates,
        t_end,
        samples=20000,
        steps=1000,
    ):
        self.R, self.nu = float(radius), float(poisson)
        self.g_inf, self.g, self.tau = (
            float(g_inf),
            np.asarray(g, float),
            np.asarray(tau, float),
        )
        s = creep_series
        self.j0, self.c, self.lam, self.f = (
            np.asarray(v, float) for v in (s.glassy, s.strengths, s.times, s.fluidity)
        )
        self.kinks, self.rates = np.asarray(kinks, float), np.asarray(rates, float)
        # t_m: the contact radius grows while C'(t) = d/dt int J(t - s) dW(s) > 0.
        fine = np.linspace(0.0, t_end, 200001)
        grows = self.c_rate(fine) > 0
        stop = np.flatnonzero(~grows[1:])[0] + 1
        self.t_m = fine[stop - 1]  # at a kink of W: C' jumps from + to - there
        near = self.kinks[np.abs(self.kinks - fine[stop]) <= fine[1] - fine[0]]
        if near.size:
            self.t_m = float(near[0])
        self.t_end = float(t_end)
        # Loading-branch tables on [0, t_m].
        self.u = np.linspace(0.0, self.t_m, samples + 1)
        self.u_mid = 0.5 * (self.u[1:] + self.u[:-1])
        self.dC = np.diff(self.c_int(self.u))  # exact increments of int J dW
        self.a_u = self.a_loading(self.u)
        self.d_delta = np.diff(self.a_u**2 / self.R)
        self._unloading(steps)

    # Creep and relaxation functions.
    def creep(self, x):
        x = np.asarray(x, float)[..., None]
        return (
            self.j0 + np.sum(self.c * -np.expm1(-x / self.lam), -1) + self.f * x[..., 0]
        )

    def creep_int(self, x):
        x = np.maximum(np.asarray(x, float), 0.0)[..., None]
        return (
            self.j0 * x[..., 0]
            + np.sum(self.c * (x + self.lam * np.expm1(-x / self.lam)), -1)
            + 0.5 * self.f * x[..., 0] ** 2
        )

    def relax(self, x):
        x = np.asarray(x, float)[..., None]
        return self.g_inf + np.sum(self.g * np.exp(-x / self.tau), -1)

    def load(self, t):
        t = np.asarray(t, float)[..., None]
        return np.sum(self.rates * np.maximum(t - self.kinks, 0.0), -1)

    def c_int(self, t):  # int_0^t J(t - s) dW(s)
        t = np.asarray(t, float)[..., None]
        return np.sum(self.rates * self.creep_int(t - self.kinks), -1)

    def c_rate(self, t):  # its derivative (right limit at the kinks)
        t = np.asarray(t, float)[..., None]
        return np.sum(
            self.rates * np.where(t >= self.kinks, self.creep(t - self.kinks), 0), -1
        )

    def a_loading(self, t):
        return (3 * self.R * (1 - self.nu) / 8 * np.maximum(self.c_int(t), 0.0)) ** (
            1 / 3
        )

    def t1(self, t):
        """The earlier time of equal contact radius:
        W(t) = int_0^{t1} G(t - s) dC(s)."""
        w = float(self.load(t))
        if w <= 0:
            return 0.0
        cum = np.concatenate([[0.0], np.cumsum(self.relax(t - self.u_mid) * self.dC)])
        return float(np.interp(w, cum, self.u))

    def _unloading(self, steps):
        v = np.linspace(self.t_m, self.t_end, steps + 1)
        v_mid = 0.5 * (v[1:] + v[:-1])
        t1 = np.array([self.t1(t) for t in v])
        delta = np.zeros(steps + 1)
        delta[0] = self.a_u[-1] ** 2 / self.R
        for j in range(1, steps + 1):
            # Edge condition, split at t_m:
            # int_{t1}^{t_m} G d(delta_loading) + int_{t_m}^{t} G d(delta) = 0.
            weights = self.relax(v[j] - self.u_mid) * self.d_delta
            cum = np.concatenate([[0.0], np.cumsum(weights)])
            known = cum[-1] - np.interp(t1[j], self.u, cum)
            kernel = self.relax(v[j] - v_mid[:j])
            rest = np.dot(kernel[:-1], np.diff(delta[:j]))
            delta[j] = delta[j - 1] - (known + rest) / kernel[-1]
        self.v, self.v_t1, self.v_delta = v, t1, delta

    def contact_radius(self, t):
        t = np.atleast_1d(np.asarray(t, float))
        out = self.a_loading(np.minimum(t, self.t_m))
        late = t > self.t_m
        out[late] = self.a_loading(np.array([self.t1(x) for x in t[late]]))
        return out

    def approach(self, t):
        t = np.atleast_1d(np.asarray(t, float))
        out = self.a_loading(np.minimum(t, self.t_m)) ** 2 / self.R
        late = t > self.t_m
        out[late] = np.interp(t[late], self.v, self.v_delta)
        return out


PMMA_N, PMMA_NT = 128, 41  # the paper's 41 time points on T = 20 s


@functools.cache
def pmma_reference():
    m = pmma()
    return TingTriangle(
        PMMA_R,
        PMMA_NU,
        PMMA_G_INF,
        PMMA_G,
        PMMA_TAU,
        m.creep_series(),
        kinks=[0.0, 10.0],
        rates=[10.0, -20.0],
        t_end=20.0,
    )


@functools.cache
def pmma_case(scheme):
    grid = jc.Grid((PMMA_N, PMMA_N), PMMA_DOMAIN)
    times = jnp.linspace(0.0, 20.0, PMMA_NT)
    scene = jc.Scene(
        grid,
        jc.Sphere(PMMA_R),
        pmma(),
        times,
        normal=jc.Force(lambda t: 10 * t - 20 * (t - 10) * (t > 10)),
    )
    return grid, np.asarray(times), as_np(jc.solve(scene, solver=jc.Rounds(),
                                                   scheme=scheme))


def test_ting_reference_loading_branch_is_lee_radok():
    # The reference's own loading branch against jc.LeeRadok (independent sums).
    ref = pmma_reference()
    assert ref.t_m == 10.0  # the radius peaks with the load (C' jumps from + to -)
    lr = jc.LeeRadok(PMMA_R, PMMA_NU, pmma(), lambda t: 10 * t * (t >= 0), samples=2000)
    for t in (2.0, 6.0, 10.0):
        assert abs(ref.contact_radius(t)[0] / lr.contact_radius(t) - 1) < 1e-5
    # Unloading: a(t) decreases to 0 at W = 0, and t1(t) < t_m decreases.
    assert np.all(np.diff(ref.v_t1) < 0) and ref.v_t1[-1] == 0.0
    # The edge condition makes the load formula consistent with the load itself: for
    # t just after t_m, t1 -> t_m.
    assert abs(ref.t1(10.0 + 1e-9) - 10.0) < 1e-6


# Approach tolerance (fraction of the largest approach, 59.2 um): the piecewise-constant
# scheme lags the ramp by O(dt) (measured 1.33e-3 on both branches at 41 steps, 7e-4 at
# 81); the linear scheme follows the piecewise-linear load exactly in time, what is left
# is spatial (measured 1.2e-4 loading, from the small early contacts, and 5e-5
# unloading; residual indentation 3.7556 um against Ting's 3.7563 um).
PMMA_DELTA_TOL = {"constant": 3e-3, "linear": 2e-4}


@pytest.mark.parametrize("scheme", ["constant", "linear"])
def test_pmma_triangular_load_loading_lee_radok_unloading_ting(scheme):
    grid, times, sol = pmma_case(scheme)
    check_converged(sol)
    ref = pmma_reference()
    dx = float(grid.spacing[0])
    w = 10 * times - 20 * (times - 10) * (times > 10)
    np.testing.assert_allclose(sol.normal_force, w, atol=1e-8 * 100)
    a_num = equivalent_radius(sol.contact, grid.cell_area)
    a_ref = ref.contact_radius(times)
    d_num, d_ref = sol.approach, ref.approach(times)
    d_max = d_ref.max()
    loading, unloading = times <= ref.t_m, times > ref.t_m
    # Contact radius within one cell on both branches (measured <= 0.17 cells; a goes
    # 0 -> 455 um -> 0, 45 cells at the top).
    assert np.max(np.abs(a_num - a_ref)[loading]) <= dx, (a_num - a_ref) / dx
    assert np.max(np.abs(a_num - a_ref)[unloading]) <= dx, (a_num - a_ref) / dx
    # Approach: loading vs Lee & Radok, unloading vs Ting.
    tol = PMMA_DELTA_TOL[scheme]
    e_load = np.abs(d_num - d_ref)[loading].max() / d_max
    e_unload = np.abs(d_num - d_ref)[unloading].max() / d_max
    print(
        f"PMMA {scheme}: approach error / delta_max: loading {e_load:.2e}, "
        f"unloading {e_unload:.2e}; residual delta {d_num[-1] * 1e6:.4f} um "
        f"(Ting {d_ref[-1] * 1e6:.4f} um)"
    )
    assert e_load <= tol and e_unload <= tol, (e_load, e_unload)


def test_pmma_hysteresis_and_residual_indentation():
    """Paper Fig. 6b: indentation against load is a hysteresis loop; at W = 0 (t = 20 s)
    an indentation remains (the surface has not recovered)."""
    grid, times, sol = pmma_case("linear")
    ref = pmma_reference()
    k_top = int(np.argmin(np.abs(times - 10.0)))
    # Same load on both branches: t and 20 - t. The unloading indentation is larger, by
    # Ting's amount within 2e-4 delta_max (measured 3.4e-5; the difference is 0.30 um
    # next to the top, 3.6 um at W = 5 N).
    d_ref = ref.approach(times)
    for k in range(1, k_top):
        k_back = len(times) - 1 - k
        assert abs(sol.normal_force[k] - sol.normal_force[k_back]) < 1e-9
        gap, gap_ref = sol.approach[k_back] - sol.approach[k], d_ref[k_back] - d_ref[k]
        assert gap > 0.005 * sol.approach[k_top]
        assert abs(gap - gap_ref) <= 2e-4 * sol.approach[k_top], (k, gap, gap_ref)
    # At W = 0: no contact, residual indentation = Ting's (3.756 um, 6.3 % of the
    # largest approach) within 2e-4 delta_max (measured 7e-4 um).
    assert sol.normal_force[-1] == 0 and not sol.contact[-1].any()
    d_max = sol.approach[k_top]
    assert sol.approach[-1] > 0.05 * d_max
    assert abs(sol.approach[-1] - ref.approach(20.0)[0]) <= 2e-4 * d_max
    # Dissipated energy: the work done on the body over the cycle, int W d(delta), is
    # positive (at equal indentation the load is higher on the loading branch).
    work = np.sum(
        0.5 * (sol.normal_force[1:] + sol.normal_force[:-1]) * np.diff(sol.approach)
    )
    assert work > 0


# ---- Constant inputs with friction and full coupling (paper section 4.2.1) -----------

CONST_N, CONST_NT, CONST_MU = 48, 21, 0.3  # T = 2 tau (paper), Zener mu_inf / mu_0 = 4


@functools.cache
def constant_input_case(kind):
    """LC: normal load W, tangential load F_x = 0.5 mu W (creep). DC: normal load W,
    tangential displacement fixed at the LC case's first-step value (relaxation in x;
    the paper's delta_x = 6.1987 um for F_x = 0.5 mu W, here 6.18 um). REL: normal
    approach AND tangential displacement fixed at the LC first-step values (the paper's
    "relaxation case", Fig. 21, with its total-slip law, Eq. 16)."""
    a0 = float(t2_hertz().contact_radius)
    grid = jc.Grid((CONST_N, CONST_N), 5.5 * a0)
    times = jnp.linspace(0.0, 2 * T2_TAU, CONST_NT)
    common = dict(friction=CONST_MU, coupling="full")
    base = functools.partial(jc.Scene, grid, jc.Sphere(T2_R), zener(ratio=4), times)
    if kind == "LC":
        scene = base(normal=jc.Force(T2_W), x=jc.Force(0.5 * CONST_MU * T2_W), **common)
        return grid, np.asarray(times), scene, as_np(jc.solve(scene))
    _, _, _, lc = constant_input_case("LC")
    dx0, dz0 = float(lc.tangential_displacement[0, 0]), float(lc.approach[0])
    if kind == "DC":
        scene = base(normal=jc.Force(T2_W), x=jc.Displacement(dx0), **common)
        return grid, np.asarray(times), scene, as_np(jc.solve(scene))
    scene = base(
        normal=jc.Displacement(dz0), x=jc.Displacement(dx0), slip="total", **common
    )
    return grid, np.asarray(times), scene, as_np(jc.solve(scene))


# The default run keeps LC through notebooks/paper_reproduction.py (ci size).
@pytest.mark.slow  # LC: paper_reproduction notebook asserts F_x = 0.5 mu W
def test_constant_tangential_load_creeps():
    """LC (creep in x). The paper's Fig. 16: F_x constant, contact and stick areas grow.
    Ours: F_x = 0.5 mu W to 1e-6 at every step (load control); contact area never
    shrinks (measured 244 -> 552 cells; the normal creep alone: delta_z 34.3 -> 80.6
    um); the rigid tangential displacement creeps monotonically (6.18 -> 15.46 um, while
    J(2 tau) / J(0) = 3.6: partial slip and the growing contact make it less); no gross
    sliding. Stick ratio: 0.25 at the first step (the normal load and F_x applied at
    once), then 0.53-0.58 (the creep increments are small and mostly stick)."""
    grid, times, scene, sol = constant_input_case("LC")
    check_converged(sol)
    np.testing.assert_allclose(sol.normal_force, T2_W, rtol=1e-8)
    np.testing.assert_allclose(
        sol.tangential_force[:, 0], 0.5 * CONST_MU * T2_W, rtol=1e-6
    )
    assert np.abs(sol.tangential_force[:, 1]).max() <= 1e-6 * CONST_MU * T2_W
    n_contact = sol.contact.sum(axis=(1, 2))
    assert np.all(np.diff(n_contact) >= 0), n_contact
    assert n_contact[-1] > 1.8 * n_contact[0]
    assert np.all(np.diff(sol.tangential_displacement[:, 0]) > 0)
    assert np.all(np.diff(sol.approach) > 0)
    assert not sol.sliding.any() and np.all(
        (sol.stick_ratio > 0.1) & (sol.stick_ratio < 1)
    )


@pytest.mark.parametrize(
    "material, duration",
    # Zener mu_inf / mu_0 = 10 (relaxation time tau / 10) and a Maxwell fluid, both as
    # one-arm Prony series: one compiled program for the two.
    [
        (jc.Prony(T2_MU_INF / 10, [0.9 * T2_MU_INF], [T2_TAU / 10], T2_NU), 4 * T2_TAU),
        (jc.Prony(0.0, [T2_MU_INF], [T2_TAU], T2_NU), 5 * T2_TAU),
    ],
    ids=["zener-10", "maxwell"],
)
def test_tangential_load_control_on_fluid_like_materials(material, duration):
    """Paper 4.2.2: "a load-controlled algorithm in the tangential direction could fail
    to converge when the contact of a viscoelastic material with a relatively high ratio
    is considered" (fluid-like, after a long time). Ours controls the load directly; the
    LC case (W and F_x = 0.5 mu W from t = 0, full coupling, the paper's total slip law)
    on Zener mu_inf / mu_0 = 10 over 4 tau (J x9.8) and on a Maxwell fluid over 5 tau
    (J x6) converges at every step in the joint iteration alone (max_steps = 60, no
    fallback; measured at most 16 iterations a step at 32^2, 41 steps).

    Exact reference (correspondence, as Lee & Radok's for the normal problem): let
    `(p_e, q_e)(s)` be the ELASTIC solution (unit modulus) for the loads `J(s) (W, F)`
    and `(p, q)(t) = int G(t - s) d(p_e, q_e)(s)`. Then `u(t) = K (p_e, q_e)(t)`
    (`G * dJ = 1`): the gap and the total slip are the elastic ones at `J(t) (W, F)`;
    a cell outside the contact, or slipping (`q_e = mu p_e`), at `t` was so at every
    `s <= t` since the zones grow, so `p = 0` there, resp. `q = mu p`; the loads are
    `(W, F)`. Under the path-independent total law the elastic problem is self-similar
    under proportional loads (`a ~ W^(1/3)`, rigid displacements `~ W^(2/3)`), so
    `delta_z(t) / delta_z(0) = delta_x(t) / delta_x(0) = (J(t) / J(0))^(2/3)` and the
    stick ratio is constant. Exact without coupling (measured, coupling "none": 4-6e-3
    at 32^2, 4-6e-4 at 64^2). With it, the shear direction of a slipping cell depends on
    r / a and turns as the zones grow, so `q = int G dq_e` falls slightly inside the
    disc: `delta_x` departs by 3e-3 at 32^2 and at 64^2 (physical), `delta_z` by 1.4e-3
    and 1.5e-4. Checked to 1 % (21 steps instead of 41: 2e-2 for the Zener case, whose
    steps would be two relaxation times), and c / a = sqrt(stick ratio) within 0.08
    (measured 0.03-0.05: cell counts). Also F_x = 0.5 mu W to 1e-6 at every step and
    |q| <= mu p."""
    a0 = float(t2_hertz().contact_radius)
    grid = jc.Grid((32, 32), 5.5 * a0)
    times = jnp.linspace(0.0, duration, 41)
    fx = 0.5 * CONST_MU * T2_W
    scene = jc.Scene(
        grid,
        jc.Sphere(T2_R),
        material,
        times,
        normal=jc.Force(T2_W),
        x=jc.Force(fx),
        friction=CONST_MU,
        coupling="full",
        slip="total",
    )
    sol = as_np(jc.solve(scene, max_steps=60, max_rounds=3))
    check_converged(sol)
    assert sol.iterations.max() <= 60, sol.iterations
    assert not sol.edge_contact.any() and not sol.sliding.any()
    np.testing.assert_allclose(sol.tangential_force[:, 0], fx, rtol=1e-6)
    np.testing.assert_allclose(sol.normal_force, T2_W, rtol=1e-8)
    q_mag = np.hypot(sol.shear[:, 0], sol.shear[:, 1])
    assert np.all(q_mag <= CONST_MU * sol.pressure * (1 + 1e-6) + 1e-12 * T2_W)
    growth = np.asarray(material.creep(times) / material.creep(0.0)) ** (2 / 3)
    dx = sol.tangential_displacement[:, 0]
    np.testing.assert_allclose(dx / dx[0], growth, rtol=1e-2)
    np.testing.assert_allclose(sol.approach / sol.approach[0], growth, rtol=1e-2)
    c_over_a = np.sqrt(sol.stick_ratio)
    assert np.ptp(c_over_a) <= 0.08, c_over_a


# The default run keeps DC through notebooks/paper_reproduction.py (ci size).
@pytest.mark.slow  # DC: paper_reproduction notebook asserts F_x relaxes
def test_constant_tangential_displacement_relaxes():
    """DC (relaxation in x). The paper's Fig. 16a: F_x relaxes. Ours: delta_x fixed; F_x
    decreases monotonically from 0.5 mu W to 0.125 mu W, i.e. by the factor
    G(2 tau) / G(0) = 0.2503 of the material (measured 0.2498: the partial slip and the
    growing contact change it only slightly); the contact grows as in LC (same normal
    load; at T 552 cells in both: the paper's "LC grows faster" through the coupling is
    below one cell here). The first step is the LC first step. Stick ratio: 0.25 at
    the first step, then 0.75-0.82, ABOVE the LC case at every later step (tangential
    unloading slips nothing: the new and relaxing cells stick). The paper (Fig. 16a,
    total-slip law) reports the DC stick ratio LOWER than LC after some time, with an
    insignificant difference: we do not reproduce that ordering (with the paper's total
    law our DC stick ratio is 0.25-0.28 and LC 0.24-0.26, still not lower; with that
    law the LC stick ratio is constant in time, see
    `test_tangential_load_control_on_fluid_like_materials`; it converges at every step,
    11-16 iterations: the coupled rounds of an early version ran out after about 12
    steps, as the paper reports for load control in x)."""
    grid, times, scene, sol = constant_input_case("DC")
    _, _, _, lc = constant_input_case("LC")
    check_converged(sol)
    np.testing.assert_allclose(sol.normal_force, T2_W, rtol=1e-8)
    fx = sol.tangential_force[:, 0]
    np.testing.assert_allclose(fx[0], 0.5 * CONST_MU * T2_W, rtol=1e-6)
    assert np.all(np.diff(fx) < 0), fx
    material = zener(ratio=4)
    g_ratio = float(material.relaxation(times[-1]) / material.relaxation(0.0))
    assert abs(fx[-1] / fx[0] - g_ratio) <= 0.02, (fx[-1] / fx[0], g_ratio)
    # Same first step as LC (same elastic problem).
    assert (sol.contact[0] == lc.contact[0]).all() and (
        sol.stick[0] == lc.stick[0]
    ).all()
    n_contact = sol.contact.sum(axis=(1, 2))
    assert np.all(np.diff(n_contact) >= 0), n_contact
    # Contact areas of DC and LC at the end: equal within 2 % (same normal load).
    assert abs(n_contact[-1] - lc.contact[-1].sum()) <= 0.02 * n_contact[-1]
    assert np.all(sol.stick_ratio[1:] > lc.stick_ratio[1:]), (
        sol.stick_ratio,
        lc.stick_ratio,
    )


# The default run keeps REL through notebooks/paper_reproduction.py (ci size).
@pytest.mark.slow  # REL: notebook asserts F_x / mu W, stick pattern constant
def test_constant_displacements_relax_self_similarly():
    """REL (paper Fig. 21: "the ratio of the tangential load to the static friction
    remains constant"; the stick/slip pattern is time-independent). Exact for the
    discrete scheme: with both rigid displacements fixed, tau_k = g_k tau_0 (g_k the
    scalar recursion of `discrete_relaxation`) keeps every surface displacement at its
    first-step value, so W and F_x relax by the same factor, F_x / (mu W) is constant,
    the contact and (with the paper's total-slip law) the stick zone are fixed."""
    grid, times, scene, sol = constant_input_case("REL")
    check_converged(sol)
    g = discrete_relaxation(zener(ratio=4), times, "constant")
    np.testing.assert_allclose(sol.normal_force / sol.normal_force[0], g, atol=1e-6)
    np.testing.assert_allclose(
        sol.tangential_force[:, 0] / sol.tangential_force[0, 0], g, atol=1e-6
    )
    assert (sol.contact == sol.contact[0]).all()
    assert (sol.stick == sol.stick[0]).all()
    tol = 2 * RTOL * CONST_N
    assert np.abs(sol.pressure - g[:, None, None] * sol.pressure[0]).max() <= (
        tol * sol.pressure[0].max()
    )
    assert np.abs(sol.shear - g[:, None, None, None] * sol.shear[0]).max() <= (
        tol * CONST_MU * sol.pressure[0].max()
    )


@pytest.mark.slow
def test_normal_load_alone_stick_ratio_insensitive_to_ratio():
    """Paper 4.2.1, Figs. 14-15: under the normal load alone (coupling makes it slip),
    the stick and contact areas grow with mu_inf / mu_0 but the stick ratio hardly
    changes. Measured (n = 48, 21 steps, incremental law): stick ratio at T 0.803
    (ratio 3) and 0.794 (ratio 10); contact 468 and 1012 cells; stick 376 and 804."""
    a0 = float(t2_hertz().contact_radius)
    grid = jc.Grid((CONST_N, CONST_N), 5.5 * a0)
    times = jnp.linspace(0.0, 2 * T2_TAU, CONST_NT)
    out = {}
    for ratio in (3, 10):
        scene = jc.Scene(
            grid,
            jc.Sphere(T2_R),
            zener(ratio=ratio),
            times,
            normal=jc.Force(T2_W),
            friction=CONST_MU,
            coupling="full",
        )
        out[ratio] = sol = as_np(jc.solve(scene))
        check_converged(sol)
        assert np.abs(sol.tangential_force).max() <= 1e-6 * CONST_MU * T2_W
    s3, s10 = out[3], out[10]
    assert s10.contact[-1].sum() > 1.5 * s3.contact[-1].sum()
    assert s10.stick[-1].sum() > 1.5 * s3.stick[-1].sum()
    assert abs(s10.stick_ratio[-1] - s3.stick_ratio[-1]) <= 0.05


# ---- Observed order in Nt of the two schemes -----------------------------------------


def _order_run(n, nt, scheme):
    a0 = float(t2_hertz().contact_radius)
    grid = jc.Grid((n, n), 5.5 * a0)
    t_end = 3 * T2_TAU
    times = jnp.linspace(0.0, t_end, nt)
    # A smooth, non-linear load (a linear ramp is integrated EXACTLY by the linear
    # scheme: the approach follows int J dW, measured error 1e-10 at every Nt).
    load = jc.Force(lambda t: T2_W * jnp.sin(jnp.pi * t / (2 * t_end)))
    sol = jc.solve(
        jc.Scene(grid, jc.Sphere(T2_R), zener(ratio=4), times, normal=load),
        solver=jc.Rounds(),
        scheme=scheme,
        history="recursive",
    )
    check_converged(sol)
    return float(sol.approach[-1])


def _observed_orders(n, nts, nt_ref):
    ref = _order_run(n, nt_ref, "linear")
    dts = 3 * T2_TAU / (np.asarray(nts) - 1)
    orders = {}
    for scheme in ("constant", "linear"):
        errs = np.array([abs(_order_run(n, nt, scheme) - ref) / ref for nt in nts])
        orders[scheme] = np.polyfit(np.log(dts), np.log(errs), 1)[0]
        print(
            f"n={n} {scheme}: Nt={list(nts)} rel. approach error at T={errs}, "
            f"order {orders[scheme]:.3f}"
        )
    return orders


def test_observed_order_in_time_steps():
    # Zener mu_inf / mu_0 = 4, W = W_max sin(pi t / 2T), T = 3 tau, n = 32; error of the
    # approach at T against Nt = 641 (linear). Measured (against 481 and 1281, the same
    # to 3 digits): constant 1.065 (errors 1.9e-2, 9.0e-3, 4.3e-3), linear 2.00 (9.5e-4,
    # 2.4e-4, 6.0e-5).
    orders = _observed_orders(32, (11, 21, 41), 641)
    assert 0.8 < orders["constant"] < 1.3
    assert orders["linear"] > 1.6


@pytest.mark.slow
def test_observed_order_in_time_steps_finer():
    # n = 48, Nt = 11 .. 81 against 1281. Measured: constant 1.05 (pairwise 1.08,
    # 1.04, 1.02), linear 2.00 (2.00, 2.00, 2.00).
    orders = _observed_orders(48, (11, 21, 41, 81), 1281)
    assert 0.8 < orders["constant"] < 1.3
    assert orders["linear"] > 1.8


# ---- History paths -------------------------------------------------------------------


def test_recursive_and_direct_history_agree_through_full_solves():
    # A Prony FLUID (g_inf = 0: creep series with a fluidity term and an exponential),
    # smooth load, n = 64, 21 steps: the O(Nt) recursion and the paper's O(Nt^2) sum
    # give the same solution to the solver tolerance.
    a0 = float(t2_hertz().contact_radius)
    grid = jc.Grid((64, 64), 5.5 * a0)
    times = jnp.linspace(0.0, 2 * T2_TAU, 21)
    material = jc.Prony(
        0.0,
        jnp.asarray([T2_MU_INF / 2, T2_MU_INF / 2]),
        jnp.asarray([0.005, 0.05]),
        T2_NU,
    )
    assert float(material.creep_series().fluidity) > 0
    scene = jc.Scene(
        grid,
        jc.Sphere(T2_R),
        material,
        times,
        normal=jc.Force(lambda t: T2_W * jnp.sin(jnp.pi * t / (4 * T2_TAU))),
    )
    rec = as_np(jc.solve(scene, solver=jc.Rounds(), history="recursive"))
    direct = as_np(jc.solve(scene, solver=jc.Rounds(), history="direct"))
    check_converged(rec)
    check_converged(direct)
    assert abs(rec.approach[-1] / rec.approach[1] - 1) > 0.5  # strong creep
    np.testing.assert_allclose(rec.approach, direct.approach, rtol=1e-7)
    assert np.abs(rec.pressure - direct.pressure).max() <= 1e-7 * rec.pressure.max()


def test_elastic_material_carries_no_history():
    times = jnp.linspace(0.0, 1.0, 5)
    hist = _history_for(jc.Elastic(T2_MU_INF, T2_NU), times, "auto", "constant")
    assert isinstance(hist, ElasticHistory)
    assert hist.init((3, 8, 8), jnp.float64) == ()
    assert hist.prepare((), jnp.zeros((3, 8, 8)), 0, 0.1).traction is None
    # A Zener material takes the recursion, with m + 1 = 2 fields.
    rec = _history_for(zener(ratio=4), times, "auto", "constant")
    assert isinstance(rec, RecursiveHistory)
    assert len(jax.tree_util.tree_leaves(rec.init((3, 8, 8), jnp.float64))) == 2


def test_zener_without_creep_equals_elastic():
    # mu_0 = mu_inf: J(t) = 1 / mu_inf; a smooth load over 11 steps gives the elastic
    # solution to rounding.
    a0 = float(t2_hertz().contact_radius)
    grid = jc.Grid((64, 64), 5.5 * a0)
    times = jnp.linspace(0.0, 2 * T2_TAU, 11)
    load = jc.Force(lambda t: T2_W * jnp.sin(jnp.pi * t / (4 * T2_TAU)))
    sols = [
        as_np(jc.solve(jc.Scene(grid, jc.Sphere(T2_R), m, times, normal=load),
                       solver=jc.Rounds()))
        for m in (
            jc.Elastic(T2_MU_INF, T2_NU),
            jc.Zener(T2_MU_INF, T2_MU_INF, T2_TAU, T2_NU),
        )
    ]
    el, ze = sols
    check_converged(el)
    check_converged(ze)
    np.testing.assert_allclose(ze.approach, el.approach, rtol=1e-12)
    assert np.abs(ze.pressure - el.pressure).max() <= 1e-12 * el.pressure.max()
    # ... and the elastic solution at each step is the Hertz solution of its load.
    for k in (5, 10):
        w = float(el.normal_force[k])
        delta_h = float(jc.Hertz(T2_R, w, T2_MU_INF, T2_NU).approach)
        assert abs(el.approach[k] / delta_h - 1) < 1e-3
