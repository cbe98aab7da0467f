"""`jc.fit_prony`: fit a Prony series to indentation data by running the full contact
model (`jc.solve`) and differentiating through it.

The driver: the problem's checks and set-up (`set_up`: the scene on the data's
times, the parametrisation's references, the start), the optimiser run
(`_optimise`: L-BFGS, Levenberg-Marquardt, or `"auto"`: L-BFGS, then LM where its
result is not certified; each restarted from boundary probes), then the certificate,
the sensitivities and the `jc.PronyFit` (`_finish`). The jobs themselves live in the
sibling modules (see `jaxcontact.fitting`).
"""

import dataclasses
import math
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree

from .._indenter import Sphere
from .._material.prony import Prony
from .._scene import Scene
from .._solve import warn_unstable_steps
from .._validate import check_int
from .certificate import (
    GN_TOL,
    at_boundary,
    certify,
    decrease_floor,
    log_covariance,
    predicted_decrease,
    with_probes,
)
from .data import IndentationData, check_series, scene_for
from .discretisation import discretisation_rms
from .lbfgs import adam_lbfgs
from .lm import LMRun, have_optimistix
from .model import Evaluator, scene_model
from .options import FitOptions, with_legacy
from .parametrisation import (
    check_bounds,
    check_fixed,
    inside,
    make_refs,
    pinned,
    project,
    to_material,
    to_theta,
)
from .result import (
    PronyFit,
    parameter_names,
    sorted_by_tau,
    sorted_covariance,
    sorted_split,
)
from .rings_model import choose_solver, ring_model
from .start import initial_guess, initial_times, lee_radok_start, load_exponent


def fit_prony(
    data: IndentationData,
    scene_template: Scene,
    n_terms: int,
    *,
    init: Prony | str | None = None,
    poisson=None,
    fit_poisson: bool = False,
    fixed: dict | None = None,
    bounds: dict | None = None,
    weights=None,
    noise_std: float | None = None,
    options: FitOptions = FitOptions(),
    _model=None,
    **legacy,
) -> PronyFit:
    """Fit a Prony series `G(t) = g_inf + sum_i g_i exp(-t / tau_i)` to indentation
    data, through the full contact model.

    **Main arguments:**

    - `data`: a `jc.IndentationData` (times, and force and/or depth).
    - `scene_template`: a `jc.Scene` giving the grid, the indenter, the control mode
      and (unless the data give it) the loading program; its `times` are replaced by
      `data.times` and its material by the fitted one.
        - displacement control (`normal=jc.Displacement(...)`): the FORCE is fitted
          (`data.force` required); the approach is `data.depth` if given, else the
          template's program evaluated at `data.times` (a callable or a scalar).
        - load control (`normal=jc.Force(...)`): the DEPTH (approach) is fitted
          (`data.depth` required); the load is `data.force` if given, else the
          template's program. Giving both force and depth fits a load-depth loop.
      Tangential inputs, friction and coupling of the template are kept.
    - `n_terms`: number of Maxwell arms `n >= 1`.

    **Other arguments:**

    - `init`: the starting `jc.Prony` (`n_terms` arms). Default: from the data
      (apparent elastic moduli, then a cheap Prony fit to them, starting from
      relaxation times log-spaced strictly inside [first time step, time span]).
      `"lee-radok"`: the best closed-form Lee & Radok model of the
      data's loading and hold (a `jc.Sphere` or a `jc.Cone`, both `data.force` and
      `data.depth`; the model the contact solve reproduces while the contact grows or
      holds, so the start is at the full model's optimum up to the grid's bias and
      the unloading). On the creep file at 32^2 with 2 arms, LM from it converged in
      43 steps where from the default start it stopped at its 100-step bound.
    - `poisson`: Poisson's ratio (fixed unless `fit_poisson`); default: that of the
      template's material. Under normal indentation alone only `G / (1 - nu)` is
      identifiable: fitting it needs tangential data (`fit_poisson=True`
      parametrises it in (0, 0.5)).
    - `fixed`: parameters held at given values, not fitted: a dict with any of
      `"g_inf"` (a number > 0 [Pa]), `"g"` and `"tau"` (`n_terms` values > 0, [Pa]
      and [s]); e.g. `fixed={"tau": [0.1, 10.0]}` fits the moduli of given times.
      Their `std` is 0. (A modulus cannot be fixed at 0: the series is positive by
      construction; fit fewer arms instead.) Poisson's ratio is fixed unless
      `fit_poisson`.
    - `bounds`: `{"g_inf" | "g" | "tau": (lo, hi)}`, `0 < lo < hi < inf` [Pa or s]:
      the parameter (every arm for `g`, `tau`) is kept in `[lo, hi]` (its log
      clipped there: beyond a bound the value is the bound, its derivative 0). E.g.
      `bounds={"tau": (dt, 10 * span)}` keeps relaxation times where the data can see
      them (a time far beyond the data is degenerate with `g_inf`). A parameter at a
      bound is a constrained minimum (`converged` can be `True` there); its `std` is
      that of the linearised, unconstrained problem.
    - `weights`: `(nt,)` positive weights of the samples (e.g. `sqrt(count)` for bin
      means of `count` raw samples: the inverse of each sample's noise); normalised to
      a mean square of 1. Default: equal. The loss is then
      `mean((w (curve - target) / rms(target))^2)`, `noise` (and `noise_std`) is the
      noise of a sample of weight 1.
    - `noise_std`: the data's noise standard deviation [data units] for `std`;
      default: estimated from the residual.
    - `options`: a `jc.FitOptions`: the optimiser (`"auto"`, `"lm"`, `"lbfgs"`), its
      step bounds and tolerances, `solve_options` for `jc.solve`, `check_grid`. Its
      fields are still accepted as keywords of this function (`lm_steps=50`), put
      into `options`; `options=` is the way.

    **Returns:** a `jc.PronyFit` (fitted material, loss history, sensitivities).

    **Raises:** `ValueError` for data that cannot be fitted (missing force/depth for
    the control mode, fewer samples than parameters, a target that is zero throughout,
    times that do not match the template's loading arrays), `TypeError` for wrong
    argument types.

    Cost: every iteration is one forward solve and one adjoint (implicit) solve of
    the whole time history; the start takes one or two, the sensitivities `2 p`.
    """
    # `_model`: a stand-in `(callable(material, ctx) -> (curve, converged), ctx)` for
    # the contact model (the tests' closed forms; it must reach Dask workers).
    options = with_legacy(options, legacy, "fit_prony")
    problem = set_up(data, scene_template, n_terms, options, init=init,
                     poisson=poisson, fit_poisson=fit_poisson, fixed=fixed,
                     bounds=bounds, weights=weights, noise_std=noise_std,
                     model=_model)
    return fit_problem(problem, options)


