r"""One step of the coupled frictional contact problem (elastic, or one viscoelastic step).

The normal and tangential problems interact through the coupling blocks of the
half-space operator (`(1 - 2 nu)` terms): the shear changes the normal displacement and
the pressure changes the tangential displacement. The step alternates the two solvers
(block Gauss-Seidel, as in the paper and Panagiotopoulos' process), each warm-started
from the previous round, until a whole round changes nothing: the normal solver accepts
the current pressure with the latest shear, and the tangential solver accepts the
current shear with the latest pressure (both at their tolerance, with zero iterations).
Without coupling, one round is exact.

All displacements here are `C * K1 * traction + history`, with `C` the step's
(instantaneous or effective) compliance and `history` a known field (zero for an
elastic body).
"""

from typing import NamedTuple

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from .normal import polonsky_keer
from .tangential import TangentialState, tangential_cg


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
    """Solve one coupled step. See the module docs; `history` is `(u_x, u_y, u_z)`."""
    grid = operator.grid
    area = grid.cell_area
    dtype = h0.dtype
    nd = config.nd
    nx, ny = grid.shape

    nn_spec = compliance * operator.normal_spectrum(poisson)

    def apply_normal(p):
        return operator.inverse(operator.forward(p) * nn_spec)

    def solve_normal(h_eff, p_start):
        return polonsky_keer(
            apply_normal, h_eff, normal_target, area,
            load_control=config.normal_force_control, rtol=config.rtol,
            max_steps=config.max_steps, resync_every=config.resync_every, p0=p_start,
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

    unit = jnp.zeros((nd, nx, ny), dtype).at[0, nx // 2, ny // 2].set(1.0)
    self_compliance = apply_tangential(unit)[0, nx // 2, ny // 2]

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
            )

        if not all_force:
            return cg()
        # Gross sliding under load control: |F| >= mu W has no static solution; the
        # indenter slides and q = mu p along F (reported, never iterated on).
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

        return jax.lax.cond((f_norm >= limit) & (f_norm > 0), slide, cg)

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
