"""Viscoelastic materials: Laplace pairs, creep series, limits, the paper's PMMA data,
gradients, transformations and input validation."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import integrate

import jaxcontact as jc


def _materials():
    """name -> (material, time scale)."""
    return {
        "elastic": (jc.Elastic(2.0, 0.3), 1.0),
        "maxwell": (jc.Maxwell(2.0, 3.0, 0.3), 1.5),
        "zener": (jc.Zener(mu_inf=3.0, mu_0=0.75, tau=0.5, poisson=0.3), 0.5),
        "prony_solid": (jc.Prony(1.0, [0.5, 2.0, 1.2], [0.1, 1.0, 7.0], 0.3), 2.0),
        "prony_fluid": (jc.Prony(0.0, [1.0, 2.0, 0.5], [1.0, 0.1, 10.0], 0.3), 2.0),
        "prony_zero_arm": (jc.Prony(1.0, [0.0, 1.0, 0.3], [0.3, 2.0, 0.05], 0.3), 1.0),
        "prony_empty": (jc.Prony(1.5, [], [], 0.3), 1.0),
        "pmma_eq28": (jc.Prony.from_creep(0.699, [0.0838, 0.06174], [133.869, 9.9404],
                                          0.38), 50.0),
        "creep_fluid": (
            jc.Prony.from_creep(0.9, [0.2, 0.3], [0.5, 4.0], 0.3, fluidity=0.25),
            2.0,
        ),
        "creep_fluidity_zero": (
            jc.Prony.from_creep(0.9, [0.2, 0.3], [0.5, 4.0], 0.3, fluidity=0.0),
            2.0,
        ),
    }


MATERIALS = _materials()


@jax.jit
def _volterra_integrand(mat, s, t):
    return mat.creep(t - s) * jax.grad(mat.relaxation)(s)


@pytest.mark.parametrize("name", list(MATERIALS))
def test_volterra_identity(name):
    """int_0^t J(t - s) dG(s) = G(0) J(t) + int_0^t J(t - s) G'(s) ds = 1."""
    mat, scale = MATERIALS[name]
    def integrand(s, t):
        return _volterra_integrand(mat, s, t)

    g0 = float(mat.relaxation(0.0))
    for t in scale * np.array([0.05, 0.4, 1.0, 3.0, 8.0]):
        integral, _ = integrate.quad(
            lambda s: float(integrand(s, t)), 0.0, t, epsabs=1e-14, epsrel=1e-13,
            limit=400
        )
        total = g0 * float(mat.creep(t)) + integral
        assert abs(total - 1.0) < 1e-8, (name, t, total)


def _laplace(mat, s):
    cs = mat.creep_series()
    jhat = (
        cs.glassy / s
        + jnp.sum(cs.strengths[None, :]
                  / (s[:, None] * (1 + s[:, None] * cs.times[None, :])), axis=1)
        + cs.fluidity / s**2
    )
    if isinstance(mat, jc.Prony):
        ghat = mat.g_inf / s + jnp.sum(
            mat.g[None, :] * mat.tau[None, :] / (1 + s[:, None] * mat.tau[None, :]),
            axis=1
        )
    else:
        ghat = None
    return ghat, jhat


@pytest.mark.parametrize("g_inf", [0.7, 1e-7, 0.0])
def test_laplace_pair_wide_spectrum(g_inf):
    """12 arms spread over 12 decades, down to (nearly) fluid: s^2 G^ J^ = 1."""
    rng = np.random.default_rng(0)
    tau = np.logspace(-6, 6, 12) * np.exp(rng.uniform(-0.3, 0.3, 12))
    g = rng.uniform(0.1, 3.0, 12)
    mat = jc.Prony(g_inf, g, tau, 0.3)
    cs = mat.creep_series()
    assert np.all(np.asarray(cs.strengths) >= 0) and np.all(np.asarray(cs.times) > 0)
    s = jnp.logspace(-9, 9, 61)
    ghat, jhat = _laplace(mat, s)
    np.testing.assert_allclose(s**2 * ghat * jhat, 1.0, rtol=1e-10, atol=0)
    # Retardation times interlace the relaxation times: one above each (the longest
    # missing for a fluid).
    times = np.sort(np.asarray(cs.times)[np.asarray(cs.strengths) > 0])
    tau_sorted = np.sort(tau)
    k = len(times)
    assert k == (12 if g_inf > 0 else 11)
    assert np.all(times > tau_sorted[:k])
    assert np.all(times[:11] < tau_sorted[1:])


