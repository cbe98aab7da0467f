"""The abstract material: a linear (visco)elastic half-space with constant Poisson
ratio."""

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
    """A linear viscoelastic, isotropic half-space with a time-independent Poisson
    ratio.

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


def check_in_dtype(material: AbstractMaterial, dtype, span) -> None:
    """Validate `material` as a solve in `dtype` sees it (concrete values only).

    `jc.solve` casts every floating leaf of the material to the grid's dtype. A material
    valid in float64 can stop being valid after that cast: a modulus that overflows,
    relaxation times that round to the same value. It is therefore rebuilt from its cast
    fields (so its own constructor checks run again, in `dtype`), and its creep
    compliance `J(0)` and `J(span)` [1/stress] (`span`: the scene's duration [time];
    `J` is non-decreasing, so these are its extremes over the scene) must lie in
    `[sqrt(tiny), 1 / sqrt(tiny)]` of `dtype` (float32: about `[1.1e-19, 9.2e18]`): the
    contact solve forms products and squares of compliances, moduli and pressures, and
    outside that range they underflow or overflow (float32 `jc.Elastic(1e38, 0.3)` gave
    a NaN approach flagged converged).

    **Raises:** `ValueError` naming the dtype, the parameter and its value.
    """
    import dataclasses

    import jax
    import numpy as np

    from .. import _validate

    if _validate.is_traced((material, span)):
        return
    dtype = jnp.dtype(dtype)
    name = dtype.name

    def cast(leaf):
        if hasattr(leaf, "dtype") and jnp.issubdtype(leaf.dtype, jnp.floating):
            return jnp.asarray(leaf).astype(dtype)
        return leaf

    fields = {f.name: getattr(material, f.name) for f in dataclasses.fields(material)}
    cast_fields = {k: jax.tree_util.tree_map(cast, v) for k, v in fields.items()}
    for key, value in cast_fields.items():
        for leaf in jax.tree_util.tree_leaves(value):
            if hasattr(leaf, "dtype") and not np.isfinite(np.asarray(leaf)).all():
                raise ValueError(
                    f"material {key}={np.asarray(fields[key]).tolist()!r} overflows in "
                    f"{name} (the grid's dtype, which the solve uses): restate the "
                    "scene in other units or solve in float64"
                )
    try:
        with jax.ensure_compile_time_eval():
            rebuilt = type(material)(**cast_fields)
    except TypeError:  # a material whose constructor does not take its fields
        rebuilt = jax.tree_util.tree_map(cast, material)
    except ValueError as exc:
        raise ValueError(
            f"material in {name} (the grid's dtype, which the solve uses): {exc}"
        ) from None
    finfo = jnp.finfo(dtype)
    low = float(np.sqrt(finfo.tiny))
    high = 1 / low
    del rebuilt
    with jax.ensure_compile_time_eval():  # in the material's own (wider) precision
        compliances = np.asarray(material.creep(jnp.asarray([0.0, float(span)])))
    for label, value in zip(("J(0)", f"J({float(span):.4g})"), compliances):
        value = float(value)
        if not (np.isfinite(value) and low <= value <= high):
            modulus = 1 / value if value else float("inf")
            given = ", ".join(
                f"{k}={np.asarray(v).tolist()!r}" for k, v in fields.items()
            )
            raise ValueError(
                f"material {type(material).__name__}({given}): the creep compliance "
                f"{label} = {value:.4g} [1/stress] (a "
                f"modulus of {modulus:.4g}) is outside the range [{low:.2g}, "
                f"{high:.2g}] that a solve in {name} (the grid's dtype) can represent "
                "with its products and squares: restate the scene in other units "
                "(e.g. MPa and mm) or solve in float64"
            )
