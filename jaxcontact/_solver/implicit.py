r"""Exact gradients of one contact step by implicit differentiation.

The CG solvers are `lax.while_loop`s, which reverse-mode cannot (and should not) go
through. Instead, at the converged solution the active sets are frozen (contact cells
`p > 0`, stick cells, slip cells with their slip direction, gross sliding), and the
solution `x = (p, q, delta_z, delta_t)` is the root of a smooth residual
`F(x, theta) = 0` on those sets, with `theta` the step's inputs (compliance, Poisson's
ratio, friction coefficient, gap, history displacement, previous slip, targets):

- contact cells: zero gap, `(h + u_z - delta_z) / k_z = 0`; other cells: `p = 0`;
- normal load control: `(A sum p - W) / (A sqrt(n_contact)) = 0`; displacement control:
  `delta_z` equals its target;
- stick cells: zero slip increment, `s / k_t = 0` with
  `s = u_t + history_t - previous_slip - delta_t`; slip cells: `q = -mu p s / |s|`
  (`nd = 2`), `q = mu p sign(q)` (`nd = 1`, the sign frozen); cells out of contact:
  `q = 0`; gross sliding under load control: `q = mu p F / |F|` (`F` the load of the
  load-controlled directions) and their `delta_t` the mean of `u_t + history_t` over
  the contact;
- tangential load control per direction: `(A sum q_d - F_d) / (A sqrt(n_contact)) = 0`;
  displacement control: `delta_t,d` equals its target,

where `u = C K (q, p)` (the half-space operator of the step, coupling blocks included)
and `k_z`, `k_t` are the self-compliances of a cell (constant scalings that make the
rows dimensionless: they do not change the root, only the conditioning). By the
implicit function theorem `dx/dtheta = -(dF/dx)^-1 dF/dtheta`, so the vector-Jacobian
product of a cotangent `x_bar` is `theta_bar = -(dF/dtheta)^T lambda` with the ADJOINT
solve `(dF/dx)^T lambda = x_bar`: one linear solve with the same FFT operator
(the operator is symmetric, so a transposed application costs what a forward one
does). Frictionless and uncoupled x-only steps solve it by projected conjugate
gradients on the contact / stick set (`_set_adjoint`); the others (coupling, 2-D slip,
gross sliding under load control) by GMRES, matrix-free through `jax.vjp` of `F`,
right-preconditioned by the full-plane inverse of the operator's diagonal blocks on the
contact cells (`_transposed_preconditioner`), with the slip rows of two shear
components scaled across their slip direction (`slip_weight`, frozen: the same root)
so that they do not grow without bound at the stick-slip boundary. Nothing of the
forward CG iterations is stored.

The derivative is that of the solution on its current active sets: exact away from
active-set changes (a cell entering or leaving contact or the stick zone), where the
solution is only directionally differentiable.
"""

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
from jax.flatten_util import ravel_pytree

from .._results import RESULTS
from .base import AbstractStepSolver, StepGuess, StepProblem, applied_load
from .gmres import restarted_gmres
from .normal import inverse_preconditioner
from .precondition import block_preconditioner, shear_x_preconditioner


class _Spec(NamedTuple):
    """The static shape of a step's residual (from its `StepProblem`)."""

    nd: int
    coupled: bool
    normal_force_control: bool
    tangential_force_control: tuple[bool, ...]
    precondition: bool


class ImplicitAdjoint(eqx.Module):
    """Gradients of each step by the implicit function theorem (see the module docs):
    one adjoint linear solve per step, nothing of the forward iterations stored.

    **Arguments:**

    - `rtol`: relative tolerance of the adjoint solve; `None`: the step solver's.
    - `max_steps`: iteration bound of the adjoint solve (conjugate-gradient iterations
      of the frictionless and uncoupled "x" adjoints; GMRES iterations otherwise).
    - `restart`: GMRES restart length (iterations per cycle).
    - `precondition`: precondition the adjoint solves with the full-plane inverse of
      the operator (as the forward solvers).
    - `gmres_method`: `"incremental"` (stops inside a restart cycle: fewer operator
      applications; the faster on CPUs), `"batched"` (whole cycles, each a few large
      kernels: the faster on GPUs, 2x at 256^2 on an H200), or `None`: by the default
      backend (`benchmarks/README.md`, `gradients.py`).
    - `mode`: `"reverse"` (default): a custom VJP, one adjoint solve per step and
      cotangent (`jax.grad`, `jax.vjp`, `jax.jacrev`), each started from the next
      step's adjoint; `"forward"`: a custom JVP, one tangent solve per step and
      tangent direction (`jax.jvp`, `jax.jacfwd`). A Jacobian with more outputs than
      inputs (a fit's curve of `nt` samples against a few parameters) costs `p`
      tangent solves forwards against `nt` adjoint solves backwards. The tangent solve
      is on the same frozen-set system, by the adjoint's method (projected CG for
      frictionless steps, right-preconditioned GMRES otherwise), inside
      `jax.lax.custom_linear_solve`: reverse mode through it works too (the
      transposed system by the same method, from zero).

    A solve that does not reach `rtol` within `max_steps` is reported, never silent:
    `jc.solve(..., throw=True)` raises `RESULTS.adjoint_not_converged` when the
    gradient is computed; with `throw=False` that step's cotangents are NaN.
    """

    rtol: float | None = eqx.field(static=True, default=None)
    max_steps: int = eqx.field(static=True, default=2000)
    restart: int = eqx.field(static=True, default=40)
    precondition: bool = eqx.field(static=True, default=True)
    gmres_method: str | None = eqx.field(static=True, default=None)
    mode: str = eqx.field(static=True, default="reverse")

    def __check_init__(self):
        if self.mode not in ("reverse", "forward"):
            raise ValueError(f'mode must be "reverse" or "forward", got {self.mode!r}')
        if self.rtol is not None and not (0 < self.rtol < 1):
            raise ValueError(f"rtol must be in (0, 1), got {self.rtol!r}")
        if self.gmres_method not in (None, "incremental", "batched"):
            raise ValueError('gmres_method must be None, "incremental" or "batched", '
                             f"got {self.gmres_method!r}")
        for name in ("max_steps", "restart"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 1):
                raise ValueError(f"{name} must be a positive integer, got {value!r}")


