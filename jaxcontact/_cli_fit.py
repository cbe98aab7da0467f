"""`jaxcontact fit FILE|FOLDER... --radius R` (a sphere) or `... --tip cone
--half-angle DEG` (a cone): Prony series fitted to AFM files.

    jaxcontact fit FILE|FOLDER... (--radius R | --tip cone --half-angle DEG)
                   [--arms N|auto] [--out DIR] [--n N]
                   [--poisson NU] [--baseline constant|linear] [--samples A,H,R]
                   [--segments approach,hold,retract] [--steps K]
                   [--contact viscoelastic|piecewise] [--start lee-radok|data]
                   [--tau-range LO,HI|auto|none] [--no-check-grid]
                   [--no-analysis-uncertainty] [--overwrite]
                   [--solver auto|rings|grid] [--rings K]

Each file (a folder: every file in it that afmformats reads) is read by `jc.read_afm`
(afmformats: `pip install "jaxcontact[afm]"`) and fitted by
`jaxcontact.fitting.afm.fit_afm_curve`: the segments binned, `jc.fit_prony` through
the full contact model (a sphere of radius `R` [m], or with `--tip cone` a sharp cone
of half-angle `DEG` degrees, the angle between its axis and its flank; by default on
`K` coaxial rings,
`solve_axisymmetric`, `--solver grid`: on an `N x N` grid) for 1 to 3 arms
(`--arms auto`, the converged fit with no parameter at a bound and the smallest BIC),
the quality judged against the raw data's own noise, and the uncertainty extended by
refits with the contact point moved by its uncertainty and with the model's
discretisation bias (at twice the rings, or on a grid twice as fine) removed
(`jaxcontact.fitting.uncertainty`). Creep files (force clamp) fit the depth
under the measured force; relaxation files (height clamp) the force under the depth.

Writes `DIR/STEM_fit.json` (Young's moduli `E = 2 G (1 + nu)` and shear moduli with
their total standard deviation and its components, `E(t)` at the approach's duration,
the apparent elastic modulus of the approach (Hertz for a sphere, Sneddon for a
cone; the JSON's `apparent_hertz` for both, its `law` says which), the probe (`tip`),
the quality verdict and flags, the contact point as time, height and force, units)
and `DIR/STEM_fit.png` (data, model, residuals, `E(t)`); with several files also
`DIR/fit_summary.csv` (a row a file).
`STEM` is the file's name minus its final extension (`gel.001.jpk-force` ->
`gel.001`); outputs already in `DIR` are refused before any fit unless
`--overwrite`, and so are two files with the same stem.

A file of several curves (a force map: `.jpk-force-map`, `.jpk-qi-data`, ...) goes
through `jc.fit_force_map`: each curve read and fitted as above (a line a curve on
stderr), and written as `DIR/STEM_map.csv` (a row a curve: grid indices, stage
position, quality, flags, E_0, E at the approach's duration, E_inf with their std,
apparent Hertz E, relaxation times, contact time, the flags' text),
`DIR/STEM_map.nc` (the whole `xarray.Dataset`, netCDF by xarray's scipy engine;
skipped, and said, where it cannot write it) and `DIR/STEM_map.png` (maps of E at the
approach's duration, E_inf and the quality; with matplotlib). Force-distance maps
have no hold: the default segments fit their approach alone; `--segments
approach,retract` adds the unloading up to the loss of contact.

Exit status: 0 when every fit is certified (converged) with nothing flagged; 1 when a
fit (a curve of a map included) did not converge, was flagged or could not be made
(the console and the JSON or CSV list the reasons: a systematic misfit, a parameter
at a bound, the grid's bias above the noise, a contact point that could not be
placed, an implausible radius); 2 for bad input (the message names the bad value).

Compiled programs are cached on disk (`jc.enable_compilation_cache`: folder
`JAXCONTACT_CACHE_DIR`, default `~/.cache/jaxcontact/xla`; `--no-cache` or
`JAXCONTACT_NO_CACHE=1`: none), so a second run of the same sizes skips most of the
compilation.

The probe is not in the files: absolute moduli scale as `R^(-1/2)` (a sphere) or
`1 / tan(alpha)` (a cone); relaxation times and modulus ratios do not depend on it.
Every closed-form piece (the contact point, the Lee & Radok start, the apparent
modulus) follows the tip's law, Hertz's `d^(3/2)` or Sneddon's `d^2`. A radius outside
`RADIUS_WINDOW` times the curve's maximum indentation depth warns (`radius_warning`:
most likely a unit slip), and so does a half-angle under 1 degree
(`half_angle_warning`: most likely radians given for degrees).
"""

