"""Exact gradients of `jc.solve` (implicit differentiation of every step, through the
`lax.scan` over time) against central finite differences and exact scaling laws.

Finite differences are taken on solves at `rtol = 1e-12` with a relative step of
`1e-5`: with the default `rtol = 1e-8` the solver's own tolerance would dominate the
difference quotient (error ~ rtol / h). Agreement asked: 1e-5 relative (the issue's
bound), on scenes whose active sets (contact, stick, slip) do not change under the
perturbation.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxcontact as jc


R, W, G, NU = 10e-3, 0.15, 1.93e6, 0.3
A0 = float(jc.Hertz(R, W, G, NU).contact_radius)
FD_RTOL = 1e-12


def _central_difference(f, x, i, rel=1e-5):
    h = rel * abs(float(x[i]))
    e = jnp.zeros_like(x).at[i].set(h)
    return (f(x + e, FD_RTOL) - f(x - e, FD_RTOL)) / (2 * h)


def _check_against_fd(f, x, tol=1e-5):
    grad = jax.grad(f)(x)
    assert np.all(np.isfinite(np.asarray(grad)))
    for i in range(x.shape[0]):
        fd = float(_central_difference(f, x, i))
        assert abs(float(grad[i]) - fd) <= tol * abs(fd) + 1e-12 * abs(float(f(x))), (
            i, float(grad[i]), fd)
    return grad


def test_viscoelastic_normal_indentation_gradient():
    """Zener creep under a ramped load: approach history and final pressure w.r.t.
    mu_0, tau, poisson, the load and the sphere radius."""
    grid = jc.Grid((20, 20), 4 * A0)
    times = jnp.linspace(0.0, 0.02, 5)

    def loss(x, rtol=None):
        mu_0, tau, poisson, load, radius = x
        material = jc.Zener(mu_inf=G, mu_0=mu_0, tau=tau, poisson=poisson)
        scene = jc.Scene(grid, jc.Sphere(radius), material, times,
                         jc.Force(load * jnp.linspace(0.5, 1.0, 5)))
        sol = jc.solve(scene, rtol=rtol)
        return 1e6 * jnp.sum(sol.approach) + 1e-12 * jnp.sum(sol.pressure[-1] ** 2)

    _check_against_fd(loss, jnp.array([G / 4, 0.01, NU, W, R]))


def test_gradient_after_unloading_to_zero():
    """Load control back to W = 0 (no contact at the last step): the approach is where
    the indenter touches the recovering surface, which depends on the material
    (central differences: about -7e-11 m per Pa of mu_0); its gradient was exactly 0
    (the adjoint held the approach fixed without contact)."""
    grid = jc.Grid((20, 20), 4 * A0)
    program = W * jnp.array([0.0, 0.5, 1.0, 1.0, 1.0, 0.6, 0.3, 0.1, 0.0])
    times = jnp.linspace(0.0, 0.04, program.shape[0])

    def last_approach(x, rtol=None):
        mu_0, tau = x
        material = jc.Zener(mu_inf=G, mu_0=mu_0, tau=tau, poisson=NU)
        scene = jc.Scene(grid, jc.Sphere(R), material, times, jc.Force(program))
        return 1e6 * jc.solve(scene, rtol=rtol).approach[-1]

    grad = _check_against_fd(last_approach, jnp.array([G / 4, 0.01]))
    assert abs(float(grad[0])) > 0


def test_relaxation_prony_gradient_displacement_control():
    """Force under a held indentation (Prony relaxation series) w.r.t. every Prony
    parameter: what `fit_prony` needs."""
    grid = jc.Grid((20, 20), 4 * A0)
    times = jnp.linspace(0.0, 0.03, 5)
    depth = float(jc.Hertz(R, W, G, NU).approach)

    def loss(x, rtol=None):
        g_inf, g1, g2, t1, t2 = x
        material = jc.Prony(g_inf, jnp.stack([g1, g2]), jnp.stack([t1, t2]), NU)
        scene = jc.Scene(grid, jc.Sphere(R), material, times, jc.Displacement(depth))
        sol = jc.solve(scene, rtol=rtol)
        return jnp.sum(sol.normal_force)

    _check_against_fd(loss, jnp.array([G / 3, G / 3, G / 3, 0.005, 0.02]))


def test_elastic_force_is_linear_in_modulus():
    """Under displacement control the elastic pressure is exactly proportional to the
    shear modulus (the contact set does not depend on it): dW/dG = W / G."""
    grid = jc.Grid((24, 24), 4 * A0)
    depth = float(jc.Hertz(R, W, G, NU).approach)

    def force(modulus):
        scene = jc.Scene(grid, jc.Sphere(R), jc.Elastic(modulus, NU), jnp.zeros(1),
                         jc.Displacement(depth))
        return jc.solve(scene).normal_force[0]

    value, slope = jax.value_and_grad(force)(jnp.asarray(G))
    # Exact up to the solves' tolerance (forward and adjoint rtol 1e-8).
    np.testing.assert_allclose(float(slope), float(value) / G, rtol=1e-7)


def test_partial_slip_gradient_displacement_control():
    """Cattaneo-Mindlin-type partial slip (coupling "none", x displacement ramped in
    steps, incremental slip law) w.r.t. the long-time modulus, the friction coefficient
    and the tangential displacement."""
    grid = jc.Grid((20, 20), 4 * A0)
    times = jnp.linspace(0.0, 0.02, 3)

    def loss(x, rtol=None):
        mu_0, friction, shift = x
        material = jc.Zener(mu_inf=G, mu_0=mu_0, tau=0.01, poisson=NU)
        scene = jc.Scene(grid, jc.Sphere(R), material, times, jc.Force(W),
                         x=jc.Displacement(shift * jnp.linspace(0.4, 1.0, 3)),
                         friction=friction)
        sol = jc.solve(scene, rtol=rtol)
        # Tangential quantities only: an O(1) approach term would bury the friction
        # derivative under the finite-difference noise (rtol x |loss| / h).
        return (jnp.sum(sol.tangential_force[:, 0]) * 1e3
                + 1e-7 * jnp.sum(sol.shear[-1] ** 2))

    _check_against_fd(loss, jnp.array([G / 3, 0.3, 1.0e-6]))


def test_partial_slip_gradient_load_control_uncoupled():
    """Uncoupled partial slip under a ramped tangential LOAD (the conjugate-gradient
    adjoint of the stick set with the load row, then the normal block) w.r.t. the
    instantaneous modulus, friction and the tangential load."""
    grid = jc.Grid((20, 20), 4 * A0)
    times = jnp.linspace(0.0, 0.02, 3)

    def loss(x, rtol=None):
        mu_0, friction, force = x
        material = jc.Zener(mu_inf=G, mu_0=mu_0, tau=0.01, poisson=NU)
        scene = jc.Scene(grid, jc.Sphere(R), material, times, jc.Force(W),
                         x=jc.Force(force * jnp.array([0.3, 0.6, 1.0])),
                         friction=friction)
        sol = jc.solve(scene, rtol=rtol)
        return (1e6 * jnp.sum(sol.tangential_displacement) + 1e6 * jnp.sum(sol.approach)
                + 1e-10 * jnp.sum(sol.shear[-1] ** 2))

    _check_against_fd(loss, jnp.array([G / 3, 0.3, 0.5 * 0.3 * W]))


def test_coupled_partial_slip_gradient_load_control():
    """Fully coupled normal and tangential load (coupling "full": the y shear is solved
    too) w.r.t. poisson (it drives the coupling), friction and the tangential load."""
    grid = jc.Grid((20, 20), 4 * A0)
    times = jnp.linspace(0.0, 0.02, 2)

    def loss(x, rtol=None):
        poisson, friction, force = x
        material = jc.Zener(mu_inf=G, mu_0=G / 3, tau=0.01, poisson=poisson)
        scene = jc.Scene(grid, jc.Sphere(R), material, times, jc.Force(W),
                         x=jc.Force(force * jnp.array([0.5, 1.0])), friction=friction,
                         coupling="full")
        # One step of 2 tau: too long for the piecewise-constant scheme at this ratio
        # (jc.TimeStepWarning); the piecewise-linear one is stable.
        sol = jc.solve(scene, rtol=rtol, scheme="linear")
        return (1e6 * jnp.sum(sol.tangential_displacement) + 1e6 * jnp.sum(sol.approach)
                + 1e-10 * jnp.sum(sol.shear[-1] ** 2))

    _check_against_fd(loss, jnp.array([NU, 0.3, 0.5 * 0.3 * W]))


def test_jit_vmap_grad_compose():
    """`jax.jit(jax.vmap(jax.grad(...)))` over a batch of materials built inside the
    traced function equals the per-material gradients."""
    grid = jc.Grid((16, 16), 4 * A0)
    times = jnp.linspace(0.0, 0.02, 3)

    def approach(mu_0):
        material = jc.Zener(mu_inf=G, mu_0=mu_0, tau=0.01, poisson=NU)
        scene = jc.Scene(grid, jc.Sphere(R), material, times, jc.Force(W))
        return jc.solve(scene).approach[-1]

    batch = jnp.array([G / 2, G / 4])
    batched = jax.jit(jax.vmap(jax.grad(approach)))(batch)
    single = jnp.stack([jax.grad(approach)(m) for m in batch])
    np.testing.assert_allclose(np.asarray(batched), np.asarray(single), rtol=1e-9)
    # Creep: a softer long-time modulus gives a deeper indentation.
    assert np.all(np.asarray(batched) < 0)


@pytest.mark.parametrize("field", ["mu_0", "tau"])
def test_tree_at_gradient_on_scene(field):
    """Gradients w.r.t. a scene's own leaves (`eqx.tree_at` replaces a material
    field)."""
    grid = jc.Grid((16, 16), 4 * A0)
    material = jc.Zener(mu_inf=G, mu_0=G / 4, tau=0.01, poisson=NU)
    scene = jc.Scene(grid, jc.Sphere(R), material, jnp.linspace(0.0, 0.02, 3),
                     jc.Force(W))

    def depth(value, rtol=None):
        new = eqx.tree_at(lambda s: getattr(s.material, field), scene, value[0])
        # Steps of tau at ratio 4: the piecewise-linear scheme (the constant one is
        # unstable there: jc.TimeStepWarning).
        return jc.solve(new, rtol=rtol, scheme="linear").approach[-1] * 1e6

    _check_against_fd(depth, jnp.atleast_1d(getattr(material, field)))


def test_float32_gradient_is_finite_and_close():
    """float32: the gradient is finite and within float32 accuracy of float64's."""
    def depth(mu_0, dtype):
        grid = jc.Grid((16, 16), jnp.asarray(4 * A0, dtype))
        material = jc.Zener(mu_inf=jnp.asarray(G, dtype), mu_0=mu_0,
                            tau=jnp.asarray(0.01, dtype),
                            poisson=jnp.asarray(NU, dtype))
        scene = jc.Scene(grid, jc.Sphere(jnp.asarray(R, dtype)), material,
                         jnp.linspace(0.0, 0.02, 3, dtype=dtype),
                         jc.Force(jnp.asarray(W, dtype)))
        return jc.solve(scene).approach[-1] * 1e6

    g32 = jax.grad(depth)(jnp.asarray(G / 4, jnp.float32), jnp.float32)
    g64 = jax.grad(depth)(jnp.asarray(G / 4, jnp.float64), jnp.float64)
    assert g32.dtype == jnp.float32 and np.isfinite(float(g32))
    np.testing.assert_allclose(float(g32), float(g64), rtol=1e-3)