# --------------------------------------------------------------------------------------
# The problem.


@dataclasses.dataclass
class _Problem:
    """A fit set up: the data and scene, what is fitted (`kind`, `target`, the
    residual's `scale` = rms / weight), the parametrisation's `refs`, the evaluator
    of the model, the start (`init`, and `theta` its free coordinates)."""

    data: IndentationData
    n: int
    kind: str
    scene: Scene
    target: object
    scale: object
    rms_target: object
    refs: dict
    ev: Evaluator
    model: object
    stand_in: bool  # `_model` given: no contact model (no grid check, no step check)
    init: Prony
    theta: dict
    fixed: dict
    fit_poisson: bool
    n_params: int
    noise_std: float | None
    dtype: object
    solver: str = "grid"  # the contact model: "rings" or "grid"

    @property
    def fd_step(self) -> float:
        """The central-difference step of the Jacobians (log-parameters)."""
        return 1e-3 if jnp.finfo(self.dtype).bits >= 64 else 3e-2


def _check_call(data, scene_template, n_terms, options, noise_std) -> int:
    """The argument checks that need no set-up: `n_terms` as an int."""
    if not isinstance(data, IndentationData):
        raise TypeError(f"data must be a jc.IndentationData, got {data!r}")
    if not isinstance(scene_template, Scene):
        raise TypeError(f"scene_template must be a jc.Scene, got {scene_template!r}")
    n = check_int("n_terms", n_terms, 1)
    if options.optimiser == "lm" and not have_optimistix():
        raise ImportError(
            'optimiser="lm" needs optimistix: pip install "jaxcontact[fit]"')
    if noise_std is not None and not (np.isfinite(noise_std) and noise_std > 0):
        raise ValueError(f"noise_std must be finite and > 0, got {noise_std!r}")
    return n


def _check_init(init, data, scene_template, n, poisson, weights):
    """`init` as a `jc.Prony` of `n` arms or `None` (`"lee-radok"` computed)."""
    if isinstance(init, str):
        if init != "lee-radok":
            raise ValueError(f"init must be a jc.Prony, None or 'lee-radok', got "
                             f"{init!r}")
        nu = float(scene_template.material.poisson) if poisson is None else poisson
        init = lee_radok_start(data, scene_template, n, poisson=nu, weights=weights)
    if init is not None and (not isinstance(init, Prony) or init.g.shape != (n,)):
        raise ValueError(f"init must be a jc.Prony with n_terms={n} arms, got {init!r}")
    return init