import argparse
import csv
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
from .fitting.afm import (  # noqa: F401
    RADIUS_NOTE,
    RADIUS_WINDOW,
    half_angle_warning,
    radius_warning,
)


SUMMARY = "fit_summary.csv"


class _BadInput(InputError):
    """Bad input to `jaxcontact fit`: exit status 2, the message names the value."""


def output_stem(path) -> str:
    """The stem of a file's outputs: its name minus the final extension only
    (`gel.001.jpk-force` -> `gel.001`), so numbered files of a series stay apart."""
    return Path(path).stem


def fit_outputs(stem, kind="curve") -> list:
    """The files `jaxcontact fit` writes in `--out` for one input of stem `stem`:
    `kind="curve"` a one-curve file, `"map"` a file of several curves (a force map:
    `_fit_map`)."""
    if kind == "map":
        return [f"{stem}_map.csv", f"{stem}_map.nc", f"{stem}_map.png"]
    return [f"{stem}_fit.json", f"{stem}_fit.png"]


def _plan_outputs(files, out, overwrite, maps=()) -> dict:
    """`{file: stem}` for the inputs, after checking (before any fit) that no two
    files of one kind (`maps`: the force maps among them) share a stem and that
    `out` can take every output (`prepare_out`: created, writable, existing outputs
    refused unless `overwrite`); `InputError` otherwise."""
    stems = {}
    for path in files:
        stem, kind = output_stem(path), "map" if path in maps else "curve"
        twin = next((f for f, s in stems.items()
                     if s == stem and (f in maps) == (path in maps)), None)
        if twin is not None:
            raise _BadInput(f"{twin!r} and {path!r} would both write "
                            f"{fit_outputs(stem, kind)[0]}: fit them into different "
                            "--out folders")
        stems[path] = stem
    names = [name for p, s in stems.items()
             for name in fit_outputs(s, "map" if p in maps else "curve")]
    curves = sum(p not in maps for p in stems)
    prepare_out(out, names + ([SUMMARY] if curves > 1 else []), overwrite)
    return stems


def expand_inputs(paths) -> list:
    """The files to fit: each path as given, a folder replaced by the files in it
    (sorted) whose extension afmformats reads; `InputError` for a missing path or a
    folder without such files."""
    import afmformats

    files = []
    for p in map(Path, paths):
        if p.is_dir():
            found = sorted(f for f in p.iterdir() if f.is_file() and f.suffix.lower()
                           in afmformats.formats.supported_extensions)
            if not found:
                known = ", ".join(afmformats.formats.supported_extensions)
                raise _BadInput(f"the folder {str(p)!r} holds no file afmformats reads "
                                f"({known})")
            files.extend(map(str, found))
        elif p.is_file():
            files.append(str(p))
        else:
            raise _BadInput(f"no such file: {str(p)!r}")
    return files


