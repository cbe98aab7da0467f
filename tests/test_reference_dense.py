"""Tests of the dense reference solver `tests/reference_dense.py` (numpy/scipy only).

Grids are coarse (n = 12-20) so that the whole file runs in well under a minute; the
tolerances on the analytic references (Hertz, Cattaneo-Mindlin, Spence) are stated in
cells, the contact conditions are checked pointwise to near round-off.
"""

import numpy as np
import pytest
import reference_dense as rd
from helpers import equivalent_radius

from jaxcontact import influence_coefficients


G = 1.0
R = 1.0
W0 = 1e-3


def hertz_radius(W, nu):
    return (3 * W * R / (4 * 2 * G / (1 - nu))) ** (1 / 3)


def setup(n, nu, span=2.5):
    """Grid of side `span` Hertz radii (for W0), its gap and influence matrices."""
    a = hertz_radius(W0, nu)
    size = span * a
    return a, size, rd.sphere_gap(n, size, R), rd.dense_influence(n, size, nu)


def assert_conditions(res, k, coulomb=True):
    c = rd.conditions(res, k)
    assert c["p_min"] >= 0.0
    assert c["gap_min"] >= -1e-10, c
    assert c["complementarity"] <= 1e-10, c
    if coulomb:
        assert c["friction_excess"] <= 1e-12, c  # |q| <= mu p (1 + 1e-12)
        assert c["q_outside"] == 0.0, c
        assert c["stick_slip"] <= 1e-9, c  # stick cells: slip increment ~ 0
        assert c["slip_misalignment"] <= 1e-6, c  # slip cells: q = -mu p Ds/|Ds|
        assert c["slip_natural"] <= 1e-9, c
    return c


# --------------------------------------------------------------------- building blocks


def test_dense_influence_reciprocity_and_definiteness():
    n = 8
    C = rd.dense_influence(n, 1.0, 0.3)
    N = n * n
    # gathered lattice == direct pairwise evaluation
    X, Y, (dx, dy) = rd.grid_coordinates(n, 1.0)
    X, Y = X.ravel(), Y.ravel()
    direct = np.asarray(
        influence_coefficients(
            X[:, None] - X[None, :], Y[:, None] - Y[None, :], dx, dy, 0.3
        )
    )
    np.testing.assert_allclose(C, direct, rtol=0, atol=1e-14 * np.abs(direct).max())
    full = C.transpose(0, 2, 1, 3).reshape(3 * N, 3 * N)
    np.testing.assert_allclose(full, full.T, atol=1e-15 * np.abs(full).max())
    np.testing.assert_allclose(C[2, 0], -C[2, 0].T, atol=1e-15)  # odd kernel
    np.testing.assert_allclose(C[0, 2], C[2, 0].T, atol=1e-15)  # reciprocity
    assert np.linalg.eigvalsh(full)[0] > 0
    # nu = 0.5: no normal-tangential coupling
    C5 = rd.dense_influence(n, 1.0, 0.5)
    assert np.abs(C5[2, :2]).max() == 0.0 and np.abs(C5[:2, 2]).max() == 0.0


@pytest.mark.parametrize("load", [True, False])
def test_normal_active_set_methods_agree(load):
    """Primal-dual active set (default) and the finite primal active-set fallback."""
    n, nu = 12, 0.3
    a, size, h0, C = setup(n, nu)
    M = C[2, 2] / G
    rng = np.random.default_rng(0)
    f = h0.ravel() + 0.05 * a * a / R * rng.standard_normal(n * n)  # rough-ish
    value = W0 / (size / n) ** 2 if load else 0.6 * a * a / R
    p1, d1 = rd._solve_normal(M, f, load, value)
    p2, d2 = rd._normal_primal_active_set(M, f, load, value, maxit=10 * n * n)
    np.testing.assert_allclose(p1, p2, rtol=0, atol=1e-10 * p1.max())
    np.testing.assert_allclose(d1, d2, rtol=1e-12)
    g = M @ p1 + f - d1
    assert p1.min() >= 0 and g.min() >= -1e-13 * abs(d1)
    assert np.abs(p1 * g).max() <= 1e-13 * p1.max() * abs(d1)


# ------------------------------------------------------------------------------ Hertz


def test_hertz_frictionless():
    n, nu = 20, 0.3
    a, size, h0, C = setup(n, nu)
    dx = size / n
    res = rd.solve_history(n, size, h0, G, nu, 0.0, W=W0, C=C)
    assert_conditions(res, 0, coulomb=False)
    np.testing.assert_allclose(res["W"][0], W0, rtol=1e-13)
    assert np.all(res["q"] == 0)
    a_num = equivalent_radius(res["contact"][0], res["cell_area"])
    assert abs(a_num - a) <= dx, (a_num / dx, a / dx)
    np.testing.assert_allclose(res["delta_z"][0], a * a / R, rtol=0.02)
    # displacement control at the approach found reproduces the pressure
    res_d = rd.solve_history(n, size, h0, G, nu, 0.0, delta_z=res["delta_z"][0], C=C)
    np.testing.assert_allclose(res_d["p"], res["p"], atol=1e-10 * res["p"].max())


