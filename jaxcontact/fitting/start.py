"""Where a fit starts (unless `init=` is a `jc.Prony`).

From the data (`initial_guess`): one elastic run of the model turns every sample
into an apparent modulus, and a cheap least-squares Prony fit (optax L-BFGS, no
contact model: `_prefit`) of `G(t)` (or `1/J(t)` under load control) to those moduli
gives the series. Or (`init="lee-radok"`, `lee_radok_start`) from the closed-form
Lee & Radok model of the data's loading and hold.
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import optax

from .._loading import Displacement
from .._material.prony import Prony, retardation_series
from .._probe import Probe
from .._scene import Scene
from .data import IndentationData
from .model import Evaluator
from .parametrisation import to_theta


def initial_times(times: np.ndarray, n: int) -> np.ndarray:
    """`n` log-spaced times strictly inside [first step, span] of the data."""
    span = float(times[-1] - times[0])
    first = float(times[1] - times[0])
    return np.geomspace(first, span, n + 2)[1:-1]


_PREFIT_CLIP = 30.0  # |log(value / reference)| the prefit can reach


@functools.partial(jax.jit, static_argnums=0)
def _prefit_loss(kind, theta, lag, apparent, weight, g_ref, t_ref):
    # Clipped exponents and no constructor checks: the line search may probe wild
    # points, which must come back as large losses, not errors. `weight`: 1 on the
    # samples used, 0 on the padding (one compiled prefit for every curve of a
    # length, whatever number of samples it uses).
    clip = _PREFIT_CLIP
    g_inf, g, tau = (c * jnp.exp(jnp.clip(theta[k], -clip, clip)) for c, k in (
        (g_ref, "g_inf"), (g_ref, "g"), (t_ref, "tau")))
    if kind == "force":  # a held indentation: G_app(t) = G(t - t_0)
        relaxation = g_inf + jnp.sum(g[None, :] * jnp.exp(-lag[:, None] / tau[None, :]),
                                     axis=1)
        return jnp.sum(weight * (relaxation / apparent - 1) ** 2) / jnp.sum(weight)
    creep = retardation_series(g_inf, g, tau)(lag)  # held load: G_app = 1 / J
    return jnp.sum(weight * (creep * apparent - 1) ** 2) / jnp.sum(weight)


_PREFIT_OPT = optax.lbfgs()


@functools.partial(jax.jit, static_argnums=(0, 1))
def _prefit_run(kind, steps, theta, *args):
    """`steps` L-BFGS steps from `theta` in one compiled loop, stopped before the
    first step that leaves a non-finite parameter (`theta` is then the last finite
    one)."""
    def fn(th):
        return _prefit_loss(kind, th, *args)

    def keep_going(carry):
        i, _, _, stopped = carry
        return (i < steps) & ~stopped

    def step(carry):
        i, theta, state, _ = carry
        value, grad = optax.value_and_grad_from_state(fn)(theta, state=state)
        updates, state = _PREFIT_OPT.update(grad, state, theta, value=value,
                                            grad=grad, value_fn=fn)
        new = optax.apply_updates(theta, updates)
        finite = jnp.all(jnp.stack([jnp.all(jnp.isfinite(x))
                                    for x in jax.tree.leaves(new)]))
        theta = jax.tree.map(lambda a, b: jnp.where(finite, a, b), new, theta)
        return i + 1, theta, state, ~finite

    carry = (jnp.asarray(0), theta, _PREFIT_OPT.init(theta), jnp.asarray(False))
    return jax.lax.while_loop(keep_going, step, carry)[1]


def _prefit(kind, lag, apparent, g_inf, arms, t_init, g_ref, t_ref, steps=200,
            length=None):
    """Least-squares Prony fit of `G(lag)` (or `1 / J(lag)` under load control) to
    the apparent moduli: a cheap curve fit, no contact model; optax L-BFGS with its
    zoom line search, bounded. `length`: the samples padded to it (weight 0)."""
    theta = {"g_inf": jnp.log(jnp.asarray(g_inf / g_ref)),
             "g": jnp.log(jnp.full(t_init.shape, arms / t_init.shape[0]) / g_ref),
             "tau": jnp.log(jnp.asarray(t_init) / t_ref)}
    pad = max(0, (length or 0) - lag.shape[0])
    weight = np.r_[np.ones(lag.shape[0]), np.zeros(pad)]
    args = (jnp.asarray(np.r_[lag, np.zeros(pad)]),
            jnp.asarray(np.r_[apparent, np.ones(pad)]), jnp.asarray(weight),
            g_ref, t_ref)
    start = float(_prefit_loss(kind, theta, *args))
    theta = _prefit_run(kind, steps, theta, *args)
    if not float(_prefit_loss(kind, theta, *args)) < start:
        return None
    # The values the loss saw: beyond the clip its gradient is zero and a line search
    # can leave a log far out (-800 on an H200: tau = 0, and the start crashed).
    theta = {k: np.clip(np.asarray(v), -_PREFIT_CLIP, _PREFIT_CLIP)
             for k, v in theta.items()}
    tau = t_ref * np.exp(theta["tau"])
    if np.any(np.diff(np.sort(tau)) <= 1e-6 * tau.max()):
        return None  # merged times: keep the plain heuristic
    return g_ref * float(np.exp(theta["g_inf"])), g_ref * np.exp(theta["g"]), tau


def _apparent_moduli(ev: Evaluator, refs, fit_poisson, kind, target, n, t_init,
                     dtype, poisson, driver, exponent):
    """`(G_app, use, g_trial)`: the apparent elastic moduli of the samples `use` (see
    `initial_guess`; `None, None` where none) and the last trial modulus."""
    loading = np.ones(np.shape(target), bool)
    if driver is not None:
        d = np.asarray(driver, float)
        loading = d >= 0.98 * np.maximum.accumulate(d)
    g_trial = float(refs["g_ref"])
    tgt = np.asarray(target)
    apparent, use = None, None
    for _ in range(1 if kind == "force" else 2):
        trial = Prony(g_trial, np.full(n, 1e-9 * g_trial), t_init, poisson)
        _, curve, _ = ev.value(to_theta(trial, refs, fit_poisson, dtype))
        curve = np.asarray(curve, dtype=float)
        if kind == "force":
            ok = (np.abs(curve) > 0.05 * np.max(np.abs(curve))) & (tgt > 0) & loading
            ratio = tgt[ok] / curve[ok]
        else:
            ok = (tgt > 0.05 * np.max(tgt)) & (curve > 0) & loading
            ratio = (curve[ok] / tgt[ok]) ** exponent
        if not ok.any() or not np.all(np.isfinite(ratio)):
            break
        apparent, use = g_trial * ratio, ok
        g_trial = float(np.median(apparent))
    return apparent, use, g_trial


def load_exponent(indenter) -> float:
    """The power `m` of `F ~ d^m` that `initial_guess` assumes for `indenter`: 2 for a
    self-similar tip (`jc.Cone`, `jc.Pyramid`), 3/2 (Hertz) for any other (exact for
    a `jc.Sphere`; a heuristic elsewhere, refined by the fit)."""
    from .._indenter import Cone, Pyramid

    return 2.0 if isinstance(indenter, (Cone, Pyramid)) else 1.5


def initial_guess(ev: Evaluator, refs, fit_poisson, kind, times, target, n, t_init,
                  dtype, poisson, driver=None, exponent=1.5):
    """A starting Prony series from apparent elastic moduli along the curve.

    One (or, under load control, two) evaluations of the model with an effectively
    elastic series (arms 1e-9 of the modulus) at a trial modulus `G`: under
    displacement control the force is proportional to `G`, under load control the
    depth goes as `G^(-1/m)` (`exponent` `m` of `F ~ d^m`: 3/2, Hertz, by default;
    2 for a cone); this turns each sample into an apparent modulus
    `G_app(t_k)`. Then `g_inf = min G_app`, `sum(g) = max G_app - g_inf` spread evenly
    over the arms at `t_init`, refined by a least-squares Prony fit of `G(t - t_0)` to
    `G_app(t)` (`t_0`: the first loaded sample). For a held indentation `G_app` is
    `G(t - t_0)` itself (Lee & Radok); for other programs a blurred version: a
    heuristic, refined by the real fit. Pass `init=` to override.

    Only samples where the imposed input (`driver`: the depth under displacement
    control, the force under load control) is within 2 % of its running maximum
    enter: on unloading the apparent elastic modulus means nothing (it falls towards
    0 as the viscoelastic force drops faster than the elastic one, and a start with
    `g_inf ~ 0` is a trap of the log-parametrisation: on a ramp-hold-unload curve it
    led to `g_inf = 2e-10 Pa`).
    """
    apparent, use, g_trial = _apparent_moduli(ev, refs, fit_poisson, kind, target, n,
                                              t_init, dtype, poisson, driver,
                                              exponent)
    if apparent is None:
        return Prony(g_trial, np.full(n, 0.1 * g_trial / n), t_init, poisson)
    g0, g_inf = float(np.max(apparent)), float(np.min(apparent))
    arms = max(g0 - g_inf, 0.05 * g0)
    refined = None
    if apparent.shape[0] > 1 + 2 * n:
        lag = times[use] - times[np.argmax(use)]
        refined = _prefit(kind, lag, apparent, g_inf, arms, t_init, g0,
                          float(times[-1] - times[0]), length=times.shape[0])
    if refined is None:
        return Prony(g_inf, np.full(n, arms / n), t_init, poisson)
    return Prony(*refined, poisson)


def lee_radok_start(data: IndentationData, scene_template: Scene, n_terms: int, *,
                    poisson: float, weights=None) -> Prony:
    """A Prony series of `n_terms` arms from the closed-form Lee & Radok model of the
    data (`jc.fit_prony(init="lee-radok")`).

    The samples up to the first where the depth falls below 98 % of its running
    maximum (the loading and the hold: the contact radius does not shrink, and the
    full contact model is the closed form there, up to its grid) are fitted by
    `jaxcontact._lee_radok.lee_radok_fit` (times on a log grid of 20 over the span,
    coefficients > 0, the fit's `weights`; `u = depth^m`, `m` 3/2 for a
    `jc.Sphere`, 2 for a `jc.Cone`); the apparent moduli (compliances) are
    converted with the probe's prefactor `C` of `F = C G d^m` at `poisson`
    (`8 sqrt(R) / (3 (1 - nu))`, `4 tan(alpha) / (pi (1 - nu))`):
    `G = G_app / C` (relaxation, displacement control), `J = C J_app` (creep,
    load control; then `jc.Prony.from_creep`).

    **Raises:** `ValueError` without a `jc.Sphere` or `jc.Cone` indenter, without
    both force and depth in `data`, or where no set of times gives positive
    coefficients.
    """
    from .._indenter import Cone, Sphere
    from .._lee_radok import lee_radok_fit

    if not isinstance(scene_template.indenter, (Sphere, Cone)):
        raise ValueError(f"init='lee-radok' needs a jc.Sphere or jc.Cone indenter, got "
                         f"{type(scene_template.indenter).__name__}")
    probe = Probe.of(scene_template.indenter)
    if data.force is None or data.depth is None:
        raise ValueError("init='lee-radok' needs both data.force and data.depth")
    depth = np.asarray(data.depth, float)
    below = depth < 0.98 * np.maximum.accumulate(depth)
    end = int(np.argmax(below)) if below.any() else depth.size
    if end < 2 * n_terms + 3:
        raise ValueError(f"init='lee-radok': {end} loading samples are too few for "
                         f"{n_terms} arms")
    mode = "relaxation" if isinstance(scene_template.normal, Displacement) else "creep"
    w = None if weights is None else np.asarray(weights, float)[:end]
    _, taus, c = lee_radok_fit(data.times[:end], np.asarray(data.force)[:end],
                               depth[:end], mode, arms=n_terms, weights=w,
                               positive=True, exponent=probe.exponent)
    if c is None:
        raise ValueError("init='lee-radok': no closed-form series with positive moduli "
                         "fits the data")
    factor = probe.prefactor(poisson)
    if mode == "relaxation":
        return Prony(c[0] / factor, c[1:] / factor, taus, poisson)
    return Prony.from_creep(c.sum() * factor, c[1:] * factor, taus, poisson)
