"""`jaxcontact fit FILE... --radius R`: fit a Prony series to AFM indentation files.

    jaxcontact fit FILE... --radius R [--arms N|auto] [--out DIR] [--n N]
                   [--poisson NU] [--baseline constant|linear] [--samples A,H,R]
                   [--segments approach,hold,retract] [--steps K]
                   [--contact viscoelastic|piecewise] [--start lee-radok|data]
                   [--tau-range LO,HI|auto|none] [--no-check-grid] [--overwrite]

Each file is read by `jc.read_afm` (afmformats: `pip install "jaxcontact[afm]"`), its
segments binned (`--samples`: points in the approach, hold and retract after contact),
and `jc.fit_prony` fits the series through the full contact model (a sphere of radius
`R` [m] on an `N x N` grid). Creep files (force clamp) fit the depth under the measured
force; relaxation files (height clamp) the force under the measured depth. `--arms auto`
fits 1 to 4 arms and keeps the converged one with the smallest BIC (AIC and BIC of
every count are reported).

Writes `DIR/STEM_fit.json` (parameters with Gauss-Newton standard deviations, the
Young's moduli `E = 2 G (1 + nu)` beside the shear moduli, the residual RMS and noise
estimate, convergence, contact point, units) and `DIR/STEM_fit.png` (data, model and
residuals per segment). `STEM` is the file's name minus its final extension
(`gel.001.jpk-force` -> `gel.001`); outputs already in `DIR` are refused before any fit
unless `--overwrite` is given, and so are two files with the same stem. The residual is
also given in units of the data's own noise (each bin mean's, from the raw curve's
successive differences): about 1 where the model reproduces the data to the noise;
and the model's discretisation error (the fitted curve on a grid twice as fine;
`--no-check-grid` skips it). Exit status: 0 on success,
1 when a fit did not converge, 2 for bad input (the message names the bad value).

Compiled programs are cached on disk (`jc.enable_compilation_cache`: folder
`JAXCONTACT_CACHE_DIR`, default `~/.cache/jaxcontact/xla`; `--no-cache` or
`JAXCONTACT_NO_CACHE=1`: none), so a second run of the same sizes skips most of the
compilation.

The probe radius is not in the files: absolute moduli scale as `R^(-1/2)`; relaxation
times and modulus ratios do not depend on it. A radius outside `RADIUS_WINDOW` times the
curve's maximum indentation depth warns (`radius_warning`: most likely a unit slip).
"""

import argparse
import json
import math
import sys
import warnings
from pathlib import Path

from ._cache import (
    add_cache_argument,
    cache_disabled_by_environment,
    enable_compilation_cache,
)
from ._cli_output import InputError, prepare_out


RADIUS_NOTE = ("the probe radius is an input (not in the file): absolute moduli scale "
               "as radius^(-1/2); relaxation times and modulus ratios do not depend "
               "on it")


# Plausible probe radius / maximum indentation depth of a sphere: below 1e-2 the Hertz
# contact radius sqrt(R d) would exceed 10 R (a sphere's is at most R); above 1e3 the
# depth is under R / 1000, at the contact point's uncertainty. A unit slip of the
# radius (um or nm read as m) is a factor 1e3-1e9, far outside.
RADIUS_WINDOW = (1e-2, 1e3)


class _BadInput(InputError):
    """Bad input to `jaxcontact fit`: exit status 2, the message names the value."""


def output_stem(path) -> str:
    """The stem of a file's outputs: its name minus the final extension only
    (`gel.001.jpk-force` -> `gel.001`), so numbered files of a series stay apart."""
    return Path(path).stem


def fit_outputs(stem) -> list:
    """The files `jaxcontact fit` writes in `--out` for one input of stem `stem`."""
    return [f"{stem}_fit.json", f"{stem}_fit.png"]


def _plan_outputs(files, out, overwrite) -> dict:
    """`{file: stem}` for the inputs, after checking (before any fit) that no two
    files share a stem and that `out` can take every output (`prepare_out`: created,
    writable, existing outputs refused unless `overwrite`); `InputError` otherwise."""
    stems = {}
    for path in files:
        stem = output_stem(path)
        twin = next((f for f, s in stems.items() if s == stem), None)
        if twin is not None:
            raise _BadInput(f"{twin!r} and {path!r} would both write {stem}_fit.json: "
                            "fit them into different --out folders")
        stems[path] = stem
    prepare_out(out, [name for s in stems.values() for name in fit_outputs(s)],
                 overwrite)
    return stems


