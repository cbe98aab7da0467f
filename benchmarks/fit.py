"""Time to fit a 2-term Prony series through the full contact model (issue 5 target:
64^2 x 40 steps in under 2 minutes on 2 CPU cores).

Scene: the paper's PMMA (Eq. 28 creep series converted to a relaxation series, true
shear modulus), rigid sphere R = 3.5 mm, nu = 0.38, a 20 um step indentation held for
500 s (displacement control), t = 0 then 39 log-spaced times from 0.5 s, grid 1.28 mm
wide, float64. Synthetic noiseless force from `jc.solve`; `jc.fit_prony(data,
template, 2, optimiser=..., solve_options={"scheme": "constant"})` (the scheme that
made the data) from its default start (apparent moduli), with optimistix's
Levenberg-Marquardt ("lm", the default) and the in-house Adam + L-BFGS ("lbfgs").
Reported: wall time of the fit including compilation (what a user waits for) and of a
second, compiled fit, the steps, model evaluations, final loss, relative error of each
parameter.

`--batch B`: the time of `jc.fit_prony_batch` on B curves (PMMA with its moduli scaled
by 0.5-2 and its times by 0.7-1.4, 0.5 % noise, `scheme="constant"`) against
`jc.fit_prony(optimiser="lm")` on the first of them, both compiled (second call) and
including compilation; the load average is recorded with every timing (the machine
is shared).

Usage::

    python benchmarks/fit.py                 # 64^2 x 40
    python benchmarks/fit.py --n 32 --nt 20 --optimiser lm
    python benchmarks/fit.py --n 16 --nt 20 --batch 16   # -> <machine>_batch_16.json

Results go to `benchmarks/results/fit/<machine>.json` (one optimiser:
`<machine>_lm.json`, `<machine>_lbfgs.json`; `--batch`: `<machine>_batch_<n>.json`),
or `--out` (layout: `results/SCHEMA.md`).
"""

import argparse
import json
import os
import sys
import time
from pathlib import Path

import jax


jax.config.update("jax_enable_x64", True)
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import jaxcontact as jc  # noqa: E402


sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import header, write_results  # noqa: E402


R, NU = 3.5e-3, 0.38


def pmma():
    """Eq. 28 (1/GPa of 2G) -> relaxation series of the true shear modulus [Pa]."""
    m = jc.Prony.from_creep(2e-9 * 0.699, 2e-9 * np.array([0.0838, 0.06174]),
                            np.array([133.869, 9.9404]), NU)
    order = np.argsort(np.asarray(m.tau))
    return jc.Prony(m.g_inf, m.g[order], m.tau[order], NU)


def params(m):
    return np.concatenate([[float(m.g_inf)], np.asarray(m.g), np.asarray(m.tau)])


def run(n, nt, optimiser):
    grid = jc.Grid((n, n), 1280e-6)
    times = jnp.concatenate([jnp.zeros(1), jnp.geomspace(0.5, 500.0, nt - 1)])
    delta = jnp.where(times > 0, 20e-6, 0.0)
    truth = pmma()
    scene = jc.Scene(grid, jc.Sphere(R), truth, times, normal=jc.Displacement(delta))
    sol = jc.solve(scene)
    data = jc.IndentationData(times, force=sol.normal_force, depth=delta)
    template = jc.Scene(grid, jc.Sphere(R), jc.Elastic(1e9, NU), times,
                        normal=jc.Displacement(delta))
    # The data are a true step computed with the piecewise-constant scheme: the fit
    # uses the same scheme (its default, "linear", would read the step as a ramp).
    options = {"scheme": "constant"}
    # solver="grid": this benchmark is the grid's (the rings: benchmarks/rings.py)
    start = time.perf_counter()
    fit = jc.fit_prony(data, template, 2, optimiser=optimiser, solve_options=options,
                       solver="grid")
    elapsed = time.perf_counter() - start
    start = time.perf_counter()  # again: compiled
    jc.fit_prony(data, template, 2, optimiser=optimiser, solve_options=options,
                 solver="grid")
    again = time.perf_counter() - start
    err = params(fit.material) / params(truth) - 1
    return {
        "n": n, "nt": nt, "optimiser": optimiser,
        "fit_s_including_compile": elapsed, "fit_s_compiled": again,
        "lm_steps": int(fit.lm_steps),
        "adam_steps": int(fit.adam_steps), "lbfgs_steps": int(fit.lbfgs_steps),
        "evaluations": int(fit.evaluations), "loss": float(fit.loss),
        "converged": bool(fit.converged), "message": fit.message,
        "solves_converged": bool(fit.solves_converged),
        "relative_errors": {"g_inf": err[0], "g": list(err[1:3]),
                            "tau": list(err[3:5])},
        "max_relative_error": float(np.max(np.abs(err))),
    }