def _displacements(operator, config: _Spec, compliance, poisson, p, q):
    """`(u_z, u_t)` = `C K (q, p)`: the operator built for the scene carries exactly the
    blocks the step uses (its coupling mode, and `q_y` only when `nd = 2`)."""
    nx, ny = p.shape
    traction = jnp.zeros((3, nx, ny), p.dtype).at[: config.nd].set(q).at[2].set(p)
    u = compliance * operator.apply(traction, poisson)
    return u[2], u[: config.nd]


def _self_compliance(operator, config, compliance, poisson):
    """`(k_z, k_t)`: normal and tangential displacement of a cell under its own unit
    traction (positive scalars, used only to scale the residual rows)."""
    kz = compliance * operator.diagonal(operator.normal_spectrum(poisson))
    if config.nd == 0:
        return kz, kz
    xx, _, _ = operator.tangential_blocks(poisson)
    return kz, compliance * operator.diagonal(xx)


def _residual(operator, config, frozen, x, theta):
    """`F(x, theta)` on the frozen active sets (see module docs)."""
    p, q, dz, dt = x
    compliance, poisson, friction, h, history, previous_slip, w_target, t_target = theta
    (contact, stick, slip_sign, sliding, kz, kt, fixed, slip_weight,
     slip_direction) = frozen[:9]
    area = operator.grid.cell_area
    n_contact = jnp.sum(contact)
    scale = area * jnp.sqrt(jnp.maximum(n_contact, 1).astype(p.dtype))
    any_contact = n_contact > 0

    uz, ut = _displacements(operator, config, compliance, poisson, p, q)
    gap = h + history[2] + uz - dz * kz
    f_p = jnp.where(contact, gap / kz, p)
    if config.normal_force_control:
        # No contact (the load back at zero): the indenter touches the surface, whose
        # recovery the history carries, at its highest point (the forward's
        # `gap_residual`): the approach depends on the material through `history`.
        # The lowest point by index, not `jnp.min`: min's derivative divides by the
        # count of entries equal to it, 0 / 0 where a program recomputes the field
        # with other round-off (vmap under XLA's unoptimised code generation).
        surface = (h + history[2] + uz).ravel()
        touching = surface[jnp.argmin(surface)] / kz
        f_dz = jnp.where(any_contact, (area * jnp.sum(p) - w_target) / scale,
                         dz - touching)
    else:
        f_dz = dz - w_target / kz
    if config.nd == 0:
        return f_p, q, f_dz, dt

    nd = config.nd
    base = ut + history[:nd] - previous_slip
    s = base - dt[:, None, None] * kt
    bound = friction * p
    if nd == 1:
        slipping = bound[None] * slip_sign
    else:
        sq = jnp.sum(s * s, axis=0)
        safe = jnp.sqrt(jnp.where(sq > 0, sq, 1.0))  # no NaN derivative at s = 0
        slipping = jnp.where(sq > 0, -bound / safe, 0.0)[None] * s
    # Slip rows (two components): the part across the frozen slip direction times the
    # frozen `slip_weight`: the same root, a better conditioned transposed system.
    slip_row = q - slipping
    if nd == 2:
        along = jnp.sum(slip_direction * slip_row, axis=0)[None] * slip_direction
        slip_row = along + slip_weight[None] * (slip_row - along)
    f_q = jnp.where(stick[None], s / kt, jnp.where(contact[None], slip_row, q))

    f_dt = []
    for d in range(nd):
        if config.tangential_force_control[d]:
            f_dt.append(jnp.where(any_contact,
                                  (area * jnp.sum(q[d]) - t_target[d]) / scale,
                                  dt[d] - fixed[1 + d]))
        else:
            f_dt.append(dt[d] - t_target[d] / kt)
    f_dt = jnp.stack(f_dt)

    if any(config.tangential_force_control):
        # Gross sliding under load control: q = mu p along F (the load-controlled
        # directions' load, `applied_load`: safe at F = 0); delta_t of a load-controlled
        # direction = mean over the contact of u_t + history_t (the rigid-body drift has
        # no stick cell to fix it), of a displacement-controlled one its target.
        _, direction = applied_load(t_target, config.tangential_force_control)
        f_q_slide = jnp.where(contact[None],
                              q - bound[None] * direction[:, None, None], q)
        mean = (jnp.sum(jnp.where(contact[None], base, 0), axis=(1, 2))
                / jnp.maximum(n_contact, 1))
        f_dt_slide = jnp.where(jnp.asarray(config.tangential_force_control),
                               dt - mean / kt, f_dt)
        f_q = jnp.where(sliding, f_q_slide, f_q)
        f_dt = jnp.where(sliding, f_dt_slide, f_dt)
    return f_p, f_q, f_dz, f_dt


