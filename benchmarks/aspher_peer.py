"""ASPHER against jaxcontact on a rough sphere (issue 32, item 4; item 1's ratio).

The problem (the issue's): a Hertz sphere R = 10 mm on a half-space with G = 1.93 MPa,
nu = 0.3 (E* = 2G / (1 - nu)), load W = 0.15 N, plus a seeded self-affine roughness
(Hurst 0.8, wavelengths L/4 ... L/64, fixed Fourier modes, so the same surface is
sampled at every n) of rms 0.15 x the Hertz approach, added to the gap; a
non-periodic square of side L = 5.5 a, n x n cells, load control.

- jaxcontact: `jc.solve_normal(grid, jc.Surface(h), jc.Elastic(G, nu), force=W,
  solver=jc.PolonskyKeer(rtol), operator=op)` with a prebuilt `jc.HalfSpace`; float64,
  and float32 on a float32 grid (float32 surface, material and load).
- ASPHER (`benchmarks/peers.py --serve` run by ASPHER's Python, e.g.
  `/work/aspher-venv/bin/python`): the same gap in its units (unit domain, E* = 1:
  gap / L, p_nominal = W / (L^2 E*), pressure x E* back), `backend="fft"` (the exact
  zero-padded Love-kernel convolution: jaxcontact's discretisation), modes `plain`
  (ContactSolver.solve, Fourier preconditioner, double) and `nested` (solve_nested,
  coarsest 64, double and single).

Error = relative L2 of the pressure against the code's own float64 solve at tolerance
1e-10 (ASPHER: the plain double solve). Time = best of `--repeats` warm solves, the
codes interleaved round by round (A B A B ...), each round recording
`os.getloadavg()`. The tolerances are each code's own (jaxcontact's rtol on the contact
conditions, ASPHER's Frank-Wolfe certificate), so compare at equal error, not equal
tolerance.

At n = 512 it also times one padded convolution (rfft2 / irfft2 of the 2n x 2n
zero-padded field, times the spectrum, in a jitted loop) in the same process, and
reports jaxcontact's time per CG iteration (solve time / iterations) over it.

    PYTHONPATH=. .venv/bin/python benchmarks/aspher_peer.py \
        --peer-python /work/aspher-venv/bin/python

Results go to `benchmarks/results/aspher_peer/<machine>_<surface>[_tamaas].json`
(`--out`; layout: `results/SCHEMA.md`): a row per n (its references, its timed rows
per code, precision, mode and tolerance); the problem in `settings`, the equal-error
times and ratios in `summary`.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import jax


jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402


HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))

from _common import header, load_results, write_results  # noqa: E402

import jaxcontact as jc  # noqa: E402


RADIUS = 10e-3
SHEAR = 1.93e6
NU = 0.3
FORCE = 0.15
E_STAR = 2 * SHEAR / (1 - NU)
A_HERTZ = (3 * FORCE * RADIUS / (4 * E_STAR)) ** (1 / 3)
DELTA_HERTZ = A_HERTZ**2 / RADIUS
SIZE = 5.5 * A_HERTZ
HURST = 0.8
K_LOW, K_HIGH = 4, 64  # wavenumbers in cycles per L
RMS = 0.15 * DELTA_HERTZ
SEED = 32
TIGHT = 1e-10


def roughness(n: int, seed: int = SEED) -> np.ndarray:
    """Self-affine roughness at jaxcontact's cell centres x_i = (i - (n-1)/2) L/n.

    Fixed modes k = (kx, ky) (cycles per L), K_LOW <= |k| <= K_HIGH, on a half plane,
    each with a complex Gaussian coefficient times |k|^-(1 + H), drawn in a fixed order
    from `seed`: the same continuous field at every n >= 2 K_HIGH + 1, scaled to rms
    RMS by its analytic rms (Parseval)."""
    if n < 2 * K_HIGH + 1:
        raise ValueError(f"n must be >= {2 * K_HIGH + 1}")
    rng = np.random.default_rng(seed)
    ks = np.arange(-K_HIGH, K_HIGH + 1)
    kx, ky = np.meshgrid(ks, np.arange(0, K_HIGH + 1), indexing="ij")
    kx, ky = kx.ravel(), ky.ravel()
    k = np.hypot(kx, ky)
    half = (ky > 0) | ((ky == 0) & (kx > 0))
    keep = half & (k >= K_LOW) & (k <= K_HIGH)
    g = rng.standard_normal((kx.size, 2))  # drawn for every mode: order fixed
    c = (g[:, 0] + 1j * g[:, 1]) / np.sqrt(2) * np.where(keep, k, 1.0) ** -(1 + HURST)
    c = np.where(keep, c, 0)
    rms = np.sqrt(2 * np.sum(np.abs(c) ** 2))
    # h(x) = sum_k 2 Re(c_k exp(2 pi i k.x / L)), x/L = i/n - (n-1)/(2n)
    shift = np.exp(-2j * np.pi * (kx + ky) * (n - 1) / (2 * n))
    spec = np.zeros((n, n), complex)
    np.add.at(spec, (kx % n, ky % n), c * shift)
    np.add.at(spec, ((-kx) % n, (-ky) % n), np.conj(c * shift))
    h = np.real(np.fft.ifft2(spec)) * n * n
    return h * (RMS / rms)


def gap_field(n: int, rough: bool = True) -> np.ndarray:
    """Initial gap [m]: sphere r^2 / (2R) + roughness (none if not `rough`: the
    Hertz problem), at the cell centres."""
    dx = SIZE / n
    c = (np.arange(n) - (n - 1) / 2) * dx
    x, y = np.meshgrid(c, c, indexing="ij")
    sphere = (x * x + y * y) / (2 * RADIUS)
    return sphere + roughness(n) if rough else sphere


def rel_l2(p, ref) -> float:
    p, ref = np.asarray(p, np.float64), np.asarray(ref, np.float64)
    return float(np.linalg.norm(p - ref) / np.linalg.norm(ref))


class Peer:
    """`peers.py --serve` in ASPHER's Python, over JSON lines."""

    def __init__(self, python: str):
        # ASPHER uses OpenMP. With the default (active, spinning) wait policy its
        # threads collapse when the 2 cores are shared: a 256^2 solve measured 0.10,
        # 0.46, 2.2 s in a row at load ~5 (0.06 s with passive waiting, 1 or 2
        # threads). Passive waiting is its best case here; recorded in the JSON.
        self.env = {"OMP_WAIT_POLICY": os.environ.get("OMP_WAIT_POLICY", "passive")}
        if "OMP_NUM_THREADS" in os.environ:
            self.env["OMP_NUM_THREADS"] = os.environ["OMP_NUM_THREADS"]
        self.proc = subprocess.Popen(
            [python, str(HERE / "peers.py"), "--serve"],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, bufsize=1,
            env={**os.environ, **self.env},
        )

    def ask(self, req: dict) -> dict:
        self.proc.stdin.write(json.dumps(req) + "\n")
        self.proc.stdin.flush()
        ans = json.loads(self.proc.stdout.readline())
        if "error" in ans:
            raise RuntimeError(f"peer: {ans['error']}\n{ans.get('traceback', '')}")
        return ans

    def close(self):
        try:
            self.proc.stdin.write(json.dumps({"cmd": "quit"}) + "\n")
            self.proc.stdin.flush()
            self.proc.wait(timeout=30)
        except Exception:
            self.proc.kill()