def test_coupled_gradient_on_a_periodic_grid_and_in_float32():
    """The preconditioned GMRES adjoint of coupled steps on a periodic grid (the
    preconditioner's padded-free branch) and in float32: Zener, full coupling, x
    displaced into partial slip, d F_x / d mu_inf at the last step. float64 equals
    central differences to 1e-4 (measured 1.0e-5, the difference step's error);
    float32 is finite and within 10 % of float64's: its adjoint, solved to 1e-5 on
    sets frozen from a float32 forward, moves with the program's round-off (6e-4
    under XLA's default code generation, 8.2e-2 under the suite's legacy emitters;
    `benchmarks/notes/coupled_gradient.md`)."""
    a = float(jc.Hertz(R, W, G, NU).contact_radius)

    def force(g, dtype):
        grid = jc.Grid((24, 24), jnp.asarray(4 * a, dtype), periodic=True)
        material = jc.Zener(mu_inf=g, mu_0=g / 3, tau=0.01, poisson=NU)
        scene = jc.Scene(grid, jc.Sphere(R), material, jnp.linspace(0, 0.02, 4),
                         jc.Force(W), x=jc.Displacement(jnp.linspace(0, 3e-6, 4)),
                         friction=0.3, coupling="full")
        return jc.solve(scene).tangential_force[-1, 0]

    g64 = float(jax.grad(force)(jnp.asarray(G, jnp.float64), jnp.float64))
    h = 1e-4 * G
    fd = (float(force(jnp.asarray(G + h), jnp.float64))
          - float(force(jnp.asarray(G - h), jnp.float64))) / (2 * h)
    np.testing.assert_allclose(g64, fd, rtol=1e-4)
    g32 = jax.grad(force)(jnp.asarray(G, jnp.float32), jnp.float32)
    assert g32.dtype == jnp.float32 and np.isfinite(float(g32))
    np.testing.assert_allclose(float(g32), g64, rtol=0.1)


