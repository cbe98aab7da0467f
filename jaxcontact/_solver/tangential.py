r"""Tangential contact with isotropic Coulomb friction: a projected conjugate gradient.

Problem (one step, pressure `p` given): find the shear traction `q` (`nd = 1` or `2`
components) with `|q_i| <= mu p_i` on every cell and the slip increment

    ds = A q + b - delta_t

equal to zero on stick cells (`|q_i| < mu p_i`) and opposite to `q` on slip cells
(`q_i = -mu p_i ds_i / |ds_i|`). `A = C K_tt` is the tangential compliance operator,
`b` collects the tangential displacement from the pressure (coupling), the loading
history and minus the previous slip (incremental law: `ds` is the slip INCREMENT), and
`delta_t` is the rigid tangential displacement: prescribed per direction
(displacement control) or the Lagrange multiplier of the load `A sum(q_d) = F_d`
(load control). These are the KKT conditions of the convex problem

    min_q  1/2 q.A q + q.(b - delta_t)   s.t.  |q_i| <= mu p_i,

so the solver is a projected CG in the spirit of Polonsky & Keer (1999):

- conjugate gradient steps on the stick set (directions made mean-free per
  load-controlled direction, which keeps the load);
- on slip cells, the projected gradient: the rotation of `q` along its disc (and the
  whole `ds` where the slip has the wrong sign, which releases the cell); the stick
  and slip parts form one search direction with an exact line search (one operator
  application);
- projection of every cell onto its friction disc; the load is then restored by a
  uniform shift of the stick cells;
- one operator application per iteration while the stick set is steady (the
  displacement is updated by linearity, and recomputed when the projection changed `q`
  outside the search direction); CG restarts when the stick set changes;
- preconditioned with one shear component (`nd = 1`, what `coupled.contact_step`
  passes on non-periodic grids): the direction on the stick and released cells is the
  full-plane inverse of `K_xx` (`precondition.shear_x_preconditioner`: the xx spectrum
  floored by the normal one, on the unpadded grid, raised to Cerruti's continuous
  symbol), made mean-free under load control (2-4x fewer iterations on
  Cattaneo-Mindlin: `benchmarks/notes/solvers.md`). With two components the diagonal
  stays: the FFT directions did not converge on a rotating oblique load history;
- convergence is tested on the Coulomb conditions AND on the loads: `residual =
  max(||violation||_2 / scale, max_d |A sum q_d - F_d| / (mu W))`, where the violation
  is `ds` on stick cells and the part of `ds` not opposite to `q` on slip cells.
"""

from typing import NamedTuple

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int


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


def _safe_div(a, b):
    ok = b != 0
    return jnp.where(ok, a / jnp.where(ok, b, 1), jnp.zeros_like(a))


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