class JC:
    """jaxcontact on this problem, one dtype."""

    def __init__(self, n: int, dtype, h: np.ndarray, smooth: bool = False,
                 periodic: bool = False):
        """`smooth`: the indenter is `jc.Sphere(RADIUS)` (its gap is `h`), as a user
        would pose Hertz; else `jc.Surface(h)`. `periodic`: the doubly periodic
        problem on the same square (Tamaas's ground), else the isolated one."""
        self.dtype = dtype
        self.grid = jc.Grid((n, n), jnp.asarray(SIZE, dtype), periodic=periodic)
        self.material = jc.Elastic(jnp.asarray(SHEAR, dtype), jnp.asarray(NU, dtype))
        self.surface = (jc.Sphere(jnp.asarray(RADIUS, dtype)) if smooth
                        else jc.Surface(jnp.asarray(h, dtype)))
        self.force = jnp.asarray(FORCE, dtype)
        self.op = jax.block_until_ready(jc.HalfSpace(self.grid))

    def solve(self, rtol: float):
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            t = time.perf_counter()
            s = jc.solve_normal(self.grid, self.surface, self.material,
                                force=self.force,
                                solver=jc.PolonskyKeer(rtol=rtol), operator=self.op,
                                throw=False)
            s.pressure.block_until_ready()
            dt = time.perf_counter() - t
        return s, dt, [str(x.message)[:200] for x in w]