def _hard_prony_cases():
    rng = np.random.default_rng(3)
    n = 30
    tau = np.logspace(-8, 8, n) * np.exp(rng.uniform(-0.5, 0.5, n))
    g = rng.uniform(0, 1, n) ** 4
    g[rng.uniform(size=n) < 0.3] = 0.0
    return [
        (1.0, [1e-300, 1.0], [1.0, 2.0]),  # a root closer to its pole than rounding
        (1.0, [1.0, 1e-12, 1.0], [1.0, 2.0, 3.0]),
        (1.0, [1.0, 1.0], [1.0, 1.0 + 1e-12]),  # nearly equal times
        (1e-200, [1.0, 1.0], [1.0, 3.0]),  # nearly a fluid
        (1.0, [1e6, 1.0], [1.0, 3.0]),
        (0.0, [0.0, 1.0, 0.0], [1.0, 2.0, 3.0]),  # a fluid with inert arms
        (0.3, g, tau),
        (0.0, g, tau),
    ]


@pytest.mark.parametrize("case", range(8))
def test_laplace_pair_hard_cases(case):
    g_inf, g, tau = _hard_prony_cases()[case]
    mat = jc.Prony(g_inf, g, tau, 0.3)
    cs = mat.creep_series()
    assert np.all(np.asarray(cs.strengths) >= 0) and np.all(np.asarray(cs.times) > 0)
    s = jnp.logspace(-14, 14, 57)
    ghat, jhat = _laplace(mat, s)
    np.testing.assert_allclose(s**2 * ghat * jhat, 1.0, rtol=1e-12, atol=0)
    if case != 0:
        return
    grads = jax.grad(lambda p: jc.Prony(p[0], p[1], p[2], 0.3).creep(3.0))(
        (mat.g_inf, mat.g, mat.tau)
    )
    assert all(np.all(np.isfinite(np.asarray(x))) for x in grads)


@pytest.mark.parametrize("fluidity", [None, 0.5])
def test_from_creep_wide_spectrum(fluidity):
    rng = np.random.default_rng(5)
    n = 20
    tau = np.logspace(-6, 6, n) * np.exp(rng.uniform(-0.5, 0.5, n))
    j = rng.uniform(0, 1, n) ** 3
    j[3] = 0.0
    j_inf = j.sum() + 0.01
    mat = jc.Prony.from_creep(j_inf, j, tau, 0.3, fluidity=fluidity)
    assert mat.g.shape == (n + (fluidity is not None),)
    assert np.all(np.asarray(mat.g) >= 0)
    s = jnp.logspace(-12, 12, 49)
    jhat = j_inf / s - jnp.sum(
        j[None, :] * tau[None, :] / (1 + s[:, None] * tau[None, :]), axis=1)
    jhat = jhat + (fluidity or 0.0) / s**2
    ghat, _ = _laplace(mat, s)
    np.testing.assert_allclose(s**2 * ghat * jhat, 1.0, rtol=1e-11, atol=0)


@pytest.mark.parametrize("name", list(MATERIALS))
def test_creep_series_reproduces_creep(name):
    mat, scale = MATERIALS[name]
    t = scale * jnp.array([0.0, 0.01, 0.3, 1.0, 4.0, 20.0])
    cs = mat.creep_series()
    assert cs.strengths.shape == cs.times.shape and cs.strengths.ndim == 1
    assert cs.glassy.shape == () and cs.fluidity.shape == ()
    assert np.all(np.asarray(cs.strengths) >= 0) and np.all(np.asarray(cs.times) > 0)
    assert float(cs.fluidity) >= 0
    np.testing.assert_allclose(cs.glassy * mat.relaxation(0.0), 1.0, rtol=1e-13)
    np.testing.assert_allclose(cs(t), mat.creep(t), rtol=1e-12, atol=0)
    # scalar and 2-D time arguments
    np.testing.assert_allclose(cs(t[2]), mat.creep(t[2]), rtol=1e-12)
    assert mat.creep(t.reshape(2, 3)).shape == (2, 3)
    assert mat.relaxation(t.reshape(2, 3)).shape == (2, 3)


