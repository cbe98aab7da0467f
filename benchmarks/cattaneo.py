"""Cattaneo-Mindlin and Spence benchmarks: run time against error of `jc.solve`.

Cases (SI units; rigid sphere R = 10 mm, W = 0.15 N, G = 1 MPa, nu = 0.3):

1. Cattaneo-Mindlin (coupling "none", mu = 0.3, F = mu W / 2, load applied in one
   step) at n = 64 .. 512 over a square of side 4a: solve time after compilation,
   iterations, error of the stick radius (from the stick area) in cells and of the
   tangential compliance against Johnson's one-body formula.
2. The issue's two timed Cattaneo-Mindlin cases: 105^2 cells over 2.3 a and 256^2 over
   5.5 a (about 45 cells per contact radius).
3. The ratio of a frictional solve to a normal solve on the same 256^2 grid, fully
   coupled ("full") and uncoupled ("none"), and the stick radius of each against
   Cattaneo-Mindlin's (which only the uncoupled solve has); also the paper's coupled
   normal load alone (no tangential input, "full", one step) against the same
   normal solve. And that ratio at several tolerances (float64, rtol 1e-4 .. 1e-8,
   each solve's error against its own tightly solved reference, to read the ratio at
   equal error) and in float32 (`--only-ratio-tolerance`: this alone, into the JSON).
4. Spence (coupling "full", nu = 0.3, mu = 0.2): the normal load applied in 90
   increments on 105^2 cells over 2.3 a; the stick radius c/a at the end. Also in
   float32 (its default rtol 1e-5), whose c/a is compared with float64's, and in
   float64 at rtol 1e-5 .. 1e-8 against a reference solved to 1e-10 (run time
   against error).

Usage::

    python benchmarks/cattaneo.py            # everything
    python benchmarks/cattaneo.py --quick    # small sizes, 30 Spence increments

Results go to `benchmarks/results/cattaneo/<machine>.json` (`--quick`:
`<machine>_quick.json`; layout: `results/SCHEMA.md`): rows tagged by `part`
(`cattaneo_mindlin`, `targets`, `normal_vs_coupled`, `spence`, `spence_float32`,
`spence_tolerance`, `ratio_tolerance`); the two tolerance studies' references in
`summary`.
"""

import argparse
import sys
import time
from pathlib import Path

import jax


jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402


ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _common import (  # noqa: E402
    FORCE,
    POISSON,
    RADIUS,
    SHEAR_MODULUS,
    fft_floor,
    header,
    load_results,
    part_rows,
    results_path,
    write_results,
)

import jaxcontact as jc  # noqa: E402


R, W, G, NU = RADIUS, FORCE, SHEAR_MODULUS, POISSON
A = float(jc.Hertz(R, W, G, NU).contact_radius)


def timed(fn, repeats):
    out = fn()
    jax.block_until_ready(out)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        out = fn()
        jax.block_until_ready(out)
        times.append(time.perf_counter() - start)
    return min(times), out


def cattaneo(n, width, mu=0.3, ratio=0.5, repeats=3):
    grid = jc.Grid((n, n), width * A)
    scene = jc.Scene(grid, jc.Sphere(R), jc.Elastic(G, NU), times=jnp.zeros(1),
                     normal=jc.Force(W), x=jc.Force(ratio * mu * W), friction=mu,
                     coupling="none")
    op = jc.HalfSpace(grid, "none", tangential_y=False)
    start = time.perf_counter()
    sol = jc.solve(scene, operator=op)
    jax.block_until_ready(sol.pressure)
    first = time.perf_counter() - start
    seconds, sol = timed(lambda: jc.solve(scene, operator=op), repeats)
    dx = float(grid.spacing[0])
    c_num = np.sqrt(float(sol.stick[0].sum()) * float(grid.cell_area) / np.pi)
    c_ref = A * (1 - ratio) ** (1 / 3)
    delta_ref = 3 * mu * W * (2 - NU) / (16 * G * A) * (1 - (1 - ratio) ** (2 / 3))
    return dict(
        n=n, width_over_a=width, cells_per_radius=A / dx, solve_s=seconds,
        compile_s=first - seconds, iterations=int(sol.iterations[0]),
        converged=bool(sol.converged[0]), residual=float(sol.residual[0]),
        stick_radius_error_cells=(c_num - c_ref) / dx,
        compliance_rel_error=float(sol.tangential_displacement[0, 0]) / delta_ref - 1,
        force_rel_error=float(sol.tangential_force[0, 0]) / (ratio * mu * W) - 1,
    )


