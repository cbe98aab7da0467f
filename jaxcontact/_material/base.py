"""The abstract material: a linear (visco)elastic half-space with constant Poisson ratio."""

import abc

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float


class AbstractMaterial(eqx.Module):
    """A linear viscoelastic, isotropic half-space with a time-independent Poisson ratio.

    Because Poisson's ratio is constant, every surface influence kernel is the elastic
    kernel for unit shear modulus times ONE scalar function of time: the shear creep
    compliance `J(t)`. Subclasses provide the shear relaxation modulus `G(t)` and
    `J(t)`, which form a Laplace pair (`s^2 G^(s) J^(s) = 1`).

    Moduli are TRUE shear moduli (the elastic plane-strain modulus is
    `E* = 2 G / (1 - nu)`).
    """

    poisson: eqx.AbstractVar[Float[Array, ""]]

    @abc.abstractmethod
    def relaxation(self, t: ArrayLike) -> Float[Array, "..."]:
        """Shear relaxation modulus `G(t)` [stress] at times `t >= 0` [time]."""

    @abc.abstractmethod
    def creep(self, t: ArrayLike) -> Float[Array, "..."]:
        """Shear creep compliance `J(t)` [1/stress] at times `t >= 0` [time]."""

    @property
    def instantaneous_compliance(self) -> Float[Array, ""]:
        """`J(0)`, the compliance of a load applied instantaneously [1/stress]."""
        return self.creep(jnp.zeros((), dtype=jnp.result_type(self.poisson)))