def test_both_gmres_methods_of_the_adjoint_give_the_same_gradient():
    """`jc.ImplicitAdjoint(gmres_method=...)`: "batched" (the default on GPUs) and
    "incremental" (on CPUs) solve the same adjoint: the coupled gradient agrees to
    1e-6 relative (both solves to rtol 1e-8); an unknown method is refused."""
    grid = jc.Grid((16, 16), 4 * A0)

    def force(g, method):
        scene = jc.Scene(grid, jc.Sphere(R), jc.Zener(mu_inf=g, mu_0=g / 3, tau=0.01,
                                                        poisson=NU),
                         jnp.linspace(0, 0.02, 3), jc.Force(W),
                         x=jc.Displacement(jnp.linspace(0, 3e-6, 3)), friction=0.3,
                         coupling="full")
        adjoint = jc.ImplicitAdjoint(gmres_method=method)
        return jc.solve(scene, adjoint=adjoint).tangential_force[-1, 0]

    incremental = float(jax.grad(force)(G, "incremental"))
    batched = float(jax.grad(force)(G, "batched"))
    assert np.isfinite(incremental) and incremental != 0.0
    np.testing.assert_allclose(batched, incremental, rtol=1e-6)
    with pytest.raises(ValueError, match="gmres_method"):
        jc.ImplicitAdjoint(gmres_method="lgmres")


