"""Adam, then L-BFGS (`FitOptions(optimiser="lbfgs")`, and `"auto"`'s first stage),
driven from Python: a few Adam steps (the best point is kept), then L-BFGS
(`optax.scale_by_lbfgs`, the direction of `optax.lbfgs`, memory 20) with an Armijo
backtracking line search, every evaluation one call of the compiled objective
(`Evaluator.loss`). Both run in coordinates whitened by the Gauss-Newton Hessian at
the start (`FitOptions.precondition`), rebuilt as the loss falls.
"""

import math

import jax
import jax.numpy as jnp
import numpy as np
import optax
from jax.flatten_util import ravel_pytree

from .model import Evaluator


_MAX_STEP = 1.0  # largest change of a log-parameter in one L-BFGS step

# Module-level compiled updates (the learning rate an argument): one compilation
# serves every fit of a parameter count, not one per fit.
_LBFGS = optax.scale_by_lbfgs(memory_size=20)
_lbfgs_update = jax.jit(_LBFGS.update)


@jax.jit
def _adam_update(grad, state, z, learning_rate):
    return optax.adam(learning_rate).update(grad, state, z)


class _Whitened:
    """The optimisers' coordinates `z`: `theta = theta_0 + M z`, `M = H^(-1/2)` for
    the Gauss-Newton Hessian `H = (2 / nt) J^T J` of the loss at `theta_0` (`J` by
    central differences, 2 p evaluations; `M = 1` without `precondition`). The loss
    is then about isotropic in `z`: L-BFGS does not crawl along the g-tau valleys of
    a Prony fit (at 32^2 x 24, noiseless PMMA: 43 L-BFGS steps without, a handful
    with)."""

    def __init__(self, ev: Evaluator, theta, precondition: bool, fd_step: float):
        self.ev, self.precondition, self.fd_step = ev, precondition, fd_step
        self.flat0, self.unravel = ravel_pytree(theta)
        self.precond = self._whitening(theta)

    def _whitening(self, theta):
        flat0 = self.flat0
        if self.precondition:
            jac = self.ev.jacobian(theta, self.fd_step)
            if np.all(np.isfinite(jac)):
                lam, vec = np.linalg.eigh(2 / jac.shape[0] * jac.T @ jac)
                lam = np.maximum(lam, max(1e-10 * float(lam.max()), 1e-300))
                return jnp.asarray((vec / np.sqrt(lam)) @ vec.T, flat0.dtype)
        return jnp.eye(flat0.shape[0], dtype=flat0.dtype)

    def theta(self, z):
        return self.unravel(self.flat0 + self.precond @ z)

    def z_grad(self, grad):
        return self.precond @ ravel_pytree(grad)[0]  # M is symmetric

    def rebuild(self, z):
        """Move `theta_0` to `z` and build `M` there (then `z = 0` is that point)."""
        self.flat0 = self.flat0 + self.precond @ z
        self.precond = self._whitening(self.unravel(self.flat0))


def _adam(ev: Evaluator, w: _Whitened, theta, steps, learning_rate, history, init):
    """`steps` Adam steps from `theta` (`z = 0`): `(loss, z, gradient, steps taken)`
    of the best point; appends the losses to `history`."""
    z = jnp.zeros_like(w.flat0)
    value, grad, _, _ = ev.loss(theta)
    if not np.isfinite(float(value)):
        raise ValueError(
            f"the model gives a non-finite loss at the initial guess {init!r}")
    value = float(value)
    history.append(value)
    if learning_rate is None:
        # Whitened: loss ~ loss_min + |z - z*|^2 / 2, so the optimum is within
        # sqrt(2 loss_0) of the start; Adam moves each z by ~lr per step.
        lr = 0.1 * math.sqrt(2 * value) if w.precondition else 0.02
    else:
        lr = learning_rate
    state = optax.adam(lr).init(z)
    lr = jnp.asarray(lr, z.dtype)
    best = (value, z, grad)
    taken = 0
    for _ in range(steps):
        updates, state = _adam_update(w.z_grad(grad), state, z, lr)
        trial = z + updates
        value_t, grad_t, _, _ = ev.loss(w.theta(trial))
        if not np.isfinite(float(value_t)):
            break  # keep the best finite point; L-BFGS takes over from there
        z, value, grad = trial, float(value_t), grad_t
        taken += 1
        history.append(value)
        if value < best[0]:
            best = (value, z, grad)
    value, z, grad = best
    return value, z, grad, taken


