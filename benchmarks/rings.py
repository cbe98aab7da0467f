"""The ring solver against the grid solver: the run time of a solve at its error, and
of a fit after compilation (issue 48, items 3 and 5).

Three parts, float64, one process (a second call of a case reuses the first's
compiled programs):

- `solvers`: one viscoelastic history (`solver_rows`: Zener, a displacement ramp
  then hold, 40 steps, scheme "linear") for a sphere and a cone, solved on 16..512
  rings and on 32^2..256^2 grids: the compiled solve's seconds and its largest
  relative force error against 2048 rings.
- `synthetic`: `jc.fit_prony` of the PMMA step of `benchmarks/fit.py` (sphere
  R = 3.5 mm, 2 arms, 20 um held 500 s, 40 times, scheme "constant"), its force made
  on 512 rings (the reference: 1e-6 of the force) plus `--noise` relative white
  noise, fitted from the default start with the default optimiser by the ring model
  (`--rings`, `FitOptions(solver="rings")`) and by the grid (`--grids`, 1.28 mm wide).
  Reported: the fit with compilation and compiled, its steps, the largest relative
  parameter error against the truth.
- `real`: `fit_afm_curve` (the whole `jaxcontact fit` pipeline: arms 1..3, the
  discretisation check, the analysis refits) on the two committed JPK files at the
  command line's defaults (R = 5 um), on rings and (`--grid-real`) on the 32^2 grid:
  the first call (compilation) and the second (compiled), the verdict and E(T).

    python benchmarks/rings.py [--parts solvers,synthetic,real] [--rings 64]
                               [--grids 32,64] [--grid-real]

Writes `benchmarks/results/rings/<machine>.json` (layout: `results/SCHEMA.md`; rows
tagged by `part`). The machine is shared: the load average is recorded with each
row.
"""

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

import jax


jax.config.update("jax_enable_x64", True)
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import jaxcontact as jc  # noqa: E402


sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import ROOT, header, part_rows, write_results  # noqa: E402
from fit import NU, R, params, pmma  # noqa: E402


FILES = {"creep": ROOT / "tests" / "data"
         / "fmt-jpk-cc_pr14-polymergel-2021.06.30.jpk-force",
         "relaxation": ROOT / "tests" / "data" / "fmt-jpk-sr_cell1-0008.jpk-force"}


def load() -> float:
    return round(os.getloadavg()[0], 2)


def synthetic(solver, size, noise, nt=40, seed=0):
    """One row: `jc.fit_prony` of the PMMA step on `size` rings or `size^2` cells."""
    from jaxcontact._solve_rings import solve_axisymmetric

    grid = jc.Grid((64, 64), 1280e-6)
    times = jnp.concatenate([jnp.zeros(1), jnp.geomspace(0.5, 500.0, nt - 1)])
    delta = jnp.where(times > 0, 20e-6, 0.0)
    truth = pmma()
    scene = jc.Scene(grid, jc.Sphere(R), truth, times, normal=jc.Displacement(delta))
    force = np.asarray(solve_axisymmetric(scene, rings=512, radius=320e-6)
                       .normal_force)
    rng = np.random.default_rng(seed)
    force = force * (1 + noise * rng.standard_normal(force.shape))
    data = jc.IndentationData(times, force=force, depth=delta)
    fit_grid = jc.Grid((size, size), 1280e-6) if solver == "grid" else grid
    template = jc.Scene(fit_grid, jc.Sphere(R), jc.Elastic(1e9, NU), times,
                        normal=jc.Displacement(delta))
    # the bias check of a 64^2 fit solves 128^2: minutes here, so from 32^2 only
    options = jc.FitOptions(solver=solver, rings=size if solver == "rings" else 64,
                            solve_options={"scheme": "constant"},
                            check_grid=solver == "rings" or size <= 32)
    start = time.perf_counter()
    jc.fit_prony(data, template, 2, options=options)
    cold = time.perf_counter() - start
    start = time.perf_counter()
    fit = jc.fit_prony(data, template, 2, options=options)
    warm = time.perf_counter() - start
    err = params(fit.material) / params(truth) - 1
    return {"solver": solver, "size": size, "nt": nt, "noise": noise,
            "fit_s_including_compile": round(cold, 3), "fit_s_compiled": round(warm, 3),
            "load_average_1min": load(), "optimiser": fit.optimiser,
            "lm_steps": int(fit.lm_steps), "lbfgs_steps": int(fit.lbfgs_steps),
            "evaluations": int(fit.evaluations), "converged": bool(fit.converged),
            "max_relative_error": float(np.max(np.abs(err))),
            "relative_errors": err.tolist(),
            "discretisation_over_noise": (None if fit.discretisation is None else
                                          float(fit.discretisation / fit.noise)),
            "ring_radius_m": fit.ring_radius}


def _timed(fn):
    """`(result, seconds of the compiled call)`: the first call compiles, the median
    of three more is the time."""
    out = jax.block_until_ready(fn())
    times = []
    for _ in range(3):
        start = time.perf_counter()
        jax.block_until_ready(fn())
        times.append(time.perf_counter() - start)
    return out, float(np.median(times))