def radius_warning(radius, depth):
    """The warning text when the probe radius `radius` [m] is implausible against the
    curve's maximum indentation depth `depth` [m], else None.

    Plausible: `RADIUS_WINDOW[0] <= radius / depth <= RADIUS_WINDOW[1]`. Outside, the
    text names the radius, the depth, the rule and, for a radius too large, the
    reading in um, nm or mm that falls inside the window (the radius is read in m).
    """
    lo, hi = RADIUS_WINDOW
    if not depth > 0:  # no indentation to compare with
        return None
    ratio = radius / depth
    if lo <= ratio <= hi:
        return None
    text = (f"--radius {radius:g} m is {ratio:.3g} x the maximum indentation depth "
            f"{depth:.3g} m; a spherical probe's radius is {lo:g} to {hi:g} x the "
            "depth (below, its Hertz contact radius sqrt(R d) would exceed 10 R; "
            "above, the depth is at the contact point's uncertainty)")
    if ratio > hi:
        for scale, unit in ((1e-6, "micrometres"), (1e-9, "nanometres"),
                            (1e-3, "millimetres")):
            if lo <= ratio * scale <= hi:
                return (text + f": the radius is in metres; if {radius:g} was meant in "
                        f"{unit}, pass --radius {radius * scale:g}")
    return text + ": check the radius's unit (metres) and the contact point"


def add_parser(sub):
    """Register `fit` on the `jaxcontact` subcommand parser `sub`."""
    p = sub.add_parser("fit", help="fit a Prony series to AFM indentation files")
    add_cache_argument(p)
    p.add_argument("files", nargs="+", metavar="FILE",
                   help="force-distance files afmformats reads (e.g. .jpk-force)")
    p.add_argument("--radius", type=float, required=True,
                   help="probe (sphere) radius [m]")
    p.add_argument("--arms", default="2",
                   help="number of Prony arms (1..8), or 'auto' (1..4, smallest BIC)")
    p.add_argument("--out", default="jaxcontact-fit", help="output directory")
    p.add_argument("--overwrite", action="store_true",
                   help="replace outputs of the same name already in --out (default: "
                        "refuse, before any fit)")
    p.add_argument("--n", type=int, default=24, help="grid cells per side (default 24)")
    p.add_argument("--poisson", type=float, default=0.5,
                   help="Poisson's ratio, fixed (default 0.5: incompressible)")
    p.add_argument("--baseline", default="constant", choices=("constant", "linear"),
                   help="baseline of the contact point fit")
    p.add_argument("--start", default="lee-radok", choices=("lee-radok", "data"),
                   help="the fit's start: the closed-form Lee & Radok fit of the "
                        "loading and hold (default), or jc.fit_prony's default start "
                        "from apparent moduli")
    p.add_argument("--contact", default="viscoelastic",
                   choices=("viscoelastic", "piecewise"),
                   help="contact point: the piecewise baseline + Hertz fit refined by "
                        "the closed-form viscoelastic model (default), or the "
                        "piecewise fit alone (jc.read_afm's contact=)")
    p.add_argument("--check-grid", action=argparse.BooleanOptionalAction, default=True,
                   help="also solve the fitted model on a grid twice as fine and "
                        "report the difference (the model's discretisation error; "
                        "default on)")
    p.add_argument("--tau-range", default="auto", metavar="LO,HI|auto|none",
                   help="bounds on the relaxation times [s]; 'auto' (default): 1e-3 x "
                        "the binned data's shortest time step to its duration (a time "
                        "longer than the data is degenerate with g_inf); 'none'")
    p.add_argument("--steps", type=int, default=200,
                   help="bound on the Levenberg-Marquardt steps (default 200)")
    p.add_argument("--samples", default="8,24,8", metavar="A,H,R",
                   help="points after binning in the approach, hold and retract")
    p.add_argument("--segments", default="approach,hold,retract",
                   help="segments to fit (approach is always needed)")
    return p


