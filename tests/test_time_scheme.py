"""Stability of the time schemes under long steps, and the warning that guards the
piecewise-constant (paper's) scheme.

One exponential creep arm: the constant scheme's step-to-step map has the eigenvalue
`1 - (J_inf / J_0) (1 - exp(-dt / tau))` (`_history.constant_scheme_amplification`),
so once `(J_inf / J_0) (1 - exp(-dt / tau)) > 2` the creep approach oscillates from
step to step instead of rising monotonically to its long-time value, although every
step converges. The piecewise-linear scheme stays monotone. `jc.solve` warns
(`jc.TimeStepWarning`) for the constant scheme exactly there. Here J_inf / J_0 = 10:
J(dt) / J(0) = 2.5 is stable (10 x 1.5 / 9 = 1.67), 3.5 is not (2.78).
"""

import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxcontact as jc
from jaxcontact._history import constant_scheme_amplification


R, W, G, NU = 10e-3, 0.15, 1.93e6, 0.3
A0 = float(jc.Hertz(R, W, G, NU).contact_radius)
# s, the Zener creep (retardation) time: J(t) = J_inf - (J_inf - J_0) e^(-t/tau)
TAU = 0.01
MATERIAL = jc.Zener(mu_inf=G, mu_0=G / 10, tau=TAU, poisson=NU)


def _times(ratio, nt=24):
    """Uniform steps with J(dt) / J(0) = ratio (J_inf / J_0 = 10)."""
    dt = TAU * np.log(9.0 / (10.0 - ratio))
    return jnp.arange(nt) * dt


def _approach(ratio, scheme):
    grid = jc.Grid((24, 24), 10 * A0)
    scene = jc.Scene(grid, jc.Sphere(R), MATERIAL, _times(ratio), jc.Force(W))
    sol = jc.solve(scene, solver=jc.Rounds(), scheme=scheme)  # the grid's stepping
    assert bool(np.all(np.asarray(sol.converged)))
    return np.asarray(sol.approach)


def _oscillations(x):
    """Number of sign changes of the step-to-step increments."""
    return int(np.sum(np.diff(np.sign(np.diff(x))) != 0))


def test_amplification_of_one_arm_is_the_closed_form():
    series = MATERIAL.creep_series()
    for ratio in (1.5, 2.5, 3.5, 9.0):
        dt = float(_times(ratio)[1])
        expected = abs(1 - 10 * (1 - np.exp(-dt / TAU)))
        np.testing.assert_allclose(constant_scheme_amplification(series, dt), expected,
                                   rtol=1e-10)


def test_time_step_amplification_is_the_worst_step_and_decides_the_warning():
    """`jc.time_step_amplification`: the largest closed-form radius over the distinct
    steps (a stable step and an unstable one in one time axis), 0 where there is no
    history; the warning of `jc.solve` fires exactly above 1."""
    stable, unstable = float(_times(2.5)[1]), float(_times(3.5)[1])
    times = jnp.concatenate([jnp.arange(4) * stable, 3 * stable + unstable
                             + jnp.arange(3) * stable])
    expected = abs(1 - 10 * (1 - np.exp(-unstable / TAU)))
    np.testing.assert_allclose(jc.time_step_amplification(MATERIAL, times), expected,
                               rtol=1e-10)
    assert jc.time_step_amplification(MATERIAL, _times(2.5)) < 1.0
    assert jc.time_step_amplification(jc.Elastic(G, NU), times) == 0.0
    assert jc.time_step_amplification(MATERIAL, times[:1]) == 0.0
    with pytest.raises(TypeError, match="concrete"):
        jax.jit(lambda t: jc.time_step_amplification(MATERIAL, t))(times)


def test_zener_creep_ratio_over_one_step():
    """`tau` of `jc.Zener` is the creep time: J(dt)/J(0) = 10 - 9 exp(-dt/tau)."""
    times = _times(3.5)
    ratio = float(MATERIAL.creep(times[1]) / MATERIAL.creep(0.0))
    np.testing.assert_allclose(ratio, 3.5, rtol=1e-12)


def test_constant_scheme_is_monotone_below_the_limit_and_silent():
    with warnings.catch_warnings():
        warnings.simplefilter("error", jc.TimeStepWarning)
        approach = _approach(2.5, "constant")
    assert _oscillations(approach) == 0


def test_constant_scheme_oscillates_beyond_the_limit_and_warns():
    with pytest.warns(jc.TimeStepWarning, match="scheme=\"linear\""):
        approach = _approach(3.5, "constant")
    # Long-time Hertz approach with the relaxed modulus mu_0 = G / 10.
    relaxed = float(jc.Hertz(R, W, G / 10, NU).approach)
    late = approach[len(approach) // 2:]
    assert _oscillations(late) >= len(late) - 3  # every increment flips sign
    assert np.max(np.abs(late / relaxed - 1)) > 1e-3  # and it does not settle


def test_linear_scheme_is_stable_at_the_same_step_and_silent():
    with warnings.catch_warnings():
        warnings.simplefilter("error", jc.TimeStepWarning)
        approach = _approach(3.5, "linear")
    assert _oscillations(approach) == 0
    relaxed = float(jc.Hertz(R, W, G / 10, NU).approach)
    # 23 steps of 2.1 tau: fully relaxed, to the grid's discretisation of Hertz.
    np.testing.assert_allclose(approach[-1], relaxed, rtol=2e-2)


def test_the_warning_is_given_inside_jit_too():
    """A concrete material's scene solved inside `jit` (whose trace stages every
    array operation): the check still evaluates the creep series at trace time and
    warns at the unstable step (it once failed there, converting a traced series),
    and says nothing at the stable one. Solved on rings: the check runs before any
    solver."""
    def solve_in_jit(ratio):
        grid = jc.Grid((8, 8), 10 * A0)
        scene = jc.Scene(grid, jc.Sphere(R), MATERIAL, _times(ratio, nt=6),
                         jc.Force(W))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", jc.TimeStepWarning)
            approach = jax.jit(lambda: jc.solve(
                scene, solver=jc.RingPolonskyKeer()).approach)()
        assert bool(np.all(np.isfinite(np.asarray(approach))))
        return [w for w in caught if issubclass(w.category, jc.TimeStepWarning)]

    assert solve_in_jit(2.5) == []
    (warned,) = solve_in_jit(3.5)
    assert "amplification" in str(warned.message)
