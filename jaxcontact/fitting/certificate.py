"""Is the fit a minimum, and how well do the data determine it?

Boundary probes: positivity by exp() has a trap: a modulus driven towards 0 (or a
relaxation time far outside the data's times) has a vanishing gradient in its log
and never comes back, and the optimiser stops there. (Ramp-hold-unload, 1 % noise,
16^2: the default start went to g_inf = 2e-10 Pa, loss 0.098 against 3e-4 at the
truth.) So every parameter sitting at such a boundary is moved back inside
(`_boundary_probe`), and if that lowers the loss the optimiser restarts there
(`with_probes`, at most `_MAX_RESTARTS` times).

The certificate (`PronyFit.converged`): the Gauss-Newton step at the result promises
less than a `GN_TOL` relative decrease of the loss (or a negligible absolute one),
no parameter at a boundary can lower it, none is left at one, and every contact
solve converged.

Sensitivities (`PronyFit.std`, `PronyFit.covariance`; `PronyFit.gradient` is
`d(loss)/d(log param)` at the result: 0 at an exact minimum, a check of convergence,
not an uncertainty): the Gauss-Newton (linearised least-squares) covariance of the
LOG-parameters, `Cov = sigma^2 (J^T J)^-1`, `J = d(residual / rms)/d(log param)` at
the optimum (central differences of the model, step 1e-3 in float64 and 3e-2 in
float32: `2 p` evaluations instead of one adjoint per sample), with `sigma` the noise
level (given as `noise_std`, or estimated from the residual as `sqrt(SSR / (n - p))`).
`std`, the root of its diagonal, is about the relative standard deviation of each
parameter. A direction the data do not determine gets `inf`.
"""

import math

import jax.numpy as jnp
import numpy as np

from .model import Evaluator
from .parametrisation import limits, to_material


GN_TOL = 1e-3  # largest relative loss decrease a Gauss-Newton step may promise
_MAX_RESTARTS = 3  # restarts from boundary probes


def decrease_floor(dtype) -> float:
    """The absolute floor of the predicted loss decrease: at an exact fit (noiseless
    data) the residual is round-off and its relative decrease means nothing."""
    return 1e-18 if jnp.finfo(dtype).bits >= 64 else 1e-10


def predicted_decrease(jac, r):
    """Relative loss decrease `(|r|^2 - |r + J d|^2) / |r|^2` of the Gauss-Newton
    step `d` (least squares, cut-off 1e-10); `inf` where `J` is not finite."""
    if not np.all(np.isfinite(jac)) or not np.all(np.isfinite(r)):
        return float("inf")
    rr = float(np.sum(r**2))
    if rr == 0:
        return 0.0
    d = np.linalg.lstsq(jac, -r, rcond=1e-10)[0]
    return max(rr - float(np.sum((r + jac @ d) ** 2)), 0.0) / rr


# --------------------------------------------------------------------------------------
# Boundary probes.


def _scales(material, times):
    """`(g_inf, g, tau, first, span, live)`: the material's parameters as float
    arrays, the data's first time step and span, and the arms the data can see
    (`live`: a relaxation time within [1e-2 first step, 1e2 span])."""
    g_inf, g, tau = (np.asarray(x, float) for x in (material.g_inf, material.g,
                                                    material.tau))
    span, first = float(times[-1] - times[0]), float(np.min(np.diff(times)))
    live = (tau >= 1e-2 * first) & (tau <= 1e2 * span)
    return g_inf, g, tau, first, span, live


class _Coordinates:
    """Moves of a parameter set `theta` (every parameter, fixed ones included; NumPy
    arrays) in scaled logs, returned in the optimiser's coordinates (the scaled logs;
    a bounded parameter kept 5 % of its range inside its bounds)."""

    def __init__(self, theta, refs):
        self.theta, self.refs = theta, refs
        self.bounded = set(refs.get("bounds", {}))

    def from_x(self, key, x):  # a scaled log -> the optimiser's coordinate of `key`
        if key in self.bounded:
            lo, hi = (float(b) for b in self.refs["bounds"][key])
            return np.clip(x, lo + 0.05 * (hi - lo), hi - 0.05 * (hi - lo))
        return x

    def log(self, key):  # `log_scaled` in NumPy
        lim = limits(self.refs, key)
        x = self.theta[key]
        return x if lim is None else np.clip(x, float(lim[0]), float(lim[1]))

    def shifted(self, key, delta):
        return self.from_x(key, self.log(key) + delta)

    def set_at(self, key, i, x):
        return self.from_x(key, _set(self.log(key), i, x))


def _set(array, i, x):
    """A copy of the NumPy `array` with element `i` set to `x`."""
    out = np.array(array)
    out[i] = x
    return out


