r"""Frictionless axisymmetric contact on rings: projected conjugate gradients.

One step (elastic, or one viscoelastic step at a known history) on the `n` rings of a
`RingOperator`: find the ring pressures `p >= 0` such that the mean gap of each ring

    g = h + C (1 - nu) U p - delta

is `>= 0`, and `0` where `p > 0`, with the load `sum_i w_i p_i = W` prescribed (load
control; the approach `delta` is its multiplier) or `delta` prescribed. `U` is the
ring operator's matrix, `w` the ring areas, `C` the step's compliance, `h` the mean
initial gap plus the history displacement. As `w[:, None] * U` is symmetric positive
definite, this is the convex programme `min 1/2 p.A p + p.(w h)` (`A = C (1 - nu) w U`)
on `p >= 0` (and `w.p = W`), solved as `normal.py` solves the grid's: Polonsky-Keer
conjugate gradients on the contact set, the gradient being `w g`; under load
control the directions are projected onto `w.t = 0` and the pressure rescaled to the
load. Differences from the grid:

- the displacement is recomputed exactly at every iteration (one dense `(n, n)`
  product, as cheap as the direction's);
- the preconditioner is the exact inverse of `A` on all rings (precomputed by the
  operator), restricted to the contact set: a displacement-controlled step whose
  contact covers every ring converges in one iteration, and a contact disc in a few;
- the conjugacy restarts whenever the contact set changes (a ring clipped to zero or
  re-entering).

Convergence is tested on the contact conditions: `residual = ||violation||_w /
||C (1 - nu) U p||_w` with area-weighted norms (`||v||_w^2 = sum w v^2`), the violation
being the gap on contact rings and the penetration elsewhere.

`ring_step` attaches exact derivatives by the implicit function theorem on the
converged contact set (`jax.lax.custom_root`; the `(n + 1)` Jacobian assembled and
factorised densely), in forward and reverse mode.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from .._results import RESULTS
from .._ring_operator import RingOperator
from .base import AbstractStepSolver, StepGuess, StepResult, make_result, safe_div


class RingProblem(eqx.Module):
    """One frictionless axisymmetric step (see the module docs).

    - `operator`: the `RingOperator` (unit modulus);
    - `compliance` `C` [1/stress], `poisson`: scalars;
    - `gap` `(n,)`: the mean initial gap of each ring [length];
    - `history` `(n,)`: known normal displacements (the viscoelastic history)
      [length];
    - `normal_target`: the load `W` [force] or the approach [length];
    - `normal_force_control` (static): which.
    """

    operator: RingOperator
    compliance: Float[Array, ""]
    poisson: Float[Array, ""]
    gap: Float[Array, " n"]
    history: Float[Array, " n"]
    normal_target: Float[Array, ""]
    normal_force_control: bool = eqx.field(static=True)

    @property
    def dtype(self):
        return self.gap.dtype

    @property
    def nd(self) -> int:
        """No shear: the ring solver is frictionless."""
        return 0


class RingSystem(eqx.Module):
    """What a ring solve holds fixed: `scale = C (1 - nu)`, the effective gap `h`,
    the `target`, the areas `w`, the ring self-compliances `k` (the diagonal of
    `scale U`), the preconditioner (`None` or the inverse of `w U`) and `rtol`."""

    matrix: Float[Array, "n n"]
    scale: Float[Array, ""]
    h: Float[Array, " n"]
    target: Float[Array, ""]
    w: Float[Array, " n"]
    k: Float[Array, " n"]
    inverse: Float[Array, "n n"] | None
    load_control: bool = eqx.field(static=True)
    rtol: float = eqx.field(static=True)

    def displacement(self, p):
        return self.scale * (self.matrix @ p)

    def evaluate(self, u, p):
        """`(g, delta, residual)` for the pressure `p` with displacement `u`."""
        raw = self.h + u
        contact = p > 0
        if self.load_control:
            # The area-weighted mean over the contact, summed as deviations from its
            # largest value (float32: the deviations at convergence are tiny).
            ref = jnp.max(jnp.where(contact, raw, -jnp.inf))
            weight = jnp.where(contact, self.w, 0)
            mean = ref + safe_div(jnp.sum(weight * jnp.where(contact, raw - ref, 0)),
                                  jnp.sum(weight))
            delta = jnp.where(jnp.any(contact), mean, jnp.min(raw))
        else:
            delta = self.target
        g = raw - delta
        violation = jnp.where(contact, g, jnp.minimum(g, 0))
        num = jnp.sqrt(jnp.sum(self.w * violation * violation))
        size = jnp.sqrt(jnp.sum(self.w * u * u))
        residual = jnp.where(num == 0, 0.0, num / jnp.where(size > 0, size, jnp.inf))
        residual = jnp.where((num > 0) & (size == 0), jnp.inf, residual)
        return g, delta, residual

    def rescale(self, p):
        total = jnp.sum(self.w * p)
        return jnp.where(total > 0, self.target / jnp.where(total > 0, total, 1), 0.0)


class _RingState(eqx.Module):
    p: Float[Array, " n"]
    u: Float[Array, " n"]
    g: Float[Array, " n"]
    t: Float[Array, " n"]  # search direction
    rz_old: Float[Array, ""]
    restart: Bool[Array, ""]
    it: Int[Array, ""]
    residual: Float[Array, ""]
    p_start: Float[Array, " n"]  # the pressure to restart from if all of it clips


def ring_guess(h, w, load, effective_modulus, steps: int = 60):
    """A Hertz-shaped start `sqrt(max(c - h, 0))` (unscaled) on rings of areas `w`:
    `normal.hertzian_guess` with the contact area `sum w [h < c]`."""
    h_min = jnp.min(h)

    def excess(level):
        area = jnp.sum(jnp.where(h < level, w, 0))
        return (4 / 3 * effective_modulus * jnp.sqrt(area / jnp.pi) * 2
                * (level - h_min) - load)

    a_ring = jnp.sqrt(w[0] / jnp.pi)
    hi = h_min + jnp.maximum(load / (8 / 3 * effective_modulus * a_ring),
                             jnp.max(h) - h_min)

    def body(_, bounds):
        lo, hi = bounds
        mid = 0.5 * (lo + hi)
        up = excess(mid) > 0
        return jnp.where(up, lo, mid), jnp.where(up, mid, hi)

    _, hi = jax.lax.fori_loop(0, steps, body, (h_min, hi))
    return jnp.sqrt(jnp.maximum(hi - h, 0))


class RingPolonskyKeer(AbstractStepSolver):
    """Polonsky-Keer conjugate gradients on rings (module docs): the step solver of
    the axisymmetric frictionless solve, entered through the protocol of
    `_solver/base.py` with a `RingProblem`.

    **Arguments:**

    - `rtol`: relative tolerance on the contact conditions; `None` (default): `1e-8`
      in float64, `1e-5` in float32.
    - `max_steps`: the most iterations (default 1000).
    - `precondition`: the exact inverse of the ring operator on all rings, restricted
      to the contact set (default `True`); `False`: plain projected CG.
    """

    rtol: float | None = eqx.field(static=True, default=None)
    max_steps: int = eqx.field(static=True, default=1000)
    precondition: bool = eqx.field(static=True, default=True)

    def supports(self, problem):
        if not isinstance(problem, RingProblem):
            return f"it solves a RingProblem (rings), got {type(problem).__name__}"
        return None

    def step_limit(self) -> int:
        return self.max_steps

    def setup(self, problem: RingProblem) -> RingSystem:
        op = problem.operator
        scale = problem.compliance * (1 - problem.poisson)
        return RingSystem(
            matrix=op.matrix, scale=scale, h=problem.gap + problem.history,
            target=jnp.asarray(problem.normal_target, problem.dtype), w=op.areas,
            k=scale * jnp.diagonal(op.matrix),
            inverse=op.inverse if self.precondition else None,
            load_control=problem.normal_force_control,
            rtol=self.tolerance(problem.dtype))

    def init(self, problem, k: RingSystem, guess: StepGuess) -> _RingState:
        h = k.h
        p0 = jnp.maximum(jnp.asarray(guess.normal, h.dtype), 0)
        if not k.load_control:
            # From nothing: the local closure of the interference.
            local = jnp.maximum(k.target - h, 0) / k.k
            p0 = jnp.where(jnp.sum(p0) > 0, p0, local)
        else:
            e_star = 2 / k.scale
            p0 = jnp.where(jnp.sum(p0) > 0, p0, ring_guess(h, k.w, k.target, e_star))
            p0 = jnp.where(jnp.sum(p0) > 0, p0, jnp.ones_like(p0))
            p0 = p0 * k.rescale(p0)
        u0 = k.displacement(p0)
        g0, _, res0 = k.evaluate(u0, p0)
        return _RingState(p=p0, u=u0, g=g0, t=jnp.zeros_like(h),
                          rz_old=jnp.ones((), h.dtype), restart=jnp.array(True),
                          it=jnp.array(0), residual=res0, p_start=p0)

    def terminate(self, problem, k: RingSystem, s: _RingState):
        return s.residual <= k.rtol, RESULTS.successful

    def step(self, problem, k: RingSystem, s: _RingState) -> _RingState:
        w = k.w
        p, g = s.p, s.g
        overlap = (p <= 0) & (g < 0)
        contact = (p > 0) | overlap
        wc = jnp.where(contact, w, 0)

        def project(v):  # onto the contact set (and w.v = 0 under load control)
            v = jnp.where(contact, v, 0)
            if k.load_control:
                v = v - wc * safe_div(jnp.sum(wc * v), jnp.sum(wc * wc))
            return v

        grad = project(w * g)
        z = grad if k.inverse is None else project(k.inverse @ grad)
        rz = jnp.sum(grad * z)
        beta = jnp.where(s.restart, 0.0, safe_div(rz, s.rz_old))
        t = z + beta * s.t
        at = w * k.displacement(t)
        tau = safe_div(jnp.sum(grad * t), jnp.sum(t * at))
        p_step = p - tau * t
        clipped = jnp.any((p_step < 0) & contact)
        p_new = jnp.maximum(p_step, 0)
        # Re-entry: penetrating rings the direction did not lift close locally.
        reenter = overlap & (p_new <= 0)
        p_new = jnp.where(reenter, -g / k.k, p_new)
        if k.load_control:
            p_new = jnp.where(jnp.sum(p_new) > 0, p_new, s.p_start)
            p_new = p_new * k.rescale(p_new)
        u_new = k.displacement(p_new)
        g_new, _, res = k.evaluate(u_new, p_new)
        return _RingState(p=p_new, u=u_new, g=g_new, t=t, rz_old=rz,
                          restart=clipped | jnp.any(overlap), it=s.it + 1,
                          residual=res, p_start=s.p_start)

    def postprocess(self, problem, k: RingSystem, s: _RingState,
                    result: RESULTS) -> StepResult:
        _, delta, residual = k.evaluate(s.u, s.p)
        n = s.p.shape[0]
        empty = jnp.zeros((0, n), s.p.dtype)
        return make_result(
            pressure=s.p, shear=empty, approach=delta,
            delta_t=jnp.zeros((0,), s.p.dtype), slip=empty,
            stick=jnp.zeros((n,), bool), sliding=False, iterations=s.it, rounds=1,
            residual=residual, converged=residual <= k.rtol, result=result)


def _residual(problem: RingProblem, contact, kz, x):
    """`F(x)` on the frozen `contact` set, `x = (p, delta / kz)`: the gap of contact
    rings over `kz`, `p` elsewhere, and the load row (its area-weighted sum less `W`,
    scaled) or the prescribed approach; without contact under load control the
    approach is the surface's highest point (the forward's `evaluate`)."""
    op = problem.operator
    p, dz = x[:-1], x[-1]
    raw = problem.gap + problem.history + op.apply_normal(problem.compliance * p,
                                                          problem.poisson)
    f_p = jnp.where(contact, (raw - dz * kz) / kz, p)
    if problem.normal_force_control:
        n_contact = jnp.maximum(jnp.sum(contact), 1).astype(p.dtype)
        scale = jnp.mean(op.areas) * jnp.sqrt(n_contact)
        # The lowest point by index (not `min`, whose derivative splits between ties).
        touching = raw[jnp.argmin(raw)] / kz
        f_dz = jnp.where(jnp.any(contact),
                         (jnp.sum(op.areas * p) - problem.normal_target) / scale,
                         dz - touching)
    else:
        f_dz = dz - problem.normal_target / kz
    return jnp.concatenate([f_p, f_dz[None]])


def _jacobian(problem: RingProblem, contact, kz, x):
    """`dF/dx` `(n + 1, n + 1)` of `_residual` at `x` (assembled: it is small)."""
    op = problem.operator
    n = contact.shape[0]
    dtype = x.dtype
    scaled = (problem.compliance * (1 - problem.poisson) / kz) * op.matrix
    eye = jnp.eye(n, dtype=dtype)
    rows = jnp.where(contact[:, None], scaled, eye)
    column = jnp.where(contact, -1.0, 0.0).astype(dtype)
    if problem.normal_force_control:
        n_contact = jnp.maximum(jnp.sum(contact), 1).astype(dtype)
        scale = jnp.mean(op.areas) * jnp.sqrt(n_contact)
        raw = problem.gap + problem.history + op.apply_normal(
            problem.compliance * x[:-1], problem.poisson)
        touching = scaled[jnp.argmin(raw)]
        any_contact = jnp.any(contact)
        last = jnp.where(any_contact, op.areas / scale, -touching)
        corner = jnp.where(any_contact, 0.0, 1.0).astype(dtype)
    else:
        last = jnp.zeros((n,), dtype)
        corner = jnp.ones((), dtype)
    top = jnp.concatenate([rows, column[:, None]], axis=1)
    bottom = jnp.concatenate([last, corner[None]])[None]
    return jnp.concatenate([top, bottom], axis=0)


def ring_step(solver: AbstractStepSolver, problem: RingProblem,
              guess: StepGuess) -> StepResult:
    """`solver.solve(problem, guess)` whose pressure and approach carry exact
    (implicit) derivatives with respect to every array of `problem` (compliance,
    Poisson's ratio, gap, history, target; not the operator, nor the warm start), in
    forward and reverse mode: `jax.lax.custom_root` on the residual of the converged
    contact set, its tangent and transposed systems solved densely (`_jacobian`).
    Exact away from a ring entering or leaving the contact."""
    sg = jax.lax.stop_gradient
    res = solver.solve(sg(problem), sg(guess))
    contact = sg(res.pressure > 0)
    fixed = sg(problem)
    kz = jnp.mean(fixed.compliance * (1 - fixed.poisson)
                  * jnp.diagonal(fixed.operator.matrix))
    x0 = sg(jnp.concatenate([res.pressure, (res.approach / kz)[None]]))
    # `dF/dx` at the root, assembled and factorised once: the tangent solves of
    # forward mode, and their transposes in reverse mode, reuse the factors.
    factors = jax.scipy.linalg.lu_factor(_jacobian(fixed, contact, kz, x0))

    def tangent_solve(_linear, b):
        return jax.scipy.linalg.lu_solve(factors, b)

    x = jax.lax.custom_root(lambda x: _residual(problem, contact, kz, x), x0,
                            lambda _f, x: x, tangent_solve)
    return res.replace(pressure=x[:-1], approach=x[-1] * kz)