def test_paper_forms():
    """Maxwell (Eqs. 22-23) and Zener (Eqs. 29-30) exactly as written."""
    t = jnp.linspace(0.0, 0.05, 7)
    mu_inf, mu_0, tau = 1.93e6, 1.93e6 / 4, 0.01
    z = jc.Zener(mu_inf=mu_inf, mu_0=mu_0, tau=tau, poisson=0.3)
    psi = mu_0 + (mu_inf - mu_0) * np.exp(-t / (mu_0 / mu_inf * tau))
    mu_1 = 1 / (1 / mu_0 - 1 / mu_inf)
    phi = 1 / mu_inf + 1 / mu_1 * (1 - np.exp(-t / tau))
    np.testing.assert_allclose(z.relaxation(t), psi, rtol=1e-14)
    np.testing.assert_allclose(z.creep(t), phi, rtol=1e-14)
    assert float(z.relaxation(0.0)) == mu_inf  # mu_inf: instantaneous
    np.testing.assert_allclose(z.relaxation(1e3), mu_0, rtol=1e-14)  # mu_0: long-time
    np.testing.assert_allclose(z.relaxation_time, tau / 4, rtol=1e-15)
    m = jc.Maxwell(shear_modulus=2.0, viscosity=5.0, poisson=0.3)
    np.testing.assert_allclose(m.relaxation(t * 100), 2.0 * np.exp(-t * 100 / 2.5),
                               rtol=1e-14)
    np.testing.assert_allclose(m.creep(t * 100), 0.5 + t * 100 / 5.0, rtol=1e-14)
    np.testing.assert_allclose(m.relaxation_time, 2.5)


def test_elastic_limits():
    t = jnp.array([0.0, 0.1, 1.0, 10.0])
    el = jc.Elastic(2.0, 0.3)
    for mat in [
        jc.Zener(2.0, 2.0, 0.7, 0.3),
        jc.Prony(2.0, [0.0, 0.0], [1.0, 3.0], 0.3),
        jc.Prony(2.0, [], [], 0.3),
        jc.Prony.from_creep(0.5, [0.0], [1.0], 0.3),
        jc.Prony.from_creep(0.5, [], [], 0.3),
    ]:
        np.testing.assert_allclose(mat.creep(t), el.creep(t), rtol=1e-14)
        np.testing.assert_allclose(mat.relaxation(t), el.relaxation(t), rtol=1e-14)
        cs = mat.creep_series()
        np.testing.assert_allclose(cs.glassy, 0.5, rtol=1e-14)
        assert float(jnp.sum(cs.strengths)) == 0.0 and float(cs.fluidity) == 0.0
    big = jc.Maxwell(2.0, 1e12, 0.3)
    np.testing.assert_allclose(big.creep(t), el.creep(t), rtol=1e-10)
    np.testing.assert_allclose(big.relaxation(t), el.relaxation(t), rtol=1e-10)
    # Nearly elastic Prony: a tiny arm perturbs J by about its share.
    near = jc.Prony(2.0, [1e-9], [1.0], 0.3)
    np.testing.assert_allclose(near.creep(t), el.creep(t), rtol=1e-9)
    ecs = el.creep_series()
    assert ecs.strengths.shape == (0,) and ecs.times.shape == (0,)
    np.testing.assert_allclose(ecs(t), el.creep(t))


def test_zener_is_a_one_arm_prony():
    z = jc.Zener(3.0, 0.75, 0.5, 0.3)
    p = jc.Prony(0.75, [2.25], [0.5 * 0.75 / 3.0], 0.3)
    t = jnp.linspace(0.0, 3.0, 9)
    np.testing.assert_allclose(p.creep(t), z.creep(t), rtol=1e-13)
    np.testing.assert_allclose(p.creep_series().times, [0.5], rtol=1e-13)
    q = jc.Prony.from_creep(1 / 0.75, [1 / 0.75 - 1 / 3.0], [0.5], 0.3)
    np.testing.assert_allclose(q.relaxation(t), z.relaxation(t), rtol=1e-13)
    # Maxwell is a fluid Prony arm, and a fluid creep series converts back.
    mx = jc.Maxwell(2.0, 3.0, 0.3)
    pm = jc.Prony(0.0, [2.0], [1.5], 0.3)
    np.testing.assert_allclose(pm.creep(t), mx.creep(t), rtol=1e-13)
    fm = jc.Prony.from_creep(0.5, [], [], 0.3, fluidity=1 / 3.0)
    np.testing.assert_allclose(fm.relaxation(t), mx.relaxation(t), rtol=1e-13)
    assert float(fm.g_inf) == 0.0