def tangential_cg(
    apply_fn,
    b: Float[Array, "nd nx ny"],
    bound: Float[Array, "nx ny"],
    force_control: tuple[bool, ...],
    target: Float[Array, " nd"],
    cell_area,
    self_compliance,
    *,
    q0: Float[Array, "nd nx ny"] | None = None,
    rtol: float,
    max_steps: int,
    resync_every: int = 25,
    precondition=None,
) -> TangentialState:
    """Solve the tangential problem (see module docs).

    **Arguments:**

    - `apply_fn`: `q -> A q`, `(nd, nx, ny)` shear [stress] to tangential
      displacement [length].
    - `b`: fixed part of the slip increment [length], `(nd, nx, ny)`.
    - `bound`: `mu p` [stress], `(nx, ny)`; cells with `bound == 0` carry no shear.
    - `force_control`: per direction, `True` for load control (`target` is the force
      [force]) or `False` for displacement control (`target` is `delta_t` [length]).
    - `cell_area`: [length^2]; `self_compliance`: `A_ii`, the tangential displacement
      of a cell under its own unit shear [length/stress] (scales the preconditioner).
    - `q0`: warm start (projected and load-corrected).
    - `precondition`: `None` (the diagonal) or, for `nd = 1` only, `r -> M r`, an
      approximate inverse of `A_xx` on the whole grid, one component `(nx, ny) ->
      (nx, ny)` (`precondition.shear_x_preconditioner`), restricted to the
      stick and released cells and, under load control, made mean-free on them (as
      Polonsky & Keer's normal CG).
    """
    nd = b.shape[0]
    if precondition is not None and nd != 1:
        raise ValueError(
            f"tangential_cg: an FFT precondition needs one shear component, got nd={nd}")
    dtype = b.dtype
    force_mask = jnp.asarray(force_control)[:, None, None]
    target = jnp.asarray(target, dtype)
    contact = bound > 0
    bound_total = cell_area * jnp.sum(bound)  # mu W
    q0 = jnp.zeros_like(b) if q0 is None else q0

    def stick_of(q):
        return contact & (_norm(q) < bound * (1 - 1e-10))

    def fix_load(q):
        """Shift the stick cells (or, if none, all contact cells) to carry the load."""
        stick = stick_of(q)
        where = jnp.where(jnp.any(stick), stick, contact)
        count = jnp.sum(where)
        deficit = _safe_div(target / cell_area - jnp.sum(q, axis=(1, 2)), count)
        shift = jnp.where(force_mask, deficit[:, None, None] * where[None], 0.0)
        return project(q + shift, bound)

    def evaluate(q, w):
        stick = stick_of(q)
        n_stick = jnp.sum(stick)
        mean_stick = _safe_div(jnp.sum(jnp.where(stick[None], w, 0), axis=(1, 2)), n_stick)
        mag_q = _norm(q)
        q_hat = q * _safe_div(1.0, mag_q)[None]
        all_slip = slip_multiplier(w, q_hat, contact, force_control, target)
        multiplier = jnp.where(n_stick > 0, mean_stick, all_slip)
        delta = jnp.where(jnp.asarray(force_control), multiplier, target)
        ds = w - delta[:, None, None]
        slip_violation = ds + _norm(ds)[None] * q_hat
        violation = jnp.where(stick[None], ds, jnp.where(contact[None], slip_violation, 0))
        scale = jnp.sqrt(jnp.sum((w - b) ** 2)) + jnp.sqrt(jnp.sum(jnp.where(contact[None], b, 0) ** 2))
        num = jnp.sqrt(jnp.sum(violation * violation))
        res = jnp.where(num == 0, 0.0, _safe_div(num, scale))
        res = jnp.where((num > 0) & (scale == 0), jnp.inf, res)
        load_err = jnp.abs(cell_area * jnp.sum(q, axis=(1, 2)) - target)
        load_err = jnp.where(jnp.asarray(force_control), _safe_div(load_err, bound_total), 0.0)
        res = jnp.maximum(res, jnp.max(load_err))
        # Nothing can carry shear: the (zero) solution is exact.
        res = jnp.where(bound_total > 0, res, 0.0)
        return ds, delta, stick, res

    q0 = fix_load(project(q0, bound))
    w0 = apply_fn(q0) + b
    ds0, _, _, res0 = evaluate(q0, w0)
    init = dict(
        q=q0, w=w0, ds=ds0, t=jnp.zeros_like(b), g_old=jnp.ones((), dtype),
        restart=jnp.array(True), it=jnp.array(0), residual=res0, applications=jnp.array(1),
    )

    def cond(s):
        return (s["residual"] > rtol) & (s["it"] < max_steps)

    def body(s):
        q, w = s["q"], s["w"]
        stick = stick_of(q)
        q_hat = q * _safe_div(1.0, _norm(q))[None]
        # Free variables: stick cells (full vectors) and, on slip cells, the rotation
        # along the friction disc (tangent component). Slip cells whose slip has the
        # wrong sign (multiplier < 0) are released: free as full vectors.
        ds_stick_delta = s["ds"]
        lam = -dot(ds_stick_delta, q_hat)
        slip_cells = contact & ~stick
        release = slip_cells & (lam < 0)
        full = stick | release
        rotate = slip_cells & ~release
        if nd == 1:
            tangent = jnp.zeros_like(q)
        else:
            tangent = jnp.stack([-q_hat[1], q_hat[0]])
        tt = jnp.where(rotate[None], tangent, 0)  # unit tangents on rotating cells
        ds = s["ds"]
        lam = jnp.maximum(-dot(ds, q_hat), 0.0)
        # Reduced gradient: ds on full cells, its tangential part on rotating cells.
        r = jnp.where(full[None], ds, tt * dot(tt, ds)[None])
        # Diagonal preconditioner: the rotation of a slip cell feels the disc
        # curvature lambda / bound on top of the self-compliance A_ii; without it the
        # cells at the contact edge (bound -> 0) make the reduced problem
        # ill-conditioned.
        curv_disc = jnp.where(rotate, _safe_div(lam, bound), 0.0)
        weight = jnp.where(full, 1.0, jnp.where(
            rotate, self_compliance / (self_compliance + curv_disc), 0.0))

        if precondition is not None:
            # Full-plane inverse on the free cells (nd = 1: no rotating cells), made
            # mean-free there under load control.
            z = jnp.where(full[None], precondition(r[0])[None], 0)
            if force_control[0]:
                mean = _safe_div(jnp.sum(z), jnp.sum(full))
                z = jnp.where(full[None], z - mean, 0)
        else:
            # Projection onto load-preserving directions (sum over free variables = 0
            # per load-controlled direction), oblique in the preconditioner's metric:
            # z = P r - P B (B^T P B)^{-1} B^T P r. Symmetric, so CG stays valid.
            def basis(c):  # B c: c on full cells, (e_perp . c) e_perp on rotating cells
                return jnp.where(full[None], c[:, None, None],
                                 tt * jnp.einsum("i,iab->ab", c, tt)[None])

            eye = jnp.eye(nd, dtype=dtype)
            m = jnp.sum(jnp.where(full, weight, 0)) * eye + jnp.einsum(
                "ab,iab,jab->ij", weight, tt, tt)
            fc = jnp.asarray(force_control)
            both = fc[:, None] & fc[None, :]
            m = jnp.where(both, m, eye)
            pr = weight[None] * r
            rhs = jnp.where(fc, jnp.sum(pr, axis=(1, 2)), 0.0)
            empty = jnp.where(jnp.trace(jnp.where(both, m, 0.0)) > 0, 0.0, 1.0)
            coef = jnp.linalg.solve(m + empty * eye, rhs)
            z = pr - weight[None] * basis(jnp.where(fc, coef, 0.0))
        rz = jnp.sum(r * z)
        beta = jnp.where(s["restart"], 0.0, _safe_div(rz, s["g_old"]))
        t = z + beta * s["t"]
        t = jnp.where(full[None], t, tt * dot(tt, t)[None])
        g_norm = rz
        at = apply_fn(t)
        curvature = jnp.sum(t * at) + jnp.sum(curv_disc * dot(t, t))
        tau = _safe_div(jnp.sum(r * t), curvature)
        q_step = q - tau * t
        w_new = w - tau * at
        q_new = project(q_step, bound)
        q_new = jax.lax.cond(
            jnp.any(jnp.asarray(force_control)), fix_load, lambda x: x, q_new
        )
        # Changes outside the search direction (projection, load fix) are not in the
        # tracked displacement. Resync only when they matter at the current accuracy:
        # the final answer is always certified with an exact displacement.
        extra = jnp.max(jnp.abs(q_new - q_step))
        dirty = extra > 1e-3 * jnp.minimum(s["residual"], 1.0) * jnp.max(bound)
        stick_new = stick_of(q_new)
        changed = jnp.any(stick_new != stick) | jnp.any(release)
        it = s["it"] + 1
        need_exact = dirty | (it % resync_every == 0)
        w_new = jax.lax.cond(need_exact, lambda: apply_fn(q_new) + b, lambda: w_new)
        ds_new, _, _, res = evaluate(q_new, w_new)

        def exact():
            w_e = apply_fn(q_new) + b
            ds_e, _, _, res_e = evaluate(q_new, w_e)
            return w_e, ds_e, res_e

        certify = (~need_exact) & (res <= rtol)
        w_new, ds_new, res = jax.lax.cond(certify, exact, lambda: (w_new, ds_new, res))
        return dict(
            q=q_new, w=w_new, ds=ds_new, t=t, g_old=g_norm,
            restart=changed | (certify & (res > rtol)), it=it, residual=res,
            applications=s["applications"] + 1 + need_exact + certify,
        )

    s = jax.lax.while_loop(cond, body, init)
    ds, delta, stick, res = evaluate(s["q"], s["w"])
    del nd
    return TangentialState(
        shear=s["q"],
        displacement=s["w"] - b,
        slip=ds,
        delta=delta,
        stick=stick,
        iterations=s["it"],
        residual=res,
        converged=res <= rtol,
        applications=s["applications"],
    )
