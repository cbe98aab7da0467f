"""The hereditary integral: recursion against the direct sum (paper Eqs. 12-13, 19)."""

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np
import pytest
from scipy import integrate

from jaxcontact._history import DirectHistory, RecursiveHistory


class Series(NamedTuple):
    glassy: jnp.ndarray
    strengths: jnp.ndarray
    times: jnp.ndarray
    fluidity: jnp.ndarray


SERIES = Series(
    glassy=jnp.asarray(0.7),
    strengths=jnp.asarray([0.2, 0.05, 0.4]),
    times=jnp.asarray([0.3, 2.0, 11.0]),
    fluidity=jnp.asarray(0.01),
)


def creep(t):
    t = jnp.asarray(t)
    lam = SERIES.times.reshape((1,) * t.ndim + (-1,))
    amp = SERIES.strengths.reshape(lam.shape)
    return (SERIES.glassy + jnp.sum(amp * (1 - jnp.exp(-t[..., None] / lam)), -1)
            + SERIES.fluidity * t)


def random_history(nt=14, shape=(3, 4, 5), seed=0):
    rng = np.random.default_rng(seed)
    times = jnp.asarray(np.cumsum(rng.uniform(0.05, 1.5, nt)) - 0.3)
    tractions = jnp.asarray(rng.normal(size=(nt, *shape)))
    return times, tractions


def displacement_sequence(scheme, times, tractions):
    """Run a history scheme over a given traction sequence: J_step tau_k + history_k."""
    out, state = [], scheme.init(tractions.shape[1:], tractions.dtype)
    prev = jnp.zeros_like(tractions[0])
    for k in range(times.shape[0]):
        dt = times[k] - times[k - 1] if k > 0 else jnp.asarray(0.0)
        prep = scheme.prepare(state, prev, k, dt)
        out.append(prep.compliance * tractions[k] + prep.traction)
        state = scheme.update(state, prev, tractions[k], k, dt)
        prev = tractions[k]
    return jnp.stack(out)


def test_recursion_equals_direct_sum():
    times, tractions = random_history()
    rec = displacement_sequence(RecursiveHistory(SERIES, "constant"), times, tractions)
    direct = displacement_sequence(DirectHistory(creep, times), times, tractions)
    # Independent reference: the paper's double sum, written out.
    increments = jnp.diff(tractions, axis=0, prepend=0.0)
    ref = jnp.stack([
        sum(creep(times[k] - times[n]) * increments[n] for n in range(k + 1))
        for k in range(times.shape[0])
    ])
    scale = float(jnp.abs(ref).max())
    assert float(jnp.abs(direct - ref).max()) / scale < 1e-13
    assert float(jnp.abs(rec - ref).max()) / scale < 1e-10


def test_linear_scheme_equals_piecewise_linear_integral():
    times, tractions = random_history(nt=9, shape=(2, 3), seed=1)
    rec = displacement_sequence(RecursiveHistory(SERIES, "linear"), times, tractions)
    increments = np.diff(np.asarray(tractions), axis=0, prepend=0.0)
    t = np.asarray(times)
    j = lambda s: float(creep(s))  # noqa: E731
    for k in range(t.shape[0]):
        # First increment: a jump at t_0; later ones spread uniformly over the step.
        total = j(t[k] - t[0]) * increments[0]
        for n in range(1, k + 1):
            weight = integrate.quad(lambda s: j(t[k] - s), t[n - 1], t[n], epsabs=1e-14,
                                    epsrel=1e-13)[0] / (t[n] - t[n - 1])
            total = total + weight * increments[n]
        np.testing.assert_allclose(np.asarray(rec[k]), total, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("scheme", ["constant", "linear"])
def test_history_memory_is_independent_of_steps(scheme):
    state = RecursiveHistory(SERIES, scheme).init((3, 8, 8), jnp.float64)
    sizes = [leaf.size for leaf in state]
    # m + 1 fields of (3, nx, ny), whatever the number of steps.
    assert sum(sizes) == (SERIES.strengths.shape[0] + 1) * 3 * 64