def test_round_trip():
    t = jnp.linspace(0.0, 30.0, 13)
    solid = jc.Prony(1.0, [0.5, 2.0, 1.2], [0.1, 1.0, 7.0], 0.3)
    cs = solid.creep_series()
    back = jc.Prony.from_creep(cs.glassy + jnp.sum(cs.strengths), cs.strengths,
                               cs.times, 0.3)
    np.testing.assert_allclose(back.g_inf, solid.g_inf, rtol=1e-13)
    order = np.argsort(np.asarray(back.tau))
    np.testing.assert_allclose(np.asarray(back.tau)[order], [0.1, 1.0, 7.0], rtol=1e-12)
    np.testing.assert_allclose(np.asarray(back.g)[order], [0.5, 2.0, 1.2], rtol=1e-12)
    # Creep -> relaxation -> creep.
    creep = jc.Prony.from_creep(0.9, [0.2, 0.3], [0.5, 4.0], 0.3)
    cs = creep.creep_series()
    order = np.argsort(np.asarray(cs.times))
    np.testing.assert_allclose(np.asarray(cs.times)[order], [0.5, 4.0], rtol=1e-12)
    np.testing.assert_allclose(np.asarray(cs.strengths)[order], [0.2, 0.3], rtol=1e-12)
    np.testing.assert_allclose(cs.glassy, 0.4, rtol=1e-13)
    # A fluid: relaxation -> creep (with fluidity) -> relaxation.
    fluid = jc.Prony(0.0, [1.0, 2.0, 0.5], [1.0, 0.1, 10.0], 0.3)
    cs = fluid.creep_series()
    np.testing.assert_allclose(cs.fluidity, 1 / (1.0 + 0.2 + 5.0), rtol=1e-14)
    back = jc.Prony.from_creep(
        cs.glassy + jnp.sum(cs.strengths), cs.strengths, cs.times, 0.3,
        fluidity=cs.fluidity
    )
    assert float(back.g_inf) == 0.0
    np.testing.assert_allclose(back.relaxation(t), fluid.relaxation(t), rtol=1e-12)


def test_paper_pmma_eq27_vs_eq28():
    """Eq. 28 (creep, 1/GPa) is the exact Laplace conversion of Eq. 27 (relaxation,
    MPa), in the SAME modulus convention (no factor 2 between them): Eq. 28 rounds
    J(inf) = 1 / 1429.71 MPa = 0.69944 /GPa to 0.699."""
    eq27 = jc.Prony(1429.71, [184.62, 191.06], [8.93, 117.96], 0.38)  # MPa, s
    cs = eq27.creep_series()
    order = np.argsort(-np.asarray(cs.times))
    times = np.asarray(cs.times)[order]
    strengths = np.asarray(cs.strengths)[order] * 1e3  # 1/MPa -> 1/GPa
    j_inf = (float(cs.glassy) + strengths.sum() / 1e3) * 1e3
    np.testing.assert_allclose(times, [133.869, 9.9404], rtol=5e-4)
    np.testing.assert_allclose(strengths, [0.0838, 0.06174], rtol=5e-4)
    np.testing.assert_allclose(j_inf, 0.699, rtol=1e-3)
    t = jnp.linspace(0.0, 600.0, 31)
    eq28 = 0.699 - 0.0838 * np.exp(-t / 133.869) - 0.06174 * np.exp(-t / 9.9404)
    np.testing.assert_allclose(eq27.creep(t) * 1e3, eq28, rtol=1e-3)
    # And back: Eq. 28 -> a relaxation series close to Eq. 27.
    pmma = jc.Prony.from_creep(0.699e-3, [0.0838e-3, 0.06174e-3], [133.869, 9.9404],
                               0.38)
    order = np.argsort(np.asarray(pmma.tau))
    np.testing.assert_allclose(pmma.g_inf, 1429.71, rtol=1e-3)
    np.testing.assert_allclose(np.asarray(pmma.tau)[order], [8.93, 117.96], rtol=5e-4)
    np.testing.assert_allclose(np.asarray(pmma.g)[order], [184.62, 191.06], rtol=2e-3)
    np.testing.assert_allclose(pmma.relaxation(t), eq27.relaxation(t), rtol=1e-3)