def _modulus_trials(c: _Coordinates, g_inf, g, tau, first, span, g0, g_ref, mid):
    """Trials that move a modulus at ~0 (or revive a dead arm) back inside."""
    theta, trials = c.theta, []
    for frac in (1e-2, 1e-1, 0.5):
        # the modulus to `frac` of g0, the others scaled to keep g0 (the instantaneous
        # modulus, which the data fix best: the trap sits in a valley along it); 0.5
        # for a dead arm that must carry a real share to beat what it mimics (a dead
        # arm with a huge modulus makes J(0) ~ 0: a one-step lag)
        inside = math.log(frac * g0 / g_ref)
        shrink = math.log(1 - frac)
        if g_inf < 1e-4 * g0:
            trials.append({**theta, "g_inf": c.from_x("g_inf", np.full_like(
                theta["g_inf"], inside)), "g": c.shifted("g", shrink)})
        for i in range(g.shape[0]):
            tau_out = tau[i] < 1e-2 * first or tau[i] > 1e2 * span
            if g[i] < 1e-4 * g0 or tau_out:
                # a dead arm (no modulus, or a time the data cannot see): revived
                # whole, its time at the middle of the data's time scales
                g_new = c.from_x("g", _set(c.log("g") + shrink, i, inside))
                trials.append({**theta, "g_inf": c.shifted("g_inf", shrink),
                               "g": g_new, "tau": c.set_at("tau", i, mid)})
            if g[i] < 1e-4 * g0 and not tau_out:
                g_new = c.from_x("g", _set(c.log("g") + shrink, i, inside))
                trials.append({**theta, "g_inf": c.shifted("g_inf", shrink),
                               "g": g_new})
    return trials


def _probe_trials(theta, free, refs, material, times):
    """The trial points of `_boundary_probe`, in the optimiser's coordinates of the
    `free` parameters, each different from `free`."""
    g_inf, g, tau, first, span, live = _scales(material, times)
    # g0 of the arms the data can see: a dead arm (tau far outside the data's times)
    # may carry any modulus (2.8e18 Pa at tau = 3e-18 s on the creep file, 1 arm)
    g0 = float(g_inf + g[live].sum()) if float(g_inf + g[live].sum()) > 0 else float(
        g_inf + g.sum())
    g_ref, t_ref = float(refs["g_ref"]), float(refs["t_ref"])
    theta = {k: np.asarray(v) for k, v in theta.items()}  # trials built in NumPy
    trials = []
    mid = math.log(math.sqrt(first * span) / t_ref)
    for i in range(g.shape[0]):
        if (tau[i] < 1e-2 * first or tau[i] > 1e2 * span) and "tau" not in refs.get(
                "bounds", {}):
            trials.append({**theta, "tau": _set(theta["tau"], i, mid)})
    c = _Coordinates(theta, refs)
    trials += _modulus_trials(c, g_inf, g, tau, first, span, g0, g_ref, mid)
    # a bounded parameter pressed against a bound (within 1 % of the range; beyond
    # it the coordinate has no gradient back) is tried at the middle of its range
    for key in c.bounded & set(free):
        lo, hi = (float(b) for b in refs["bounds"][key])
        frac = (theta[key].reshape(-1) - lo) / (hi - lo)
        for i in np.flatnonzero((frac < 0.01) | (frac > 0.99)):
            moved = _set(theta[key].reshape(-1), i, 0.5 * (lo + hi))
            trials.append({**theta, key: moved.reshape(theta[key].shape)})
    current = {k: np.asarray(v) for k, v in free.items()}
    return [{k: jnp.asarray(t[k], dtype=free[k].dtype) for k in free} for t in trials
            if any(not np.array_equal(t[k], current[k]) for k in free)]


def _boundary_probe(ev: Evaluator, theta, refs, fit_poisson, times):
    """`theta` with the parameters that sit at a boundary of the log-parametrisation
    moved back inside, if that lowers the loss by more than 0.1 %; else `None`.
    Boundaries: a modulus below 1e-4 of the instantaneous modulus `g_inf + sum g`;
    a relaxation time below 1e-2 of the first time step or above 1e2 of the span.
    Each is tried alone, and a dead arm (modulus ~ 0 or time out of range) also
    revived whole; a parameter with bounds pressed against one is tried at the middle
    of its range (one evaluation each); the best is returned."""
    value = float(ev.value(theta)[0])
    material = to_material(theta, refs, fit_poisson)
    full = {**refs.get("fixed", {}), **theta}  # trials on all, kept: the free ones
    best, best_value = None, value * (1 - 1e-3)
    for trial in _probe_trials(full, theta, refs, material, times):
        v = float(ev.value(trial)[0])
        if np.isfinite(v) and v < best_value:
            best, best_value = trial, v
    return best