def _set_adjoint(a_full, active, load_control, a, b_bar, z_bar, guess, rtol, maxiter,
                 precondition=None):
    """Conjugate-gradient solve of the transposed system of one field on a frozen set.

    The frictionless block (pressure `p` on the contact set, the approach as its
    multiplier) and the uncoupled tangential block in x (shear on the stick set, the
    tangential displacement as its multiplier) have the same structure. With the set
    `S` (`active`), `A` the scaled operator (`a_full`), `mu` the adjoint on `S` and
    `lam_m` the multiplier's adjoint, `(dF/dx)^T lambda = (b_bar, z_bar)` reads

    - on `S`: `(A mu)_S + a lam_m = b_bar_S`,
    - load control with a non-empty set: `-sum(mu) = z_bar`; otherwise (displacement
      control, or no cell in `S`): `lam_m = z_bar + sum(mu)` and no `a lam_m` term,
    - off `S`: `lambda = b_bar - A mu - a lam_m` (identity rows).

    `a` is the load row's derivative `A_cell / scale` (module docs). The `S` block is
    symmetric positive definite (on mean-free `mu` under load control): projected CG,
    one FFT pair per iteration, started from `guess` (the next step's adjoint);
    with `precondition` (`r -> M r`, an approximate inverse of `a_full`, e.g.
    `normal.inverse_preconditioner`), projected PCG with `P M P`: two FFT pairs per
    iteration, several times fewer iterations (as the forward `normal.py`).
    The stopping rule is `||r|| <= rtol ||b||` on a system scaled to `max |b| = 1`
    (`_unit_scale`), started from `guess` only where it is closer than zero: a step
    whose right-hand side is zero (nothing links it to the output) returns zero, and
    one whose right-hand side is tiny (1e-19) is solved to the same relative accuracy
    whatever its warm start and without under- or overflow in float32.
    **Returns:** `(lambda, lam_m, converged)`.
    """
    scale = _unit_scale((b_bar, z_bar))
    lam, lam_m, converged = _set_adjoint_scaled(
        a_full, active, load_control, a, b_bar / scale, z_bar / scale, guess / scale,
        rtol, maxiter, precondition)
    return lam * scale, lam_m * scale, converged


def _unit_scale(tree):
    """`max |v|` over the leaves of `tree`, or 1 where they are all zero: the factor
    that brings a linear system's right-hand side to unit size."""
    size = jnp.max(jnp.stack([jnp.max(jnp.abs(v)) for v in jax.tree.leaves(tree)]))
    return jnp.where(size > 0, size, 1.0)


def _set_adjoint_scaled(a_full, active, load_control, a, b_bar, z_bar, guess, rtol,
                        maxiter, precondition):
    """`_set_adjoint` on a right-hand side of unit size."""
    dtype = b_bar.dtype
    c = active.astype(dtype)
    n_s = jnp.sum(c)
    has_set = n_s > 0
    safe_n = jnp.maximum(n_s, 1.0)

    def project(v):
        v = c * v
        if load_control:
            v = v - c * jnp.sum(v) / safe_n
        return v

    mu0 = c * (-z_bar / safe_n) if load_control else jnp.zeros_like(b_bar)
    b = c * (b_bar - a_full(mu0))
    rhs = project(b)
    v = project(guess)
    r = rhs - project(a_full(v))
    # The warm start only where its residual is below the zero start's (`rhs`): a
    # previous step's adjoint is no start for a step with a zero right-hand side.
    warm = jnp.sum(r * r) < jnp.sum(rhs * rhs)
    v = jnp.where(warm, v, 0.0)
    r = jnp.where(warm, r, rhs)
    # Relative to the unprojected right-hand side: when b_bar is (nearly) uniform on S
    # the projected one vanishes and the adjoint is all in lam_m.
    limit = (rtol * jnp.sqrt(jnp.sum(b * b))) ** 2

    def apply_m(r):
        return r if precondition is None else project(precondition(r))

    def cond(state):
        _, r, _, _, it = state
        return (jnp.sum(r * r) > limit) & (it < maxiter)

    def body(state):
        v, r, d, rz, it = state
        ad = project(a_full(d))
        alpha = rz / jnp.sum(d * ad)
        v = v + alpha * d
        r = r - alpha * ad
        z = apply_m(r)
        rz_new = jnp.sum(r * z)
        d = z + (rz_new / rz) * d
        return v, r, d, rz_new, it + 1

    z = apply_m(r)
    v, r, _, _, _ = jax.lax.while_loop(cond, body,
                                       (v, r, z, jnp.sum(r * z), jnp.array(0)))
    converged = jnp.sum(r * r) <= limit
    mu = mu0 + v
    a_mu = a_full(mu)
    if load_control:
        lam_m = jnp.where(has_set, jnp.sum(c * (b_bar - a_mu)) / safe_n / a, z_bar)
        shift = jnp.where(has_set, a * lam_m, 0.0)
    else:
        lam_m = z_bar + jnp.sum(mu)
        shift = 0.0
    return jnp.where(active, mu, b_bar - a_mu - shift), lam_m, converged