def _residual_scale(target, weights, kind, dtype):
    """`(rms(target), scale)`: residual k is `(curve - target)_k w_k / rms(target)`,
    `scale` holds `rms / w` (weights normalised to a mean square of 1)."""
    rms_target = jnp.sqrt(jnp.mean(target**2))
    if weights is not None:
        w = check_series("weights", weights).astype(float)
        if w.shape != target.shape or not np.all(w > 0):
            raise ValueError(f"weights must be {target.shape[0]} numbers > 0 (one per "
                             f"time), got shape {w.shape}, min {w.min()!r}")
        w = w / np.sqrt(np.mean(w**2))  # mean w^2 = 1: the loss keeps its scale
    else:
        w = np.ones(target.shape)
    scale = rms_target / jnp.asarray(w, dtype)
    if not float(rms_target) > 0:
        raise ValueError(f"data.{kind} is zero at every time: nothing to fit")
    return rms_target, scale


def _check_poisson(poisson, scene_template, fit_poisson):
    if poisson is None:
        poisson = float(scene_template.material.poisson)
    if fit_poisson and not 0 < poisson < 0.5:
        raise ValueError(f"poisson must be in (0, 0.5) to be fitted, got {poisson!r}")
    if not -1 < poisson <= 0.5:
        raise ValueError(f"poisson must be in (-1, 0.5], got {poisson!r}")
    return poisson


def set_up(data, scene_template, n_terms, options: FitOptions, *, init, poisson,
           fit_poisson, fixed, bounds, weights, noise_std, model) -> _Problem:
    """Every check of the problem, the scene, the references and the start."""
    n = _check_call(data, scene_template, n_terms, options, noise_std)
    init = _check_init(init, data, scene_template, n, poisson, weights)
    dtype = scene_template.grid.size.dtype
    fixed = check_fixed(fixed, n)
    bounds = check_bounds(bounds, fixed)
    fit_poisson = bool(fit_poisson)
    n_params = 1 + 2 * n + int(fit_poisson) - sum(
        int(np.size(v)) for v in fixed.values())
    if data.times.shape[0] <= n_params:
        raise ValueError(
            f"{n_params} parameters need more than {n_params} samples, got "
            f"{data.times.shape[0]} (use more samples or fewer terms)"
        )
    scene, kind, target = scene_for(data, scene_template, dtype)
    rms_target, scale = _residual_scale(target, weights, kind, dtype)
    poisson = _check_poisson(poisson, scene_template, fit_poisson)
    stand_in = model is not None
    solver = "grid"
    if stand_in:
        model, ctx = model
    else:
        solver = choose_solver(options.solver, scene,
                               {"scheme": "linear", **(options.solve_options or {})})
        if solver == "rings":
            model, ctx = ring_model(scene, kind, options.solve_options,
                                    rings=options.rings, depth=data.depth)
        else:
            model, ctx = scene_model(scene, kind, options.solve_options)
    g_ref = float(init.relaxation(0.0)) if init is not None else float(
        scene_template.material.relaxation(0.0))
    refs = make_refs(g_ref, float(data.times[-1] - data.times[0]), poisson, fixed,
                     bounds, dtype)
    ev = Evaluator(ctx, refs, target, scale, model, fit_poisson, dtype)
    if init is None:
        init = initial_guess(ev, refs, fit_poisson, kind, data.times, target, n,
                             initial_times(data.times, n), dtype, poisson,
                             data.depth if kind == "force" else data.force,
                             exponent=load_exponent(scene.indenter))
    theta = to_theta(init, refs, fit_poisson, dtype)
    theta = {k: v for k, v in theta.items() if k not in fixed}
    return _Problem(data, n, kind, scene, target, scale, rms_target, refs, ev, model,
                    stand_in, init, theta, fixed, fit_poisson, n_params, noise_std,
                    dtype, solver)


# --------------------------------------------------------------------------------------
# The optimiser run.


class _Run(NamedTuple):
    theta: dict
    message: str
    probe: dict | None  # the last boundary probe's point: None when none helps
    adam_steps: int
    lbfgs_steps: int
    lm_steps: int
    optimiser: str  # what ran: "lm", "lbfgs" or "lbfgs+lm"
    history: list


def fit_problem(p: _Problem, options: FitOptions, lm_ready=None) -> PronyFit:
    """The fit of a set-up problem (`lm_ready`: see `LMRun`)."""
    return _finish(p, options, _optimise(p, options, lm_ready))