def at_boundary(material, times, refs):
    """Names of the parameters at a boundary of the log-parametrisation (see
    `_boundary_probe`): a modulus below 1e-4 of the live arms' g0, an (unbounded)
    relaxation time below 1e-2 of the first step or above 1e2 of the span."""
    g_inf, g, tau, _, _, live = _scales(material, times)
    g0 = float(g_inf + g[live].sum()) or float(g_inf + g.sum())
    out = ["g_inf"] if g_inf < 1e-4 * g0 else []
    for i in range(g.shape[0]):
        if g[i] < 1e-4 * g0:
            out.append(f"g_{i + 1} (tau {tau[i]:.3g})")
        if not live[i] and "tau" not in refs.get("bounds", {}):
            out.append(f"tau_{i + 1} = {tau[i]:.3g}")
    return out


def with_probes(run, theta, adam_steps, *, ev, refs, fit_poisson, times):
    """`run(theta, adam_steps)` (an optimiser: `(theta, converged, message, Adam
    steps, L-BFGS steps)`), restarted from `_boundary_probe`'s point while it finds
    one (at most `_MAX_RESTARTS` times, without Adam): `(theta, message, probe, Adam
    steps, L-BFGS steps)`, `probe` the last probe's point (`None`: none lowers the
    loss)."""
    theta, _, message, n_adam, n_lbfgs = run(theta, adam_steps)
    restarts = 0
    while True:
        probe = _boundary_probe(ev, theta, refs, fit_poisson, times)
        if probe is None or restarts >= _MAX_RESTARTS:
            break
        theta, _, message, a_more, l_more = run(probe, 0)
        n_adam, n_lbfgs, restarts = n_adam + a_more, n_lbfgs + l_more, restarts + 1
    if restarts:
        message += (f" (after {restarts} restart(s) from a parameter at its "
                    "boundary)")
    if probe is not None:
        message += ("; a parameter at a boundary of the parametrisation (a "
                    "modulus ~ 0 or a time far outside the data's) can still lower "
                    "the loss")
    return theta, message, probe, n_adam, n_lbfgs


# --------------------------------------------------------------------------------------
# Sensitivities and the certificate.


def log_covariance(rows, sigma_rel):
    """`(std, cov)` of the log-parameters from the Jacobian `rows` in the optimiser's
    coordinates (the logs); `None` where the Jacobian is not finite."""
    if not np.all(np.isfinite(rows)):
        return None
    eigval, eigvec = np.linalg.eigh(rows.T @ rows)
    keep = eigval > 1e-14 * max(float(eigval.max()), 1e-300)
    inv = np.where(keep, 1 / np.where(keep, eigval, 1), 0.0)
    var = np.sum(eigvec**2 * inv[None, :], axis=1)
    # a parameter with a component along an undetermined direction: inf
    var = np.where(np.any((eigvec**2 > 0) & ~keep[None, :], axis=1), np.inf, var)
    std = np.where(np.isinf(var), np.inf, np.sqrt(var) * sigma_rel)
    cov = sigma_rel**2 * (eigvec * inv[None, :]) @ eigvec.T
    cov = np.where(np.isinf(var)[:, None] | np.isinf(var)[None, :], np.inf, cov)
    return std, cov


def certify(rows, rel, value, ok, probe, stuck, dtype):
    """`(converged, note)`: the certificate of a fit with Jacobian `rows`, relative
    residual `rel`, loss `value`, contact solves' flags `ok`, the last boundary probe
    `probe` and the (not fixed) parameters `stuck` at a boundary; `note` is appended
    to the fit's message."""
    # Converged means the Gauss-Newton model at the result predicts no decrease of the
    # loss worth having (relative decrease < `GN_TOL`), and no parameter at a boundary
    # could lower it (the probes); whichever test of the optimiser stopped it. A fit
    # stopped away from the minimum says so. At an exact fit (noiseless data) the
    # residual is round-off and its relative decrease means nothing: an absolute floor
    # on the predicted decrease of the loss (mean squared relative residual) covers it.
    predicted = predicted_decrease(rows, rel)
    floor = decrease_floor(dtype)
    small = predicted < GN_TOL or predicted * float(value) < floor
    note = ""
    # A parameter left at a boundary is not an interior minimum the certificate can
    # see (its log's column is ~0): NOT converged, and said why.
    if stuck:
        note += (f"; at a boundary of the parametrisation: {', '.join(stuck)} (the "
                 "data do not determine it: fewer arms, fixed= or bounds=)")
    converged = (bool(small) and bool(np.all(np.asarray(ok))) and probe is None
                 and not stuck)
    verdict = "converged" if converged else "NOT converged"
    note += (f"; Gauss-Newton predicts a further {predicted:.2g} relative decrease "
             f"of the loss {float(value):.3g} ({verdict}: the bound is {GN_TOL:g}, "
             f"or {floor:g} absolute)")
    return converged, note
