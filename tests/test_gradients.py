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
        return jnp.sum(sol.tangential_force[:, 0]) * 1e3 + 1e-7 * jnp.sum(sol.shear[-1] ** 2)

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
                         x=jc.Force(force * jnp.array([0.3, 0.6, 1.0])), friction=friction)
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
    """Gradients w.r.t. a scene's own leaves (`eqx.tree_at` replaces a material field)."""
    grid = jc.Grid((16, 16), 4 * A0)
    material = jc.Zener(mu_inf=G, mu_0=G / 4, tau=0.01, poisson=NU)
    scene = jc.Scene(grid, jc.Sphere(R), material, jnp.linspace(0.0, 0.02, 3), jc.Force(W))

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
                            tau=jnp.asarray(0.01, dtype), poisson=jnp.asarray(NU, dtype))
        scene = jc.Scene(grid, jc.Sphere(jnp.asarray(R, dtype)), material,
                         jnp.linspace(0.0, 0.02, 3, dtype=dtype), jc.Force(jnp.asarray(W, dtype)))
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