def _check(args):
    if not math.isfinite(args.radius):
        raise _BadInput("--radius must be a finite number > 0 [m], got "
                        f"{args.radius!r}")
    if args.radius <= 0:
        raise _BadInput(f"--radius must be a finite number > 0 [m]: the probe radius "
                        f"must be positive, got {args.radius!r}")
    if args.arms != "auto":
        try:
            arms = int(args.arms)
        except ValueError:
            raise _BadInput(f"--arms must be an integer or 'auto', got {args.arms!r}")
        if not 1 <= arms <= 8:
            raise _BadInput(f"--arms must be in 1..8, got {arms}")
    if args.tau_range in ("auto", "none"):
        args.tau_bounds = None if args.tau_range == "none" else "auto"
    elif args.tau_range is not None:
        try:
            lo, hi = (float(v) for v in args.tau_range.split(","))
        except ValueError:
            lo = hi = float("nan")
        if not (0 < lo < hi < math.inf):
            raise _BadInput(f"--tau-range must be LO,HI with 0 < LO < HI [s], got "
                            f"{args.tau_range!r}")
        args.tau_bounds = (lo, hi)
    else:
        args.tau_bounds = None
    if args.steps < 1:
        raise _BadInput(f"--steps must be >= 1, got {args.steps}")
    if args.n < 4:
        raise _BadInput(f"--n must be >= 4, got {args.n}")
    if not (-1 < args.poisson <= 0.5):
        raise _BadInput(f"--poisson must be in (-1, 0.5], got {args.poisson!r}")
    try:
        samples = [int(v) for v in args.samples.split(",")]
    except ValueError:
        samples = []
    if len(samples) != 3 or min(samples) < 1:
        raise _BadInput(f"--samples must be three integers >= 1 "
                        f"(approach,hold,retract), got {args.samples!r}")
    segments = tuple(s.strip() for s in args.segments.split(",") if s.strip())
    if "approach" not in segments or any(
            s not in ("approach", "hold", "retract") for s in segments):
        raise _BadInput(f"--segments must list approach and any of hold, retract; got "
                        f"{args.segments!r}")
    for f in args.files:
        if not Path(f).is_file():
            raise _BadInput(f"no such file: {f!r}")
    return samples, segments


def _information(fit, n_params):
    """AIC and BIC of a least-squares fit with Gaussian noise of unknown variance."""
    import numpy as np

    n = fit.residual.shape[0]
    ssr = float(np.sum(fit.residual**2))
    base = n * math.log(max(ssr, 1e-300) / n)
    return base + 2 * n_params, base + n_params * math.log(n)


def _correlation(cov):
    """Correlation matrix of a covariance (nested lists; None where undetermined)."""
    import numpy as np

    d = np.sqrt(np.diag(cov))
    with np.errstate(invalid="ignore", divide="ignore"):
        c = cov / np.outer(d, d)
    return [[float(v) if np.isfinite(v) else None for v in row] for row in c]


def _choose(fits):
    """The arm count with the smallest BIC among the converged fits (an unconverged
    fit's BIC is not its model's: e.g. a second arm far slower than the hold,
    degenerate with g_inf), among all when none converged. `fits`: {arms: (fit, aic,
    bic)}."""
    converged = [k for k in fits if fits[k][0].converged] or list(fits)
    return min(converged, key=lambda k: fits[k][2])


