"""The quality verdict of a fitted AFM curve, and its moduli as AFM users read them.

The verdict compares the fitted model with the RAW samples of each fitted segment
(approach, hold, retract; each thinned evenly to at most 600): `rms(model - data) /
noise`, with `noise` the raw curve's white noise (`AFMCurve.noise`: successive
differences). A model that reproduces the data leaves the noise: a ratio of 1. The fit
is `"good"` when every fitted segment is within `QUALITY_LIMIT` of it, a
`"systematic misfit"` otherwise, naming the segments.

A systematic misfit is diagnosed with the closed-form floor (`fitting.floor`): the
model's own limit, or the fit's shortfall.

Flags (each makes `jaxcontact fit` exit 1): not converged, a systematic misfit, a
parameter at a bound, the grid's bias above the noise, a contact point the
viscoelastic refinement could not place, an implausible probe radius (a sphere) or
half-angle (a cone). Caveats (do not change the exit status): a modulus that rests on
relaxation times faster than the approach (`E_0`); an indentation deeper than the
sphere's radius (a cone has no length scale: no such caveat; its own limit, a sharp
apex, is in the report's `tip_note`).
"""

import math

import numpy as np

from .._loading import Displacement, Force
from .._solve import solve
from .._solver.rounds import Rounds
from .floor import closed_form_floor


# A model within the noise gives 1; 2 allows a systematic part of sqrt(3) x the noise.
QUALITY_LIMIT = 2.0
SEGMENTS = ("approach", "hold", "retract")
_AT_BOUND = 0.01  # a relaxation time within 1 % (in log) of a bound sits on it
DEEP = 1.0  # depth / radius above which the caveat on the small-strain model shows


def ring_keywords(fit) -> dict:
    """`model_curve`'s `rings`, `radius` of a `jc.PronyFit` (empty on the grid)."""
    if fit.solver != "rings":
        return {}
    return {"rings": int(fit.rings), "radius": float(fit.ring_radius)}


def model_curve(material, template, *, times, force, depth, kind, refine=1,
                rings=None, radius=None):
    """`(nt,)` the contact model of `material` on `template`'s grid (`refine` times
    the cells per side, same width), or on `rings` rings over `[0, radius]` [m]
    (`refine` times the rings, `solve_axisymmetric`), driven by the measured `force`
    (`kind="depth"`: returns the depth [m]) or `depth` (`kind="force"`: returns the
    force [N]) at `times` [s], from an unloaded start, scheme `"linear"` as in the
    fit."""
    import equinox as eqx
    import jax.numpy as jnp

    if rings is not None:
        from .._solve_rings import solve_axisymmetric
        from .rings_model import ring_context

        normal = (Force(jnp.asarray(force)) if kind == "depth"
                  else Displacement(jnp.asarray(depth)))
        scene = eqx.tree_at(lambda s: (s.material, s.times, s.normal), template,
                            (material, jnp.asarray(times), normal))
        _, operator = ring_context(template, refine * rings, radius)
        sol = solve_axisymmetric(scene, operator=operator, scheme="linear",
                                 throw=False)
        return np.asarray(sol.approach if kind == "depth" else sol.normal_force)
    grid = template.grid
    if refine != 1:
        grid = type(grid)(shape=tuple(refine * k for k in grid.shape), size=grid.size,
                          periodic=grid.periodic)
    normal = (Force(jnp.asarray(force)) if kind == "depth"
              else Displacement(jnp.asarray(depth)))
    scene = eqx.tree_at(lambda s: (s.grid, s.material, s.times, s.normal), template,
                        (grid, material, jnp.asarray(times), normal))
    # The grid's own check: `jc.solve` would put an axisymmetric scene on rings.
    sol = solve(scene, solver=Rounds(), scheme="linear", throw=False)
    return np.asarray(sol.approach if kind == "depth" else sol.normal_force)


def padded_length(n: int) -> int:
    """The length a raw curve of `n` samples is solved at: the next power of two (at
    least 64), so that the curves of a map, whose sample counts after the contact
    differ, share a few compiled programs (one, mostly) instead of one each."""
    return max(64, 1 << (int(n) - 1).bit_length())


