"""Argument checks that work on concrete values and on tracers alike.

Concrete values are checked at construction with a `ValueError` that names the
argument and the bad value. Traced values (inside `jit`/`vmap`/`grad`) cannot be
inspected in Python, so they are checked with `eqx.error_if`, which raises at run
time (see `EQX_ON_ERROR`).
"""

import contextlib
import contextvars
import re

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np


_RUNTIME_MESSAGE = re.compile(r"EquinoxRuntimeError: (.+)")


def runtime_error_message(exc: BaseException) -> str | None:
    """The message of a failed `eqx.error_if` check carried by `exc`, or `None`.

    What a user sees of a traced check depends on the `jit` around it (measured with
    jax 0.10.2, equinox 0.13.8): under `jax.jit` a `JaxRuntimeError` whose first line
    is "INTERNAL: CpuCallback error calling callback: Traceback ...", the message on a
    line "_EquinoxRuntimeError: MESSAGE" after ~50 lines of stack; under
    `eqx.filter_jit` (and so `jc.solve` called directly) an `EquinoxRuntimeError` whose
    first line is "Above is the stack outside of JIT...", the message on the line
    "equinox.EquinoxRuntimeError: MESSAGE". Both carry the message after the text
    "EquinoxRuntimeError: "; this finds it.
    """
    match = _RUNTIME_MESSAGE.search(str(exc))
    return None if match is None else match.group(1).strip()


@contextlib.contextmanager
def clear_runtime_errors():
    """Re-raise a failed run-time check (`eqx.error_if`) as a `ValueError` whose first
    line is its message: `with clear_runtime_errors(): out = jitted(...)`.

    JAX cannot put the message first itself (it formats the callback's stack before
    it), so the boundary that runs the compiled program catches and re-raises. Other
    exceptions pass through unchanged. (`EQX_ON_ERROR=nan` turns the checks into NaN
    outputs instead; `EQX_ON_ERROR=breakpoint` opens a debugger.)
    """
    try:
        yield
    except Exception as exc:
        message = runtime_error_message(exc)
        if message is None:
            raise
        raise ValueError(
            f"{message}\n(a run-time check of jaxcontact, eqx.error_if: a traced input "
            "or a step that did not converge)"
        ) from None


_TRUSTED = contextvars.ContextVar("jaxcontact_trusted_inputs", default=False)


@contextlib.contextmanager
def trusted_inputs(trusted: bool = True):
    """Inside this context, traced inputs are not checked at run time: for a caller
    whose traced values are valid by construction (a fit's material from its
    coordinates, positive by its parametrisation; a scene checked concretely before
    tracing). Concrete values are still checked. Its programs then hold no
    `eqx.error_if` (a host callback), so JAX's persistent compilation cache can store
    them: a program that calls back into Python is never written to it.

    A jitted function's trace is cached without this context in its key: `jc.solve`
    turns its scene checks off by a static argument and traces its own program with
    `trusted_inputs(False)`, so no user's call reuses an unchecked trace."""
    token = _TRUSTED.set(trusted)
    try:
        yield
    finally:
        _TRUSTED.reset(token)


def checks_traced_inputs() -> bool:
    """Whether traced inputs get run-time checks here (not inside `trusted_inputs`)."""
    return not _TRUSTED.get()


def runtime_check(value, bad, message: str):
    """`eqx.error_if(value, bad, message)`: the run-time check of a traced input, or
    `value` unchanged inside `trusted_inputs`."""
    if not checks_traced_inputs():
        return value
    return eqx.error_if(value, bad, message)


def is_traced(x) -> bool:
    """True if any leaf of `x` is a JAX tracer (we are inside a transformation)."""
    return any(isinstance(leaf, jax.core.Tracer)
               for leaf in jax.tree_util.tree_leaves(x))


