"""Robustness of the joint coupled solver: a sweep of frictional loads, iterations per
step, and whether the joint iteration alone converged (no fallback).

Rigid sphere R = 10 mm, W = 0.15 N, G = 1 MPa on a square grid of side 4 a (a: Hertz
radius), `jc.solve` with `max_steps = 300` and `max_rounds = 3`: a step that needs more
than 300 iterations has gone through the fallbacks of the default solver (the
rounds, the load root search), i.e. the joint iteration gave up. Loads:

- one step, F_x = ratio mu W (mu = 0.3), ratio 0.3 / 0.6 / 0.85 / 0.95 / 0.995,
  nu 0 / 0.1 / 0.2 / 0.3 / 0.45, coupling "x" and "full" (n = 48; `--n` to change);
- float32, one step, n = 64, nu 0 / 0.1 / 0.3, ratio 0.6 / 0.95;
- F_x ramped in 5 steps (mu = 0.5), and an oblique load (F_x, F_y at 0.7 rad) ramped
  in 3 steps, nu 0 / 0.1 / 0.3, ratio 0.6 / 0.95;
- the oblique load in one step near gross sliding, n = 64 on a grid of 4 a(nu = 0.3),
  nu 0 / 0.1 / 0.3, ratio 0.85 / 0.95 / 0.995;
- viscoelastic (`--viscoelastic`, 63 more scenes; `--viscoelastic-only`): Zener
  mu_inf / mu_0 = 4 and 10 and a Maxwell fluid (long-time or spring modulus G,
  retardation / relaxation time tau = 1 s), nu 0.1 / 0.3 / 0.45, 20 steps over 3 tau,
  n = 40 on a grid of 4 a(G / 2.5) (room for the Maxwell creep), full coupling, under
  constant W: F_x ramped over tau to 0.6 / 0.95 mu W and held (creep), an oblique
  0.9 mu W, delta_x ramped to twice Cattaneo-Mindlin's sliding displacement (gross
  sliding), F_x 0 -> 0.8 -> -0.8 mu W (reversal), a (F_x, F_y)
  of 0.7 mu W turning by 180 degrees; and W falling to 0.2 W under a constant
  F_x = 0.25 mu W(0) (gross sliding in the last two steps).

Strong coupling (small nu) with a load near mu W leaves a small stick zone or none at
all (the shear directions fan out): the cases that used to stall (joint.py,
`_SPREAD_WHEN`; tangential.py, `slip_multiplier`).

Usage::

    python benchmarks/joint_robustness.py            # 77 cases, ~2 min on 2 cores
    python benchmarks/joint_robustness.py --quick    # one-step "full" cases only
    python benchmarks/joint_robustness.py --viscoelastic   # + 63 viscoelastic, ~2 min

Results go to `benchmarks/results/joint_robustness/<machine>.json` (with `--quick`, or
without the viscoelastic or the elastic scenes: `<machine>_quick.json`,
`<machine>_elastic.json`, `<machine>_viscoelastic.json`; layout: `results/SCHEMA.md`):
a row per case, its group (`elastic`, `viscoelastic`), its
parameters, the iterations per step, `converged`, `fallback` (a step above
`max_steps`), the final stick ratio and the wall time (including compilation: not a
timing benchmark); `summary` per group.
"""

import argparse
import sys
import time
from pathlib import Path

import jax


jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import jaxcontact as jc  # noqa: E402


ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _common import header, write_results  # noqa: E402


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


VISCO_PROGRAMS = ("creep 0.6", "creep 0.95", "oblique 0.9", "displacement",
                  "reversal", "unloading", "turning")


def visco_material(name, nu, tau=1.0):
    """`zener4` / `zener10` (long-time modulus G) or `maxwell` (spring G)."""
    if name == "maxwell":
        return jc.Maxwell(G, G * tau, nu)
    ratio = {"zener4": 4.0, "zener10": 10.0}[name]
    return jc.Zener(ratio * G, G, tau, nu)