# The three smallest scenes that raised or were silently wrong before (issue 46), on a
# 20^2 grid of side 3 mm: an elastic load ramp (no history links a step to the
# output), full coupling with the total slip law, and a Zener step at 0.997 mu W that
# slips everywhere without sliding (two shear components: the directions fan out).
GRID_20 = jc.Grid((20, 20), 3e-3)
TIMES_4 = jnp.linspace(0, 1, 4)


def _grad_and_difference(f, x, h):
    """`(jax.grad(f)(x), central difference of f at rtol 1e-10)`, the difference
    Richardson-extrapolated from steps `h` and `h / 2` (fourth order: near mu W the
    response is so curved that a plain one at 1e-5 relative is 1.4e-5 off)."""
    grad = float(jax.grad(lambda v: f(v, None))(x))
    # 1e-10: the joint iteration stalls near 1e-11 on the 0.997 mu W scene.
    fm, fmh, fph, fp = (float(f(x + s * h, 1e-10)) for s in (-1, -0.5, 0.5, 1))
    return grad, (8 * (fph - fmh) - (fp - fm)) / (6 * h)


def test_elastic_load_ramp_gradient_with_steps_not_linked_to_the_output():
    """Each earlier step's adjoint right-hand side is zero while its warm start (the
    next step's adjoint) is not: the adjoint returns zero for them (it raised)."""
    def depth(s, rtol):
        scene = jc.Scene(GRID_20, jc.Sphere(10e-3), jc.Elastic(G, NU), TIMES_4,
                         jc.Force(s * W * jnp.linspace(0.5, 1.0, 4)))
        return jc.solve(scene, rtol=rtol).approach[-1] * 1e6

    grad, fd = _grad_and_difference(depth, 1.0, 1e-4)
    assert abs(grad - fd) <= 1e-5 * abs(fd), (grad, fd)


