r"""Frictional partial slip: Cattaneo-Mindlin, Coulomb's law pointwise, coupled normal
loading (Spence), the dense reference solver, friction laws, gross sliding.

Every test states a physical or numerical fact with its tolerance. Conventions
(docs/conventions.md): z points into the half-space; `sol.shear` is the traction ON the
half-space; the slip is `s = u_t - delta_t` (surface tangential displacement minus the
rigid tangential displacement of the indenter), and the incremental Coulomb law acts on
the slip increment `Ds_k = s_k - s_{k-1}`: `Ds = 0` in stick cells, `q = -mu p Ds/|Ds|`
in slip cells.

The displacements used to check the solutions are recomputed here, independently of
the solver's internal state, as `u = jc.HalfSpace(grid, coupling).apply((q_x, q_y, p),
nu) / G` (the operator is tested against dense convolution in test_operator.py).

Solver tolerance: `jc.solve` stops at `rtol = 1e-8` on L2 norms of the Coulomb / gap
violations relative to L2 norms of the displacement field. Pointwise, a violation can
therefore reach about `rtol * n` of the largest displacement, and tractions (through
the conditioning of the operator, ~ n) about `rtol * n` of the peak. Two solutions of
the same discrete problem reached along different iteration paths are compared to
`same(n) = 2 rtol n` (1e-6 at n = 48, 1.3e-6 at n = 64) of max p and mu max p; against
the dense reference both solvers run at 1e-10 and are compared to 1e-8.

Compilation dominates the run time, so solutions are cached (`functools.cache`) and
shared between tests, and scenes that differ only in dynamic values (loads, Poisson's
ratio, friction, grid size) reuse one compiled program: every normal ramp runs on a
40-step time axis whose load ramps in `m` increments and is then held (holding a load
is a no-op under the incremental law, which is itself checked).

Parameters (as in the paper's elastic checks): rigid sphere R = 10 mm,
G = 1 MPa, nu = 0.3, W = 0.15 N, mu = 0.3, grid of 4 Hertz radii unless stated.
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import reference_dense as rd
from helpers import (
    SOLUTION_FIELDS,
    as_np,
    check_converged,
    equivalent_radius,
    hertz_radius,
    radii,
    same,
)

import jaxcontact as jc


R, W, G, NU, MU = 10e-3, 0.15, 1e6, 0.3, 0.3
# The tests share cached solutions and their compiled programs (functools.cache):
# one test process runs them all (an xdist group, see tests/conftest.py).
pytestmark = pytest.mark.xdist_group("partial_slip")

RTOL = 1e-8  # jc.solve's default in float64


def scene(n, times, *, nu=NU, mu=MU, span=4.0, **kwargs):
    grid = jc.Grid((n, n), span * hertz_radius(nu))
    return jc.Scene(
        grid, jc.Sphere(R), jc.Elastic(G, nu), times=times, friction=mu, **kwargs
    )


# ------------------------------------------------------------------ cached solutions


@functools.cache
def cattaneo_mindlin_128():
    """Uncoupled (Mindlin's assumptions): W constant, F_x/(mu W) = 0, .25, .5, .75.

    n = 128 over 4 a: 32 cells per contact radius. The tangential load increases
    monotonically, for which the incremental solution is Mindlin's."""
    ratios = np.array([0.0, 0.25, 0.5, 0.75])
    sc = scene(
        128,
        jnp.arange(4.0),
        normal=jc.Force(W),
        x=jc.Force(ratios * MU * W),
        coupling="none",
    )
    sol = as_np(jc.solve(sc))
    check_converged(sol, SOLUTION_FIELDS)
    return sc, sol, ratios


RAMP_N, RAMP_NT = 64, 40


@functools.cache
def normal_ramp(m, nu=NU, mu=MU, slip="incremental"):
    """Fully coupled normal load alone, ramped to W in `m` equal increments and then
    held, on a 40-step time axis (one compiled program for every `m`, nu and mu)."""
    loads = W * np.minimum(np.arange(1, RAMP_NT + 1), m) / m
    sc = scene(
        RAMP_N,
        jnp.arange(float(RAMP_NT)),
        nu=nu,
        mu=mu,
        normal=jc.Force(loads),
        coupling="full",
        slip=slip,
    )
    sol = as_np(jc.solve(sc))
    check_converged(sol, SOLUTION_FIELDS)
    return sc, sol, loads


HIST_N, HIST_NT = 48, 10
HIST_W = W * np.minimum(np.arange(1, HIST_NT + 1), 4) / 4  # ramp in 4, then hold
HIST_F = MU * W * np.array([0, 0, 0, 0, 0.25, 0.5, 0.7, 0.4, 0.1, -0.3])


@functools.cache
def coupled_history(direction="x", nu=NU):
    """Fully coupled: normal ramp (partial slip from the coupling alone), then a
    tangential load along `direction` that grows, is partly removed and reversed."""
    kw = {direction: jc.Force(HIST_F)}
    sc = scene(
        HIST_N,
        jnp.arange(float(HIST_NT)),
        nu=nu,
        normal=jc.Force(HIST_W),
        coupling="full",
        **kw,
    )
    sol = as_np(jc.solve(sc))
    check_converged(sol, SOLUTION_FIELDS)
    forces = np.zeros((HIST_NT, 2))
    forces[:, "xy".index(direction)] = HIST_F
    return sc, sol, HIST_W, forces


OBLIQUE_AMP = np.array([0, 0, 0, 0, 0.3, 0.6, 0.8, 0.5, 0.2, -0.2])
OBLIQUE_DEG = np.array([0, 0, 0, 0, 0, 20, 40, 60, 80, 100.0])


@functools.cache
def uncoupled_history(amplitudes=tuple(OBLIQUE_AMP), degrees=tuple(OBLIQUE_DEG), nu=NU):
    """Uncoupled, both tangential directions load controlled: an oblique load whose
    direction rotates while its magnitude changes (a genuinely 2-D slip path)."""
    amp, th = np.asarray(amplitudes), np.deg2rad(np.asarray(degrees))
    forces = MU * W * np.stack([amp * np.cos(th), amp * np.sin(th)], axis=1)
    sc = scene(
        HIST_N,
        jnp.arange(float(HIST_NT)),
        nu=nu,
        normal=jc.Force(HIST_W),
        x=jc.Force(forces[:, 0]),
        y=jc.Force(forces[:, 1]),
        coupling="none",
    )
    sol = as_np(jc.solve(sc))
    check_converged(sol, SOLUTION_FIELDS)
    return sc, sol, HIST_W, forces


# ------------------------------------------------------------------ Coulomb checks


def surface_fields(sc, sol, law="incremental"):
    """Displacements `u` (nt, 3, nx, ny), slip `s` and slip increment `Ds`
    (nt, 2, nx, ny), recomputed from the tractions with an independent operator call."""
    op = jc.HalfSpace(sc.grid, sc.coupling)
    nu = sc.material.poisson
    traction = jnp.concatenate(
        [jnp.asarray(sol.shear), jnp.asarray(sol.pressure)[:, None]], axis=1
    )
    u = np.asarray(jax.vmap(lambda t: op.apply(t, nu))(traction)) / G
    s = u[:, :2] - sol.tangential_displacement[:, :, None, None]
    if law == "incremental":
        ds = np.diff(s, axis=0, prepend=np.zeros_like(s[:1]))
    else:
        ds = s
    return u, s, ds


def coulomb_residuals(sc, sol, law="incremental"):
    """Per step: friction excess, |q| - mu p on slip cells, |Ds| on stick cells,
    misalignment of q with -Ds on slip cells, and the natural residual
    |Ds + (|Ds|/(mu p)) q| on slip cells (zero iff Ds is a non-positive multiple of q,
    well defined where |Ds| vanishes). Lengths relative to the step's displacement
    scale max(|u|, approach), tractions to mu max p."""
    mu = float(sc.friction)
    u, _, ds = surface_fields(sc, sol, law)
    out = []
    for k in range(sol.pressure.shape[0]):
        p, q = sol.pressure[k], sol.shear[k]
        stick, contact = sol.stick[k], sol.contact[k]
        slip = contact & ~stick
        scale_q = mu * p.max()
        scale_u = max(np.abs(u[k]).max(), abs(sol.approach[k]))
        qn, dsn = np.hypot(*q), np.hypot(*ds[k])
        big = slip & (dsn > 1e-4 * scale_u)
        cos = np.sum(q * ds[k], axis=0) / np.where(big, qn * dsn, 1.0)
        ratio = np.where(slip, dsn / np.where(slip, mu * p, 1.0), 0.0)
        natural = np.hypot(*(ds[k] + ratio * q))
        out.append(
            dict(
                excess=np.max(qn - mu * p * (1 + 1e-6)) / scale_q,
                outside=np.max(np.where(contact, 0.0, qn)) / scale_q,
                on_disc=np.max(np.where(slip, np.abs(qn - mu * p), 0.0)) / scale_q,
                stick_slip=np.max(np.where(stick, dsn, 0.0)) / scale_u,
                misalignment=np.max(np.where(big, 1 + cos, 0.0)),
                natural=np.max(np.where(slip, natural, 0.0)) / scale_u,
                n_stick=int(stick.sum()),
                n_slip=int(slip.sum()),
            )
        )
    return out


def masks_agree(a, b, sol_a, sol_b, mu, margin=1e-5):
    """Two stick masks agree except on marginal cells (|q| within `margin` of mu p in
    either solution: the stick/slip boundary, decided at solver tolerance)."""

    def marginal(sol_):
        qn = np.hypot(*sol_["q"])
        return sol_["contact"] & (qn >= mu * sol_["p"] * (1 - margin))

    differ = a != b
    return not np.any(differ & ~(marginal(sol_a) | marginal(sol_b))), int(differ.sum())


def traction_dict(sol, k, transform=lambda f: f):
    return dict(
        p=transform(sol.pressure[k]),
        q=np.stack([transform(c) for c in sol.shear[k]]),
        contact=transform(sol.contact[k]),
    )


# ==================================================================== Cattaneo-Mindlin


def test_cattaneo_mindlin_stick_radius():
    """c/a = (1 - F/(mu W))^(1/3) within one cell (n = 128: a = 32 cells), from the
    stick area and along the x axis (the two rows of cells next to y = 0)."""
    sc, sol, ratios = cattaneo_mindlin_128()
    a = hertz_radius()
    dx = float(sc.grid.spacing[0])
    x, _, r = radii(sc.grid)
    n = sc.grid.shape[0]
    assert sol.stick[0].sum() == sol.contact[0].sum()  # F = 0: all stick
    for k in range(1, len(ratios)):
        stick = sol.stick[k]
        c_th = a * (1 - ratios[k]) ** (1 / 3)
        c_area = equivalent_radius(stick, sc.grid.cell_area)
        assert abs(c_area - c_th) <= dx, (k, (c_area - c_th) / dx)
        for j in (n // 2 - 1, n // 2):  # rows at y = -dx/2, +dx/2
            xs = x[stick[:, j], j]
            half = 0.5 * (xs.max() - xs.min() + dx)
            c_axis = np.hypot(half, 0.5 * dx)
            assert abs(c_axis - c_th) <= dx, (k, j, (c_axis - c_th) / dx)
        # a central stick disc: every stick cell within a cell of c
        assert r[stick].max() <= c_th + dx


def test_cattaneo_mindlin_shear_profile():
    """q(r) = mu p0 / a [sqrt(a^2 - r^2) - sqrt(c^2 - r^2) (r < c)] (Johnson 1985, 7.2)
    along the x axis, within 2e-3 mu p0 away from the edges.

    Justification: away from r = a the discrete Hertz pressure is within ~1e-3 p0 of
    the analytic one at 32 cells per radius (measured 7e-4 p0); the slip-annulus shear
    is mu p and the stick-zone shear the difference of two such elliptic profiles, so
    it inherits that error. At r = a and r = c the analytic profiles have an infinite
    slope: a boundary that is resolved to a cell gives O(sqrt(dx/a)) errors there, so
    the cells within 2 dx of r = a and r = c are excluded. Measured: <= 8e-4 mu p0
    (1.6e-2 including the edge cells)."""
    sc, sol, ratios = cattaneo_mindlin_128()
    hz = jc.Hertz(R, W, G, NU)
    a, p0 = float(hz.contact_radius), float(hz.peak_pressure)
    dx = float(sc.grid.spacing[0])
    _, _, r = radii(sc.grid)
    n = sc.grid.shape[0]
    for k in range(1, len(ratios)):
        c = a * (1 - ratios[k]) ** (1 / 3)
        for j in (n // 2 - 1, n // 2):
            rr = r[:, j]
            q_th = (
                MU
                * p0
                / a
                * (
                    np.sqrt(np.maximum(a * a - rr * rr, 0.0))
                    - np.sqrt(np.maximum(c * c - rr * rr, 0.0))
                )
            )
            away = (rr < a - 2 * dx) & (np.abs(rr - c) > 2 * dx)
            err = np.abs(sol.shear[k, 0, :, j] - q_th) / (MU * p0)
            assert err[away].max() <= 2e-3, (k, err[away].max())
            assert away.sum() >= 40
            np.testing.assert_array_equal(sol.shear[k, 1], 0.0)


def test_cattaneo_mindlin_compliance():
    """Rigid sphere on ONE elastic body (half of Johnson's two-body value):
    delta_x = 3 mu W (2 - nu) / (16 G a) [1 - (1 - F/(mu W))^(2/3)], within 1 % (the
    discrete contact radius is within 0.6 % of Hertz's at n = 128). Measured: within
    1e-4."""
    sc, sol, ratios = cattaneo_mindlin_128()
    a = hertz_radius()
    d_th = 3 * MU * W * (2 - NU) / (16 * G * a) * (1 - (1 - ratios) ** (2 / 3))
    assert sol.tangential_displacement[0, 0] == pytest.approx(0.0, abs=1e-9 * d_th[-1])
    np.testing.assert_allclose(sol.tangential_displacement[1:, 0], d_th[1:], rtol=1e-2)


# ====================================================================== Coulomb, loads


COULOMB_CASES = ["coupled_history", "uncoupled_history", "coupled_normal_ramp"]


def coulomb_case(name):
    if name == "coupled_history":
        return coupled_history("x")
    if name == "uncoupled_history":
        return uncoupled_history()
    slip = "total" if name.endswith("total") else "incremental"
    sc, sol, loads = normal_ramp(10, slip=slip)
    return sc, sol, loads, np.zeros((RAMP_NT, 2))


@pytest.mark.parametrize("case", COULOMB_CASES + ["coupled_normal_ramp_total"])
def test_coulomb_conditions_pointwise(case):
    """At every step and every cell (incremental law; for the last case the paper's
    total law, Ds = s_k):

    - |q| <= mu p (1 + 1e-6), and q = 0 out of contact;
    - slip cells: |q| = mu p to 1e-8 mu max p (stick is |q| < mu p (1 - 1e-10));
    - stick cells: |Ds| <= 1e-7 of the displacement scale (10 rtol: rtol bounds an L2
      norm; measured <= 7e-9);
    - slip cells: q opposite to the slip INCREMENT: natural residual <= 1e-6 of the
      displacement scale (the pointwise bound ~ rtol * 2n; measured <= 5e-9), and
      1 + cos(q, Ds) <= 1e-6 where |Ds| > 1e-4 of the scale (its direction is defined;
      measured <= 1.4e-10).

    Cases: fully coupled normal ramp then a tangential load grown, partly removed and
    reversed (the slip reverses); uncoupled oblique load rotating by 100 degrees; fully
    coupled normal load alone (partial slip from the coupling only), under each law."""
    sc, sol, _, _ = coulomb_case(case)
    res = coulomb_residuals(sc, sol, law=sc.slip)
    slipping_steps = 0
    for k, c in enumerate(res):
        assert c["excess"] <= 0.0, (k, c)
        assert c["outside"] == 0.0, (k, c)
        assert c["on_disc"] <= 1e-8, (k, c)
        assert c["stick_slip"] <= 1e-7, (k, c)
        assert c["natural"] <= 1e-6, (k, c)
        assert c["misalignment"] <= 1e-6, (k, c)
        slipping_steps += c["n_slip"] > 0 and c["n_stick"] > 0
    assert slipping_steps >= 5  # the checks above covered partial slip


@pytest.mark.parametrize("case", COULOMB_CASES + ["cattaneo_mindlin"])
def test_load_balance(case):
    """Normal force = W and tangential forces = (F_x, F_y) to 1e-8 (relative to W and
    mu W; for the held directions of the coupled normal ramp, (k + 1) 1e-8 mu W at step
    k), both as reported and as cell_area * sum of the tractions."""
    if case == "cattaneo_mindlin":
        sc, sol, ratios = cattaneo_mindlin_128()
        loads = np.full(len(ratios), W)
        forces = np.stack([ratios * MU * W, 0 * ratios], axis=1)
    else:
        sc, sol, loads, forces = coulomb_case(case)
    area = float(sc.grid.cell_area)
    np.testing.assert_allclose(sol.normal_force, loads, rtol=1e-8)
    np.testing.assert_allclose(area * sol.pressure.sum(axis=(1, 2)), loads, rtol=1e-8)
    tol = 1e-8 * MU * W
    if case == "coupled_normal_ramp":
        # Both directions held (no tangential input): F = 0 by symmetry, not imposed;
        # each incremental step may move it within its tolerance, so the bound grows
        # with the step (measured 7e-11 N a held step, 2e-9 N at step 22).
        tol = tol * np.arange(1, len(loads) + 1)[:, None]
    assert np.all(np.abs(sol.tangential_force - forces) <= tol)
    assert np.all(np.abs(area * sol.shear.sum(axis=(2, 3)) - forces) <= tol)


# ================================================================= coupled normal load


def test_coupled_normal_load_stick_disc():
    """Rigid sphere, nu = 0.3, mu = 0.3, full coupling, W ramped in 10 increments (paper
    Fig. 14): a central stick disc in a slip annulus, axisymmetric to within a cell,
    with the square grid's symmetries; shear radial and pointing outward.

    Why outward: a normal point load moves the surface points towards it, u_r =
    -(1 - 2 nu) / (4 pi G r) per unit force (Johnson eq. 3.19), so under
    the pressure the half-space surface contracts radially inward while the rigid
    indenter (delta_t = 0) does not move tangentially. In the slip annulus the surface
    therefore slips inward relative to the indenter and the friction ON the half-space
    opposes that slip: it points outward. In the stick disc the shear holds the surface
    against the same inward pull, so it points outward too."""
    m = 10
    sc, sol, _ = normal_ramp(m)
    dx = float(sc.grid.spacing[0])
    x, y, r = radii(sc.grid)
    k = m - 1  # end of the ramp
    p, q = sol.pressure[k], sol.shear[k]
    stick, contact = sol.stick[k], sol.contact[k]
    slip = contact & ~stick
    assert stick.any() and slip.any()
    n = sc.grid.shape[0]
    centre = slice(n // 2 - 1, n // 2 + 1)
    assert stick[centre, centre].all()
    # stick disc inside, slip annulus outside (within a cell), out to the contact edge
    assert r[stick].max() <= r[slip].min() + dx, (
        r[stick].max() / dx,
        r[slip].min() / dx,
    )
    assert r[slip].max() == r[contact].max()
    # axisymmetric within a cell: every boundary cell of the stick zone (a stick cell
    # with a non-stick neighbour) lies within one cell of the equivalent radius
    c = equivalent_radius(stick, sc.grid.cell_area)
    neighbour_free = np.zeros_like(stick)
    for shift, axis in ((1, 0), (-1, 0), (1, 1), (-1, 1)):
        neighbour_free |= ~np.roll(stick, shift, axis=axis)
    boundary = stick & neighbour_free
    assert np.abs(r[boundary] - c).max() <= dx, np.abs(r[boundary] - c).max() / dx
    # the square grid's symmetries: 90-degree rotation, mirrors, transpose
    ref = dict(p=p, q=q, contact=contact)
    for f in (np.rot90, lambda a: a[::-1], lambda a: a[:, ::-1], np.transpose):
        ok, n_diff = masks_agree(stick, f(stick), ref, ref, MU)
        assert ok and n_diff <= 8, n_diff
        np.testing.assert_allclose(f(p), p, rtol=0, atol=same(n) * p.max())
    # shear radial and outward on the half-space
    scale = MU * p.max()
    safe_r = np.where(r > 0, r, 1.0)
    q_r = (q[0] * x + q[1] * y) / safe_r
    q_t = (q[1] * x - q[0] * y) / safe_r
    assert np.all(q_r[slip] > 0)
    assert q_r[contact].min() >= -1e-8 * scale  # measured: >= 0.05 mu max p
    # hoop component: zero on the diagonals (mirror lines through cell centres), and
    # small elsewhere: the square grid is not axisymmetric (measured 0.0095 mu max p)
    diag = np.eye(n, dtype=bool) | np.eye(n, dtype=bool)[::-1]
    assert np.abs(q_t[diag]).max() <= 1e-6 * scale
    assert np.abs(q_t).max() <= 2e-2 * scale
    # no net tangential force or rigid tangential displacement (symmetry)
    np.testing.assert_allclose(sol.tangential_displacement[k], 0.0, atol=1e-6 * dx)


def stick_ratios_over_ramp(sol, m):
    return np.asarray(sol.stick_ratio[:m])


def test_hold_is_a_no_op():
    """After the ramp, holding the load changes nothing under the incremental law: the
    premise of the 40-step ramps (whose results are read at the end of the ramp, step
    m - 1). Each held step is re-solved to rtol, so p and q may move by ~rtol * n
    (6.4e-7) per held step and drift by up to 30-39 times that: 2e-5 of their maxima
    (measured 5e-6); the stick cells of the end of the ramp stay stick. (The labels of
    the former slip cells are not tested: with a zero slip increment and |q| = mu p at
    solver tolerance, stick and slip are both admissible.)"""
    for m in (1, 10):
        _, sol, _ = normal_ramp(m)
        for name in ("pressure", "shear"):
            field = getattr(sol, name)
            scale = np.abs(field[m - 1]).max()
            drift = np.abs(field[m:] - field[m - 1]).max() / scale
            assert drift <= 2e-5, (m, name, drift)
        end = traction_dict(sol, m - 1)
        for k in range(m, RAMP_NT):
            lost = sol.stick[m - 1] & ~sol.stick[k]
            ok, _ = masks_agree(
                lost, np.zeros_like(lost), end, traction_dict(sol, k), MU
            )
            assert ok, (m, k, lost.sum())


def test_spence_self_similar():
    """Spence (1975): under a monotonically increasing normal load the stick zone is
    self-similar, c/a independent of the load. W in 40 increments (nu = 0.3, mu =
    0.3); over the second half of the ramp (a from 0.79 a_W to a_W, 12.7 to 16 cells)
    c/a stays within one cell at the final radius, dx/a_W = 1/16 (measured ptp 0.035),
    and its mean is Spence's value (measured 0.896). c and a are the equivalent
    radii of the stick and contact areas."""
    m = 40
    sc, sol, _ = normal_ramp(m)
    ca = np.sqrt(stick_ratios_over_ramp(sol, m))
    dx_a = float(sc.grid.spacing[0]) / hertz_radius()
    second = ca[m // 2 :]
    assert np.ptp(second) <= dx_a, np.ptp(second)
    # Spence (1975), incremental law: stick area ratio 0.78-0.81, c/a = 0.883-0.900,
    # +- half a cell
    assert 0.883 - dx_a / 2 <= second.mean() <= 0.900 + dx_a / 2, second.mean()


def test_spence_published_point():
    """Rigid sphere on a half-space with nu = 0 and mu = 0.2986: c/a = 0.5 (Spence
    1975). W in 40 increments, a = 16 cells; tolerance: half a cell on the stick radius,
    0.5 dx / a = 0.031, for the final c/a and its mean over the second half of the
    ramp. Measured: 0.509 (final), 0.505 (mean)."""
    m = 40
    sc, sol, _ = normal_ramp(m, nu=0.0, mu=0.2986)
    a = hertz_radius(0.0)
    dx = float(sc.grid.spacing[0])
    ca = np.sqrt(stick_ratios_over_ramp(sol, m))
    tol = 0.5 * dx / a
    assert abs(ca[-1] - 0.5) <= tol, ca[-1]
    assert abs(ca[m // 2 :].mean() - 0.5) <= tol, ca[m // 2 :].mean()
    assert np.ptp(ca[m // 2 :]) <= dx / a


def test_one_step_vs_ramped_stick_ratio():
    """The slip law's path dependence (nu = 0.3, mu = 0.3): stick area ratio ~0.29
    when W is applied in one step, ~0.78-0.81 when ramped in 10-40 increments.
    Tolerance: the stick boundary is resolved to half a cell, so the ratio (c/a)^2
    to 2 (c/a) (dx/2)/a = (c/a) dx/a
    (0.033 one-step, 0.056 ramped; a = 16 cells). Measured: 0.274; 0.782 (10),
    0.802 (20), 0.812 (40)."""
    sc, one, _ = normal_ramp(1)
    dx_a = float(sc.grid.spacing[0]) / hertz_radius()
    r_one = one.stick_ratio[0]
    assert abs(r_one - 0.29) <= np.sqrt(0.29) * dx_a, r_one
    for m in (10, 20, 40):
        _, sol, _ = normal_ramp(m)
        tol = np.sqrt(0.8) * dx_a
        r_ramp = sol.stick_ratio[m - 1]
        assert 0.78 - tol <= r_ramp <= 0.81 + tol, (m, r_ramp)
        assert r_ramp > r_one + 0.4


def test_ramp_increments_converge():
    """The solution of a ramped load converges as the increments get smaller (5, 10,
    20, 40): the stick ratio increases towards its limit with non-increasing successive
    differences (up to one symmetry orbit of 8 cells, the quantum of a D4-symmetric
    stick set; measured differences 16, 16, 8 cells), and the relative L2 difference of
    the final shear fields shrinks by a factor < 0.8 at each halving (measured 0.096,
    0.057, 0.036)."""
    ms = (5, 10, 20, 40)
    sols = [normal_ramp(m)[1] for m in ms]
    ratios = np.array([s.stick_ratio[m - 1] for s, m in zip(sols, ms)])
    shears = [s.shear[m - 1] for s, m in zip(sols, ms)]
    quantum = 8 / sols[-1].contact[-1].sum()
    d = np.diff(ratios)
    assert np.all(d >= 0), ratios
    assert np.all(d[1:] <= d[:-1] + quantum + 1e-12), ratios
    assert d[-1] < d[0], ratios
    diffs = [
        np.linalg.norm(a - b) / np.linalg.norm(b)
        for a, b in zip(shears[:-1], shears[1:])
    ]
    for e0, e1 in zip(diffs[:-1], diffs[1:]):
        assert e1 < 0.8 * e0, diffs


# ===================================================================== dense reference


DENSE_N, DENSE_SPAN = 24, 2.5  # a = 9.6 cells, as in test_reference_dense.py


@functools.cache
def dense_setup():
    a = hertz_radius()
    size = DENSE_SPAN * a
    return size, rd.sphere_gap(DENSE_N, size, R), rd.dense_influence(DENSE_N, size, NU)


def compare_with_dense(sol, ref, mu):
    """Max differences of p, q (relative to max p, mu max p), stick masks (except
    marginal cells) and contact masks, over all steps."""
    pmax = ref["p"].max()
    dp = np.abs(sol.pressure - ref["p"]).max() / pmax
    dq = np.abs(sol.shear - ref["q"]).max() / (mu * pmax)
    n_diff = 0
    for k in range(ref["p"].shape[0]):
        ok, nd = masks_agree(
            sol.stick[k],
            ref["stick"][k],
            dict(p=sol.pressure[k], q=sol.shear[k], contact=sol.contact[k]),
            dict(p=ref["p"][k], q=ref["q"][k], contact=ref["contact"][k]),
            mu,
            margin=1e-6,
        )
        assert ok, k
        n_diff += nd
        np.testing.assert_array_equal(sol.contact[k], ref["contact"][k])
    return dp, dq, n_diff


# Redundant in the default run: the coupled operator equals the dense convolution
# (test_operator, 1e-12), the coupled ramps meet Coulomb and complementarity cell by
# cell (test_coulomb_conditions_pointwise), and the uncoupled FFT solve equals the
# dense one (test_dense_reference_cattaneo_mindlin).
@pytest.mark.slow  # redundant: see the comment above
def test_dense_reference_coupled_ramp():
    """Full coupling, nu = 0.3, mu = 0.3, W ramped in 10 increments, n = 24 over 2.5 a:
    the FFT solver (rtol = 1e-10) and the dense reference (PDAS + FISTA, tol = 1e-10)
    solve the same discrete problem: p and q agree to 1e-8 (measured 3e-9), contact
    masks exactly, stick masks except marginal boundary cells (measured: identical),
    approaches to 1e-9."""
    size, h0, C = dense_setup()
    nt = 10
    loads = W * np.arange(1, nt + 1) / nt
    ref = rd.solve_history(DENSE_N, size, h0, G, NU, MU, W=loads, coupling="full", C=C)
    sc = jc.Scene(
        jc.Grid((DENSE_N, DENSE_N), size),
        jc.Sphere(R),
        jc.Elastic(G, NU),
        times=jnp.arange(float(nt)),
        normal=jc.Force(loads),
        friction=MU,
        coupling="full",
    )
    np.testing.assert_allclose(np.asarray(sc.indenter.gap(sc.grid)), h0, rtol=1e-13)
    sol = as_np(jc.solve(sc, rtol=1e-10))
    check_converged(sol, SOLUTION_FIELDS)
    dp, dq, n_diff = compare_with_dense(sol, ref, MU)
    assert dp <= 1e-8 and dq <= 1e-8, (dp, dq)
    assert n_diff <= 8
    np.testing.assert_allclose(sol.approach, ref["delta_z"], rtol=1e-9)
    assert sol.stick[-1].any() and (sol.contact[-1] & ~sol.stick[-1]).any()


def test_dense_reference_coupled_ramp_on_a_prime_grid():
    """As `test_dense_reference_coupled_ramp` (full coupling, nu = 0.3, mu = 0.3) in 3
    increments on 23 x 23 cells, a prime: the DC-FFT pads to 45 (not 2 x 23 = 46, whose
    factor 23 makes the FFT slow) and the joint solver's preconditioner runs on 24 x 24
    (`_operator.padded_shape`, `precondition.preconditioner_shape`). Against the dense
    reference: float64 (rtol 1e-10) p and q to 1e-8 (measured 5e-11, 3e-10), the
    approach to 1e-9 (1e-12); float32 (rtol 1e-5) p and q to 1e-4 (measured 5e-6,
    2e-5), the approach to 1e-6 (1e-7); contact masks exactly and stick masks up to
    marginal cells (measured: identical) in both."""
    n = 23
    size = DENSE_SPAN * hertz_radius()
    h0 = rd.sphere_gap(n, size, R)
    loads = W * np.arange(1, 4) / 3
    ref = rd.solve_history(n, size, h0, G, NU, MU, W=loads, coupling="full",
                           C=rd.dense_influence(n, size, NU))
    for dtype, rtol, tol, tol_approach in ((jnp.float64, 1e-10, 1e-8, 1e-9),
                                           (jnp.float32, 1e-5, 1e-4, 1e-6)):
        def f(v):
            return jnp.asarray(v, dtype)

        sc = jc.Scene(jc.Grid((n, n), f(size)), jc.Sphere(f(R)),
                      jc.Elastic(f(G), f(NU)), times=jnp.arange(3.0, dtype=dtype),
                      normal=jc.Force(f(loads)), friction=MU, coupling="full")
        sol = as_np(jc.solve(sc, rtol=rtol))
        assert sol.pressure.dtype == dtype
        check_converged(sol, SOLUTION_FIELDS)
        dp, dq, n_diff = compare_with_dense(sol, ref, MU)
        assert dp <= tol and dq <= tol, (dtype, dp, dq)
        assert n_diff <= 8
        np.testing.assert_allclose(sol.approach, ref["delta_z"], rtol=tol_approach)
        assert sol.stick[-1].any() and (sol.contact[-1] & ~sol.stick[-1]).any()


def test_dense_reference_cattaneo_mindlin():
    """Uncoupled, W then F_x = mu W / 2 with delta_y = 0 (both shear components solved,
    as in the reference), n = 24 over 2.5 a, rtol = 1e-10: p, q to 1e-8 (measured
    3e-9), stick masks identical up to marginal cells, delta_x to 1e-8."""
    size, h0, C = dense_setup()
    F = 0.5 * MU * W
    ref = rd.solve_history(
        DENSE_N, size, h0, G, NU, MU, W=[W, W], Fx=[0.0, F], coupling="none", C=C
    )
    sc = jc.Scene(
        jc.Grid((DENSE_N, DENSE_N), size),
        jc.Sphere(R),
        jc.Elastic(G, NU),
        times=jnp.arange(2.0),
        normal=jc.Force(W),
        x=jc.Force(jnp.array([0.0, F])),
        y=jc.Displacement(0.0),
        friction=MU,
        coupling="none",
    )
    sol = as_np(jc.solve(sc, rtol=1e-10))
    check_converged(sol, SOLUTION_FIELDS)
    dp, dq, n_diff = compare_with_dense(sol, ref, MU)
    assert dp <= 1e-8 and dq <= 1e-8, (dp, dq)
    assert n_diff <= 8
    assert sol.tangential_displacement[1, 0] == pytest.approx(
        ref["delta_x"][1], rel=1e-8
    )
    assert sol.tangential_force[1, 0] == pytest.approx(F, rel=1e-10)
    assert 0 < sol.stick[1].sum() < sol.contact[1].sum()


def test_oblique_ramp_converges_tightly_with_two_shear_components():
    """Uncoupled, W held, F = (0.6, 0.4) mu W t ramped in 8 steps, 32^2, rtol 1e-10:
    every step of the two-component tangential CG converges in <= 60 iterations
    (measured 22-36) and carries its load to 1e-10 mu W. Before the CG restarted after
    each exact resync, the stale direction crept for 2000 iterations at 1e-9 on two
    of these steps (max_steps_reached)."""
    n, nt = 32, 9
    t = jnp.linspace(0.0, 1.0, nt)
    sc = scene(n, t, normal=jc.Force(W), x=jc.Force(0.6 * MU * W * t),
               y=jc.Force(0.4 * MU * W * t), coupling="none")
    sol = as_np(jc.solve(sc, rtol=1e-10))
    assert sol.iterations.max() <= 60, sol.iterations
    expected = MU * W * np.stack([0.6 * np.asarray(t), 0.4 * np.asarray(t)], axis=1)
    np.testing.assert_allclose(sol.tangential_force, expected, rtol=0,
                               atol=1e-10 * MU * W)
    assert 0 < sol.stick[-1].sum() < sol.contact[-1].sum()


# =========================================================================== histories


def test_displacement_ramp_to_gross_sliding():
    """Constant W, delta_x ramped from 0 to 1.5 delta_s (delta_s = 3 mu W (2 - nu) /
    (16 G a), Mindlin's sliding displacement): the stick zone shrinks monotonically to
    nothing, `sliding` turns on past delta_s (no sample within 10 % of it: the discrete
    threshold differs slightly) and stays on, F_x increases monotonically to mu W (to
    1e-6 at full sliding), and before sliding F(delta) follows Mindlin, F/(mu W) =
    1 - (1 - delta/delta_s)^(3/2), to 1e-2 (the compliance test: 1e-4 at n = 128)."""
    nt = 10
    a = hertz_radius()
    d_s = 3 * MU * W * (2 - NU) / (16 * G * a)
    deltas = d_s * np.array([0.0, 0.15, 0.3, 0.45, 0.6, 0.75, 0.9, 1.1, 1.3, 1.5])
    sc = scene(
        HIST_N,
        jnp.arange(float(nt)),
        normal=jc.Force(W),
        x=jc.Displacement(deltas),
        coupling="none",
    )
    sol = as_np(jc.solve(sc))
    check_converged(sol, SOLUTION_FIELDS)
    np.testing.assert_allclose(
        sol.tangential_displacement[:, 0], deltas, rtol=0, atol=1e-12 * d_s
    )
    n_stick = sol.stick.sum(axis=(1, 2))
    assert n_stick[0] == sol.contact[0].sum()
    assert np.all(np.diff(n_stick) <= 0), n_stick
    partial_slip = n_stick[1:] > 0
    assert np.all(np.diff(n_stick)[partial_slip] < 0), n_stick  # strictly
    sliding = deltas > d_s
    np.testing.assert_array_equal(sol.sliding, sliding)
    assert np.all(sol.stick_ratio[sliding] == 0) and np.all(n_stick[sliding] == 0)
    f = sol.tangential_force[:, 0] / (MU * W)
    assert np.all(np.diff(f[~sliding]) > 0), f
    np.testing.assert_allclose(f[sliding], 1.0, rtol=1e-6)
    np.testing.assert_allclose(sol.normal_force, W, rtol=1e-8)
    partial = deltas < 0.95 * d_s
    f_th = 1 - (1 - np.minimum(deltas / d_s, 1.0)) ** 1.5
    np.testing.assert_allclose(f[partial], f_th[partial], rtol=0, atol=1e-2)


def rot90_scalar(f):
    """g(x, y) = f(R^-1 (x, y)) = f(y, -x) for the rotation R by +90 degrees on a square
    grid centred on the origin (index i for x, j for y)."""
    return f.T[::-1, :]


def test_y_load_is_rotated_x_load():
    """Fully coupled history (normal ramp, then a tangential load grown and reversed)
    along y equals the x history rotated by 90 degrees: p_y(x) = p_x(R^-1 x),
    q_y(x) = R q_x(R^-1 x), delta_y = delta_x, to solver tolerance (same(48) = 1e-6 of
    max p and mu max p; measured 1.4e-7), stick masks identical up to marginal cells."""
    _, sx, _, _ = coupled_history("x")
    _, sy, _, forces = coupled_history("y")
    np.testing.assert_allclose(sy.tangential_force, forces, rtol=0, atol=1e-8 * MU * W)
    pmax = sx.pressure.max()
    tol = same(HIST_N)
    for k in range(HIST_NT):
        np.testing.assert_allclose(
            sy.pressure[k], rot90_scalar(sx.pressure[k]), rtol=0, atol=tol * pmax
        )
        # R (q_x, q_y) = (-q_y, q_x)
        np.testing.assert_allclose(
            sy.shear[k, 0], -rot90_scalar(sx.shear[k, 1]), rtol=0, atol=tol * MU * pmax
        )
        np.testing.assert_allclose(
            sy.shear[k, 1], rot90_scalar(sx.shear[k, 0]), rtol=0, atol=tol * MU * pmax
        )
        ok, _ = masks_agree(
            sy.stick[k],
            rot90_scalar(sx.stick[k]),
            traction_dict(sy, k),
            traction_dict(sx, k, rot90_scalar),
            MU,
        )
        assert ok, k
    np.testing.assert_allclose(
        sy.tangential_displacement[:, 1],
        sx.tangential_displacement[:, 0],
        rtol=0,
        atol=tol * np.abs(sx.tangential_displacement).max(),
    )


def test_slip_laws():
    """A load applied in one step: the incremental and total laws give the same result
    (the previous slip is zero in both). Ramped in 10 increments: the total law
    forgets the path (same final state as one step, to same(64) = 1.3e-6; measured
    5.8e-7) while the incremental law does not (shear differs by > 0.1 mu max p; stick
    ratio 0.27 vs 0.78). States compared at the end of the ramps (steps 0 and 9)."""
    _, inc1, _ = normal_ramp(1)
    _, tot1, _ = normal_ramp(1, slip="total")
    _, inc10, _ = normal_ramp(10)
    _, tot10, _ = normal_ramp(10, slip="total")
    pmax = inc1.pressure.max()
    for a, ka, b, kb in ((inc1, 0, tot1, 0), (tot1, 0, tot10, 9)):
        tol = same(RAMP_N)
        np.testing.assert_allclose(
            a.pressure[ka], b.pressure[kb], rtol=0, atol=tol * pmax
        )
        np.testing.assert_allclose(
            a.shear[ka], b.shear[kb], rtol=0, atol=tol * MU * pmax
        )
        ok, _ = masks_agree(
            a.stick[ka], b.stick[kb], traction_dict(a, ka), traction_dict(b, kb), MU
        )
        assert ok
    assert np.abs(inc10.shear[9] - tot10.shear[9]).max() > 0.1 * MU * pmax
    assert inc10.stick_ratio[9] - tot10.stick_ratio[9] > 0.4


def test_poisson_half_uncoupled():
    """nu = 0.5: the normal-tangential kernels vanish, so coupling "none" and "full"
    give the same solution, to solver tolerance (same(48) = 1e-6 of max p and mu max p:
    the two take different iteration paths; measured 2e-9), through the coupled
    history (normal ramp, tangential load grown, partly removed, reversed). Both solve
    q_x and q_y (the "none" scene is given y = Force(0))."""
    _, full, _, _ = coupled_history("x", nu=0.5)
    amp = HIST_F / (MU * W)
    _, none, _, forces = uncoupled_history(tuple(amp), tuple(0 * amp), nu=0.5)
    np.testing.assert_allclose(forces[:, 1], 0.0)
    pmax = full.pressure.max()
    tol = same(HIST_N)
    np.testing.assert_allclose(none.pressure, full.pressure, rtol=0, atol=tol * pmax)
    np.testing.assert_allclose(none.shear, full.shear, rtol=0, atol=tol * MU * pmax)
    np.testing.assert_allclose(none.approach, full.approach, rtol=1e-8)
    np.testing.assert_allclose(
        none.tangential_displacement,
        full.tangential_displacement,
        rtol=0,
        atol=tol * np.abs(full.tangential_displacement).max(),
    )
    for k in range(HIST_NT):
        ok, _ = masks_agree(
            none.stick[k],
            full.stick[k],
            traction_dict(none, k),
            traction_dict(full, k),
            MU,
        )
        assert ok, k
    # the coupled normal ramp leaves no slip at nu = 0.5 (nothing drives it)
    assert np.all(full.stick[:4] == full.contact[:4])
    np.testing.assert_allclose(full.shear[:4], 0.0, atol=1e-8 * MU * pmax)


@functools.cache
def coupled_history_gross():
    """Same compiled program as `coupled_history("x")`, F_x exceeding mu W."""
    amp = np.array([0, 0, 0, 0, 0.5, 0.9, 1.2, 1.5, 2.0, 1.2])
    sc = scene(
        HIST_N,
        jnp.arange(float(HIST_NT)),
        normal=jc.Force(HIST_W),
        x=jc.Force(MU * W * amp),
        coupling="full",
    )
    return as_np(jc.solve(sc))


def test_gross_sliding_load_control():
    """|F| > mu W under load control (uncoupled, oblique load at 30 degrees; and fully
    coupled along x): reported as sliding (converged, no stick cell, stick_ratio 0),
    q = mu p along F (to 1e-10 mu max p), tangential force mu W along F, all finite;
    steps with |F| < mu W before it are partial slip."""
    amp = np.array([0, 0, 0, 0, 0.5, 0.9, 1.2, 1.5, 2.0, 1.2])
    _, sol, _, _ = uncoupled_history(tuple(amp), tuple(np.full(HIST_NT, 30.0)))
    sol_c = coupled_history_gross()
    for s, direction in ((sol, np.deg2rad(30.0)), (sol_c, 0.0)):
        check_converged(s, SOLUTION_FIELDS)
        e = np.array([np.cos(direction), np.sin(direction)])
        sliding = amp > 1
        np.testing.assert_array_equal(s.sliding, sliding)
        assert np.all(s.stick_ratio[sliding] == 0) and not s.stick[sliding].any()
        assert np.all(s.stick_ratio[4:6] > 0) and np.all(s.stick_ratio[4:6] < 1)
        for k in np.flatnonzero(sliding):
            p, q = s.pressure[k], s.shear[k]
            expect = MU * p[None] * e[:, None, None]
            np.testing.assert_allclose(q, expect, rtol=0, atol=1e-10 * MU * p.max())
            np.testing.assert_allclose(
                s.tangential_force[k],
                MU * s.normal_force[k] * e,
                rtol=1e-10,
                atol=1e-12 * MU * W,
            )
        np.testing.assert_allclose(s.normal_force, HIST_W, rtol=1e-8)
        assert np.all(s.iterations < 2000 * 100)  # bounded (max_steps x max_rounds)


# ======================================================================= skipping work


def test_zero_friction_skips_tangential_solve():
    """friction = 0 (coupled, with a tangential displacement input): no tangential
    solve; zero shear, no stick cell, stick_ratio 0, and the frictionless pressure."""
    times = jnp.arange(float(HIST_NT))
    sc = scene(
        HIST_N,
        times,
        mu=0.0,
        normal=jc.Force(HIST_W),
        x=jc.Displacement(1e-6),
        coupling="full",
    )
    assert sc.tangential_directions == 0
    sol = as_np(jc.solve(sc))
    check_converged(sol, SOLUTION_FIELDS)
    assert np.all(sol.shear == 0) and np.all(sol.tangential_force == 0)
    assert not sol.stick.any() and np.all(sol.stick_ratio == 0)
    assert not sol.sliding.any()
    frictionless = as_np(
        jc.solve(scene(HIST_N, times, normal=jc.Force(HIST_W), coupling="none"))
    )
    np.testing.assert_allclose(
        sol.pressure,
        frictionless.pressure,
        rtol=0,
        atol=1e-12 * frictionless.pressure.max(),
    )


def test_no_tangential_input_uncoupled_skips_tangential_solve():
    """coupling "none", no tangential input: nothing drives a shear, so no tangential
    solve: zero shear, the whole contact sticks (stick_ratio 1), no sliding."""
    sc = scene(
        HIST_N, jnp.arange(float(HIST_NT)), normal=jc.Force(HIST_W), coupling="none"
    )
    assert sc.tangential_directions == 0
    sol = as_np(jc.solve(sc))
    check_converged(sol, SOLUTION_FIELDS)
    assert np.all(sol.shear == 0) and np.all(sol.tangential_force == 0)
    assert np.all(sol.stick == sol.contact) and np.all(sol.stick_ratio == 1)
    assert not sol.sliding.any()
    np.testing.assert_allclose(sol.normal_force, HIST_W, rtol=1e-8)


@pytest.mark.parametrize("control", ["force", "displacement"])
def test_fft_preconditioned_tangential_cg(control):
    # The tangential CG with one shear component (Cattaneo-Mindlin) takes the
    # full-plane inverse of K_xx as its preconditioner (what `jc.solve` uses on
    # non-periodic grids): the same solution as the diagonal one, to same(n) of mu max
    # p, in at most 65 % of the iterations (measured at 48^2: load control 18 -> 8,
    # displacement control 22 -> 13; in `jc.solve` at 512^2 76 -> 20).
    from jaxcontact._solver.precondition import shear_x_preconditioner
    from jaxcontact._solver.tangential_cg import tangential_cg

    n = 48
    grid = jc.Grid((n, n), 4 * hertz_radius())
    op = jc.HalfSpace(grid, "none", tangential_y=False)
    p = jc.solve_normal(grid, jc.Sphere(R), jc.Elastic(G, NU), force=W).pressure
    xx = op.tangential_blocks(NU)[0]
    symbol = (xx / G)[None]

    def apply(q):
        return op.inverse(op.forward(q) * symbol)

    fft = shear_x_preconditioner(op, NU)

    bound = MU * p
    if control == "force":
        target, force_control = jnp.array([0.5 * MU * W]), (True,)
    else:  # about half of the sliding displacement
        sliding = 3 * MU * W * (2 - NU) / (16 * G * hertz_radius())
        target, force_control = jnp.array([sliding / 2]), (False,)
    sols = {
        name: tangential_cg(apply, jnp.zeros((1, n, n)), bound, force_control, target,
                            grid.cell_area, op.diagonal(symbol[0]), rtol=RTOL,
                            max_steps=500, precondition=pc)
        for name, pc in (("diagonal", None), ("fft", fft))
    }
    assert all(bool(s.converged) for s in sols.values())
    scale = MU * float(p.max())
    np.testing.assert_allclose(sols["fft"].shear, sols["diagonal"].shear,
                               atol=same(n) * scale)
    its = {name: int(s.iterations) for name, s in sols.items()}
    print(f"{control}: iterations {its}")
    assert its["fft"] <= 0.65 * its["diagonal"]
    stick = np.asarray(sols["fft"].stick).sum()
    assert 0 < stick < 0.9 * int((p > 0).sum())  # partial slip
