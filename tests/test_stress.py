"""Stress tests: extreme but legal inputs. Every step converges or is flagged; no NaN;
no hang (every loop is bounded by `max_steps`); where a reference exists the answer is
checked against it.

Each case is classified by `outcome()`:

- `"pass"`: every step converged, no edge contact, finite, and the case's own physical
  checks hold;
- `"flagged"`: some step reports `converged=False` or `edge_contact=True` (the user is
  told);
- `"failed"`: NaN/inf, or a wrong answer reported as converged (silently wrong).

Known issue (characterised in `test_constant_scheme_stability_criterion`): the paper's
piecewise-constant scheme is unstable for a stiff Zener solid at coarse steps. The
scalar recursion `sum_n J(t_k - t_n) d_n = f_k` of a Zener solid has its one pole at
`z = 1 / (1 - r (1 - exp(-dt / tau)))` (`r = mu_inf / mu_0`): an alternating mode
grows by `s = r (1 - exp(-dt / tau)) - 1` per step when `s > 0`, so the scheme is
unstable when `r (1 - exp(-dt / tau)) > 2` (the same analysis for Maxwell:
`dt > 2 tau`). The steps still report `converged=True` (each elastic step IS solved);
the tractions jump by up to the peak pressure from step to step. The piecewise-linear
scheme is stable in the same cases. Those cases are `xfail` here (strict): they are
silently wrong, and they are counted as failures in the stress matrix.

Grids are 16 x 16 (32 x 32 for the rough surface) so that the default run stays short;
long cases (Nt = 2000, coupled gross sliding, float32 viscoelastic, Maxwell to 10 tau)
are marked `slow`.
"""

import time
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import as_np

import jaxcontact as jc


def solve_flagged(scene, **options):
    """`jc.solve` returning its flags: this matrix records failures, it does not
    raise."""
    return jc.solve(scene, throw=False, **options)



MU_INF, NU, R, W = 1.93e6, 0.3, 10e-3, 0.15  # the paper's Table 2 (true shear modulus)
TAU = 0.01
A0 = float(jc.Hertz(R, W, MU_INF, NU).contact_radius)
N = 16


def finite(sol):
    fields = [sol.pressure]
    if hasattr(sol, "shear"):
        fields += [sol.shear, sol.approach, sol.tangential_force]
    return all(np.isfinite(np.asarray(f)).all() for f in fields)


def outcome(sol, physics_ok=True):
    """`"pass"`, `"flagged"` or `"failed"` (see the module docstring)."""
    if not finite(sol):
        return "failed"
    converged = np.asarray(sol.converged).all()
    edge = np.asarray(sol.edge_contact).any()
    if not converged or edge:
        return "flagged"
    return "pass" if physics_ok else "failed"


def zener_grid(ratio, n=N):
    """A grid that holds the long-time Hertz contact (radius ratio^(1/3) A0) with a
    margin of 30 % on each side."""
    return jc.Grid((n, n), 2 * 1.3 * ratio ** (1 / 3) * A0)


def lee_radok_approach(material, times):
    ref = jc.LeeRadok(R, NU, material, lambda t: W * (t >= 0), samples=300)
    return np.array([ref.approach(float(t)) for t in times])


