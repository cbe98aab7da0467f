r"""One step of the coupled frictional contact problem (elastic, or one viscoelastic step).

The normal and tangential problems interact through the coupling blocks of the
half-space operator (`(1 - 2 nu)` terms): the shear changes the normal displacement and
the pressure changes the tangential displacement. The step alternates the two solvers
(block Gauss-Seidel, as in the paper and Panagiotopoulos' process), each warm-started
from the previous round, until a whole round changes nothing: the normal solver accepts
the current pressure with the latest shear, and the tangential solver accepts the
current shear with the latest pressure (both at their tolerance, with zero iterations).
Without coupling, one round is exact.

Coupled steps are solved by the joint projected CG of `joint.py` (`method="joint"`,
the default: one loop over `(p, q)` with the full symmetric operator, several times
cheaper than the rounds), or by the rounds above (`method="rounds"`). Neither returns
a wrong answer flagged converged: every result is checked on the contact conditions at
`rtol` with exact displacements, and a step that fails is retried (vmap-friendly
`while_loop`s, so nothing extra runs when every step converges):

1. joint failed -> the rounds, warm-started from the joint iterate;
2. still failing under tangential LOAD control (e.g. the paper's total slip law on a
   viscoelastic body, where the load-controlled iterations can cycle) -> the load is
   met by a safeguarded, bracketed root search on the rigid tangential displacement
   `delta_d` of the load-controlled direction `d` (x if it is load-controlled, else
   y), each evaluation a displacement-controlled step. The tangential force
   `F_d(delta_d)` is non-decreasing in `delta_d` (the tangential operator is positive
   definite; the force saturates at `+-mu W` in gross sliding), so a bracket is grown
   geometrically from the failed step's `delta_d` and then shrunk by the Illinois
   variant of regula falsi with bisection safeguards, until the load error is below
   `rtol mu W`.

All displacements here are `C * K1 * traction + history`, with `C` the step's
(instantaneous or effective) compliance and `history` a known field (zero for an
elastic body).
"""

from typing import NamedTuple

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from .normal import inverse_preconditioner, polonsky_keer
from .precondition import shear_x_preconditioner
from .tangential import TangentialState, gross_sliding, tangential_cg


class StepResult(NamedTuple):
    pressure: Float[Array, "nx ny"]
    shear: Float[Array, "nd nx ny"]
    approach: Float[Array, ""]
    delta_t: Float[Array, " nd"]
    slip: Float[Array, "nd nx ny"]  # slip s = u_t - delta_t after the step (for the next)
    stick: Bool[Array, "nx ny"]
    sliding: Bool[Array, ""]
    iterations: Int[Array, ""]
    rounds: Int[Array, ""]
    residual: Float[Array, ""]
    converged: Bool[Array, ""]


class StepConfig(NamedTuple):
    """Static configuration of a step."""

    nd: int  # shear components solved: 0, 1 or 2
    coupled: bool  # normal-tangential coupling blocks in use
    normal_force_control: bool
    tangential_force_control: tuple[bool, ...]
    rtol: float
    max_steps: int
    max_rounds: int
    resync_every: int
    # Coupled steps: "joint" (joint projected CG, `joint.py`) or "rounds" (block
    # Gauss-Seidel normal/tangential rounds). Ignored without coupling (one round).
    method: str = "joint"
    # CG solves preconditioned by the full-plane inverse of the operator: normal
    # (`normal.py`) and joint coupled (`precondition.py`); the tangential CG of the
    # uncoupled / rounds path keeps its diagonal preconditioner.
    precondition: bool = True


