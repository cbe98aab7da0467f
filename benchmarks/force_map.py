"""`jc.fit_force_map` on the committed force map at `jaxcontact fit`'s defaults: seconds
per curve, the first with compilation, the rest reusing (or not) its programs.

The map: `tests/data/fmt-jpk-fd_2020.02.07-16.29.05.036.jpk-qi-data` (4 curves of a
JPK QI map, force-distance, no hold; see tests/data/README.md), radius 5 um (an
input), the settings `AFMFitSettings(radius=5e-6)` = the command line's defaults
(64 rings, `--solver grid`: the 32^2 grid; 8 approach bins, 1..3 arms by BIC, tau
bounded to what the data resolve, the discretisation check and the analysis refits;
default segments: approach and hold, i.e. the approach alone here), float64, no
persistent compilation cache (every program compiles in this process).

Two passes over the map in one process: the first (cold: the first curve compiles
the pipeline's programs; a later curve compiles what its own shapes or optimiser
path need) and the second (warm: everything compiled; the steady cost of a curve).
Each curve's compilations are counted from JAX's compile log
(`jax_log_compiles`): number and seconds, by program.

`--tile N`: the whole of `jc.fit_force_map` (reading, every fit, compilation
included, the map's Dataset) timed on an N x N map made of the 4 curves, each copy
with its own white noise added to the force (half the curve's own noise, from its
first 100 samples: distinct curves of one shape); `--workers W` fits it on a local
Dask cluster of W one-thread worker processes (`client=`). Writes
`<machine>_tile<N>[_workers<W>].json`.

Usage::

    python benchmarks/force_map.py [--passes 2] [--tiny] [--solver auto|rings|grid]
    python benchmarks/force_map.py --tile 16 [--workers 2]

Writes `benchmarks/results/force_map/<machine>.json` (`--tiny`: `<machine>_tiny.json`,
`--solver grid`: `<machine>_grid.json`;
layout: `results/SCHEMA.md`: a row per
pass and curve, with the stages' seconds: the fits for each arm count, the analysis
refits, the grid check, the raw residual).
"""

import argparse
import collections
import json
import logging
import os
import re
import sys
import time
from pathlib import Path

import numpy as np


sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import ROOT, header, write_results  # noqa: E402


MAP = ROOT / "tests" / "data" / "fmt-jpk-fd_2020.02.07-16.29.05.036.jpk-qi-data"
RADIUS = 5e-6
_FINISHED = re.compile(r"Finished XLA compilation of (.+?) in ([0-9.eE+-]+) s")


class CompileLog(logging.Handler):
    """Collects JAX's "Finished XLA compilation of NAME in S s" records."""

    def __init__(self):
        super().__init__(logging.DEBUG)
        self.records = []

    def emit(self, record):
        m = _FINISHED.search(record.getMessage())
        if m:
            self.records.append((m.group(1), float(m.group(2))))

    def take(self) -> dict:
        out, self.records = self.records, []
        by_program = collections.Counter()
        for name, seconds in out:
            by_program[name] += seconds
        return {"count": len(out), "seconds": round(sum(s for _, s in out), 3),
                "top": [[k, round(v, 3)] for k, v in by_program.most_common(6)]}


class StageTimes:
    """Wall seconds of the pipeline's stages inside `fit_afm_curve` (wrappers that
    only time: the fits for each arm count, the analysis refits, the grid check, the
    raw residual)."""

    def __init__(self):
        from jaxcontact.fitting import afm

        self.seconds = collections.Counter()
        fit, disc = afm._Problem.fit, afm._Problem.grid_bias
        raw, unc = afm.raw_residual, afm.analysis_uncertainty
        depth = [0]  # the refits inside analysis_uncertainty are counted there

        def timed(fn, label):
            def wrapper(*args, **kwargs):
                depth[0] += 1
                t = time.perf_counter()
                try:
                    return fn(*args, **kwargs)
                finally:
                    depth[0] -= 1
                    if depth[0] == 0:
                        name = label(args) if callable(label) else label
                        self.seconds[name] += time.perf_counter() - t
            return wrapper

        afm._Problem.fit = timed(fit, lambda a: f"fit_arms{a[1]}_s")
        afm._Problem.grid_bias = timed(disc, "discretisation_check_s")
        afm.raw_residual = timed(raw, "raw_residual_s")
        afm.analysis_uncertainty = timed(unc, "analysis_refits_s")

    def take(self) -> dict:
        out = {k: round(v, 3) for k, v in sorted(self.seconds.items())}
        self.seconds.clear()
        return out


def tiled_curves(raw, n: int, seed: int = 0) -> list:
    """An `n` x `n` map of copies of the afmformats curves `raw` (in turn), each
    copy's force with its own white noise of half the curve's noise (the std of the
    first 100 samples' differences / sqrt 2), at grid index (x, y)."""
    import copy

    rng = np.random.default_rng(seed)
    out = []
    for k in range(n * n):
        curve = copy.deepcopy(raw[k % len(raw)])
        force = np.asarray(curve["force"], float)
        noise = float(np.std(np.diff(force[:100]))) / np.sqrt(2)
        curve["force"] = force + 0.5 * noise * rng.standard_normal(force.shape)
        # afmformats exposes its metadata as a copy: the grid index set in place
        curve._metadata["grid index x"], curve._metadata["grid index y"] = k % n, k // n
        out.append(curve)
    return out