@pytest.mark.parametrize(
    "j, ratios",
    [((0.0838, 0.06174), (1.136, 1.097)), ((0.5595, 0.02), (5.0, 1.03))],  # Eqs. 28, 31
)
def test_paper_zener_ratios(j, ratios):
    """Paper Eqs. 32-33: each creep term alone is a Zener with mu_inf / mu_0 ~ ratio."""
    for jk, tk, ratio in zip(j, (133.869, 9.9404), ratios):
        p = jc.Prony.from_creep(0.699, [jk], [tk], 0.38)
        np.testing.assert_allclose(p.relaxation(0.0) / p.g_inf, ratio, rtol=3e-3)
    p = jc.Prony.from_creep(0.699, list(j), [133.869, 9.9404], 0.38)  # Eq. 31 is valid
    assert np.all(np.asarray(p.g) > 0)


def _fd_check(f, x, ts=(0.05, 0.7, 6.0), rel=1e-6, h=1e-6):
    """jax.grad of `f(x, t)` w.r.t. `x` vs central differences, at each `t`."""
    x = jnp.asarray(x, dtype=jnp.float64)
    grad_fn = jax.jit(jax.grad(f))
    f = jax.jit(f)
    flat = np.atleast_1d(np.asarray(x))
    for t in ts:
        grad = np.atleast_1d(np.asarray(grad_fn(x, t)))
        fd = np.zeros_like(flat)
        for i in range(flat.size):
            step = h * max(abs(flat[i]), 1e-3)
            xp, xm = flat.copy(), flat.copy()
            xp[i] += step
            xm[i] -= step
            fp = f(jnp.asarray(xp).reshape(x.shape), t)
            fm = f(jnp.asarray(xm).reshape(x.shape), t)
            fd[i] = (fp - fm) / (2 * step)
        scale = np.max(np.abs(fd))
        assert scale > 0
        np.testing.assert_allclose(grad, fd, rtol=rel, atol=rel * scale,
                                   err_msg=f"t={t}")


def test_gradients_vs_finite_differences_simple():
    _fd_check(lambda p, t: jc.Maxwell(p[0], p[1], 0.3).creep(t), [2.0, 3.0])
    _fd_check(lambda p, t: jc.Maxwell(p[0], p[1], 0.3).relaxation(t), [2.0, 3.0])
    _fd_check(lambda p, t: jc.Zener(p[0], p[1], p[2], 0.3).creep(t), [3.0, 0.75, 0.5])
    _fd_check(lambda p, t: jc.Zener(p[0], p[1], p[2], 0.3).relaxation(t),
              [3.0, 0.75, 0.5])
    _fd_check(lambda p, t: jc.Elastic(p, 0.3).creep(t), 2.0)


def test_gradients_vs_finite_differences_prony():
    # Prony solid: [g_inf, g (3), tau (3)]
    def f(p, t):
        return jc.Prony(p[0], p[1:4], p[4:7], 0.3).creep(t)

    _fd_check(f, [1.0, 0.5, 2.0, 1.2, 0.1, 1.0, 7.0])

    # Prony fluid (g_inf = 0 held fixed): g and tau
    def f(p, t):
        return jc.Prony(0.0, p[0:3], p[3:6], 0.3).creep(t)

    _fd_check(f, [1.0, 2.0, 0.5, 1.0, 0.1, 10.0])


def test_gradients_vs_finite_differences_from_creep():
    # [j_inf, j (2), tau (2)] -> relaxation and creep
    def f(p, t):
        mat = jc.Prony.from_creep(p[0], p[1:3], p[3:5], 0.3)
        return mat.relaxation(t) + 3 * mat.creep(t)

    _fd_check(f, [0.9, 0.2, 0.3, 0.5, 4.0])

    def f(p, t):
        return jc.Prony.from_creep(p[0], p[1:3], p[3:5], 0.3,
                                   fluidity=p[5]).relaxation(t)

    _fd_check(f, [0.9, 0.2, 0.3, 0.5, 4.0, 0.25])