# ------------------------------------------------------------------ Cattaneo-Mindlin


@pytest.mark.parametrize("nu, coupling", [(0.0, "none"), (0.5, "full"), (0.5, "x")])
def test_cattaneo_mindlin(nu, coupling):
    """Normal load W, then F_x = mu W / 2 at constant W (no normal-tangential
    coupling: nu = 0.5 makes the coupling kernels vanish).

    Mindlin: c/a = (1 - F/(mu W))^(1/3); rigid sphere on one body:
    delta_x = 3 mu W (2 - nu) / (16 G a) [1 - (1 - F/(mu W))^(2/3)].
    Measured (n = 20, a = 8 cells): c - c_th = -0.07 cells (nu = 0), +0.03 cells
    (nu = 0.5); delta_x within 0.5 % of the formula."""
    n, mu = 20, 0.3
    a, size, h0, C = setup(n, nu)
    dx = size / n
    F = 0.5 * mu * W0
    res = rd.solve_history(
        n, size, h0, G, nu, mu, W=[W0, W0], Fx=[0.0, F], coupling=coupling, C=C
    )
    for k in range(2):
        assert_conditions(res, k)
    np.testing.assert_allclose(res["W"], W0, rtol=1e-13)
    np.testing.assert_allclose(res["Fx"], [0.0, F], rtol=1e-10, atol=1e-12 * mu * W0)
    assert abs(res["Fy"][1]) <= 1e-12 * mu * W0
    c_num = equivalent_radius(res["stick"][1], res["cell_area"])
    c_th = a * (1 - F / (mu * W0)) ** (1 / 3)
    assert abs(c_num - c_th) <= 1.5 * dx, (c_num - c_th) / dx
    d_th = 3 * mu * W0 * (2 - nu) / (16 * G * a) * (1 - (1 - F / (mu * W0)) ** (2 / 3))
    np.testing.assert_allclose(res["delta_x"][1], d_th, rtol=0.02)
    # the shear is in the loading direction; stick core, slip annulus
    assert res["q"][1, 0].min() >= 0.0
    r = np.hypot(res["x"], res["y"])
    assert r[res["stick"][1]].max() < r[res["slip"][1]].max()
    if coupling == "none":
        # displacement control at the delta_x found reproduces the tractions
        res_d = rd.solve_history(
            n,
            size,
            h0,
            G,
            nu,
            mu,
            W=[W0, W0],
            delta_x=res["delta_x"],
            coupling=coupling,
            C=C,
        )
        np.testing.assert_allclose(
            res_d["q"], res["q"], atol=1e-8 * mu * res["p"].max()
        )


def test_tangential_y_and_oblique_loads():
    """Square grid: a y load is the transposed x load; an oblique load (both directions
    load controlled, nested root search) balances in both directions."""
    n, nu, mu = 12, 0.3, 0.3
    a, size, h0, C = setup(n, nu)
    F = 0.4 * mu * W0
    rx = rd.solve_history(n, size, h0, G, nu, mu, W=[W0, W0], Fx=[0.0, F], C=C)
    ry = rd.solve_history(n, size, h0, G, nu, mu, W=[W0, W0], Fy=[0.0, F], C=C)
    scale = mu * rx["p"].max()
    np.testing.assert_allclose(ry["q"][1, 1], rx["q"][1, 0].T, atol=1e-8 * scale)
    np.testing.assert_allclose(ry["q"][1, 0], rx["q"][1, 1].T, atol=1e-8 * scale)
    np.testing.assert_allclose(ry["delta_y"][1], rx["delta_x"][1], rtol=1e-7)
    Fxy = F * np.array([0.6, 0.8])
    rb = rd.solve_history(
        n, size, h0, G, nu, mu, W=[W0, W0], Fx=[0.0, Fxy[0]], Fy=[0.0, Fxy[1]], C=C
    )
    assert_conditions(rb, 1)
    np.testing.assert_allclose([rb["Fx"][1], rb["Fy"][1]], Fxy, rtol=1e-9)


def test_gross_sliding_raises():
    n, nu, mu = 12, 0.3, 0.3
    a, size, h0, C = setup(n, nu)
    with pytest.raises(ValueError, match="gross sliding"):
        rd.solve_history(
            n, size, h0, G, nu, mu, W=W0, Fx=1.01 * mu * W0, coupling="none", C=C
        )


# ------------------------------------------------------------- coupled normal loading


