r"""One coupled frictional step solved JOINTLY: one projected CG loop over `(p, q)`.

The rounds of `coupled.contact_step` (block Gauss-Seidel: a full normal solve, then a
full tangential solve, repeated until nothing changes) gain only a factor ~0.1 per
round at `nu = 0.3`, and every round restarts both CGs from scratch. Here the normal
and the tangential problems are iterated together with the full symmetric half-space
operator

    [u_z]       [K_zz  K_zt] [p]
    [u_t] = C   [K_tz  K_tt] [q]          (K_tz = K_zt^T: reciprocal theorem)

applied ONCE per iteration (forward FFTs of the direction's `p` and `q` components,
the spectra combined with every block of the coupling mode, inverse FFTs). The
conditions solved are those of the two separate solvers at a common `(p, q)`:

- normal: `g = h + u_z - delta_z >= 0`, `p >= 0`, `p g = 0`, with the load
  `A sum p = W` (load control, `delta_z` its multiplier) or `delta_z` prescribed;
- tangential (incremental Coulomb law): `ds = b + u_t - delta_t` is `0` on stick cells
  (`|q| < mu p`) and opposite to `q` on slip cells (`|q| = mu p`), with load or
  displacement control per direction;

with `h = h0 + history_z` and `b = history_t - previous_slip` (the coupling terms are
part of the operator). Convergence is tested on the residuals of `normal._evaluate`
and `tangential.tangential_cg` (same definitions, same `rtol`, loads included) with
exact displacements.

**The friction bound is lagged.** Coulomb friction is not associated: the problem is
not a minimisation, and with the bound `mu p` of the current pressure the iteration is
not symmetric. Two current-bound variants were tried and dropped (see the benchmark
notes in `benchmarks/joint_vs_rounds.py`): projecting `q` onto the moving discs after
every step thrashes (hundreds of iterations), and "slaving" the slip shear to the
pressure inside the search direction is fast when it converges but falls into limit
cycles at the contact edge in about half of a parameter sweep. Here the bound `B` is
frozen, which makes the inner problem the CONVEX quadratic programme

    min 1/2 t.C K t + p.(h - delta_z) + q.(b - delta_t),  p >= 0,  |q_i| <= B_i,

(plus the load constraints), and it is updated to `mu p` (slip cells follow) as soon as
the inner residual has dropped below `sigma` times the residual after the previous
update, or has not halved for `_UPDATE_WHEN_STUCK` iterations (then at most every
third iteration): an inexact outer loop
on the bound only (about 7 updates per increment of Spence's ramp to reach `1e-8`).
The update decided after an iteration is made inside the next one (the new bound and
the slip cells moved onto it are part of that iteration's change of `x`, so it needs
no operator application of its own); an updated iterate within the tolerance is
certified with exact displacements and residual scales. The bound is always updated
after each of the first three iterations (`_EARLY`): the warm start's pressure is off
by the load increment, and converging the inner problem for its bound was wasted
(Spence, 30 increments, one early update: 759 -> 668 iterations).
Cells that came into contact since the last update start on their new disc, opposite
to their slip increment (contact edges slip; `move_to_bound` in the loop).

**Inner iteration** (projected, preconditioned, locally optimal CG):

- free variables: `p` on contact cells and on penetrating cells out of contact
  (Polonsky & Keer's re-entry, here inside the subspace: the exact minimisation sets
  their pressure; clip at zero after the step, mean-free directions and rescaling for
  load control);
  `q` on stick cells and on released slip cells (wrong-sign slip) as vectors, and the
  rotation of slip cells along their disc, with the disc curvature `lambda / B` in the
  preconditioner and the step (`tangential.py`); a released cell whose wrong-sign
  slip no move inside its disc could undo jumps onto its disc opposite to its slip
  instead (with one shear component: to the other side; `_FLIP`);
- preconditioner: the full-plane inverse of the operator's block diagonal
  (`precondition.block_preconditioner`: the padded tangential spectra floored by the
  normal one, on the unpadded grid, raised to the continuous half-space symbols where
  the wrapped kernel's are too small; inverting the whole symbol matrix, coupling and
  `xy` included, saved 3 % of the iterations at a higher cost), restricted to the
  free variables, the rotating cells scaled by `w = C K_tt(0) / (C K_tt(0) +
  curvature)` (non-periodic grids only: see `fft_precond`); after the first
  iterations of a step, a rotating cell's direction interpolates by `w` between the
  full-plane inverse and the diagonal `1 / C K_tt(0)` before that scaling (where the
  curvature dominates, the operator's non-local part hardly matters:
  `_ROT_BLEND_AFTER`; a one-step Cattaneo-Mindlin load "full" 47 -> 34 iterations at
  256^2 over 4 a). Right after slip cells
  were released, unless the residual is already below `_FFT_RES`, the diagonal
  preconditioner (`p` by `1 / C K_zz(0)`, `q` by `1 / (C K_tt(0) + curvature)`) is
  used instead; with two shear components, after the early iterations, only for the
  released cells (34 -> 26 iterations for that step). Then the mean removal (normal
  load) and the oblique load-preserving projection of `tangential.py` (tangential
  loads), block-diagonal because each load involves only `p` or only `q`. Measured
  (105^2, float64, rtol 1e-8), with the merged and early bound updates below:
  Spence's ramp (90 increments) 3921 -> 1709 iterations (FFT preconditioner always:
  1548, but Cattaneo-Mindlin under load control in one step then takes 88 instead of
  55; with the switch 62); with the continuous symbols 1450, and 46 for that
  Cattaneo-Mindlin step (56 at 256^2 over 4 a, 72 before); with no release at the
  early bound updates (`_EARLY`) and `_FFT_RES` 1255, the Cattaneo-Mindlin steps
  unchanged;
- the step minimises the quadratic exactly over the subspace spanned by the
  preconditioned gradient's `p` part, its `q` part, and the previous change of `x` (a
  3x3 system): one exact line search per block, and the CG recurrence (the 2-d
  subspace `{z, previous}` is CG for a quadratic). The quadratic forms of the
  direction are evaluated in Fourier space (Parseval: one forward transform of `z`,
  one pass over its spectrum with the Parseval weights folded into the symbols); those
  with the previous change use its displacement, kept in real space;
- the whole change of `x` after the projections (clipping, rescaling,
  projection onto the discs, load fixes) is transformed (forward and inverse), so the
  displacement is exact at every iteration (up to round-off): 1.5 coupled operator
  applications per iteration plus the preconditioner's unpadded transforms. Three
  `cond`s in the loop body, on cheap real-space operands: the preconditioner (skipped
  while the diagonal one is used), the projection onto updated discs (bound updates
  only) and the final certification;
- the loads after the projections: the stick cells take the tangential load deficit
  (a uniform shift); where they cannot (it would take them out of their discs) or no
  cell sticks, the deficit is first spread by one common shift of every contact cell,
  slip cells turning on their discs (`fix_load`, `spread_load`: small or absent stick
  zones under strong coupling, which used to stall);
- no restart when variables are freed (released slip cells, re-entering cells): the
  previous step stays in the subspace, whose minimisation is exact anyway (restarting
  there, as Polonsky-Keer, with `_FFT_RES` 3e-5 instead of 1e-4: Spence 90 x 105^2
  1075 -> 1097 iterations, one-step Cattaneo-Mindlin "full" 40/44/53/49 -> 47/52/57/54;
  restarting at every change of an active set or at bound updates was worse); every
  `resync_every` iterations the displacement of `x` itself is transformed instead of
  the change (round-off drift).

**Cost** (2-core CPU, float64, n = 128, padded spectra 256 x 129): one iteration is
three 3-component FFTs (forward of `z`, forward and inverse of the change), two
unpadded ones (the preconditioner) plus real-space passes (~180 XLA kernels at 105^2,
about as much time as the transforms: benchmarks/README.md); the spectra are
kept in the `(ky, kx)` layout that the column FFTs produce (`forward` / `inverse`
below), so no spectral pass is strided. An earlier
version spent ~10 ms of ~14 ms per iteration in nine Parseval inner products over the
padded spectra with a broadcast weight (XLA:CPU's YNN reduction fusions run those ~10x
slower than plain reductions) and in `cond` copies of the pending-change transform.

Gross sliding under tangential load control (`|F| >= mu W`, to `rtol / 2`:
`tangential.gross_sliding`) is handled as in `coupled.py`: `q = B F/|F|` on every
contact cell, only `p` is iterated, the tangential residual is zero, and the bound
updates converge to `q = mu p F/|F|`.

**Use and validation.** `coupled.contact_step` calls `joint_step` for every coupled
step by default (`StepConfig.method = "joint"`) and falls back to the rounds when it
returns `converged=False`; `converged` is decided here only from an exact evaluation
of both residuals with the bound `mu p` (the same definitions as the separate solvers),
so a lagged-bound iterate is never reported as a solution. The iteration gives up
early when the best residual has not halved for `_STALL` iterations (one known case:
displacement control past gross sliding with the total slip law, where the stick set
cycles). tests/test_joint.py compares it with the rounds on coupled scenes (both slip
laws, load and displacement control, "x" and "full" coupling, a Zener scene through
`jc.solve`) to `2 rtol n` of max p.
"""