def test_gradients_of_creep_series():
    """d(strengths, times, fluidity)/d(parameters), through jacfwd and grad alike."""
    def series(p):
        cs = jc.Prony(p[0], p[1:4], p[4:7], 0.3).creep_series()
        return jnp.concatenate([cs.glassy[None], cs.strengths, cs.times,
                                cs.fluidity[None]])

    p = jnp.array([1.0, 0.5, 2.0, 1.2, 0.1, 1.0, 7.0])
    jac = jax.jit(jax.jacfwd(series))(p)
    jac_rev = jax.jit(jax.jacrev(series))(p)
    series = jax.jit(series)
    np.testing.assert_allclose(jac, jac_rev, rtol=1e-12, atol=1e-14)
    h = 1e-6
    fd = np.stack(
        [(series(p.at[i].add(h * p[i])) - series(p.at[i].add(-h * p[i])))
         / (2 * h * p[i]) for i in range(7)],
        axis=1,
    )
    np.testing.assert_allclose(jac, fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())


def test_gradient_at_a_zero_arm():
    """g_k = 0 is allowed; d J / d g_k there matches a one-sided difference."""
    t = 0.7
    f = jax.jit(lambda gk: jc.Prony(1.0, jnp.stack([gk, 1.0, 0.3]), [0.3, 2.0, 0.05],
                                    0.3).creep(t))
    grad = float(jax.grad(f)(0.0))
    h = 1e-5
    fd = (-3 * f(0.0) + 4 * f(h) - f(2 * h)) / (2 * h)
    np.testing.assert_allclose(grad, fd, rtol=1e-6)
    assert grad < 0  # a stiffer material creeps less


def test_vmap_and_jit_construction():
    t = jnp.array([0.0, 0.3, 2.0])
    ratios = jnp.array([2.0, 4.0, 8.0, 10.0])

    @jax.jit
    def zener_creep(r):
        return jc.Zener(mu_inf=1.93e6, mu_0=1.93e6 / r, tau=0.01,
                        poisson=0.3).creep(t * 0.01)

    batched = jax.vmap(zener_creep)(ratios)
    for k, r in enumerate(ratios):
        expect = jc.Zener(1.93e6, 1.93e6 / float(r), 0.01, 0.3).creep(t * 0.01)
        np.testing.assert_allclose(batched[k], expect, rtol=1e-14)

    gs = jnp.array([[0.5, 2.0, 1.2], [0.1, 0.0, 3.0], [1.0, 1.0, 1.0]])
    tau = jnp.array([0.1, 1.0, 7.0])
    mats = jax.jit(jax.vmap(lambda g: jc.Prony(1.0, g, tau, 0.3)))(gs)
    assert mats.g.shape == (3, 3)
    creep = jax.jit(jax.vmap(lambda m: m.creep(t)))(mats)
    series = jax.vmap(lambda m: m.creep_series())(mats)
    assert series.strengths.shape == (3, 3)
    for k in range(3):
        expect = jc.Prony(1.0, gs[k], tau, 0.3).creep(t)
        np.testing.assert_allclose(creep[k], expect, rtol=1e-13)

    fc = jax.jit(jax.vmap(
        lambda j: jc.Prony.from_creep(0.9, j, [0.5, 4.0], 0.3).relaxation(t)))
    out = fc(jnp.array([[0.2, 0.3], [0.1, 0.0]]))
    np.testing.assert_allclose(
        out[1], jc.Prony.from_creep(0.9, [0.1, 0.0], [0.5, 4.0], 0.3).relaxation(t))

    mx = jax.vmap(lambda eta: jc.Maxwell(2.0, eta, 0.3).creep(t))(jnp.array([1.0, 2.0]))
    np.testing.assert_allclose(mx[1], 0.5 + t / 2.0)

    # tree_at on a field, then grad through the material
    z = jc.Zener(3.0, 0.75, 0.5, 0.3)
    z2 = eqx.tree_at(lambda m: m.mu_0, z, jnp.asarray(1.5))
    np.testing.assert_allclose(z2.creep(1e3), 1 / 1.5)


def test_float32():
    f32 = jnp.float32
    mat = jc.Prony(f32(1.0), jnp.array([0.5, 2.0, 1.2], f32),
                   jnp.array([0.1, 1.0, 7.0], f32), 0.3)
    cs = mat.creep_series()
    assert cs.strengths.dtype == jnp.float32
    ref = jc.Prony(1.0, [0.5, 2.0, 1.2], [0.1, 1.0, 7.0], 0.3)
    t = jnp.array([0.0, 1.0, 10.0])
    np.testing.assert_allclose(mat.creep(t.astype(f32)), ref.creep(t), rtol=1e-5)