def _line_search(ev: Evaluator, w: _Whitened, z, direction, value, slope, alpha):
    """Armijo backtracking along `-direction` from step `alpha`, halved at most 30
    times: `(z, loss, gradient, alpha)` of the first accepted step, or `None`."""
    for _ in range(30):
        trial = z - alpha * direction
        value_t, grad_t, _, _ = ev.loss(w.theta(trial))
        if (np.isfinite(float(value_t))
                and float(value_t) <= value - 1e-4 * alpha * slope):
            return trial, float(value_t), grad_t, alpha
        alpha *= 0.5
    return None


def _lbfgs(ev: Evaluator, w: _Whitened, z, value, grad, steps, gtol, history):
    """At most `steps` L-BFGS iterations from `z`: `(z, converged, message, steps
    taken)`; appends the losses to `history`. Far from the optimum `H` changes: when
    L-BFGS has cut the loss 100-fold since `M` was built, `M` is rebuilt there and
    L-BFGS restarts (at most 4 times)."""
    lbfgs, lbfgs_update = _LBFGS, _lbfgs_update
    state = lbfgs.init(z)
    g_theta = ravel_pytree(grad)[0]
    converged, message = (
        False, f"stopped at the iteration bound lbfgs_steps={steps}")
    taken, refreshes, value_at_precond = 0, 0, value
    for _ in range(steps):
        if w.precondition and refreshes < 4 and value < 1e-2 * value_at_precond:
            w.rebuild(z)
            state = lbfgs.init(z)
            z = jnp.zeros_like(z)
            refreshes, value_at_precond = refreshes + 1, value
        if float(jnp.max(jnp.abs(g_theta))) <= gtol:
            converged, message = True, f"gradient below gtol={gtol:g}"
            break
        g_z = w.precond @ g_theta
        direction, state = lbfgs_update(g_z, state, z)
        slope = float(jnp.vdot(g_z, direction))
        if not slope > 0:  # not a descent direction: restart from steepest descent
            state = lbfgs.init(z)
            direction, slope = g_z, float(jnp.vdot(g_z, g_z))
        # At most a factor e^MAX_STEP per parameter per iteration: a first L-BFGS
        # step can be long, and exp() would overflow.
        longest = float(jnp.max(jnp.abs(w.precond @ direction)))
        found = _line_search(ev, w, z, direction, value, slope,
                             min(1.0, _MAX_STEP / max(longest, 1e-300)))
        if found is None:
            message = "the line search cannot decrease the loss further"
            break
        z, value, grad_t, alpha = found
        g_theta = ravel_pytree(grad_t)[0]
        taken += 1
        history.append(value)
        if alpha * longest < 1e-12:
            converged, message = True, "step below 1e-12 (log-parameters)"
            break
    else:
        if steps and float(jnp.max(jnp.abs(g_theta))) <= gtol:
            converged, message = True, f"gradient below gtol={gtol:g}"
    return z, converged, message, taken


def adam_lbfgs(ev: Evaluator, theta, adam_steps, *, options, gtol, fd_step,
               history, init):
    """Adam, then L-BFGS, from `theta`: `(theta, converged, message, Adam steps,
    L-BFGS steps)`; appends the losses to `history`. `options`: the
    `jc.FitOptions` (`learning_rate`, `lbfgs_steps`, `precondition`)."""
    w = _Whitened(ev, theta, options.precondition, fd_step)
    value, z, grad, steps_adam = _adam(ev, w, theta, adam_steps,
                                       options.learning_rate, history, init)
    z, converged, message, steps_lbfgs = _lbfgs(ev, w, z, value, grad,
                                                options.lbfgs_steps, gtol, history)
    return w.theta(z), converged, message, steps_adam, steps_lbfgs
