"""Analytic reference solutions (library objects, used by tests, benchmarks and examples)."""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float


class Hertz(eqx.Module):
    """Hertz contact of a rigid sphere (paraboloid) on an elastic half-space.

    **Arguments:** `radius` R [length], `force` W [force], `shear_modulus` G [stress],
    `poisson` nu. The plane-strain modulus is `E* = 2 G / (1 - nu)`.

    Contact radius `a = (3 W R / (4 E*))^(1/3)`, peak pressure
    `p0 = 3 W / (2 pi a^2)`, approach `delta = a^2 / R`,
    pressure `p(r) = p0 sqrt(1 - r^2 / a^2)` (Johnson 1985, section 4.2).
    """

    radius: Float[Array, ""]
    force: Float[Array, ""]
    shear_modulus: Float[Array, ""]
    poisson: Float[Array, ""]

    @property
    def effective_modulus(self):
        return 2 * self.shear_modulus / (1 - self.poisson)

    @property
    def contact_radius(self):
        return (3 * self.force * self.radius / (4 * self.effective_modulus)) ** (1 / 3)

    @property
    def peak_pressure(self):
        a = self.contact_radius
        return 3 * self.force / (2 * jnp.pi * a * a)

    @property
    def approach(self):
        return self.contact_radius**2 / self.radius

    def pressure(self, r):
        a = self.contact_radius
        return self.peak_pressure * jnp.sqrt(jnp.maximum(1 - (r / a) ** 2, 0.0))
