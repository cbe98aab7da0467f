"""Options of `jc.solve` that do not change the solution: progress reporting, the
normal CG's preconditioner."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxcontact as jc


def _scene():
    grid = jc.Grid((16, 16), 2e-3)
    material = jc.Zener(mu_inf=1.93e6, mu_0=1.93e6 / 4, tau=0.01, poisson=0.3)
    return jc.Scene(grid, jc.Sphere(10e-3), material, jnp.linspace(0.0, 0.02, 4),
                    jc.Force(0.05))


def test_progress_callback_sees_every_step_in_order_and_changes_nothing():
    seen = []
    plain = jc.solve(_scene())
    reported = jc.solve(_scene(), progress=lambda k, n: seen.append((int(k), int(n))))
    jax.block_until_ready(reported.pressure)
    assert seen == [(k, 4) for k in range(4)]
    np.testing.assert_array_equal(np.asarray(plain.pressure),
                                  np.asarray(reported.pressure))


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


@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_preconditioner_changes_the_path_not_the_solution(friction):
    # A Zener creep history (frictionless, and with uncoupled partial slip under a
    # tangential load): both paths meet rtol 1e-10 at every step, so the pressures
    # agree to ~1e-9 of the peak (stated tolerance 1e-7) and the shear to 1e-7 mu p.
    base = _scene()
    x = jc.Force(0.3 * friction * 0.05) if friction else None
    scene = jc.Scene(base.grid, base.indenter, base.material, base.times, base.normal,
                     x=x, friction=friction, coupling="none")
    sols = {pc: jc.solve(scene, rtol=1e-10, precondition=pc) for pc in (False, True)}
    plain, pre = sols[False], sols[True]
    assert bool(np.all(plain.converged)) and bool(np.all(pre.converged))
    peak = float(np.max(plain.pressure))
    np.testing.assert_allclose(pre.pressure, plain.pressure, atol=1e-7 * peak)
    np.testing.assert_allclose(pre.shear, plain.shear,
                               atol=1e-7 * max(friction, 1e-3) * peak)
    np.testing.assert_allclose(pre.approach, plain.approach, rtol=1e-8)


def test_float32_grid_with_float64_material_solves_in_float32():
    # With x64 enabled, a material built from Python floats is float64; the grid's
    # dtype decides the solve's (this used to fail in the time-stepping scan with a
    # float32/float64 carry mismatch). The float32 history follows the float64 one to
    # the float32 tolerance (rtol 1e-5): approach within 1e-4.
    base = _scene()
    grid32 = jc.Grid((16, 16), jnp.asarray(2e-3, jnp.float32))
    scene32 = jc.Scene(grid32, base.indenter, base.material, base.times, base.normal)
    sol32 = jc.solve(scene32)
    sol64 = jc.solve(base)
    assert sol32.pressure.dtype == jnp.float32
    assert bool(np.all(sol32.converged))
    np.testing.assert_allclose(np.asarray(sol32.approach), np.asarray(sol64.approach),
                               rtol=1e-4)