def add_parser(sub):
    """Register `fit` on the `jaxcontact` subcommand parser `sub`."""
    p = sub.add_parser("fit", help="fit a Prony series to AFM indentation files")
    add_cache_argument(p)
    p.add_argument("files", nargs="+", metavar="FILE",
                   help="force-distance files afmformats reads (e.g. .jpk-force), or "
                        "folders of them")
    p.add_argument("--radius", type=float, default=None,
                   help="the sphere's radius [m] (required with --tip sphere, the "
                        "default)")
    p.add_argument("--tip", default="sphere", choices=("sphere", "cone"),
                   help="the probe: 'sphere' (default; Hertz, --radius) or 'cone' (a "
                        "sharp cone, Sneddon; --half-angle)")
    p.add_argument("--half-angle", type=float, default=None, metavar="DEG",
                   help="the cone's half-angle in DEGREES, the angle between its "
                        "axis and its flank (required with --tip cone; e.g. 20)")
    p.add_argument("--arms", default="auto",
                   help="number of Prony arms (1..8), or 'auto' (default: 1..3, the "
                        "converged fit with no parameter at a bound and the smallest "
                        "BIC)")
    p.add_argument("--out", default="jaxcontact-fit", help="output directory")
    p.add_argument("--overwrite", action="store_true",
                   help="replace outputs of the same name already in --out (default: "
                        "refuse, before any fit)")
    p.add_argument("--n", type=int, default=32,
                   help="grid cells per side with --solver grid (default 32)")
    p.add_argument("--solver", default="auto", choices=("auto", "rings", "grid"),
                   help="the contact model: 'auto' (default) and 'rings' solve the "
                        "sphere or cone on coaxial rings (solve_axisymmetric: the same "
                        "accuracy as the grid in a small fraction of its time); "
                        "'grid' on an N x N grid")
    p.add_argument("--rings", type=int, default=64,
                   help="rings of the ring model (default 64)")
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
                   help="contact point: the piecewise baseline + Hertz (sphere) or "
                        "Sneddon (cone) fit refined by the closed-form viscoelastic "
                        "model (default), or the piecewise fit alone (jc.read_afm's "
                        "contact=)")
    p.add_argument("--check-grid", action=argparse.BooleanOptionalAction, default=True,
                   help="also solve the fitted model at twice the resolution (twice "
                        "the rings, or a grid twice as fine) and report the "
                        "difference (the model's discretisation error; default on)")
    p.add_argument("--tau-range", default="auto", metavar="LO,HI|auto|none",
                   help="bounds on the relaxation times [s]; 'auto' (default): the raw "
                        "sampling step (a faster time is not sampled) to the data's "
                        "duration (a slower one is degenerate with g_inf); 'none'")
    p.add_argument("--analysis-uncertainty", action=argparse.BooleanOptionalAction,
                   default=True,
                   help="add to each standard deviation the parameters' shift when the "
                        "contact point moves by its uncertainty and when the grid's "
                        "bias is removed (three refits from the result; default on)")
    p.add_argument("--steps", type=int, default=200,
                   help="bound on the Levenberg-Marquardt steps (default 200)")
    p.add_argument("--samples", default="8,24,8", metavar="A,H,R",
                   help="points after binning in the approach, hold and retract")
    p.add_argument("--segments", default="approach,hold",
                   help="segments to fit (approach is always needed; default approach,"
                        "hold: the retract's unloading is fitted only when asked)")
    return p


def _check_tip(args):
    """The probe's options: `--radius` for a sphere, `--half-angle` (degrees) for a
    cone, each refused with the other tip; `InputError` naming the option."""
    if args.tip == "sphere":
        if args.half_angle is not None:
            raise _BadInput(f"--half-angle {args.half_angle:g} is a cone's: give --tip "
                            "cone (without --radius), or leave --half-angle out")
        if args.radius is None:
            raise _BadInput("--radius is required for a spherical probe (--tip "
                            "sphere, the default): the sphere's radius [m]; a conical "
                            "probe: --tip cone --half-angle DEG")
        if not math.isfinite(args.radius):
            raise _BadInput("--radius must be a finite number > 0 [m], got "
                            f"{args.radius!r}")
        if args.radius <= 0:
            raise _BadInput(f"--radius must be a finite number > 0 [m]: the probe "
                            f"radius must be positive, got {args.radius!r}")
        return
    if args.radius is not None:
        raise _BadInput(f"--radius {args.radius:g} is a sphere's: a cone (--tip cone) "
                        "takes --half-angle DEG only")
    if args.half_angle is None:
        raise _BadInput("--tip cone needs --half-angle DEG: the cone's half-angle in "
                        "degrees, the angle between its axis and its flank")
    if not (math.isfinite(args.half_angle) and 0 < args.half_angle < 90):
        raise _BadInput(f"--half-angle must be in (0, 90) degrees (the angle between "
                        f"the cone's axis and its flank), got {args.half_angle!r}")