def _optimise(p: _Problem, options: FitOptions, lm_ready=None) -> _Run:
    """The optimiser's run from the start, restarted from boundary probes; `"auto"`
    hands over to LM where L-BFGS' result is not certified."""
    history = []
    lm = LMRun(p.ev, options.lm_steps, p.dtype, p.init, history, ready=lm_ready)

    def probed(run, theta, adam_steps):
        return with_probes(run, theta, adam_steps, ev=p.ev, refs=p.refs,
                           fit_poisson=p.fit_poisson, times=p.data.times)

    # On rings "auto" is LM alone: its Jacobian (one tangent solve on rings per
    # parameter) is cheap there, while L-BFGS crawls to its step bound on the same
    # curves and hands over to LM anyway (benchmarks/rings.py).
    lm_only = options.optimiser == "lm" or (
        options.optimiser == "auto" and p.solver == "rings" and have_optimistix())
    if lm_only:
        history.append(float(p.ev.value(p.theta)[0]))
        theta, message, probe, n_adam, n_lbfgs = probed(lm, p.theta, 0)
        return _Run(theta, message, probe, n_adam, n_lbfgs, lm.total, "lm", history)
    gtol = options.gtol
    if gtol is None:
        gtol = 1e-12 if jnp.finfo(p.dtype).bits >= 64 else 1e-6

    def lbfgs(theta, adam_steps):
        return adam_lbfgs(p.ev, theta, adam_steps, options=options, gtol=gtol,
                          fd_step=p.fd_step, history=history, init=p.init)

    theta, message, probe, n_adam, n_lbfgs = probed(lbfgs, p.theta, options.adam_steps)
    used = "lbfgs"
    if options.optimiser == "auto" and have_optimistix():
        handed = _hand_over(p, theta, probe, lambda th: probed(lm, th, 0))
        if handed is not None:
            theta, message_lm, probe, from_start, why = handed
            message = (f"L-BFGS: {message}; not certified ({why}), then, from "
                       f"{'the start' if from_start else 'its end'}, {message_lm}")
            used = "lbfgs+lm"
    return _Run(theta, message, probe, n_adam, n_lbfgs, lm.total, used, history)


def _hand_over(p: _Problem, theta, probe, run_lm):
    """`"auto"`'s second stage: where L-BFGS' result `theta` is not certified, LM
    (`run_lm`, with probes) from it AND from the start, the lower loss kept:
    `(theta, message, probe, from the start?, why)`; `None` where it is certified."""
    # L-BFGS is fast from a good start (64^2 x 40, PMMA step, float64: 6.8 s against
    # 7.1 s for LM, whose Jacobian costs one tangent solve per parameter per step); LM
    # reaches the minimum from starts where L-BFGS stalls. So LM takes over where
    # L-BFGS' result is not certified (see `certify`).
    ev = p.ev
    theta = project(theta, p.refs)
    _, grad, c_auto, _ = ev.loss(theta)
    r_auto = (np.asarray(c_auto) - np.asarray(p.target)) / np.asarray(p.scale, float)
    rows, active = _jacobian(p, theta, grad)
    pred = predicted_decrease(np.where(active[None, :], 0.0, rows), r_auto)
    value_auto = float(np.mean(r_auto**2))
    stuck = at_boundary(to_material(theta, p.refs, p.fit_poisson), p.data.times,
                        p.refs)
    if not (probe is not None or stuck
            or not (pred < GN_TOL or pred * value_auto < decrease_floor(p.dtype))):
        return None
    # LM from L-BFGS' end AND from the start (L-BFGS may have walked into a dead arm,
    # where no gradient leads out: the creep file at 16^2, 1 arm, sent tau_1 to
    # 3e-18 s, while LM from the start converges); the lower loss
    start_lm = run_lm(p.theta)
    end_lm = run_lm(theta)
    best = min((start_lm, end_lm), key=lambda r: float(ev.value(r[0])[0]))
    why = (f"at a boundary ({', '.join(stuck)})" if stuck else
           f"Gauss-Newton predicts {pred:.2g}")
    return best[0], best[1], best[2], best is start_lm, why


# --------------------------------------------------------------------------------------
# The certificate, the sensitivities and the result.