def _fit_one(path, args, samples, segments):
    import numpy as np

    import jaxcontact as jc
    from jaxcontact._fit import lee_radok_start

    try:
        curve = jc.read_afm(path, baseline=args.baseline, segments=segments,
                            contact=args.contact)
    except (ValueError, TypeError) as exc:
        raise _BadInput(f"{path}: {exc}") from exc
    radius_note = radius_warning(args.radius, float(np.max(curve.depth)))
    if radius_note is not None:
        warnings.warn(f"{path}: {radius_note}", UserWarning, stacklevel=2)
    names = ("approach", "hold", "retract")
    t, f, d, seg, counts = curve.resampled(dict(zip(names, samples, strict=True)),
                                           return_counts=True)
    data = jc.IndentationData(t, force=f, depth=d)
    template = curve.scene_template(args.radius, n=args.n, poisson=args.poisson)
    tau_bounds = args.tau_bounds
    if tau_bounds == "auto":
        steps = np.diff(t)
        tau_bounds = (1e-3 * float(np.min(steps[steps > 0])), float(t[-1] - t[0]))
    arm_counts = range(1, 5) if args.arms == "auto" else [int(args.arms)]
    fits = {}
    for k in arm_counts:
        if t.size <= 2 * k + 2:
            break
        # bin means of `counts` raw samples: weights sqrt(counts) (inverse noise)
        init = None
        if args.start == "lee-radok":
            try:
                init = lee_radok_start(data, template, k, poisson=args.poisson,
                                       weights=np.sqrt(counts))
            except ValueError:  # too few loading samples: the default start
                init = None
        fit = jc.fit_prony(data, template, k, lm_steps=args.steps,
                           weights=np.sqrt(counts), init=init,
                           bounds={"tau": tau_bounds} if tau_bounds else None)
        aic, bic = _information(fit, 1 + 2 * k)
        fits[k] = (fit, aic, bic)
    if not fits:
        raise _BadInput(f"{path}: {t.size} samples are too few to fit")
    best = _choose(fits)
    fit = fits[best][0]
    disc = None
    if args.check_grid:
        from ._fit import discretisation_error

        disc = discretisation_error(fit, data, template)
    m = fit.material

    def entry(value, std_log):
        value, std_log = float(value), float(std_log)
        return {"value": value, "std": value * std_log if math.isfinite(std_log)
                else None, "std_log": std_log if math.isfinite(std_log) else None}

    g0 = float(m.g_inf) + float(np.sum(m.g))
    parameters = {
        "g_inf_Pa": entry(m.g_inf, fit.std["g_inf"]),
        "g_Pa": [entry(v, s) for v, s in zip(np.asarray(m.g), fit.std["g"],
                                              strict=True)],
        "tau_s": [entry(v, s) for v, s in zip(np.asarray(m.tau), fit.std["tau"],
                                               strict=True)],
    }
    rms = float(np.sqrt(np.mean(fit.residual**2)))
    # The noise of each bin mean from the raw curve's own noise (independent of the
    # fit), and the residual in units of it (1: the model is within the noise).
    sigma = curve.noise(fit.kind) / np.sqrt(counts)
    hold = seg == 1
    chi = float(np.sqrt(np.mean((fit.residual / sigma) ** 2)))
    chi_hold = float(np.sqrt(np.mean((fit.residual[hold] / sigma[hold]) ** 2))) if (
        hold.any()) else None
    # The measure: the model on the RAW samples of the hold against their
    # white noise (bin means weigh the first instants of the hold, where log-spaced
    # bins hold a sample or two, as much as its last seconds).
    _, raw_res, raw_seg = raw_residual(fit, curve, template)
    raw_hold = raw_seg == 1
    chi_raw = None
    if raw_hold.any():
        chi_raw = float(np.sqrt(np.mean(raw_res[raw_hold] ** 2))
                        / curve.noise(fit.kind))
    result = {
        "file": str(path),
        "mode": curve.mode,
        "fitted": fit.kind,
        "radius_m": args.radius,
        "radius_note": RADIUS_NOTE,
        "radius_warning": radius_note,
        "poisson": args.poisson,
        "tau_bounds_s": list(tau_bounds) if tau_bounds else None,
        "grid": [args.n, args.n],
        "arms": best,
        "parameters": parameters,
        "youngs_moduli": youngs_moduli(parameters, g0, args.poisson),
        "log_parameter_names": list(fit.parameter_names),
        "log_parameter_correlation": _correlation(fit.covariance),
        "instantaneous_modulus_Pa": g0,
        "ratios_g_over_g0": [float(v) / g0 for v in np.asarray(m.g)],
        "residual_rms": rms,
        "discretisation_rms": disc,
        "discretisation_note": ("RMS change of the fitted model's curve on a grid "
                                "twice as fine: a bias of the model, to compare with "
                                "the residual and the noise"),
        "noise_raw": curve.noise(fit.kind),
        "residual_over_noise": chi,
        "residual_over_noise_hold": chi_hold,
        "hold_residual_over_noise_raw": chi_raw,
        "hold_residual_note": ("RMS of the fitted model against the raw samples of "
                               "the hold (at most 600, evenly thinned) over the raw "
                               "curve's white noise (successive differences)"),
        "contact": args.contact,
        "contact_note": curve.contact_note,
        "start": args.start,
        "converged": bool(fit.converged),
        "message": fit.message,
        "information_criteria": {str(k): {"aic": v[1], "bic": v[2], "loss": v[0].loss,
                                          "converged": bool(v[0].converged)}
                                 for k, v in fits.items()},
        "contact_time_s": curve.contact_time,
        "spring_constant_N_per_m": curve.spring_constant,
        "samples": int(t.size),
        "units": {"time": "s", "force": "N", "depth": "m", "modulus": "Pa (shear)",
                  "youngs_modulus": "Pa"},
    }
    return result, fit, seg


