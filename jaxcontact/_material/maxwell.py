"""Maxwell fluid half-space: a spring and a dashpot in series (paper Eqs. 22-23)."""

import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from .. import _validate
from .base import AbstractMaterial, CreepSeries
from .checks import check_arg, check_scalar, promote


class Maxwell(AbstractMaterial):
    """A Maxwell (viscoelastic fluid) half-space.

    **Arguments:**

    - `shear_modulus`: the spring's shear modulus `G` [stress], > 0 (the TRUE shear
      modulus; the paper's Table 1 lists twice this value).
    - `viscosity`: the dashpot's shear viscosity `eta` [stress time], > 0.
    - `poisson`: Poisson's ratio, in `(-1, 0.5]`.

    `relaxation(t) = G exp(-t / tau)` with the relaxation time `tau = eta / G`, and
    `creep(t) = 1 / G + t / eta`.
    """

    shear_modulus: Float[Array, ""]
    viscosity: Float[Array, ""]
    poisson: Float[Array, ""]

    def __init__(self, shear_modulus, viscosity, poisson):
        shear_modulus = check_scalar("shear_modulus", check_arg(
            _validate.positive, "shear_modulus", shear_modulus))
        viscosity = check_scalar(
            "viscosity", check_arg(_validate.positive, "viscosity", viscosity))
        self.shear_modulus, self.viscosity = promote(shear_modulus, viscosity)
        self.poisson = check_scalar(
            "poisson", check_arg(_validate.poisson_ratio, "poisson", poisson))

    @property
    def relaxation_time(self) -> Float[Array, ""]:
        """`tau = eta / G` [time]."""
        return self.viscosity / self.shear_modulus

    def relaxation(self, t: ArrayLike) -> Float[Array, "..."]:
        t = jnp.asarray(t)
        return self.shear_modulus * jnp.exp(-t * (self.shear_modulus / self.viscosity))

    def creep(self, t: ArrayLike) -> Float[Array, "..."]:
        t = jnp.asarray(t)
        return 1 / self.shear_modulus + t / self.viscosity

    def creep_series(self) -> CreepSeries:
        glassy = 1 / self.shear_modulus
        empty = jnp.zeros((0,), glassy.dtype)
        return CreepSeries(glassy, empty, empty, 1 / self.viscosity)