def _check(args):
    _check_tip(args)
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
    if args.rings < 4:
        raise _BadInput(f"--rings must be >= 4, got {args.rings}")
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
        if not Path(f).exists():
            raise _BadInput(f"no such file: {f!r}")
    return samples, segments


def _settings(args, samples, segments):
    from .fitting.afm import AFMFitSettings

    cone = args.tip == "cone"
    return AFMFitSettings(
        radius=None if cone else args.radius, tip=args.tip,
        half_angle=math.radians(args.half_angle) if cone else None,
        arms=args.arms if args.arms == "auto" else int(args.arms),
        n=args.n, poisson=args.poisson, samples=tuple(samples),
        segments=tuple(segments), tau_bounds=args.tau_bounds, start=args.start,
        steps=args.steps, check_grid=args.check_grid,
        analysis_uncertainty=args.analysis_uncertainty, solver=args.solver,
        rings=args.rings)


def _fit_one(path, args, samples, segments):
    """`(report, fit, segment)` of one file (`fit_afm_curve`), the report extended by
    the command's own settings."""
    import jaxcontact as jc
    from jaxcontact.fitting.afm import fit_afm_curve

    settings = _settings(args, samples, segments)
    try:
        curve = jc.read_afm(path, baseline=args.baseline, segments=segments,
                            contact=args.contact, exponent=settings.probe.exponent)
    except (ValueError, TypeError) as exc:
        raise _BadInput(f"{path}: {exc}") from exc
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", UserWarning)
        try:
            result = fit_afm_curve(curve, settings)
        except ValueError as exc:
            raise _BadInput(f"{path}: {exc}") from exc
    for w in caught:  # re-issued with the file's name (one line each, by `main`)
        warnings.warn(f"{path}: {w.message}", w.category, stacklevel=2)
    report = result.report
    report["file"] = str(path)
    report["contact"] = args.contact
    report["start"] = args.start
    hold = report["residual_over_noise_raw"].get("hold")
    report["hold_residual_over_noise_raw"] = hold
    return report, result.fit, result.segment


