r"""A semismooth Newton solver for one coupled frictional step (issue 27, item 4).

Built to be measured against `jc.JointPCG` behind the same solver interface
(`AbstractStepSolver`: `jc.solve(scene, solver=SemismoothNewton(...))`); the
comparison is `newton_vs_joint.py`, the outcome `benchmarks/notes/newton.md` (it lost:
2.5-6.8x slower than `JointPCG` with the same answers). A probe kept as the record of
that measurement, not a maintained solver: it reads private names of `jaxcontact`
(`_solver.joint`, `_solver.base`, `_solver.tangential`) and may stop running when they
change. Its agreement test (`tests/test_semismooth_newton.py`: GMRES against a dense
solve; Newton and `JointPCG` equal to 1e-8 on a 24^2 oblique coupled load) was
retired with the move here; `git show 3547241:tests/test_semismooth_newton.py`.

**The equations** (Alart & Curnier 1991; Hueeber, Stadler & Wohlmuth 2008 for the 3-D
Coulomb disc). Unknowns `x = (p, q, a_z, a_t)`: pressure, shear `(nd, nx, ny)` and the
rigid approach and tangential displacements, scaled by the self-compliances `k_z`,
`k_t` of a cell (`a_z = delta_z / k_z`, `a_t = delta_t / k_t`: every row in stress
units). With `u = C K (p, q)` (the step's full operator, coupling included),

- gap `g = h + u_z - delta_z`, augmented pressure `lam = p - g / k_z`;
  `F_p = g / k_z` where `lam > 0` (contact), else `F_p = p`;
- slip increment `s = u_t + b - delta_t`, augmented shear `z = q - s / k_t`, bound
  `B = mu max(lam, 0)`; `F_q = s / k_t` where `|z| < B` (stick), `F_q = q - B z / |z|`
  where `|z| >= B > 0` (slip), `F_q = q` out of contact;
- load rows as `implicit._residual`: `(A sum p - W) / (A sqrt(n_contact))` or
  `a_z - target / k_z`; per shear direction the same with `q_d` or `a_t,d`.

`F(x) = 0` is the contact problem (the complementarity conditions and the Coulomb law
written as projections). `F` is piecewise smooth; its derivative on the current sets
(`jax.linearize`) is a generalized Jacobian: each Newton step solves `J dx = -F` on
the sets of the iterate. Across the slip direction the slip row is
`(1 - beta) dq + beta ds / k_t` with `beta = B / |z|` in `[0, 1]` (bounded, unlike the
frozen-direction row `q + mu p s / |s|` of the adjoint).

**Linear solve**: right-preconditioned restarted GMRES (`gmres` below: counts its
iterations, one operator application each), to a relative tolerance `eta` (inexact
Newton; Eisenstat & Walker's second choice, capped at `forcing`). Preconditioner: as
the adjoint's (`implicit._transposed_preconditioner`): `k` times the full-plane
inverse of the operator's diagonal blocks on the contact cells (stick rows and the
shear of slip rows blended by `beta`), the identity elsewhere.

**Row weights**: the normal rows times `k_z / s_n`, the shear rows times `k_t / s_t`
(`s_n`, `s_t`: the certification's residual scales at the last iterate), so that
`||F||` weighs each block as the certified residual does (without them a shear problem
whose whole scale is below the normal rows' round-off, e.g. Spence's first stage with
one cell in contact, cannot converge).

**Globalisation**: backtracking on `||F||` (Armijo, halving), one operator
application per trial; where no trial decreases `||F||` the full step is taken, and
three such steps in a row end the solve (`RESULTS.stalled`).

**Certification**: after each Newton step the iterate (pressure clipped at zero, shear
projected onto the discs `mu p`) is evaluated by `JointPCG`'s own residual with exact
displacements and scales (`_JointOperator.exact`, `.evaluate`): both solvers stop on
the same number.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jax.flatten_util import ravel_pytree

from jaxcontact._solution import RESULTS
from jaxcontact._solver.base import AbstractStepSolver, make_result, step_outcome
from jaxcontact._solver.joint import JointPCG, _JointOperator
from jaxcontact._solver.tangential import project


def gmres(matvec, precondition, b, rtol, restart, max_iterations):
    """`(x, iterations)`: right-preconditioned restarted GMRES for `matvec(x) = b`
    (flat vectors; `x = M y`, `M` = `precondition`), from zero, until the estimated
    residual is below `rtol ||b||` or `max_iterations` operator applications;
    modified Gram-Schmidt, Givens rotations. `iterations` counts `matvec` calls."""
    n = b.shape[0]
    dtype = b.dtype
    b_norm = jnp.linalg.norm(b)
    target = rtol * b_norm

    def cycle(carry):
        x, _, it = carry
        r = b - matvec(x)
        beta = jnp.linalg.norm(r)
        v = jnp.zeros((restart + 1, n), dtype)
        v = v.at[0].set(r / jnp.where(beta > 0, beta, 1))
        z = jnp.zeros((restart, n), dtype)
        h = jnp.zeros((restart + 1, restart), dtype)
        cs = jnp.zeros(restart, dtype)
        sn = jnp.zeros(restart, dtype)
        g = jnp.zeros(restart + 1, dtype).at[0].set(beta)

        def inner_cond(state):
            j, _, _, _, _, _, g, it = state
            return (j < restart) & (jnp.abs(g[j]) > target) & (it < max_iterations)

        def inner(state):
            j, v, z, h, cs, sn, g, it = state
            zj = precondition(v[j])
            w = matvec(zj)

            def orth(i, carry):
                w, hcol = carry
                hij = jnp.where(i <= j, jnp.dot(v[i], w), 0.0)
                return w - hij * v[i], hcol.at[i].set(hij)

            w, hcol = jax.lax.fori_loop(0, restart, orth,
                                        (w, jnp.zeros(restart + 1, dtype)))
            hn = jnp.linalg.norm(w)
            hcol = hcol.at[j + 1].set(hn)
            v = v.at[j + 1].set(w / jnp.where(hn > 0, hn, 1))

            def rotate(i, hcol):
                a, c = hcol[i], hcol[i + 1]
                new_a = cs[i] * a + sn[i] * c
                new_c = -sn[i] * a + cs[i] * c
                keep = i < j
                return hcol.at[i].set(jnp.where(keep, new_a, a)).at[i + 1].set(
                    jnp.where(keep, new_c, c))

            hcol = jax.lax.fori_loop(0, restart, rotate, hcol)
            a, c = hcol[j], hcol[j + 1]
            rho = jnp.sqrt(a * a + c * c)
            cj = jnp.where(rho > 0, a / jnp.where(rho > 0, rho, 1), 1.0)
            sj = jnp.where(rho > 0, c / jnp.where(rho > 0, rho, 1), 0.0)
            hcol = hcol.at[j].set(rho).at[j + 1].set(0.0)
            g = g.at[j + 1].set(-sj * g[j]).at[j].set(cj * g[j])
            return (j + 1, v, z.at[j].set(zj), h.at[:, j].set(hcol), cs.at[j].set(cj),
                    sn.at[j].set(sj), g, it + 1)

        j, v, z, h, cs, sn, g, it = jax.lax.while_loop(
            inner_cond, inner, (jnp.array(0), v, z, h, cs, sn, g, it))
        # Back substitution on the leading j x j block (the rest masked to identity).
        mask = jnp.arange(restart) < j
        hh = jnp.where(mask[:, None] & mask[None, :], h[:restart], 0.0)
        hh = hh + jnp.diag(jnp.where(mask, 0.0, 1.0))
        y = jax.scipy.linalg.solve_triangular(hh, jnp.where(mask, g[:restart], 0.0))
        x = x + z.T @ y
        return x, jnp.abs(g[j]), it + 1  # + 1: the true residual of the next cycle

    def outer_cond(carry):
        _, estimate, it = carry
        return (estimate > target) & (it < max_iterations)

    x, _, it = jax.lax.while_loop(
        outer_cond, cycle, (jnp.zeros_like(b), b_norm, jnp.array(0)))
    return x, it


class _NewtonState(eqx.Module):
    x: tuple
    f_norm: jax.Array
    f_prev: jax.Array
    residual: jax.Array  # JointPCG's certified residual of the projected iterate
    ev: object
    p_cert: jax.Array
    q_cert: jax.Array
    it: jax.Array
    linear: jax.Array  # GMRES operator applications, summed
    evaluations: jax.Array  # residual evaluations (one application each)
    stuck: jax.Array  # consecutive steps without a decrease of ||F||
    weights: jax.Array  # row weights (w_n, w_t) of the next Newton step
    failed: jax.Array


class SemismoothNewton(AbstractStepSolver):
    """Semismooth Newton on the Alart-Curnier equations of a coupled frictional step
    (module docs). Benchmark peer of `jc.JointPCG`; same tolerance semantics.

    - `rtol`: relative tolerance of JointPCG's residual; `None`: 1e-8 / 1e-5.
    - `max_steps`: Newton steps.
    - `restart`, `max_linear`: GMRES cycle length and applications per Newton step.
    - `forcing`: the largest relative tolerance of a Newton step's linear solve.
    - `backtracks`: halvings of the line search.
    """

    rtol: float | None = eqx.field(static=True, default=None)
    max_steps: int = eqx.field(static=True, default=60)
    restart: int = eqx.field(static=True, default=30)
    max_linear: int = eqx.field(static=True, default=300)
    forcing: float = eqx.field(static=True, default=0.1)
    backtracks: int = eqx.field(static=True, default=8)
    precondition: bool = eqx.field(static=True, default=True)

    def step_limit(self) -> int:
        return self.max_steps

    def supports(self, problem):
        if problem.nd not in (1, 2):
            return "the Newton solver needs a frictional step (a tangential solve)"
        return None

    def setup(self, problem):
        k = _JointOperator(JointPCG(rtol=self.rtol, precondition=self.precondition),
                           problem)
        return k

    # ---- the equations ------------------------------------------------------------
    def _residual(self, problem, k, x, weights):
        """`(F(x), sets)`: the residual (module docs), its normal and shear rows times
        `weights = (w_n, w_t)`, and, for the preconditioner, the sets it was evaluated
        on `(contact, stick, beta, direction of z)`."""
        p, q, az, at = x
        nd = k.nd
        kz, kt = k.c_zz, k.c_tt
        u = k.apply(jnp.concatenate([p[None], q]))
        g = k.h + u[0] - az * kz
        lam = p - g / kz
        contact = lam > 0
        f_p = jnp.where(contact, g / kz, p)
        area = k.area
        n_contact = jnp.sum(contact)
        scale = area * jnp.sqrt(jnp.maximum(n_contact, 1).astype(p.dtype))
        if k.load_n:
            f_z = (area * jnp.sum(p) - k.normal_target) / scale
        else:
            f_z = az - k.normal_target / kz
        s = u[1:] + k.b - at[:, None, None] * kt
        z = q - s / kt
        bound = k.friction * jnp.maximum(lam, 0.0)
        zz = jnp.sum(z * z, axis=0)
        z_norm = jnp.sqrt(jnp.where(zz > 0, zz, 1.0))
        stick = contact & (zz < bound * bound)
        slip = contact & ~stick
        beta = bound / z_norm
        f_q = jnp.where(stick[None], s / kt,
                        jnp.where(slip[None], q - beta[None] * z, q))
        f_t = []
        for d in range(nd):
            if problem.tangential_force_control[d]:
                f_t.append((area * jnp.sum(q[d]) - k.tangential_target[d]) / scale)
            else:
                f_t.append(at[d] - k.tangential_target[d] / kt)
        sets = jax.lax.stop_gradient(
            (contact, stick, jnp.where(slip, beta, 1.0), z / z_norm[None]))
        w_n, w_t = weights
        return (w_n * f_p, w_t * f_q, w_n * f_z, w_t * jnp.stack(f_t)), sets

    def _preconditioner(self, k, sets, weights):
        """`v -> M v`, approximately the inverse of the weighted Jacobian (the rows
        unweighted first)."""
        contact, stick, beta, direction = sets
        kz, kt = k.c_zz, k.c_tt
        w_n, w_t = weights

        def apply(v):
            v_p, v_q, v_z, v_t = v[0] / w_n, v[1] / w_t, v[2] / w_n, v[3] / w_t
            if not k.fft_precond:
                return v_p, v_q, v_z, v_t
            along = jnp.sum(direction * v_q, axis=0)[None] * direction
            across = v_q - along
            slip = contact & ~stick
            # Stick rows: the operator's inverse; slip rows: along their direction the
            # identity, across it a blend (beta) of the inverse and the identity.
            shear = jnp.where(stick[None], v_q,
                              jnp.where(slip[None], beta[None] * across, 0))
            field = jnp.concatenate([jnp.where(contact, v_p, 0)[None], shear])
            m = k.precondition(field)
            m_p = jnp.where(contact, kz * m[0], v_p)
            m_t = kt * m[1:]
            m_across = m_t - jnp.sum(direction * m_t, axis=0)[None] * direction
            m_slip = along + (1 - beta[None]) * across + m_across
            m_q = jnp.where(stick[None], m_t, jnp.where(slip[None], m_slip, v_q))
            return m_p, m_q, v_z, v_t

        return apply

    def _certify(self, k, x, contact):
        """`(p, q, evaluation)`: the iterate with its pressure zero off the `contact`
        set (`F_p = p` there, zero only to round-off) and clipped at zero, its shear
        on the discs, evaluated by JointPCG's residual (exact displacements)."""
        p, q = x[0], x[1]
        p_c = jnp.where(contact, jnp.maximum(p, 0.0), 0.0)
        bound = k.friction * p_c
        q_c = project(q, bound)
        xc = jnp.concatenate([p_c[None], q_c])
        u, scales = k.exact(xc)
        sliding = k.sliding_of(p_c)
        ev = k.evaluate(xc, u, scales, bound, sliding)
        return p_c, q_c, ev, self._weights(k, scales)

    def _weights(self, k, scales):
        """Row weights `(k_z / s_n, k_t / s_t)` from the certification's residual
        scales: `||F||` then measures the normal and shear rows as the certified
        residual does, each relative to its own scale (a shear problem whose whole
        scale is below the normal rows' round-off is otherwise invisible)."""
        s_n, s_t = scales[0], scales[1]
        w_n = k.c_zz / jnp.where(s_n > 0, s_n, 1.0)
        w_t = k.c_tt / jnp.where(s_t > 0, s_t, 1.0)
        return jax.lax.stop_gradient(jnp.stack([w_n, w_t]))

    # ---- the solver protocol ---------------------------------------------------------
    def init(self, problem, k, guess):
        dtype = k.dtype
        p = jnp.maximum(jnp.asarray(guess.normal, dtype), 0)
        if k.load_n:
            p = jnp.where(jnp.sum(p) > 0, p, jnp.ones_like(p))
            p = k.rescale(p)
        q = jnp.asarray(guess.shear, dtype)
        p_c, q_c, ev, weights = self._certify(k, (p, q), p > 0)
        x = (p, q, ev.dz / k.c_zz, ev.dt / k.c_tt)
        f, _ = self._residual(problem, k, x, weights)
        f_norm = jnp.linalg.norm(ravel_pytree(f)[0])
        return _NewtonState(x=x, f_norm=f_norm, f_prev=f_norm, residual=ev.residual,
                            ev=ev, p_cert=p_c, q_cert=q_c, it=jnp.array(0),
                            linear=jnp.array(0), evaluations=jnp.array(2),
                            stuck=jnp.array(0), weights=weights,
                            failed=jnp.array(False))

    def terminate(self, problem, k, s):
        failure = RESULTS.where(s.failed, RESULTS.stalled, RESULTS.max_steps_reached)
        converged = s.residual <= k.rtol
        return converged | s.failed, RESULTS.where(converged, RESULTS.successful,
                                                   failure)

    def step(self, problem, k, s):
        x = s.x
        flat, unravel = ravel_pytree(x)
        f0, linear, sets = jax.linearize(
            lambda y: self._residual(problem, k, y, s.weights), x, has_aux=True)
        f0_flat = ravel_pytree(f0)[0]
        f_norm = jnp.linalg.norm(f0_flat)
        precondition = self._preconditioner(k, sets, s.weights)
        # Eisenstat-Walker (choice 2) forcing term, capped at `forcing`.
        ratio = f_norm / jnp.where(s.f_prev > 0, s.f_prev, 1.0)
        eta = jnp.clip(0.9 * ratio * ratio, 0.1 * k.rtol, self.forcing)
        eta = jnp.where(s.it == 0, self.forcing, eta)

        def matvec(v):
            return ravel_pytree(linear(unravel(v)))[0]

        def m_flat(v):
            return ravel_pytree(precondition(unravel(v)))[0]

        dx, n_linear = gmres(matvec, m_flat, -f0_flat, eta, self.restart,
                             self.max_linear)

        def trial(alpha):
            xt = unravel(flat + alpha * dx)
            ft, sets_t = self._residual(problem, k, xt, s.weights)
            return xt, sets_t[0], jnp.linalg.norm(ravel_pytree(ft)[0])

        def ls_cond(state):
            alpha, _, _, fn, n = state
            return (fn > (1 - 1e-4 * alpha) * f_norm) & (n < self.backtracks)

        def ls_body(state):
            alpha, _, _, _, n = state
            alpha = 0.5 * alpha
            return (alpha, *trial(alpha), n + 1)

        one = jnp.asarray(1.0, flat.dtype)
        x1, contact1, fn1 = trial(one)
        alpha, x_new, contact_new, fn, n_ls = jax.lax.while_loop(
            ls_cond, ls_body, (one, x1, contact1, fn1, jnp.array(0)))
        accepted = fn <= (1 - 1e-4 * alpha) * f_norm
        # No decrease of ||F|| (at its round-off, the normal rows can hide a shear
        # correction far below it): take the full Newton step; give up after three.
        x_new, contact_new, fn = jax.tree.map(
            lambda a, b: jnp.where(accepted, a, b), (x_new, contact_new, fn),
            (x1, contact1, fn1))
        p_c, q_c, ev, weights = self._certify(k, x_new, contact_new)
        return _NewtonState(
            x=x_new, f_norm=fn, f_prev=f_norm, residual=ev.residual, ev=ev,
            p_cert=p_c, q_cert=q_c, it=s.it + 1, linear=s.linear + n_linear,
            evaluations=s.evaluations + 1 + n_ls + 1,
            stuck=jnp.where(accepted, 0, s.stuck + 1), weights=weights,
            failed=(s.stuck >= 2) & ~accepted | ~jnp.isfinite(fn))

    def postprocess(self, problem, k, s, result):
        ev = s.ev
        p = s.p_cert
        contact = p > 0
        converged = s.residual <= k.rtol
        failure = RESULTS.where(result == RESULTS.successful,
                                RESULTS.max_steps_reached, result)
        result = step_outcome(problem, p, converged, k.rtol, failure)
        return make_result(
            pressure=p, shear=s.q_cert, approach=ev.dz, delta_t=ev.dt,
            slip=ev.ds + problem.previous_slip, stick=ev.stick,
            sliding=jnp.any(contact) & ~jnp.any(ev.stick), iterations=s.linear,
            rounds=s.it, residual=ev.residual, converged=converged, result=result)
