"""The abstract material: a linear (visco)elastic half-space with constant Poisson ratio."""

import abc
from typing import NamedTuple

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float


class CreepSeries(NamedTuple):
    """The shear creep compliance as a constant, exponentials and a linear term:

        J(t) = glassy + sum_i strengths[i] * (1 - exp(-t / times[i])) + fluidity * t

    - `glassy`: `J(0) > 0`, the instantaneous compliance [1/stress].
    - `strengths`: shape `(m,)`, `>= 0` [1/stress]; `m` is static and may be 0.
    - `times`: shape `(m,)`, `> 0`, the retardation times [time].
    - `fluidity`: `>= 0`, one over the viscosity of a fluid, `0` for a solid
      [1/(stress time)].

    Every value is a JAX array, differentiable with respect to the material's
    parameters. A mode with `strengths[i] == 0` is inert (its time is arbitrary).
    """

    glassy: Float[Array, ""]
    strengths: Float[Array, " m"]
    times: Float[Array, " m"]
    fluidity: Float[Array, ""]

    def __call__(self, t: ArrayLike) -> Float[Array, "..."]:
        """Evaluate `J(t)` at times `t >= 0` (any shape)."""
        t = jnp.asarray(t)
        dtype = jnp.result_type(t, self.glassy)
        t = t.astype(dtype)
        shape = (1,) * t.ndim + self.times.shape
        x = t[..., None] / self.times.reshape(shape)
        retarded = jnp.sum(self.strengths.reshape(shape) * -jnp.expm1(-x), axis=-1)
        return self.glassy + retarded + self.fluidity * t


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

    @abc.abstractmethod
    def creep_series(self) -> CreepSeries:
        """`J(t)` as a constant, exponentials and a linear term (see `CreepSeries`).

        The time stepper carries the hereditary integral with one internal variable
        per retardation time, exactly.
        """

    @property
    def instantaneous_compliance(self) -> Float[Array, ""]:
        """`J(0)`, the compliance of a load applied instantaneously [1/stress]."""
        return self.creep(jnp.zeros((), dtype=jnp.result_type(self.poisson)))