def conv_floor(jcase: JC, n: int, repeats: int = 5) -> float:
    """One padded convolution (rfft2/irfft2 on 2n x 2n), as benchmarks/hertz.py."""
    from _common import convolution_times

    spectrum = jcase.material.instantaneous_compliance * jcase.op.normal_spectrum(
        jcase.material.poisson)
    return convolution_times(jcase.op, spectrum, n, jcase.dtype, repeats)["naive"]


def iteration_cost(n: int, steps=(10, 40), repeats: int = 5) -> dict:
    """Marginal cost of one jaxcontact CG iteration, float64, on this problem: solves
    with rtol 1e-30 (never met) stopped at `steps` iterations, interleaved, best of
    `repeats`; (t_long - t_short) / (long - short). Also the eager overhead of
    `jc.solve_normal` (the argument checks and contact estimate) against calling its
    jitted core directly, and one padded convolution in the same process."""
    from jaxcontact import _solve_normal as sn

    jcase = JC(n, jnp.float64, gap_field(n))
    solvers = {k: jc.PolonskyKeer(rtol=1e-30, max_steps=k) for k in steps}
    times = {k: [] for k in steps}
    direct = []
    its = {}
    g, mat = jcase.grid, jcase.material
    h = jcase.surface.gap(g)

    def core(solver):
        return sn._solve(jcase.op, h, mat.instantaneous_compliance, mat.poisson,
                         jcase.force, True, solver)

    for k in steps:  # compile
        s = jc.solve_normal(g, jcase.surface, mat, force=jcase.force,
                            solver=solvers[k], operator=jcase.op, throw=False)
        its[k] = int(s.iterations)
        core(solvers[k]).pressure.block_until_ready()
    loads = []
    for _ in range(repeats):
        loads.append(os.getloadavg()[0])
        for k in steps:
            t = time.perf_counter()
            jc.solve_normal(g, jcase.surface, mat, force=jcase.force,
                            solver=solvers[k], operator=jcase.op, throw=False
                            ).pressure.block_until_ready()
            times[k].append(time.perf_counter() - t)
        t = time.perf_counter()
        core(solvers[steps[-1]]).pressure.block_until_ready()
        direct.append(time.perf_counter() - t)
    lo, hi = steps
    marginal = (min(times[hi]) - min(times[lo])) / (its[hi] - its[lo])
    floor = conv_floor(jcase, n)
    return {
        "n": n, "dtype": "float64", "iterations": its,
        "best_s": {k: min(v) for k, v in times.items()},
        "times_s": times, "loadavg": loads,
        "marginal_iteration_s": marginal,
        "conv_naive_s": floor,
        "marginal_iteration_over_conv_naive": marginal / floor,
        "fixed_cost_s": min(times[lo]) - its[lo] * marginal,
        "jitted_core_best_s": min(direct),
        "eager_overhead_s": min(times[hi]) - min(direct),
    }


