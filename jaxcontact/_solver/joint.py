r"""`JointPCG`: one coupled frictional step solved jointly, one projected CG over
`(p, q)`.

The normal and tangential problems are iterated together with the full symmetric
half-space operator

    [u_z]       [K_zz  K_zt] [p]
    [u_t] = C   [K_tz  K_tt] [q]          (K_tz = K_zt^T: reciprocal theorem)

applied once per iteration, on the conditions of the separate solvers at a common
`(p, q)`: the normal gap (`g = h + u_z - delta_z >= 0`, `p >= 0`, `p g = 0`, load or
approach prescribed) and the incremental Coulomb law (`ds = b + u_t - delta_t` is 0 on
stick cells `|q| < mu p` and opposite to `q` on slip cells `|q| = mu p`, load or
displacement per direction), with `h = h0 + history_z`, `b = history_t - previous_slip`.

Coulomb friction is not associated, so the friction bound `B` is LAGGED: frozen, the
inner problem is the convex quadratic programme

    min 1/2 t.C K t + p.(h - delta_z) + q.(b - delta_t),  p >= 0,  |q_i| <= B_i

(plus the loads), iterated by a projected, preconditioned CG; `B` is updated to `mu p`
(slip cells following their discs) whenever the inner residual has dropped below
`sigma` times its value at the last update: an inexact outer loop on the bound only.
A converged answer is always certified with exact displacements and the bound `mu p`.

This differs from a textbook projected PCG in:

1. the step minimises the quadratic exactly over span{preconditioned gradient's `p`
   part, its `q` part, the previous change} (a 3x3 system, quadratic forms by
   Parseval from one forward transform): line searches and the CG recurrence at once;
2. the whole change of `x` after the projections (clipping, discs, load fixes) is
   transformed, so displacements are exact at every iteration (1.5 applications);
3. the active sets: re-entering penetrating cells are free pressure variables; slip
   cells rotate on their discs with the disc curvature `lambda / B` in the Hessian;
   released cells (wrong-sign slip) become free, unless their slip is too large to
   undo (`flip`: they jump across their disc instead);
4. the preconditioner is the full-plane inverse of the operator's block diagonal
   (`precondition.block_preconditioner`) restricted to the free variables, the
   diagonal right after a release (`fft_residual`), blended with the diagonal on
   rotating cells by their curvature (`blend_after`);
5. loads are restored after every projection: stick cells take the deficit, or, where
   they cannot or none sticks, one common shift of every contact cell found by Newton
   steps (`spread_when`, `spread_newton`);
6. the bound is also updated in the first `early` iterations and after
   `update_when_stuck` iterations without the residual halving; the iteration gives up
   (`RESULTS.stalled`) after `stall` such iterations.

Gross sliding under tangential load control (`|F| >= mu W` to `rtol / 2`,
`tangential.gross_sliding`, `F` the load of the load-controlled directions,
`base.applied_load`): `q = B F/|F|` on every contact cell, only `p` iterates; the
load-controlled directions' `delta_t` is the mean of `u_t + b` over the contact.
Design notes and the measurements behind every default: `benchmarks/notes/joint.md`.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from .._results import RESULTS
from .base import AbstractStepSolver, applied_load, make_result, run, step_outcome
from .base import safe_div as _safe_div
from .precondition import block_preconditioner
from .residual import (
    coulomb_residual,
    gap_residual,
    masked_mean,
    rigid_tangential_displacement,
)
from .tangential import dot as _dot
from .tangential import gross_sliding
from .tangential import solve_small as _solve_small


def _inv_norm(q):
    """`1 / |q|` per cell (0 where `q = 0`)."""
    m2 = _dot(q, q)
    pos = m2 > 0
    return jnp.where(pos, jax.lax.rsqrt(jnp.where(pos, m2, 1.0)), 0.0)


def _sum2(a):
    """Per-component totals `(nd,)` of a vector field."""
    return jnp.sum(a, axis=(-2, -1))


def _onto_discs(q, bound, follow):
    """Each cell's shear onto its disc `|q| <= bound`, the `follow` cells onto its
    boundary circle (`|q| = bound`; those with `q = 0` to zero): one `rsqrt` pass for
    both (it is among the costliest elementwise passes of the loop)."""
    m2 = _dot(q, q)
    pos = m2 > 0
    inv = jnp.where(pos, jax.lax.rsqrt(jnp.where(pos, m2, 1.0)), 0.0)
    onto = follow | (m2 > bound * bound)
    return q * jnp.where(onto, bound * inv, 1.0)[None]


def _solve3(h, g):
    """Minimiser `a = -H^{-1} g` of `g.a + a.H a / 2` for a 3x3 positive semidefinite
    `H`, robust to zero or dependent basis vectors (Jacobi scaling, a tiny ridge)."""
    d = jnp.diagonal(h)
    s = jnp.where(d > 0, jax.lax.rsqrt(jnp.where(d > 0, d, 1.0)), 0.0)
    hs = h * s[:, None] * s[None, :] + jnp.diag(jnp.where(d > 0, 1e-12, 1.0))
    gs = g * s
    a = [[hs[i, j] for j in range(3)] for i in range(3)]
    b = [-gs[i] for i in range(3)]
    for k in range(3):
        for i in range(k + 1, 3):
            f = a[i][k] / a[k][k]
            for j in range(k, 3):
                a[i][j] = a[i][j] - f * a[k][j]
            b[i] = b[i] - f * b[k]
    x = [None] * 3
    for i in (2, 1, 0):
        acc = b[i]
        for j in range(i + 1, 3):
            acc = acc - a[i][j] * x[j]
        x[i] = acc / a[i][i]
    return jnp.stack(x) * s


def _parseval_weights(operator):
    """Weights `w` and normaliser `N` with `a.b = sum(w Re(conj(a^) b^)) / N` for the
    spectra `a^ = forward(a)` of the operator (rfft along the last axis)."""
    lx, n_fft = operator.fft_shape
    count = lx * n_fft
    w = np.full(n_fft // 2 + 1, 2.0)
    w[0] = 1.0
    if n_fft % 2 == 0:
        w[-1] = 1.0
    return w, float(count)


class _Evaluation(eqx.Module):
    """Both residuals at an iterate, and what the next iteration needs of them."""

    g: Float[Array, "nx ny"]  # normal gap [length]
    dz: Float[Array, ""]  # approach [length]
    res_n: Float[Array, ""]
    ds: Float[Array, "nd nx ny"]  # slip increment [length]
    dt: Float[Array, " nd"]  # rigid tangential displacement [length]
    stick: Bool[Array, "nx ny"]
    res_t: Float[Array, ""]
    residual: Float[Array, ""]
    gate: Float[Array, ""]  # `residual`, the shear scale at least `||b + u_t||_contact`
    inv_norm: Float[Array, "nx ny"]  # 1 / |q|


class _JointOperator:
    """The step's coupled operator and contact conditions, built once per step (the
    loop invariants of `JointPCG`): symbols in the `(ky, kx)` layout of the column
    FFTs on non-periodic grids, Parseval weights folded in, the preconditioner."""

    def __init__(self, solver: "JointPCG", problem):
        nd = problem.nd
        operator = problem.operator
        grid = operator.grid
        dtype = problem.dtype
        compliance, poisson = problem.compliance, problem.poisson
        self.nd, self.grid, self.dtype = nd, grid, dtype
        self.nx, self.ny = grid.shape
        self.area = grid.cell_area
        self.rtol = solver.tolerance(dtype)
        self.load_n = problem.normal_force_control
        fc_tuple = tuple(bool(f) for f in problem.tangential_force_control)
        self.fc = jnp.asarray(fc_tuple)
        self.any_force = any(fc_tuple)
        self.normal_target = jnp.asarray(problem.normal_target, dtype)
        self.tangential_target = jnp.asarray(problem.tangential_target, dtype)
        self.friction = jnp.asarray(problem.friction, dtype)
        self.h = problem.gap + problem.history[2]
        self.b = problem.history[:nd] - problem.previous_slip
        # A cell projected onto its disc must not count as stick by round-off.
        self.stick_tol = max(solver.stick_tol, 64 * float(jnp.finfo(dtype).eps))
        self.spread_when, self.spread_newton = solver.spread_when, solver.spread_newton

        def symbols(transposed):
            """`(nn, xx, xy, yy, zx, zy, czx, czy)` in the `(kx, ky)` layout of
            `operator.forward`, or `transposed` to `(ky, kx)`."""
            nn = compliance * operator.normal_spectrum(poisson, transposed)
            xx, xy, yy = operator.tangential_blocks(poisson, transposed)
            xx = compliance * xx
            if nd == 2:
                xy, yy = compliance * xy, compliance * yy
            zx, zy = operator.coupling_spectra(poisson, transposed)
            czx = compliance * zx  # u_z <- q_x: i czx; u_x <- p: -i czx
            czy = compliance * zy if (nd == 2 and zy is not None) else None
            return nn, xx, xy, yy, zx, zy, czx, czy

        nn, xx, xy, yy, zx, zy, czx, czy = symbols(False)
        w_ky, n_par = _parseval_weights(operator)
        w_ky = jnp.asarray(w_ky, dtype)[None, :]  # (1, ky): broadcasts over kx
        # Self-compliances (the operator's diagonal): the kernels at zero offset.
        self.c_zz = jnp.sum(w_ky * nn) / n_par
        self.c_tt = jnp.sum(w_ky * xx) / n_par
        # Not on periodic grids: their inverse has no zero mode (notes: fft_precond).
        self.fft_precond = solver.precondition and not grid.periodic
        if self.fft_precond:
            self.precondition = block_preconditioner(
                operator, nn, xx, yy if nd == 2 else None, compliance=compliance,
                poisson=poisson)
        if not grid.periodic:
            # The `(ky, kx)` layout of `forward` below: spectral passes contiguous.
            nn, xx, xy, yy, zx, zy, czx, czy = symbols(True)
            w_ky = jnp.swapaxes(w_ky, -1, -2)
        self.nn, self.xx, self.xy, self.yy = nn, xx, xy, yy
        self.czx, self.czy = czx, czy
        # Parseval weights folded into the real symbols: quadratic forms become plain
        # sums over a spectrum.
        wn = w_ky / n_par
        self.s_zz = wn * nn
        self.s_xx = wn * xx
        self.s_zx = wn * czx
        if nd == 2:
            self.s_xy, self.s_yy = wn * xy, wn * yy
            self.s_zy = wn * czy if czy is not None else None
        self.periodic = grid.periodic
        self.operator = operator
        self.w_p = self.c_tt / self.c_zz  # preconditioner weight of p relative to q
        self.f_norm, self.direction = applied_load(self.tangential_target, fc_tuple)

    # ---- the operator ------------------------------------------------------------
    def k_of_p(self, ph):
        """Spectra `(u_z, u_t...)` of a pressure spectrum."""
        pr, pi = jnp.real(ph), jnp.imag(ph)
        czx, czy = self.czx, self.czy
        re = [self.nn * pr, czx * pi]
        im = [self.nn * pi, -czx * pr]
        if self.nd == 2:
            zero = jnp.zeros_like(pr)
            re.append(czy * pi if czy is not None else zero)
            im.append(-czy * pr if czy is not None else zero)
        return jax.lax.complex(jnp.stack(re), jnp.stack(im))

    def k_of_q(self, qh):
        """Spectra `(u_z, u_t...)` of a shear spectrum `(nd, ...)`."""
        # Real arithmetic on real symbols: a complex product would make XLA hoist
        # complex copies of the symbols out of the loop (twice the memory traffic).
        czx, czy = self.czx, self.czy
        xr, xi = jnp.real(qh[0]), jnp.imag(qh[0])
        if self.nd == 1:
            return jax.lax.complex(jnp.stack([-czx * xi, self.xx * xr]),
                                   jnp.stack([czx * xr, self.xx * xi]))
        yr, yi = jnp.real(qh[1]), jnp.imag(qh[1])
        zr, zi = -czx * xi, czx * xr
        if czy is not None:
            zr, zi = zr - czy * yi, zi + czy * yr
        re = [zr, self.xx * xr + self.xy * yr, self.xy * xr + self.yy * yr]
        im = [zi, self.xx * xi + self.xy * yi, self.xy * xi + self.yy * yi]
        return jax.lax.complex(jnp.stack(re), jnp.stack(im))

    def k_full(self, th):
        return self.k_of_p(th[0]) + self.k_of_q(th[1:])

    def quad_forms(self, zh):
        """`(z_p.C K_zz z_p, z_p.C K_zt z_q, z_q.C K_tt z_q)` from the spectrum of
        `z = (z_p, z_q)`: one pass over it (Parseval)."""
        pr, pi = jnp.real(zh[0]), jnp.imag(zh[0])
        xr, xi = jnp.real(zh[1]), jnp.imag(zh[1])
        t11 = self.s_zz * (pr * pr + pi * pi)
        t12 = -self.s_zx * (pr * xi - pi * xr)  # Re(conj(P) i zx Q) = -zx Im(conj(P) Q)
        t22 = self.s_xx * (xr * xr + xi * xi)
        if self.nd == 2:
            yr, yi = jnp.real(zh[2]), jnp.imag(zh[2])
            if self.s_zy is not None:
                t12 = t12 - self.s_zy * (pr * yi - pi * yr)
            t22 = (t22 + 2 * self.s_xy * (xr * yr + xi * yi)
                   + self.s_yy * (yr * yr + yi * yi))
        return jnp.sum(jnp.stack([t11, t12, t22]), axis=(-2, -1))

    def forward(self, x):
        """`operator.forward`, on non-periodic grids in the `(ky, kx)` layout (the
        column transforms along the contiguous axis)."""
        return self.operator.forward(x, transposed=not self.periodic)

    def inverse(self, uh):
        return self.operator.inverse(uh, transposed=not self.periodic)

    def apply(self, x):
        """Displacements `(u_z, u_t...)` of the traction `(p, q...)`: one
        application."""
        return self.inverse(self.k_full(self.forward(x)))

    def exact(self, x):
        """Exact displacements and the residual scales of the separate solvers,
        `||C K_zz p||` and `||C K_tt q|| + ||b + C K_tz p||_contact` (1.5 applications:
        the p and q parts are transformed back separately)."""
        nd = self.nd
        th = self.forward(x)
        both = self.inverse(jnp.concatenate([self.k_of_p(th[0]), self.k_of_q(th[1:])]))
        up, uq = both[:1 + nd], both[1 + nd:]
        contact = self.friction * x[0] > 0
        s_n = jnp.sqrt(jnp.sum(up[0] * up[0]))
        s_t = jnp.sqrt(jnp.sum(uq[1:] * uq[1:])) + jnp.sqrt(
            jnp.sum(jnp.where(contact[None], up[1:] + self.b, 0) ** 2))
        return up + uq, jnp.stack([s_n, s_t])

    # ---- the conditions (as normal._evaluate and tangential_cg) ---------------------
    def sliding_of(self, p):
        if not self.any_force:
            return jnp.array(False)
        limit = self.area * jnp.sum(self.friction * p)
        return gross_sliding(self.f_norm, limit, self.rtol)

    def stick_of(self, q, bound):
        """Contact cells strictly inside their disc `|q| < bound` (by `stick_tol`)."""
        return (bound > 0) & (_dot(q, q) < (bound * (1 - self.stick_tol)) ** 2)

    def evaluate(self, x, u, scales, bound, sliding) -> _Evaluation:
        """Both residuals at `(p, q)` with displacements `u`, the tangential one for
        the friction bound `bound`, relative to the `scales` of the last certification.

        `gate`, the residual that decides whether to certify, takes as tangential
        scale at least `||b + u_t||` over the contact, which the exact scale of this
        iterate, `||C K_tt q|| + ||b + C K_tz p||_contact`, cannot be below (triangle
        inequality): the frozen scale is that of an earlier iterate, and a warm start
        without shear whose coupling displacement vanishes on the contact (a contact
        of one cell, whose own `K_tz` is zero; `nu = 0.5`) has a zero scale, against
        which no residual of the step could reach `rtol`."""
        fc, area = self.fc, self.area
        tangential_target = self.tangential_target
        p, q = x[0], x[1:]
        g, dz, res_n = gap_residual(self.h + u[0], p > 0, self.load_n,
                                    self.normal_target, scales[0])
        contact_t = bound > 0
        w = u[1:] + self.b
        stick = self.stick_of(q, bound)
        inv = _inv_norm(q)
        dt = rigid_tangential_displacement(w, stick, q * inv[None], contact_t, fc,
                                           tangential_target)
        if self.any_force:
            # Gross sliding: a load-controlled direction's delta_t is the mean of w
            # over the contact (no stick cell fixes it), as `Rounds` and the adjoint.
            dt = jnp.where(sliding & jnp.asarray(fc), masked_mean(w, contact_t), dt)
        ds = w - dt[:, None, None]
        ds_mag = jnp.sqrt(_dot(ds, ds))
        slip_violation = ds + (ds_mag * inv)[None] * q

        def tangential(scale):
            return coulomb_residual(ds, slip_violation, stick, contact_t, scale,
                                    area * _sum2(q), tangential_target, fc,
                                    area * jnp.sum(bound), sliding)

        res_t = tangential(scales[1])
        w_contact = jnp.sqrt(jnp.sum(jnp.where(contact_t[None], w, 0) ** 2))
        gate = jnp.maximum(res_n, tangential(jnp.maximum(scales[1], w_contact)))
        return _Evaluation(g=g, dz=dz, res_n=res_n, ds=ds, dt=dt, stick=stick,
                           res_t=res_t, residual=jnp.maximum(res_n, res_t), gate=gate,
                           inv_norm=inv)

    # ---- loads and projections -------------------------------------------------------
    def rescale(self, p):
        total = self.area * jnp.sum(p)
        factor = self.normal_target / jnp.where(total > 0, total, 1)
        return p * jnp.where(total > 0, factor, 0.0)

    def spread_load(self, q, bound):
        """Restore the tangential load by one common shift `lam` [stress] of every
        contact cell: cells inside their disc move by `lam` (and onto the disc if they
        cross it), cells on it stay on it and turn towards `lam` (two components:
        shifted by `lam B / max B`, so edge cells with a tiny bound keep their
        direction; one component: they flip where `lam` crosses them). `lam` solves
        the load equation by `spread_newton` Newton steps."""
        nd, fc, dtype = self.nd, self.fc, self.dtype
        contact = bound > 0
        on_disc = contact & ~self.stick_of(q, bound)
        target = self.tangential_target / self.area
        eye = jnp.eye(nd, dtype=dtype)

        if nd == 2:
            b_max = jnp.max(bound)
            factor = jnp.where(on_disc, bound / jnp.where(b_max > 0, b_max, 1.0), 1.0)
        else:
            factor = jnp.ones_like(bound)

        def shifted(lam):
            y = q + jnp.where(contact[None], factor[None] * lam[:, None, None], 0.0)
            m2 = _dot(y, y)
            inv = jnp.where(m2 > 0, jax.lax.rsqrt(jnp.where(m2 > 0, m2, 1.0)), 0.0)
            onto = contact & (on_disc | (m2 > bound * bound))
            scale = jnp.where(onto, bound * inv, 1.0)
            return y * scale[None], y * inv[None], scale, onto

        def newton(_, lam):
            qs, yh, scale, onto = shifted(lam)
            err = jnp.where(fc, _sum2(jnp.where(contact[None], qs, 0.0)) - target, 0.0)
            # d q_i / d lam: factor x (the identity inside, scale (I - y^ y^T) on it).
            w = jnp.where(contact, scale * factor, 0.0)
            jac = jnp.stack([jnp.stack([
                jnp.sum(w * (float(i == j) - jnp.where(onto, yh[i] * yh[j], 0.0)))
                for j in range(nd)]) for i in range(nd)])
            both = fc[:, None] & fc[None, :]
            jac = jnp.where(both, jac, eye)
            det = jac[0, 0]
            if nd == 2:
                det = det * jac[1, 1] - jac[0, 1] * jac[1, 0]
            ok = jnp.abs(det) > 0
            step = _solve_small(jnp.where(ok, jac, eye), err)
            return lam - jnp.where(ok & fc, step, 0.0)

        lam = jax.lax.fori_loop(0, self.spread_newton, newton, jnp.zeros(nd, dtype))
        return jnp.where(contact[None], shifted(lam)[0], q)

    def fix_load(self, q, bound):
        """Restore the loads: `shift_stick`, and where that leaves a load error above
        `spread_when` x mu W or no cell sticks, `spread_load` first."""
        fixed = self.shift_stick(q, bound)
        err = jnp.abs(self.area * _sum2(fixed) - self.tangential_target)
        err = _safe_div(jnp.max(jnp.where(self.fc, err, 0.0)),
                        self.area * jnp.sum(bound))
        bad = (err > self.spread_when) | ~jnp.any(self.stick_of(q, bound))
        # A `cond`: the Newton steps run only where needed.
        return jax.lax.cond(
            bad, lambda: self.shift_stick(self.spread_load(q, bound), bound),
            lambda: fixed)

    def shift_stick(self, q, bound):
        """Shift the stick cells (or, if none, all contact cells) to carry the load.
        Without stick cells the contact cells move along their discs (renormalised),
        so that none counts as stick by being moved inside."""
        contact = bound > 0
        stick = self.stick_of(q, bound)
        any_stick = jnp.any(stick)
        where = jnp.where(any_stick, stick, contact)
        count = jnp.sum(where)
        deficit = _safe_div(self.tangential_target / self.area - _sum2(q), count)
        shift = jnp.where(self.fc[:, None, None], deficit[:, None, None] * where[None],
                          0.0)
        moved = q + shift
        return _onto_discs(moved, bound, contact & ~any_stick)

    def settle_shear(self, q, bound, follow, sliding):
        """Shear on the discs `|q| <= bound`: `follow` cells on the boundary (slip
        cells when the bound is updated), the others projected; loads restored."""
        q = _onto_discs(q, bound, follow)
        if self.any_force:
            q = jnp.where(sliding, bound[None] * self.direction[:, None, None],
                          self.fix_load(q, bound))
        return q


class _JointState(eqx.Module):
    """The iterate and the bookkeeping of the outer (bound) loop."""

    x: Float[Array, "1+nd nx ny"]  # (p, q)
    u: Float[Array, "1+nd nx ny"]  # C K x, exact up to round-off
    bound: Float[Array, "nx ny"]  # the lagged friction bound B
    sliding: Bool[Array, ""]
    scales: Float[Array, " 2"]  # residual normalisers of the last certification
    ev: _Evaluation
    p_start: Float[Array, "nx ny"]  # the pressure to restart from if all of it clips
    res_ref: Float[Array, ""]  # residual after the last bound update
    anchor: Float[Array, ""]  # residual at the last halving
    since: Int[Array, ""]  # iterations since the residual last halved
    fresh: Bool[Array, "nx ny"]  # cells bound to their disc by the last step
    prev: Float[Array, "1+nd nx ny"]  # the previous change of x ...
    k_prev: Float[Array, "1+nd nx ny"]  # ... its displacement ...
    prev_k_prev: Float[Array, ""]  # ... and their product
    it: Int[Array, ""]
    certified: Bool[Array, ""]  # this iterate's bound is mu p (it was updated)
    updates: Int[Array, ""]
    applications: Float[Array, ""]
    counts: Int[Array, " 2"]  # (periodic resyncs, bound updates)
    want: Bool[Array, ""]  # update the bound in the next iteration
    steady: Bool[Array, ""]  # no release in the last iteration (or nearly converged)


class JointPCG(AbstractStepSolver):
    """Joint projected CG over pressure and shear for a coupled frictional step (see
    the module docs). Needs a coupled step (`coupling` "x" or "full") with friction.

    **Arguments** (defaults chosen by the measurements in `benchmarks/notes/joint.md`):

    - `rtol`: relative tolerance of both contact residuals and the loads; `None`: `1e-8`
      in float64, `1e-5` in float32.
    - `max_steps`: iteration bound (at most one more iteration certifies).
    - `resync_every`: transform `x` itself instead of its change this often (round-off).
    - `precondition`: the full-plane inverse of the operator's block diagonal (non-
      periodic grids); `False`: its diagonal only.
    - `sigma`: update the bound when the residual fell below `sigma` x its value at the
      last update (0.3-0.6 within 1 % on Spence's ramp).
    - `early`: always update the bound in the first `early` iterations (the warm
      start's pressure is off by the load increment).
    - `update_when_stuck`: also update after this many iterations without the residual
      halving (a release/spread two-cycle without stick cells).
    - `stall`: give up (`RESULTS.stalled`) after this many iterations without halving.
    - `flip`: a released cell whose wrong-sign slip exceeds `flip` x `2 c_tt B` (what
      moving across its disc changes locally) jumps across its disc instead of being
      freed (a two-cycle at contact edges otherwise).
    - `fft_residual`: below this residual the full-plane preconditioner is kept right
      after a release (else the diagonal for that iteration).
    - `blend_after`: after this many iterations a rotating slip cell's direction
      blends the full-plane inverse and the diagonal by its disc curvature; `None`:
      `early + 1`.
    - `spread_when`, `spread_newton`: spread the tangential load deficit over every
      contact cell when the stick cells leave it above `spread_when` x mu W (or none
      sticks), by `spread_newton` Newton steps.
    - `stick_tol`: a cell sticks when `|q| < (1 - stick_tol) B` (at least 64 eps).
    """

    rtol: float | None = eqx.field(static=True, default=None)
    max_steps: int = eqx.field(static=True, default=2000)
    resync_every: int = eqx.field(static=True, default=25)
    precondition: bool = eqx.field(static=True, default=True)
    sigma: float = eqx.field(static=True, default=0.5)
    early: int = eqx.field(static=True, default=3)
    update_when_stuck: int = eqx.field(static=True, default=8)
    stall: int = eqx.field(static=True, default=150)
    flip: float = eqx.field(static=True, default=4.0)
    fft_residual: float = eqx.field(static=True, default=1e-4)
    blend_after: int | None = eqx.field(static=True, default=None)
    spread_when: float = eqx.field(static=True, default=1e-3)
    spread_newton: int = eqx.field(static=True, default=4)
    stick_tol: float = eqx.field(static=True, default=1e-10)

    def step_limit(self) -> int:
        # Exhaustion forces a bound update in the next iteration, which certifies.
        return self.max_steps + 1

    def supports(self, problem):
        if problem.nd not in (1, 2) or not problem.coupled:
            return ("the joint iteration needs a coupled frictional step (coupling "
                    '"x" or "full" with a tangential solve); use jc.Rounds()')
        return None

    def setup(self, problem) -> _JointOperator:
        return _JointOperator(self, problem)

    def _exhausted(self, it, since):
        return (it >= self.max_steps) | (since >= self.stall)

    def init(self, problem, k: _JointOperator, guess) -> _JointState:
        nd, dtype, area, fc = k.nd, k.dtype, k.area, k.fc
        nx, ny = k.nx, k.ny
        p_init = jnp.maximum(jnp.asarray(guess.normal, dtype), 0)
        if k.load_n:
            p_init = jnp.where(jnp.sum(p_init) > 0, p_init, jnp.ones_like(p_init))
            p_init = k.rescale(p_init)
        else:
            local = jnp.maximum(k.normal_target - k.h, 0) / k.c_zz
            p_init = jnp.where(jnp.sum(p_init) > 0, p_init, local)
        bound_init = k.friction * p_init
        sliding_init = k.sliding_of(p_init)
        q_init = jnp.asarray(guess.shear, dtype)
        if k.any_force:
            # No shear to start from (a first step): the load-controlled shear in
            # proportion to the pressure (inside the discs while |F| < mu W).
            total_p = area * jnp.sum(p_init)
            ratio = jnp.where(fc, _safe_div(k.tangential_target, total_p), 0.0)
            q_init = jnp.where(jnp.any(q_init != 0), q_init,
                               ratio[:, None, None] * p_init[None])
        q_init = k.settle_shear(q_init, bound_init, jnp.zeros((nx, ny), bool),
                                sliding_init)
        x_init = jnp.concatenate([p_init[None], q_init])
        u_init, scales_init = k.exact(x_init)
        ev_init = k.evaluate(x_init, u_init, scales_init, bound_init, sliding_init)
        zeros_x = jnp.zeros((1 + nd, nx, ny), dtype)
        return _JointState(
            x=x_init, u=u_init, bound=bound_init, sliding=sliding_init,
            scales=scales_init, ev=ev_init, p_start=p_init, res_ref=ev_init.residual,
            anchor=ev_init.residual, since=jnp.array(0),
            fresh=jnp.zeros((nx, ny), bool), prev=zeros_x, k_prev=zeros_x,
            prev_k_prev=jnp.zeros((), dtype), it=jnp.array(0),
            certified=jnp.array(True), updates=jnp.array(0),
            applications=jnp.asarray(1.5, dtype), counts=jnp.zeros(2, jnp.int32),
            want=jnp.array(False), steady=jnp.array(False))

    def terminate(self, problem, k, s: _JointState):
        # Leave only from a certified state (bound mu p; exact displacements and
        # scales when within the tolerance). Exhaustion is the algorithm's own: it
        # forces the bound update that certifies the last iterate.
        converged = s.ev.residual <= k.rtol
        done = (converged | self._exhausted(s.it, s.since)) & s.certified
        failure = RESULTS.where(s.since >= self.stall, RESULTS.stalled,
                                RESULTS.max_steps_reached)
        return done, RESULTS.where(converged, RESULTS.successful, failure)

    def step(self, problem, k: _JointOperator, s: _JointState) -> _JointState:
        nd, fc, dtype = k.nd, k.fc, k.dtype
        c_tt, w_p = k.c_tt, k.w_p
        early = self.early
        blend_after = early + 1 if self.blend_after is None else self.blend_after
        x, u, ev, bound, sliding = s.x, s.u, s.ev, s.bound, s.sliding
        p, q = x[0], x[1:]
        g, ds, stick = ev.g, ev.ds, ev.stick
        contact = p > 0
        contact_t = bound > 0
        # Pressure variables: contact cells and penetrating cells out of contact
        # (Polonsky-Keer's re-entry, set by the exact minimisation below).
        overlap = (~contact) & (g < 0)
        free_p = contact | overlap

        # -- active sets --
        q_hat = q * ev.inv_norm[None]
        slip_cells = contact_t & ~stick
        lam_raw = -_dot(ds, q_hat)
        release = slip_cells & (lam_raw < 0) & ~sliding
        # Not freed: cells bound to their disc by the last step, any cell at the early
        # bound updates.
        release = release & ~s.fresh & ~(s.want & (s.it <= early))
        flip = release & (-lam_raw > self.flip * c_tt * 2 * bound)
        release = release & ~flip
        full = (stick | release) & ~sliding
        if nd == 2:
            rotate = slip_cells & ~release & ~flip & ~sliding
            tt = jnp.where(rotate[None], jnp.stack([-q_hat[1], q_hat[0]]), 0)
            curv_disc = jnp.where(  # the disc curvature lambda / B of a rotation
                rotate, _safe_div(jnp.maximum(lam_raw, 0.0), bound), 0.0)
        else:
            rotate = jnp.zeros_like(contact)
            tt = jnp.zeros_like(q)
            curv_disc = jnp.zeros_like(p)

        # -- reduced gradient, preconditioned load-preserving directions --
        r_p = jnp.where(free_p, g, 0)
        r_q = jnp.where(full[None], ds, tt * _dot(tt, ds)[None])
        weight = jnp.where(full, 1.0, jnp.where(
            rotate, c_tt / (c_tt + curv_disc), 0.0))
        z_p_diag, pr_diag = w_p * r_p, weight[None] * r_q
        if k.fft_precond:
            # The full-plane inverse on the free variables; right after a release the
            # diagonal (two components: after the early iterations, only the released
            # cells take it).
            use_fft = s.steady
            if nd == 2:
                use_fft = use_fft | (s.it > early)
            m_r = jax.lax.cond(use_fft, k.precondition, jnp.zeros_like,
                               jnp.concatenate([r_p[None], r_q]))
            z_p = jnp.where(use_fft, jnp.where(free_p, m_r[0], 0), z_p_diag)
            rot = tt * _dot(tt, m_r[1:])[None]
            jacobi = r_q / c_tt
            # Rotating cells: blend inverse and diagonal by the curvature weight.
            blend = weight[None] * rot + (1 - weight)[None] * jacobi
            rot = jnp.where(s.it > blend_after, blend, rot)
            pr = jnp.where(use_fft, weight[None] * jnp.where(full[None], m_r[1:], rot),
                           pr_diag)
            if nd == 2:
                pr = jnp.where(release[None] & ~s.steady, jacobi, pr)
        else:
            z_p, pr = z_p_diag, pr_diag
        if k.load_n:
            z_p = jnp.where(free_p, z_p - _safe_div(jnp.sum(z_p), jnp.sum(free_p)), 0)
        if k.any_force:
            # Oblique projection onto load-preserving directions (tangential.py).
            n_w = jnp.sum(jnp.where(full, weight, 0))
            if nd == 2:
                wt0, wt1 = weight * tt[0], weight * tt[1]
                m01 = jnp.sum(wt0 * tt[1])
                m = jnp.stack([jnp.stack([n_w + jnp.sum(wt0 * tt[0]), m01]),
                               jnp.stack([m01, n_w + jnp.sum(wt1 * tt[1])])])
            else:
                m = n_w[None, None]
            eye = jnp.eye(nd, dtype=dtype)
            both = fc[:, None] & fc[None, :]
            m = jnp.where(both, m, eye)
            rhs = jnp.where(fc, _sum2(pr), 0.0)
            empty = jnp.where(jnp.trace(jnp.where(both, m, 0.0)) > 0, 0.0, 1.0)
            coef = jnp.where(fc, _solve_small(m + empty * eye, rhs), 0.0)
            basis = jnp.where(full[None], coef[:, None, None],
                              tt * _dot(coef[:, None, None], tt)[None])
            z_q = pr - weight[None] * basis
        else:
            z_q = pr
        z = jnp.concatenate([z_p[None], z_q])

        # -- exact minimisation over span{z_p, z_q, previous change} --
        h11, h12, h22 = k.quad_forms(k.forward(z))
        prev, kprev = s.prev, s.k_prev
        have = s.it > 0  # the previous change is never dropped (no restarts)

        def disc(a, b_):
            return jnp.sum(curv_disc * _dot(a, b_))

        g1 = jnp.sum(r_p * z_p)
        g2 = jnp.sum(r_q * z_q)
        g3 = jnp.where(have, jnp.sum(r_p * prev[0]) + jnp.sum(r_q * prev[1:]), 0.0)
        h22 = h22 + disc(z_q, z_q)
        h13 = jnp.where(have, jnp.sum(z_p * kprev[0]), 0.0)
        h23 = jnp.where(have, jnp.sum(z_q * kprev[1:]) + disc(z_q, prev[1:]), 0.0)
        h33 = jnp.where(have, s.prev_k_prev + disc(prev[1:], prev[1:]), 0.0)
        hm = jnp.stack([jnp.stack([h11, h12, h13]), jnp.stack([h12, h22, h23]),
                        jnp.stack([h13, h23, h33])])
        alpha = _solve3(hm, jnp.stack([g1, g2, g3]))
        alpha = jnp.where(jnp.isfinite(alpha), alpha, 0.0)
        a1, a2, a3 = alpha[0], alpha[1], alpha[2]
        step = jnp.concatenate([(a1 * z_p)[None], a2 * z_q]) + a3 * prev

        # -- projections --
        x_step = x + step
        p_step, q_step = x_step[0], x_step[1:]
        # Cells out of contact stay out unless they penetrate (`free_p`).
        p_new = jnp.where(free_p, jnp.maximum(p_step, 0), 0)
        if k.load_n:
            p_new = jnp.where(jnp.sum(p_new) > 0, p_new, s.p_start)
            p_new = k.rescale(p_new)
        # Slip cells that stay slip go back ON their disc; flipped cells onto it,
        # opposite to their slip (one component: the other side).
        keep_on = slip_cells & ~release & ~sliding
        q_flip = -q if nd == 1 else -(bound * _inv_norm(ds))[None] * ds
        q_step = jnp.where(flip[None], q_flip, q_step)
        q_new = k.settle_shear(q_step, bound, keep_on, sliding)
        # The bound update decided after the last iteration, made inside this one.
        upd = s.want
        bound_new = jnp.where(upd, k.friction * p_new, bound)
        sliding_new = jnp.where(upd, k.sliding_of(p_new), sliding)

        def move_to_bound(q_):
            # Slip cells follow their discs; entering cells start on theirs, opposite
            # to their slip increment (contact edges slip).
            follow = (contact_t & ~k.stick_of(q_, bound) & (p_new > 0)
                      & ~sliding_new)
            entering = (~contact_t) & (p_new > 0) & ~sliding_new
            q_ = jnp.where(entering[None], -ds * _inv_norm(ds)[None], q_)
            follow = follow | entering
            return k.settle_shear(q_, bound_new, follow, sliding_new)

        q_new = jax.lax.cond(upd, move_to_bound, lambda q_: q_, q_new)
        x_new = jnp.concatenate([p_new[None], q_new])

        # -- the exact displacement of the whole change (one application); every
        # `resync_every` iterations that of x_new itself (round-off drift) --
        d = x_new - x
        it = s.it + 1
        periodic = it % self.resync_every == 0
        kt = k.apply(jnp.where(periodic, x_new, d))
        u_new = jnp.where(periodic, kt, u + kt)
        kd = jnp.where(periodic, kt - u, kt)
        applications = s.applications + 1.5
        ev_new = k.evaluate(x_new, u_new, s.scales, bound_new, sliding_new)

        # -- outer loop: the friction bound --
        halved = ev_new.residual <= 0.5 * s.anchor
        since = jnp.where(halved, 0, s.since + 1)
        scales_new = s.scales
        res_ref = jnp.where(upd, ev_new.residual, s.res_ref)
        # A bound-updated iterate within the tolerance: certified with exact
        # displacements and residual scales.
        final = upd & (ev_new.gate <= k.rtol)

        def certify():
            ue, sce = k.exact(x_new)
            return ue, sce, k.evaluate(x_new, ue, sce, bound_new, sliding_new)

        u_new, scales_new, ev_new = jax.lax.cond(
            final, certify, lambda: (u_new, scales_new, ev_new))
        want = (ev_new.residual <= self.sigma * res_ref) | (
            ev_new.gate <= k.rtol) | self._exhausted(it, since) | (it <= early) | (
            (since >= self.update_when_stuck) & ~upd & ~s.certified)
        applications = applications + 1.5 * final
        return _JointState(
            x=x_new, u=u_new, bound=bound_new, sliding=sliding_new, scales=scales_new,
            ev=ev_new, p_start=s.p_start, res_ref=res_ref,
            anchor=jnp.where(halved, ev_new.residual, s.anchor), since=since,
            fresh=full & ~ev_new.stick, prev=d, k_prev=kd,
            prev_k_prev=jnp.sum(d * kd), it=it, certified=upd,
            updates=s.updates + upd, applications=applications,
            counts=s.counts + jnp.stack([periodic, upd]).astype(jnp.int32),
            want=want,
            steady=~jnp.any(release) | (ev_new.residual < self.fft_residual))

    def postprocess(self, problem, k: _JointOperator, s: _JointState, result):
        x, ev = s.x, s.ev
        p = x[0]
        contact = p > 0
        # Only a certified iterate (bound mu p, exact displacements) is an answer.
        converged = (ev.residual <= k.rtol) & s.certified
        failure = RESULTS.where(result == RESULTS.successful,
                                RESULTS.max_steps_reached, result)
        result = step_outcome(problem, p, converged, k.rtol, failure)
        return make_result(
            pressure=p, shear=x[1:], approach=ev.dz, delta_t=ev.dt,
            slip=ev.ds + problem.previous_slip, stick=ev.stick,
            sliding=jnp.any(contact) & ~jnp.any(ev.stick), gross_sliding=s.sliding,
            iterations=s.it,
            rounds=s.updates, residual=ev.residual, converged=converged, result=result)

    def statistics(self, problem, guess):
        """`(StepResult, stats)` with `stats = dict(applications, counts)`:
        equivalent coupled operator applications (a forward or inverse transform of all
        components counts 1/2; the preconditioner's unpadded transforms are not
        counted) and `counts` (periodic resyncs, bound updates). Benchmarks only."""
        out = run(self, problem, guess)
        return out.output, dict(applications=out.state.applications,
                                counts=out.state.counts)