@pytest.mark.parametrize(
    "build, match",
    [
        (lambda: jc.Maxwell(-1.0, 1.0, 0.3), "shear_modulus"),
        (lambda: jc.Maxwell(1.0, 0.0, 0.3), "viscosity"),
        (lambda: jc.Maxwell(1.0, np.nan, 0.3), "viscosity"),
        (lambda: jc.Maxwell(1.0, 1.0, 0.6), "poisson"),
        (lambda: jc.Maxwell(1.0, 1.0, -1.0), "poisson"),
        (lambda: jc.Maxwell([1.0, 2.0], 1.0, 0.3), "shear_modulus"),
        (lambda: jc.Zener(-3.0, 1.0, 1.0, 0.3), "mu_inf"),
        (lambda: jc.Zener(3.0, 0.0, 1.0, 0.3), "mu_0"),
        (lambda: jc.Zener(1.0, 2.0, 1.0, 0.3), "mu_0"),
        (lambda: jc.Zener(3.0, 1.0, 0.0, 0.3), "tau"),
        (lambda: jc.Zener(3.0, 1.0, 1.0, 0.7), "poisson"),
        (lambda: jc.Prony(-1.0, [1.0], [1.0], 0.3), "g_inf"),
        (lambda: jc.Prony(1.0, [1.0, -0.5], [1.0, 2.0], 0.3), "g"),
        (lambda: jc.Prony(1.0, [1.0, 0.5], [1.0, -2.0], 0.3), "tau"),
        (lambda: jc.Prony(1.0, [1.0, 0.5], [1.0], 0.3), "tau"),
        (lambda: jc.Prony(1.0, [[1.0]], [[1.0]], 0.3), "tau"),
        (lambda: jc.Prony([1.0, 2.0], [1.0], [1.0], 0.3), "g_inf"),
        (lambda: jc.Prony(1.0, [1.0, 0.5], [2.0, 2.0], 0.3), "tau"),
        (lambda: jc.Prony(0.0, [0.0, 0.0], [1.0, 2.0], 0.3), "g_inf"),
        (lambda: jc.Prony(1.0, [1.0], [1.0], 0.5000001), "poisson"),
        (lambda: jc.Prony.from_creep(0.5, [0.3, 0.3], [1.0, 2.0], 0.3), "j_inf"),
        (lambda: jc.Prony.from_creep(1.0, [0.3, -0.1], [1.0, 2.0], 0.3), "j"),
        (lambda: jc.Prony.from_creep(1.0, [0.3], [0.0], 0.3), "tau"),
        (lambda: jc.Prony.from_creep(np.inf, [0.3], [1.0], 0.3), "j_inf"),
        (lambda: jc.Prony.from_creep(1.0, [0.3], [1.0, 2.0], 0.3), "tau"),
        (lambda: jc.Prony.from_creep(1.0, [0.3], [1.0], 0.3, fluidity=-1.0),
         "fluidity"),
        (lambda: jc.Prony.from_creep(1.0, [0.3], [1.0], 2.0), "poisson"),
    ],
)
def test_bad_input(build, match):
    with pytest.raises(ValueError, match=match):
        build()


@pytest.mark.parametrize(
    "build, good, bad, match",
    [
        (lambda v: jc.Maxwell(1.0, v, 0.3), 1.0, -1.0, "viscosity"),
        (lambda v: jc.Zener(1.0, v, 1.0, 0.3), 0.5, 2.0, "mu_0"),
        (lambda v: jc.Prony(1.0, jnp.stack([v, 1.0]), [1.0, 2.0], 0.3), 1.0, -1.0, "g"),
        (lambda v: jc.Prony(1.0, [1.0, 1.0], jnp.stack([v, 2.0]), 0.3), 3.0, 2.0,
         "tau"),
        (lambda v: jc.Prony.from_creep(v, [0.3, 0.3], [1.0, 2.0], 0.3), 0.9, 0.5,
         "j_inf"),
    ],
)
def test_bad_traced_input(build, good, bad, match):
    """Inside jit the checks are eqx.error_if: they raise when the result is
    computed."""
    f = jax.jit(lambda v: build(v).creep(jnp.asarray([0.0, 1.0])))
    assert np.all(np.isfinite(np.asarray(f(jnp.asarray(good)))))
    with pytest.raises(Exception, match=match):
        jax.block_until_ready(f(jnp.asarray(bad)))
