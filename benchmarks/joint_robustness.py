"""Robustness of the joint coupled solver: a sweep of frictional loads, iterations per
step, and whether the joint iteration alone converged (no fallback).

Rigid sphere R = 10 mm, W = 0.15 N, G = 1 MPa on a square grid of side 4 a (a: Hertz
radius), `jc.solve` with `max_steps = 300` and `max_rounds = 3`: a step that needs more
than 300 iterations has gone through the fallbacks of `coupled.contact_step` (the
rounds, the load root search), i.e. the joint iteration gave up. Loads:

- one step, F_x = ratio mu W (mu = 0.3), ratio 0.3 / 0.6 / 0.85 / 0.95 / 0.995,
  nu 0 / 0.1 / 0.2 / 0.3 / 0.45, coupling "x" and "full" (n = 48; `--n` to change);
- float32, one step, n = 64, nu 0 / 0.1 / 0.3, ratio 0.6 / 0.95;
- F_x ramped in 5 steps (mu = 0.5), and an oblique load (F_x, F_y at 0.7 rad) ramped
  in 3 steps, nu 0 / 0.1 / 0.3, ratio 0.6 / 0.95;
- the oblique load in one step near gross sliding, n = 64 on a grid of 4 a(nu = 0.3),
  nu 0 / 0.1 / 0.3, ratio 0.85 / 0.95 / 0.995.

Strong coupling (small nu) with a load near mu W leaves a small stick zone or none at
all (the shear directions fan out): the cases that used to stall (joint.py,
`_SPREAD_WHEN`; tangential.py, `slip_multiplier`).

Usage::

    python benchmarks/joint_robustness.py            # 77 cases, ~2 min on 2 cores
    python benchmarks/joint_robustness.py --quick    # one-step "full" cases only

Results go to `benchmarks/results/joint_robustness.json`: per case its parameters,
the iterations per step, `converged`, `fallback` (a step above `max_steps`), the
final stick ratio and the wall time (including compilation: not a timing benchmark).
"""

import argparse
import json
import platform
import time
from pathlib import Path

import jax


jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import jaxcontact as jc  # noqa: E402


ROOT = Path(__file__).resolve().parents[1]
R, W, G = 10e-3, 0.15, 1e6
MAX_STEPS = 300


def run_case(n, nu, mu, ratio, coupling, steps, dtype, angle=None, grid_nu=None):
    """One scene; `angle` (rad) adds a y load (F_x, F_y) = F (cos, sin). The grid
    spans 4 Hertz radii of the material (`grid_nu`: of a material with that Poisson
    ratio instead)."""
    a = float(jc.Hertz(R, W, G, nu if grid_nu is None else grid_nu).contact_radius)
    grid = jc.Grid((n, n), jnp.asarray(4.0 * a, dtype))
    t = jnp.arange(steps, dtype=dtype)
    force = ratio * mu * W * (t + 1) / steps
    loads = dict(x=jc.Force(force if angle is None else force * np.cos(angle)))
    if angle is not None:
        loads["y"] = jc.Force(force * np.sin(angle))
    scene = jc.Scene(grid, jc.Sphere(R), jc.Elastic(G, nu), times=t,
                     normal=jc.Force(jnp.full(steps, W, dtype)), friction=mu,
                     coupling=coupling, **loads)
    start = time.perf_counter()
    sol = jc.solve(scene, operator=jc.HalfSpace(grid, coupling), max_steps=MAX_STEPS,
                   max_rounds=3)
    iterations = np.asarray(sol.iterations).tolist()
    return dict(
        n=n, nu=nu, mu=mu, ratio=ratio, coupling=coupling, steps=steps,
        dtype=jnp.dtype(dtype).name, angle=angle, grid_nu=grid_nu,
        iterations=iterations,
        converged=bool(np.all(sol.converged)),
        fallback=max(iterations) > MAX_STEPS,
        stick_ratio=float(sol.stick_ratio[-1]),
        seconds=time.perf_counter() - start,
    )


def cases(n, quick):
    out = []
    couplings = ("full",) if quick else ("x", "full")
    for nu in (0.0, 0.1, 0.2, 0.3, 0.45):
        for ratio in (0.3, 0.6, 0.85, 0.95, 0.995):
            for coupling in couplings:
                out.append((n, nu, 0.3, ratio, coupling, 1, jnp.float64))
    if quick:
        return out
    for nu in (0.0, 0.1, 0.3):
        for ratio in (0.6, 0.95):
            out.append((n, nu, 0.5, ratio, "full", 5, jnp.float64))
            out.append((64, nu, 0.3, ratio, "full", 1, jnp.float32))
            out.append((n, nu, 0.3, ratio, "full", 3, jnp.float64, 0.7))
    # Oblique loads near gross sliding in one step on a grid of 4 a(nu = 0.3) (no
    # stick cell left at 0.95 and 0.995): where joint.py's two-component wrong-slip
    # flip (`_FLIP`) was found (nu 0, 0.95 mu W: 1039 iterations without it).
    for nu in (0.0, 0.1, 0.3):
        for ratio in (0.85, 0.95, 0.995):
            out.append((64, nu, 0.3, ratio, "full", 1, jnp.float64, 0.7, 0.3))
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=48)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument(
        "--out", default=str(ROOT / "benchmarks/results/joint_robustness.json"))
    args = parser.parse_args()
    rows = []
    for case in cases(args.n, args.quick):
        row = run_case(*case)
        rows.append(row)
        mark = "  <- FALLBACK" if row["fallback"] or not row["converged"] else ""
        print(f"{row['coupling']:>4} nu {row['nu']:.2f} F/muW {row['ratio']:.3f} "
              f"steps {row['steps']} {row['dtype']} angle {row['angle']}: "
              f"{row['iterations']} stick {row['stick_ratio']:.3f}{mark}", flush=True)
    bad = [r for r in rows if r["fallback"] or not r["converged"]]
    steps = [i for r in rows for i in r["iterations"]]
    summary = dict(cases=len(rows), fallbacks=len(bad), max_iterations=max(steps),
                   median_iterations=float(np.median(steps)))
    print(summary)
    machine = dict(platform=platform.platform(), processor=platform.processor(),
                   python=platform.python_version(), jax=jax.__version__)
    out = dict(machine=machine, max_steps=MAX_STEPS, summary=summary, cases=rows)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
