"""Loading programs: a prescribed force or displacement as a function of time."""

from collections.abc import Callable

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from . import _validate


def _one_dim(name, value):
    value = _validate.finite(name, value)
    if value.ndim > 1:
        raise ValueError(
            f"{name} must be a scalar or a 1-D array (one value per time), got shape "
            f"{value.shape}"
        )
    return value


def _program_values(name, value, times):
    if callable(value):
        out = jnp.asarray(value(times), dtype=times.dtype)
        out = jnp.broadcast_to(out, times.shape) if out.ndim == 0 else out
    else:
        out = jnp.asarray(value, dtype=times.dtype)
        if out.ndim == 0:
            out = jnp.broadcast_to(out, times.shape)
    if out.shape != times.shape:
        raise ValueError(
            f"{name} must be a scalar, an array with one value per time "
            f"({times.shape[0]}), or a callable of t; got shape {out.shape}"
        )
    return out


class Force(eqx.Module):
    """A prescribed force [force] in one direction (load control).

    **Arguments:**

    - `value`: a scalar (constant in time), an array with one value per entry of the
      scene's `times`, or a callable `f(t)` evaluated on the `times` array.
    """

    value: Float[Array, "..."] | Callable

    def __init__(self, value):
        self.value = value if callable(value) else _one_dim("Force value", value)

    def values(self, times: Float[Array, " nt"]) -> Float[Array, " nt"]:
        """The force at each time, shape `(nt,)`."""
        return _program_values("Force value", self.value, times)


class Displacement(eqx.Module):
    """A prescribed rigid-body displacement [length] in one direction.

    Normal direction: the approach `delta_z` of the indenter (positive into the body).
    Tangential directions: the rigid tangential displacement `delta_x` or `delta_y`.

    **Arguments:**

    - `value`: a scalar, an array with one value per time, or a callable `f(t)`.
    """

    value: Float[Array, "..."] | Callable

    def __init__(self, value):
        self.value = (
            value if callable(value) else _one_dim("Displacement value", value)
        )

    def values(self, times: Float[Array, " nt"]) -> Float[Array, " nt"]:
        """The displacement at each time, shape `(nt,)`."""
        return _program_values("Displacement value", self.value, times)