import jax
import jax.numpy as jnp
import numpy as np

from .coupled import StepConfig, StepResult
from .precondition import block_preconditioner
from .tangential import dot as _dot
from .tangential import gross_sliding, slip_multiplier
from .tangential import solve_small as _solve_small


# Bound update when the inner residual < sigma x the residual at the last update.
_SIGMA = 0.5
_STICK_TOL = 1e-10  # as tangential.py (float64; at least 64 eps of the dtype)
_DEBUG = False
# A slip cell whose slip has the direction of its shear (a release, `lambda < 0`) by
# more than `_FLIP` times what moving its shear across the whole disc would change
# locally (`c_tt 2 B`, the operator's diagonal) cannot stick: it flips to the other
# side of its disc (two shear components: onto its disc opposite to its slip) instead
# of being freed. Freed, the step carried such cells (at the contact edge, where
# `B = mu p` is tiny and the slip largest) across the disc, the projection left them
# on the opposite side with the residual up ~100x, and the next step undid it
# (`alpha_3 = -1`): a two-cycle until `_STALL`. One component ("x"): the coupled
# normal load alone at 256^2: 205 -> 19 iterations; CM nu 0.45 at 256^2: 46 -> 15;
# one-step sweeps at 48^2 and 64^2 (50 loads): 1054 -> 770, max 169 -> 23;
# benchmarks/joint_robustness.py 1756 -> 1731. 1 flipped too early (48^2, nu 0,
# F 0.85 mu W: 24 -> 287); 2, 4 and 8 all mended the cases above. Two components
# ("full"; the same cycle, with 2 cells released every other iteration and no stick
# cell left): nu 0, F = 0.95 mu W at 0.7 rad in one step, 64^2 / 128^2 over 4 a:
# 1039 / 1194 iterations (through the fallbacks) -> 21 / 21 (2 and 8 the same); a
# one-step "full" sweep (nu 0-0.45 x F 0.3-0.995 mu W, 48^2, 64^2 and 64^2 oblique;
# 75 loads) 2387 -> 1342 iterations, max 34 -> 23, none worse; joint_robustness
# 1731 -> 1730; Spence 90 x 105^2 1006 unchanged.
_FLIP = 4.0
# Give up (converged=False, so that `contact_step` falls back to the rounds) when the
# best residual has not halved for this many iterations: the lagged-bound iteration
# can cycle on the stick set (seen under displacement control past gross sliding with
# the total slip law, where the load fix of a load-controlled direction shifts every
# slip cell back inside its disc). Converging runs halve it every few iterations.
_STALL = 150
# Update the bound also when the residual has not halved for this many iterations. With
# one shear component and no stick cell the load spread runs every iteration, and a
# release/spread two-cycle can hold the residual (40 and 26 cells released in turn,
# alpha_3 = -1): "x", Zener mu_inf / mu_0 = 10, nu 0.45, W falling under a constant F_x,
# 40^2 (fast creep: the predictor's pressure peak 3x off, the early updates had left
# no stick cell): one step 55 -> 27 iterations; the 45-scene "x" viscoelastic sweep
# 11025 -> 10976, max 55 -> 27 (its three steps above 24 mended, no other step
# changed); joint_robustness 77 + 63 scenes and the 9 coupled scenes unchanged (one
# viscoelastic scene +1). 4 gave 26 on that step.
_UPDATE_WHEN_STUCK = 8
# ... but not at every iteration: only when neither this iteration nor the previous one
# updated it (at most every third iteration). `since` counts from the last halving of
# the BEST residual, so after the residual jumped up (a bound update that changed the
# slip state) the rule held for every iteration to convergence, and a bound updated
# at every iteration never lets the inner problem converge: a periodic 48^2
# Cattaneo-Mindlin "full" step at the gross-sliding limit (the slow
# test_periodic_coupled_step_converges_quickly) went 83 -> 193 iterations with
# be2bcd9's rule, back to 83 with this gap (116 updating only at every 8th stalled
# iteration); the "x" stuck step 27 -> 26 (the 45-scene "x" sweep 10976 -> 10978, max
# 27 -> 26); joint_robustness 77 + 63 scenes 1861 / 16568 -> 1861 / 16567; the 9
# coupled scenes 2399 unchanged. Waiting for three iterations: the "x" step 38.
# Always update the bound after each of the first `_EARLY` iterations (the predictor's
# p is off by the load increment). With `_SIGMA` 0.3 -> 0.5 (more frequent updates),
# 1 -> 3: Spence 90 x 105^2 1201 -> 1097 iterations; Spence 30 increments (mu 0.1 /
# 0.4; 64^2 over 3 a, nu 0.1) 522/607/459 -> 503/532/411; Cattaneo-Mindlin "full" in
# one step 45/50/59/60 -> 47/52/57/54, its 10-step ramp at 64^2 178 -> 165. The
# neighbours (2 or 4; 0.4 or 0.6) are within 1 % of the total, 1 / 0.3 is 9 % more.
# At those early updates no slip cell is released: the bound moves by the whole load
# increment in the same iteration, so the slip signs evaluated at the predictor's bound
# are stale (Spence, 90 increments: ~700 cells released at the second iteration of
# every increment, and back to slip at the third; 1450 -> 1365 iterations).
_EARLY = 3
# Below this residual the FFT preconditioner is kept right after a release (the
# released cells are then few, near the stick edge, and the diagonal steps that follow
# a release gain little): Spence, 90 increments 1365 -> 1255 iterations;
# Cattaneo-Mindlin "full" in one step unchanged (at 1e-4: 77 -> 83 iterations at
# 256^2 over 4 a, F = 0.9 mu W; with the restarts then in use). 1e-3 gives
# the same totals as 1e-4, 1 (always the FFT directions) 323 iterations for one
# Cattaneo-Mindlin step at 105^2 (F = 0.9 mu W).
_FFT_RES = 1e-4
# The preconditioner of rotating slip cells interpolates between the operator's
# full-plane inverse and its diagonal by their disc curvature (see `body`) once more
# than this many iterations of a step are done. Measured, float64, iterations of one
# Cattaneo-Mindlin step "full" (F = 0.5 / 0.9 mu W; 105^2 over 2.3 a, 256^2 over 4 a)
# / Spence 90 x 105^2 / three Spence ramps of 30 increments at 64^2 over 3 a (mu 0.1,
# 0.4; nu 0.1) / a 10-step Cattaneo-Mindlin ramp at 64^2: never (the full-plane
# inverse always): 43, 50, 47, 53 / 1000 / 356, 461, 387 / 150;
# 4: 28, 33, 34, 29 / 1005 / 328, 464, 378 / 143; from the first iteration: 24, 24,
# 25, 26 / 1071 / 350, 465, 389 / 155; 3, 5, 8: Spence 1075, 998, 1004. The diagonal
# alone (no full-plane inverse on rotating cells) 31, 25, 35, 26 / 2150.
_ROT_BLEND_AFTER = _EARLY + 1
# The load fix (`fix_load`): the stick cells carry the load deficit left by a step's
# projections; where that leaves the load off by more than `_SPREAD_WHEN` x mu W (the
# stick cells cannot take the deficit: they would leave their discs), or where no
# cell sticks, the deficit is first spread over every contact cell by one common
# shift found in `_SPREAD_NEWTON` Newton steps (`spread_load`). With nu = 0.1
# and F = 0.75 / 0.9 / 0.99 mu W in one step ("full", 64^2 over 4 a) the step took
# 808 / 1410 / 1332 iterations through the fallbacks (the deficit on the few new
# stick cells pushed them back out, the stall criterion handed over), now 20 / 23 /
# 15 (at 0.99 also thanks to `tangential.slip_multiplier`). Spreading at every
# iteration (`_SPREAD_WHEN` = 0) sent the 256^2 Cattaneo-Mindlin step at 0.9 mu W
# from 24 to 364 iterations (a 2-cycle: each step undid the last spread); 1e-6: 334.
# A sweep of one-step loads (48^2 over 4 a, nu 0 / 0.1 / 0.2 / 0.3 / 0.45, F = 0.3 /
# 0.6 / 0.85 / 0.95 / 0.995 mu W, "x" and "full"; 64^2 float32; 5-step ramps; oblique
# ramps; benchmarks/joint_robustness.py): all 68 converge without the fallbacks,
# 8-24 iterations a step; on a grid of 4 a(nu = 0.3) for every nu, one step of "x",
# nu 0.1, F = 0.85 mu W took 169 (a release / recapture 2-cycle of 2 cells). With
# one shear component, without the spread: "x", nu 0, F = 0.3 mu W fell back (315);
# the spread moving only the cells inside their discs: one fallback in the 25 "x"
# loads at 64^2 (nu 0.1, F = 0.3 mu W: 316), none with them all moving (<= 100).
_SPREAD_WHEN = 1e-3
_SPREAD_NEWTON = 4