def _plot(fit, seg, result, path):
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    import numpy as np

    from .fitting.quality import relaxation_modulus

    fig, (top, middle, bottom) = plt.subplots(3, 1, figsize=(7, 8.5),
                                              gridspec_kw={"height_ratios": [3, 1, 2]})
    unit = "nN" if fit.kind == "force" else "um"
    scale = 1e9 if fit.kind == "force" else 1e6
    for code, (name, colour) in enumerate(zip(("approach", "hold", "retract"),
                                              ("C0", "C1", "C2"), strict=True)):
        sel = seg == code
        if not sel.any():
            continue
        top.plot(fit.times[sel], fit.target[sel] * scale, "o", ms=3, color=colour,
                 label=f"data ({name})")
        middle.plot(fit.times[sel], fit.residual[sel] * scale, "o", ms=3,
                    color=colour)
    top.plot(fit.times, fit.curve * scale, "k-", lw=1, label="model")
    top.set_ylabel(f"{fit.kind} [{unit}]")
    q = result["quality"]
    top.set_title(f"{Path(result['file']).name}: {result['arms']} arm(s), "
                  f"{tip_text(result['tip'])}; quality: {q['verdict']}", fontsize=9)
    top.legend(fontsize=8)
    middle.axhline(0, color="k", lw=0.5)
    middle.set_ylabel(f"residual [{unit}]")
    middle.set_xlabel("time since contact [s]")
    # E(t) = 2 (1 + nu) G(t): the fitted relaxation function, with the moduli AFM
    # users compare (the apparent Hertz or Sneddon modulus of the approach, E at its
    # duration).
    e = result["youngs_moduli"]
    factor = 2 * (1 + result["poisson"])
    span = max(float(fit.times[-1]), 1e-9)
    t = np.geomspace(span * 1e-4, span * 10, 200)
    curve = [factor * relaxation_modulus(fit.material, v) for v in t]
    bottom.semilogx(t, curve, "k-", lw=1, label="E(t) = 2 (1 + nu) G(t)")
    bottom.axhline(result["apparent_hertz"]["E_Pa"], color="C3", ls="--", lw=1,
                   label=f"apparent {_law(result)} E (approach)")
    bottom.plot([e["approach_time_s"]], [e["E_at_approach_Pa"]["value"]], "o",
                color="C0", label="E at the approach's duration")
    bottom.set_xlabel("t [s]")
    bottom.set_ylabel("E(t) [Pa]")
    right = bottom.secondary_yaxis("right", functions=(lambda x: x / factor,
                                                       lambda x: x * factor))
    right.set_ylabel("G(t) [Pa]")
    bottom.legend(fontsize=8)
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
        files = expand_inputs(args.files)
        out = Path(args.out)
        maps = force_maps(files)
        stems = _plan_outputs(files, out, args.overwrite, maps)
        import jax

        jax.config.update("jax_enable_x64", True)
        # A persistent compilation cache: the Levenberg-Marquardt solve through the
        # contact model's adjoint compiles for tens of seconds; a second run of the
        # same shapes (another file, the same --n and --samples) loads it instead.
        if not (args.no_cache or cache_disabled_by_environment()):
            enable_compilation_cache()
        status, rows = 0, []
        for path in files:
            if path in maps:  # several curves: a map (`jc.fit_force_map`)
                status = max(status, _fit_map(path, args, samples, segments,
                                              out, stems[path], maps[path]))
                continue
            result, fit, seg = _fit_one(path, args, samples, segments)
            stem = stems[path]
            json_path = out / f"{stem}_fit.json"
            png = _plot(fit, seg, result, out / f"{stem}_fit.png")
            result["plot"] = str(png) if png else None
            json_path.write_text(json.dumps(result, indent=2))
            _print(result, json_path)
            rows.append(summary_row(result))
            if result["flags"]:
                status = 1
        if len(rows) > 1:
            _write_summary(rows, out / SUMMARY,
                           "Sneddon" if args.tip == "cone" else "Hertz")
        return status
    except InputError as exc:
        print(f"jaxcontact: error: {exc}", file=sys.stderr)
        return 2


SUMMARY_COLUMNS = ("file", "mode", "arms", "quality", "flags", "E_0_Pa",
                   "E_at_approach_Pa", "E_at_approach_std_Pa", "E_inf_Pa",
                   "E_inf_std_Pa", "apparent_hertz_E_Pa", "taus_s", "contact_time_s")


def summary_row(r) -> dict:
    """One file's row of `fit_summary.csv` (`SUMMARY_COLUMNS`)."""
    e = r["youngs_moduli"]
    return {
        "file": r["file"], "mode": r["mode"], "arms": r["arms"],
        "quality": r["quality"]["verdict"], "flags": len(r["flags"]),
        "E_0_Pa": e["E_0_Pa"]["value"],
        "E_at_approach_Pa": e["E_at_approach_Pa"]["value"],
        "E_at_approach_std_Pa": e["E_at_approach_Pa"]["std"],
        "E_inf_Pa": e["E_inf_Pa"]["value"], "E_inf_std_Pa": e["E_inf_Pa"]["std"],
        "apparent_hertz_E_Pa": r["apparent_hertz"]["E_Pa"],
        "taus_s": " ".join(f"{t['value']:.4g}" for t in r["parameters"]["tau_s"]),
        "contact_time_s": r["contact_point"]["time_s"],
    }


def _write_summary(rows, path, law="Hertz"):
    with open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=SUMMARY_COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    print(f"{len(rows)} files: summary -> {path}")
    print(f"  {'file':<44} {'quality':<18} {'E_0':>9} {'E(T_app)':>9} {'E_inf':>9} "
          f"{law + ' E':>9}  flags")
    for row in rows:
        print(f"  {Path(row['file']).name[:44]:<44} {row['quality']:<18} "
              f"{row['E_0_Pa']:>9.4g} {row['E_at_approach_Pa']:>9.4g} "
              f"{row['E_inf_Pa']:>9.4g} {row['apparent_hertz_E_Pa']:>9.4g}  "
              f"{row['flags']}")