def normal_vs_coupled(n=256, width=4.0, mu=0.3, repeats=3):
    grid = jc.Grid((n, n), width * A)
    op = jc.HalfSpace(grid)
    normal_s, _ = timed(lambda: jc.solve_normal(grid, jc.Sphere(R), jc.Elastic(G, NU),
                                                force=W, operator=op).pressure, repeats)
    scene = jc.Scene(grid, jc.Sphere(R), jc.Elastic(G, NU), times=jnp.zeros(1),
                     normal=jc.Force(W), x=jc.Force(0.5 * mu * W), friction=mu,
                     coupling="full")
    op_full = jc.HalfSpace(grid, "full")
    coupled_s, sol = timed(lambda: jc.solve(scene, operator=op_full), repeats)
    # The paper's coupled normal load alone (Fig. 14's scene: no tangential input, the
    # shear only from the coupling), fully coupled, in one step.
    normal_only = jc.Scene(grid, jc.Sphere(R), jc.Elastic(G, NU), times=jnp.zeros(1),
                           normal=jc.Force(W), friction=mu, coupling="full")
    coupled_normal_s, sol_cn = timed(lambda: jc.solve(normal_only, operator=op_full),
                                     repeats)
    # The same frictional scene without the normal-tangential coupling (Cattaneo-
    # Mindlin: the normal solve, then one tangential solve).
    uncoupled = jc.Scene(grid, jc.Sphere(R), jc.Elastic(G, NU), times=jnp.zeros(1),
                         normal=jc.Force(W), x=jc.Force(0.5 * mu * W), friction=mu,
                         coupling="none")
    op_none = jc.HalfSpace(grid, "none", tangential_y=False)
    uncoupled_s, sol_none = timed(lambda: jc.solve(uncoupled, operator=op_none),
                                  repeats)
    # The stick radius of each against Cattaneo-Mindlin's (1 - F / (mu W))^(1/3) a, in
    # cells: the target's "stick radius within one cell" describes the uncoupled solve
    # (the coupling shrinks the stick zone by many cells at nu = 0.3).
    dx = float(grid.spacing[0])
    c_ref = A * 0.5 ** (1 / 3)

    def c_error(s):
        return float(np.sqrt(float(s.stick[0].sum()) * float(grid.cell_area) / np.pi)
                - c_ref) / dx

    return dict(n=n, normal_s=normal_s, coupled_full_s=coupled_s,
                ratio=coupled_s / normal_s, rounds=int(sol.rounds[0]),
                iterations=int(sol.iterations[0]), converged=bool(sol.converged[0]),
                uncoupled_s=uncoupled_s, ratio_uncoupled=uncoupled_s / normal_s,
                coupled_normal_load_s=coupled_normal_s,
                ratio_coupled_normal_load=coupled_normal_s / normal_s,
                iterations_coupled_normal_load=int(sol_cn.iterations[0]),
                stick_radius_error_cells_full=c_error(sol),
                stick_radius_error_cells_uncoupled=c_error(sol_none))


def coupled_fft_floor(n, dtype, repeats=5):
    """Seconds of the FFT floor of ONE fully coupled iteration:
    one forward and one inverse padded FFT per block (p, q_x, q_y), i.e. three padded
    convolutions (`_common.fft_floor`, median of `repeats` jitted loops)."""
    return 3 * fft_floor(n, dtype, repeats)