def jumps(pressure):
    """Largest step-to-step change of the peak pressure in the second half of the run,
    relative to the peak pressure (a smooth creep under a constant load changes it by
    a few per cent per step at most)."""
    peak = pressure.max(axis=(1, 2))
    d = np.abs(np.diff(peak))
    return d[len(d) // 2:].max() / peak.max()


def creep_step(ratio, nt, scheme, span=3.0, n=N):
    """A Zener half-space under a step load W held for `span` retardation times."""
    material = jc.Zener(MU_INF, MU_INF / ratio, TAU, NU)
    times = jnp.linspace(0.0, span * TAU, nt)
    loads = jc.Force(np.full(nt, W))  # an array: the program is shared between tests
    scene = jc.Scene(zener_grid(ratio, n), jc.Sphere(R), material, times, loads)
    start = time.perf_counter()
    sol = as_np(solve_flagged(scene, scheme=scheme))
    return sol, material, np.asarray(times), time.perf_counter() - start


def alternation(ratio, dt_over_tau):
    """`s = r (1 - exp(-dt / tau)) - 1`: the factor by which the alternating (+-) mode
    of the piecewise-constant Zener recursion grows per step when `s > 0` (none when
    `s <= 0`: monotone creep). Unstable when `s > 1`."""
    return ratio * (1 - np.exp(-dt_over_tau)) - 1


def check_creep(sol, material, times, rtol_approach):
    """Load balance at every step, monotone creep, Lee-Radok approach."""
    np.testing.assert_allclose(sol.normal_force, W, rtol=1e-8)
    assert np.all(np.diff(sol.approach) >= -1e-9 * sol.approach[-1])  # creeps in
    ref = lee_radok_approach(material, times)
    err = np.max(np.abs(sol.approach / ref - 1))
    assert err < rtol_approach, err
    return err


# --------------------------------------------------------------------------------------
# Zener stiffness ratio from 1.01 to 100, Maxwell to 10 tau.

ZENER_RATIOS = (1.01, 2.0, 10.0, 100.0)


@pytest.mark.parametrize("ratio", ZENER_RATIOS)
def test_zener_ratio_linear_scheme(ratio):
    # Nt = 11 over 3 tau (dt = 0.3 tau). The approach follows Lee & Radok within the
    # resolution of the initial contact (ratio 100: 0.75 cell per initial radius... so
    # the tolerance grows with the ratio).
    sol, material, times, _ = creep_step(ratio, 11, "linear")
    assert outcome(sol) == "pass"
    check_creep(sol, material, times, rtol_approach=0.03 if ratio <= 10 else 0.12)
    assert jumps(sol.pressure) < 0.05


@pytest.mark.parametrize(
    "ratio",
    [
        1.01,
        2.0,
        pytest.param(10.0, marks=pytest.mark.xfail(
            strict=True, raises=jc.TimeStepWarning,
            reason="piecewise-constant scheme unstable at this step (s=1.59): warned")),
        pytest.param(100.0, marks=pytest.mark.xfail(
            strict=True, raises=jc.TimeStepWarning,
            reason="piecewise-constant scheme unstable at this step (s=24.9): warned")),
    ],
)
def test_zener_ratio_constant_scheme(ratio):
    # The paper's scheme at the same Nt = 11 (the case of the known issue: ratio 10).
    sol, material, times, _ = creep_step(ratio, 11, "constant")
    assert outcome(sol) == "pass"  # converged even where unstable: not flagged
    assert jumps(sol.pressure) < 0.05
    check_creep(sol, material, times, rtol_approach=0.05)


def test_constant_scheme_stability_criterion():
    # The alternation factor s = r (1 - exp(-dt / tau)) - 1 predicts where the
    # piecewise-constant scheme goes wrong, over ratios 2-100 and dt / tau 0.05-3 (one
    # compiled program per scheme: tau is a traced value). Reference: the piecewise-
    # linear scheme on the same steps, which is smooth in all of these cases. Over the
    # second half of the run, the constant scheme departs from it by < 6 % of the peak
    # pressure where s < 0 (no alternating mode) and by > 30 % where s > 1.2 (measured
    # on 16 x 16: <= 4.4 % and >= 53 %); in between (0 < s < 1.2) the oscillation decays
    # or grows slowly (5-22 %), not asserted. Every step reports converged=True; the
    # unstable cases (s > 1) are flagged by jc.TimeStepWarning, and only they.
    times = jnp.arange(11.0)  # dt = 1; dt / tau through tau
    for ratio in (2.0, 4.0, 10.0, 30.0, 100.0):
        for dt_tau in (0.05, 0.2, 0.5, 3.0):
            material = jc.Zener(MU_INF, MU_INF / ratio, 1 / dt_tau, NU)
            scene = jc.Scene(zener_grid(ratio), jc.Sphere(R), material, times,
                             jc.Force(np.full(11, W)))
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", jc.TimeStepWarning)
                const = as_np(solve_flagged(scene, solver=jc.Rounds(),
                                            scheme="constant"))
            warned = any(issubclass(w.category, jc.TimeStepWarning) for w in caught)
            linear = as_np(solve_flagged(scene, solver=jc.Rounds(), scheme="linear"))
            assert outcome(const) == "pass" and outcome(linear) == "pass"
            assert jumps(linear.pressure) < 0.1  # smooth creep
            diff = np.abs(const.pressure[5:] - linear.pressure[5:]).max()
            diff /= linear.pressure.max()
            s = alternation(ratio, dt_tau)
            case = (f"r={ratio}, dt/tau={dt_tau}: s={s:.2f}, constant vs linear "
                    f"{diff:.3f}")
            assert warned == (s > 1), case
            if s > 1.2:
                assert diff > 0.3, case
            elif s < 0:
                assert diff < 0.06, case


@pytest.mark.slow
def test_maxwell_to_ten_relaxation_times():
    # A fluid: the contact grows as a^3 ~ 1 + t / tau; a(10 tau) = 11^(1/3) a0.
    shear, tau = MU_INF, TAU
    material = jc.Maxwell(shear, shear * tau, NU)
    times = jnp.linspace(0.0, 10 * tau, 21)  # dt = 0.5 tau < 2 tau: stable
    grid = jc.Grid((N, N), 2 * 1.3 * 11 ** (1 / 3) * A0)
    for scheme in ("constant", "linear"):
        # On the grid: `jumps` reads the cells (jc.solve's default: the rings).
        sol = as_np(solve_flagged(jc.Scene(grid, jc.Sphere(R), material, times,
                                           jc.Force(W)),
                                  solver=jc.Rounds(), scheme=scheme))
        assert outcome(sol) == "pass"
        check_creep(sol, material, np.asarray(times), rtol_approach=0.05)
        assert jumps(sol.pressure) < 0.05


# --------------------------------------------------------------------------------------
# Coarse and fine time steps.


def test_coarse_steps_linear_scheme():
    # Nt = 5 over 3 tau (dt = 0.75 tau), ratio 4: the linear scheme stays smooth and
    # within 5 % of Lee-Radok.
    sol, material, times, _ = creep_step(4.0, 5, "linear")
    assert outcome(sol) == "pass"
    check_creep(sol, material, times, rtol_approach=0.05)


@pytest.mark.slow
@pytest.mark.xfail(strict=True,
                   reason="known issue: constant scheme, r=4, dt=0.75 tau: s=1.11")
def test_coarse_steps_constant_scheme():
    sol, material, times, _ = creep_step(4.0, 5, "constant")
    assert outcome(sol) == "pass"
    assert jumps(sol.pressure) < 0.05


@pytest.mark.slow
@pytest.mark.parametrize("scheme", ["constant", "linear"])
def test_fine_steps(scheme):
    # Nt = 2000 (dt = 0.0015 tau): bounded time (O(Nt) recursion) and the error against
    # Lee-Radok is the grid's, not the time step's.
    sol, material, times, seconds = creep_step(10.0, 2000, scheme)
    assert outcome(sol) == "pass"
    keep = np.arange(0, 2000, 100)
    sub = jax.tree_util.tree_map(lambda a: a[keep] if a.ndim else a, sol)
    check_creep(sub, material, times[keep], rtol_approach=0.03)
    assert seconds < 300


# --------------------------------------------------------------------------------------
# Loads from 1e-6 to 1e6 times nominal; float32.

LOAD_SCALES = 10.0 ** np.arange(-6, 7, 2)


def test_load_scale_invariance():
    # Elastic sphere, grid sized to the Hertz radius of each load: the normalised
    # pressure p / p0 is the same for twelve decades of load.
    reference = None
    for scale in LOAD_SCALES:
        w = 0.05 * scale
        hertz = jc.Hertz(R, w, 1e6, NU)
        a = float(hertz.contact_radius)
        sol = jc.solve_normal(jc.Grid((N, N), 4 * a), jc.Sphere(R), jc.Elastic(1e6, NU),
                              force=w)
        assert outcome(sol) == "pass"
        np.testing.assert_allclose(float(sol.normal_force), w, rtol=1e-10)
        p = np.asarray(sol.pressure) / float(hertz.peak_pressure)
        np.testing.assert_allclose(float(sol.approach) / float(hertz.approach),
                                   1.0, atol=0.03)
        if reference is None:
            reference = p
        np.testing.assert_allclose(p, reference, atol=1e-6)


def test_float32_normal():
    # float32 end to end: finite, converged at its default tolerance 1e-5, Hertz
    # approach within 3 %, load balance to float32 precision.
    f32 = jnp.float32
    for scale in (1e-6, 1.0, 1e6):
        w = 0.05 * scale
        hertz = jc.Hertz(R, w, 1e6, NU)
        grid = jc.Grid((N, N), jnp.asarray(4 * float(hertz.contact_radius), f32))
        sol = jc.solve_normal(grid, jc.Sphere(jnp.asarray(R, f32)),
                              jc.Elastic(jnp.asarray(1e6, f32), jnp.asarray(NU, f32)),
                              force=jnp.asarray(w, f32))
        assert sol.pressure.dtype == f32
        assert outcome(sol) == "pass"
        np.testing.assert_allclose(float(sol.normal_force), w, rtol=1e-5)
        np.testing.assert_allclose(float(sol.approach), float(hertz.approach),
                                   rtol=0.03)


@pytest.mark.slow
def test_float32_viscoelastic():
    # Zener ratio 4 in float32 against the same scene in float64.
    f32 = jnp.float32
    material = jc.Zener(*(jnp.asarray(v, f32) for v in (MU_INF, MU_INF / 4, TAU, NU)))
    times = jnp.linspace(0.0, 3 * TAU, 11).astype(f32)
    grid = jc.Grid((N, N), jnp.asarray(2 * 1.3 * 4 ** (1 / 3) * A0, f32))
    scene = jc.Scene(grid, jc.Sphere(jnp.asarray(R, f32)), material, times,
                     jc.Force(jnp.asarray(W, f32)))
    sol32 = as_np(solve_flagged(scene, scheme="linear"))
    sol64, *_ = creep_step(4.0, 11, "linear")
    assert sol32.pressure.dtype == np.float32
    assert outcome(sol32) == "pass"
    np.testing.assert_allclose(sol32.approach, sol64.approach, rtol=1e-4)
    # float32 solves to rtol 1e-5 on the gap; the pressure follows to ~3e-4 (measured
    # 2.8e-4 of the peak at 16 x 16).
    np.testing.assert_allclose(sol32.pressure, sol64.pressure,
                               atol=1e-3 * sol64.pressure.max())


# --------------------------------------------------------------------------------------
# Rough surfaces with many contact islands.


def rough_surface(seed, n, rms):
    """Gaussian random surface, correlation length ~ 2 cells, zero mean (NumPy)."""
    rng = np.random.default_rng(seed)
    noise = rng.standard_normal((n, n))
    k = np.fft.fftfreq(n)
    filt = np.exp(-((k[:, None] ** 2 + k[None, :] ** 2) * (2 * np.pi * 2) ** 2) / 2)
    h = np.real(np.fft.ifft2(np.fft.fft2(noise) * filt))
    return rms * h / h.std()


def islands(mask):
    from scipy import ndimage

    return ndimage.label(mask)[1]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_rough_surface_many_islands(seed):
    # A periodic patch (the set-up for rough surfaces: contact reaches the patch edges,
    # which is right there, so `edge_contact` does not apply).
    n, size, rms, g = 32, 1e-3, 1e-6, 1e6
    heights = rough_surface(seed, n, rms)
    grid = jc.Grid((n, n), size, periodic=True)
    # A mean pressure of 1 kPa brings ~8 % of the nominal area into contact.
    w = 1e3 * size**2
    sol = jc.solve_normal(grid, heights, jc.Elastic(g, NU), force=w)
    p, gap = np.asarray(sol.pressure), np.asarray(sol.gap)
    assert bool(sol.converged) and finite(sol)
    np.testing.assert_allclose(float(sol.normal_force), w, rtol=1e-10)
    assert p.min() >= 0 and gap.min() >= -1e-7 * rms
    assert np.all(np.abs(gap[p > 0]) <= 1e-7 * rms)
    assert islands(p > 0) >= 5  # many contact islands
    # Independent check: the gap is h + u - delta with u recomputed by the operator.
    op = jc.HalfSpace(grid)
    u = np.asarray(op.apply_normal(jnp.asarray(p), NU)) / g
    np.testing.assert_allclose(gap, heights + u - float(sol.approach), atol=1e-9 * rms)


# --------------------------------------------------------------------------------------
# Contact that reaches the domain boundary: flagged, not silently wrong.


@pytest.mark.slow
def test_creep_to_the_boundary_is_flagged():
    # Zener ratio 10 on a grid that holds the instantaneous contact but not the
    # long-time one: the scene warns up front, the solution flags the late steps.
    ratio = 10.0
    material = jc.Zener(MU_INF, MU_INF / ratio, TAU, NU)
    grid = jc.Grid((N, N), 2 * 1.3 * A0)
    times = jnp.linspace(0.0, 3 * TAU, 11)
    with pytest.warns(jc.EdgeContactWarning):
        scene = jc.Scene(grid, jc.Sphere(R), material, times, jc.Force(W))
    sol = as_np(solve_flagged(scene, scheme="linear"))
    assert finite(sol)
    assert not sol.edge_contact[0] and sol.edge_contact[-1]
    assert outcome(sol) == "flagged"


# --------------------------------------------------------------------------------------
# Bounded failure: max_steps.


def test_max_steps_bounds_the_time_to_flag():
    # Two CG iterations cannot solve a Hertz contact: every step is flagged, finite,
    # and the run stops at the bound.
    grid = jc.Grid((N, N), 4 * A0)
    scene = jc.Scene(grid, jc.Sphere(R), jc.Elastic(MU_INF, NU), jnp.arange(3.0),
                     jc.Force(W * np.array([0.5, 1.0, 1.5])))
    sol = as_np(solve_flagged(scene, max_steps=2))
    assert finite(sol)
    assert not sol.converged.any()
    assert np.all(sol.iterations <= 2)
    assert outcome(sol) == "flagged"


# --------------------------------------------------------------------------------------
# Increasing tangential displacement through gross sliding (paper Figs. 23-27).


@pytest.mark.slow
@pytest.mark.parametrize("coupling", ["none", "full"])
def test_tangential_displacement_through_gross_sliding(coupling):
    # delta_x ramps to twice the Cattaneo-Mindlin sliding displacement under a constant
    # normal load: F_x rises monotonically to mu W and stays there (sliding), the stick
    # ratio falls to zero, every step converges.
    mu, g = 0.3, MU_INF
    a = float(jc.Hertz(R, W, g, NU).contact_radius)
    slide = 3 * mu * W * (2 - NU) / (16 * g * a)  # one body, Johnson/2
    nt = 13
    deltas = np.linspace(0.0, 2 * slide, nt)
    scene = jc.Scene(
        jc.Grid((12, 12), 4 * a), jc.Sphere(R), jc.Elastic(g, NU),
        jnp.arange(float(nt)),
        normal=jc.Force(np.full(nt, W)), x=jc.Displacement(deltas), friction=mu,
        coupling=coupling,
    )
    sol = as_np(solve_flagged(scene))
    assert outcome(sol) == "pass"
    fx = sol.tangential_force[:, 0]
    assert np.all(np.diff(fx) >= -1e-8 * mu * W)
    assert sol.sliding[-1] and sol.stick_ratio[-1] == 0
    # Sliding: every contact cell on the Coulomb cone. Uncoupled, the shear is along x
    # and F_x = mu W exactly; coupled, the slip direction is not quite x (radial slip
    # from the pressure), so F_x is slightly below mu W (measured 1.2e-4 at 12 x 12).
    p, q = sol.pressure[-1], np.hypot(sol.shear[-1, 0], sol.shear[-1, 1])
    np.testing.assert_allclose(q[p > 0], mu * p[p > 0], rtol=1e-5)
    rtol = 1e-6 if coupling == "none" else 1e-3
    np.testing.assert_allclose(fx[-1], mu * sol.normal_force[-1], rtol=rtol)
    assert np.all(fx <= mu * sol.normal_force * (1 + 1e-6))


@pytest.mark.slow
def test_coupled_one_step_low_friction_is_flagged():
    # Found by test_properties (hypothesis): nu = 0 (strongest coupling), mu = 0.1, the
    # normal load applied in one step with no tangential load. The normal/tangential
    # rounds do not converge; the step is flagged (converged=False), finite, and the
    # time to flag it is bounded by max_rounds (here 10 rounds instead of 100).
    a = float(jc.Hertz(R, W, MU_INF, 0.0).contact_radius)
    scene = jc.Scene(
        jc.Grid((N, N), 4 * a), jc.Sphere(R), jc.Elastic(MU_INF, 0.0), jnp.arange(3.0),
        normal=jc.Force(np.full(3, W)), x=jc.Force(np.zeros(3)),
        y=jc.Force(np.zeros(3)),
        friction=0.1, coupling="full",
    )
    start = time.perf_counter()
    sol = as_np(solve_flagged(scene, max_rounds=10, max_steps=500))
    seconds = time.perf_counter() - start
    assert finite(sol)
    # Bounded: `rounds` also counts the joint solver's friction-bound updates, so bound
    # the work instead (at most (rounds + 1) x (normal + tangential + joint) solves of
    # max_steps each).
    assert np.all(sol.iterations <= (sol.rounds + 1) * 3 * 500)
    assert seconds < 600
    assert outcome(sol) in ("pass", "flagged")
    np.testing.assert_allclose(sol.normal_force, W, rtol=1e-8)
    # Coulomb holds on the converged steps. (A flagged step may return tractions
    # outside the cone: measured on the first run; they are marked converged=False.)
    q = np.hypot(sol.shear[:, 0], sol.shear[:, 1])
    ok = q <= 0.1 * sol.pressure * (1 + 1e-6) + 1e-12 * sol.pressure.max()
    assert np.all(ok[sol.converged])
    print("converged", sol.converged, "rounds", sol.rounds, "iterations",
          sol.iterations,
          "cone violation", (q - 0.1 * sol.pressure).max() / sol.pressure.max(),
          f"{seconds:.0f} s")
