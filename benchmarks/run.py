"""One-command benchmark: run time against error, side by side with peer solvers.

Three problems with analytic answers, over grid size n, number of time steps Nt and
float64/float32 (SI units, rigid sphere R = 10 mm, W = 0.15 N, nu = 0.3):

- Hertz (`jc.solve_normal`, G = 1 MPa, square of side 4a, non-periodic): peak
  pressure, contact radius and approach against `jc.Hertz` (the case function of
  `benchmarks/hertz.py`, which also times one padded rfft2/irfft2 pair of size 2n in
  the same process: the floor of one CG iteration);
- Cattaneo-Mindlin (`jc.solve`, coupling "none", mu = 0.3, F_x = mu W / 2 reached in
  Nt equal increments at constant W, side 4a): stick radius against
  a (1 - F/(mu W))^(1/3) and the tangential compliance against Johnson's one-body
  formula;
- Lee-Radok (`jc.solve`, Zener mu_inf/mu_0 = 10, paper Table 2 otherwise, step load,
  T = 3 tau, side 5.5 a0, schemes "constant" and "linear"): contact radius and
  approach against Lee & Radok (closed form from J(t)).

Each (problem, n, dtype) runs in its own subprocess, so that the compile time (first
call minus the best later call) and the peak memory (`ru_maxrss` of that process,
Linux; the import baseline is reported beside it) belong to that case alone.

Peers: the Hertz problem is solved with ContactMechanics (non-periodic, the same
Love/DC-FFT discretisation) and Tamaas (periodic only: compared with jaxcontact on
the same periodic grid), each tolerance tuned until its error against Hertz matches
jaxcontact's converged error within 10 %; jaxcontact's own tolerance is tuned the same
way; then the two are timed interleaved (best of several rounds) and the time ratio
reported. The peers run in another Python (`--peer-python`, default
`$JAXCONTACT_PEER_PYTHON`, else `/tmp/peers-venv/bin/python` if it exists, else this
one) through `benchmarks/peers.py`; a peer that does not import is skipped with its
error recorded.

Usage::

    python benchmarks/run.py --quick           # a few minutes
    python benchmarks/run.py --full            # tens of minutes
    python benchmarks/run.py --quick --only hertz peers --no-plot

Results: `benchmarks/results/run/<machine>_{quick,full}.json` (layout:
`results/SCHEMA.md`: rows tagged by `part`, `hertz`, `cattaneo`, `leeradok` or `peers`;
the peer Python and its probe in `settings.peers`) and, with matplotlib, PNG plots
`<machine>_{quick,full}_{hertz,cattaneo,leeradok,scaling}.png` next to it.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
import types
from pathlib import Path


HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

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
    rows_of,
    write_results,
)


# Error of a peer (or of a loose jaxcontact tolerance) "matches" the reference error
# when |e - e_ref| <= MATCH * |e_ref|, for every matched metric.
MATCH = 0.10

MODES = {
    "quick": {
        "hertz_sizes": [64, 128, 256],
        "cattaneo_sizes": [64, 128],
        "cattaneo_nts": [1, 4],
        "leeradok_sizes": [64, 128],
        "leeradok_nts": [11, 21, 41],
        "dtypes": ["float64", "float32"],
        "peer_sizes": [256],
        "peer_rounds": 3,
        "repeats": 3,
        "timeout_s": 600,
    },
    "full": {
        "hertz_sizes": [64, 128, 256, 512, 1024],
        "cattaneo_sizes": [64, 128, 256],
        "cattaneo_nts": [1, 4, 16],
        "leeradok_sizes": [64, 128, 256],
        "leeradok_nts": [11, 21, 41, 81],
        "dtypes": ["float64", "float32"],
        "peer_sizes": [256, 512],
        "peer_rounds": 5,
        "repeats": 5,
        "timeout_s": 3000,
    },
}

SINGLE_THREAD_XLA = "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1"


def _maxrss_mib() -> float:
    """Peak resident set of this process [MiB] (Linux reports ru_maxrss in KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _loadavg():
    try:
        return list(os.getloadavg())
    except OSError:
        return None


# =====================================================================================
# Worker side: one case per process. Imports jax lazily so that the parent stays light.
# =====================================================================================


def _worker_imports():
    import jax

    jax.config.update("jax_enable_x64", True)
    sys.path.insert(0, str(ROOT))
    sys.path.insert(0, str(HERE))
    import jax.numpy as jnp
    import numpy as np

    import jaxcontact as jc

    return jax, jnp, np, jc


def _best_of(fn, repeats):
    """(best time of `repeats` calls [s], all times, last output); `fn` must block."""
    times, out = [], None
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return min(times), times, out


def worker_hertz(spec):
    jax, jnp, np, jc = _worker_imports()
    import hertz

    base = _maxrss_mib()
    args = types.SimpleNamespace(
        rtol=None, max_steps=2000, control="force", repeats=spec["repeats"]
    )
    notes: list[str] = []
    row = hertz.run_case(spec["n"], spec["dtype"], args, notes)
    row["notes"] = notes
    row["maxrss_mib"] = _maxrss_mib()
    row["baseline_rss_mib"] = base
    return row


def _cast(jnp, dtype, value):
    return jnp.asarray(value, dtype)


def worker_cattaneo(spec):
    jax, jnp, np, jc = _worker_imports()
    base = _maxrss_mib()
    dtype = {"float64": jnp.float64, "float32": jnp.float32}[spec["dtype"]]
    n, mu, ratio, width = spec["n"], 0.3, 0.5, 4.0
    R, W, G, NU = RADIUS, FORCE, SHEAR_MODULUS, POISSON  # cattaneo.py's sphere
    A = float(jc.Hertz(R, W, G, NU).contact_radius)
    grid = jc.Grid((n, n), _cast(jnp, dtype, width * A))
    dx = float(grid.spacing[0])
    sphere = jc.Sphere(_cast(jnp, dtype, R), centre=jnp.zeros(2, dtype))
    material = jc.Elastic(_cast(jnp, dtype, G), _cast(jnp, dtype, NU))
    op = jc.HalfSpace(grid, "none", tangential_y=False)
    c_ref = A * (1 - ratio) ** (1 / 3)
    delta_ref = 3 * mu * W * (2 - NU) / (16 * G * A) * (1 - (1 - ratio) ** (2 / 3))
    floor = fft_floor(n, dtype, spec["repeats"])
    rows = []
    for nt in spec["nts"]:
        fx = ratio * mu * W * np.arange(1, nt + 1) / nt

        def make(scale, nt=nt, fx=fx):
            return jc.Scene(
                grid,
                sphere,
                material,
                times=jnp.arange(nt, dtype=dtype),
                normal=jc.Force(_cast(jnp, dtype, W * scale)),
                x=jc.Force(_cast(jnp, dtype, fx)),
                friction=_cast(jnp, dtype, mu),
                coupling="none",
            )

        def run(scale=1.0, make=make):
            sol = jc.solve(make(scale), operator=op)
            jax.block_until_ready(sol.pressure)
            return sol

        t = time.perf_counter()
        sol = run()
        first = time.perf_counter() - t
        best, times, _ = _best_of(lambda: run(1 + 1e-9), spec["repeats"])
        c_num = np.sqrt(float(sol.stick[-1].sum()) * float(grid.cell_area) / np.pi)
        its = int(np.asarray(sol.iterations).sum())
        rows.append(
            {
                "n": n,
                "nt": nt,
                "dtype": spec["dtype"],
                "solution_dtype": str(sol.pressure.dtype),
                "cells_per_radius": A / dx,
                "first_call_s": first,
                "compile_s": first - best,
                "solve_s": best,
                "solve_s_all": times,
                "step_s": best / nt,
                "iterations": its,
                "rounds": int(np.asarray(sol.rounds).sum()),
                "converged": bool(np.asarray(sol.converged).all()),
                "residual_max": float(np.asarray(sol.residual).max()),
                "time_per_iteration_s": best / its if its else None,
                "conv_naive_s": floor,
                "iteration_over_conv_naive": best / its / floor if its else None,
                "errors": {
                    "stick_radius_cells": (c_num - c_ref) / dx,
                    "stick_radius_rel": c_num / c_ref - 1,
                    "compliance_rel": float(sol.tangential_displacement[-1, 0])
                    / delta_ref
                    - 1,
                    "tangential_force_rel": float(sol.tangential_force[-1, 0])
                    / (ratio * mu * W)
                    - 1,
                },
                "maxrss_mib": _maxrss_mib(),
            }
        )
    return {"rows": rows, "baseline_rss_mib": base}


def worker_leeradok(spec):
    jax, jnp, np, jc = _worker_imports()
    import viscoelastic as ve  # Table 2 constants, StepLeeRadok, equivalent_radius

    base = _maxrss_mib()
    dtype = {"float64": jnp.float64, "float32": jnp.float32}[spec["dtype"]]
    n, ratio = spec["n"], 10.0
    material64 = ve.zener(ratio)
    material = jc.Zener(
        _cast(jnp, dtype, ve.MU_INF),
        _cast(jnp, dtype, ve.MU_INF / ratio),
        _cast(jnp, dtype, ve.TAU),
        _cast(jnp, dtype, ve.NU),
    )
    ref = ve.StepLeeRadok(ve.R, ve.NU, material64, ve.W)
    grid = jc.Grid((n, n), _cast(jnp, dtype, 5.5 * ve.a0_table2()))
    dx = float(grid.spacing[0])
    sphere = jc.Sphere(_cast(jnp, dtype, ve.R), centre=jnp.zeros(2, dtype))
    op = jc.HalfSpace(grid)
    floor = fft_floor(n, dtype, spec["repeats"])
    rows = []
    for nt in spec["nts"]:
        t_np = np.linspace(0.0, 3 * ve.TAU, nt)
        times = jnp.asarray(t_np, dtype)
        a_ref, d_ref = ref.contact_radius(t_np), ref.approach(t_np)
        for scheme in spec["schemes"]:

            def run(scale=1.0, times=times, scheme=scheme):
                scene = jc.Scene(
                    grid,
                    sphere,
                    material,
                    times,
                    normal=jc.Force(_cast(jnp, dtype, ve.W * scale)),
                )
                sol = jc.solve(scene, scheme=scheme, operator=op)
                jax.block_until_ready(sol.pressure)
                return sol

            t = time.perf_counter()
            sol = run()
            first = time.perf_counter() - t
            best, all_t, _ = _best_of(
                lambda run=run: run(1 + 1e-9), max(1, spec["repeats"] - 1)
            )
            a_area = ve.equivalent_radius(sol, grid)
            approach = np.asarray(sol.approach, dtype=np.float64)
            a_appr = np.sqrt(np.maximum(approach, 0.0) * ve.R)
            its = int(np.asarray(sol.iterations).sum())
            rows.append(
                {
                    "n": n,
                    "nt": nt,
                    "dtype": spec["dtype"],
                    "scheme": scheme,
                    "solution_dtype": str(sol.pressure.dtype),
                    "first_call_s": first,
                    "compile_s": first - best,
                    "solve_s": best,
                    "solve_s_all": all_t,
                    "step_s": best / nt,
                    "iterations": its,
                    "iterations_per_step": its / nt,
                    "converged": bool(np.asarray(sol.converged).all()),
                    "time_per_iteration_s": best / its if its else None,
                    "conv_naive_s": floor,
                    "iteration_over_conv_naive": best / its / floor if its else None,
                    "errors": {
                        "contact_radius_cells_max": float(
                            np.max(np.abs(a_area - a_ref)) / dx
                        ),
                        "contact_radius_from_approach_rel_max": float(
                            np.max(np.abs(a_appr / a_ref - 1))
                        ),
                        "approach_rel_max": float(np.max(np.abs(approach / d_ref - 1))),
                    },
                    "maxrss_mib": _maxrss_mib(),
                }
            )
    return {"rows": rows, "baseline_rss_mib": base}


# ---- Peers (run inside a jax worker; the peer runs in its own server process) -------


class PeerServer:
    """`benchmarks/peers.py --serve` in the peer Python; one JSON line per request."""

    def __init__(self, python):
        self.proc = subprocess.Popen(
            [python, str(HERE / "peers.py"), "--serve"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )

    def ask(self, req):
        self.proc.stdin.write(json.dumps(req) + "\n")
        self.proc.stdin.flush()
        line = self.proc.stdout.readline()
        if not line:
            err = self.proc.stderr.read()
            raise RuntimeError(f"peer server died: {err[-2000:]}")
        return json.loads(line)

    def close(self):
        try:
            self.proc.stdin.write('{"cmd": "quit"}\n')
            self.proc.stdin.flush()
            self.proc.wait(timeout=30)
        except Exception:
            self.proc.kill()


def probe_peers(python):
    """Run `peers.py --probe` with `python`: which peers import, or why not."""
    if python is None:
        return {"error": "no peer Python given or found"}
    try:
        out = subprocess.run(
            [python, str(HERE / "peers.py"), "--probe"],
            capture_output=True,
            text=True,
            timeout=300,
        )
    except (OSError, subprocess.SubprocessError) as exc:
        return {"error": f"{type(exc).__name__}: {exc}"}
    if out.returncode != 0:
        return {"error": out.stderr.strip()[-2000:]}
    return json.loads(out.stdout)


def worker_peers(spec):
    jax, jnp, np, jc = _worker_imports()
    import hertz  # DOMAIN_OVER_A

    base = _maxrss_mib()
    n, rounds, repeats = spec["n"], spec["rounds"], spec["repeats"]
    hz = jc.Hertz(RADIUS, FORCE, SHEAR_MODULUS, POISSON)
    a, p0, delta = float(hz.contact_radius), float(hz.peak_pressure), float(hz.approach)
    size = hertz.DOMAIN_OVER_A * a
    e_star = float(hz.effective_modulus)
    material = jc.Elastic(SHEAR_MODULUS, POISSON)
    sphere = jc.Sphere(RADIUS)
    dx = size / n
    tmp = Path(spec["tmpdir"])

    def errors(peak, cells, approach):
        a_num = np.sqrt(cells * dx * dx / np.pi)
        return {
            "peak_pressure_rel": peak / p0 - 1,
            "approach_rel": None if approach is None else approach / delta - 1,
            "contact_radius_cells": (a_num - a) / dx,
        }

    def matches(err, ref, metrics):
        return all(abs(err[m] - ref[m]) <= MATCH * abs(ref[m]) for m in metrics)

    server = PeerServer(spec["peer_python"])
    problems = []
    if spec["probe"].get("contactmechanics", {}).get("available"):
        problems.append(
            (
                "contactmechanics",
                False,
                ["peak_pressure_rel", "approach_rel"],
                [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10],
                "pentol = tol x delta_Hertz (penetration tolerance [m])",
            )
        )
    if spec["probe"].get("tamaas", {}).get("available"):
        problems.append(
            (
                "tamaas",
                True,
                ["peak_pressure_rel"],
                [1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10],
                "PolonskyKeerRey relative tolerance",
            )
        )
    out = {"n": n, "size_m": size, "cells_per_radius": a / dx, "comparisons": []}
    ours_ladder = [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8]
    try:
        for code, periodic, metrics, ladder, tol_meaning in problems:
            grid = jc.Grid((n, n), size, periodic=periodic)
            op = jc.HalfSpace(grid)

            def ours(rtol, scale=1.0, grid=grid, op=op):
                sol = jc.solve_normal(
                    grid,
                    sphere,
                    material,
                    force=FORCE * scale,
                    operator=op,
                    solver=jc.PolonskyKeer(rtol=rtol),
                    throw=False,
                )
                sol.pressure.block_until_ready()
                return sol

            def ours_errors(sol):
                return errors(
                    float(sol.pressure.max()),
                    int(sol.contact.sum()),
                    None if periodic else float(sol.approach),
                )

            ref_sol = ours(1e-10)
            ref = ours_errors(ref_sol)
            ref_p = np.asarray(ref_sol.pressure)
            # jaxcontact's loosest rtol that matches its own converged error.
            ours_walk, ours_rtol = [], None
            for rtol in ours_ladder:
                t = time.perf_counter()
                ours(rtol)
                compile_s = time.perf_counter() - t
                sol = ours(rtol)
                e = ours_errors(sol)
                ours_walk.append(
                    {
                        "rtol": rtol,
                        "iterations": int(sol.iterations),
                        "errors": e,
                        "first_call_s": compile_s,
                    }
                )
                if matches(e, ref, metrics):
                    ours_rtol = rtol
                    break
            if ours_rtol is None:
                ours_rtol = ours_ladder[-1]
            # The peer's loosest tolerance that matches jaxcontact's converged error.
            peer_walk, peer_tol, matched = [], None, False
            base_req = {
                "code": code,
                "n": n,
                "size": size,
                "radius": RADIUS,
                "force": FORCE,
                "e_star": e_star,
                "poisson": POISSON,
                "repeats": 1,
            }
            scale_tol = delta if code == "contactmechanics" else 1.0
            for tol in ladder:
                ans = server.ask({**base_req, "tol": tol * scale_tol})
                if "error" in ans:
                    raise RuntimeError(
                        f"{code}: {ans['error']}\n{ans.get('traceback')}"
                    )
                e = errors(ans["peak_pressure"], ans["contact_cells"], ans["approach"])
                peer_walk.append(
                    {
                        "tol": tol,
                        "errors": e,
                        "time_s": ans["times_s"][0],
                        "iterations": ans["iterations"],
                        "converged": ans["converged"],
                        "setup_s": ans["setup_s"],
                    }
                )
                if matches(e, ref, metrics):
                    peer_tol, matched = tol, True
                    break
            if peer_tol is None:
                peer_tol = ladder[-1]
            # Interleaved timing at the matched tolerances: rounds of (ours, peer).
            ours_times, peer_times, peer_last = [], [], None
            warm_times, warm_last = [], None
            save = str(tmp / f"{code}_{n}.npy")
            # A peer solve longer than a few seconds is timed once per round.
            peer_repeats = repeats if peer_walk[-1]["time_s"] < 2.0 else 1
            for r in range(rounds):
                for i in range(repeats):
                    t = time.perf_counter()
                    sol = ours(ours_rtol, 1 + 1e-9 * (r * repeats + i + 1))
                    ours_times.append(time.perf_counter() - t)
                peer_last = server.ask(
                    {
                        **base_req,
                        "tol": peer_tol * scale_tol,
                        "repeats": peer_repeats,
                        "save": save,
                    }
                )
                if "error" in peer_last:
                    raise RuntimeError(f"{code}: {peer_last['error']}")
                peer_times.extend(peer_last["times_s"])
                # The same peer started from the Hertz guess jaxcontact starts from.
                warm_last = server.ask(
                    {
                        **base_req,
                        "tol": peer_tol * scale_tol,
                        "repeats": peer_repeats,
                        "warm": True,
                    }
                )
                if "error" in warm_last:
                    raise RuntimeError(f"{code} (warm): {warm_last['error']}")
                warm_times.extend(warm_last["times_s"])
            sol = ours(ours_rtol)
            warm_errors = errors(
                warm_last["peak_pressure"],
                warm_last["contact_cells"],
                warm_last["approach"],
            )
            p_peer = np.load(save)
            ours_best, peer_best = min(ours_times), min(peer_times)
            ours_med = float(np.median(ours_times))
            peer_med = float(np.median(peer_times))
            out["comparisons"].append(
                {
                    "peer": code,
                    "periodic": periodic,
                    "matched_metrics": metrics,
                    "match_tolerance": MATCH,
                    "reference_errors": ref,
                    "ours": {
                        "rtol": ours_rtol,
                        "iterations": int(sol.iterations),
                        "errors": ours_errors(sol),
                        "times_s": ours_times,
                        "best_s": ours_best,
                        "median_s": ours_med,
                        "tolerance_walk": ours_walk,
                    },
                    "peer_result": {
                        "tol": peer_tol,
                        "tol_meaning": tol_meaning,
                        "matched": matched,
                        "errors": errors(
                            peer_last["peak_pressure"],
                            peer_last["contact_cells"],
                            peer_last["approach"],
                        ),
                        "iterations": peer_last["iterations"],
                        "times_s": peer_times,
                        "best_s": peer_best,
                        "median_s": peer_med,
                        "tolerance_walk": peer_walk,
                        "peer_process_maxrss_mib": peer_last["maxrss_mib"],
                        "pressure_diff_max_over_p0": float(
                            np.max(np.abs(p_peer - ref_p)) / p0
                        ),
                    },
                    "time_ratio_peer_over_ours_best": peer_best / ours_best,
                    "time_ratio_peer_over_ours_median": peer_med / ours_med,
                    "peer_warm_start": {
                        "what": "the peer at the same tolerance, started from the "
                        "Hertz pressure scaled to W (jaxcontact's own initial guess)",
                        "errors": warm_errors,
                        "matched": matches(warm_errors, ref, metrics),
                        "iterations": warm_last["iterations"],
                        "times_s": warm_times,
                        "best_s": min(warm_times),
                        "median_s": float(np.median(warm_times)),
                        "time_ratio_peer_over_ours_best": min(warm_times) / ours_best,
                        "time_ratio_peer_over_ours_median": float(
                            np.median(warm_times)
                        )
                        / ours_med,
                    },
                }
            )
    finally:
        server.close()
    out["maxrss_mib"] = _maxrss_mib()
    out["baseline_rss_mib"] = base
    return out


WORKERS = {
    "hertz": worker_hertz,
    "cattaneo": worker_cattaneo,
    "leeradok": worker_leeradok,
    "peers": worker_peers,
}


def worker_main(spec_json: str) -> int:
    spec = json.loads(spec_json)
    result = {"spec": spec, "load_before": _loadavg()}
    if spec.get("threads") == "1" and hasattr(os, "sched_setaffinity"):
        # One core for this process and the peer server it starts (inherited), on
        # top of XLA_FLAGS (set by the parent before jax is imported here).
        cpu = min(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {cpu})
        result["cpu_affinity"] = [cpu]
    t = time.perf_counter()
    result["result"] = WORKERS[spec["kind"]](spec)
    result["wall_s"] = time.perf_counter() - t
    result["load_after"] = _loadavg()
    print("RESULT " + json.dumps(result), flush=True)
    return 0


# =====================================================================================
# Parent side: run the workers, collect, summarise, plot.
# =====================================================================================


def run_worker(spec, timeout, env_extra=None, log=print):
    env = dict(os.environ)
    if env_extra:
        env.update(env_extra)
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", json.dumps(spec)]
    label = " ".join(
        f"{k}={v}"
        for k, v in spec.items()
        if k in ("kind", "n", "dtype", "nts", "threads")
    )
    t = time.perf_counter()
    try:
        proc = subprocess.run(
            cmd, capture_output=True, text=True, timeout=timeout, env=env, cwd=str(ROOT)
        )
    except subprocess.TimeoutExpired:
        log(f"  TIMEOUT after {timeout} s: {label}")
        return {"spec": spec, "error": f"timed out after {timeout} s"}
    wall = time.perf_counter() - t
    for line in proc.stdout.splitlines():
        if line.startswith("RESULT "):
            out = json.loads(line[len("RESULT ") :])
            out["process_wall_s"] = wall
            log(f"  done {label} ({wall:.1f} s)")
            return out
    log(f"  FAILED {label} (rc {proc.returncode}):\n{proc.stderr[-3000:]}")
    return {
        "spec": spec,
        "error": f"rc {proc.returncode}",
        "stderr_tail": proc.stderr[-3000:],
    }


def find_peer_python(given):
    if given:
        return given
    env = os.environ.get("JAXCONTACT_PEER_PYTHON")
    if env:
        return env
    venv = Path("/tmp/peers-venv/bin/python")
    return str(venv) if venv.exists() else sys.executable


def pareto_front(points):
    """Indices of the points (time, error) not dominated by another (less time and
    less error), sorted by time."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], float("inf")
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def _fit_exponent(xs, ys):
    import numpy as np

    pts = [(x, y) for x, y in zip(xs, ys) if x and y and x > 0 and y > 0]
    if len(pts) < 2:
        return None
    return float(
        np.polyfit(np.log([p[0] for p in pts]), np.log([p[1] for p in pts]), 1)[0]
    )


def summarise(out):
    """Pareto fronts, cost growth with n (per CG iteration, per solve) and with Nt."""
    s = {}
    hz = [r for r in out.get("hertz", []) if "errors" in r]
    for metric in ("peak_pressure_rel", "approach_rel", "contact_radius_cells"):
        pts = [(r["solve_s"], abs(r["errors"][metric])) for r in hz]
        s[f"hertz_pareto_{metric}"] = [
            {
                "n": hz[i]["n"],
                "dtype": hz[i]["dtype"],
                "solve_s": pts[i][0],
                "error": pts[i][1],
            }
            for i in pareto_front(pts)
        ]
    growth = {}
    for dtype in sorted({r["dtype"] for r in hz}):
        sel = [r for r in hz if r["dtype"] == dtype and r["n"] >= 128]
        ns = [r["n"] for r in sel]
        growth[dtype] = {
            "solve_vs_n": _fit_exponent(ns, [r["solve_s"] for r in sel]),
            "iteration_time_vs_n": _fit_exponent(
                ns, [r["time_per_iteration_s"] for r in sel]
            ),
            "fft_floor_vs_n": _fit_exponent(ns, [r["conv_naive_s"] for r in sel]),
            "iterations_vs_n": _fit_exponent(ns, [r["iterations"] for r in sel]),
            "iteration_over_fft_floor": {
                r["n"]: r["iteration_over_conv_naive"] for r in sel
            },
            "peak_rss_mib": {r["n"]: r["maxrss_mib"] for r in sel},
        }
    s["hertz_growth_exponents_n>=128"] = growth
    cm = [r for r in out.get("cattaneo", []) if "errors" in r]
    pts = [(r["solve_s"], abs(r["errors"]["stick_radius_rel"])) for r in cm]
    s["cattaneo_pareto_stick_radius"] = [
        {
            "n": cm[i]["n"],
            "nt": cm[i]["nt"],
            "dtype": cm[i]["dtype"],
            "solve_s": pts[i][0],
            "error": pts[i][1],
        }
        for i in pareto_front(pts)
    ]
    lr = [r for r in out.get("leeradok", []) if "errors" in r]
    pts = [
        (r["solve_s"], r["errors"]["contact_radius_from_approach_rel_max"]) for r in lr
    ]
    s["leeradok_pareto_radius_from_approach"] = [
        {
            "n": lr[i]["n"],
            "nt": lr[i]["nt"],
            "dtype": lr[i]["dtype"],
            "scheme": lr[i]["scheme"],
            "solve_s": pts[i][0],
            "error": pts[i][1],
        }
        for i in pareto_front(pts)
    ]
    nt_growth = {}
    for key in sorted({(r["n"], r["dtype"], r["scheme"]) for r in lr}):
        sel = sorted(
            (r for r in lr if (r["n"], r["dtype"], r["scheme"]) == key),
            key=lambda r: r["nt"],
        )
        nt_growth[f"n={key[0]} {key[1]} {key[2]}"] = _fit_exponent(
            [r["nt"] for r in sel], [r["solve_s"] for r in sel]
        )
    s["leeradok_solve_vs_nt_exponent"] = nt_growth
    ratios = []
    for p in out.get("peers", {}).get("results", []):
        for c in p.get("result", {}).get("comparisons", []):
            ratios.append(
                {
                    "peer": c["peer"],
                    "n": p["result"]["n"],
                    "threads": p["spec"].get("threads", "default"),
                    "periodic": c["periodic"],
                    "matched": c["peer_result"]["matched"],
                    "ours_rtol": c["ours"]["rtol"],
                    "peer_tol": c["peer_result"]["tol"],
                    "ours_best_s": c["ours"]["best_s"],
                    "peer_best_s": c["peer_result"]["best_s"],
                    "ratio_best": c["time_ratio_peer_over_ours_best"],
                    "ratio_median": c["time_ratio_peer_over_ours_median"],
                    "ratio_best_peer_warm": c.get("peer_warm_start", {}).get(
                        "time_ratio_peer_over_ours_best"
                    ),
                    "ratio_median_peer_warm": c.get("peer_warm_start", {}).get(
                        "time_ratio_peer_over_ours_median"
                    ),
                }
            )
    s["peer_time_ratios"] = ratios
    return s


def plot_all(out, stem: Path, log=print):
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as exc:
        log(f"no plots (matplotlib: {exc})")
        return []
    written = []

    def finish(fig, axes, name, title, xlabel="run time after compilation [s]"):
        for ax in axes:
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xlabel(xlabel)
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=7)
        axes[0].set_title(title, fontsize=10)
        fig.tight_layout()
        path = stem.with_name(f"{stem.name}_{name}.png")
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(str(path))

    def front_line(ax, pts):
        idx = pareto_front(pts)
        ax.plot(
            [pts[i][0] for i in idx],
            [pts[i][1] for i in idx],
            "k--",
            lw=0.8,
            label="Pareto front",
        )

    def annotate(ax, labels, pts):
        for label, (x, y) in zip(labels, pts):
            ax.annotate(
                str(label),
                (x, y),
                fontsize=6,
                textcoords="offset points",
                xytext=(3, 3),
            )

    hz = [r for r in out.get("hertz", []) if "errors" in r]
    if hz:
        fig, axes = plt.subplots(1, 3, figsize=(13, 4))
        for ax, metric, lab in zip(
            axes,
            ("peak_pressure_rel", "contact_radius_cells", "approach_rel"),
            (
                "|peak pressure error| / p0",
                "|contact radius error| [cells]",
                "|approach error| / delta",
            ),
        ):
            allpts = []
            for dtype, m in (("float64", "o-"), ("float32", "s--")):
                sel = [r for r in hz if r["dtype"] == dtype]
                pts = [
                    (r["solve_s"], max(abs(r["errors"][metric]), 1e-12)) for r in sel
                ]
                if pts:
                    allpts += pts
                    ax.plot(*zip(*pts), m, label=dtype)
                    annotate(ax, [r["n"] for r in sel], pts)
            front_line(ax, allpts)
            ax.set_ylabel(lab)
        finish(fig, list(axes), "hertz", "Hertz, load control (labels: n)")
    cm = [r for r in out.get("cattaneo", []) if "errors" in r]
    if cm:
        fig, ax = plt.subplots(figsize=(6, 4.5))
        pts_all = []
        for key in sorted({(r["dtype"], r["nt"]) for r in cm}):
            sel = sorted(
                (r for r in cm if (r["dtype"], r["nt"]) == key), key=lambda r: r["n"]
            )
            pts = [
                (r["solve_s"], max(abs(r["errors"]["stick_radius_rel"]), 1e-12))
                for r in sel
            ]
            pts_all += pts
            ax.plot(
                *zip(*pts),
                "o-" if key[0] == "float64" else "s--",
                label=f"{key[0]} Nt={key[1]}",
            )
            annotate(ax, [r["n"] for r in sel], pts)
        front_line(ax, pts_all)
        ax.set_ylabel("|stick radius error| / c")
        finish(fig, [ax], "cattaneo", "Cattaneo-Mindlin, coupling none (labels: n)")
    lr = [r for r in out.get("leeradok", []) if "errors" in r]
    if lr:
        fig, ax = plt.subplots(figsize=(6.5, 4.8))
        pts_all = []
        for key in sorted({(r["dtype"], r["scheme"], r["n"]) for r in lr}):
            sel = sorted(
                (r for r in lr if (r["dtype"], r["scheme"], r["n"]) == key),
                key=lambda r: r["nt"],
            )
            pts = [
                (
                    r["solve_s"],
                    max(r["errors"]["contact_radius_from_approach_rel_max"], 1e-12),
                )
                for r in sel
            ]
            pts_all += pts
            ax.plot(
                *zip(*pts),
                ("o-" if key[1] == "linear" else "^:"),
                label=f"{key[0]} {key[1]} n={key[2]}",
            )
            annotate(ax, [r["nt"] for r in sel], pts)
        front_line(ax, pts_all)
        ax.set_ylabel("max |sqrt(R delta) / a_LR - 1|")
        finish(fig, [ax], "leeradok", "Lee-Radok, Zener ratio 10 (labels: Nt)")
    if hz:
        fig, ax = plt.subplots(figsize=(6, 4.5))
        for dtype, m, color in (("float64", "o", "C0"), ("float32", "s", "C1")):
            sel = [r for r in hz if r["dtype"] == dtype and r["time_per_iteration_s"]]
            if sel:
                ax.plot(
                    [r["n"] for r in sel],
                    [r["time_per_iteration_s"] for r in sel],
                    m + "-",
                    color=color,
                    label=f"{dtype}: time per CG iteration",
                )
                ax.plot(
                    [r["n"] for r in sel],
                    [r["conv_naive_s"] for r in sel],
                    m + ":",
                    color=color,
                    mfc="none",
                    label=f"{dtype}: one padded rfft2/irfft2 pair (2n)",
                )
        ax.set_ylabel("seconds")
        finish(
            fig,
            [ax],
            "scaling",
            "Hertz: cost per CG iteration against the FFT floor",
            xlabel="n (n x n cells)",
        )
    return written


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    mode = ap.add_mutually_exclusive_group()
    mode.add_argument(
        "--quick", action="store_true", help="small sizes (a few minutes)"
    )
    mode.add_argument("--full", action="store_true", help="all sizes (tens of minutes)")
    mode.add_argument("--worker", help=argparse.SUPPRESS)
    ap.add_argument(
        "--only",
        nargs="+",
        choices=["hertz", "cattaneo", "leeradok", "peers"],
        help="run only these parts",
    )
    ap.add_argument(
        "--peer-python",
        default=None,
        help="Python with tamaas/contactmechanics (default: "
        "$JAXCONTACT_PEER_PYTHON, /tmp/peers-venv/bin/python, this one)",
    )
    ap.add_argument(
        "--peer-threads",
        choices=["default", "1", "both"],
        default=None,
        help="jaxcontact threads in the peer comparison: XLA's default "
        "(all cores), 1 (the peers run single-threaded), or both "
        "(default: both with --full, default with --quick)",
    )
    ap.add_argument(
        "--out",
        type=Path,
        default=None,
        help="JSON path (default benchmarks/results/run/<machine>_{quick,full}.json)",
    )
    ap.add_argument("--no-plot", action="store_true", help="write no PNG")
    ap.add_argument(
        "--merge",
        action="store_true",
        help="keep the parts not run now from the existing JSON at the output path "
        "(their machine block and date are kept beside them in settings.merged)",
    )
    return ap.parse_args(argv)


def main(argv=None) -> int:
    args = parse_args(argv)
    if args.worker:
        return worker_main(args.worker)
    mode = "full" if args.full else "quick"
    cfg = MODES[mode]
    parts = args.only or ["hertz", "cattaneo", "leeradok", "peers"]
    threads = args.peer_threads or ("both" if mode == "full" else "default")
    t0 = time.perf_counter()
    record = header("run", argv, variant=mode)  # imports jax (in the parent only)
    out_path = Path(args.out or results_path("run", mode, record["machine"]["name"]))
    machine = record["machine"]
    machine["load_average_before"] = _loadavg()
    log = lambda msg: print(msg, flush=True)  # noqa: E731
    log(
        f"run.py --{mode} on {machine['processor']} ({machine['cpu_count_usable']} "
        f"usable CPUs), load {machine['load_average_before']}"
    )
    out = {
        **record,
        "settings": {**cfg, "parts": parts, "match": MATCH, "peer_threads": threads},
        "memory_method": (
            "peak resident set size (resource.getrusage(RUSAGE_SELF).ru_maxrss, KiB on "
            "Linux, reported in MiB) of the subprocess that ran the case, which "
            "includes the Python + JAX + jaxcontact import baseline given as "
            "baseline_rss_mib; for a worker running several Nt the figure is the peak "
            "up to that row. "
            "Peers: ru_maxrss of the peer server process (NumPy + the peer)."
        ),
        "timing_method": (
            "compile_s = first call minus the best later call (same shapes, load "
            "changed by ~1e-9 so that nothing is reused but the compiled program); "
            "solve_s = best of the later calls, wall clock, block_until_ready. "
            "conv_naive_s = one padded rfft2/irfft2 pair of size 2n x 2n timed in a "
            "jitted fori_loop in the same process (the floor of one CG iteration)."
        ),
    }
    timeout = cfg["timeout_s"]
    common = {"repeats": cfg["repeats"]}
    if "hertz" in parts:
        log("Hertz")
        out["hertz"] = []
        for dtype in cfg["dtypes"]:
            for n in cfg["hertz_sizes"]:
                res = run_worker(
                    {"kind": "hertz", "n": n, "dtype": dtype, **common},
                    timeout,
                    log=log,
                )
                out["hertz"].append(
                    res.get("result", res)
                    | {
                        "load_before": res.get("load_before"),
                        "load_after": res.get("load_after"),
                    }
                )
    if "cattaneo" in parts:
        log("Cattaneo-Mindlin")
        out["cattaneo"] = []
        for dtype in cfg["dtypes"]:
            for n in cfg["cattaneo_sizes"]:
                res = run_worker(
                    {
                        "kind": "cattaneo",
                        "n": n,
                        "dtype": dtype,
                        "nts": cfg["cattaneo_nts"],
                        **common,
                    },
                    timeout,
                    log=log,
                )
                if "result" in res:
                    base = res["result"]["baseline_rss_mib"]
                    out["cattaneo"] += [
                        r | {"baseline_rss_mib": base} for r in res["result"]["rows"]
                    ]
                else:
                    out["cattaneo"].append(res)
    if "leeradok" in parts:
        log("Lee-Radok")
        out["leeradok"] = []
        for dtype in cfg["dtypes"]:
            for n in cfg["leeradok_sizes"]:
                res = run_worker(
                    {
                        "kind": "leeradok",
                        "n": n,
                        "dtype": dtype,
                        "nts": cfg["leeradok_nts"],
                        "schemes": ["constant", "linear"],
                        **common,
                    },
                    timeout,
                    log=log,
                )
                if "result" in res:
                    base = res["result"]["baseline_rss_mib"]
                    out["leeradok"] += [
                        r | {"baseline_rss_mib": base} for r in res["result"]["rows"]
                    ]
                else:
                    out["leeradok"].append(res)
    if "peers" in parts:
        log("Peers")
        python = find_peer_python(args.peer_python)
        probe = probe_peers(python)
        out["peers"] = {"python": python, "probe": probe, "results": []}
        log(f"  peer Python {python}: {json.dumps(probe)}")
        available = [
            k
            for k in ("tamaas", "contactmechanics")
            if probe.get(k, {}).get("available")
        ]
        if not available:
            out["peers"]["skipped"] = "no peer imports in the peer Python (see probe)"
        else:
            import tempfile

            tmpdir = tempfile.mkdtemp(prefix="jaxcontact-peers-")
            thread_modes = ["default", "1"] if threads == "both" else [threads]
            for n in cfg["peer_sizes"]:
                for th in thread_modes:
                    spec = {
                        "kind": "peers",
                        "n": n,
                        "rounds": cfg["peer_rounds"],
                        "repeats": cfg["repeats"],
                        "peer_python": python,
                        "probe": probe,
                        "tmpdir": tmpdir,
                        "threads": th,
                    }
                    env = {"XLA_FLAGS": SINGLE_THREAD_XLA} if th == "1" else None
                    out["peers"]["results"].append(
                        run_worker(spec, timeout, env_extra=env, log=log)
                    )
    out["machine"]["load_average_after"] = _loadavg()
    if args.merge and out_path.exists():
        prev = sections(load_results(out_path))
        kept = [k for k in ("hertz", "cattaneo", "leeradok", "peers")
                if k in prev and k not in parts]
        for k in kept:
            out[k] = prev[k]
        out["merged"] = {"parts": kept, **{k: prev["record"][k] for k in (
            "date", "command", "machine", "commit", "dirty", "versions")},
            "total_time_s": prev["record"]["summary"].get("total_time_s")}
    out["summary"] = summarise(out)
    out["total_time_s"] = time.perf_counter() - t0
    log(f"wrote {write_results(to_record(out), out_path)}")
    if not args.no_plot:
        for p in plot_all(out, out_path.with_suffix("")):
            log(f"wrote {p}")
    print_summary(out, log)
    log(
        f"total {out['total_time_s']:.0f} s; load average before "
        f"{machine['load_average_before']}, after {machine['load_average_after']}"
    )
    return 0


def to_record(out: dict) -> dict:
    """The results file (`results/SCHEMA.md`) of `main`'s `out`: its parts as rows
    tagged `part`; the methods, the peer Python and a merge in `settings`."""
    keys = ("benchmark", "variant", "date", "command", "machine", "commit", "dirty",
            "versions")
    record = {k: out[k] for k in keys}
    settings = {**out["settings"], "memory_method": out["memory_method"],
                "timing_method": out["timing_method"]}
    rows = []
    for part in ("hertz", "cattaneo", "leeradok"):
        rows += part_rows(part, out.get(part, []))
    if "peers" in out:
        settings["peers"] = {k: v for k, v in out["peers"].items() if k != "results"}
        rows += part_rows("peers", out["peers"]["results"])
    if "merged" in out:
        settings["merged"] = out["merged"]
    summary = {**out["summary"], "total_time_s": out["total_time_s"]}
    return {**record, "settings": settings, "rows": rows, "summary": summary}


def sections(record: dict) -> dict:
    """The parts of a results file written by `to_record`, as `main` holds them
    (and the record itself under `"record"`)."""
    parts = {row["part"] for row in record["rows"]}
    out = {p: rows_of(record, p) for p in ("hertz", "cattaneo", "leeradok")
           if p in parts}
    if "peers" in parts or "peers" in record["settings"]:
        out["peers"] = {**record["settings"].get("peers", {}),
                        "results": rows_of(record, "peers")}
    out["record"] = record
    return out


def print_summary(out, log=print):
    for r in out.get("hertz", []):
        if "errors" in r:
            log(
                f"hertz {r['dtype']} n={r['n']:5d}: solve {r['solve_s']:.4f} s, "
                f"compile {r['compile_s']:.1f} s, {r['iterations']} it, it/FFT floor "
                f"{r['iteration_over_conv_naive'] or float('nan'):.2f}, p0 err "
                f"{r['errors']['peak_pressure_rel']:+.1e}, a err "
                f"{r['errors']['contact_radius_cells']:+.2f} cells, peak RSS "
                f"{r['maxrss_mib']:.0f} MiB"
            )
    for r in out.get("cattaneo", []):
        if "errors" in r:
            log(
                f"CM {r['dtype']} n={r['n']:4d} Nt={r['nt']:3d}: solve "
                f"{r['solve_s']:.3f} s, compile {r['compile_s']:.1f} s, "
                f"{r['iterations']} it, stick radius err "
                f"{r['errors']['stick_radius_cells']:+.2f} cells, compliance err "
                f"{r['errors']['compliance_rel']:+.1e}"
            )
    for r in out.get("leeradok", []):
        if "errors" in r:
            log(
                f"LR {r['dtype']} n={r['n']:4d} Nt={r['nt']:3d} {r['scheme']:8s}: "
                f"solve {r['solve_s']:.3f} s, compile {r['compile_s']:.1f} s, "
                f"{r['iterations_per_step']:.1f} it/step, a err "
                f"{r['errors']['contact_radius_cells_max']:.2f} cells, sqrt(R delta) "
                f"err {r['errors']['contact_radius_from_approach_rel_max']:.1e}"
            )
    for c in out.get("summary", {}).get("peer_time_ratios", []):
        log(
            f"peer {c['peer']} n={c['n']} (jaxcontact threads {c['threads']}, periodic "
            f"{c['periodic']}, matched {c['matched']}): ours {c['ours_best_s']:.4f} s "
            f"at rtol {c['ours_rtol']:g}, peer {c['peer_best_s']:.4f} s at tol "
            f"{c['peer_tol']:g}: peer/ours {c['ratio_best']:.1f}x (best), "
            f"{c['ratio_median']:.1f}x (median)"
        )
        if c.get("ratio_best_peer_warm") is not None:
            log(
                f"    peer started from the Hertz guess: peer/ours "
                f"{c['ratio_best_peer_warm']:.1f}x (best), "
                f"{c['ratio_median_peer_warm']:.1f}x (median)"
            )


if __name__ == "__main__":
    sys.exit(main())
