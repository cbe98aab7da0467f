"""Linear elastic half-space."""

import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from .. import _validate
from .base import AbstractMaterial, CreepSeries


class Elastic(AbstractMaterial):
    """A linear elastic half-space.

    **Arguments:**

    - `shear_modulus`: shear modulus `G` [stress], > 0.
    - `poisson`: Poisson's ratio `nu`, in `(-1, 0.5]`.

    `relaxation(t) = G` and `creep(t) = 1 / G` for all `t`.
    """

    shear_modulus: Float[Array, ""]
    poisson: Float[Array, ""]

    def __init__(self, shear_modulus, poisson):
        shear_modulus = _validate.positive("shear_modulus", shear_modulus)
        self.shear_modulus = _validate.scalar("shear_modulus", shear_modulus)
        self.poisson = _validate.scalar(
            "poisson", _validate.poisson_ratio("poisson", poisson))

    def relaxation(self, t: ArrayLike) -> Float[Array, "..."]:
        return jnp.broadcast_to(self.shear_modulus, jnp.shape(t))

    def creep(self, t: ArrayLike) -> Float[Array, "..."]:
        return jnp.broadcast_to(1 / self.shear_modulus, jnp.shape(t))

    def creep_series(self) -> CreepSeries:
        glassy = 1 / self.shear_modulus
        empty = jnp.zeros((0,), dtype=glassy.dtype)
        return CreepSeries(glassy, empty, empty, jnp.zeros((), dtype=glassy.dtype))
