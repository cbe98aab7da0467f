"""Levenberg-Marquardt (`FitOptions(optimiser="lm")`, and `"auto"`'s second stage):
optimistix's `LevenbergMarquardt` on the relative residual, its Jacobian by forward
mode through the contact solve's implicit tangent solves (one per parameter), one
compiled program per problem shape; vmapped over a batch of curves for
`jc.fit_prony_batch`. `LMRun` drives it from a fit (a failure is a message, not an
exception), in compiled runs of `LM_CHUNK` steps: a run that lowered the loss by less
than `STALL_TOL` of itself ends it, NOT converged ("stalled"). LM's own test (on the
parameters AND the loss) never fires while a parameter creeps towards a bound or along
a valley the data do not determine (curves without a hold: every run went to its step
bound, `benchmarks/notes/rings.md`); the fit's certificate judges the end point as
before. Between runs a modulus the data do not need is dropped (`drop_a_modulus`):
LM walks a modulus towards 0 only a few hundredths of its log a step."""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._solver.implicit import ImplicitAdjoint
from .model import Evaluator, SceneModel, relative_residual
from .parametrisation import LOG_FLOOR


def have_optimistix() -> bool:
    try:
        import optimistix  # noqa: F401
    except ImportError:
        return False
    return True


# LM steps of one compiled run of `LMRun`, and the relative decrease of the loss over
# one below which it stops: chi^2 lowered by 1e-4 of itself in 25 steps (0.01 for a fit
# at the noise of 100 samples), far below what the data resolve. Between runs a
# modulus the data do not need is dropped: the shorter the run, the sooner.
LM_CHUNK = 25
STALL_TOL = 1e-4


def run_steps(max_steps: int, done: int = 0) -> int:
    """The steps of the next compiled run of `LMRun` after `done` of `max_steps`
    (`jc.fit_prony_batch` batches the first)."""
    return min(LM_CHUNK, max_steps - done)


def lm_rtol(dtype) -> float:
    """LM's relative tolerance (its absolute one is a tenth of it) for `dtype`."""
    return 1e-8 if jnp.finfo(dtype).bits >= 64 else 1e-4


@eqx.filter_jit
def _lm_solve(theta, args, rtol, atol, max_steps):
    """`optimistix.least_squares` with `LevenbergMarquardt`: `(theta, result, steps)`.
    The Jacobian comes from forward mode (`jac="fwd"`: `jax.jacfwd`, one tangent solve
    per parameter, batched; the contact model's solves in
    `ImplicitAdjoint(mode="forward")`, `_forward_model`): `p` tangent solves per LM
    step instead of one adjoint per sample. Compiled once per problem shape;
    `throw=False`: a failure is a result code."""
    return _lm_solve_unjitted(theta, args, rtol, atol, max_steps)


def _forward_model(model):
    """The contact model with its solves differentiated in forward mode (the options'
    `adjoint`, or the default one, with `mode="forward"`); other models as they are."""
    if not isinstance(model, SceneModel):
        return model
    options = dict(model.options)
    given = options.get("adjoint") or ImplicitAdjoint()
    options["adjoint"] = dataclasses.replace(given, mode="forward")
    return SceneModel(model.kind, tuple(sorted(options.items())))


def _cast(tree, dtype):
    return jax.tree.map(lambda x: x.astype(dtype), tree)


def _lm_solve_unjitted(theta, args, rtol, atol, max_steps):
    """LM's own arithmetic runs in the default float type (float64 under x64), the
    model in the fit's: optimistix's trust region keeps its step size in the default
    type, which would promote the damped operator of a float32 fit out of the
    structure of its float32 residual (lineax: "Vector and operator structures do not
    match"). A no-op for a fit in the default type."""
    import optimistix as optx

    ctx, refs, target, scale, model, fit_poisson = args
    args = (ctx, refs, target, scale, _forward_model(model), fit_poisson)
    dtype = jax.tree.leaves(theta)[0].dtype
    wide = jax.dtypes.canonicalize_dtype(jnp.float64)

    def residual(th, a):
        return relative_residual(_cast(th, dtype), a).astype(wide)

    sol = optx.least_squares(residual, optx.LevenbergMarquardt(rtol=rtol, atol=atol),
                             _cast(theta, wide), args, options={"jac": "fwd"},
                             max_steps=max_steps, throw=False)
    return (_cast(sol.value, dtype), sol.result == optx.RESULTS.successful,
            sol.stats["num_steps"])


@eqx.filter_jit
def lm_solve_batch(theta, args, axes, rtol, atol, max_steps):
    """`_lm_solve` over a batch of curves: `jax.vmap` of the whole Levenberg-Marquardt
    solve (one compiled program; the loop runs until its slowest member, the others
    held at their end point). `theta`: every leaf with a leading batch axis; `args`:
    `relative_residual`'s arguments, the leaves whose `axes` entry is 0 batched. Inputs
    sharded along the batch axis are computed where they lie (XLA's partitioner)."""
    return eqx.filter_vmap(
        lambda th, a: _lm_solve_unjitted(th, a, rtol, atol, max_steps),
        in_axes=(0, axes))(theta, args)