def _rounds_step(
    operator,
    config: StepConfig,
    compliance,
    poisson,
    friction,
    h0: Float[Array, "nx ny"],
    history: Float[Array, "3 nx ny"],
    normal_target,
    tangential_target: Float[Array, " nd"],
    previous_slip: Float[Array, "nd nx ny"],
    p0: Float[Array, "nx ny"],
    q0: Float[Array, "nd nx ny"],
    normal_guess=None,
) -> StepResult:
    """One step by normal/tangential rounds (see the module docs)."""
    grid = operator.grid
    area = grid.cell_area
    dtype = h0.dtype
    nd = config.nd
    nx, ny = grid.shape

    nn_spec = compliance * operator.normal_spectrum(poisson)

    def apply_normal(p):
        return operator.inverse(operator.forward(p) * nn_spec)

    precondition = None
    if config.precondition:
        precondition = inverse_preconditioner(
            operator, operator.normal_spectrum(poisson), poisson)
    k_zz = operator.diagonal(nn_spec)  # once, not in every round

    def solve_normal(h_eff, p_start):
        return polonsky_keer(
            apply_normal, h_eff, normal_target, area,
            load_control=config.normal_force_control, rtol=config.rtol,
            max_steps=config.max_steps, resync_every=config.resync_every,
            self_compliance=k_zz, p0=p_start, precondition=precondition,
        )

    if nd == 0:
        p_start = p0 if normal_guess is None else normal_guess
        normal = solve_normal(h0 + history[2], p_start)
        return StepResult(
            pressure=normal.pressure, shear=jnp.zeros((0, nx, ny), dtype),
            approach=normal.approach, delta_t=jnp.zeros((0,), dtype),
            slip=jnp.zeros((0, nx, ny), dtype),
            stick=(normal.pressure > 0) & (friction > 0),
            sliding=jnp.array(False), iterations=normal.iterations,
            rounds=jnp.array(1), residual=normal.residual, converged=normal.converged,
        )

    xx, xy, yy = operator.tangential_blocks(poisson)
    blocks = (compliance * xx, None if xy is None else compliance * xy,
              None if yy is None else compliance * yy)

    def apply_tangential(q):
        return operator.apply_tangential(q, poisson, blocks=blocks)

    self_compliance = operator.diagonal(blocks[0])  # A_xx at zero offset
    precondition_t = None
    if config.precondition and nd == 1 and not operator.grid.periodic:
        # The xx spectrum floored by the normal one (its DC-FFT modes near zero or
        # negative, see precondition.py), on the unpadded grid, raised to Cerruti's.
        precondition_t = shear_x_preconditioner(operator, poisson)

    zx, zy = operator.coupling_spectra(poisson)

    def uz_from_shear(q):
        if not config.coupled:
            return jnp.zeros((nx, ny), dtype)
        hat = 1j * compliance * zx * operator.forward(q[0])
        if zy is not None and nd == 2:
            hat = hat + 1j * compliance * zy * operator.forward(q[1])
        return operator.inverse(hat)

    def ut_from_pressure(p):
        if not config.coupled:
            return jnp.zeros((nd, nx, ny), dtype)
        p_hat = operator.forward(p)
        ux = operator.inverse(-1j * compliance * zx * p_hat)
        if nd == 1:
            return ux[None]
        uy = operator.inverse(-1j * compliance * zy * p_hat) if zy is not None else jnp.zeros_like(ux)
        return jnp.stack([ux, uy])

    all_force = all(config.tangential_force_control)

    def solve_tangential(p, q_start):
        bound = friction * p
        b = ut_from_pressure(p) + history[:nd] - previous_slip

        def cg():
            return tangential_cg(
                apply_tangential, b, bound, config.tangential_force_control,
                tangential_target, area, self_compliance, q0=q_start, rtol=config.rtol,
                max_steps=config.max_steps, resync_every=config.resync_every,
                precondition=precondition_t,
            )

        if not all_force:
            return cg()
        # Gross sliding under load control: |F| >= mu W has no static solution; the
        # indenter slides and q = mu p along F (reported, never iterated on). A load
        # at the limit to rtol / 2 slides too (`gross_sliding`: not round-off's call).
        limit = area * jnp.sum(bound)
        f_norm = jnp.sqrt(jnp.sum(tangential_target**2))

        def slide():
            direction = tangential_target / jnp.where(f_norm > 0, f_norm, 1)
            q = bound[None] * direction[:, None, None]
            w = apply_tangential(q) + b
            contact = bound > 0
            n = jnp.maximum(jnp.sum(contact), 1)
            delta = jnp.sum(jnp.where(contact[None], w, 0), axis=(1, 2)) / n
            return TangentialState(
                shear=q, displacement=w - b, slip=w - delta[:, None, None], delta=delta,
                stick=jnp.zeros_like(contact), iterations=jnp.array(0),
                residual=jnp.zeros((), dtype), converged=jnp.array(True),
                applications=jnp.array(1),
            )

        return jax.lax.cond(gross_sliding(f_norm, limit, config.rtol), slide, cg)

    # ---- Rounds of normal / tangential solves --------------------------------------
    def round_(state):
        p, q, _, _, it, rounds, _ = state
        normal = solve_normal(h0 + history[2] + uz_from_shear(q), p)
        tang = solve_tangential(normal.pressure, q)
        done = (normal.iterations == 0) & (tang.iterations == 0)
        ok = normal.converged & tang.converged
        return (normal.pressure, tang.shear, (normal, tang), done & ok,
                it + normal.iterations + tang.iterations, rounds + 1, ok)

    p_start = p0 if normal_guess is None else normal_guess
    first = round_((p_start, q0, None, False, jnp.array(0), jnp.array(0), False))
    if config.coupled:
        def cond(state):
            return (~state[3]) & (state[5] < config.max_rounds)

        def body(state):
            return round_(state)

        state = jax.lax.while_loop(cond, body, first)
        converged = state[6] & state[3]
    else:
        state = first
        converged = state[6]
    p, q, (normal, tang), _, iterations, rounds, _ = state
    contact = p > 0
    stick = tang.stick
    sliding = jnp.any(contact) & ~jnp.any(stick)
    return StepResult(
        pressure=p, shear=q, approach=normal.approach, delta_t=tang.delta,
        slip=tang.slip + previous_slip, stick=stick, sliding=sliding,
        iterations=iterations, rounds=rounds,
        residual=jnp.maximum(normal.residual, tang.residual), converged=converged,
    )