def test_full_coupling_total_slip_gradient():
    """The total slip law carries nothing between steps: the same zero right-hand
    sides, through the GMRES adjoint of full coupling (it raised)."""
    def fx(mu, rtol):
        scene = jc.Scene(GRID_20, jc.Sphere(10e-3), jc.Elastic(G, NU), TIMES_4,
                         jc.Force(W), x=jc.Displacement(jnp.linspace(0, 5e-6, 4)),
                         friction=mu, coupling="full", slip="total")
        return jc.solve(scene, rtol=rtol).tangential_force[-1, 0] * 1e2

    grad, fd = _grad_and_difference(fx, 0.3, 3e-5)
    assert abs(grad - fd) <= 1e-5 * abs(fd), (grad, fd)


def test_slipping_everywhere_below_the_friction_limit_is_not_gross_sliding():
    """Full coupling, F = 0.997 mu W: the forward leaves no stick cell but meets the
    load with fanned-out slip directions; the adjoint must use those equations, not
    gross sliding's (total shear mu W), which gave -1.59e-6 against -1.233e-5."""
    material = jc.Zener(mu_inf=G, mu_0=G / 3, tau=0.01, poisson=NU)
    program = jc.Force(0.045 * jnp.array([0.3, 0.6, 0.8, 0.997]))

    def solve(mu, rtol):
        scene = jc.Scene(GRID_20, jc.Sphere(10e-3), material, jnp.linspace(0, 0.02, 4),
                         jc.Force(W), x=program, friction=mu, coupling="full")
        return jc.solve(scene, rtol=rtol)

    sol = solve(0.3, None)
    assert bool(sol.sliding[-1]) and not np.any(np.asarray(sol.stick[-1]))
    np.testing.assert_allclose(float(sol.tangential_force[-1, 0]), 0.045 * 0.997,
                               rtol=1e-7)
    grad, fd = _grad_and_difference(lambda mu, rtol: solve(mu, rtol).approach[-1] * 1e6,
                                    0.3, 3e-5)
    assert abs(grad - fd) <= 1e-5 * abs(fd), (grad, fd)


def test_vmap_grad_equals_the_loop_under_every_compile_mode():
    """`vmap(grad)` of a coupled scene whose tangential load starts at zero equals the
    loop of gradients, here under the default test selection's unoptimised code
    generation (where the derivative of `jnp.min` in the no-contact approach row gave
    0 / 0 = NaN for two of three batch members)."""
    a = float(jc.Hertz(R, W, G, NU).contact_radius)
    grid = jc.Grid((16, 16), 4 * a)
    times = jnp.linspace(0, 0.02, 4)

    def response(mu):
        scene = jc.Scene(grid, jc.Sphere(R), jc.Elastic(G, NU), times, jc.Force(W),
                         x=jc.Force(mu * W * jnp.array([0.0, 0.25, 0.5, 0.7])),
                         friction=mu, coupling="x")
        sol = jc.solve(scene)
        return sol.approach[-1] * 1e6 + sol.tangential_displacement[-1, 0] * 1e6

    points = jnp.array([0.29, 0.3, 0.31])
    batched = np.asarray(jax.jit(jax.vmap(jax.grad(response)))(points))
    single = jax.jit(jax.grad(response))
    loop = np.asarray([float(single(m)) for m in points])
    assert np.all(np.isfinite(batched)), batched
    np.testing.assert_allclose(batched, loop, rtol=1e-8)


