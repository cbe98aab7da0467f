"""Argument checks shared by the viscoelastic materials (`Prony`, `Maxwell`,
`Zener`): one of `_validate`'s checks applied to a concrete value or a tracer alike,
a condition across several arguments, a scalar, and the parameters promoted to one
float dtype."""

import contextlib

import jax
import jax.numpy as jnp
import numpy as np

from .. import _validate


def _eager(*values):
    """Evaluate eagerly when every value is concrete, even while tracing: inside `jit`,
    operations on concrete arrays are otherwise staged and could not be inspected.
    Traced values are left to `eqx.error_if` (which must not run eagerly)."""
    if _validate.is_traced(values):
        return contextlib.nullcontext()
    return jax.ensure_compile_time_eval()


def check_arg(check, name: str, value) -> jax.Array:
    """Apply one of the `_validate` checks (concrete: ValueError; traced: error_if)."""
    with _eager(value):
        return check(name, value)


def require(name: str, value, inputs, ok, what: str, got) -> jax.Array:
    """Check a condition `ok(*inputs)` that may involve several arguments.

    Concrete inputs: a ValueError naming `name`, with `got()` describing the values.
    Traced inputs: `eqx.error_if` attached to `value`, so the returned array must be
    used.
    """
    if _validate.is_traced(inputs):
        return _validate.runtime_check(value, ~jnp.all(ok(*inputs)),
                                       f"{name} must be {what}")
    with jax.ensure_compile_time_eval():
        good = bool(np.all(np.asarray(ok(*inputs))))
    if not good:
        raise ValueError(f"{name} must be {what}, got {got()}")
    return value


def check_scalar(name: str, value: jax.Array) -> jax.Array:
    if jnp.ndim(value) != 0:
        raise ValueError(
            f"{name} must be a scalar, got an array of shape {jnp.shape(value)} "
            "(batch materials with jax.vmap)"
        )
    return value


def promote(*values):
    dtype = jnp.result_type(*values)
    with _eager(values):
        return tuple(v.astype(dtype) for v in values)