def run_n(n: int, tols, repeats: int, peer: Peer | None, tmp: Path, log,
          tamaas: bool = False, rough: bool = True) -> dict:
    h = gap_field(n, rough)
    out: dict = {"n": n, "notes": []}
    p_nom = FORCE / (SIZE**2 * E_STAR)
    gap_file = tmp / f"gap_{n}.npy"
    np.save(gap_file, h / SIZE)
    gap_si = tmp / f"gap_si_{n}.npy"
    np.save(gap_si, h)

    def ask_tamaas(tol, save=None):
        return peer.ask({"code": "tamaas_gap", "n": n, "size": SIZE,
                         "gap_file": str(gap_si), "e_star": E_STAR, "poisson": NU,
                         "force": FORCE, "tol": tol, "save": save})

    jcs = {"float64": JC(n, jnp.float64, h, smooth=not rough),
           "float32": JC(n, jnp.float32, h, smooth=not rough)}
    # References: each code's own float64 solve at TIGHT.
    ref_sol, t_ref, w_ref = jcs["float64"].solve(TIGHT)
    p_ref_jc = np.asarray(ref_sol.pressure)
    out["jaxcontact_reference"] = {
        "rtol": TIGHT, "iterations": int(ref_sol.iterations),
        "converged": bool(ref_sol.converged), "first_call_s": t_ref,
        "contact_fraction": float(np.mean(p_ref_jc > 0)),
        "edge_contact": bool(ref_sol.edge_contact), "warnings": w_ref,
        "force_rel": float(ref_sol.normal_force) / FORCE - 1,
    }
    log(f"n={n} jc ref: {out['jaxcontact_reference']}")
    p_ref_as = None
    if peer is not None:
        ref_file = tmp / f"aspher_ref_{n}.npy"
        a = peer.ask({"code": "aspher", "n": n, "gap_file": str(gap_file),
                      "p_nominal": p_nom, "tol": TIGHT, "mode": "plain",
                      "precision": "double", "save": str(ref_file)})
        p_ref_as = np.load(ref_file) * E_STAR
        a["rel_l2_vs_jaxcontact_reference"] = rel_l2(p_ref_as, p_ref_jc)
        out["aspher_reference"] = a
        log(f"n={n} aspher ref: it {a['iterations']} {a['status']} "
            f"conv {a['converged']} vs jc {a['rel_l2_vs_jaxcontact_reference']:.2e}")

    p_ref_jcp = None
    if peer is not None and tamaas:  # ours on Tamaas's ground: the periodic problem
        for prec, dt in (("float64", jnp.float64), ("float32", jnp.float32)):
            jcs[f"{prec} periodic"] = JC(n, dt, h, smooth=not rough, periodic=True)
        ref_p, _, _ = jcs["float64 periodic"].solve(TIGHT)
        p_ref_jcp = np.asarray(ref_p.pressure)
        out["jaxcontact_periodic_reference"] = {
            "rtol": TIGHT, "iterations": int(ref_p.iterations),
            "converged": bool(ref_p.converged),
            "rel_l2_vs_jaxcontact_reference": rel_l2(p_ref_jcp, p_ref_jc)}

    p_ref_tm = None
    if peer is not None and tamaas:
        ref_file = tmp / f"tamaas_ref_{n}.npy"
        a = ask_tamaas(TIGHT, str(ref_file))
        p_ref_tm = np.load(ref_file)
        a["rel_l2_vs_jaxcontact_reference"] = rel_l2(p_ref_tm, p_ref_jc)
        a["rel_l2_vs_jaxcontact_periodic_reference"] = rel_l2(p_ref_tm, p_ref_jcp)
        out["tamaas_reference"] = a
        log(f"n={n} tamaas ref: conv {a['converged']} {a['times_s'][0]:.2f} s vs jc "
            f"{a['rel_l2_vs_jaxcontact_reference']:.2e} (periodic)")

    configs = [("jaxcontact", "float64", None), ("jaxcontact", "float32", None)]
    if peer is not None:
        configs += [("aspher", "double", "plain"), ("aspher", "double", "nested"),
                    ("aspher", "single", "nested")]
    if peer is not None and tamaas:
        configs += [("tamaas", "double", "periodic"),
                    ("jaxcontact", "float64", "periodic"),
                    ("jaxcontact", "float32", "periodic")]

    def once(cfg, tol, save):
        code, prec, mode = cfg
        if code == "jaxcontact":
            s, dt, w = jcs[prec if mode is None else f"{prec} {mode}"].solve(tol)
            p = np.asarray(s.pressure, np.float64)
            return dt, {"iterations": int(s.iterations), "converged": bool(s.converged),
                        "warnings": w}, p
        f = tmp / "p.npy"
        if code == "tamaas":
            a = ask_tamaas(tol, str(f) if save else None)
            p = np.load(f) if save else None
            info = {k: a[k] for k in ("iterations", "converged", "final_error")}
            return a["times_s"][0], info, p
        a = peer.ask({"code": "aspher", "n": n, "gap_file": str(gap_file),
                      "p_nominal": p_nom, "tol": tol, "mode": mode, "precision": prec,
                      "save": str(f) if save else None})
        p = np.load(f) * E_STAR if save else None
        info = {k: a[k] for k in ("iterations", "converged", "status", "fw_error",
                                  "effective_tol")}
        return a["times_s"][0], info, p

    floor_before = conv_floor(jcs["float64"], n) if n == 512 else None
    rows = []
    for tol in tols:
        res = {cfg: {"times_s": [], "loadavg": []} for cfg in configs}
        for cfg in configs:  # warm-up (jaxcontact: compile), untimed; gives the error
            dt, info, p = once(cfg, tol, True)
            ref = {"jaxcontact": p_ref_jc if cfg[2] is None else p_ref_jcp,
                   "aspher": p_ref_as, "tamaas": p_ref_tm}[cfg[0]]
            res[cfg].update(info)
            res[cfg]["error"] = rel_l2(p, ref)
            res[cfg]["first_call_s"] = dt
        for _ in range(repeats):  # interleaved rounds
            for cfg in configs:
                load = os.getloadavg()[0]
                dt, info, _ = once(cfg, tol, False)
                res[cfg]["times_s"].append(dt)
                res[cfg]["loadavg"].append(load)
        for cfg in configs:
            r = res[cfg]
            r.update(code=cfg[0], precision=cfg[1], mode=cfg[2] or "pcg", tol=tol, n=n,
                     best_s=min(r["times_s"]))
            rows.append(r)
            log(f"n={n} tol={tol:g} {cfg}: best {r['best_s']:.3f} s it "
                f"{r['iterations']} err {r['error']:.2e} conv {r['converged']} "
                f"load {r['loadavg']}")
    out["rows"] = rows
    if n == 512:
        floor_after = conv_floor(jcs["float64"], n)
        floor = min(floor_before, floor_after)
        r64 = [r for r in rows if r["code"] == "jaxcontact"
               and r["precision"] == "float64" and r["mode"] == "pcg"]
        its = np.array([r["iterations"] for r in r64], float)
        best = np.array([r["best_s"] for r in r64])
        slope = intercept = None
        if len(set(its)) > 1:  # marginal cost of one iteration: best time vs iterations
            slope, intercept = (float(v) for v in np.polyfit(its, best, 1))
        out["iteration_vs_conv"] = {
            "conv_naive_s": floor,
            "conv_naive_s_before_after": [floor_before, floor_after],
            "marginal_iteration_s": slope,
            "fixed_cost_s": intercept,
            "marginal_iteration_over_conv_naive":
                None if slope is None else slope / floor,
            "loadavg": os.getloadavg()[0],
            "per_tol": [{"tol": r["tol"],
                         "time_per_iteration_s": r["best_s"] / r["iterations"],
                         "iteration_over_conv_naive":
                             r["best_s"] / r["iterations"] / floor}
                        for r in r64 if r["iterations"] > 0],  # 0: the guess met tol
            "note": "time per iteration = best solve time / iterations (includes the "
                    "solve's set-up: initial guess, final displacement); conv = one "
                    "rfft2/irfft2 pair of the 2n x 2n padded field times the spectrum, "
                    "jitted fori_loop, median of 5, same process, measured before and "
                    "after the timed rows (the smaller kept); marginal_iteration_s = "
                    "slope of a straight-line fit of the best solve time against the "
                    "iteration count over the tolerances",
        }
        log(f"n=512 conv floor {floor * 1e3:.2f} ms: {out['iteration_vs_conv']}")
    return out


