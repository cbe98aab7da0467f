"""Tangential contact with isotropic Coulomb friction: the helpers every frictional
solver shares (pointwise products of vector fields, the friction-disc projection, the
all-slip load multiplier, the gross-sliding test, the small closed-form solves).
The uncoupled tangential CG itself is `tangential_cg.py`."""

from typing import NamedTuple

import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from .base import safe_div as _safe_div


class TangentialState(NamedTuple):
    shear: Float[Array, "nd nx ny"]
    displacement: Float[Array, "nd nx ny"]  # A q (without b)
    slip: Float[Array, "nd nx ny"]  # ds = A q + b - delta
    delta: Float[Array, " nd"]
    stick: Bool[Array, "nx ny"]
    iterations: Int[Array, ""]
    residual: Float[Array, ""]
    converged: Bool[Array, ""]
    applications: Int[Array, ""]


# Vector fields are (nd, nx, ny). Component sums are written out: XLA:CPU runs a
# reduction over the leading axis fused with elementwise work several times slower
# (a YNN reduction fusion: 1.8 ms of a 22 ms joint iteration at 256^2).
def dot(a, b):
    """Pointwise inner product `(nx, ny)` of two `(nd, nx, ny)` vector fields."""
    out = a[0] * b[0]
    for i in range(1, a.shape[0]):
        out = out + a[i] * b[i]
    return out


def solve_small(m, rhs):
    """A 1x1 or 2x2 linear system in closed form (no LAPACK call inside a loop)."""
    if m.shape[0] == 1:
        return rhs / m[0, 0]
    det = m[0, 0] * m[1, 1] - m[0, 1] * m[1, 0]
    return jnp.stack([m[1, 1] * rhs[0] - m[0, 1] * rhs[1],
                      m[0, 0] * rhs[1] - m[1, 0] * rhs[0]]) / det


def _norm(q):
    """Pointwise magnitude of an `(nd, nx, ny)` vector field."""
    return jnp.sqrt(dot(q, q))


def project(q, bound):
    """Project each cell's traction onto its friction disc `|q| <= bound`."""
    mag = _norm(q)
    factor = jnp.where(mag > bound, _safe_div(bound, mag), 1.0)
    return q * factor[None]


def slip_multiplier(w, q_hat, contact, force_control, target):
    """The rigid tangential displacement `delta_t` [length], `(nd,)`, when NO contact
    cell sticks: every contact cell slips, `w_i - delta_t = -lambda_i q^_i` with
    `lambda_i >= 0`, which fixes `delta_t` through the slip DIRECTIONS (the mean of
    `w` over the contact, used before, is off by the mean of `lambda q^`, so an
    all-slip solution could never pass the convergence test).

    - `w`: `(nd, nx, ny)` tangential displacement `A q + b` [length]; `q_hat`: the
      unit shear directions (0 where `q = 0`); `contact`: `(nx, ny)` cells with a
      friction bound; `force_control`: `(nd,)` bool; `target`: `(nd,)`, `delta_t`
      of the displacement-controlled directions.

    Load-controlled components: the least-squares fit `sum_i P_i (w_i - delta_t) = 0`,
    `P_i = I - q^_i q^_i^T` (the part of the slip not along `q^_i`), regularised
    towards the mean of `w` where it is undetermined (every shear parallel). With one
    shear component `P = 0`; the signs then bound `delta_t` (`>= w_i` where `q_i > 0`,
    `<= w_i` where `q_i < 0`) and the mean is clipped to that interval (its midpoint
    if it is empty). Displacement-controlled components: `target`.
    """
    nd = w.shape[0]
    dtype = w.dtype
    force_control = jnp.asarray(force_control)
    cells = contact[None]
    n_c = jnp.sum(contact).astype(dtype)
    mean_w = _safe_div(jnp.sum(jnp.where(cells, w, 0), axis=(1, 2)), n_c)
    if nd == 1:
        above = jnp.max(jnp.where(contact & (q_hat[0] > 0), w[0], -jnp.inf))
        below = jnp.min(jnp.where(contact & (q_hat[0] < 0), w[0], jnp.inf))
        fit = jnp.where(above <= below, jnp.clip(mean_w[0], above, below),
                        0.5 * (above + below))
        fit = jnp.where(jnp.isfinite(fit), fit, mean_w[0])[None]
        return jnp.where(force_control, fit, target)
    # Only for an exactly undetermined fit (all shear parallel, e.g. a first guess
    # q ~ p F / |F|): far below the rounding of `m` (~ eps n_c), which a larger
    # weight would bias (float32 at 128^2, F = 0.99 mu W: 16 eps n_c floored the
    # residual at 1.1e-5, 1238 iterations with the fallbacks, against 13).
    eps = float(jnp.finfo(dtype).eps) ** 2 * n_c
    along = dot(q_hat, w)
    m = jnp.stack([jnp.stack([
        jnp.sum(jnp.where(contact, float(i == j) - q_hat[i] * q_hat[j], 0.0))
        + eps * (i == j) for j in range(nd)]) for i in range(nd)])
    across = jnp.where(cells, w - q_hat * along[None], 0)
    rhs = jnp.sum(across, axis=(1, 2)) + eps * mean_w
    fixed = jnp.where(force_control, 0.0, target)
    rhs = jnp.where(force_control, rhs - m @ fixed, target)
    both = force_control[:, None] & force_control[None, :]
    eye = jnp.eye(nd, dtype=dtype)
    m = jnp.where(both, m, eye)
    det = m[0, 0] * m[1, 1] - m[0, 1] * m[1, 0]
    fit = solve_small(jnp.where(det != 0, m, eye), rhs)
    # No contact cell (det = 0): the mean (zero), not a NaN.
    return jnp.where(det != 0, fit, jnp.where(force_control, mean_w, target))


def gross_sliding(force, limit, rtol):
    """Whether a tangential load of magnitude `force` [N] slides the indenter against
    the friction limit `limit = A sum(mu p) = mu W` [N]: `force >= (1 - rtol / 2)
    limit`. A load AT the limit (no stick zone left) is then sliding whatever the
    round-off of `sum(p)`, which otherwise decided it (and flipped it from one bound
    update to the next); the sliding answer's load `mu W` is within `rtol / 2` of `F`
    relative to `mu W`, as the tangential load residual requires."""
    return (force >= limit * (1 - 0.5 * rtol)) & (force > 0)


def tangential_lipschitz(blocks):
    """Largest eigenvalue of the tangential operator from its spectra `(xx, xy, yy)`.

    The (padded) operator is a principal submatrix of the circulant whose 2x2 symbol is
    `[[xx, xy], [xy, yy]]` at each frequency, so by interlacing its eigenvalues are
    bounded by the symbol's largest eigenvalue.
    """
    xx, xy, yy = blocks
    if xy is None:
        return jnp.max(xx)
    half = 0.5 * (xx + yy)
    return jnp.max(half + jnp.sqrt(0.25 * (xx - yy) ** 2 + xy * xy))
