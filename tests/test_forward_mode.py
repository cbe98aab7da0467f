"""Forward-mode derivatives of `jc.solve` (`jc.ImplicitAdjoint(mode="forward")`): a
custom JVP that solves the frozen-set system `(dF/dx) x_dot = -(dF/dtheta) theta_dot`
per step, against the reverse mode (the custom VJP's adjoint solve of the transposed
system, itself checked against finite differences in test_gradients.py).

Two independent linear solves of two different systems (a matrix and its transpose)
must give one Jacobian: asked to 1e-6 relative (tangent and adjoint solves at rtol
1e-10, the forward solve at 1e-12).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxcontact as jc


R, W, G, NU = 10e-3, 0.15, 1.93e6, 0.3
A0 = float(jc.Hertz(R, W, G, NU).contact_radius)
FORWARD = jc.ImplicitAdjoint(mode="forward", rtol=1e-10)
REVERSE = jc.ImplicitAdjoint(rtol=1e-10)
# One test process for the file: the tests share compiled programs (the "force" and
# "unload" Jacobians: one pair; the reverse gradient: the "force" scene's).
pytestmark = pytest.mark.xdist_group("forward_mode")


LOADINGS = {
    # a ramped load; the load back to zero (steps without contact, where the approach
    # follows the surface's recovery); a ramped approach (the force is the output)
    "force": (jc.Force, W * jnp.linspace(0.3, 1.0, 6)),
    "unload": (jc.Force, W * jnp.array([0.3, 0.6, 1.0, 0.5, 0.0, 0.0])),
    "displacement": (jc.Displacement, 2e-5 * jnp.linspace(0.3, 1.0, 6)),
}


def _creep_curve(adjoint, loading="force"):
    """Zener body, 16^2 x 6, under `LOADINGS[loading]`: the approach (load control)
    or the force (displacement control) history w.r.t. (mu_0, tau, poisson)."""
    grid = jc.Grid((16, 16), 4 * A0)
    times = jnp.linspace(0.0, 0.03, 6)
    control, values = LOADINGS[loading]

    def curve(x):
        mu_0, tau, poisson = x
        material = jc.Zener(mu_inf=G, mu_0=mu_0, tau=tau, poisson=poisson)
        scene = jc.Scene(grid, jc.Sphere(R), material, times, control(values))
        # The grid's tangent and adjoint (jc.solve's default here: the rings).
        sol = jc.solve(scene, solver=jc.Rounds(rtol=1e-12), adjoint=adjoint)
        return 1e6 * sol.approach if control is jc.Force else sol.normal_force

    return curve


@pytest.mark.parametrize("loading", sorted(LOADINGS))
def test_forward_jacobian_of_a_creep_curve_equals_the_reverse_one(loading):
    """Frictionless steps: the tangent by projected CG (`_normal_tangent`), the
    adjoint by its own CG on the transposed system."""
    x = jnp.array([G / 4, 0.01, NU])
    forward = np.asarray(jax.jacfwd(_creep_curve(FORWARD, loading))(x))
    reverse = np.asarray(jax.jacrev(_creep_curve(REVERSE, loading))(x))
    assert forward.shape == (6, 3)
    assert np.all(np.isfinite(forward))
    scale = np.abs(reverse).max(axis=0)  # per parameter (columns differ in units)
    assert np.all(np.abs(forward - reverse) <= 1e-6 * scale), (forward, reverse)


@pytest.mark.slow  # ~35 s for both couplings (four programs); the suite is over time
@pytest.mark.parametrize("coupling", ["x", "full"])
def test_forward_and_reverse_agree_on_a_coupled_partial_slip_history(coupling):
    """Two steps of a Zener body under W and a tangential load (partial slip): the
    tangent of (poisson, friction, F) along t, dotted with a cotangent v, equals the
    cotangent's reverse-mode product dotted with t."""
    grid = jc.Grid((16, 16), 4 * A0)
    times = jnp.linspace(0.0, 0.02, 2)

    def outputs(adjoint):
        def f(x):
            poisson, friction, force = x
            material = jc.Zener(mu_inf=G, mu_0=G / 3, tau=0.01, poisson=poisson)
            scene = jc.Scene(grid, jc.Sphere(R), material, times, jc.Force(W),
                             x=jc.Force(force * jnp.array([0.5, 1.0])),
                             friction=friction, coupling=coupling)
            sol = jc.solve(scene, rtol=1e-12, scheme="linear", adjoint=adjoint)
            return jnp.concatenate([1e6 * sol.tangential_displacement[:, 0],
                                    1e6 * sol.approach])
        return f

    x = jnp.array([NU, 0.3, 0.5 * 0.3 * W])
    t = jnp.array([0.01, 0.02, 0.1 * 0.3 * W])  # a mixed direction
    value, tangent = jax.jvp(outputs(FORWARD), (x,), (t,))
    v = jnp.array([1.0, -0.5, 0.3, 2.0])
    _, vjp = jax.vjp(outputs(REVERSE), x)
    (cotangent,) = vjp(v)
    lhs, rhs = float(jnp.dot(v, tangent)), float(jnp.dot(cotangent, t))
    assert np.isfinite(lhs)
    assert abs(lhs - rhs) <= 1e-6 * (abs(rhs) + float(jnp.linalg.norm(value)) * 1e-3)


def test_reverse_mode_through_the_forward_rule_gives_the_reverse_gradient():
    """`jax.grad` of a forward-mode solve transposes its tangent solve
    (`custom_linear_solve`): the same gradient as the custom VJP."""
    x = jnp.array([G / 4, 0.01, NU])
    weights = jnp.linspace(1.0, 2.0, 6)
    through_forward = jax.grad(lambda x: jnp.dot(weights, _creep_curve(FORWARD)(x)))(x)
    reverse = jax.grad(lambda x: jnp.dot(weights, _creep_curve(REVERSE)(x)))(x)
    assert np.allclose(np.asarray(through_forward), np.asarray(reverse), rtol=1e-6,
                       atol=0)


def test_forward_mode_is_checked_by_name():
    with pytest.raises(ValueError, match="mode"):
        jc.ImplicitAdjoint(mode="sideways")
