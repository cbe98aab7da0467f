"""Zener (standard linear solid) half-space, in the form of the paper's Eqs. 29-30."""

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from .. import _validate
from .base import AbstractMaterial, CreepSeries
from .checks import check_arg, check_scalar, promote, require


class Zener(AbstractMaterial):
    """A Zener (standard linear solid) half-space, exactly as in the paper's Eqs. 29-30:

        G(t) = mu_0 + (mu_inf - mu_0) exp(-t / (tau mu_0 / mu_inf))           (29)
        J(t) = 1 / mu_inf + (1 / mu_0 - 1 / mu_inf) (1 - exp(-t / tau))       (30)

    **Arguments** (the subscripts are frequencies, as in the paper: `inf` = fast):

    - `mu_inf`: the INSTANTANEOUS (glassy) shear modulus `G(0)` [stress], > 0.
    - `mu_0`: the LONG-TIME (relaxed) shear modulus `G(inf)` [stress], in `(0, mu_inf]`.
    - `tau`: the RETARDATION (creep) time [time], > 0. The relaxation time is
      `tau * mu_0 / mu_inf`, shorter by the ratio `mu_inf / mu_0` (paper section 4.1;
      the paper's Table 2 calls `tau` a relaxation time, but Eqs. 29-30, which this
      class follows, make it the retardation time).
    - `poisson`: Poisson's ratio, in `(-1, 0.5]`.

    Moduli are TRUE shear moduli (the paper's Table 2 lists `mu_inf = 3.86 MPa`, twice
    the shear modulus: use `mu_inf = 1.93e6` Pa). `mu_0 = mu_inf` is elastic.
    """

    mu_inf: Float[Array, ""]
    mu_0: Float[Array, ""]
    tau: Float[Array, ""]
    poisson: Float[Array, ""]

    def __init__(self, mu_inf, mu_0, tau, poisson):
        mu_inf = check_scalar("mu_inf", check_arg(_validate.positive, "mu_inf", mu_inf))
        mu_0 = check_scalar("mu_0", check_arg(_validate.positive, "mu_0", mu_0))
        tau = check_scalar("tau", check_arg(_validate.positive, "tau", tau))
        mu_inf, mu_0, tau = promote(mu_inf, mu_0, tau)
        mu_0 = require(
            "mu_0 (the long-time modulus)",
            mu_0,
            (mu_0, mu_inf),
            lambda mu_0, mu_inf: mu_0 <= mu_inf,
            "<= mu_inf (the instantaneous modulus)",
            lambda: (f"mu_0={np.asarray(mu_0).item()!r}, "
                     f"mu_inf={np.asarray(mu_inf).item()!r}"),
        )
        self.mu_inf = mu_inf
        self.mu_0 = mu_0
        self.tau = tau
        self.poisson = check_scalar(
            "poisson", check_arg(_validate.poisson_ratio, "poisson", poisson))

    @property
    def relaxation_time(self) -> Float[Array, ""]:
        """`tau * mu_0 / mu_inf` [time]."""
        return self.tau * self.mu_0 / self.mu_inf

    def relaxation(self, t: ArrayLike) -> Float[Array, "..."]:
        t = jnp.asarray(t)
        decay = jnp.exp(-t / self.relaxation_time)
        return self.mu_0 + (self.mu_inf - self.mu_0) * decay

    def creep(self, t: ArrayLike) -> Float[Array, "..."]:
        t = jnp.asarray(t)
        return (1 / self.mu_inf
                + (1 / self.mu_0 - 1 / self.mu_inf) * -jnp.expm1(-t / self.tau))

    def creep_series(self) -> CreepSeries:
        glassy = 1 / self.mu_inf
        strength = (1 / self.mu_0 - 1 / self.mu_inf).reshape(1)
        return CreepSeries(glassy, strength, self.tau.reshape(1),
                           jnp.zeros_like(glassy))
