"""Options of `jc.solve` that do not change the solution: progress reporting."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxcontact as jc


def _scene():
    grid = jc.Grid((16, 16), 2e-3)
    material = jc.Zener(mu_inf=1.93e6, mu_0=1.93e6 / 4, tau=0.01, poisson=0.3)
    return jc.Scene(grid, jc.Sphere(10e-3), material, jnp.linspace(0.0, 0.02, 4), jc.Force(0.05))


def test_progress_callback_sees_every_step_in_order_and_changes_nothing():
    seen = []
    plain = jc.solve(_scene())
    reported = jc.solve(_scene(), progress=lambda k, n: seen.append((int(k), int(n))))
    jax.block_until_ready(reported.pressure)
    assert seen == [(k, 4) for k in range(4)]
    np.testing.assert_array_equal(np.asarray(plain.pressure), np.asarray(reported.pressure))


# Redundant: tests/test_cli.py asserts the same stderr lines (CLI: progress=True).
@pytest.mark.slow  # redundant with tests/test_cli.py's progress check
def test_progress_true_prints_to_stderr(capfd):
    sol = jc.solve(_scene(), progress=True)
    jax.block_until_ready(sol.pressure)
    err = capfd.readouterr().err
    assert "step 1/4" in err and "step 4/4" in err


def test_progress_rejects_non_callable():
    with pytest.raises(TypeError, match="progress"):
        jc.solve(_scene(), progress="yes")