def solver_rows(tip, ring_counts, grid_sizes, nt=40):
    """Run time against error of the ring and grid solvers on one history: a Zener
    body (relaxation 3:1, tau = half the run) indented by `tip` ("sphere" R = 1 or
    "cone" of half-angle 70 deg) along a displacement ramp over half the run, then
    held (the contact radius never shrinks), scheme "linear", float64. The errors:
    the largest relative force error over the steps whose force is above 1e-3 of
    the peak (the first steps of the ramp: a contact of a few cells or rings) and
    the last step's, against the same history on 2048 rings (its own error, second
    order, is ~1e-7 of the force);
    the grid is 2 x 1.25 the final contact radius wide, the rings cover half that
    width."""
    from jaxcontact._solve_rings import solve_axisymmetric

    material = jc.Zener(mu_inf=1.0, mu_0=0.5, tau=0.5, poisson=0.3)
    times = jnp.linspace(0.0, 1.0, nt)
    depth = 0.02 * jnp.minimum(times / 0.5, 1.0)
    if tip == "sphere":
        indenter, contact = jc.Sphere(1.0), float(np.sqrt(0.02))
    else:
        alpha = np.deg2rad(70.0)
        indenter, contact = jc.Cone(alpha), float(2 * 0.02 * np.tan(alpha) / np.pi)
    side = 2 * 1.25 * contact

    def scene(n):
        return jc.Scene(jc.Grid((n, n), side), indenter, material, times,
                        normal=jc.Displacement(depth))

    ref = np.asarray(solve_axisymmetric(scene(16), rings=2048, scheme="linear")
                     .normal_force)
    used = ref > 1e-3 * ref.max()
    rows = []
    for solver, sizes in (("rings", ring_counts), ("grid", grid_sizes)):
        for n in sizes:
            if solver == "rings":
                run = jax.jit(lambda n=n: solve_axisymmetric(
                    scene(16), rings=n, scheme="linear").normal_force)
            else:
                run = jax.jit(lambda n=n: jc.solve(scene(n), solver=jc.Rounds(),
                                                   scheme="linear").normal_force)
            force, seconds = _timed(run)
            rel = np.abs(np.asarray(force)[used] / ref[used] - 1)
            rows.append({"tip": tip, "solver": solver, "size": int(n), "nt": nt,
                         "max_relative_force_error": float(rel.max()),
                         "final_relative_force_error": float(rel[-1]),
                         "solve_s_compiled": round(seconds, 5),
                         "load_average_1min": load()})
            print(rows[-1], flush=True)
    return rows


def real(name, solver, rings):
    """One row: `fit_afm_curve` of a committed file, twice (cold, compiled)."""
    from jaxcontact.fitting.afm import AFMFitSettings, fit_afm_curve

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        curve = jc.read_afm(str(FILES[name]), segments=("approach", "hold"),
                           contact="viscoelastic")  # as `jaxcontact fit` reads
    settings = AFMFitSettings(radius=5e-6, solver=solver, rings=rings)
    seconds = []
    for _ in range(2):
        start = time.perf_counter()
        result = fit_afm_curve(curve, settings)
        seconds.append(time.perf_counter() - start)
    r = result.report
    e = r["youngs_moduli"]
    return {"file": name, "solver": solver,
            "model": r["rings"] if solver == "rings" else r["grid"],
            "fit_s_including_compile": round(seconds[0], 3),
            "fit_s_compiled": round(seconds[1], 3), "load_average_1min": load(),
            "arms": r["arms"], "quality": r["quality"]["verdict"],
            "by_segment": r["quality"]["by_segment"], "flags": r["flags"],
            "discretisation_over_noise": r["discretisation_over_noise"],
            **{k: {"value": e[k]["value"], "std_log": e[k]["std_log"]}
               for k in ("E_at_approach_Pa", "E_inf_Pa", "E_0_Pa")},
            "taus_s": [t["value"] for t in r["parameters"]["tau_s"]]}


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rings", type=int, default=64)
    p.add_argument("--grids", default="32,64", help="grid sizes of the synthetic part")
    p.add_argument("--noise", type=float, default=0.005)
    p.add_argument("--grid-real", action="store_true",
                   help="also fit the real files on the 32^2 grid (minutes)")
    p.add_argument("--parts", default="solvers,synthetic,real")
    args = p.parse_args()
    parts = args.parts.split(",")
    record = header("rings")
    load_before = os.getloadavg()
    rows = []
    if "synthetic" in parts:
        cases = [("rings", args.rings)] + [("grid", int(n))
                                           for n in args.grids.split(",") if n]
        found = []
        for solver, size in cases:
            row = synthetic(solver, size, args.noise)
            print(row, flush=True)
            found.append(row)
        rows += part_rows("synthetic", found)
    if "solvers" in parts:
        for tip in ("sphere", "cone"):
            rows += part_rows("solvers", solver_rows(
                tip, (16, 32, 64, 128, 256, 512), (32, 64, 128, 256)))
    if "real" in parts:
        found = []
        for name in FILES:
            for solver in ("rings", "grid") if args.grid_real else ("rings",):
                row = real(name, solver, args.rings)
                print(row, flush=True)
                found.append(row)
        rows += part_rows("real", found)
    record["machine"]["load_average_before"] = list(load_before)
    record["machine"]["load_average_after"] = list(os.getloadavg())
    record["settings"] = {"rings": args.rings, "grids": args.grids,
                          "noise": args.noise, "grid_real": args.grid_real,
                          "parts": parts, "dtype": "float64",
                          "synthetic": "PMMA step of benchmarks/fit.py, 40 times, "
                                       "force on 512 rings + noise",
                          "real": "fit_afm_curve defaults, R = 5 um, the file read "
                                  "as `jaxcontact fit` reads it (approach and "
                                  "hold, viscoelastic contact point)"}
    record["rows"] = rows
    record["notes"] = [
        "wall seconds on a shared 2-core machine: compare load_average_1min",
        "the default optimiser: on rings Levenberg-Marquardt alone, on the grid "
        "L-BFGS then LM where not certified"]
    print("wrote", write_results(record))


if __name__ == "__main__":
    main()