def drop_a_modulus(ev: Evaluator, theta, value: float):
    """`(theta, loss)` with the one modulus (`g_inf` or an arm's `g`, without
    `bounds=`) put beyond its floor (0 to the data, no gradient back) that gives the
    lowest loss not above `value`, the loss at `theta`; `None` where dropping any
    raises it. (The certificate's boundary probes revive a dropped arm that the data
    want back.)"""
    if not isinstance(theta, dict):  # not a fit's coordinates (a test's stand-in)
        return None
    bounded = ev.args[1].get("bounds", {})
    best = None
    for key in ("g_inf", "g"):
        if key not in theta or key in bounded:
            continue
        flat = np.ravel(np.asarray(theta[key]))  # trials built in NumPy
        for i in np.flatnonzero(flat > LOG_FLOOR):
            moved = flat.copy()
            moved[i] = LOG_FLOOR - 1
            trial = {**theta, key: jnp.asarray(moved.reshape(np.shape(theta[key])),
                                               dtype=theta[key].dtype)}
            v = float(ev.value(trial)[0])
            if np.isfinite(v) and v <= (value if best is None else best[1]):
                best = (trial, v)
    return best


class LMRun:
    """Levenberg-Marquardt runs of one fit: `run(theta)` -> `(theta, converged,
    message, 0, 0)` (the zeros: no Adam or L-BFGS steps), the end point's loss
    appended to `history`, the LM steps summed in `total`. `ready`: the result
    `(theta, converged, steps)` of this fit's first run, already solved (by
    `jc.fit_prony_batch`'s batched program), used in place of the first solve. A
    run of more than `LM_CHUNK` steps goes in compiled runs of `LM_CHUNK` (one
    program; `ready` is the first) and stops, not converged, after one that lowered
    the loss by less than `STALL_TOL` of itself."""

    def __init__(self, ev: Evaluator, max_steps: int, dtype, init, history: list,
                 ready=None):
        self.ev, self.max_steps, self.dtype = ev, max_steps, dtype
        self.init, self.history, self.ready = init, history, ready
        self.total = 0

    def _run(self, theta, steps):
        if self.ready is not None:
            ready, self.ready = self.ready, None
            return ready
        rtol = lm_rtol(self.dtype)
        return _lm_solve(theta, self.ev.args, rtol, 0.1 * rtol, steps)

    def _solve(self, theta, before):
        """`(theta, converged, steps, stalled)` of one LM run in compiled runs from
        `theta`, whose loss is `before`."""
        done = 0
        while True:
            chunk = run_steps(self.max_steps, done)
            theta, ok, steps = self._run(theta, chunk)
            done += int(steps)
            # converged, at the bound, or ended short of its steps for its own reason
            if bool(ok) or done >= self.max_steps or int(steps) < chunk:
                return theta, ok, done, False
            after = float(self.ev.value(theta)[0])
            dropped = drop_a_modulus(self.ev, theta, after)
            if dropped is not None:  # LM goes on without it
                theta, before = dropped
                continue
            if not before - after > STALL_TOL * before:
                return theta, ok, done, True
            before = after

    def __call__(self, theta, adam_steps=0):
        del adam_steps  # the signature of the Adam + L-BFGS run (`with_probes`)
        ev = self.ev
        start_loss = float(ev.value(theta)[0])
        if not np.isfinite(start_loss):
            raise ValueError(
                f"the model gives a non-finite loss at the start {self.init!r}")
        try:
            new, ok, steps, stalled = self._solve(theta, start_loss)
        except eqx.EquinoxRuntimeError as exc:  # a trial made an invalid material
            first_line = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
            return theta, False, ("Levenberg-Marquardt stopped: a trial step made an "
                                  f"invalid material ({first_line})"), 0, 0
        ev.calls += 1
        self.total += int(steps)
        value = float(ev.value(new)[0])
        if not np.isfinite(value):  # keep the start rather than a broken end point
            return theta, False, "Levenberg-Marquardt ended at a non-finite loss", 0, 0
        self.history.append(value)
        if stalled:
            how = (f"stalled after {int(steps)} steps (the last {LM_CHUNK} lowered "
                   f"the loss by less than {STALL_TOL:g} of itself)")
        else:
            # "met its tolerance", not "converged": the certificate decides that
            how = (f"{'met its tolerance' if bool(ok) else 'stopped'} after "
                   f"{int(steps)} steps")
        return new, bool(ok), f"Levenberg-Marquardt: {how}", 0, 0