def contact_step(
    operator,
    config: StepConfig,
    compliance,
    poisson,
    friction,
    h0: Float[Array, "nx ny"],
    history: Float[Array, "3 nx ny"],
    normal_target,
    tangential_target: Float[Array, " nd"],
    previous_slip: Float[Array, "nd nx ny"],
    p0: Float[Array, "nx ny"],
    q0: Float[Array, "nd nx ny"],
    normal_guess=None,
) -> StepResult:
    """Solve one coupled step (see the module docs).

    **Arguments:**

    - `operator`: the `HalfSpace` (unit modulus); `config`: a `StepConfig`.
    - `compliance`: the step's compliance `C` [1/stress] (`1/G` elastic, `J(0)` or an
      effective one in a viscoelastic step); `poisson`, `friction`: scalars.
    - `h0`: initial gap [length], `(nx, ny)`; `history`: the known displacements
      `(u_x, u_y, u_z)` [length], `(3, nx, ny)`.
    - `normal_target`: load `W` [force] or approach [length] (per
      `config.normal_force_control`); `tangential_target`: `(nd,)` forces [force] or
      rigid tangential displacements [length] per direction.
    - `previous_slip`: `(nd, nx, ny)` slip before the step [length] (zeros for the
      total slip law); `p0`, `q0`, `normal_guess`: warm starts [stress].

    **Returns:** a `StepResult`; `converged` is `True` only when the contact
    conditions hold at `config.rtol` (checked with exact displacements).
    """
    if config.method not in ("joint", "rounds"):
        raise ValueError(f'method must be "joint" or "rounds", got {config.method!r}')
    args = (operator, config, compliance, poisson, friction, h0, history, normal_target,
            tangential_target, previous_slip)
    if config.nd == 0 or not config.coupled:
        return _rounds_step(*args, p0, q0, normal_guess=normal_guess)
    if config.method == "joint":
        from .joint import joint_step  # joint.py imports StepConfig/StepResult from here

        res = joint_step(*args, p0, q0, normal_guess=normal_guess)
        res = _retry(res, lambda r: _add_work(r, _rounds_step(
            *args, r.pressure, r.shear, normal_guess=r.pressure)))
    else:
        res = _rounds_step(*args, p0, q0, normal_guess=normal_guess)
    if any(config.tangential_force_control):
        res = _retry(res, lambda r: _add_work(r, _load_by_displacement(*args, r)))
    return res


def _retry(res: StepResult, fn) -> StepResult:
    """`fn(res)` if `res` did not converge, else `res`.

    A `while_loop` of at most one pass rather than a `cond`: under `vmap` a `cond`
    becomes a `select` that always runs both branches, while a batched `while_loop`
    runs its body only while some member needs it.
    """

    def cond(carry):
        r, tried = carry
        return (~r.converged) & (~tried)

    def body(carry):
        return fn(carry[0]), jnp.array(True)

    return jax.lax.while_loop(cond, body, (res, jnp.array(False)))[0]


def _add_work(before: StepResult, after: StepResult) -> StepResult:
    """`after`, with the iterations and rounds of `before` included."""
    return after._replace(iterations=before.iterations + after.iterations,
                          rounds=before.rounds + after.rounds)


_ROOT_STEPS = 40  # evaluations of the load root search (bracketing + Illinois)


