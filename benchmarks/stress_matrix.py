"""The stress matrix of issue 31: `jc.solve` across materials, step counts, load scales
and unit systems, dtypes, friction through gross sliding, coupling modes, periodic and
rough surfaces, contact at the grid edge.

Every cell is one scene solved in this process (the first call compiles; the best of
three more is timed) with `throw=False`, and records: `converged` (every step), the most
and the total iterations, `fallbacks`, whether any output is NaN, the solve time [s],
the load balance `max_t |A sum p - W| / W` (load control), and Coulomb's conditions
`max (|q| - mu p) / (mu max p)` over the contact (frictional cells). A cell is FLAGGED
when a step did not converge, when an output is NaN, or when its time per step is more
than 10x the median of its group.

Usage::

    python benchmarks/stress_matrix.py             # every group
    python benchmarks/stress_matrix.py --groups units friction

Results: `benchmarks/results/stress_matrix/<machine>.json` (some `--groups` only:
`<machine>_<groups>.json`; layout: `results/SCHEMA.md`), a row per cell; `--table`
prints the Markdown table of the cells from it.
"""

import argparse
import json
import os
import sys
import time
import warnings
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np


jax.config.update("jax_enable_x64", True)

import jaxcontact as jc  # noqa: E402


ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _common import (  # noqa: E402
    header,
    load_results,
    results_path,
    write_results,
)


GROUPS = ("material", "steps", "load", "units", "friction", "surface")
R, W, G, NU = 10e-3, 0.15, 1.93e6, 0.3  # sphere [m], load [N], modulus [Pa]
TAU = 0.01  # [s]


def _material(name, scale=1.0):
    """`scale`: stress per unit of the scene's stress (unit systems, load scales)."""
    g = G / scale
    return {
        "elastic": lambda: jc.Elastic(g, NU),
        "zener 1.01": lambda: jc.Zener(1.01 * g, g, TAU, NU),
        "zener 3": lambda: jc.Zener(3 * g, g, TAU, NU),
        "zener 100": lambda: jc.Zener(100 * g, g, TAU, NU),
        "maxwell": lambda: jc.Maxwell(g, g * TAU, NU),
        "prony 3": lambda: jc.Prony(0.2 * g, [0.3 * g, 0.3 * g, 0.2 * g],
                                    [TAU / 10, TAU, 10 * TAU], NU),
    }[name]()


def _rough(n, rms, seed=0, hurst=0.8):
    """A seeded self-affine height field `(n, n)` of RMS `rms` (periodic spectrum)."""
    rng = np.random.default_rng(seed)
    k = np.fft.fftfreq(n)
    kk = np.hypot(*np.meshgrid(k, k, indexing="ij"))
    amp = np.where(kk > 0, np.maximum(kk, 1.0 / n) ** (-(1 + hurst)), 0.0)
    amp[kk > 0.25] = 0.0
    field = np.fft.ifft2(amp * np.exp(2j * np.pi * rng.random((n, n)))).real
    return field * rms / field.std()


def cells(groups):
    """`(group, label, scene)` for every requested group."""
    out = []
    if "material" in groups:
        for dtype in ("float64", "float32"):
            for name in ("elastic", "zener 1.01", "zener 3", "zener 100", "maxwell",
                         "prony 3"):
                grid = jc.Grid((32, 32), jnp.asarray(6e-3, dtype))
                times = jnp.linspace(0, 10 * TAU, 21)
                out.append(("material", f"{name}, {dtype}", jc.Scene(
                    grid, jc.Sphere(R), _material(name), times, jc.Force(W))))
    if "steps" in groups:
        for steps in (5, 50, 500, 2000):
            grid = jc.Grid((16, 16), 6e-3)
            times = jnp.linspace(0, 10 * TAU, steps)
            out.append(("steps", f"zener 3, {steps} steps", jc.Scene(
                grid, jc.Sphere(R), _material("zener 3"), times, jc.Force(W))))
    if "load" in groups:
        # Loads and moduli scaled together (the same contact), in SI.
        for dtype in ("float64", "float32"):
            for scale in (1e-6, 1e-3, 1.0, 1e3, 1e6):
                grid = jc.Grid((32, 32), jnp.asarray(6e-3, dtype))
                out.append(("load", f"W x {scale:g}, {dtype}", jc.Scene(
                    grid, jc.Sphere(R), _material("zener 3", 1 / scale),
                    jnp.linspace(0, 10 * TAU, 11), jc.Force(W * scale))))
    if "units" in groups:
        # The frictional Zener scene of issue 31 item 4 in three unit systems.
        for dtype in ("float64", "float32"):
            for name, (length, force) in {"SI": (1.0, 1.0), "mm/N/MPa": (1e-3, 1.0),
                                          "um/uN/MPa": (1e-6, 1e-6)}.items():
                stress = force / length**2
                grid = jc.Grid((32, 32), jnp.asarray(2.4e-3 / length, dtype))
                out.append(("units", f"{name}, {dtype}", jc.Scene(
                    grid, jc.Sphere(R / length), _material("zener 3", stress),
                    jnp.linspace(0, 0.02, 11), jc.Force(W / force),
                    x=jc.Displacement(jnp.linspace(0, 25e-6 / length, 11)),
                    friction=0.3, coupling="full")))
    if "friction" in groups:
        # Partial slip through gross sliding: a tangential load ramp to 0.5 W (above
        # mu W for mu < 0.5) or a displacement ramp to 20 um, for each coupling.
        for coupling in ("none", "x", "full"):
            for control in ("load", "displacement"):
                for mu in (0.0, 0.1, 0.3, 1.0):
                    grid = jc.Grid((24, 24), 3e-3)
                    ramp = jnp.linspace(0, 1, 11)
                    x = (jc.Force(0.5 * W * ramp) if control == "load"
                         else jc.Displacement(20e-6 * ramp))
                    out.append(("friction", f"{coupling}, {control}, mu {mu:g}",
                                jc.Scene(grid, jc.Sphere(R), _material("elastic"),
                                         ramp * 0.02, jc.Force(W), x=x, friction=mu,
                                         coupling=coupling)))
    if "surface" in groups:
        n = 64
        heights = _rough(n, 2e-6)
        for periodic in (False, True):
            grid = jc.Grid((n, n), 1e-3, periodic=periodic)
            out.append(("surface", f"rough, {'periodic' if periodic else 'isolated'}",
                        jc.Scene(grid, jc.Surface(jnp.asarray(heights)),
                                 _material("zener 3"), jnp.linspace(0, 10 * TAU, 11),
                                 jc.Force(0.02))))
        # A sphere whose contact reaches the edge of the grid (warned, solved).
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", jc.EdgeContactWarning)
            grid = jc.Grid((24, 24), 1.5e-3)
            out.append(("surface", "sphere, contact at the edge", jc.Scene(
                grid, jc.Sphere(R), _material("zener 3"), jnp.linspace(0, 10 * TAU, 11),
                jc.Force(W))))
    return out