def visco_loads(program, t, nu, mu, tau=1.0):
    """The normal and tangential inputs of one viscoelastic program at times `t`."""
    ramp = jnp.minimum(t / tau, 1.0)
    full_w = jc.Force(jnp.full_like(t, W))
    # Cattaneo-Mindlin's sliding displacement with the soft modulus G.
    a_soft = float(jc.Hertz(R, W, G, nu).contact_radius)
    slide = 3 * mu * W * (2 - nu) / (8 * G * a_soft)
    turn = np.pi * t / t[-1]
    if program.startswith("creep"):
        return dict(normal=full_w, x=jc.Force(float(program[6:]) * mu * W * ramp))
    if program == "oblique 0.9":
        f = 0.9 * mu * W * ramp
        return dict(normal=full_w, x=jc.Force(f * np.cos(0.7)),
                    y=jc.Force(f * np.sin(0.7)))
    if program == "displacement":
        return dict(normal=full_w, x=jc.Displacement(2 * slide * t / t[-1]))
    if program == "reversal":
        half = t[-1] / 2
        tri = jnp.where(t < half, t / half, 1 - 2 * (t - half) / half)
        return dict(normal=full_w, x=jc.Force(0.8 * mu * W * tri))
    if program == "unloading":
        return dict(normal=jc.Force(W * (1 - 0.8 * t / t[-1])),
                    x=jc.Force(jnp.full_like(t, 0.25 * mu * W)))
    if program == "turning":
        f = 0.7 * mu * W * ramp
        return dict(normal=full_w, x=jc.Force(f * jnp.cos(turn)),
                    y=jc.Force(f * jnp.sin(turn)))
    raise ValueError(f"unknown program {program!r}")


def run_viscoelastic_case(material, nu, program, n=40, steps=20, mu=0.3):
    """One viscoelastic scene (see the module docstring)."""
    a_soft = float(jc.Hertz(R, W, G / 2.5, nu).contact_radius)
    grid = jc.Grid((n, n), 4.0 * a_soft)
    t = jnp.linspace(0.0, 3.0, steps)
    scene = jc.Scene(grid, jc.Sphere(R), visco_material(material, nu), times=t,
                     friction=mu, coupling="full", **visco_loads(program, t, nu, mu))
    start = time.perf_counter()
    sol = jc.solve(scene, max_steps=MAX_STEPS, max_rounds=3)
    iterations = np.asarray(sol.iterations).tolist()
    return dict(
        material=material, nu=nu, program=program, n=n, steps=steps, mu=mu,
        coupling="full", dtype="float64", iterations=iterations,
        converged=bool(np.all(sol.converged)),
        fallback=max(iterations) > MAX_STEPS,
        sliding_steps=int(np.sum(sol.sliding)),
        finite=bool(np.all(np.isfinite(np.asarray(sol.pressure)))),
        stick_ratio=float(sol.stick_ratio[-1]),
        seconds=time.perf_counter() - start,
    )


def summarise(rows):
    bad = [r for r in rows if r["fallback"] or not r["converged"]]
    steps = [i for r in rows for i in r["iterations"]]
    return dict(cases=len(rows), fallbacks=len(bad), max_iterations=max(steps),
                median_iterations=float(np.median(steps)), total_iterations=sum(steps))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=48)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--viscoelastic", action="store_true",
                        help="also the 63 viscoelastic scenes")
    parser.add_argument("--viscoelastic-only", action="store_true")
    parser.add_argument("--out", default=None, help="JSON path (default "
                        "results/joint_robustness/<machine>.json)")
    args = parser.parse_args()
    both = args.viscoelastic and not args.viscoelastic_only
    variant = "_".join(
        (["quick"] if args.quick else [])
        + ([] if both else ["viscoelastic" if args.viscoelastic_only else "elastic"])
    ) or None
    rows = []
    for case in ([] if args.viscoelastic_only else cases(args.n, args.quick)):
        row = run_case(*case)
        rows.append(row)
        mark = "  <- FALLBACK" if row["fallback"] or not row["converged"] else ""
        print(f"{row['coupling']:>4} nu {row['nu']:.2f} F/muW {row['ratio']:.3f} "
              f"steps {row['steps']} {row['dtype']} angle {row['angle']}: "
              f"{row['iterations']} stick {row['stick_ratio']:.3f}{mark}", flush=True)
    visco = []
    if args.viscoelastic or args.viscoelastic_only:
        for nu in (0.1, 0.3, 0.45):
            for material in ("zener4", "zener10", "maxwell"):
                for program in VISCO_PROGRAMS:
                    row = run_viscoelastic_case(material, nu, program)
                    visco.append(row)
                    mark = ("  <- FALLBACK" if row["fallback"] or not row["converged"]
                            or not row["finite"] else "")
                    print(f"{material:>8} nu {nu:.2f} {program:>12}: "
                          f"{row['iterations']} sliding {row['sliding_steps']}{mark}",
                          flush=True)
    summary = summarise(rows) if rows else None
    visco_summary = summarise(visco) if visco else None
    print(summary, visco_summary)
    settings = dict(n=args.n, quick=args.quick, viscoelastic=bool(visco),
                    max_steps=MAX_STEPS)
    out = dict(**header("joint_robustness", variant=variant), settings=settings,
               summary=dict(elastic=summary, viscoelastic=visco_summary),
               rows=[dict(group="elastic", **r) for r in rows]
               + [dict(group="viscoelastic", **r) for r in visco])
    print(f"wrote {write_results(out, args.out)}")


if __name__ == "__main__":
    main()