def _area_scale(operator, contact):
    """`a = A_cell / scale` of the load rows: `1 / sqrt(n_contact)`."""
    n_contact = jnp.sum(contact).astype(operator.grid.cell_area.dtype)
    return 1.0 / jnp.sqrt(jnp.maximum(n_contact, 1.0))


def _normal_block(operator, config, frozen, theta):
    """`(A, M)` of a frictionless step: `A = C K_zz / k_z` (a function of a field) and
    its preconditioner (`normal.inverse_preconditioner`, or `None`)."""
    kz = frozen[4]
    compliance, poisson = theta[0], theta[1]

    def a_full(v):
        return (compliance / kz) * operator.apply_normal(v, poisson)

    precondition = None
    if config.precondition:
        precondition = inverse_preconditioner(
            operator, operator.normal_spectrum(poisson), poisson)
    return a_full, precondition


def _normal_adjoint(operator, config, frozen, theta, x_bar, guess, rtol, maxiter):
    """The adjoint of a frictionless step (`nd = 0`): `_set_adjoint` on the contact
    set with `A = C K_zz / k_z`; the shear rows are identities (`lambda_q = q_bar`)."""
    contact = frozen[0]
    p_bar, q_bar, dz_bar, dt_bar = x_bar
    a_full, precondition = _normal_block(operator, config, frozen, theta)
    lam_p, lam_dz, ok = _set_adjoint(
        a_full, contact, config.normal_force_control, _area_scale(operator, contact),
        p_bar, dz_bar, guess[0], rtol, maxiter, precondition)
    return (lam_p, q_bar, lam_dz, dt_bar), ok


def _normal_tangent(operator, config, frozen, theta, b, linear, rtol, maxiter):
    """The tangent of a frictionless step (`nd = 0`): `(dF/dx) x_dot = b` by the
    projected CG of `_set_adjoint`, the forward system brought to its form.

    With `S` the contact set, `A = C K_zz / k_z` and `O` the other cells, `dF/dx x_dot
    = b` reads `p_dot_O = b_O` (identity rows); on `S` `(A p_dot)_S - dz_dot = b_S`;
    load control: `a sum(p_dot) = b_dz`; displacement control: `dz_dot = b_dz`. So
    `p_dot_S` solves `_set_adjoint`'s system with `b_bar = b_S - (A b_O)_S` (plus
    `dz_dot` under displacement control) and, under load control, `z_bar = sum(b_O) -
    b_dz / a`, `dz_dot = -a lam_m`. Under load control without contact the approach
    row is `dz - touching(p)`: `dz_dot = b_dz - (dF_dz/dp) p_dot` (one product with
    `linear`). Shear rows are identities. **Returns:** `(x_dot, converged)`."""
    contact = frozen[0]
    b_p, b_q, b_dz, b_dt = b
    c = contact.astype(b_p.dtype)
    a_full, precondition = _normal_block(operator, config, frozen, theta)
    b_off = (1 - c) * b_p
    rhs = c * (b_p - a_full(b_off))
    zero = jnp.zeros_like(b_p)
    if config.normal_force_control:
        a = _area_scale(operator, contact)
        mu, lam_m, ok = _set_adjoint(a_full, contact, True, a, rhs,
                                     jnp.sum(b_off) - b_dz / a, zero, rtol, maxiter,
                                     precondition)
        p_dot = jnp.where(contact, mu, b_p)
        dz_dot = jax.lax.cond(
            jnp.any(contact), lambda: -a * lam_m,
            lambda: b_dz - linear((p_dot, jnp.zeros_like(b_q), jnp.zeros_like(b_dz),
                                   jnp.zeros_like(b_dt)))[2])
    else:
        dz_dot = b_dz
        mu, _, ok = _set_adjoint(a_full, contact, False, 1.0, rhs + c * dz_dot,
                                 jnp.zeros_like(b_dz), zero, rtol, maxiter,
                                 precondition)
        p_dot = jnp.where(contact, mu, b_p)
    return (p_dot, b_q, dz_dot, b_dt), ok