def batch_curves(n, nt, count, seed=0):
    grid = jc.Grid((n, n), 1280e-6)
    times = jnp.concatenate([jnp.zeros(1), jnp.geomspace(0.5, 500.0, nt - 1)])
    delta = jnp.where(times > 0, 20e-6, 0.0)
    rng = np.random.default_rng(seed)
    base = pmma()
    data = []
    for _ in range(count):
        m = jc.Prony(base.g_inf * rng.uniform(0.5, 2), base.g * rng.uniform(0.5, 2, 2),
                     base.tau * rng.uniform(0.7, 1.4, 2), NU)
        sol = jc.solve(jc.Scene(grid, jc.Sphere(R), m, times,
                                normal=jc.Displacement(delta)), scheme="constant")
        force = np.asarray(sol.normal_force) * (1 + 0.005 * rng.standard_normal(nt))
        data.append(jc.IndentationData(times, force=force, depth=delta))
    template = jc.Scene(grid, jc.Sphere(R), jc.Elastic(1e9, NU), times,
                        normal=jc.Displacement(delta))
    return data, template


def run_batch(n, nt, count):
    data, template = batch_curves(n, nt, count)
    options = {"solve_options": {"scheme": "constant"}, "solver": "grid"}
    out = {"n": n, "nt": nt, "curves": count}
    for label, call in (
            ("one_curve", lambda: [jc.fit_prony(data[0], template, 2, optimiser="lm",
                                                **options)]),
            ("batch", lambda: jc.fit_prony_batch(data, template, 2, **options))):
        for attempt in ("including_compile", "compiled"):
            load = os.getloadavg()
            start = time.perf_counter()
            fits = call()
            out[f"{label}_s_{attempt}"] = time.perf_counter() - start
            out[f"{label}_load_average_{attempt}"] = [load, os.getloadavg()]
        out[f"{label}_lm_steps"] = [int(f.lm_steps) for f in fits]
        out[f"{label}_converged"] = [bool(f.converged) for f in fits]
        print(json.dumps(out), flush=True)
    out["batch_s_per_curve_compiled"] = out["batch_s_compiled"] / count
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=64)
    parser.add_argument("--nt", type=int, default=40)
    parser.add_argument("--optimiser", default="both", choices=("lm", "lbfgs", "both"))
    parser.add_argument("--batch", type=int, default=0,
                        help="time a batch of this many curves instead")
    parser.add_argument("--out", default=None,
                        help="JSON path (default results/fit/<machine>.json, with "
                             "--batch results/fit/<machine>_batch_<n>.json)")
    args = parser.parse_args()
    if args.batch:
        result = header("fit", variant=f"batch_{args.n}")
        result["settings"] = dict(n=args.n, nt=args.nt, batch=args.batch,
                                  dtype="float64")
        result["rows"] = [run_batch(args.n, args.nt, args.batch)]
        print("wrote", write_results(result, args.out))
        return
    result = header("fit", variant=None if args.optimiser == "both"
                    else args.optimiser)
    cases = []
    for optimiser in (("lm", "lbfgs") if args.optimiser == "both"
                      else (args.optimiser,)):
        case = run(args.n, args.nt, optimiser)
        case["relative_errors"] = {k: np.asarray(v).tolist()
                                   for k, v in case["relative_errors"].items()}
        print(json.dumps(case), flush=True)
        cases.append(case)
    result["machine"]["load_average_after"] = os.getloadavg()
    result["settings"] = dict(n=args.n, nt=args.nt, optimiser=args.optimiser,
                              dtype="float64")
    result["rows"] = cases
    print("wrote", write_results(result, args.out))


if __name__ == "__main__":
    main()