def _jacobian(p: _Problem, theta, grad):
    """`(rows, active)`: the `(nt, p)` Jacobian of the relative residual at `theta`
    (central differences; a bounded coordinate on its bound is differenced a step
    inside, so its column is the inside's, not half of it) and the flat `(p,)` mask
    of the active set: the coordinates on a bound that the loss's gradient `grad`
    pushes outwards, whose columns a Gauss-Newton step leaves out."""
    rows = p.ev.jacobian(inside(theta, p.refs, p.fd_step), p.fd_step)
    active = np.asarray(ravel_pytree(pinned(theta, grad, p.refs))[0], bool)
    return rows, active


def _sensitivities(p: _Problem, rows, rel):
    """`(std, cov, sigma_rel, note)`: the Gauss-Newton std and covariance of the
    log-parameters (NaN, and a note, where the Jacobian is not finite) and the
    relative noise level."""
    if p.noise_std is None:
        sigma_rel = math.sqrt(float(np.sum(rel**2)) / (rel.shape[0] - p.n_params))
    else:
        sigma_rel = float(p.noise_std) / float(p.rms_target)
    found = log_covariance(rows, sigma_rel)
    if found is None:
        return (np.full(rows.shape[1], np.nan), np.full((rows.shape[1],) * 2, np.nan),
                sigma_rel, "; the model's Jacobian is not finite: std is NaN")
    return *found, sigma_rel, ""


def _grid_check(p: _Problem, options: FitOptions, theta, curve):
    """`(PronyFit.discretisation, note)` of `FitOptions.check_grid`."""
    if not options.check_grid or p.stand_in:
        return None, ""
    material = to_material(theta, p.refs, p.fit_poisson)
    if p.solver == "rings":  # twice the rings over the same radius
        return discretisation_rms(p.scene, material, p.model, curve,
                                  ctx=p.ev.args[0]), ""
    if not isinstance(p.scene.indenter, Sphere):
        return None, ("; check_grid needs a jc.Sphere indenter (a surface array is "
                      "per grid)")
    return discretisation_rms(p.scene, material, p.model, curve), ""


def _finish(p: _Problem, options: FitOptions, run: _Run) -> PronyFit:
    """Certificate, sensitivities and the `jc.PronyFit` of the optimiser's `run`."""
    theta = project(run.theta, p.refs)
    value, grad, curve, ok = p.ev.loss(theta)
    rows, active = _jacobian(p, theta, grad)
    residual = np.asarray(curve) - np.asarray(p.target)
    rel = residual / np.asarray(p.scale, float)  # weighted, relative
    std, cov, sigma_rel, note = _sensitivities(p, rows, rel)
    stuck = [x for x in at_boundary(to_material(theta, p.refs, p.fit_poisson),
                                    p.data.times, p.refs)
             if x.split("_")[0] + ("_inf" if x.startswith("g_inf") else "")
             not in p.fixed]
    # a constrained minimum: the Gauss-Newton step moves the free coordinates only
    converged, verdict = certify(np.where(active[None, :], 0.0, rows), rel, value, ok,
                                 run.probe, stuck, p.dtype)
    discretisation, grid_note = _grid_check(p, options, theta, curve)
    material = to_material(theta, p.refs, p.fit_poisson)
    if not p.stand_in and dict(p.model.options).get("scheme") == "constant":
        # Inside the fit the material is traced and jc.solve cannot check its steps;
        # check the result (the fits sat at an amplification of 1.14 unseen).
        warn_unstable_steps(material, p.scene.times)
    material, order = sorted_by_tau(material)
    operator = p.ev.args[0][1] if p.solver == "rings" else None
    return PronyFit(
        material=material,
        initial=p.init,
        loss=float(value),
        loss_history=np.asarray(run.history),
        adam_steps=run.adam_steps,
        lbfgs_steps=run.lbfgs_steps,
        lm_steps=run.lm_steps,
        optimiser=run.optimiser,
        evaluations=p.ev.calls,
        converged=converged,
        message=run.message + note + verdict + grid_note,
        solves_converged=bool(np.all(np.asarray(ok))),
        times=np.asarray(p.data.times),
        target=np.asarray(p.target),
        curve=np.asarray(curve),
        residual=residual,
        kind=p.kind,
        std=sorted_split(theta, std, p.fixed, order),
        covariance=sorted_covariance(cov, theta, p.fixed, order, p.fit_poisson),
        parameter_names=parameter_names(p.n, p.fit_poisson),
        gradient=sorted_split(theta, np.asarray(ravel_pytree(grad)[0]), p.fixed,
                              order),
        noise=sigma_rel * float(p.rms_target),
        discretisation=discretisation,
        solver=p.solver,
        rings=operator.rings if operator is not None else None,
        ring_radius=(float(np.asarray(operator.edges)[-1]) if operator is not None
                     else None),
    )