def _fmt(e):
    return (f"{e['value']:.4g} +- {e['std']:.2g}" if e["std"] is not None
            else f"{e['value']:.4g} +- inf")


def tip_text(tip) -> str:
    """The probe of a report's `tip` (or a map's attributes: `tip`, `radius_m` or
    `half_angle_rad`) in a few words: `R = 5e-06 m` or `cone 20 deg`."""
    shape = tip.get("shape", tip.get("tip", "sphere"))
    if shape == "sphere":
        return f"R = {tip['radius_m']:g} m"
    return f"cone {math.degrees(tip['half_angle_rad']):.4g} deg"


def _law(r) -> str:
    """`Hertz` or `Sneddon`: the apparent modulus's law of a report."""
    return r["apparent_hertz"].get("law", "Hertz")


def _model_text(r) -> str:
    """The contact model of a report: `64 rings over 2.1e-06 m` or `grid 32^2`."""
    if r.get("rings"):
        return f"{r['rings']['rings']} rings over {r['rings']['radius_m']:.3g} m"
    return f"grid {r['grid'][0]}^2"


def _print(r, json_path):
    p, e = r["parameters"], r["youngs_moduli"]
    auto = len(r["information_criteria"]) > 1
    print(f"{r['file']}: {r['mode']} ({r['fitted']} fitted), {r['arms']} arm(s)"
          + (" (BIC among " + ", ".join(r["information_criteria"]) + ")" if auto
             else "") + f", {r['samples']} samples, " + _model_text(r))
    q = r["quality"]
    print(f"  quality: {q['verdict']}: model - data over the raw noise, "
          + ", ".join(f"{k} {v:.2f} x" for k, v in q["by_segment"].items())
          + f" (good: <= {q['limit']:g})")
    print(f"  Young's moduli E = 2 g (1 + nu) [Pa] at nu = {r['poisson']:g}; +- total "
          "std (optimiser" + (", contact point, grid" if r["uncertainty"] else "")
          + ")")
    print(f"  E at the approach's duration ({e['approach_time_s']:.3g} s) = "
          f"{_fmt(e['E_at_approach_Pa'])} Pa   apparent {_law(r)} E (approach) = "
          f"{r['apparent_hertz']['E_Pa']:.4g} Pa")
    print(f"  E_inf = {_fmt(e['E_inf_Pa'])} Pa   E_0 = {_fmt(e['E_0_Pa'])} Pa")
    for i, (g, tau, y) in enumerate(zip(p["g_Pa"], p["tau_s"], e["E_Pa"], strict=True),
                                    1):
        print(f"  E_{i} = {_fmt(y)} Pa   tau_{i} = {_fmt(tau)} s   (g_{i} = "
              f"{g['value']:.4g} Pa)")
    print(f"  shear moduli: g_inf = {_fmt(p['g_inf_Pa'])} Pa, G_0 = "
          f"{r['instantaneous_modulus_Pa']:.4g} Pa")
    c = r["contact_point"]
    unc = (r["uncertainty"] or {}).get("components", {}).get("contact")
    print(f"  contact point: t = {c['time_s']:.4g} s, height {c['height_m']:.5g} m, "
          f"force {c['force_N']:.3g} N ({c['note']})"
          + (f"; uncertainty +- {unc['samples']} samples ({unc['time_s']:.3g} s)"
             if unc else ""))
    disc = r["discretisation_over_noise"]
    print(f"  raw noise {r['noise_raw']:.3g}"
          + (f"; discretisation bias ({'rings' if r.get('rings') else 'grid'} "
             f"x2) {disc:.2f} x the noise" if disc is not None else "")
          + f"; converged: {r['converged']}")
    for text in r["caveats"]:
        print(f"  caveat: {text}")
    if r["flags"]:
        print("  flagged (exit status 1):")
        for text in r["flags"]:
            print(f"    - {text}")
    else:
        print("  nothing flagged")
    print(f"  note: {r['tip_note']}")
    print(f"  -> {json_path}" + (f", {r['plot']}" if r["plot"] else ""))