def spence(n=105, width=2.3, increments=90, mu=0.2, dtype=jnp.float64, repeats=5):
    """Spence's ramp; `dtype` is the grid's (the solve's), rtol its default (1e-8 in
    float64, 1e-5 in float32). The best of `repeats` timed solves (other tenants of a
    shared machine slow single runs by up to 50 %), and the time per joint iteration
    over the coupled FFT floor measured in the same process."""
    grid = jc.Grid((n, n), jnp.asarray(width * A, dtype))
    loads = W * jnp.arange(1, increments + 1) / increments
    scene = jc.Scene(grid, jc.Sphere(R), jc.Elastic(G, NU),
                     times=jnp.arange(increments, dtype=float), normal=jc.Force(loads),
                     friction=mu, coupling="full")
    op = jc.HalfSpace(grid, "full")
    seconds, sol = timed(lambda: jc.solve(scene, operator=op), repeats)
    floor = coupled_fft_floor(n, dtype)
    iterations = int(sol.iterations.sum())
    ratio = np.asarray(sol.stick_ratio)
    return dict(n=n, increments=increments, mu=mu, poisson=NU, solve_s=seconds,
                iteration_s=seconds / iterations, coupled_fft_floor_s=floor,
                iteration_over_floor=seconds / iterations / floor,
                dtype=str(sol.pressure.dtype), cell_over_a=float(grid.spacing[0]) / A,
                c_over_a_final=float(np.sqrt(ratio[-1])),
                c_over_a_half_load=float(np.sqrt(ratio[increments // 2])),
                iterations_total=iterations,
                rounds_total=int(sol.rounds.sum()),
                all_converged=bool(sol.converged.all()))


def spence_versus_tolerance(rtols=(1e-5, 1e-6, 1e-7, 1e-8), n=105, width=2.3,
                            increments=90, mu=0.2):
    """Spence's ramp (float64) at several rtol against a reference solved to 1e-10:
    time, iterations, the largest pressure and shear differences over all steps
    (over the reference's peak pressure), the stick cells that differ (all steps)
    and c/a at the end."""
    grid = jc.Grid((n, n), width * A)
    loads = W * jnp.arange(1, increments + 1) / increments
    scene = jc.Scene(grid, jc.Sphere(R), jc.Elastic(G, NU),
                     times=jnp.arange(increments, dtype=float), normal=jc.Force(loads),
                     friction=mu, coupling="full")
    op = jc.HalfSpace(grid, "full")
    ref = jc.solve(scene, operator=op, rtol=1e-10)
    peak = float(jnp.max(ref.pressure))
    rows = []
    for rtol in rtols:
        seconds, sol = timed(
            lambda rtol=rtol: jc.solve(scene, operator=op, rtol=rtol), 2)
        rows.append(dict(
            rtol=rtol, solve_s=seconds, iterations_total=int(sol.iterations.sum()),
            all_converged=bool(sol.converged.all()),
            c_over_a_final=float(np.sqrt(float(sol.stick_ratio[-1]))),
            pressure_error=float(jnp.max(jnp.abs(sol.pressure - ref.pressure))) / peak,
            shear_error=float(jnp.max(jnp.abs(sol.shear - ref.shear))) / peak,
            stick_cells_differing=int(jnp.sum(sol.stick != ref.stick)),
            stick_cells_differing_final=int(jnp.sum(sol.stick[-1] != ref.stick[-1]))))
    return dict(reference_rtol=1e-10, cell_over_a=float(grid.spacing[0]) / A,
                c_over_a_reference=float(np.sqrt(float(ref.stick_ratio[-1]))),
                rows=rows)


def ratio_versus_tolerance(rtols=(1e-4, 1e-5, 1e-6, 1e-7, 1e-8), n=256, width=4.0,
                           mu=0.3, repeats=5):
    """Section 3's fully coupled step and normal solve at several rtol (float64), each
    against its own reference solved to 1e-11 / 1e-12: time, iterations and the error
    (max over the grid / the reference's peak pressure), so that the ratio can be read
    at equal error; then both in float32 at their default rtol (1e-5), their error
    against the float64 references. Every input is cast to the grid's dtype."""
    rows = []
    refs = {}
    for dtype, ladder in ((jnp.float64, rtols), (jnp.float32, (None,))):
        grid = jc.Grid((n, n), jnp.asarray(width * A, dtype))
        sphere = jc.Sphere(jnp.asarray(R, dtype))
        material = jc.Elastic(jnp.asarray(G, dtype), jnp.asarray(NU, dtype))
        op = jc.HalfSpace(grid)
        op_full = jc.HalfSpace(grid, "full")
        scene = jc.Scene(grid, sphere, material, times=jnp.zeros(1, dtype),
                         normal=jc.Force(jnp.asarray(W, dtype)),
                         x=jc.Force(jnp.asarray(0.5 * mu * W, dtype)), friction=mu,
                         coupling="full")

        def normal(rtol, op=op, grid=grid, sphere=sphere, material=material):
            return jc.solve_normal(grid, sphere, material, force=jnp.asarray(W, dtype),
                                   operator=op, solver=jc.PolonskyKeer(rtol=rtol))

        if not refs:
            refs["p_normal"] = np.asarray(normal(1e-12).pressure)
            ref = jc.solve(scene, operator=op_full, rtol=1e-11)
            refs["p_full"] = np.asarray(ref.pressure[0])
            refs["q_full"] = np.asarray(ref.shear[0])
            refs["stick"] = np.asarray(ref.stick[0])
        for rtol in ladder:
            normal_s, sn = timed(lambda rtol=rtol: normal(rtol), repeats)
            full_s, sf = timed(
                lambda rtol=rtol: jc.solve(scene, operator=op_full, rtol=rtol), repeats)
            peak_n, peak_f = refs["p_normal"].max(), refs["p_full"].max()
            rows.append(dict(
                dtype=jnp.dtype(dtype).name, rtol=rtol, normal_s=normal_s,
                normal_iterations=int(sn.iterations),
                normal_error=float(np.abs(np.asarray(sn.pressure, np.float64)
                                          - refs["p_normal"]).max() / peak_n),
                full_s=full_s, full_iterations=int(sf.iterations[0]),
                full_converged=bool(sf.converged[0]),
                full_pressure_error=float(np.abs(np.asarray(sf.pressure[0], np.float64)
                                                 - refs["p_full"]).max() / peak_f),
                full_shear_error=float(np.abs(np.asarray(sf.shear[0], np.float64)
                                              - refs["q_full"]).max() / peak_f),
                full_stick_cells_differing=int(np.sum(np.asarray(sf.stick[0])
                                                      != refs["stick"])),
                ratio=full_s / normal_s))
    return dict(n=n, width_over_a=width, mu=mu, reference_rtol=(1e-12, 1e-11),
                rows=rows)


def _study(part, study):
    """The rows of a tolerance study tagged `part`, and its other keys (the
    reference) for `summary`."""
    rows = part_rows(part, study["rows"])
    return rows, {k: v for k, v in study.items() if k != "rows"}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--out", default=None,
                        help="JSON path (default results/cattaneo/<machine>.json)")
    parser.add_argument("--only-ratio-tolerance", action="store_true",
                        help="run ratio_versus_tolerance alone and replace its rows "
                        "in --out")
    args = parser.parse_args()
    variant = "quick" if args.quick else None
    if args.only_ratio_tolerance:
        out = Path(args.out or results_path("cattaneo", variant))
        record = load_results(out) if out.exists() else {
            **header("cattaneo", variant=variant), "settings": {"dtype": "float64"},
            "rows": [], "summary": {}}
        rows, reference = _study("ratio_tolerance", ratio_versus_tolerance(
            n=128 if args.quick else 256))
        for row in rows:
            print("full / normal:", row)
        record["rows"] = [r for r in record["rows"]
                          if r.get("part") != "ratio_tolerance"] + rows
        record.setdefault("summary", {})["ratio_tolerance"] = reference
        print(f"updated {write_results(record, out)}")
        return
    sizes = [64, 128] if args.quick else [64, 128, 256, 512]
    results = dict(
        cattaneo_mindlin=[cattaneo(n, 4.0) for n in sizes],
        targets=[cattaneo(105, 2.3), cattaneo(256, 5.5)],
        normal_vs_coupled=normal_vs_coupled(128 if args.quick else 256),
        spence=spence(increments=30 if args.quick else 90),
        spence_float32=spence(increments=30 if args.quick else 90, dtype=jnp.float32),
        spence_tolerance=spence_versus_tolerance(increments=30 if args.quick else 90),
        ratio_tolerance=ratio_versus_tolerance(n=128 if args.quick else 256),
    )
    for row in results["cattaneo_mindlin"] + results["targets"]:
        print(f"CM n={row['n']:4d} width={row['width_over_a']}a "
              f"cells/a={row['cells_per_radius']:.1f} "
              f"solve={row['solve_s']:.3f}s it={row['iterations']} "
              f"c err={row['stick_radius_error_cells']:+.2f} cells "
              f"compliance err={row['compliance_rel_error']:+.1e}")
    print("normal vs coupled:", results["normal_vs_coupled"])
    print("Spence:", results["spence"])
    print("Spence, float32:", results["spence_float32"])
    for row in results["spence_tolerance"]["rows"]:
        print("Spence, float64, rtol:", row)
    for row in results["ratio_tolerance"]["rows"]:
        print("full / normal:", row)
    record = header("cattaneo", variant=variant)
    record["settings"] = {"dtype": "float64", "quick": args.quick, "sizes": sizes}
    record["rows"], record["summary"] = [], {}
    for part, value in results.items():
        if part in ("spence_tolerance", "ratio_tolerance"):
            rows, record["summary"][part] = _study(part, value)
        else:
            rows = part_rows(part, value)
        record["rows"] += rows
    print(f"wrote {write_results(record, args.out)}")


if __name__ == "__main__":
    main()
