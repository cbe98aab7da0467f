r"""The contact residuals, defined once: every solver's convergence test uses them.

- `gap_residual`: the normal contact conditions. With `raw = h + u_z` (effective gap
  plus normal displacement) and the approach `delta` (prescribed, or under load
  control the mean of `raw` over the contact, its least-squares multiplier), the gap
  is `g = raw - delta`; the violation is `g` on contact cells and `min(g, 0)` (the
  penetration) elsewhere; the residual is `||violation||_2 / scale`.
- `rigid_tangential_displacement`: `delta_t` per direction: prescribed, or under load
  control the mean of `w = u_t + b` over the stick cells, or, with no stick cell, the
  least-squares fit of the slip directions (`tangential.slip_multiplier`).
- `coulomb_residual`: the incremental Coulomb law. The violation is the slip
  increment `ds = w - delta_t` on stick cells and its part not opposite to `q` on
  slip cells (given by the solver: each keeps its own unit vectors); the residual is
  `max(||violation||_2 / scale, max_d |A sum q_d - F_d| / (mu W))`, the second term
  over the load-controlled directions only, and zero where nothing can carry shear.

The `scale`s are the solver's: `||C K p||` for the normal solve (the displacement of
the pressure), `||w - b|| + ||b||_contact` for the tangential one. The implicit
adjoint's `F(x, theta)` (`implicit.py`) is the root function of the same conditions on
frozen active sets, a different object (smooth, with the sets fixed).
"""

import jax.numpy as jnp

from .base import safe_div
from .tangential import slip_multiplier


def masked_mean(values, mask):
    """Mean of `values` `(..., nx, ny)` over the `mask` cells `(nx, ny)` (0 where none),
    summed as deviations from the largest masked value: a plain float32 sum of a few
    hundred values drifts by tens of eps of their size, while the deviations at a
    converged contact are tiny, and so is their sum's error (notes/round_off.md)."""
    count = jnp.sum(mask)
    ref = jnp.max(jnp.where(mask, values, -jnp.inf), axis=(-2, -1))
    ref = jnp.where(count > 0, ref, 0.0)
    deviation = jnp.where(mask, values - ref[..., None, None], 0.0)
    return ref + safe_div(jnp.sum(deviation, axis=(-2, -1)), count)


def gap_residual(raw, contact, load_control: bool, target, scale):
    """`(g, delta, residual)` of the normal conditions (module docs): `raw = h + u_z`
    [length] `(nx, ny)`, `contact` the cells with `p > 0`, `target` the prescribed
    approach [length] (ignored under load control), `scale` [length]."""
    if load_control:
        delta = jnp.where(jnp.any(contact), masked_mean(raw, contact), jnp.min(raw))
    else:
        delta = target
    g = raw - delta
    violation = jnp.where(contact, g, jnp.minimum(g, 0))
    num = jnp.sqrt(jnp.sum(violation * violation))
    residual = jnp.where(num == 0, 0.0, num / jnp.where(scale > 0, scale, jnp.inf))
    # A non-zero violation with zero displacement (p = 0 but penetration) is not
    # converged.
    residual = jnp.where((num > 0) & (scale == 0), jnp.inf, residual)
    return g, delta, residual


def rigid_tangential_displacement(w, stick, q_hat, contact, force_control, target):
    """`delta_t` `(nd,)` [length] (module docs): `w = u_t + b` `(nd, nx, ny)`, the
    `stick` and `contact` cells, the unit shear directions `q_hat` (0 where `q = 0`),
    `force_control` `(nd,)` bool, `target` (`delta_t` of displacement-controlled
    directions)."""
    n_stick = jnp.sum(stick)
    mean_stick = safe_div(jnp.sum(jnp.where(stick[None], w, 0), axis=(-2, -1)), n_stick)
    all_slip = slip_multiplier(w, q_hat, contact, force_control, target)
    multiplier = jnp.where(n_stick > 0, mean_stick, all_slip)
    return jnp.where(jnp.asarray(force_control), multiplier, target)


def coulomb_residual(ds, slip_violation, stick, contact, scale, load, target,
                     force_control, bound_total, sliding=None):
    """The Coulomb residual (module docs): `ds` `(nd, nx, ny)` slip increment and
    `slip_violation` (its part not opposite to `q`) [length], `stick` and `contact`
    cells, `scale` [length], `load` `(nd,)` the carried `A sum q` and `target` the
    asked forces [force], `force_control` `(nd,)` bool, `bound_total` `mu W` [force];
    `sliding` (optional): gross sliding under load control, where it is zero."""
    violation = jnp.where(stick[None], ds, jnp.where(contact[None], slip_violation, 0))
    num = jnp.sqrt(jnp.sum(violation * violation))
    residual = jnp.where(num == 0, 0.0, safe_div(num, scale))
    residual = jnp.where((num > 0) & (scale == 0), jnp.inf, residual)
    load_error = jnp.abs(load - target)
    load_error = jnp.where(jnp.asarray(force_control),
                           safe_div(load_error, bound_total), 0.0)
    residual = jnp.maximum(residual, jnp.max(load_error))
    carried = bound_total > 0  # nothing can carry shear: the (zero) solution is exact
    if sliding is not None:
        carried = carried & ~sliding
    return jnp.where(carried, residual, 0.0)