def test_coupled_normal_ramp_conditions():
    """nu = 0.3, mu = 0.3, full coupling, normal load ramped in 10 increments:
    Coulomb and contact conditions pointwise at every step, load balance, outward
    friction."""
    n, nu, mu, nt = 16, 0.3, 0.3, 10
    a, size, h0, C = setup(n, nu)
    Ws = W0 * np.arange(1, nt + 1) / nt
    res = rd.solve_history(n, size, h0, G, nu, mu, W=Ws, coupling="full", C=C)
    r = np.hypot(res["x"], res["y"])
    for k in range(nt):
        c = assert_conditions(res, k)
        assert c["friction_excess"] <= 1e-8
        contact, stick, slip = res["contact"][k], res["stick"][k], res["slip"][k]
        p, q = res["p"][k], res["q"][k]
        qn = np.hypot(q[0], q[1])
        np.testing.assert_allclose(qn[slip], mu * p[slip], rtol=1e-8)
        assert stick.any() and slip.any()
        # shear on the half-space points radially outward (the surface moves inward)
        q_r = (q[0] * res["x"] + q[1] * res["y"]) / np.where(r > 0, r, 1.0)
        assert q_r[contact].min() >= -1e-12 * mu * p.max()
        assert np.all(q_r[slip] > 0)
        # the slip increment of slip cells points inward
        ds_r = (res["ds"][k][0] * res["x"] + res["ds"][k][1] * res["y"]) / np.where(
            r > 0, r, 1.0
        )
        assert np.all(ds_r[slip] <= 0)
    np.testing.assert_allclose(res["W"], Ws, rtol=1e-13)
    np.testing.assert_allclose(res["Fx"], 0.0, atol=1e-12 * mu * W0)
    np.testing.assert_allclose(res["Fy"], 0.0, atol=1e-12 * mu * W0)
    np.testing.assert_allclose(res["delta_x"], 0.0)
    # symmetry: q_x odd in x, even in y
    q = res["q"][-1]
    np.testing.assert_allclose(q[0], -q[0][::-1, :], atol=1e-9 * mu * res["p"].max())
    np.testing.assert_allclose(q[0], q[0][:, ::-1], atol=1e-9 * mu * res["p"].max())


def _stick_ratio(res, k=-1):
    return res["stick"][k].sum() / res["contact"][k].sum()


def test_incremental_vs_total():
    """One-step loading: same result under both laws (the previous slip is 0). Ramped:
    the total law is path independent (same as one step), the incremental law is not.
    The slip law's path dependence (fine grid): stick area ratio ~0.29 one-step,
    ~0.78-0.81 ramped. The coarse grids here underestimate both (grid of 2.5 a):
    n = 16: 0.258 / 0.710; n = 20 (this test): 0.250 / 0.712 (10 increments);
    n = 24: 0.282 / 0.761 (10) and
    0.789 (20); n = 32: 0.296 / 0.784 (10) and 0.800 (20)."""
    n, nu, mu, nt = 20, 0.3, 0.3, 10
    a, size, h0, C = setup(n, nu)
    Ws = W0 * np.arange(1, nt + 1) / nt
    one_inc = rd.solve_history(n, size, h0, G, nu, mu, W=W0, law="incremental", C=C)
    one_tot = rd.solve_history(n, size, h0, G, nu, mu, W=W0, law="total", C=C)
    ramp_inc = rd.solve_history(n, size, h0, G, nu, mu, W=Ws, law="incremental", C=C)
    ramp_tot = rd.solve_history(n, size, h0, G, nu, mu, W=Ws, law="total", C=C)
    scale = mu * one_inc["p"].max()
    for key in ("p", "q"):
        np.testing.assert_allclose(one_tot[key], one_inc[key], atol=1e-12 * scale)
        np.testing.assert_allclose(
            ramp_tot[key][-1], one_tot[key][0], atol=1e-7 * scale
        )
    assert np.array_equal(ramp_tot["stick"][-1], one_tot["stick"][0])
    for k in range(nt):
        assert_conditions(ramp_tot, k)
    assert np.abs(ramp_inc["q"][-1] - one_inc["q"][0]).max() > 0.1 * scale
    r_one, r_ramp = _stick_ratio(one_inc), _stick_ratio(ramp_inc)
    print(f"stick area ratio: one step {r_one:.3f}, {nt} increments {r_ramp:.3f}")
    assert 0.2 <= r_one <= 0.36
    assert 0.65 <= r_ramp <= 0.86


def test_spence_self_similar_stick_zone():
    """Spence (1975): rigid sphere, nu = 0, mu = 0.2986, monotonic normal loading:
    c/a ~ 0.5.

    Measured with c, a the equivalent radii of the stick and contact areas (this grid:
    a = 8 cells, 20 increments): 0.520; n = 16: 0.516, n = 24: 0.525, n = 32: 0.494.
    The tolerance, 0.06 ~ dx / (2a), is half a cell of the stick-zone boundary."""
    n, nu, mu, nt = 20, 0.0, 0.2986, 20
    a, size, h0, C = setup(n, nu)
    Ws = W0 * np.arange(1, nt + 1) / nt
    res = rd.solve_history(n, size, h0, G, nu, mu, W=Ws, coupling="full", C=C)
    for k in (nt // 2, nt - 1):
        assert_conditions(res, k)
    ratio = np.sqrt(_stick_ratio(res))
    print(f"Spence c/a = {ratio:.3f}")
    assert abs(ratio - 0.5) <= 0.5 * (size / n) / a
    # self-similar: the ratio hardly changes over the second half of the ramp
    ratios = np.sqrt(res["stick"].sum(axis=(1, 2)) / res["contact"].sum(axis=(1, 2)))
    assert np.ptp(ratios[nt // 2 :]) <= 0.1