def check_int(name: str, value, minimum: int) -> int:
    """`value` as an `int`, or a `TypeError` (not an integer; booleans refused) or a
    `ValueError` (below `minimum`) naming `name` and the value."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an integer, got {value!r}")
    if value < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {value!r}")
    return int(value)


def as_float_array(name: str, value, dtype=None) -> jax.Array:
    """Convert `value` to a floating JAX array, rejecting complex and non-numeric
    input."""
    if isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be a real number, got the boolean {value!r}")
    if not is_traced(value):
        try:
            arr = np.asarray(value)
        except Exception as exc:  # pragma: no cover - exotic input
            raise TypeError(
                f"{name} must be a real number or array, got {value!r}") from exc
        if arr.dtype == object or arr.dtype.kind not in "biuf":
            raise TypeError(f"{name} must be a real number or array, got {value!r}")
    if dtype is None:
        dtype = jnp.result_type(float)
        if hasattr(value, "dtype") and jnp.issubdtype(value.dtype, jnp.floating):
            dtype = value.dtype
    return jnp.asarray(value, dtype=dtype)


def _check(name: str, value: jax.Array, bad, what: str) -> jax.Array:
    """Raise (concrete) or attach a runtime error (traced) where `bad(value)` holds."""
    mask = bad(value)
    # Inside `jit` even a concrete array's comparison is staged: check the result.
    if is_traced(value) or is_traced(mask):
        return runtime_check(value, mask, f"{name} must be {what}")
    bad_mask = np.asarray(mask)
    if bad_mask.any():
        shown = np.asarray(value)
        shown = shown.item() if shown.size == 1 else shown
        raise ValueError(f"{name} must be {what}, got {shown!r}")
    return value


def finite(name: str, value) -> jax.Array:
    value = as_float_array(name, value)
    return _check(name, value, lambda v: ~jnp.isfinite(v), "finite (no NaN or inf)")


def positive(name: str, value) -> jax.Array:
    value = as_float_array(name, value)
    return _check(name, value, lambda v: ~(jnp.isfinite(v) & (v > 0)), "finite and > 0")


def non_negative(name: str, value) -> jax.Array:
    value = as_float_array(name, value)
    return _check(name, value, lambda v: ~(jnp.isfinite(v) & (v >= 0)),
                  "finite and >= 0")


def open_interval(name: str, value, low: float, high: float,
                  what: str = "") -> jax.Array:
    """`value` in `(low, high)`, else a `ValueError` naming `name`, the value and
    `what` the bounds mean."""
    value = as_float_array(name, value)
    return _check(name, value, lambda v: ~((v > low) & (v < high)),
                  f"in ({low:g}, {high:g}){what}")


def poisson_ratio(name: str, value) -> jax.Array:
    value = as_float_array(name, value)
    return _check(
        name, value, lambda v: ~((v > -1) & (v <= 0.5)), "in the interval (-1, 0.5]"
    )


def scalar(name: str, value: jax.Array) -> jax.Array:
    """Reject arrays of rank > 0 (under `vmap` a batched scalar has rank 0)."""
    if jnp.ndim(value) != 0:
        raise ValueError(
            f"{name} must be a scalar, got an array of shape {jnp.shape(value)}"
        )
    return value


def positive_int(name: str, value) -> int:
    """A Python integer >= 1 (booleans rejected): iteration bounds and the like."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be a positive integer, got {value!r}")
    if value < 1:
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def tolerance(name: str, value) -> float:
    """A Python real number in the open interval (0, 1)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(
        value, (int, float, np.integer, np.floating)
    ):
        raise TypeError(f"{name} must be a real number in (0, 1), got {value!r}")
    if not (0 < value < 1):
        raise ValueError(f"{name} must be in (0, 1), got {value!r}")
    return float(value)


class TimeStepWarning(UserWarning):
    """A time step is too long for the piecewise-constant (paper's) time scheme.

    With tractions piecewise constant in time, the step-to-step update has an
    alternating mode that grows when `dt` is long against the material's retardation
    times (one arm: when `(J_inf / J_0) (1 - exp(-dt / lambda)) > 2`). The approach and
    the contact radius then oscillate from step to step instead of creeping, although
    every step converges. Use `scheme="linear"` (stable for any step) or shorter steps.
    """


class EdgeContactWarning(UserWarning):
    """The contact reaches (or is expected to reach) the edge of a non-periodic grid.

    The solution of an isolated contact is then truncated by the domain and wrong:
    enlarge the grid's `size` (keep the cell size) or lower the load.
    """
