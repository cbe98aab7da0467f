"""Semismooth Newton (`semismooth_newton.py`) against `jc.JointPCG` on coupled scenes
(issue 27, item 4): iterations, operator applications, time and compile time.

Both solvers run through `jc.solve(scene, solver=..., throw=False)` at the same `rtol`
and stop on the same residual (JointPCG's, with exact displacements). Scenes:

- Spence (CONTACT's discretisation, `contact_peer.spence_scene`): nu 0.3, mu 0.2,
  45 cells per radius (113^2), 90 stages F (k / 90)^3, full coupling, incremental
  slip, rtol 1e-6 and 1e-8 (`--quick`: 15 cells per radius, 30 stages);
- one-step frictional loads of `joint_robustness.py` (sphere R = 10 mm, W = 0.15 N,
  G = 1 MPa, 48^2 over 4 a, mu 0.3): F_x = 0.6 / 0.95 mu W, nu 0 / 0.3, coupling "x"
  and "full"; and the oblique load (0.7 rad) at 0.95 mu W, nu 0.1 (64^2);
- viscoelastic (Zener mu_inf / mu_0 = 4, tau = 1 s, nu 0.3, 40^2, 20 steps over 3 tau,
  full coupling): F_x ramped to 0.95 mu W and held (creep), and F_x 0 -> 0.8 -> -0.8
  mu W (reversal).

Recorded per scene and solver: first call (compile + solve) and second call (solve),
wall seconds; iterations (JointPCG: its iterations; Newton: GMRES operator
applications, plus its Newton steps and residual evaluations), whether every step
converged, and the contact / stick cells and pressure of the last step against
JointPCG's. Newton's operator applications: one per GMRES iteration, one for the
linearisation and one per line-search trial of each Newton step, 1.5 per
certification; JointPCG's: `applications` of its statistics are not available through
`jc.solve`, so its iterations x 1.5 (its per-iteration cost) is quoted.

Usage::

    python benchmarks/experiments/newton_vs_joint.py            # ~6 min on 2 cores
    python benchmarks/experiments/newton_vs_joint.py --quick    # Spence at N = 15 only

Results: `benchmarks/results/newton_vs_joint/newton_vs_joint.json` (`--out`).
"""

from __future__ import annotations

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


ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import contact_inputs  # noqa: E402
import contact_peer  # noqa: E402
import joint_robustness as jr  # noqa: E402
from _common import library_info, machine_info  # noqa: E402
from semismooth_newton import SemismoothNewton  # noqa: E402

import jaxcontact as jc  # noqa: E402


def spence(n_per_radius, stages):
    text, _ = contact_inputs.spence_input(0.3, 0.2, n_per_radius, stages, eps=1e-6,
                                          wflow=3)
    return contact_peer.spence_scene(text)


def one_step(n, nu, ratio, coupling, angle=None):
    mu = 0.3
    a = float(jc.Hertz(jr.R, jr.W, jr.G, nu if angle is None else 0.3).contact_radius)
    grid = jc.Grid((n, n), 4.0 * a)
    force = ratio * mu * jr.W
    loads = dict(x=jc.Force(force if angle is None else force * np.cos(angle)))
    if angle is not None:
        loads["y"] = jc.Force(force * np.sin(angle))
    return jc.Scene(grid, jc.Sphere(jr.R), jc.Elastic(jr.G, nu), times=jnp.zeros(1),
                    normal=jc.Force(jr.W), friction=mu, coupling=coupling, **loads)


def viscoelastic(program):
    nu, n, steps = 0.3, 40, 20
    a_soft = float(jc.Hertz(jr.R, jr.W, jr.G / 2.5, nu).contact_radius)
    grid = jc.Grid((n, n), 4.0 * a_soft)
    t = jnp.linspace(0.0, 3.0, steps)
    return jc.Scene(grid, jc.Sphere(jr.R), jr.visco_material("zener4", nu), times=t,
                    friction=0.3, coupling="full",
                    **jr.visco_loads(program, t, nu, 0.3))