def _uncoupled_x_adjoint(operator, config, frozen, theta, x_bar, guess, rtol, maxiter,
                         residual_vjp):
    """The adjoint of an uncoupled step with shear in x only (`nd = 1`, no coupling
    blocks) when it is not gross sliding under load control.

    The Jacobian is block lower triangular (the normal rows do not see `q`), so the
    transposed system is solved tangential block first (`_set_adjoint` on the stick
    set with `A = C K_xx / k_t`: slip and out-of-contact shear rows are identities),
    then the normal block with the right-hand side less the tangential rows'
    derivatives with respect to `p` (the slip rows `q = mu p sign`), through one
    product with the residual's transpose.
    """
    contact, stick, kt = frozen[0], frozen[1], frozen[5]
    compliance, poisson = theta[0], theta[1]
    p_bar, q_bar, dz_bar, dt_bar = x_bar

    def a_full(v):
        return (compliance / kt) * operator.apply_tangential(v[None], poisson)[0]

    precondition = None
    if config.precondition:
        precondition = shear_x_preconditioner(operator, poisson)
    lam_q, lam_dt, ok_t = _set_adjoint(
        a_full, stick, config.tangential_force_control[0],
        _area_scale(operator, contact), q_bar[0], dt_bar[0], guess[1][0], rtol,
        maxiter, precondition)
    lam_q, lam_dt = lam_q[None], lam_dt[None]
    zero = jnp.zeros((), p_bar.dtype)
    coupling = residual_vjp((jnp.zeros_like(p_bar), lam_q, zero, lam_dt))
    (lam_p, _, lam_dz, _), ok_n = _normal_adjoint(
        operator, config, frozen, theta,
        (p_bar - coupling[0], q_bar, dz_bar - coupling[2], dt_bar), guess, rtol,
        maxiter)
    return (lam_p, lam_q, lam_dz, lam_dt), ok_t & ok_n


def _slip_out(operator, config, x, theta, kt):
    """Total slip after the step `u_t + history_t - delta_t` (carried to the next)."""
    p, q, _, dt = x
    compliance, poisson, _, _, history, _, _, _ = theta
    _, ut = _displacements(operator, config, compliance, poisson, p, q)
    return ut + history[: config.nd] - dt[:, None, None] * kt


def _tree_dot(a, b):
    return sum(jnp.sum(u * v) for u, v in zip(jax.tree.leaves(a), jax.tree.leaves(b)))


# GMRES passes of an adjoint solve: the second starts from the true residual where the
# first one's running estimate stopped short of it.
_GMRES_PASSES = 2


def _right_preconditioned_gmres(mv, precondition, b, x0, rtol, restart, max_steps,
                                method="incremental"):
    """`(x, converged)` with `||mv(x) - b|| <= rtol ||b||` (2-norm) by GMRES from `x0`,
    right-preconditioned: GMRES on `mv(M y) = b - mv(x0)`, then `x = x0 + M y`, so its
    residual is the true one. `method` "incremental" (`gmres.restarted_gmres`) stops
    inside a restart cycle as soon as its running estimate meets the target (lineax's
    GMRES, and the "batched" method, `jax.scipy.sparse.linalg.gmres`, run every cycle
    to its end); that estimate can stop up to ~2x above it, hence a quarter of
    `rtol ||b||` ("batched" tests the true residual after each cycle: `rtol ||b||`).
    At most `max_steps` iterations in cycles of `restart`. `converged` is judged on
    `mv(x)` once more (relative 2-norm), as the forward solves and the CG adjoints are;
    where that misses, one more GMRES starts from the true residual
    (`_GMRES_PASSES`).

    As `_set_adjoint`, the system is scaled to `max |b| = 1` and started from `x0` only
    where `x0` is closer than zero: a zero `b` returns zero, converged."""
    scale = _unit_scale(b)
    x, ok = _scaled_gmres(
        mv, precondition, jax.tree.map(lambda v: v / scale, b),
        jax.tree.map(lambda v: v / scale, x0), rtol, restart, max_steps, method)
    return jax.tree.map(lambda v: v * scale, x), ok