def youngs_moduli(parameters, g0, poisson) -> dict:
    """Young's moduli `E = 2 G (1 + nu)` [Pa] of the fitted shear moduli at the fixed
    Poisson's ratio `poisson`: `E_inf_Pa` and `E_Pa` (entries as `parameters`'
    `g_inf_Pa` and `g_Pa`: value, std, std_log) and `E_0_Pa`, the instantaneous
    modulus from `g0` = g_inf + sum g [Pa]. Poisson's ratio is an input, not fitted:
    the factor carries no uncertainty."""
    factor = 2 * (1 + poisson)

    def scaled(e):
        return {"value": factor * e["value"],
                "std": None if e["std"] is None else factor * e["std"],
                "std_log": e["std_log"]}

    return {
        "E_inf_Pa": scaled(parameters["g_inf_Pa"]),
        "E_Pa": [scaled(e) for e in parameters["g_Pa"]],
        "E_0_Pa": factor * g0,
        "poisson": poisson,
        "note": (f"Young's moduli E = 2 G (1 + nu) at the given Poisson's ratio nu = "
                 f"{poisson:g} (fixed); E_0 = 2 G_0 (1 + nu), G_0 = g_inf + sum g: the "
                 "instantaneous modulus"),
    }


def raw_residual(fit, curve, template, *, max_samples=600):
    """`(time, residual, segment)` of the fitted model against the RAW samples of an
    `AFMCurve` (each segment thinned evenly to at most `max_samples`): one forward
    solve of `fit.material` on the fit's grid, driven by the
    raw force (creep) or depth (relaxation), from an unloaded start at `t = 0` as in
    the fit. `residual` = model - data [N or m]."""
    import jax.numpy as jnp
    import numpy as np

    import jaxcontact as jc

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
    normal = jc.Force(jnp.asarray(f)) if fit.kind == "depth" else jc.Displacement(
        jnp.asarray(d))
    scene = jc.Scene(template.grid, template.indenter, fit.material, jnp.asarray(t),
                     normal)
    sol = jc.solve(scene, scheme="linear", throw=False)
    model = np.asarray(sol.approach if fit.kind == "depth" else sol.normal_force)
    return t, model - (d if fit.kind == "depth" else f), s