def scenes(quick):
    if quick:
        return [("spence_N15_K30", spence(15, 30), (1e-6, 1e-8))]
    out = [("spence_N45_K90", spence(45, 90), (1e-6, 1e-8))]
    for coupling in ("x", "full"):
        for nu in (0.0, 0.3):
            for ratio in (0.6, 0.95):
                out.append((f"one_step_{coupling}_nu{nu:g}_F{ratio:g}",
                            one_step(48, nu, ratio, coupling), (1e-8,)))
    out.append(("one_step_oblique_nu0.1_F0.95", one_step(64, 0.1, 0.95, "full", 0.7),
                (1e-8,)))
    for program in ("creep 0.95", "reversal"):
        out.append((f"zener4_{program.replace(' ', '_')}", viscoelastic(program),
                    (1e-8,)))
    return out


def run(scene, solver):
    def call():
        sol = jc.solve(scene, solver=solver, throw=False)
        return jax.block_until_ready(sol)

    jax.clear_caches()
    start = time.perf_counter()
    call()
    first = time.perf_counter() - start
    start = time.perf_counter()
    sol = call()
    second = time.perf_counter() - start
    return sol, first, second


def one(name, scene, rtol):
    row = dict(scene=name, rtol=rtol, grid=list(scene.grid.shape),
               steps=int(scene.times.shape[0]), load_before=os.getloadavg())
    sol_j, first_j, second_j = run(scene, jc.JointPCG(rtol=rtol))
    sol_n, first_n, second_n = run(scene, SemismoothNewton(rtol=rtol))
    it_j = int(sol_j.iterations.sum())
    # Newton: `iterations` are GMRES applications, `rounds` Newton steps.
    gmres_n = int(sol_n.iterations.sum())
    newton_n = int(sol_n.rounds.sum())
    row["joint"] = dict(first_call_s=first_j, second_call_s=second_j,
                        compile_s=first_j - second_j, iterations=it_j,
                        applications_estimate=1.5 * it_j,
                        all_converged=bool(sol_j.converged.all()))
    # Per Newton step: the linearisation (1), at least one line-search trial (1) and
    # the certification (1.5); extra trials are not returned by `jc.solve`.
    row["newton"] = dict(first_call_s=first_n, second_call_s=second_n,
                         compile_s=first_n - second_n, gmres_iterations=gmres_n,
                         newton_steps=newton_n,
                         applications_at_least=gmres_n + 3.5 * newton_n,
                         all_converged=bool(sol_n.converged.all()),
                         steps_not_converged=np.nonzero(
                             ~np.asarray(sol_n.converged))[0].tolist())
    cj, cn = np.asarray(sol_j.contact[-1]), np.asarray(sol_n.contact[-1])
    sj, sn = np.asarray(sol_j.stick[-1]) & cj, np.asarray(sol_n.stick[-1]) & cn
    pj, pn = np.asarray(sol_j.pressure[-1]), np.asarray(sol_n.pressure[-1])
    row["contact_cells_differing"] = int(np.sum(cj != cn))
    row["stick_cells_differing"] = int(np.sum(sj != sn))
    row["pressure_relative_difference"] = float(np.linalg.norm(pj - pn)
                                                / np.linalg.norm(pj))
    row["time_ratio_newton_over_joint"] = second_n / second_j
    row["load_after"] = os.getloadavg()
    return row


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument(
        "--out",
        default=str(ROOT / "benchmarks/results/newton_vs_joint/newton_vs_joint.json"))
    args = parser.parse_args()
    rows = []
    for name, scene, tolerances in scenes(args.quick):
        for rtol in tolerances:
            row = one(name, scene, rtol)
            rows.append(row)
            j, n = row["joint"], row["newton"]
            print(f"{name:34s} rtol {rtol:g}: joint {j['second_call_s']:.2f} s "
                  f"({j['iterations']} it, compile {j['compile_s']:.1f} s) | newton "
                  f"{n['second_call_s']:.2f} s ({n['newton_steps']} Newton, "
                  f"{n['gmres_iterations']} GMRES, compile {n['compile_s']:.1f} s, "
                  f"converged {n['all_converged']}) | ratio "
                  f"{row['time_ratio_newton_over_joint']:.1f}, cells differing "
                  f"{row['contact_cells_differing']}/{row['stick_cells_differing']}",
                  flush=True)
    out = dict(benchmark="newton_vs_joint", machine=machine_info(),
               libraries=library_info(), dtype="float64", rows=rows)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=1))
    print("wrote", args.out)


if __name__ == "__main__":
    main()