def measure(scene):
    # The grid's matrix: `jc.solve` would put the frictionless spheres on rings.
    solver = jc.Rounds() if scene.tangential_directions == 0 else None
    sol = jax.block_until_ready(jc.solve(scene, solver=solver, throw=False))
    times = []
    for _ in range(3):
        start = time.perf_counter()
        sol = jax.block_until_ready(jc.solve(scene, solver=solver, throw=False))
        times.append(time.perf_counter() - start)
    solve_s = min(times)
    arrays = [np.asarray(v) for v in jax.tree.leaves(sol)
              if hasattr(v, "dtype") and jnp.issubdtype(v.dtype, jnp.floating)]
    row = dict(
        converged=bool(np.all(sol.converged)),
        failed_steps=int(np.sum(~np.asarray(sol.converged))),
        steps=int(sol.times.shape[0]),
        max_iterations=int(np.max(sol.iterations)),
        iterations=int(np.sum(sol.iterations)),
        fallbacks=int(np.sum(sol.fallbacks)),
        nan=bool(any(np.isnan(a).any() for a in arrays)),
        solve_s=solve_s,
    )
    if isinstance(scene.normal, jc.Force):
        target = np.broadcast_to(np.asarray(scene.normal.value, np.float64),
                                 (row["steps"],))
        load = np.asarray(sol.normal_force, np.float64)
        row["load_balance"] = float(np.max(np.abs(load - target) / np.abs(target)))
    mu = float(scene.friction)
    if mu > 0:
        p = np.asarray(sol.pressure, np.float64)
        q = np.hypot(*np.moveaxis(np.asarray(sol.shear, np.float64), 1, 0))
        excess = np.where(p > 0, q - mu * p, 0.0).max()
        row["coulomb_excess"] = float(excess / (mu * p.max()))
    return row


def flag(rows):
    """Mark each row against its group's median time per step."""
    for group in {r["group"] for r in rows}:
        members = [r for r in rows if r["group"] == group]
        median = float(np.median([r["solve_s"] / r["steps"] for r in members]))
        for r in members:
            r["slow_vs_group"] = (r["solve_s"] / r["steps"]) / median
    for r in rows:
        why = []
        if not r["converged"]:
            why.append(f"{r['failed_steps']} steps not converged")
        if r["nan"]:
            why.append("NaN")
        if r["slow_vs_group"] > 10:
            why.append(f"{r['slow_vs_group']:.0f}x its group's time per step")
        r["flag"] = "; ".join(why)
    return rows


def table(data):
    lines = ["| group | cell | converged | it max / total | fallbacks | load balance | "
             "Coulomb excess | solve [s] | vs group | flag |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in data["rows"]:
        lb = f"{r['load_balance']:.1e}" if "load_balance" in r else "-"
        ce = f"{r['coulomb_excess']:.1e}" if "coulomb_excess" in r else "-"
        lines.append(
            f"| {r['group']} | {r['cell']} | {'yes' if r['converged'] else 'NO'} | "
            f"{r['max_iterations']} / {r['iterations']} | {r['fallbacks']} | {lb} | "
            f"{ce} | "
            f"{r['solve_s']:.3f} | {r['slow_vs_group']:.1f} | {r['flag'] or '-'} |")
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--groups", nargs="+", default=list(GROUPS))
    parser.add_argument("--out", default=None,
                        help="JSON path (default results/stress_matrix/<machine>.json)")
    parser.add_argument("--table", action="store_true",
                        help="print the Markdown table of --out and exit")
    args = parser.parse_args()
    variant = None if set(args.groups) == set(GROUPS) else "_".join(args.groups)
    if args.table:
        print(table(load_results(args.out or results_path("stress_matrix", variant))))
        return
    record = header("stress_matrix", variant=variant)
    rows = []
    for group, label, scene in cells(args.groups):
        row = dict(group=group, cell=label, **measure(scene))
        rows.append(row)
        print(json.dumps(row), flush=True)
        jax.clear_caches()  # each cell its own programs: bounded memory maps
    record["machine"]["load_average_after"] = os.getloadavg()
    data = dict(**record, settings=dict(groups=args.groups), rows=flag(rows))
    print(f"wrote {write_results(data, args.out)}")
    print(table(data))


if __name__ == "__main__":
    main()