# --------------------------------------------------------------------------------------
# Files of several curves (force maps): `jc.fit_force_map`.


MAP_COLUMNS = ("x", "y", "position_x_m", "position_y_m", "quality", "flags",
               "converged", "arms", "E_0_Pa", "E_0_std_Pa", "E_at_approach_Pa",
               "E_at_approach_std_Pa", "approach_time_s", "E_inf_Pa", "E_inf_std_Pa",
               "apparent_hertz_E_Pa", "taus_s", "contact_time_s", "flag_text")


def force_maps(files) -> dict:
    """`{file: number of curves}` of the files among `files` that hold more than one
    curve (afmformats): fitted as force maps. A file afmformats cannot read is left
    to the one-curve path, whose error names it."""
    import afmformats

    missing = getattr(afmformats.errors, "MissingMetaDataError", Exception)
    maps = {}
    for path in files:
        with warnings.catch_warnings():  # read_afm warns again when it reads it
            warnings.simplefilter("ignore")
            try:
                count = len(afmformats.load_data(path))
            except (Exception, missing):
                continue
        if count > 1:
            maps[path] = count
    return maps


def map_rows(ds) -> list:
    """The rows of `STEM_map.csv` (`MAP_COLUMNS`): a row a curve of the map `ds`
    (`jc.fit_force_map`), in (y, x) order; numbers in SI units, NaN where absent."""
    from ._force_map import QUALITY_NO_CURVE

    rows = []
    for j, y in enumerate(ds.y.values):
        for i, x in enumerate(ds.x.values):
            cell = ds.isel(y=j, x=i)
            if str(cell.quality.values) == QUALITY_NO_CURVE:
                continue
            taus = cell.tau.values[: int(cell.arms)]
            rows.append({
                "x": int(x), "y": int(y),
                "position_x_m": float(cell.position_x),
                "position_y_m": float(cell.position_y),
                "quality": str(cell.quality.values), "flags": int(cell.flags),
                "converged": bool(cell.converged), "arms": int(cell.arms),
                "E_0_Pa": float(cell.E_0), "E_0_std_Pa": float(cell.E_0_std),
                "E_at_approach_Pa": float(cell.E_at_approach),
                "E_at_approach_std_Pa": float(cell.E_at_approach_std),
                "approach_time_s": float(cell.approach_time),
                "E_inf_Pa": float(cell.E_inf), "E_inf_std_Pa": float(cell.E_inf_std),
                "apparent_hertz_E_Pa": float(cell.apparent_hertz_E),
                "taus_s": " ".join(f"{t:.6g}" for t in taus),
                "contact_time_s": float(cell.contact_time),
                "flag_text": str(cell.flag_text.values)})
    return rows