def test_gross_sliding_tangential_displacement_is_the_contact_mean_in_every_solver():
    """Past mu W under load control `delta_t` is a convention (the indenter slides):
    the mean of `u_t + history_t` over the contact. `JointPCG` took the largest value
    for one shear component, so its gradient (the adjoint's mean) was 84 % off."""
    a = float(jc.Hertz(R, W, G, NU).contact_radius)
    scene = jc.Scene(jc.Grid((16, 16), 4 * a), jc.Sphere(R), jc.Elastic(G, NU),
                     jnp.linspace(0, 1, 3), jc.Force(W),
                     x=jc.Force(0.3 * W * jnp.array([0.3, 0.6, 1.2])), friction=0.3,
                     coupling="x")
    joint = jc.solve(scene, solver=jc.JointPCG(rtol=1e-10), throw=False)
    rounds = jc.solve(scene, solver=jc.Rounds(rtol=1e-10), throw=False)
    assert bool(joint.sliding[-1]) and bool(rounds.sliding[-1])
    np.testing.assert_allclose(float(joint.tangential_displacement[-1, 0]),
                               float(rounds.tangential_displacement[-1, 0]), rtol=1e-6)


def test_adjoint_solves_are_well_posed_for_zero_and_tiny_right_hand_sides():
    """The adjoint's linear solves (GMRES and projected CG): a zero right-hand side
    gives zero, converged, whatever the warm start (it never passed its stopping test
    relative to `||b|| = 0`); a right-hand side of 1e-30 in float32 is solved to the
    accuracy of a unit one (its squared norm underflows)."""
    from jaxcontact._solver.implicit import _right_preconditioned_gmres, _set_adjoint

    rng = np.random.default_rng(0)
    m = rng.normal(size=(40, 40))
    a = m @ m.T / 40 + np.eye(40)  # symmetric positive definite
    b = rng.normal(size=40)
    guess = rng.normal(size=40)
    exact = np.linalg.solve(a, b)
    every = jnp.ones(40, bool)
    for dtype, rtol in ((jnp.float64, 1e-10), (jnp.float32, 1e-5)):
        a_j = jnp.asarray(a, dtype)
        mv = lambda v: a_j @ v  # noqa: E731
        zero = jnp.zeros(40, dtype)
        x, ok = _right_preconditioned_gmres(mv, lambda v: v, zero,
                                            jnp.asarray(guess, dtype), rtol, 40, 400)
        assert bool(ok) and not np.any(np.asarray(x))
        lam, lam_m, ok = _set_adjoint(mv, every, False, 1.0, zero, jnp.zeros((), dtype),
                                      jnp.asarray(guess, dtype), rtol, 400)
        assert bool(ok) and not np.any(np.asarray(lam)) and float(lam_m) == 0
        for scale in (1.0, 1e-30):
            rhs = jnp.asarray(scale * b, dtype)
            x, ok = _right_preconditioned_gmres(
                mv, lambda v: v, rhs, jnp.asarray(guess, dtype), rtol, 40, 400)
            assert bool(ok)
            np.testing.assert_allclose(np.asarray(x, float) / scale, exact,
                                       rtol=100 * rtol, atol=100 * rtol)
            lam, _, ok = _set_adjoint(mv, every, False, 1.0, rhs, jnp.zeros((), dtype),
                                      jnp.asarray(guess, dtype), rtol, 400)
            assert bool(ok)
            np.testing.assert_allclose(np.asarray(lam, float) / scale, exact,
                                       rtol=100 * rtol, atol=100 * rtol)


def test_a_failed_forward_step_gives_its_own_error_or_nan_not_a_gradient():
    """A step whose forward solve did not converge has no derivative: with `throw` the
    gradient raises the forward's own message (here the step bound), not the
    adjoint's (whose advice, more adjoint steps, was the wrong remedy); without, NaN."""
    grid = jc.Grid((16, 16), 4 * A0)

    def depth(w, throw):
        scene = jc.Scene(grid, jc.Sphere(R), jc.Elastic(G, NU), jnp.linspace(0, 1, 3),
                         jc.Force(w * jnp.array([0.5, 0.8, 1.0])))
        sol = jc.solve(scene, solver=jc.Rounds(rtol=1e-12, max_steps=2), throw=throw)
        return sol.approach[-1] * 1e6

    assert np.isnan(float(jax.jit(jax.grad(lambda w: depth(w, False)))(W)))
    with pytest.raises(Exception, match="maximum number of") as info:
        jax.block_until_ready(jax.jit(jax.grad(lambda w: depth(w, True)))(W))
    assert "adjoint" not in str(info.value)
