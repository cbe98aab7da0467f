"""benchmarks/semismooth_newton.py: the semismooth Newton peer of `jc.JointPCG`.

The issue-27 comparison (`newton_vs_joint.py`) is only meaningful if the two solvers
solve the same problem: here a fully coupled oblique one-step load and a two-step
ramp at 24^2 are solved by both to rtol 1e-10 (float64), and their pressures and
shears agree to 1e-8 relative (measured 2e-11 to 4e-10) with identical contact and
stick cells; the GMRES helper is checked against a dense solve.
"""

import importlib.util
import sys
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest

import jaxcontact as jc


ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def newton():
    spec = importlib.util.spec_from_file_location(
        "semismooth_newton", ROOT / "benchmarks" / "semismooth_newton.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its eqx.Modules (dataclasses) look it up
    spec.loader.exec_module(module)
    return module


def test_gmres_solves_a_nonsymmetric_system_to_its_tolerance(newton):
    rng = np.random.default_rng(0)
    n = 40
    a = jnp.asarray(np.eye(n) * 4 + rng.normal(size=(n, n)) / np.sqrt(n))
    b = jnp.asarray(rng.normal(size=n))
    jacobi = 1 / jnp.diag(a)
    x, iterations = newton.gmres(lambda v: a @ v, lambda v: jacobi * v, b, 1e-10,
                                 restart=8, max_iterations=200)
    exact = np.linalg.solve(np.asarray(a), np.asarray(b))
    # Restarted (8) and stopped on the running estimate: residual within 1e-10 ||b||.
    assert np.linalg.norm(np.asarray(a @ x - b)) <= 1e-10 * np.linalg.norm(b) * 1.01
    assert np.allclose(np.asarray(x), exact, rtol=0, atol=1e-9)
    assert 8 < int(iterations) < 200


def _oblique_ramp(steps):
    """Sphere R = 10 mm on G = 1 MPa, nu = 0.2, W = 0.15 N, 24^2 over 4 a, mu 0.3;
    (F_x, F_y) = 0.8 mu W (cos 0.7, sin 0.7) ramped in `steps`; full coupling."""
    a = float(jc.Hertz(10e-3, 0.15, 1e6, 0.2).contact_radius)
    t = jnp.arange(steps, dtype=jnp.float64)
    force = 0.8 * 0.3 * 0.15 * (t + 1) / steps
    return jc.Scene(jc.Grid((24, 24), 4 * a), jc.Sphere(10e-3), jc.Elastic(1e6, 0.2),
                    times=t, normal=jc.Force(jnp.full(steps, 0.15)),
                    x=jc.Force(force * np.cos(0.7)), y=jc.Force(force * np.sin(0.7)),
                    friction=0.3, coupling="full")


@pytest.mark.slow  # two compilations of each solver (~15 s): a benchmark's peer
@pytest.mark.parametrize("steps", [1, 2])
def test_newton_and_joint_give_the_same_coupled_solution(newton, steps):
    scene = _oblique_ramp(steps)
    joint = jc.solve(scene, solver=jc.JointPCG(rtol=1e-10))
    other = jc.solve(scene, solver=newton.SemismoothNewton(rtol=1e-10))
    assert bool(jnp.all(other.converged))
    p_j, p_n = np.asarray(joint.pressure[-1]), np.asarray(other.pressure[-1])
    q_j, q_n = np.asarray(joint.shear[-1]), np.asarray(other.shear[-1])
    assert np.linalg.norm(p_n - p_j) <= 1e-8 * np.linalg.norm(p_j)
    assert np.linalg.norm(q_n - q_j) <= 1e-8 * np.linalg.norm(q_j)
    assert np.array_equal(np.asarray(joint.contact[-1]), np.asarray(other.contact[-1]))
    assert np.array_equal(np.asarray(joint.stick[-1]), np.asarray(other.stick[-1]))
    # A partial-slip state: both zones present, so the test exercises both row kinds.
    stick = np.asarray(other.stick[-1]) & np.asarray(other.contact[-1])
    assert 0 < stick.sum() < np.asarray(other.contact[-1]).sum()