def time_at_error(rows, target: float):
    """Best time at relative error `target`, interpolated linearly in log(time) against
    log(error) between the measured tolerances; None outside the measured range."""
    pts = sorted((r["error"], r["best_s"]) for r in rows if r["error"] > 0)
    for (e0, t0), (e1, t1) in zip(pts, pts[1:]):
        if e0 <= target <= e1 and e1 > e0:
            w = (np.log(target) - np.log(e0)) / (np.log(e1) - np.log(e0))
            return float(np.exp((1 - w) * np.log(t0) + w * np.log(t1)))
    return None


def summarise(result: dict, targets=(1e-4, 3e-5, 1e-5)) -> dict:
    """Per n: time of each configuration at equal error, and ratios to jaxcontact."""
    out = {}
    for case in result["rows"]:
        by_cfg: dict = {}
        for r in case["rows"]:
            by_cfg.setdefault(f"{r['code']} {r['precision']} {r['mode']}", []).append(r)
        at = {name: {f"{t:g}": time_at_error(rows, t) for t in targets}
              for name, rows in by_cfg.items()}
        ratios = {}
        for t in targets:
            k = f"{t:g}"
            peers = {nm: v[k] for nm, v in at.items()
                     if nm.startswith("aspher") and v[k]}
            best_peer = min(peers.values()) if peers else None
            tamaas = at.get("tamaas double periodic", {}).get(k)
            for ours in ("jaxcontact float64 pcg", "jaxcontact float32 pcg"):
                mine = at.get(ours, {}).get(k)
                if mine and best_peer:
                    ratios[f"{k} best aspher / {ours.split()[1]}"] = best_peer / mine
                if mine and tamaas:
                    ratios[f"{k} tamaas / {ours.split()[1]}"] = tamaas / mine
                # Tamaas on its own ground: against our periodic solve.
                periodic = at.get(f"{ours[:-4]} periodic", {}).get(k)
                if periodic and tamaas:
                    name = f"{k} tamaas / {ours.split()[1]} periodic"
                    ratios[name] = tamaas / periodic
        out[str(case["n"])] = {"time_at_error_s": at, "ratios": ratios}
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, nargs="+", default=[256, 512])
    ap.add_argument("--tol", type=float, nargs="+", default=[1e-4, 1e-6])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--surface", choices=("rough", "hertz"), default="rough",
                    help="the rough sphere (default) or the smooth Hertz sphere")
    ap.add_argument("--tamaas", action="store_true",
                    help="also Tamaas (periodic PolonskyKeerRey) when the peer's "
                         "Python has it")
    ap.add_argument("--peer-python", default=os.environ.get(
        "JAXCONTACT_ASPHER_PYTHON", "/work/aspher-venv/bin/python"))
    ap.add_argument("--out", default=None, help="JSON path (default "
                    "results/aspher_peer/<machine>_<surface>[_tamaas].json)")
    ap.add_argument("--summarise", metavar="JSON",
                    help="only (re)compute the equal-error summary of a results file")
    ap.add_argument("--iteration-cost", metavar="JSON",
                    help="only measure one CG iteration's marginal cost at the first "
                         "--n and store it in this results file")
    args = ap.parse_args(argv)
    if args.iteration_cost:
        res = load_results(args.iteration_cost)
        res["summary"]["iteration_cost"] = iteration_cost(args.n[0])
        write_results(res, args.iteration_cost)
        print(json.dumps(res["summary"]["iteration_cost"], indent=1))
        return 0
    if args.summarise:
        res = load_results(args.summarise)
        res["summary"] = {**res.get("summary", {}), **summarise(res)}
        write_results(res, args.summarise)
        print(json.dumps(res["summary"], indent=1))
        return 0

    def log(msg):
        print(f"[{time.strftime('%H:%M:%S')}] {msg}", flush=True)

    peer, probe = None, None
    try:
        peer = Peer(args.peer_python)
        probe = peer.ask({"cmd": "probe"})
        probe["env"] = peer.env
        if not probe.get("aspher", {}).get("available"):
            log(f"ASPHER not available: {probe.get('aspher')}")
            peer.close()
            peer = None
    except Exception as exc:
        log(f"peer failed: {exc}")
        peer = None
    result = header("aspher_peer", argv, variant=args.surface
                    + ("_tamaas" if args.tamaas else ""))
    result["machine"]["load_average_before"] = os.getloadavg()
    result["settings"] = {
        "n": args.n, "tol": args.tol, "repeats": args.repeats,
        "problem": {"radius": RADIUS, "shear": SHEAR, "poisson": NU, "force": FORCE,
                    "e_star": E_STAR, "a_hertz": A_HERTZ, "delta_hertz": DELTA_HERTZ,
                    "size": SIZE, "size_over_a": 5.5, "hurst": HURST,
                    "k_cycles_per_L": [K_LOW, K_HIGH], "rms": RMS,
                    "rms_over_delta": 0.15, "seed": SEED, "periodic": False,
                    "control": "load", "tight": TIGHT, "surface": args.surface},
        "peer_probe": probe,
    }
    result["rows"] = []
    with tempfile.TemporaryDirectory() as td:
        try:
            for n in args.n:
                result["rows"].append(
                    run_n(n, args.tol, args.repeats, peer, Path(td), log,
                          tamaas=args.tamaas and bool(
                              (probe or {}).get("tamaas", {}).get("available")),
                          rough=args.surface == "rough"))
        finally:
            if peer is not None:
                peer.close()
    result["machine"]["load_average_after"] = os.getloadavg()
    result["summary"] = summarise(result)
    log(f"wrote {write_results(result, args.out)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