def _tile_summary(row: dict) -> dict:
    """The measured map's minutes and seconds a curve (no extrapolation: the
    compilation does not scale with the curves)."""
    return {"wall_per_curve_s": row["wall_per_curve_s"],
            "wall_min": round(row["wall_s"] / 60, 1)}


def tiled_map(args):
    """`--tile N`: `jc.fit_force_map` on an N x N tiled map, timed whole."""
    import warnings

    import afmformats
    import jax

    jax.config.update("jax_enable_x64", True)
    import jaxcontact as jc

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        raw = afmformats.load_data(str(MAP))
    curves = tiled_curves(raw, args.tile)
    settings = jc.AFMFitSettings(radius=RADIUS, solver=args.solver)
    client = cluster = None
    if args.workers:
        from dask.distributed import Client, LocalCluster

        cluster = LocalCluster(n_workers=args.workers, threads_per_worker=1,
                               processes=True, dashboard_address=None)
        client = Client(cluster)
    load_before = os.getloadavg()
    t0, cpu0 = time.perf_counter(), time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ds = jc.fit_force_map(curves, settings=settings, client=client,
                              progress=False)
    wall, cpu = time.perf_counter() - t0, time.process_time() - cpu0
    if client is not None:
        client.close()
        cluster.close()
    quality = {str(q): int((ds.quality == q).sum()) for q in np.unique(ds.quality)}
    seconds = np.asarray(ds.seconds, float).ravel()
    row = {"map": f"{args.tile}x{args.tile}", "curves": len(curves),
           "workers": args.workers or 0, "wall_s": round(wall, 1),
           "wall_per_curve_s": round(wall / len(curves), 3),
           "main_process_cpu_s": round(cpu, 1),
           "fit_s_median": round(float(np.nanmedian(seconds)), 3),
           "fit_s_max": round(float(np.nanmax(seconds)), 3),
           "fitted": int(ds.attrs["fitted"]), "flagged": int(ds.attrs["flagged"]),
           "converged": int(np.asarray(ds.converged).sum()), "quality": quality,
           "load_average_1min": round(os.getloadavg()[0], 2)}
    summary = _tile_summary(row)
    variant = f"tile{args.tile}" + (f"_workers{args.workers}" if args.workers else "")
    result = {**header("force_map", variant=variant),
              "settings": {"map": str(MAP.relative_to(ROOT)), "tile": args.tile,
                           "added_noise": "0.5 x each curve's own, seed 0",
                           "workers": args.workers or 0,
                           **json.loads(json.dumps(vars(settings), default=list)),
                           "x64": True, "persistent_cache": False,
                           "versions_extra": {"afmformats": afmformats.__version__}},
              "rows": [row], "summary": summary,
              "notes": ["wall_s: the whole jc.fit_force_map call in a fresh process "
                        "(every compilation included); fit_s: each curve's fit as "
                        "the Dataset's `seconds` records it"]}
    result["machine"]["load_average_before"] = list(load_before)
    path = write_results(result)
    print(json.dumps(row, indent=1))
    print(f"-> {path}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--passes", type=int, default=2)
    ap.add_argument("--solver", default="auto", choices=("auto", "rings", "grid"),
                    help="the contact model (AFMFitSettings.solver; default auto: "
                         "the rings); 'grid' writes <machine>_grid.json")
    ap.add_argument("--tiny", action="store_true",
                    help="tests/test_force_map.py's tiny settings (8^2, 8 approach "
                         "bins, 1 arm, no refits, no grid check) instead of the "
                         "command line's defaults; writes <machine>_tiny.json")
    ap.add_argument("--tile", type=int, default=0,
                    help="time jc.fit_force_map whole on an N x N map tiled from the "
                         "4 curves (each copy with its own added noise)")
    ap.add_argument("--workers", type=int, default=0,
                    help="with --tile: a local Dask cluster of this many one-thread "
                         "worker processes")
    args = ap.parse_args()
    if args.tile:
        return tiled_map(args)

    import warnings

    import afmformats
    import jax

    jax.config.update("jax_enable_x64", True)
    jax.config.update("jax_log_compiles", True)
    log = CompileLog()
    jax_logger = logging.getLogger("jax")
    jax_logger.addHandler(log)
    jax_logger.setLevel(logging.DEBUG)
    jax_logger.propagate = False  # not on the console

    import jaxcontact as jc
    from jaxcontact._force_map import _cell_values, fit_cell

    settings = (jc.AFMFitSettings(radius=RADIUS, n=8, samples=(8, 8, 4), arms=1,
                                  analysis_uncertainty=False, check_grid=False,
                                  solver=args.solver)
                if args.tiny else jc.AFMFitSettings(radius=RADIUS, solver=args.solver))
    variant = "_".join(v for v in ("tiny" if args.tiny else "",
                                   "grid" if args.solver == "grid" else "") if v)
    stages = StageTimes()
    load_before = os.getloadavg()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        raw = afmformats.load_data(str(MAP))
    rows = []
    for p in range(args.passes):
        for k, c in enumerate(raw):
            t0 = time.perf_counter()
            curve = jc.read_afm(c, contact="viscoelastic", segments=settings.segments)
            t_read = time.perf_counter() - t0
            log.take()
            stages.take()
            cpu0 = time.process_time()
            result = fit_cell(curve, settings)
            cpu = time.process_time() - cpu0
            compiles = log.take()
            row = {"pass": "cold" if p == 0 else "warm", "curve": k,
                   "x": int(c.metadata["grid index x"]),
                   "y": int(c.metadata["grid index y"]),
                   "raw_samples_in_contact": int(curve.time.size),
                   "solver": (result["report"] or {}).get("solver"),
                   "read_s": round(t_read, 3), "fit_s": round(result["seconds"], 3),
                   "cpu_s": round(cpu, 3),
                   "load_average_1min": round(os.getloadavg()[0], 2),
                   "compilations": compiles["count"],
                   "compile_s": compiles["seconds"],
                   "compile_top": "; ".join(f"{n} {t:.1f} s"
                                            for n, t in compiles["top"][:4]),
                   **stages.take()}
            if result["report"] is not None:
                r = result["report"]
                v = _cell_values(r)
                row.update(
                    samples=r["samples"], arms=v["arms"], quality=v["quality"],
                    flags=len(r["flags"]), converged=v["converged"],
                    E_0_Pa=v["E_0"], E_at_approach_Pa=v["E_at_approach"],
                    E_inf_Pa=v["E_inf"], apparent_hertz_E_Pa=v["apparent_hertz_E"],
                    taus_s=" ".join(f"{t:.4g}" for t in v["tau"]),
                    residual_over_noise=v["residual_over_noise"],
                    arms_at_a_bound=" ".join(
                        a for a, ic in r["information_criteria"].items()
                        if ic.get("at_bounds")),
                    arms_not_converged=" ".join(
                        a for a, ic in r["information_criteria"].items()
                        if not ic.get("converged", True)),
                    arms_failed=" ".join(
                        a for a, ic in r["information_criteria"].items()
                        if "error" in ic),
                    flag_text="; ".join(r["flags"]))
            else:
                row.update(quality="not fitted", flags=1, error=result["error"])
            print(f"{row['pass']} curve {k}: fit {row['fit_s']:.1f} s (CPU "
                  f"{row['cpu_s']:.1f} s), {row['compilations']} compilations "
                  f"{row['compile_s']:.1f} s ({row['compile_top']}), "
                  f"{row['quality']}, E(T) "
                  f"{row.get('E_at_approach_Pa', float('nan')):.4g} Pa, "
                  f"{row['flags']} flag(s)", flush=True)
            rows.append(row)

    cold = [r["fit_s"] for r in rows if r["pass"] == "cold"]
    warm = [r["fit_s"] for r in rows if r["pass"] == "warm"]
    summary = {"curves": len(raw), "cold_first_curve_s": cold[0],
               "cold_later_curves_s": cold[1:], "cold_total_s": round(sum(cold), 3)}
    notes = ["wall seconds on a shared machine: compare machine.load_average and "
             "each row's load_average_1min with the cores; cpu_s is this process's "
             "CPU time (all its threads), less sensitive to other processes",
             "compile_s counts XLA's compilation only (jax_log_compiles), not the "
             "tracing and lowering before it"]
    if warm:
        per_curve = float(np.mean(warm))
        summary.update({
            "warm_mean_s": round(per_curve, 3),
            "extrapolated_64x64_h": round(64 * 64 * per_curve / 3600, 1),
            "extrapolated_64x64_note": (
                "an extrapolation, not a measurement: 4096 x the warm mean per curve "
                "of these 4 curves, on this CPU, one process, no Dask; the "
                "compilation (here cold total - 4 x warm mean) comes on top once, and "
                "again for every bin count or optimiser path not seen before (the "
                "raw residual is solved at a power-of-two length)")})
    result = {**header("force_map", variant=variant or None),
              "settings": {"map": str(MAP.relative_to(ROOT)),
                           **json.loads(json.dumps(vars(settings), default=list)),
                           "contact": "viscoelastic", "baseline": "constant",
                           "x64": True, "persistent_cache": False,
                           "passes": args.passes,
                           "versions_extra": {"afmformats": afmformats.__version__}},
              "rows": rows, "summary": summary, "notes": notes}
    result["machine"]["load_average_before"] = list(load_before)
    path = write_results(result)
    print(json.dumps(summary, indent=1))
    print(f"-> {path}")


if __name__ == "__main__":
    main()