def _plot(fit, seg, result, path):
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 6), sharex=True,
                                      gridspec_kw={"height_ratios": [3, 1]})
    unit = "nN" if fit.kind == "force" else "um"
    scale = 1e9 if fit.kind == "force" else 1e6
    for code, (name, colour) in enumerate(zip(("approach", "hold", "retract"),
                                              ("C0", "C1", "C2"), strict=True)):
        sel = seg == code
        if not sel.any():
            continue
        top.plot(fit.times[sel], fit.target[sel] * scale, "o", ms=3, color=colour,
                 label=f"data ({name})")
        bottom.plot(fit.times[sel], fit.residual[sel] * scale, "o", ms=3, color=colour)
    top.plot(fit.times, fit.curve * scale, "k-", lw=1, label="model")
    top.set_ylabel(f"{fit.kind} [{unit}]")
    top.set_title(f"{Path(result['file']).name}: {result['arms']} arm(s), "
                  f"R = {result['radius_m']:g} m", fontsize=9)
    top.legend(fontsize=8)
    bottom.axhline(0, color="k", lw=0.5)
    bottom.set_ylabel(f"residual [{unit}]")
    bottom.set_xlabel("time since contact [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def run_fit(args) -> int:
    """The `fit` subcommand; returns the exit status."""
    try:
        samples, segments = _check(args)
        try:
            import afmformats  # noqa: F401
        except ImportError:
            raise _BadInput('reading AFM files needs afmformats: pip install '
                            '"jaxcontact[afm]"')
        out = Path(args.out)
        stems = _plan_outputs(args.files, out, args.overwrite)
        import jax

        jax.config.update("jax_enable_x64", True)
        # A persistent compilation cache: the Levenberg-Marquardt solve through the
        # contact model's adjoint compiles for tens of seconds; a second run of the
        # same shapes (another file, the same --n and --samples) loads it instead.
        if not (args.no_cache or cache_disabled_by_environment()):
            enable_compilation_cache()
        status = 0
        for path in args.files:
            result, fit, seg = _fit_one(path, args, samples, segments)
            stem = stems[path]
            json_path = out / f"{stem}_fit.json"
            png = _plot(fit, seg, result, out / f"{stem}_fit.png")
            result["plot"] = str(png) if png else None
            json_path.write_text(json.dumps(result, indent=2))
            _print(result, json_path)
            if not result["converged"]:
                status = 1
        return status
    except InputError as exc:
        print(f"jaxcontact: error: {exc}", file=sys.stderr)
        return 2


def _print(r, json_path):
    p = r["parameters"]

    def fmt(e):
        return f"{e['value']:.4g} +- {e['std']:.2g}" if e["std"] is not None else (
            f"{e['value']:.4g} +- inf")

    print(f"{r['file']}: {r['mode']} ({r['fitted']} fitted), {r['arms']} arm(s), "
          f"{r['samples']} samples, grid {r['grid'][0]}^2")
    e = r["youngs_moduli"]
    print(f"  shear moduli g [Pa]; Young's moduli E = 2 g (1 + nu) [Pa] at nu = "
          f"{r['poisson']:g}")
    print(f"  g_inf = {fmt(p['g_inf_Pa'])} Pa   E_inf = {fmt(e['E_inf_Pa'])} Pa")
    for i, (g, tau, y) in enumerate(zip(p["g_Pa"], p["tau_s"], e["E_Pa"], strict=True),
                                    1):
        print(f"  g_{i} = {fmt(g)} Pa   tau_{i} = {fmt(tau)} s   E_{i} = {fmt(y)} Pa")
    print(f"  instantaneous: G_0 = {r['instantaneous_modulus_Pa']:.4g} Pa   "
          f"E_0 = {e['E_0_Pa']:.4g} Pa")
    hold = r["residual_over_noise_hold"]
    print(f"  residual RMS {r['residual_rms']:.3g} = {r['residual_over_noise']:.2f} x "
          f"the noise of the binned data" + (f" (hold: {hold:.2f})" if hold is not None
                                         else "")
          + f" (raw noise {r['noise_raw']:.3g}); converged: {r['converged']}")
    if r["hold_residual_over_noise_raw"] is not None:
        print(f"  hold, raw samples: residual RMS = "
              f"{r['hold_residual_over_noise_raw']:.2f} x the white noise")
    if r["discretisation_rms"] is not None:
        print(f"  discretisation (grid x2): {r['discretisation_rms']:.3g} RMS "
              f"({r['discretisation_rms'] / r['residual_rms']:.2f} x the residual, "
              f"{r['discretisation_rms'] / r['noise_raw']:.2f} x the raw noise)")
        if r["discretisation_rms"] > r["noise_raw"]:
            print("  note: the grid's bias exceeds the raw noise: a finer --n lowers "
                  "it (the creep file: 8.2 x the noise at 16^2, 1.3 x at 32^2, 0.4 x "
                  "at 64^2)")
    if len(r["information_criteria"]) > 1:
        for k, v in r["information_criteria"].items():
            print(f"  {k} arm(s): AIC {v['aic']:.1f}  BIC {v['bic']:.1f}"
                  + ("" if v["converged"] else "  (not converged)"))
    print(f"  note: {RADIUS_NOTE}")
    print(f"  -> {json_path}" + (f", {r['plot']}" if r["plot"] else ""))