def raw_residual(material, kind, curve, template, *, refine=1, max_samples=600,
                 rings=None, radius=None):
    """`(time, residual, segment)` of the model of `material` against the RAW samples
    of an `AFMCurve` (each segment thinned evenly to at most `max_samples`): one
    forward solve on `template`'s grid (`refine` x the cells per side; or on `rings`
    rings over `radius`, `model_curve`) from an unloaded start at `t = 0`, fitting
    `kind` ("depth" or "force"). The solve runs on `padded_length` samples (the
    last ones held after the end: the model is causal, the samples are unchanged).
    `residual` = model - data [N or m], every sample after the contact's."""
    keep = np.zeros(curve.time.shape, bool)
    for code in (0, 1, 2):
        idx = np.flatnonzero(curve.segment == code)
        keep[idx[:: max(1, -(-idx.size // max_samples))]] = True
    t, f, d, s = (x[keep].copy() for x in (curve.time, curve.force, curve.depth,
                                            curve.segment))
    if t[0] <= 0:  # the contact sample: the model starts unloaded there
        f[0], d[0] = 0.0, 0.0
    else:
        t, f, d, s = np.r_[0.0, t], np.r_[0.0, f], np.r_[0.0, d], np.r_[0, s]
    n, pad = t.size, padded_length(t.size) - t.size
    step = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    tp = np.r_[t, t[-1] + step * np.arange(1, pad + 1)]
    fp, dp = np.r_[f, np.full(pad, f[-1])], np.r_[d, np.full(pad, d[-1])]
    model = model_curve(material, template, times=tp, force=fp, depth=dp, kind=kind,
                        refine=refine, rings=rings, radius=radius)[:n]
    # The contact sample itself is no measurement (force and depth 0 by definition;
    # under load control the model's first approach is the gap of the node nearest
    # the apex): it is left out.
    res = model - (d if kind == "depth" else f)
    return t[1:], res[1:], s[1:]


def at_bounds(material, tau_bounds) -> list:
    """Parameters of `material` at a bound: a relaxation time within 1 % (in log) of
    `tau_bounds` [s], or a modulus below 1e-4 of the instantaneous one (the positive
    parametrisation's floor). Texts such as `"tau_2 = 31.2 s at its upper bound"`."""
    g_inf, g, tau = (np.asarray(x, float) for x in (material.g_inf, material.g,
                                                    material.tau))
    g0 = float(g_inf + g.sum())
    out = [f"g_inf = {float(g_inf):.3g} Pa at 0"] if g_inf < 1e-4 * g0 else []
    for i in range(g.shape[0]):
        if g[i] < 1e-4 * g0:
            out.append(f"g_{i + 1} = {g[i]:.3g} Pa at 0")
        if tau_bounds:
            for bound, name in zip(tau_bounds, ("lower", "upper"), strict=True):
                if abs(math.log(tau[i] / bound)) < _AT_BOUND:
                    out.append(f"tau_{i + 1} = {tau[i]:.4g} s at its {name} bound "
                               f"{bound:.4g} s")
    return out


def finer_grid(n, bias_over_noise):
    """The cells per side (a multiple of 8) at which a grid bias of `bias_over_noise`
    x the noise on `n` cells falls below the noise, assuming it falls as `n^-1.5`
    (measured on the creep file: `n^-2.7` from 16^2 to 32^2, `n^-1.7` from 32^2 to
    64^2; the slower rate, rounded down, errs towards a finer grid)."""
    return int(8 * math.ceil(n * bias_over_noise ** (1 / 1.5) / 8))


def finer_rings(n, bias_over_noise):
    """The ring count (a multiple of 8) at which a ring bias of `bias_over_noise` x
    the noise on `n` rings falls below the noise: the rings converge at second order
    (`benchmarks/notes/rings.md`: orders 1.97-2.00 from 32 to 512 rings)."""
    return int(8 * math.ceil(n * bias_over_noise ** 0.5 / 8))


def relaxation_modulus(material, t):
    """`G(t) = g_inf + sum g_i exp(-t / tau_i)` [Pa] of a `jc.Prony` at `t` [s]."""
    g, tau = np.asarray(material.g, float), np.asarray(material.tau, float)
    return float(material.g_inf) + float(np.sum(g * np.exp(-t / tau)))


def log_std_of(material, covariance, t):
    """Gauss-Newton standard deviation of `log G(t)` [-] from the fit's covariance of
    the log-parameters (`g_inf, g_1..n, tau_1..n`); `t = 0`: the instantaneous
    modulus. Inf where a parameter it depends on is undetermined."""
    g, tau = np.asarray(material.g, float), np.asarray(material.tau, float)
    decay = g * np.exp(-t / tau)
    total = float(material.g_inf) + decay.sum()
    w = np.concatenate([[float(material.g_inf)], decay, decay * t / tau]) / total
    c = np.asarray(covariance, float)[: w.size, : w.size]
    used = w != 0
    c, w = c[np.ix_(used, used)], w[used]
    if not np.isfinite(c).all():
        return math.inf
    return float(math.sqrt(max(float(w @ c @ w), 0.0)))


def _entry(value, std_log, components=None):
    """One reported parameter: value, std (= value x std_log, the relative standard
    deviation), std_log, and the analysis components of std_log."""
    value = float(value)
    finite = std_log is not None and math.isfinite(std_log)
    out = {"value": value, "std": value * std_log if finite else None,
           "std_log": std_log if finite else None}
    if components is not None:
        out["std_log_components"] = {k: (v if math.isfinite(v) else None)
                                     for k, v in components.items()}
    return out


def _combined(stat, shifts):
    """Total std of a log quantity: its Gauss-Newton std and the analysis shifts in
    quadrature; `(total, components)`."""
    comps = {"optimiser": stat, **shifts}
    return math.sqrt(sum(v * v for v in comps.values())), comps


def _parameters(fit, uncertainty):
    m = fit.material
    out = {}

    def one(value, stat, getter):
        shifts = {} if uncertainty is None else uncertainty.log_shifts(getter)
        total, comps = _combined(stat, shifts)
        return _entry(value, total, comps if uncertainty is not None else None)

    out["g_inf_Pa"] = one(m.g_inf, float(fit.std["g_inf"]),
                          lambda mm: float(mm.g_inf))
    out["g_Pa"] = [one(v, float(s), lambda mm, i=i: float(mm.g[i]))
                   for i, (v, s) in enumerate(zip(np.asarray(m.g), fit.std["g"],
                                                  strict=True))]
    out["tau_s"] = [one(v, float(s), lambda mm, i=i: float(mm.tau[i]))
                    for i, (v, s) in enumerate(zip(np.asarray(m.tau), fit.std["tau"],
                                                   strict=True))]
    return out


def youngs_moduli(parameters, material, poisson, approach_time, uncertainty,
                  covariance=None) -> dict:
    """Young's moduli `E = 2 G (1 + nu)` [Pa] at the fixed Poisson's ratio `poisson`:
    `E_inf_Pa`, `E_Pa` (the arms), `E_0_Pa` (instantaneous, `G(0)`) and
    `E_at_approach_Pa` (`E(T)`, `T` = `approach_time` [s], the approach's duration:
    the modulus the approach measures, comparable with a Hertz fit of it). Entries:
    value, std, std_log (the factor `2 (1 + nu)` carries no uncertainty)."""
    factor = 2 * (1 + poisson)

    def scaled(e):
        out = dict(e)
        out["value"] = factor * e["value"]
        out["std"] = None if e["std"] is None else factor * e["std"]
        return out

    out = {"E_inf_Pa": scaled(parameters["g_inf_Pa"]),
           "E_Pa": [scaled(e) for e in parameters["g_Pa"]]}
    for key, t in (("E_0_Pa", 0.0), ("E_at_approach_Pa", approach_time)):
        stat = (log_std_of(material, covariance, t) if covariance is not None
                else math.nan)
        shifts = {} if uncertainty is None else uncertainty.log_shifts(
            lambda mm, t=t: relaxation_modulus(mm, t))
        total, comps = _combined(stat, shifts)
        out[key] = _entry(factor * relaxation_modulus(material, t), total,
                          comps if uncertainty is not None else None)
    out["approach_time_s"] = approach_time
    out["poisson"] = poisson
    out["note"] = (f"Young's moduli E = 2 G (1 + nu) at the given Poisson's ratio nu = "
                   f"{poisson:g} (fixed); E_0 = E(0), the instantaneous modulus; "
                   f"E_at_approach = E(T) at the approach's duration T = "
                   f"{approach_time:.3g} s")
    return out


def assess(fit, curve, problem, raw_res, raw_seg, disc, tip_note, uncertainty):
    """The report's verdict: parameters with their uncertainty, residuals against the
    noise by segment, the quality verdict, flags and caveats (a dict to merge into
    the report). `tip_note`: the tip's plausibility warning (`fitting.afm.
    tip_warning`) or None."""
    probe = problem.settings.probe
    noise = curve.noise(fit.kind)
    fitted = [s for s in SEGMENTS if s in problem.settings.segments]
    by_segment = {}
    for code, name in enumerate(SEGMENTS):
        sel = raw_seg == code
        if name in fitted and sel.any():
            by_segment[name] = float(np.sqrt(np.mean(raw_res[sel] ** 2)) / noise)
    worse = {k: v for k, v in by_segment.items() if v > QUALITY_LIMIT}
    verdict = "good" if not worse else "systematic misfit"
    flags = []
    if not fit.converged:
        flags.append(f"not converged: {fit.message}")
    floor = (closed_form_floor(curve, exponent=probe.exponent) if worse
             else None)
    if worse:
        flags.append("systematic misfit: " + ", ".join(
            f"{k} {v:.3g} x the noise" for k, v in worse.items())
            + f" (limit {QUALITY_LIMIT:g}); " + misfit_diagnosis(worse, floor))
    for text in at_bounds(fit.material, problem.tau_bounds):
        flags.append(f"parameter at a bound: {text}")
    if disc is not None and disc > noise and fit.solver == "rings":
        flags.append(f"ring discretisation bias {disc / noise:.3g} x the noise "
                     f"({fit.rings} rings): about --rings "
                     f"{finer_rings(fit.rings, disc / noise)} brings it below the "
                     "noise")
    elif disc is not None and disc > noise:
        flags.append(f"grid bias {disc / noise:.3g} x the noise (grid "
                     f"{problem.settings.n}^2): about --n "
                     f"{finer_grid(problem.settings.n, disc / noise)} brings it "
                     "below the noise")
    if "no minimum" in curve.contact_note or "too few" in curve.contact_note:
        flags.append(f"contact point: {curve.contact_note}")
    if tip_note is not None:
        what = "radius" if probe.tip == "sphere" else "half-angle"
        flags.append(f"{what}: {tip_note}")
    if uncertainty is not None:
        flags.extend(uncertainty.flags)
    caveats = []
    tau1 = float(np.min(np.asarray(fit.material.tau)))
    if tau1 < problem.approach_time:
        caveats.append(
            f"E_0 rests on tau_1 = {tau1:.3g} s, faster than the approach "
            f"({problem.approach_time:.3g} s): an extrapolation the loading does not "
            "see; E_at_approach is what the approach measures")
    depth_ratio = (float(np.max(curve.depth)) / probe.size if probe.tip == "sphere"
                   else 0.0)
    if depth_ratio > DEEP:
        caveats.append(
            f"the maximum depth is {depth_ratio:.3g} x the probe radius: beyond the "
            "small-strain half-space the model (and Hertz) assumes (depth << radius)")
    params = _parameters(fit, uncertainty)
    return {
        "parameters": params,
        "log_parameter_names": list(fit.parameter_names),
        "log_parameter_correlation": _correlation(fit.covariance),
        "instantaneous_modulus_Pa": relaxation_modulus(fit.material, 0.0),
        "residual_rms": float(np.sqrt(np.mean(fit.residual**2))),
        "noise_raw": noise,
        "residual_over_noise_raw": by_segment,
        "quality": {
            "verdict": verdict,
            "criterion": (f"good when the RMS of model - data over the raw samples of "
                          f"every fitted segment is within {QUALITY_LIMIT:g} x the "
                          "raw white noise (successive differences); 1 = the noise"),
            "limit": QUALITY_LIMIT, "by_segment": by_segment},
        "closed_form_floor": floor,
        "discretisation_rms": disc,
        "discretisation_over_noise": None if disc is None else disc / noise,
        "uncertainty": None if uncertainty is None else uncertainty.summary(),
        "flags": flags,
        "caveats": caveats,
    }


def misfit_diagnosis(worse, floor) -> str:
    """Whose misfit it is, from the closed-form floor (`fitting.floor`): the model's
    (the floor is above the limit too) or the fit's (the floor is below), and whether
    the hold alone is one linear viscoelastic response. `worse`: {segment: ratio}."""
    joint, parts = floor["joint"], []
    for name in worse:
        if name not in joint:
            continue
        if joint[name] > QUALITY_LIMIT:
            parts.append(f"the model's floor in the {name} is {joint[name]:.3g} x "
                         f"(closed form, {floor['arms']} arms): a limit of the model, "
                         "not of the fit")
        else:
            parts.append(f"the model reaches {joint[name]:.3g} x in the {name} "
                         f"(closed form, {floor['arms']} arms): the fit falls short "
                         "(more arms, a finer --n, another contact point)")
    alone = floor["hold_alone"]
    if alone is not None and joint.get("hold", 0.0) > QUALITY_LIMIT:
        parts.append(
            f"the hold alone reaches {alone:.3g} x: the approach and the hold are not "
            "one linear viscoelastic response of this model" if alone <= QUALITY_LIMIT
            else f"even the hold alone is {alone:.3g} x at best ({floor['arms']} arms)")
    if "retract" in worse:
        parts.append("the retract (the unloading) has no closed-form floor; a fitted "
                     "retract also pulls the approach and hold: compare without it "
                     "(--segments approach,hold, the default)")
    return "; ".join(parts) if parts else "no closed-form floor for these segments"


def _correlation(cov):
    """Correlation matrix of a covariance (nested lists; None where undetermined)."""
    cov = np.asarray(cov, float)
    d = np.sqrt(np.diag(cov))
    with np.errstate(invalid="ignore", divide="ignore"):
        c = cov / np.outer(d, d)
    return [[float(v) if np.isfinite(v) else None for v in row] for row in c]