def _load_by_displacement(operator, config, compliance, poisson, friction, h0, history,
                          normal_target, tangential_target, previous_slip,
                          failed: StepResult) -> StepResult:
    """Meet the tangential load of one direction by a root search on its displacement.

    The direction `d` is x if x is load-controlled, else y (the others keep their
    control). Each evaluation solves the step with `delta_d` prescribed (by the
    configured method), warm-started from the last one. See
    the module docs for the bracketing and the Illinois iteration.
    """
    fc = config.tangential_force_control
    d = fc.index(True)
    sub_config = config._replace(
        tangential_force_control=tuple(f if i != d else False for i, f in enumerate(fc)))
    dtype = h0.dtype
    target_force = jnp.asarray(tangential_target, dtype)[d]
    area = operator.grid.cell_area
    tol = config.rtol

    def evaluate(delta, start: StepResult):
        targets = jnp.asarray(tangential_target, dtype).at[d].set(delta)
        args = (operator, sub_config, compliance, poisson, friction, h0, history,
                normal_target, targets, previous_slip)
        # One solver per evaluation (no nested fallback: compile time); a failed
        # evaluation still steers the bracket but cannot be the answer.
        if config.method == "joint":
            from .joint import joint_step

            r = joint_step(*args, start.pressure, start.shear, normal_guess=start.pressure)
        else:
            r = _rounds_step(*args, start.pressure, start.shear,
                             normal_guess=start.pressure)
        force = area * jnp.sum(r.shear[d])
        scale = area * friction * jnp.sum(r.pressure)  # mu W
        # Load residual as the tangential solver defines it (relative to mu W).
        raw = jnp.abs(force - target_force) / jnp.where(scale > 0, scale, 1)
        raw = jnp.where(jnp.isfinite(raw), raw, jnp.inf)
        # Only a converged evaluation can be the answer (rank: load error, or inf).
        err = jnp.where(r.converged, raw, jnp.inf)
        return r, force - target_force, err, raw

    # ---- Bracket: from the failed step's delta_d, grow geometrically ------------------
    # First step: the force error over the stiffness of a stuck contact of the
    # current size L (~ L / C), floored at 1e-3 of the full slip distance mu W C / L
    # (any positive scale works: it only sets where the geometric growth starts).
    d0 = failed.delta_t[d]
    d0 = jnp.where(jnp.isfinite(d0), d0, 0.0)
    r0, f0, e0, raw0 = evaluate(d0, failed)
    n_contact = jnp.maximum(jnp.sum(r0.pressure > 0), 1)
    size = jnp.sqrt(n_contact * area)
    mu_w = area * friction * jnp.sum(r0.pressure)
    step0 = compliance * jnp.maximum(jnp.abs(f0), 1e-3 * mu_w) / size
    step0 = jnp.where(jnp.isfinite(step0) & (step0 > 0), step0, compliance / size)
    # b: the latest point; a: the other end of the bracket once there is one.
    init = dict(
        a=d0, fa=f0, b=d0, fb=f0, last=r0, best=r0, best_err=e0, best_raw=raw0,
        n=jnp.array(1),
        bracketed=f0 == 0, step=step0, it=r0.iterations, rounds=r0.rounds,
    )

    def cond(s):
        return (s["best_err"] > tol) & (s["n"] < _ROOT_STEPS)

    def body(s):
        a, fa, b, fb = s["a"], s["fa"], s["b"], s["fb"]
        # Not bracketed yet: step from b towards the root (F non-decreasing).
        grow = b - jnp.sign(fb) * s["step"]
        # Bracketed: regula falsi, safeguarded by bisection when the secant point
        # falls outside the inner 90 % of the bracket.
        denom = fb - fa
        ok = denom != 0
        secant = b - fb * (b - a) / jnp.where(ok, denom, 1)
        lo, hi = jnp.minimum(a, b), jnp.maximum(a, b)
        margin = 0.05 * (hi - lo)
        inside = ok & (secant > lo + margin) & (secant < hi - margin)
        x = jnp.where(s["bracketed"], jnp.where(inside, secant, 0.5 * (a + b)), grow)
        r, fx, ex, rawx = evaluate(x, s["last"])
        # Better: a smaller converged load error, or, while nothing has converged, a
        # smaller overall residual (so that a failure reports its best attempt).
        better = (ex < s["best_err"]) | (
            jnp.isinf(s["best_err"]) & jnp.isinf(ex)
            & (jnp.maximum(r.residual, rawx) < jnp.maximum(s["best"].residual, s["best_raw"])))
        best = jax.tree_util.tree_map(lambda n, o: jnp.where(better, n, o), r, s["best"])
        flipped = jnp.sign(fx) != jnp.sign(fb)
        # Bracketed: a sign change moves a to the old b; otherwise a is kept and its
        # value halved (Illinois), which stops regula falsi from stalling on one end.
        # Not bracketed: a sign change closes the bracket [b, x].
        a_new = jnp.where(flipped, b, a)
        fa_new = jnp.where(flipped, fb, jnp.where(s["bracketed"], 0.5 * fa, fa))
        return dict(
            a=a_new, fa=fa_new, b=x, fb=fx, last=r, best=best,
            best_err=jnp.minimum(ex, s["best_err"]),
            best_raw=jnp.where(better, rawx, s["best_raw"]), n=s["n"] + 1,
            bracketed=s["bracketed"] | flipped, step=2 * s["step"],
            it=s["it"] + r.iterations, rounds=s["rounds"] + r.rounds,
        )

    s = jax.lax.while_loop(cond, body, init)
    best = s["best"]
    return best._replace(
        iterations=s["it"], rounds=s["rounds"],
        residual=jnp.maximum(best.residual, s["best_raw"]),
        converged=best.converged & (s["best_err"] <= tol),
    )