def _scaled_gmres(mv, precondition, b, x0, rtol, restart, max_steps, method):
    """`_right_preconditioned_gmres` on a right-hand side of unit size."""
    b_norm = jnp.sqrt(_tree_dot(b, b))

    def refine(state):
        # One GMRES from `x` on the true residual; a pass whose running estimate
        # stopped short of the true one (round-off, float32) is followed by another.
        x, r, passes, _ = state
        cycles = max(1, -(-max_steps // restart))
        if method == "incremental":
            r_flat, unravel = ravel_pytree(r)
            y_flat, _ = restarted_gmres(
                lambda v: ravel_pytree(mv(precondition(unravel(v))))[0], -r_flat,
                jnp.zeros_like(r_flat), 0.25 * rtol * b_norm, restart, cycles)
            y = unravel(y_flat)
        else:
            y, _ = jax.scipy.sparse.linalg.gmres(
                lambda y: mv(precondition(y)), jax.tree.map(jnp.negative, r),
                jax.tree.map(jnp.zeros_like, r), tol=0.0, atol=rtol * b_norm,
                restart=restart, maxiter=cycles, solve_method=method)
        x = jax.tree.map(jnp.add, x, precondition(y))
        r = jax.tree.map(jnp.subtract, mv(x), b)
        r2 = _tree_dot(r, r)
        return x, r, passes + 1, jnp.isfinite(r2) & (r2 <= (rtol * b_norm) ** 2)

    def again(state):
        _, _, passes, ok = state
        return ~ok & (passes < _GMRES_PASSES)

    r0 = jax.tree.map(jnp.subtract, mv(x0), b)
    r0_2 = _tree_dot(r0, r0)
    # The warm start only where it is closer than zero (whose residual is `-b`).
    warm = r0_2 < b_norm**2
    x0 = jax.tree.map(lambda v: jnp.where(warm, v, 0.0), x0)
    r0 = jax.tree.map(lambda v, w: jnp.where(warm, v, -w), r0, b)
    r0_2 = jnp.where(warm, r0_2, b_norm**2)
    ok0 = r0_2 <= (rtol * b_norm) ** 2
    x, _, _, ok = jax.lax.while_loop(again, refine, (x0, r0, 0, ok0))
    return x, ok


def _gmres_method(adjoint: ImplicitAdjoint) -> str:
    """The adjoint's GMRES method: its own, or by the default backend (measured:
    "incremental" on the 2-core CPU, 2.6x against 3.8x for "batched" at 64^2 x 20;
    "batched" on an H200, 3.4x against 5.7x at 256^2 x 50; coupling "full")."""
    if adjoint.gmres_method is not None:
        return adjoint.gmres_method
    return "incremental" if jax.default_backend() == "cpu" else "batched"


def _transposed_preconditioner(operator, config, frozen, theta, precondition):
    """`v -> M v`, an approximate inverse of `(dF/dx)^T` for the GMRES adjoint (the
    identity without `precondition`).

    On the contact rows of `F` (the gap), the stick rows (zero slip) and, once scaled
    by `slip_weight`, across the slip direction of the slip rows, `dF/dx` is close to
    the operator `C K` scaled by `1 / k_z`, `1 / k_t`; out of contact it is the
    identity. `M`: on the contact cells `k` times the full-plane inverse of the
    diagonal blocks of `C K` (`block_preconditioner`, as `JointPCG`; `K` is symmetric,
    so the same for the transpose), the identity elsewhere and on the load and
    displacement unknowns. A frictionless step (`nd = 0`, whose adjoint is solved by
    CG; this serves its tangent solve): `k_z` times `normal.inverse_preconditioner`.
    """
    if not precondition:
        return lambda v: v
    contact, kz, kt = frozen[0], frozen[4], frozen[5]
    compliance, poisson = theta[0], theta[1]
    nd = config.nd
    if nd == 0:
        inverse_k = inverse_preconditioner(operator, operator.normal_spectrum(poisson),
                                           poisson)

        def apply_normal(v):
            v_p, v_q, v_dz, v_dt = v
            m = (kz / compliance) * inverse_k(jnp.where(contact, v_p, 0))
            return jnp.where(contact, m, v_p), v_q, v_dz, v_dt

        return apply_normal
    nn = compliance * operator.normal_spectrum(poisson)
    xx, _, yy = operator.tangential_blocks(poisson)
    inverse = block_preconditioner(
        operator, nn, compliance * xx, compliance * yy if nd == 2 else None,
        compliance=compliance, poisson=poisson)

    def apply(v):
        v_p, v_q, v_dz, v_dt = v
        field = jnp.where(contact[None], jnp.concatenate([v_p[None], v_q]), 0)
        m = inverse(field)
        m_p = jnp.where(contact, kz * m[0], v_p)
        m_q = jnp.where(contact[None], kt * m[1:], v_q)
        return m_p, m_q, v_dz, v_dt

    return apply


def _unless_forward_failed(solution, frozen, throw: bool):
    """A step's adjoint or tangent `solution` where its forward solve converged; where
    it did not, that is no derivative: the forward's own `RESULTS` error (`throw`), or
    NaN. (The adjoint solve of such a step often fails too, and its message, about
    the adjoint's `max_steps`, would point at the wrong cause.)"""
    converged, result = frozen[9], frozen[10]
    if throw:
        solution = result.error_if(solution, ~converged)
    return jax.tree.map(lambda v: jnp.where(converged, v, jnp.nan), solution)


def _reported(solution, ok, throw: bool):
    """A linear solve's `solution` (a pytree) as the caller sees it: raises
    `RESULTS.adjoint_not_converged` where not `ok` (`throw`), else NaN there."""
    if throw:
        return eqx.error_if(solution, ~ok, RESULTS[RESULTS.adjoint_not_converged])
    return jax.tree.map(lambda v: jnp.where(ok, v, jnp.nan), solution)


def _make_attach(config: _Spec, adjoint: ImplicitAdjoint, rtol: float, throw: bool):
    """A function `x, slip, seed = attach(x, slip, frozen, theta, operator, seed)` that
    returns `x`, `slip` unchanged and whose vector-Jacobian product is the implicit one.

    `seed` carries nothing forward (zeros); backwards, the cotangent that reaches it is
    the adjoint of the NEXT step (returned by that step's `bwd` as the cotangent of its
    `seed` input), used as the initial guess of this step's adjoint solve: consecutive
    steps have close adjoints. Its own cotangent never enters a parameter gradient.
    """
    maxiter = adjoint.max_steps

    @jax.custom_vjp
    def attach(x, slip, frozen, theta, operator, seed):
        return x, slip, jax.tree.map(jnp.zeros_like, seed)

    def fwd(x, slip, frozen, theta, operator, seed):
        return (attach(x, slip, frozen, theta, operator, seed),
                (x, frozen, theta, operator))

    def bwd(saved, cotangents):
        x, frozen, theta, operator = saved
        x_bar, slip_bar, guess = cotangents
        kt = frozen[5]
        if config.nd > 0:
            _, slip_vjp = jax.vjp(
                lambda x, theta: _slip_out(operator, config, x, theta, kt), x, theta)
            x_extra, theta_extra = slip_vjp(slip_bar)
            x_bar = jax.tree.map(jnp.add, x_bar, x_extra)
        else:
            theta_extra = None

        _, residual_vjp = jax.vjp(
            lambda x, theta: _residual(operator, config, frozen, x, theta), x, theta)

        def by_gmres():
            precondition = _transposed_preconditioner(operator, config, frozen, theta,
                                                      adjoint.precondition)
            return _right_preconditioned_gmres(
                lambda v: residual_vjp(v)[0], precondition, x_bar, guess, rtol,
                adjoint.restart, maxiter, _gmres_method(adjoint))

        if config.nd == 0:
            lam, ok = _normal_adjoint(operator, config, frozen, theta, x_bar, guess,
                                      rtol, maxiter)
        elif config.nd == 1 and not config.coupled:
            def by_cg():
                return _uncoupled_x_adjoint(
                    operator, config, frozen, theta, x_bar, guess, rtol, maxiter,
                    lambda v: residual_vjp(v)[0])

            if config.tangential_force_control[0]:
                lam, ok = jax.lax.cond(frozen[3], by_gmres, by_cg)  # sliding: GMRES
            else:
                lam, ok = by_cg()
        else:
            lam, ok = by_gmres()
        lam = _reported(lam, ok | ~frozen[9], throw)
        lam = _unless_forward_failed(lam, frozen, throw)
        theta_bar = residual_vjp(lam)[1]
        theta_bar = jax.tree.map(jnp.negative, theta_bar)
        if theta_extra is not None:
            theta_bar = jax.tree.map(jnp.add, theta_bar, theta_extra)
        zero = lambda tree: jax.tree.map(jnp.zeros_like, tree)  # noqa: E731
        return zero(x), zero(slip_bar), None, theta_bar, zero(operator), lam

    attach.defvjp(fwd, bwd)
    return attach


def _make_tangent(config: _Spec, adjoint: ImplicitAdjoint, rtol: float, throw: bool):
    """A function `x, slip = attach(x, slip, frozen, theta, operator)` that returns
    `x`, `slip` unchanged and whose JVP is the implicit one: the tangent `x_dot`
    solves `(dF/dx) x_dot = -(dF/dtheta) theta_dot` on the frozen sets (GMRES,
    right-preconditioned as the adjoint; frictionless steps by projected CG,
    `_normal_tangent`), `slip_dot` follows from `x_dot`. Only the
    tangents of `theta` enter (`frozen` and the operator are held)."""

    @jax.custom_jvp
    def attach(x, slip, frozen, theta, operator):
        return x, slip

    @attach.defjvp
    def attach_jvp(primals, tangents):
        x, slip, frozen, theta, operator = primals
        theta_dot = tangents[3]

        # One linearisation in (x, theta): dF/dtheta theta_dot and the map dF/dx.
        _, both = jax.linearize(
            lambda x_, th: _residual(operator, config, frozen, x_, th), x, theta)
        f_dot = both(jax.tree.map(jnp.zeros_like, x), theta_dot)
        zero_theta = jax.tree.map(jnp.zeros_like, theta)

        def linear(v):
            return both(v, zero_theta)
        precondition = _transposed_preconditioner(operator, config, frozen, theta,
                                                  adjoint.precondition)
        # On flat vectors: `custom_linear_solve` transposes only a right-hand side
        # that is linear as a whole (some rows of `f_dot` are constant zeros). The
        # rows of `F` and the unknowns `x` share one structure: one `unravel`.
        b_flat, unravel = ravel_pytree(jax.tree.map(jnp.negative, f_dot))

        def flat(fn):
            return lambda v: ravel_pytree(fn(unravel(v)))[0]

        def gmres(matvec, b):
            v, ok = _right_preconditioned_gmres(
                matvec, flat(precondition), b, jnp.zeros_like(b), rtol, adjoint.restart,
                adjoint.max_steps, _gmres_method(adjoint))
            return _reported(v, ok | ~frozen[9], throw)

        def normal_cg(matvec, b):  # frictionless: projected CG, as the adjoint
            v, ok = _normal_tangent(operator, config, frozen, theta, unravel(b), linear,
                                    rtol, adjoint.max_steps)
            return _reported(ravel_pytree(v)[0], ok | ~frozen[9], throw)

        def normal_cg_transposed(vecmat, b):
            zero = jax.tree.map(jnp.zeros_like, x)
            v, ok = _normal_adjoint(operator, config, frozen, theta, unravel(b), zero,
                                    rtol, adjoint.max_steps)
            return _reported(ravel_pytree(v)[0], ok | ~frozen[9], throw)

        # A transposable solve (the transposed system by the same method): reverse
        # mode through the forward rule works too (without the adjoint's warm starts).
        solve, transpose = ((normal_cg, normal_cg_transposed) if config.nd == 0
                            else (gmres, gmres))
        x_dot = unravel(jax.lax.custom_linear_solve(flat(linear), b_flat, solve,
                                                    transpose))
        x_dot = _unless_forward_failed(x_dot, frozen, throw)
        if config.nd > 0:
            kt = frozen[5]
            _, slip_dot = jax.jvp(
                lambda x_, th: _slip_out(operator, config, x_, th, kt), (x, theta),
                (x_dot, theta_dot))
        else:
            slip_dot = jnp.zeros_like(slip)
        return (x, slip), (x_dot, slip_dot)

    return attach


def differentiable_step(
    solver: AbstractStepSolver, problem: StepProblem, guess: StepGuess,
    adjoint_seed=None, *, adjoint: ImplicitAdjoint | None = None, throw: bool = True,
):
    """`solver.solve(problem, guess)` whose pressure, shear, approach, tangential
    displacement and slip carry exact (implicit) derivatives with respect to every
    array of `problem` (not the warm start `guess`, which does not change the
    solution).

    The forward solve runs on inputs with their derivatives stopped; the derivatives
    are attached afterwards by `_make_attach` (see the module docs). `adjoint_seed`
    (`None`, or the seed returned by the previous step) links the adjoint solves of
    consecutive steps (warm start; in forward mode it passes through unchanged).
    `adjoint`: an `ImplicitAdjoint` (default one);
    `throw`: a non-converged adjoint raises (`True`) or gives NaN cotangents.

    **Returns:** `(StepResult, seed)`, the seed to pass to the next step.
    """
    adjoint = ImplicitAdjoint() if adjoint is None else adjoint
    sg = jax.lax.stop_gradient
    res = solver.solve(sg(problem), sg(guess))
    config = _Spec(problem.nd, problem.coupled, problem.normal_force_control,
                   tuple(problem.tangential_force_control), adjoint.precondition)
    operator = problem.operator
    compliance, poisson = problem.compliance, problem.poisson
    dtype = problem.dtype
    kz, kt = _self_compliance(sg(operator), config, sg(compliance), sg(poisson))
    kz, kt = sg(kz), sg(kt)
    contact = res.pressure > 0
    nd = config.nd
    slip_sign = jnp.sign(res.shear)
    x = (res.pressure, res.shear, res.approach / kz, res.delta_t / kt)
    fixed = jnp.concatenate([x[2][None], x[3]])
    slip_weight = jnp.ones_like(res.pressure)
    slip_direction = jnp.zeros_like(res.shear)
    if nd == 2:
        # Across the slip direction the row `q + mu p s / |s|` has derivative
        # ~ mu p k_t / |s| times the operator, unbounded at the stick-slip boundary;
        # times `|s| / (|s| + k_t mu p)` it is bounded and tends to the stick row
        # `s / k_t` as |s| -> 0 (along the slip direction the derivative is 1: kept).
        increment = res.slip - problem.previous_slip
        size = jnp.sqrt(jnp.sum(increment * increment, axis=0))
        scale = size + kt * jnp.asarray(problem.friction, dtype) * res.pressure
        # A cell of zero slip keeps its row (there it is `q`: `_residual`'s guard).
        slip_weight = sg(jnp.where(size > 0, size / jnp.where(size > 0, scale, 1), 1.0))
        slip_direction = sg(increment / jnp.where(size > 0, size, 1)[None])
    # The gross-sliding equations only where the forward solved the step as such:
    # no stick cell below the friction limit (2-D slip fanning out) is not sliding.
    # Last: whether the forward converged, and its RESULTS (`_unless_forward_failed`).
    frozen = (contact, res.stick & contact, slip_sign, res.gross_sliding, kz, kt, fixed,
              slip_weight, slip_direction, sg(res.converged), sg(res.result))
    theta = (jnp.asarray(compliance, dtype), jnp.asarray(poisson, dtype),
             jnp.asarray(problem.friction, dtype), problem.gap, problem.history,
             problem.previous_slip, jnp.asarray(problem.normal_target, dtype),
             jnp.asarray(problem.tangential_target, dtype))
    rtol = solver.tolerance(dtype) if adjoint.rtol is None else adjoint.rtol
    slip = res.slip if nd > 0 else jnp.zeros_like(res.slip)
    if adjoint_seed is None:
        adjoint_seed = empty_seed(res.pressure, res.shear)
    if adjoint.mode == "forward":
        attach = _make_tangent(config, adjoint, rtol, throw)
        (p, q, dz, dt), slip = attach(x, slip, frozen, theta, operator)
        seed = adjoint_seed
    else:
        attach = _make_attach(config, adjoint, rtol, throw)
        (p, q, dz, dt), slip, seed = attach(x, slip, frozen, theta, operator,
                                            adjoint_seed)
    result = res.replace(pressure=p, shear=q, approach=dz * kz, delta_t=dt * kt,
                         slip=slip)
    return result, seed


def empty_seed(pressure, shear):
    """The adjoint seed of a first step: zeros shaped like
    `(p, q, delta_z, delta_t)`."""
    dtype = pressure.dtype
    return (jnp.zeros_like(pressure), jnp.zeros_like(shear), jnp.zeros((), dtype),
            jnp.zeros(shear.shape[:1], dtype))
