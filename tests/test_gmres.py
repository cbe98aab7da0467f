"""The adjoints' restarted GMRES (`jaxcontact/_solver/gmres.py`) on small dense systems
with known answers."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxcontact._solver.gmres import restarted_gmres


def _system(n, seed=0, shift=4.0):
    """A nonsymmetric, well-conditioned `(n, n)` matrix and a right-hand side."""
    rng = np.random.default_rng(seed)
    a = shift * np.eye(n) + rng.normal(size=(n, n)) / np.sqrt(n)
    return a, rng.normal(size=n)


@pytest.mark.parametrize("restart", [3, 10, 40])
def test_solves_a_nonsymmetric_system_to_its_tolerance(restart):
    """The true relative residual is within 1e-10 (the target) and the answer equals
    LAPACK's to 1e-9, whatever the restart length."""
    a, b = _system(60)
    atol = 1e-10 * np.linalg.norm(b)
    x, iterations = jax.jit(lambda b_: restarted_gmres(
        lambda v: jnp.asarray(a) @ v, b_, jnp.zeros_like(b_), atol, restart, 100))(
        jnp.asarray(b))
    x = np.asarray(x)
    assert np.linalg.norm(a @ x - b) <= 1.5e-10 * np.linalg.norm(b)
    np.testing.assert_allclose(x, np.linalg.solve(a, b), rtol=0, atol=1e-9)
    assert 0 < int(iterations) <= 100 * restart


def test_terminates_within_n_iterations_without_restarts():
    """In exact arithmetic full GMRES solves an n x n system in at most n iterations;
    in float64 at n = 8 the residual is at round-off after 8 (a matrix far from normal:
    no early stop from clustered eigenvalues)."""
    rng = np.random.default_rng(3)
    a = np.triu(rng.normal(size=(8, 8)) * 3) + np.diag(np.arange(1.0, 9.0))
    b = rng.normal(size=8)
    x, iterations = restarted_gmres(lambda v: jnp.asarray(a) @ v, jnp.asarray(b),
                                    jnp.zeros(8), 1e-13 * np.linalg.norm(b), 8, 1)
    assert int(iterations) <= 8
    assert np.linalg.norm(a @ np.asarray(x) - b) <= 1e-12 * np.linalg.norm(b)


def test_starts_from_x0_and_stops_at_once_on_an_answer():
    """From the answer itself no iteration runs; from another start the answer is
    reached the same."""
    a, b = _system(20, seed=1)
    exact = np.linalg.solve(a, b)
    mv = lambda v: jnp.asarray(a) @ v  # noqa: E731
    x, iterations = restarted_gmres(mv, jnp.asarray(b), jnp.asarray(exact),
                                    1e-8 * np.linalg.norm(b), 10, 10)
    assert int(iterations) == 0
    np.testing.assert_array_equal(np.asarray(x), exact)
    x, _ = restarted_gmres(mv, jnp.asarray(b), jnp.ones(20), 1e-12 * np.linalg.norm(b),
                           10, 10)
    np.testing.assert_allclose(np.asarray(x), exact, rtol=0, atol=1e-10)


def test_a_nan_operator_ends_the_loop():
    """A NaN from the operator stops the iteration at once (no infinite loop, no
    cycle run on a NaN residual); the caller's check of the true residual, NaN, then
    reports it."""
    op = lambda v: v * jnp.nan  # noqa: E731
    x, iterations = jax.jit(lambda b_: restarted_gmres(
        op, b_, jnp.zeros_like(b_), 1e-10, 5, 1000))(jnp.ones(4))
    assert int(iterations) == 0
    assert np.isnan(float(jnp.linalg.norm(op(x) - jnp.ones(4))))


def test_float32():
    """In float32 the same system reaches 1e-5 (relative), its answer within 1e-4."""
    a, b = _system(40, seed=2)
    a32, b32 = jnp.asarray(a, jnp.float32), jnp.asarray(b, jnp.float32)
    x, _ = restarted_gmres(lambda v: a32 @ v, b32, jnp.zeros_like(b32),
                           1e-5 * float(jnp.linalg.norm(b32)), 20, 10)
    assert x.dtype == jnp.float32
    assert np.linalg.norm(a @ np.asarray(x, np.float64) - b) <= 2e-5 * np.linalg.norm(b)
    np.testing.assert_allclose(np.asarray(x), np.linalg.solve(a, b), rtol=0, atol=1e-4)