def _safe_div(a, b):
    ok = b != 0
    return jnp.where(ok, a / jnp.where(ok, b, 1), jnp.zeros_like(a))


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
    both (it is among the costliest elementwise passes of the joint loop)."""
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
    # Gaussian elimination without pivoting (hs is SPD with unit diagonal).
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


def _parseval_weights(grid):
    """Weights `w` and normaliser `N` with `a.b = sum(w Re(conj(a^) b^)) / N` for the
    spectra `a^ = forward(a)` of the operator (rfft along the last axis)."""
    nx, ny = grid.shape
    n_fft = ny if grid.periodic else 2 * ny
    count = nx * ny if grid.periodic else 4 * nx * ny
    w = np.full(n_fft // 2 + 1, 2.0)
    w[0] = 1.0
    if n_fft % 2 == 0:
        w[-1] = 1.0
    return w, float(count)


def joint_step(*args, **kwargs) -> StepResult:
    """Solve one coupled step jointly; a drop-in for the rounds of `contact_step`.

    Arguments as `coupled.contact_step`: `(operator, config, compliance, poisson,
    friction, h0, history, normal_target, tangential_target, previous_slip, p0, q0,
    normal_guess=None)`. `config.coupled` must be `True` and `config.nd` 1 or 2;
    `config.max_steps` bounds the joint iterations (`max_rounds` is unused).
    `StepResult.rounds` counts the friction-bound updates; `iterations` the joint CG
    iterations.
    """
    return joint_solve(*args, **kwargs)[0]


def joint_solve(
    operator,
    config: StepConfig,
    compliance,
    poisson,
    friction,
    h0,
    history,
    normal_target,
    tangential_target,
    previous_slip,
    p0,
    q0,
    normal_guess=None,
):
    """`joint_step`, also returning statistics: `applications` (equivalent coupled
    operator applications: a forward or an inverse transform of all components counts
    1/2; the preconditioner's unpadded transforms, about 1/4 of an application per
    iteration, are not counted) and `counts` (periodic resyncs, bound updates)."""
    nd = config.nd
    if nd not in (1, 2) or not config.coupled:
        raise ValueError("joint_step needs a coupled step with nd = 1 or 2")
    grid = operator.grid
    area = grid.cell_area
    dtype = h0.dtype
    nx, ny = grid.shape
    rtol = config.rtol
    load_n = config.normal_force_control
    fc_tuple = tuple(bool(f) for f in config.tangential_force_control)
    fc = jnp.asarray(fc_tuple)
    any_force = any(fc_tuple)
    all_force = all(fc_tuple)
    normal_target = jnp.asarray(normal_target, dtype)
    tangential_target = jnp.asarray(tangential_target, dtype)
    friction = jnp.asarray(friction, dtype)

    h = h0 + history[2]
    b = history[:nd] - previous_slip
    # A cell projected onto its disc must not count as stick by round-off (float32).
    stick_tol = max(_STICK_TOL, 64 * float(jnp.finfo(dtype).eps))

    # ---- The coupled operator: symbols (unit-modulus spectra x compliance) ---------
    def symbols(transposed):
        """`(nn, xx, xy, yy, zx, zy, izx, izy)` in the `(kx, ky)` layout of
        `operator.forward`, or `transposed` to `(ky, kx)`."""
        nn = compliance * operator.normal_spectrum(poisson, transposed)
        xx, xy, yy = operator.tangential_blocks(poisson, transposed)
        xx = compliance * xx
        if nd == 2:
            xy, yy = compliance * xy, compliance * yy
        zx, zy = operator.coupling_spectra(poisson, transposed)
        izx = 1j * compliance * zx  # u_z <- q_x; u_x <- p is its negative (reciprocity)
        izy = 1j * compliance * zy if (nd == 2 and zy is not None) else None
        return nn, xx, xy, yy, zx, zy, izx, izy

    nn, xx, xy, yy, zx, zy, izx, izy = symbols(False)
    w_ky, n_par = _parseval_weights(grid)
    w_ky = jnp.asarray(w_ky, dtype)[None, :]  # (1, ky): broadcasts over kx
    # Self-compliances (the operator's diagonal): the kernels at zero offset.
    c_zz = jnp.sum(w_ky * nn) / n_par
    c_tt = jnp.sum(w_ky * xx) / n_par
    # Not on periodic grids: their operator maps a uniform traction to zero (the mean
    # displacement goes into the approach), the inverse has no zero mode, and under
    # tangential load control the FFT directions then stall (48^2, CM "full": 4208
    # iterations with the fallbacks, against 61 with the diagonal; a finite zero mode
    # 184-8250).
    fft_precond = config.precondition and not grid.periodic
    if fft_precond:
        precondition = block_preconditioner(
            operator, nn, xx, yy if nd == 2 else None, compliance=compliance,
            poisson=poisson)

    # Spectra in the (ky, kx) layout of `forward` below, from the operator's raw
    # spectra in that layout (held by `HalfSpace.with_transposed_spectra`, which
    # `jc.solve` builds before its time loop; transposing the symbols here cost ~3 ms
    # per step at 105^2, Spence 4.62 -> 4.22 s on one core).
    if not grid.periodic:
        nn, xx, xy, yy, zx, zy, izx, izy = symbols(True)
        w_ky = jnp.swapaxes(w_ky, -1, -2)
    # Parseval weights folded into the (real) symbols once, outside the loop: the
    # quadratic forms of a direction's spectrum are then plain sums over the spectrum
    # (XLA:CPU runs a reduction fused with a broadcast weight ~10x slower).
    wn = w_ky / n_par
    s_zz = wn * nn
    s_xx = wn * xx
    s_zx = wn * compliance * zx
    if nd == 2:
        s_xy, s_yy = wn * xy, wn * yy
        s_zy = wn * compliance * zy if izy is not None else None

    def k_of_p(ph):
        """Spectra `(u_z, u_t...)` of a pressure spectrum."""
        out = [nn * ph, -izx * ph]
        if nd == 2:
            out.append(-izy * ph if izy is not None else jnp.zeros_like(ph))
        return jnp.stack(out)

    def k_of_q(qh):
        """Spectra `(u_z, u_t...)` of a shear spectrum `(nd, ...)`."""
        qx = qh[0]
        if nd == 1:
            return jnp.stack([izx * qx, xx * qx])
        qy = qh[1]
        uz = izx * qx + (izy * qy if izy is not None else 0)
        return jnp.stack([uz, xx * qx + xy * qy, xy * qx + yy * qy])

    def k_full(th):
        return k_of_p(th[0]) + k_of_q(th[1:])

    def quad_forms(zh):
        """`(z_p.C K_zz z_p, z_p.C K_zt z_q, z_q.C K_tt z_q)` from the spectrum of
        `z = (z_p, z_q)`: one pass over it (Parseval)."""
        pr, pi = jnp.real(zh[0]), jnp.imag(zh[0])
        xr, xi = jnp.real(zh[1]), jnp.imag(zh[1])
        t11 = s_zz * (pr * pr + pi * pi)
        # Re(conj(P) i zx Q) = -zx Im(conj(P) Q)
        t12 = -s_zx * (pr * xi - pi * xr)
        t22 = s_xx * (xr * xr + xi * xi)
        if nd == 2:
            yr, yi = jnp.real(zh[2]), jnp.imag(zh[2])
            if s_zy is not None:
                t12 = t12 - s_zy * (pr * yi - pi * yr)
            t22 = t22 + 2 * s_xy * (xr * yr + xi * yi) + s_yy * (yr * yr + yi * yi)
        return jnp.sum(jnp.stack([t11, t12, t22]), axis=(-2, -1))

    if grid.periodic:
        def forward(x):
            return operator.forward(x)

        def inverse(uh):
            return operator.inverse(uh)
    else:
        # `operator.forward` / `inverse` with the spectrum TRANSPOSED, `(ky, kx)`: the
        # column transforms run along the last (contiguous) axis, so XLA keeps the
        # spectra in that layout and every spectral pass reads them contiguously (with
        # the `(kx, ky)` layout, each multiply by a symbol was a strided transpose).
        def forward(x):
            spec = jnp.fft.rfft(x, n=2 * ny, axis=-1)
            return jnp.fft.fft(jnp.swapaxes(spec, -1, -2), n=2 * nx, axis=-1)

        def inverse(uh):
            field = jnp.fft.ifft(uh, axis=-1)[..., :nx]
            field = jnp.swapaxes(field, -1, -2)
            return jnp.fft.irfft(field, n=2 * ny, axis=-1)[..., :ny]

    def apply(x):
        """Displacements `(u_z, u_t...)` of the traction `(p, q...)`: one application
        of the operator."""
        return inverse(k_full(forward(x)))

    def exact(x):
        """Exact displacements and the residual scales of the separate solvers,
        `||C K_zz p||` and `||C K_tt q|| + ||b + C K_tz p||_contact` (1.5 applications:
        the p and q parts are transformed back separately)."""
        th = forward(x)
        both = inverse(jnp.concatenate([k_of_p(th[0]), k_of_q(th[1:])]))
        up, uq = both[:1 + nd], both[1 + nd:]
        contact = friction * x[0] > 0
        s_n = jnp.sqrt(jnp.sum(up[0] * up[0]))
        s_t = jnp.sqrt(jnp.sum(uq[1:] * uq[1:])) + jnp.sqrt(
            jnp.sum(jnp.where(contact[None], up[1:] + b, 0) ** 2))
        return up + uq, jnp.stack([s_n, s_t])

    w_p = c_tt / c_zz  # preconditioner weight of p relative to q

    f_norm = jnp.sqrt(jnp.sum(tangential_target**2))
    direction = tangential_target / jnp.where(f_norm > 0, f_norm, 1)

    def sliding_of(p):
        if not all_force:
            return jnp.array(False)
        limit = area * jnp.sum(friction * p)
        return gross_sliding(f_norm, limit, rtol)

    # ---- Conditions (normal._evaluate and tangential_cg's evaluate) ------------------
    def stick_of(q, bound):
        """Contact cells strictly inside their disc `|q| < bound` (by `stick_tol`)."""
        return (bound > 0) & (_dot(q, q) < (bound * (1 - stick_tol)) ** 2)

    def evaluate(x, u, scales, bound, sliding):
        """Both residuals at `(p, q)` with displacements `u`, the tangential one for
        the friction bound `bound`."""
        p, q = x[0], x[1:]
        contact = p > 0
        n_contact = jnp.sum(contact)
        raw = h + u[0]
        if load_n:
            dz = jnp.where(
                n_contact > 0,
                _safe_div(jnp.sum(jnp.where(contact, raw, 0)), n_contact),
                jnp.min(raw))
        else:
            dz = normal_target
        g = raw - dz
        violation = jnp.where(contact, g, jnp.minimum(g, 0))
        num = jnp.sqrt(jnp.sum(violation * violation))
        scale = scales[0]
        res_n = jnp.where(num == 0, 0.0, num / jnp.where(scale > 0, scale, jnp.inf))
        res_n = jnp.where((num > 0) & (scale == 0), jnp.inf, res_n)

        contact_t = bound > 0
        w = u[1:] + b
        stick = stick_of(q, bound)
        n_stick = jnp.sum(stick)
        mean_stick = _safe_div(_sum2(jnp.where(stick[None], w, 0)), n_stick)
        inv = _inv_norm(q)
        all_slip = slip_multiplier(w, q * inv[None], contact_t, fc, tangential_target)
        multiplier = jnp.where(n_stick > 0, mean_stick, all_slip)
        dt = jnp.where(fc, multiplier, tangential_target)
        ds = w - dt[:, None, None]
        ds_mag = jnp.sqrt(_dot(ds, ds))
        slip_violation = ds + (ds_mag * inv)[None] * q
        violation = jnp.where(stick[None], ds,
                              jnp.where(contact_t[None], slip_violation, 0))
        num = jnp.sqrt(jnp.sum(violation * violation))
        res_t = jnp.where(num == 0, 0.0, _safe_div(num, scales[1]))
        res_t = jnp.where((num > 0) & (scales[1] == 0), jnp.inf, res_t)
        bound_total = area * jnp.sum(bound)
        load_err = jnp.abs(area * _sum2(q) - tangential_target)
        load_err = jnp.where(fc, _safe_div(load_err, bound_total), 0.0)
        res_t = jnp.maximum(res_t, jnp.max(load_err))
        res_t = jnp.where((bound_total > 0) & ~sliding, res_t, 0.0)
        return dict(g=g, dz=dz, res_n=res_n, ds=ds, dt=dt, stick=stick, res_t=res_t,
                    residual=jnp.maximum(res_n, res_t), inv_norm=inv)

    # ---- Loads and projections -----------------------------------------------------
    def rescale(p):
        total = area * jnp.sum(p)
        factor = normal_target / jnp.where(total > 0, total, 1)
        return p * jnp.where(total > 0, factor, 0.0)

    def spread_load(q, bound):
        """Restore the tangential load by one common shift `lam` [stress] of every
        contact cell: cells inside their disc move by `lam` (and onto the disc if they
        cross it), cells on it stay on it and turn towards `lam` (two shear
        components: shifted by `lam B / max B`; one component: they flip to the other
        side where `lam` crosses them; keeping them took "x", nu 0.1, F = 0.99 mu W
        at 64^2 from 32 to 147 iterations). `lam`
        solves the load equation by `_SPREAD_NEWTON` Newton steps (the load is a
        monotone function of `lam`, the gradient of a convex one, up to those flips;
        what is left is for `shift_stick`)."""
        contact = bound > 0
        on_disc = contact & ~stick_of(q, bound)
        target = tangential_target / area
        eye = jnp.eye(nd, dtype=dtype)

        if nd == 2:
            # Cells on their disc shift by `lam B / max B`: each turns by about the
            # same angle, and those with a tiny bound (the contact edge: they carry
            # almost none of the load) keep their direction, opposite to their slip.
            # With the whole `lam`, such a cell turned by up to 180 degrees at every
            # spread (every iteration without stick cells), whatever its slip: one
            # step of "full", nu 0.1, F = 0.95 mu W at 1.2 rad, 64^2 over 4 a(0.3):
            # a cell that had just entered the contact (p 1e-6 of max p, the largest
            # slip) held the residual at 1e-2 for ~150 iterations (164 in all; now
            # 15). Not with one component, whose cells flip across the disc where
            # `lam` crosses them ("x", nu 0.3, F = 0.995 mu W at 64^2: 12 -> 208).
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
            # d q_i / d lam: factor x (the identity inside, scale (I - y^ y^T) on
            # the circle).
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

        lam = jax.lax.fori_loop(0, _SPREAD_NEWTON, newton, jnp.zeros(nd, dtype))
        return jnp.where(contact[None], shifted(lam)[0], q)

    def fix_load(q, bound):
        """Restore the loads: `shift_stick`, and where that leaves a load error above
        `_SPREAD_WHEN` x mu W or no cell sticks, `spread_load` first."""
        fixed = shift_stick(q, bound)
        err = jnp.abs(area * _sum2(fixed) - tangential_target)
        err = _safe_div(jnp.max(jnp.where(fc, err, 0.0)), area * jnp.sum(bound))
        bad = (err > _SPREAD_WHEN) | ~jnp.any(stick_of(q, bound))
        if _DEBUG:
            jax.debug.print("      spread {} load error {:.2e}", bad, err)
        # A `cond`: the Newton steps run only where needed (their passes would cost
        # every iteration with a `where`).
        return jax.lax.cond(bad, lambda: shift_stick(spread_load(q, bound), bound),
                            lambda: fixed)

    def shift_stick(q, bound):
        """Shift the stick cells (or, if none, all contact cells) to carry the load."""
        contact = bound > 0
        stick = stick_of(q, bound)
        any_stick = jnp.any(stick)
        where = jnp.where(any_stick, stick, contact)
        count = jnp.sum(where)
        deficit = _safe_div(tangential_target / area - _sum2(q), count)
        shift = jnp.where(fc[:, None, None], deficit[:, None, None] * where[None], 0.0)
        moved = q + shift
        # No stick cell: every contact cell is on its disc; the shift moves them along
        # it (renormalised) rather than inside, where they would count as stick and
        # the stick set would cycle (displacement control past gross sliding with a
        # load-controlled direction). The load is then met to first order only.
        return _onto_discs(moved, bound, contact & ~any_stick)

    def settle_shear(q, bound, follow, sliding):
        """Shear on the discs `|q| <= bound`: `follow` cells on the boundary (slip
        cells when the bound is updated), the others projected; loads restored."""
        q = _onto_discs(q, bound, follow)
        if any_force:
            q = jnp.where(sliding, q, fix_load(q, bound))
        if all_force:
            q = jnp.where(sliding, bound[None] * direction[:, None, None], q)
        return q

    # ---- Initial state -------------------------------------------------------------
    p_init = p0 if normal_guess is None else normal_guess
    p_init = jnp.maximum(jnp.asarray(p_init, dtype), 0)
    if load_n:
        p_init = jnp.where(jnp.sum(p_init) > 0, p_init, jnp.ones_like(p_init))
        p_init = rescale(p_init)
    else:
        local = jnp.maximum(normal_target - h, 0) / c_zz
        p_init = jnp.where(jnp.sum(p_init) > 0, p_init, local)
    bound_init = friction * p_init
    sliding_init = sliding_of(p_init)
    q_init = jnp.asarray(q0, dtype)
    if any_force:
        # No shear to start from (a first step): the load-controlled shear in
        # proportion to the pressure (inside the discs while |F| < mu W).
        total_p = area * jnp.sum(p_init)
        ratio = jnp.where(fc, _safe_div(tangential_target, total_p), 0.0)
        q_init = jnp.where(jnp.any(q_init != 0), q_init,
                           ratio[:, None, None] * p_init[None])
    q_init = settle_shear(q_init, bound_init, jnp.zeros((nx, ny), bool), sliding_init)
    x_init = jnp.concatenate([p_init[None], q_init])
    u_init, scales_init = exact(x_init)
    ev_init = evaluate(x_init, u_init, scales_init, bound_init, sliding_init)

    zeros_x = jnp.zeros((1 + nd, nx, ny), dtype)
    init = dict(
        x=x_init, u=u_init, bound=bound_init, sliding=sliding_init, scales=scales_init,
        ev=ev_init, res_ref=ev_init["residual"],
        anchor=ev_init["residual"], since=jnp.array(0),
        fresh=jnp.zeros((nx, ny), bool),
        # previous change of x, its displacement, and their product
        s=zeros_x, ks=zeros_x, sks=jnp.zeros((), dtype),
        it=jnp.array(0), certified=jnp.array(True), updates=jnp.array(0),
        applications=jnp.asarray(1.5, dtype),
        counts=jnp.zeros(2, jnp.int32), want=jnp.array(False), steady=jnp.array(False),
    )

    def exhausted(it, since):
        return (it >= config.max_steps) | (since >= _STALL)

    def cond(s):
        # Leave only from a certified state (bound mu p; exact displacements and
        # scales when within the tolerance): running out of iterations forces a bound
        # update in the next one (so at most max_steps + 1 iterations).
        done = (s["ev"]["residual"] <= rtol) | exhausted(s["it"], s["since"])
        return ~(done & s["certified"])

    def body(s):
        x, u, ev, bound, sliding = s["x"], s["u"], s["ev"], s["bound"], s["sliding"]
        p, q = x[0], x[1:]
        g, ds, stick = ev["g"], ev["ds"], ev["stick"]
        contact = p > 0
        contact_t = bound > 0
        # The step's pressure variables: contact cells and the penetrating cells out of
        # contact (Polonsky-Keer's re-entry), whose gradient `g < 0` enters the subspace
        # like the others, so the exact minimisation below, with the load constraint,
        # sets their pressure (it replaced a local estimate scaled by a tuned factor:
        # Spence, 90 x 105^2, 1046 -> 1000 iterations).
        overlap = (~contact) & (g < 0)
        free_p = contact | overlap

        # -- active sets ------------------------------------------------------------
        q_hat = q * ev["inv_norm"][None]
        slip_cells = contact_t & ~stick
        lam_raw = -_dot(ds, q_hat)
        release = slip_cells & (lam_raw < 0) & ~sliding
        # Cells bound to their disc by the last step are not freed at once, nor any
        # cell at the early bound updates (`_EARLY`).
        release = release & ~s["fresh"] & ~(s["want"] & (s["it"] <= _EARLY))
        # `_FLIP`: cells that cannot stick jump across their disc (no step variable)
        flip = release & (-lam_raw > _FLIP * c_tt * 2 * bound)
        release = release & ~flip
        full = (stick | release) & ~sliding
        if nd == 2:
            rotate = slip_cells & ~release & ~flip & ~sliding
            tt = jnp.where(rotate[None], jnp.stack([-q_hat[1], q_hat[0]]), 0)
            # Disc curvature lambda / B of the rotation of a slip cell.
            curv_disc = jnp.where(
                rotate, _safe_div(jnp.maximum(lam_raw, 0.0), bound), 0.0)
        else:
            rotate = jnp.zeros_like(contact)
            tt = jnp.zeros_like(q)
            curv_disc = jnp.zeros_like(p)

        # -- reduced gradient, preconditioned load-preserving directions -------------
        r_p = jnp.where(free_p, g, 0)
        r_q = jnp.where(full[None], ds, tt * _dot(tt, ds)[None])
        weight = jnp.where(full, 1.0, jnp.where(
            rotate, c_tt / (c_tt + curv_disc), 0.0))
        z_p_diag, pr_diag = w_p * r_p, weight[None] * r_q
        if fft_precond:
            # The full-plane inverse restricted to the free variables (contact cells;
            # full cells and the rotation of slip cells), then the curvature weights.
            # Right after slip cells were released, the diagonal instead: the FFT
            # directions are non-local, and at a large slip annulus (Cattaneo-Mindlin
            # under load control) they flip the slip sign of cells near the stick
            # edge at every iteration (88 iterations against 55 at 105^2; 62 with
            # this switch), while on Spence's ramp they halve the iterations. Late
            # releases (residual < _FFT_RES) keep the FFT directions.
            use_fft = s["steady"]
            if nd == 2:
                # Two shear components: after the early bound updates, the full-plane
                # inverse for every variable but the cells just released (below).
                use_fft = use_fft | (s["it"] > _EARLY)
            m_r = jax.lax.cond(use_fft, precondition, jnp.zeros_like,
                               jnp.concatenate([r_p[None], r_q]))
            z_p = jnp.where(use_fft, jnp.where(free_p, m_r[0], 0), z_p_diag)
            rot = tt * _dot(tt, m_r[1:])[None]
            # The Jacobi direction `r / c_tt` (on the scale of the full-plane inverse);
            # `r_q` is already tangential on rotating cells.
            jacobi = r_q / c_tt
            # A rotating cell's Hessian is the operator plus its disc curvature
            # lambda / B. Where the curvature dominates (a large slip, e.g. a
            # Cattaneo-Mindlin load in one step: median lambda / B = 24 c_tt at
            # 256^2), the operator's diagonal `1 / c_tt` describes it better than
            # its full-plane inverse: the two are interpolated with the curvature
            # weight `c_tt / (c_tt + lambda / B)` (then scaled by it as before).
            # Not in the first iterations of a step, while the bound still moves
            # by the load increment and lambda / B is the predictor's.
            blend = weight[None] * rot + (1 - weight)[None] * jacobi
            rot = jnp.where(s["it"] > _ROT_BLEND_AFTER, blend, rot)
            pr = jnp.where(use_fft, weight[None] * jnp.where(full[None], m_r[1:], rot),
                           pr_diag)
            if nd == 2:
                # Right after a release only the released cells take the diagonal
                # (Jacobi) direction: one-step Cattaneo-Mindlin loads "full" 28, 33,
                # 34, 29 -> 22, 22, 26, 24 iterations (`_ROT_BLEND_AFTER`'s scenes;
                # the ramps within 1 %). With one shear component ("x") it made a
                # load near gross sliding slower (nu 0.1, F = 0.99 mu W, 64^2: 31 ->
                # 263), so there every variable keeps the diagonal direction after a
                # release.
                pr = jnp.where(release[None] & ~s["steady"], jacobi, pr)
        else:
            z_p, pr = z_p_diag, pr_diag
        if load_n:
            z_p = jnp.where(free_p, z_p - _safe_div(jnp.sum(z_p), jnp.sum(free_p)), 0)
        if any_force:
            # Oblique projection onto load-preserving directions (tangential.py):
            # z = P r - P B (B^T P B)^{-1} B^T P r, B c = c on full cells and its
            # tangential part on rotating cells.
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

        # -- exact minimisation over span{z_p, z_q, previous change} -----------------
        # The quadratic forms of z from its spectrum (one forward transform); those
        # with the previous change from its displacement (real space).
        h11, h12, h22 = quad_forms(forward(z))
        prev, kprev = s["s"], s["ks"]
        have = s["it"] > 0  # the previous change is never dropped (no restarts)

        def disc(a, b_):
            return jnp.sum(curv_disc * _dot(a, b_))

        g1 = jnp.sum(r_p * z_p)
        g2 = jnp.sum(r_q * z_q)
        g3 = jnp.where(have, jnp.sum(r_p * prev[0]) + jnp.sum(r_q * prev[1:]), 0.0)
        h22 = h22 + disc(z_q, z_q)
        h13 = jnp.where(have, jnp.sum(z_p * kprev[0]), 0.0)
        h23 = jnp.where(have, jnp.sum(z_q * kprev[1:]) + disc(z_q, prev[1:]), 0.0)
        h33 = jnp.where(have, s["sks"] + disc(prev[1:], prev[1:]), 0.0)
        hm = jnp.stack([jnp.stack([h11, h12, h13]), jnp.stack([h12, h22, h23]),
                        jnp.stack([h13, h23, h33])])
        alpha = _solve3(hm, jnp.stack([g1, g2, g3]))
        alpha = jnp.where(jnp.isfinite(alpha), alpha, 0.0)
        a1, a2, a3 = alpha[0], alpha[1], alpha[2]
        step = jnp.concatenate([(a1 * z_p)[None], a2 * z_q]) + a3 * prev

        # -- projections -------------------------------------------------------------
        x_step = x + step
        p_step, q_step = x_step[0], x_step[1:]
        # Cells out of contact stay out unless they penetrate (`free_p`): the previous
        # change in the step would bring back the cells it just clipped, a cycle on the
        # contact set (nu = 0.5, where the pressure alone moves: a 30-step ramp at
        # 105^2 had steps of ~160 iterations, stopped by `_STALL`, now 10-13).
        p_new = jnp.where(free_p, jnp.maximum(p_step, 0), 0)
        if load_n:
            p_new = jnp.where(jnp.sum(p_new) > 0, p_new, p_init)
            p_new = rescale(p_new)
        # Slip cells that stay slip are put back ON their disc (the previous change
        # in the step may point inside it); the others are projected.
        keep_on = slip_cells & ~release & ~sliding
        # Flipped cells (`_FLIP`): on their disc, opposite to their slip (with one
        # component, the other side).
        q_flip = -q if nd == 1 else -(bound * _inv_norm(ds))[None] * ds
        q_step = jnp.where(flip[None], q_flip, q_step)
        q_new = settle_shear(q_step, bound, keep_on, sliding)
        # The bound update decided at the end of the last iteration: the bound
        # becomes mu p of this iterate and its slip cells follow their discs, inside
        # the one transform of the change below (no application of its own).
        upd = s["want"]
        bound_new = jnp.where(upd, friction * p_new, bound)
        sliding_new = jnp.where(upd, sliding_of(p_new), sliding)

        # A `cond`, not a `where`: the second projection (and its load fix) runs only on
        # the iterations that update the bound (Spence: 604 of 1046);
        # entering cells are put on their discs there too: opposite to their slip
        # increment (contact edges slip: p, hence the bound, vanishes there), rather
        # than at q = 0, where they would count as stick until their slip shows
        # (Spence, 90 increments: 1255 -> 1201 iterations; Cattaneo-Mindlin "full" in
        # one step 46/54/56/77 -> 45/50/59/60).
        def move_to_bound(q_):
            follow = contact_t & ~stick_of(q_, bound) & (p_new > 0) & ~sliding_new
            entering = (~contact_t) & (p_new > 0) & ~sliding_new
            q_ = jnp.where(entering[None], -ds * _inv_norm(ds)[None], q_)
            follow = follow | entering
            return settle_shear(q_, bound_new, follow, sliding_new)

        q_new = jax.lax.cond(upd, move_to_bound, lambda q_: q_, q_new)
        x_new = jnp.concatenate([p_new[None], q_new])

        # -- the exact displacement of the whole change (one application) -----------
        # Every `resync_every` iterations, the displacement of x_new itself instead
        # (against round-off drift; the change's displacement is then the difference).
        d = x_new - x
        it = s["it"] + 1
        periodic = it % config.resync_every == 0
        kt = apply(jnp.where(periodic, x_new, d))
        u_new = jnp.where(periodic, kt, u + kt)
        kd = jnp.where(periodic, kt - u, kt)
        applications = s["applications"] + 1.5
        ev_new = evaluate(x_new, u_new, s["scales"], bound_new, sliding_new)
        if _DEBUG:
            changed = (jnp.any((p_new > 0) != contact)
                       | jnp.any(ev_new["stick"] != stick) | jnp.any(release)
                       | jnp.any(overlap))
            jax.debug.print(
                "it {} res_n {:.2e} res_t {:.2e} alpha {} changed {} dC {} dS {} "
                "rel {} ov {}", it, ev["res_n"], ev["res_t"], alpha, changed,
                jnp.sum((p_new > 0) != contact), jnp.sum(ev_new["stick"] != stick),
                jnp.sum(release), jnp.sum(overlap))

        # -- outer loop: update the friction bound to mu p, with exact displacements -
        # Iterations since the residual last halved: measured against the residual at
        # the last halving (`anchor`), not the running best, so that a steady
        # convergence slower than a halving per iteration does not count as a stall.
        halved = ev_new["residual"] <= 0.5 * s["anchor"]
        since = jnp.where(halved, 0, s["since"] + 1)
        scales_new = s["scales"]
        res_ref = jnp.where(upd, ev_new["residual"], s["res_ref"])
        # A bound-updated iterate within the tolerance is certified with exact
        # displacements AND exact residual scales (in between, the scales of the last
        # certification serve: they are only normalisers).
        final = upd & (ev_new["residual"] <= rtol)

        def certify():
            ue, sce = exact(x_new)
            return ue, sce, evaluate(x_new, ue, sce, bound_new, sliding_new)

        u_new, scales_new, ev_new = jax.lax.cond(
            final, certify, lambda: (u_new, scales_new, ev_new))
        if _DEBUG:
            jax.debug.print(
                "   bound updated: {} residual {:.2e} since {} anchor {:.2e}", upd,
                ev_new["residual"], since, s["anchor"])
        want = (ev_new["residual"] <= _SIGMA * res_ref) | (
            ev_new["residual"] <= rtol) | exhausted(it, since) | (it <= _EARLY) | (
            # `certified` is the previous iteration's `upd`
            (since >= _UPDATE_WHEN_STUCK) & ~upd & ~s["certified"])
        applications = applications + 1.5 * final
        return dict(
            x=x_new, u=u_new, bound=bound_new, sliding=sliding_new, scales=scales_new,
            ev=ev_new, res_ref=res_ref,
            fresh=full & ~ev_new["stick"],
            s=d, ks=kd, sks=jnp.sum(d * kd),
            it=it, certified=upd, updates=s["updates"] + upd,
            anchor=jnp.where(halved, ev_new["residual"], s["anchor"]),
            since=since,
            applications=applications, want=want,
            steady=~jnp.any(release) | (ev_new["residual"] < _FFT_RES),
            counts=s["counts"] + jnp.stack([periodic, upd]).astype(jnp.int32),
        )

    s = jax.lax.while_loop(cond, body, init)

    # ---- Finish: the loop ends certified (exact displacements, both residuals with
    # the bound mu p), so its evaluation is the answer's.
    x, ev = s["x"], s["ev"]
    p = x[0]
    contact = p > 0
    result = StepResult(
        pressure=p, shear=x[1:], approach=ev["dz"], delta_t=ev["dt"],
        slip=ev["ds"] + previous_slip, stick=ev["stick"],
        sliding=jnp.any(contact) & ~jnp.any(ev["stick"]),
        iterations=s["it"], rounds=s["updates"], residual=ev["residual"],
        converged=ev["residual"] <= rtol,
    )
    return result, dict(applications=s["applications"], counts=s["counts"])