def _fit_map(path, args, samples, segments, out, stem, count) -> int:
    """Fit the force map `path` (`jc.fit_force_map`, progress on stderr) and write
    `STEM_map.csv`, `STEM_map.nc` (xarray's scipy engine: skipped, and said, where
    it cannot write netCDF) and `STEM_map.png` (with matplotlib). Returns the exit
    status: 1 when a curve is flagged or not fitted, else 0."""
    import jaxcontact as jc

    print(f"{path}: {count} curves, a force map (jc.fit_force_map; a line a curve "
          "on stderr)", flush=True)
    settings = _settings(args, samples, segments)
    try:
        ds = jc.fit_force_map(path, settings=settings,
                              baseline=args.baseline, contact=args.contact)
    except ValueError as exc:
        raise _BadInput(f"{path}: {exc}") from exc
    written = []
    csv_path = out / f"{stem}_map.csv"
    rows = map_rows(ds)
    with open(csv_path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=MAP_COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    written.append(str(csv_path))
    nc = out / f"{stem}_map.nc"
    try:
        ds.to_netcdf(nc, engine="scipy")
        written.append(str(nc))
    except (ImportError, ValueError, TypeError) as exc:
        nc.unlink(missing_ok=True)  # no partial or stale file
        print(f"  {nc.name} not written: xarray cannot write netCDF here ({exc})")
    png = _plot_map(ds, out / f"{stem}_map.png", Path(path).name)
    if png is None:
        (out / f"{stem}_map.png").unlink(missing_ok=True)
        print(f"  {stem}_map.png not written: matplotlib is not installed")
    else:
        written.append(str(png))
    _print_map(ds, rows)
    print(f"  note: {settings.probe.scaling_note()}")
    print("  -> " + ", ".join(written))
    return 1 if any(r["flags"] for r in rows) else 0


def _print_map(ds, rows):
    import numpy as np

    flagged = [r for r in rows if r["flags"]]
    a = ds.attrs
    print(f"  force map: {len(rows)} curves on a {ds.sizes['y']} x {ds.sizes['x']} "
          f"grid (grid indices y {int(ds.y.min())}..{int(ds.y.max())}, x "
          f"{int(ds.x.min())}..{int(ds.x.max())}), {a['curve_mode']}, segments "
          f"{a['segments']}, grid {a['n']}^2, {tip_text(a)}, nu = "
          f"{a['poisson']:g}")
    for key, label in (("E_at_approach", "E at the approach's duration"),
                       ("E_inf", "E_inf"),
                       ("apparent_hertz_E", "apparent "
                        + ("Hertz" if a.get("tip", "sphere") == "sphere"
                           else "Sneddon") + " E")):
        v = np.asarray(ds[key].values, float)
        v = v[np.isfinite(v)]
        if v.size:
            print(f"  {label}: median {np.median(v):.4g} Pa, range {v.min():.4g} .. "
                  f"{v.max():.4g} Pa")
    verdicts = {}
    for r in rows:
        verdicts[r["quality"]] = verdicts.get(r["quality"], 0) + 1
    print("  quality: " + ", ".join(f"{k} {v}" for k, v in sorted(verdicts.items()))
          + f"; {len(flagged)} of {len(rows)} curves flagged"
          + (" (exit status 1; the reasons in the CSV's flag_text)" if flagged
             else ""))


def _plot_map(ds, path, title):
    """Maps of E at the approach's duration, E_inf and the quality; None without
    matplotlib."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from matplotlib.colors import ListedColormap
        from matplotlib.ticker import MaxNLocator
    except ImportError:
        return None
    import numpy as np

    quality = np.asarray(ds.quality.values).astype(str)
    flags = np.asarray(ds.flags.values)
    code = np.full(quality.shape, np.nan)
    labels = ("good", "good, flagged", "systematic misfit", "not fitted")
    code[(quality == "good") & (flags == 0)] = 0
    code[(quality == "good") & (flags > 0)] = 1
    code[quality == "systematic misfit"] = 2
    code[quality == "not fitted"] = 3
    extent = (float(ds.x.min()) - 0.5, float(ds.x.max()) + 0.5,
              float(ds.y.min()) - 0.5, float(ds.y.max()) + 0.5)
    fig, axes = plt.subplots(1, 3, figsize=(13, 4))
    for ax, key, label in ((axes[0], "E_at_approach", "E(T) at the approach's duration "
                                                      "[Pa]"),
                           (axes[1], "E_inf", "E_inf [Pa]")):
        img = ax.imshow(np.asarray(ds[key].values, float), origin="lower",
                        extent=extent, interpolation="nearest", aspect="equal")
        fig.colorbar(img, ax=ax, shrink=0.8, label="Pa")
        ax.set_title(label, fontsize=9)
    cmap = ListedColormap(["tab:green", "gold", "tab:orange", "tab:red"])
    img = axes[2].imshow(code, origin="lower", extent=extent, interpolation="nearest",
                         aspect="equal", cmap=cmap, vmin=-0.5, vmax=3.5)
    bar = fig.colorbar(img, ax=axes[2], shrink=0.8, ticks=range(4))
    bar.ax.set_yticklabels(labels, fontsize=8)
    axes[2].set_title("quality (blank: no curve)", fontsize=9)
    for ax in axes:
        ax.set_xlabel("grid index x")
        ax.set_ylabel("grid index y")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    fig.suptitle(f"{title}: {tip_text(ds.attrs)}, nu = "
                 f"{ds.attrs['poisson']:g}, {ds.attrs['curve_mode']}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
