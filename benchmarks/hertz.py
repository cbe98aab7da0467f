"""Hertz benchmark: run time against error of `jc.solve_normal`.

A rigid sphere (R = 10 mm) pressed with W = 0.15 N on an elastic half-space
(G = 1 MPa, nu = 0.3), SI units, on a non-periodic square domain of side 4a (a is
the Hertz contact radius), at n x n cells for several n, in float64 and/or float32.

For each (n, dtype) it records:

- the operator build time, the compile time (first call minus a timed second call)
  and the solve time after compilation (median of `--repeats` calls with slightly
  different loads, the operator built once and passed with `operator=`);
- iterations, operator applications, residual and convergence flag;
- the time per CG iteration and per operator application, divided by the time of
  ONE padded FFT convolution measured in the same process, (a) the naive
  `irfft2(rfft2(p, s=(2n, 2n)) * k, s=(2n, 2n))[:n, :n]` and (b) the library's pruned
  transform `op.inverse(op.forward(p) * spectrum)`, each timed per iteration of a
  jitted `lax.fori_loop`;
- errors against Hertz theory (`jc.Hertz`): peak pressure, approach, contact radius
  (from the contact area, in cells) and the largest pressure-profile error / p0.

Usage::

    python benchmarks/hertz.py                      # n = 64 .. 1024, float64
    python benchmarks/hertz.py --quick --plot       # n = 64, 128, 256 (< 1 min)
    python benchmarks/hertz.py --dtypes float64 float32 --rtol 1e-10

Results go to `benchmarks/results/hertz/<machine>.json` (`--quick`:
`<machine>_quick.json`; `--out`; layout: `results/SCHEMA.md`), a row per n and dtype;
`--plot` also writes a PNG (time against peak-pressure error, log-log) next to it.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from pathlib import Path

import jax


# x64 is enabled for the whole script; float32 runs build float32 inputs.
jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402


ROOT = Path(__file__).resolve().parent.parent
# Benchmark the checkout this script lives in (the package need not be installed).
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _common import (  # noqa: E402
    FORCE,
    POISSON,
    RADIUS,
    SHEAR_MODULUS,
    convolution_times,
    header,
    machine_info,
    write_results,
)

import jaxcontact as jc  # noqa: E402


# ---- The problem ------------------------------------------------------------------

DOMAIN_OVER_A = 4.0  # side of the square domain / Hertz contact radius

DEFAULT_SIZES = (64, 128, 256, 512, 1024)
QUICK_SIZES = (64, 128, 256)
DTYPES = {"float64": jnp.float64, "float32": jnp.float32}
# Fewer CG iterations than this: the result is essentially the initial guess.
MIN_ITERATIONS = 3


def _timed(fn):
    t = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t


# ---- Errors against Hertz ---------------------------------------------------------


def hertz_errors(sol, n: int, size: float, hz: jc.Hertz) -> dict:
    a = float(hz.contact_radius)
    p0 = float(hz.peak_pressure)
    delta = float(hz.approach)
    dx = size / n
    cell_area = dx * dx
    p = np.asarray(sol.pressure, dtype=np.float64)
    c = np.arange(n) - (n - 1) / 2
    xx, yy = np.meshgrid(c * dx, c * dx, indexing="ij")
    r = np.hypot(xx, yy)
    exact = p0 * np.sqrt(np.maximum(1 - (r / a) ** 2, 0.0))
    n_contact = int(np.count_nonzero(np.asarray(sol.contact)))
    a_num = math.sqrt(n_contact * cell_area / math.pi)
    return {
        "peak_pressure_rel": float(p.max() / p0 - 1),
        "approach_rel": float(float(sol.approach) / delta - 1),
        "contact_radius_cells": (a_num - a) / dx,
        "contact_radius_rel": a_num / a - 1,
        "profile_max_over_p0": float(np.max(np.abs(p - exact)) / p0),
        "force_rel": float(float(sol.normal_force) / hz.force - 1),
        "contact_cells": n_contact,
        "contact_radius_numeric": a_num,
    }


# ---- One case ---------------------------------------------------------------------


def build(n: int, dtype, notes: list[str]):
    """Grid, material, indenter, all with `dtype` values (x64 is on)."""
    hz = jc.Hertz(RADIUS, FORCE, SHEAR_MODULUS, POISSON)
    size = DOMAIN_OVER_A * float(hz.contact_radius)
    grid = jc.Grid((n, n), jnp.asarray(size, dtype))
    material = jc.Elastic(jnp.asarray(SHEAR_MODULUS, dtype),
                          jnp.asarray(POISSON, dtype))
    sphere = jc.Sphere(jnp.asarray(RADIUS, dtype))
    gap_dtype = sphere.gap(grid).dtype
    if gap_dtype != dtype:
        msg = (
            f"jc.Sphere(radius={jnp.dtype(dtype).name}) with the default centre gives "
            f"a {gap_dtype} gap on a {jnp.dtype(dtype).name} grid (the default centre "
            f"(0.0, 0.0) is {sphere.centre.dtype} under x64), so the solve would run "
            f"in {gap_dtype}; the benchmark passes centre=jnp.zeros(2, "
            f"{jnp.dtype(dtype).name})."
        )
        if msg not in notes:
            notes.append(msg)
        sphere = jc.Sphere(jnp.asarray(RADIUS, dtype), centre=jnp.zeros(2, dtype))
    return hz, size, grid, material, sphere


def _ratio(a, b):
    return None if a is None else a / b


def run_case(n: int, dtype_name: str, args, notes: list[str]) -> dict:
    dtype = DTYPES[dtype_name]
    hz, size, grid, material, sphere = build(n, dtype, notes)
    solver = jc.PolonskyKeer(rtol=args.rtol, max_steps=args.max_steps)
    rtol_used = solver.tolerance(jnp.dtype(dtype))

    op, t_build = _timed(lambda: jax.block_until_ready(jc.HalfSpace(grid)))

    # Load control at W, or displacement control at the Hertz approach for W.
    nominal = FORCE if args.control == "force" else float(hz.approach)

    def solve(value):
        s = jc.solve_normal(grid, sphere, material, solver=solver, operator=op,
                            throw=False, **{args.control: value})
        s.pressure.block_until_ready()
        return s

    # First call (compiles) at the nominal load: its solution is the one compared
    # with Hertz. Second call at a slightly different load, timed; the difference is
    # the compile time.
    sol, t_first = _timed(lambda: solve(nominal))
    _, t_second = _timed(lambda: solve(nominal * (1 + 1e-4)))
    times, iters, apps = [], [], []
    for i in range(args.repeats):
        s, t = _timed(lambda i=i: solve(nominal * (1 + 1e-4 * (i + 2))))
        times.append(t)
        iters.append(int(s.iterations))
        apps.append(int(s.applications))
    t_solve = statistics.median(times)
    # Per-call cost that does not depend on the iteration count: at zero load (or
    # approach) the solver stops before its first iteration, so this is the eager
    # set-up (argument checks, the indenter's gap, the initial guess), the dispatch
    # and one or two operator applications.
    zero = solve(0.0)
    overhead = []
    for _ in range(args.repeats):
        overhead.append(_timed(lambda: solve(0.0))[1])
    # Per-iteration figures only from calls that iterated (a solve that stops at its
    # initial guess has no iteration to time).
    per_iter = [t / k for t, k in zip(times, iters) if k > 0]
    per_iter = statistics.median(per_iter) if per_iter else None
    per_app = statistics.median(t / max(k, 1) for t, k in zip(times, apps))
    if int(sol.iterations) < MIN_ITERATIONS:
        notes.append(
            f"{dtype_name} n={n}: {int(sol.iterations)} iterations "
            f"(rtol {rtol_used:g}): the solve is (nearly) the solver's initial guess, "
            "so its errors measure the guess and its per-iteration ratios are not "
            "meaningful."
        )

    compliance = material.instantaneous_compliance
    spectrum = compliance * op.normal_spectrum(material.poisson)
    conv = convolution_times(op, spectrum, n, dtype, args.repeats)

    out_dtypes = {
        "pressure": str(sol.pressure.dtype),
        "approach": str(sol.approach.dtype),
        "residual": str(sol.residual.dtype),
        "displacement": str(sol.displacement.dtype),
    }
    if any(v != dtype_name for v in out_dtypes.values()):
        note = (
            f"n={n}: {dtype_name} inputs gave solution dtypes {out_dtypes} "
            f"(expected {dtype_name} throughout)."
        )
        notes.append(note)

    return {
        "n": n,
        "dtype": dtype_name,
        "control": args.control,
        "solution_dtype": str(sol.pressure.dtype),
        "solution_dtypes": out_dtypes,
        "rtol": rtol_used,
        "max_steps": args.max_steps,
        "cell_size": size / n,
        "operator_build_s": t_build,
        "first_call_s": t_first,
        "second_call_s": t_second,
        "compile_s": t_first - t_second,
        "solve_s": t_solve,
        "solve_s_all": times,
        "zero_load_call_s": statistics.median(overhead),
        "zero_load_iterations": int(zero.iterations),
        "iterations": int(sol.iterations),
        "applications": int(sol.applications),
        "residual": float(sol.residual),
        "converged": bool(sol.converged),
        "iterations_timed": iters,
        "applications_timed": apps,
        "time_per_iteration_s": per_iter,
        "time_per_application_s": per_app,
        "conv_naive_s": conv["naive"],
        "conv_pruned_s": conv["pruned"],
        "iteration_over_conv_naive": _ratio(per_iter, conv["naive"]),
        "iteration_over_conv_pruned": _ratio(per_iter, conv["pruned"]),
        "application_over_conv_naive": per_app / conv["naive"],
        "application_over_conv_pruned": per_app / conv["pruned"],
        "errors": hertz_errors(sol, n, size, hz),
    }


# ---- Report -----------------------------------------------------------------------

def _fmt(value, spec: str) -> str:
    return "-" if value is None else format(value, spec)


COLUMNS = [
    # header, width, formatter
    ("dtype", 7, lambda r: r["dtype"]),
    ("n", 5, lambda r: f"{r['n']}"),
    ("iter", 5, lambda r: f"{r['iterations']}"),
    ("apps", 5, lambda r: f"{r['applications']}"),
    ("residual", 8, lambda r: f"{r['residual']:.1e}" + ("" if r["converged"] else "!")),
    ("compile", 7, lambda r: f"{r['compile_s']:.2f}"),
    ("solve[s]", 8, lambda r: f"{r['solve_s']:.4f}"),
    ("ovh[ms]", 7, lambda r: f"{1e3 * r['zero_load_call_s']:.2f}"),
    ("it/cvN", 6, lambda r: _fmt(r["iteration_over_conv_naive"], ".2f")),
    ("it/cvP", 6, lambda r: _fmt(r["iteration_over_conv_pruned"], ".2f")),
    ("ap/cvN", 6, lambda r: f"{r['application_over_conv_naive']:.2f}"),
    ("ap/cvP", 6, lambda r: f"{r['application_over_conv_pruned']:.2f}"),
    ("conv[ms]", 8, lambda r: f"{1e3 * r['conv_naive_s']:.3f}"),
    ("p0 err", 9, lambda r: f"{r['errors']['peak_pressure_rel']:+.2e}"),
    ("d err", 9, lambda r: f"{r['errors']['approach_rel']:+.2e}"),
    ("W err", 9, lambda r: f"{r['errors']['force_rel']:+.2e}"),
    ("a err", 6, lambda r: f"{r['errors']['contact_radius_cells']:+.2f}"),
    ("prof/p0", 8, lambda r: f"{r['errors']['profile_max_over_p0']:.2e}"),
]

LEGEND = """\
iter/apps: CG iterations / operator applications; residual: '!' = not converged.
compile: first call minus second call [s]; solve: median after compilation [s].
ovh: time of a call at zero load/approach (no iteration: set-up and dispatch).
it/cvN, it/cvP: time per iteration / one padded convolution, naive rfft2 (N) or
  the library's pruned transform (P); ap/..: the same per operator application.
