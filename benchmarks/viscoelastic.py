"""Viscoelastic benchmark: run time against error of `jc.solve` over time.

Parts (see benchmarks/README.md, section `viscoelastic.py`):

(a) Lee-Radok, Zener mu_inf/mu_0 = 10 (paper Table 2 otherwise, true shear moduli:
    mu_inf = 1.93 MPa, tau = 0.01 s, nu = 0.3, R = 10 mm, W = 0.15 N step, domain
    5.5 a0, T = 3 tau): run time against error over n and Nt, both time schemes.
(b) Time per step against Nt: the O(Nt) recursion against the paper's O(Nt^2) direct
    sum (`history="direct"`), n = 64.
(c) The cost of a viscoelastic step relative to an elastic step on the same grid.
(d) The issue's target scene: standard linear solid creep,
    `jc.Prony(g_inf=1.93e6, g=[3.86e6], tau=[0.1], poisson=0.3)`, R = 10 mm, W = 0.15 N
    step, 150 steps to 1.5 s, 256^2 over 1.4 mm (just covering the final contact),
    non-periodic, SI; contact radius against Lee-Radok
    at every step; whole-history time; and the same scene in other units (mm, N, MPa;
    and stresses scaled so that G_inf = 1) giving the same normalised result.
(e) Paper Table 2 scene at 256^2, 81 steps, normal load only, total time including
    compilation; and the same fully coupled with friction (skipped by `--quick`).

Usage::

    python benchmarks/viscoelastic.py --quick     # a few minutes
    python benchmarks/viscoelastic.py             # everything
    python benchmarks/viscoelastic.py --parts cd  # some parts, merged into --out

Results: `benchmarks/results/viscoelastic/<machine>.json` (`--quick`:
`<machine>_quick.json`; `--out`; layout: `results/SCHEMA.md`): rows tagged by `part`
(`a_lee_radok`, `b_history_paths`, `c_step_cost`, `d_target_scene`, `e_table2`).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import jax


jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402


HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE))

from _common import (  # noqa: E402
    header,
    load_results,
    machine_info,
    part_rows,
    results_path,
    write_results,
)

import jaxcontact as jc  # noqa: E402


# ---- Problems ------------------------------------------------------------------------

R, W, NU = 10e-3, 0.15, 0.3
MU_INF, TAU = (
    3.86e6 / 2,
    0.01,
)  # paper Table 2, true shear modulus; tau = retardation time


def zener(ratio):
    return jc.Zener(MU_INF, MU_INF / ratio, TAU, NU)


def a0_table2():
    return float(jc.Hertz(R, W, MU_INF, NU).contact_radius)


def p0_table2():
    return float(jc.Hertz(R, W, MU_INF, NU).peak_pressure)


def step_load(w):
    return jc.Force(w)


def _block(sol):
    jax.block_until_ready(sol.pressure)
    return sol


def timed_solve(make_scene, *, w=W, **solve_kwargs):
    """(first solution, first-call time, second-call time). The second call uses a load
    changed by 1e-9 (same compiled program, nothing cached). On the grid (the
    rounds): this benchmark is the grid solver's; `jc.solve` would put these
    frictionless spheres on rings (`benchmarks/rings.py`)."""
    solve_kwargs.setdefault("solver", jc.Rounds())
    t = time.perf_counter()
    sol = _block(jc.solve(make_scene(w), **solve_kwargs))
    first = time.perf_counter() - t
    t = time.perf_counter()
    _block(jc.solve(make_scene(w * (1 + 1e-9)), **solve_kwargs))
    second = time.perf_counter() - t
    return sol, first, second


def equivalent_radius(sol, grid):
    n = np.asarray(sol.contact).sum(axis=(1, 2))
    return np.sqrt(n * float(grid.cell_area) / np.pi)


def centre_pressure(sol, grid):
    nx, ny = grid.shape
    p = np.asarray(sol.pressure)[
        :, nx // 2 - 1 : nx // 2 + 1, ny // 2 - 1 : ny // 2 + 1
    ]
    return p.mean(axis=(1, 2))


class StepLeeRadok:
    """Lee-Radok for a step load W at t = 0, in closed form from J(t) (exact):
    a^3 = 3 R (1 - nu) / 8 W J(t), delta = a^2 / R; the centre pressure from
    `jc.LeeRadok` (Stieltjes sums)."""

    def __init__(self, radius, poisson, material, w, samples=1000):
        self.r, self.nu, self.m, self.w = radius, poisson, material, w
        self.lr = jc.LeeRadok(
            radius, poisson, material, lambda t: w * (t >= 0), samples=samples
        )

    def contact_radius(self, t):
        j = np.asarray(self.m.creep(jnp.asarray(t)))
        return (3 * self.r * (1 - self.nu) / 8 * self.w * j) ** (1 / 3)

    def approach(self, t):
        return self.contact_radius(t) ** 2 / self.r

    def pressure(self, r, t):
        return self.lr.pressure(r, t)


# ---- (a) Lee-Radok: time against error -----------------------------------------------


def part_a(sizes, nts, log):
    material = zener(10)
    ref = StepLeeRadok(R, NU, material, W)
    p0 = p0_table2()
    rows = []
    for n in sizes:
        grid = jc.Grid((n, n), 5.5 * a0_table2())
        dx = float(grid.spacing[0])
        r_c = dx / np.sqrt(2)
        for nt in nts:
            times = jnp.linspace(0.0, 3 * TAU, nt)
            t_np = np.asarray(times)
            a_ref, d_ref = ref.contact_radius(t_np), ref.approach(t_np)
            pc_ref = np.array([ref.pressure([r_c], t)[0] for t in t_np])
            for scheme in ("constant", "linear"):

                def make(w, grid=grid, times=times):
                    return jc.Scene(
                        grid, jc.Sphere(R), material, times, normal=step_load(w)
                    )

                sol, first, second = timed_solve(make, scheme=scheme)
                a_num = equivalent_radius(sol, grid)
                row = {
                    "n": n,
                    "nt": nt,
                    "scheme": scheme,
                    "compile_s": first - second,
                    "solve_s": second,
                    "step_s": second / nt,
                    "iterations": int(np.asarray(sol.iterations).sum()),
                    "converged": bool(np.asarray(sol.converged).all()),
                    "a_error_cells": float(np.max(np.abs(a_num - a_ref)) / dx),
                    "approach_rel_error": float(
                        np.max(np.abs(np.asarray(sol.approach) / d_ref - 1))
                    ),
                    "centre_pressure_error_p0": float(
                        np.max(np.abs(centre_pressure(sol, grid) - pc_ref)) / p0
                    ),
                    "centre_pressure_error_p0_after_tau": float(
                        np.max(np.abs(centre_pressure(sol, grid) - pc_ref)[t_np >= TAU])
                        / p0
                    ),
                }
                rows.append(row)
                log(
                    f"  (a) n={n:4d} Nt={nt:3d} {scheme:8s} solve {second:7.3f} s "
                    f"compile {first - second:5.1f} s  "
                    f"a err {row['a_error_cells']:.3f} cells  "
                    f"delta err {row['approach_rel_error']:.1e}  p(0) err/p0 "
                    f"{row['centre_pressure_error_p0']:.3f} (t>=tau "
                    f"{row['centre_pressure_error_p0_after_tau']:.4f})"
                    + ("" if row["converged"] else "  NOT CONVERGED")
                )
    return rows


# ---- (b) time per step: recursive against direct -------------------------------------


def part_b(nts, log, n=64):
    material = zener(10)
    grid = jc.Grid((n, n), 5.5 * a0_table2())
    rows = []
    for nt in nts:
        times = jnp.linspace(0.0, 3 * TAU, nt)
        out = {"n": n, "nt": nt}
        sols = {}
        for history in ("recursive", "direct"):

            def make(w, times=times):
                return jc.Scene(
                    grid, jc.Sphere(R), material, times, normal=step_load(w)
                )

            sol, first, second = timed_solve(make, history=history)
            sols[history] = sol
            out[f"{history}_solve_s"] = second
            out[f"{history}_step_s"] = second / nt
            out[f"{history}_compile_s"] = first - second
            out[f"{history}_iterations"] = int(np.asarray(sol.iterations).sum())
            out[f"{history}_iteration_s"] = second / max(
                out[f"{history}_iterations"], 1
            )
        out["max_approach_rel_diff"] = float(
            np.max(
                np.abs(
                    np.asarray(sols["recursive"].approach)
                    / np.asarray(sols["direct"].approach)
                    - 1
                )
            )
        )
        rows.append(out)
        log(
            f"  (b) n={n} Nt={nt:4d}  per step: recursive "
            f"{out['recursive_step_s'] * 1e3:7.2f} ms"
            f"  direct {out['direct_step_s'] * 1e3:7.2f} ms;  per CG iteration: "
            f"recursive "
            f"{out['recursive_iteration_s'] * 1e3:6.3f} ms  direct "
            f"{out['direct_iteration_s'] * 1e3:6.3f} ms  (approach diff "
            f"{out['max_approach_rel_diff']:.1e})"
        )
    return rows


# ---- (c) viscoelastic step against elastic step --------------------------------------


def part_c(sizes, log, nt=41):
    rows = []
    for n in sizes:
        grid = jc.Grid((n, n), 5.5 * a0_table2())
        times = jnp.linspace(0.0, 3 * TAU, nt)
        # The same smooth loading for both (a sine ramp: every step does work), so that
        # the iteration counts are comparable.
        out = {"n": n, "nt": nt}
        for name, material in (
            ("elastic", jc.Elastic(MU_INF, NU)),
            ("zener", zener(4)),
        ):

            def make(w, material=material):
                return jc.Scene(
                    grid,
                    jc.Sphere(R),
                    material,
                    times,
                    normal=jc.Force(lambda t: w * jnp.sin(jnp.pi * t / (6 * TAU))),
                )

            sol, first, second = timed_solve(make)
            its = int(np.asarray(sol.iterations).sum())
            out[f"{name}_step_s"] = second / nt
            out[f"{name}_iterations"] = its
            out[f"{name}_iteration_s"] = second / max(its, 1)
        out["step_ratio"] = out["zener_step_s"] / out["elastic_step_s"]
        out["iteration_ratio"] = out["zener_iteration_s"] / out["elastic_iteration_s"]
        rows.append(out)
        log(
            f"  (c) n={n}: step zener/elastic = {out['step_ratio']:.2f} "
            f"(iterations {out['zener_iterations']} / {out['elastic_iterations']}; per "
            f"iteration {out['iteration_ratio']:.2f})"
        )
    return rows


# ---- (d) the target scene and unit invariance --------------------------------


def part_d(log, n=256, nt=151):
    # SI: m, N, Pa, s. The grid just covers the final contact (a(1.5 s) = 0.587 mm,
    # diameter 1.17 mm; DC-FFT is exact for a non-periodic grid, no margin needed):
    # 1.4 mm over 256 cells puts 75 cells on a0 and 107 on a(1.5 s).
    base = dict(g_inf=1.93e6, g=3.86e6, tau=0.1, radius=10e-3, w=0.15, domain=1.4e-3)
    # Unit systems: (length unit in m, stress unit in Pa); force unit = stress x
    # length^2.
    systems = {
        "SI (m, N, Pa)": (1.0, 1.0),
        "mm, N, MPa": (1e-3, 1e6),
        "m, G_inf = 1": (1.0, 1.93e6),
    }
    out = {"n": n, "nt": nt, "t_end_s": 1.5, "systems": {}}
    normalised = {}
    for label, (length, stress) in systems.items():
        force = stress * length**2
        material = jc.Prony(
            base["g_inf"] / stress,
            jnp.asarray([base["g"] / stress]),
            jnp.asarray([base["tau"]]),
            NU,
        )
        grid = jc.Grid((n, n), base["domain"] / length)
        times = jnp.linspace(0.0, 1.5, nt)
        radius = base["radius"] / length

        def make(w, grid=grid, material=material, times=times, radius=radius):
            return jc.Scene(
                grid, jc.Sphere(radius), material, times, normal=jc.Force(w)
            )

        sol, first, second = timed_solve(make, w=base["w"] / force)
        ref = StepLeeRadok(radius, NU, material, base["w"] / force)
        t_np = np.asarray(times)
        a_ref = ref.contact_radius(t_np)
        a_area = equivalent_radius(sol, grid)
        a_approach = np.sqrt(np.asarray(sol.approach) * radius)
        dx = float(grid.spacing[0])
        res = {
            # The later unit systems reuse the first one's compiled program.
            "first_call_s": first,
            "solve_s": second,
            "compile_s": max(first - second, 0.0),
            "converged": bool(np.asarray(sol.converged).all()),
            "iterations": int(np.asarray(sol.iterations).sum()),
            "a_area_rel_error_max": float(np.max(np.abs(a_area / a_ref - 1))),
            "a_area_error_cells_max": float(np.max(np.abs(a_area - a_ref)) / dx),
            "a_from_approach_rel_error_max": float(
                np.max(np.abs(a_approach / a_ref - 1))
            ),
            "approach_rel_error_max": float(
                np.max(np.abs(np.asarray(sol.approach) / ref.approach(t_np) - 1))
            ),
            "a0_cells": float(a_ref[0] / dx),
            "a_end_cells": float(a_ref[-1] / dx),
        }
        out["systems"][label] = res
        # Normalised by the scene's own scales (length: R; stress: g_inf).
        normalised[label] = (
            np.asarray(sol.approach) / radius,
            np.asarray(sol.pressure) / (base["g_inf"] / stress),
            np.asarray(sol.contact),
        )
        log(
            f"  (d) {label:14s}: whole history {second:6.2f} s "
            f"(first call {first:5.1f} s),"
            f" a(area) err max {res['a_area_rel_error_max'] * 100:.3f} % "
            f"({res['a_area_error_cells_max']:.2f} cells of {res['a0_cells']:.0f}-"
            f"{res['a_end_cells']:.0f}), a = sqrt(R delta) err max "
            f"{res['a_from_approach_rel_error_max'] * 100:.4f} %"
            + ("" if res["converged"] else "  NOT CONVERGED")
        )
    si = normalised["SI (m, N, Pa)"]
    out["unit_invariance"] = {}
    for label, (d, p, c) in normalised.items():
        inv = {
            "approach_rel_diff_max": float(np.max(np.abs(d / si[0] - 1))),
            "pressure_diff_over_max": float(
                np.max(np.abs(p - si[1])) / np.max(np.abs(si[1]))
            ),
            "contact_cells_differing": int(np.sum(c != si[2])),
        }
        out["unit_invariance"][label] = inv
        log(
            f"  (d) invariance {label:14s}: approach/R rel diff "
            f"{inv['approach_rel_diff_max']:.1e}, "
            f"p/G_inf diff {inv['pressure_diff_over_max']:.1e}, "
            f"contact cells differing {inv['contact_cells_differing']}"
        )
    return out


# ---- (e) paper Table 2 scene ---------------------------------------------------------


def part_e(log, n=256, nt=81, ratio=10):
    out = {"n": n, "nt": nt, "ratio": ratio, "t_end": "3 tau"}
    grid = jc.Grid((n, n), 5.5 * a0_table2())
    times = jnp.linspace(0.0, 3 * TAU, nt)
    for label, kwargs, solver in (
        ("normal", {}, jc.Rounds()),  # the grid's: jc.solve's default is the rings
        ("coupled_friction", dict(friction=0.3, coupling="full"), None),
    ):
        scene = jc.Scene(
            grid, jc.Sphere(R), zener(ratio), times, normal=jc.Force(W), **kwargs
        )
        t = time.perf_counter()
        sol = _block(jc.solve(scene, solver=solver))
        total = time.perf_counter() - t
        res = {
            "total_s_including_compile": total,
            "converged": bool(np.asarray(sol.converged).all()),
            "iterations": int(np.asarray(sol.iterations).sum()),
            "stick_ratio_end": float(sol.stick_ratio[-1]),
        }
        out[label] = res
        log(
            f"  (e) Table 2, ratio {ratio}, {n}^2, {nt} steps, {label}: "
            f"{total:6.1f} s including "
            f"compilation" + ("" if res["converged"] else "  NOT CONVERGED")
        )
    return out


# ---- Main ----------------------------------------------------------------------------


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "--quick",
        action="store_true",
        help="small sizes, skip part (e) and n = 256 in (a)",
    )
    parser.add_argument(
        "--out", type=Path, default=None,
        help="JSON path (default results/viscoelastic/<machine>.json)",
    )
    parser.add_argument(
        "--parts",
        default="abcde",
        help="which parts to run (letters a-e); results are merged into --out",
    )
    return parser.parse_args(argv)


def main(argv=None) -> int:
    args = parse_args(argv)
    machine = machine_info()
    print(
        f"Viscoelastic benchmark on {machine['processor']} "
        f"({machine['cpu_count_usable']} "
        f"usable CPUs), jax {machine['jax']}, {machine['device']}"
        + (" [--quick]" if args.quick else "")
    )

    def log(msg):
        print(msg, flush=True)

    start = time.perf_counter()
    variant = "quick" if args.quick else None
    out = args.out or results_path("viscoelastic", variant)
    record = header("viscoelastic", argv, variant)
    record["machine"]["load_average_before"] = list(os.getloadavg())
    record["settings"] = {"quick": args.quick, "parts": args.parts}
    results = {}
    parts = set(args.parts)
    quick = args.quick
    if "a" in parts:
        results["a_lee_radok"] = part_a(
            (64, 128) if quick else (64, 128, 256),
            (11, 21, 41) if quick else (11, 21, 41, 81), log)
    if "b" in parts:
        results["b_history_paths"] = part_b(
            (20, 80, 320) if quick else (20, 40, 80, 160, 320, 640), log)
    if "c" in parts:
        results["c_step_cost"] = part_c((128,) if quick else (128, 256), log)
    if "d" in parts:
        results["d_target_scene"] = part_d(log)
    if "e" in parts and not quick:
        results["e_table2"] = part_e(log)
    record["machine"]["load_average_after"] = list(os.getloadavg())
    record["rows"] = [row for part, value in results.items()
                      for row in part_rows(part, value)]
    if out.exists() and args.parts != "abcde":  # merge: keep the other parts' rows
        previous = load_results(out)
        kept = [r for r in previous["rows"] if r["part"] not in results]
        record["rows"] = kept + record["rows"]
        record["settings"]["merged"] = {
            "parts": sorted({r["part"] for r in kept}),
            "date": previous["date"], "commit": previous["commit"]}
    record["summary"] = {"wall_s": time.perf_counter() - start}
    path = write_results(record, out)
    print(f"wrote {path} ({record['summary']['wall_s']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