conv: one naive padded convolution [ms]. p0 err, d err, W err: relative errors of the
  peak pressure, approach and load; a err: contact radius error [cells];
  prof/p0: max |p - p_H| / p0."""


def format_table(rows) -> str:
    head = " ".join(h.rjust(w) for h, w, _ in COLUMNS)
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(" ".join(f(r).rjust(w) for _, w, f in COLUMNS))
    return "\n".join(lines)


def growth_exponents(rows) -> dict:
    """Least-squares slope of log(iterations) against log(n), per dtype."""
    out = {}
    for dtype in sorted({r["dtype"] for r in rows}):
        pts = [(r["n"], r["iterations"]) for r in rows if r["dtype"] == dtype]
        if len(pts) >= 2:
            x = np.log([p[0] for p in pts])
            y = np.log([max(p[1], 1) for p in pts])
            out[dtype] = float(np.polyfit(x, y, 1)[0])
    return out


def plot(rows, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4.5))
    for dtype, marker in (("float64", "o"), ("float32", "s")):
        sel = [r for r in rows if r["dtype"] == dtype]
        if not sel:
            continue
        err = [max(abs(r["errors"]["peak_pressure_rel"]), 1e-16) for r in sel]
        t = [r["solve_s"] for r in sel]
        ax.loglog(t, err, marker=marker, label=dtype)
        for r, ti, ei in zip(sel, t, err):
            ax.annotate(f"n={r['n']}", (ti, ei), textcoords="offset points",
                        xytext=(5, 4), fontsize=8)
    ax.set_xlabel("solve time after compilation [s]")
    ax.set_ylabel("|peak pressure error| (relative to Hertz p0)")
    ax.set_title("Hertz: rigid sphere on elastic half-space "
                 f"({rows[0]['control']} control)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


# ---- Main -------------------------------------------------------------------------


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=list(DEFAULT_SIZES),
                    help="grid sizes n (n x n cells); default %(default)s")
    ap.add_argument("--quick", action="store_true",
                    help=f"only n = {', '.join(map(str, QUICK_SIZES))} "
                         "(overrides --sizes)")
    ap.add_argument("--dtypes", nargs="+", default=["float64"], choices=list(DTYPES),
                    help="floating-point types; default %(default)s")
    ap.add_argument("--control", choices=["force", "approach"], default="force",
                    help="load control at W (default) or displacement control at the "
                         "Hertz approach for W (no Hertz-shaped initial guess)")
    ap.add_argument("--rtol", type=float, default=None,
                    help="solver tolerance (default: jc.PolonskyKeer's own, 1e-8 in "
                         "float64 and looser in float32; the JSON records the value "
                         "used)")
    ap.add_argument("--max-steps", type=int, default=2000,
                    help="solver iteration bound (default %(default)s)")
    ap.add_argument("--repeats", type=int, default=5,
                    help="timed calls per case, the median is reported "
                         "(default %(default)s)")
    ap.add_argument("--out", type=Path, default=None,
                    help="JSON output path (default results/hertz/<machine>.json)")
    ap.add_argument("--plot", action="store_true",
                    help="also write a PNG (time vs peak-pressure error) next to the "
                         "JSON")
    args = ap.parse_args(argv)
    if args.quick:
        args.sizes = list(QUICK_SIZES)
    if args.repeats < 1:
        ap.error("--repeats must be >= 1")
    return args


def main(argv=None) -> int:
    args = parse_args(argv)
    t_start = time.perf_counter()
    machine = machine_info()
    hz = jc.Hertz(RADIUS, FORCE, SHEAR_MODULUS, POISSON)
    problem = {
        "radius_m": RADIUS,
        "force_N": FORCE,
        "shear_modulus_Pa": SHEAR_MODULUS,
        "poisson": POISSON,
        "domain": f"square, side {DOMAIN_OVER_A:g} a, non-periodic",
        "hertz_contact_radius_m": float(hz.contact_radius),
        "hertz_peak_pressure_Pa": float(hz.peak_pressure),
        "hertz_approach_m": float(hz.approach),
    }
    print(f"Hertz benchmark on {machine['processor']} "
          f"({machine['cpu_count_usable']} usable CPUs), jax {machine['jax']}, "
          f"{machine['device']}")
    print(f"control: {args.control}; rtol: "
          f"{'solver default' if args.rtol is None else args.rtol}")
    print(f"a = {problem['hertz_contact_radius_m']:.6e} m, "
          f"p0 = {problem['hertz_peak_pressure_Pa']:.6e} Pa, "
          f"delta = {problem['hertz_approach_m']:.6e} m")

    notes: list[str] = []
    if args.rtol is not None and args.rtol < 1e-6 and "float32" in args.dtypes:
        notes.append(
            f"--rtol {args.rtol:g} is below float32 round-off: float32 solves may stop "
            f"at --max-steps {args.max_steps} with converged=False (and take long)."
        )
        print("WARNING:", notes[-1])
    rows = []
    for dtype in args.dtypes:
        for n in args.sizes:
            r = run_case(n, dtype, args, notes)
            rows.append(r)
            print(f"  done {dtype} n={n}: {r['iterations']} iterations, "
                  f"solve {r['solve_s']:.4f} s, compile {r['compile_s']:.2f} s, "
                  f"operator build {r['operator_build_s']:.2f} s", flush=True)

    exponents = growth_exponents(rows)
    result = {
        **header("hertz", argv, variant="quick" if args.quick else None),
        "settings": {
            "sizes": args.sizes,
            "dtypes": args.dtypes,
            "control": args.control,
            "rtol": args.rtol,
            "max_steps": args.max_steps,
            "repeats": args.repeats,
            "x64_enabled": bool(jax.config.jax_enable_x64),
            "problem": problem,
        },
        "notes": notes,
        "summary": {"iteration_growth_exponent": exponents,
                    "total_time_s": time.perf_counter() - t_start},
        "rows": rows,
    }

    print()
    print(format_table(rows))
    print(LEGEND)
    if exponents:
        print("iterations ~ n^k, fitted k: "
              + ", ".join(f"{d}: {k:.2f}" for d, k in exponents.items())
              + "  (sqrt(n) is k = 0.5)")
    for note in notes:
        print("NOTE:", note)

    path = write_results(result, args.out)
    print(f"wrote {path}")
    if args.plot:
        png = path.with_suffix(".png")
        plot(rows, png)
        print(f"wrote {png}")
    print(f"total {time.perf_counter() - t_start:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
