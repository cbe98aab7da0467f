"""Joint (p, q) solver against the normal/tangential rounds (`jc.JointPCG`,
`jc.Rounds`).

Both solve the same discrete coupled step (normal-tangential coupling "full" unless
stated, float64, rtol 1e-8 on the same residual definitions) and are called the same
way, directly at the step level (`solver.solve(jc.StepProblem, jc.StepGuess)`, each
jitted on its own; time stepping by `lax.scan` with the previous slip carried exactly
as `jaxcontact/_solve.py` does). Rigid sphere R = 10 mm, W = 0.15 N, G = 1 MPa,
nu = 0.3, mu = 0.3, square grid of side 4a (a: Hertz radius).

Cases:

- (a) normal load alone, one step (coupling-induced partial slip);
- (b) Cattaneo-Mindlin: normal load and F_x = 0.5 mu W in one step;
- (c) the normal load ramped in 10 steps (incremental slip law);
- (d) W fixed, tangential displacement delta_x ramped in 10 steps past gross sliding;
- (e) W fixed, F_x ramped to 0.5, 0.9, 1.0, 1.2 mu W (the last two: gross sliding);
- (f) semi-coupled ("x", q_y = 0): Cattaneo-Mindlin as in (b);
- Spence (cattaneo.py): 105^2 over 2.3 a, mu = 0.2, W in 30 increments;
- the ratio of (b) to a normal solve (`jc.solve_normal`) on the same grid.

Reported per case and solver: agreement of (p, q, stick) with the rounds
(max |dp| / max p, max |dq| / (mu max p), stick cells that differ), iterations
(rounds: normal + tangential CG iterations; joint: joint iterations), FFT transforms
of one real 2-D field (counted by a `HalfSpace` whose transforms report to a host
callback, in a separate untimed run), equivalent coupled operator applications
(transforms / (2 (1 + nd))), and wall time after compilation (best of `--repeats`).

Usage::

    python benchmarks/experiments/joint_vs_rounds.py         # n = 128 (Spence at 105)
    python benchmarks/experiments/joint_vs_rounds.py --n 64
    python benchmarks/experiments/joint_vs_rounds.py --speed # jc.solve, both methods

Results go to `benchmarks/results/joint_vs_rounds/joint_vs_rounds.json` (`--speed`:
`benchmarks/results/joint_vs_rounds/coupled_speed.json`).

Notes on the design of `jaxcontact/_solver/joint.py` (what was tried):

- friction bound from the CURRENT pressure at every iteration, shear projected onto
  the moving discs after each step (the brief's first option): the displacement is
  stale after every step, and the iteration thrashes (720 iterations at n = 128);
- current bound with the slip shear "slaved" to the pressure inside the search
  direction (q = mu p e moves with t_p; Galerkin step, Polak-Ribiere): 28-51
  iterations when it converges, but limit cycles at the contact edge in 17 of 30
  cases of a parameter sweep (n = 48..160, mu = 0.1..1, nu = 0..0.45, F/muW = 0..0.95);
- lagged bound (kept): the inner problem is a convex QP, robust in the same sweep
  (the only failures are the cases the rounds cannot solve either: F = 0.95 mu W and
  mu = 0.1 with F = 0.5 mu W, where no stick cell survives; solved since db55c27,
  whose all-slip load multiplier and load fix `joint_robustness.py` measures);
- wired in as the default of the step solver with the rounds as fallback; the one
  failure found by tests/test_joint.py (displacement control past gross sliding with
  the total slip law: the stick set cycles) now gives up after 150 iterations without
  progress and falls back;
- the step: exact minimisation over span{z_p, z_q, previous step} with Parseval
  quadratic forms (no extra inverse FFT), outside changes folded into the next
  forward transform; this replaced a plain PCG with exact resyncs (about the same
  iteration count, ~15 % more applications);
- per-iteration cost (issue 3): the nine Parseval inner products over the padded
  spectra with a broadcast weight ran ~10x slower than plain reductions on XLA:CPU
  (YNN reduction fusions), and the pending-change `cond` copied spectra: ~10 of ~14
  ms per iteration at n = 128. Now the whole change of (p, q) after the projections
  is transformed each iteration (exact displacement, no pending change, no `cond`
  but the bound update), the direction's three quadratic forms come from one pass
  over its spectrum with the weights folded into the symbols, and the spectra stay
  in the (ky, kx) layout of the column FFTs: ~3.5x cheaper per iteration;
- iterations: restart only when variables are freed (as Polonsky-Keer), bound
  update at sigma = 0.3, first-step shear proportional to p under load control,
  slip cells kept on their discs after each step, and the load fix without stick
  cells moving cells along their discs (this also removed the one known failure,
  displacement control past gross sliding with a load-controlled direction).
"""

import argparse
import json
import os
import platform
import sys
import time
from collections import Counter
from pathlib import Path

import jax


jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402


ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

import jaxcontact as jc  # noqa: E402
from jaxcontact._solver.normal import hertzian_guess  # noqa: E402


R, W, G, NU, MU = 10e-3, 0.15, 1e6, 0.3, 0.3

_COUNTS = Counter()


class CountingHalfSpace(jc.HalfSpace):
    """A `HalfSpace` whose transforms report the number of fields to a callback."""

    def forward(self, field):
        n = int(np.prod(field.shape[:-2], dtype=int))
        jax.debug.callback(lambda: _COUNTS.update(fwd=n))
        return super().forward(field)

    def inverse(self, spec):
        n = int(np.prod(spec.shape[:-2], dtype=int))
        jax.debug.callback(lambda: _COUNTS.update(inv=n))
        return super().inverse(spec)


ROUNDS = jc.Rounds(rtol=1e-8)
JOINT = jc.JointPCG(rtol=1e-8)
# What `method="rounds"` / `"joint"` of `jc.solve` were before the solver objects.
SOLVE_WITH = {
    "joint": None,
    "rounds": jc.Fallback(ROUNDS, jc.LoadByDisplacement(ROUNDS)),
}


def rounds_solve(problem, guess):
    return ROUNDS.solve(problem, guess), None


def joint_solve(problem, guess):
    return JOINT.statistics(problem, guess)


def make_runner(solver, op, cfg, h0, nu, mu):
    """A jitted time stepper (`lax.scan`) over `(W_k, T_k)`, as `_solve.py` does it."""
    grid = op.grid
    nd = cfg["nd"]
    nx, ny = grid.shape
    area = grid.cell_area
    history = jnp.zeros((3, nx, ny))
    e_star = 2 * G / (1 - nu)

    def step(carry, inputs):
        p_prev, q_prev, s_prev, p_prev2, q_prev2 = carry
        w_target, t_target = inputs
        have_two = jnp.sum(p_prev2) > 0
        p_start = jnp.where(have_two, jnp.maximum(2 * p_prev - p_prev2, 0), p_prev)
        p_start = jnp.where(p_prev > 0, p_start, 0)
        q_start = jnp.where(have_two, 2 * q_prev - q_prev2, q_prev)
        guess = p_start
        if cfg["normal_force_control"]:
            fresh = hertzian_guess(h0, w_target, e_star, area)
            guess = jnp.where(jnp.sum(p_start) > 0, p_start, fresh)
        problem = jc.StepProblem(
            op, jnp.asarray(1 / G), jnp.asarray(nu), jnp.asarray(mu), h0, history,
            w_target, t_target, s_prev, cfg["nd"], True, cfg["normal_force_control"],
            cfg["tangential_force_control"])
        res, stats = solver(problem, jc.StepGuess(p_start, q_start, normal=guess))
        return (res.pressure, res.shear, res.slip, p_prev, q_prev), (res, stats)

    @jax.jit
    def run(w_targets, t_targets):
        zp = jnp.zeros((nx, ny))
        zq = jnp.zeros((nd, nx, ny))
        _, out = jax.lax.scan(step, (zp, zq, zq, zp, zq), (w_targets, t_targets))
        return out

    return run


def best_time(fn, repeats):
    out = fn()
    jax.block_until_ready(out)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        out = fn()
        jax.block_until_ready(out)
        times.append(time.perf_counter() - start)
    return min(times), out


def case(name, n, width, coupling, tangential_force, normal_force, w_targets, t_targets,
         *, nu=NU, mu=MU, repeats=3):
    grid = jc.Grid((n, n), width * float(jc.Hertz(R, W, G, nu).contact_radius))
    nd = 2 if coupling == "full" else 1
    cfg = dict(nd=nd, normal_force_control=normal_force,
               tangential_force_control=tuple(tangential_force[:nd]))
    h0 = jc.Sphere(R).gap(grid)
    w_targets = jnp.asarray(w_targets, float)
    t_targets = jnp.asarray(t_targets, float)[:, :nd]
    out = {}
    for label, solver in (("rounds", rounds_solve), ("joint", joint_solve)):
        op = jc.HalfSpace(grid, coupling, tangential_y=nd == 2)
        run = make_runner(solver, op, cfg, h0, nu, mu)
        seconds, (res, stats) = best_time(lambda: run(w_targets, t_targets), repeats)
        counting = CountingHalfSpace(grid, coupling, tangential_y=nd == 2)
        _COUNTS.clear()
        jax.block_until_ready(make_runner(solver, counting, cfg, h0, nu, mu)(
            w_targets, t_targets))
        transforms = _COUNTS["fwd"] + _COUNTS["inv"]
        out[label] = dict(
            seconds=seconds, transforms=int(transforms),
            applications=transforms / (2 * (1 + nd)),
            iterations=np.asarray(res.iterations).tolist(),
            rounds=np.asarray(res.rounds).tolist(),
            converged=bool(np.all(res.converged)),
            residual_max=float(np.max(res.residual)),
            sliding=np.asarray(res.sliding).tolist(),
            stick_cells=np.asarray(res.stick.sum(axis=(1, 2))).tolist(),
            _res=res,
        )
    a, b = out["rounds"].pop("_res"), out["joint"].pop("_res")
    p_scale = np.max(np.asarray(a.pressure), axis=(1, 2))
    dp = (np.max(np.abs(np.asarray(a.pressure) - np.asarray(b.pressure)), axis=(1, 2))
          / p_scale)
    dq = (np.max(np.abs(np.asarray(a.shear) - np.asarray(b.shear)), axis=(1, 2, 3))
          / (mu * p_scale))
    dstick = np.sum(np.asarray(a.stick) != np.asarray(b.stick), axis=(1, 2))
    row = dict(case=name, n=n, steps=int(w_targets.shape[0]), coupling=coupling, nu=nu,
               mu=mu, dp_max=float(dp.max()), dq_max=float(dq.max()),
               dstick_max=int(dstick.max()), **{k: out[k] for k in out})
    r, j = out["rounds"], out["joint"]
    print(f"{name:38s} n={n:4d} steps={row['steps']:2d} | rounds "
          f"it={sum(r['iterations']):6d} "
          f"apps={r['applications']:8.1f} t={r['seconds']:7.3f}s "
          f"conv={r['converged']} | "
          f"joint it={sum(j['iterations']):5d} apps={j['applications']:7.1f} "
          f"t={j['seconds']:6.3f}s conv={j['converged']} | speed-up "
          f"{r['seconds'] / j['seconds']:5.1f}x"
          f" | dp={row['dp_max']:.1e} dq={row['dq_max']:.1e} "
          f"dstick={row['dstick_max']}",
          flush=True)
    return row


def normal_reference(n, width=4.0, repeats=3):
    a = float(jc.Hertz(R, W, G, NU).contact_radius)
    grid = jc.Grid((n, n), width * a)
    op = jc.HalfSpace(grid)
    seconds, sol = best_time(lambda: jc.solve_normal(
        grid, jc.Sphere(R), jc.Elastic(G, NU), force=W, operator=op), repeats)
    return dict(n=n, seconds=seconds, iterations=int(sol.iterations),
                applications=int(sol.applications))


def _timed_once(fn):
    start = time.perf_counter()
    out = fn()
    jax.block_until_ready(out)
    return time.perf_counter() - start, out


def speed(sizes=(128, 256), increments=90, repeats=5, methods=("joint", "rounds"),
          widths=None):
    """Through `jc.solve` (what users run): the coupled Cattaneo-Mindlin step (F_x =
    mu W / 2, coupling "full", one step) over a normal solve (`jc.solve_normal`) on the
    same grid (side 4a), and Spence (105^2 over 2.3 a, mu = 0.2, W in `increments`
    steps), for each method. Runs are INTERLEAVED (normal, joint, rounds, normal, ...)
    so that the ratios of one repeat share the machine's load; the median ratio over
    repeats is reported with every time."""
    mat = jc.Elastic(G, NU)
    out = dict(cm=[], spence=None)
    widths = [4.0] * len(sizes) if widths is None else widths
    for n, width in zip(sizes, widths):
        a = float(jc.Hertz(R, W, G, NU).contact_radius)
        grid = jc.Grid((n, n), width * a)
        op_n, op_f = jc.HalfSpace(grid), jc.HalfSpace(grid, "full")
        scene = jc.Scene(grid, jc.Sphere(R), mat, times=jnp.zeros(1),
                         normal=jc.Force(W), x=jc.Force(0.5 * MU * W), friction=MU,
                         coupling="full")
        fns = {
            "normal": lambda: jc.solve_normal(grid, jc.Sphere(R), mat, force=W,
                                              operator=op_n).pressure,
            "joint": lambda: jc.solve(scene, operator=op_f, solver=SOLVE_WITH["joint"]),
            "rounds": lambda: jc.solve(scene, operator=op_f,
                                       solver=SOLVE_WITH["rounds"]),
        }
        fns = {k: f for k, f in fns.items() if k == "normal" or k in methods}
        compile_s, sols = {}, {}
        for k, fn in fns.items():
            compile_s[k], sols[k] = _timed_once(fn)
        times = {k: [] for k in fns}
        for _ in range(repeats):
            for k, fn in fns.items():
                times[k].append(_timed_once(fn)[0])
        ratio = {k: float(np.median(np.array(times[k]) / np.array(times["normal"])))
                 for k in methods}
        row = dict(
            n=n, width_over_a=width, seconds={k: times[k] for k in times},
            best_s={k: min(times[k]) for k in times}, first_call_s=compile_s,
            median_ratio_over_normal=ratio,
            best_ratio_over_normal={k: min(times[k]) / min(times["normal"])
                                    for k in methods},
            iterations={k: int(sols[k].iterations[0]) for k in methods},
            converged={k: bool(sols[k].converged[0]) for k in methods},
        )
        if "rounds" in methods and "joint" in methods:
            pj, pr = (np.asarray(sols["joint"].pressure),
                      np.asarray(sols["rounds"].pressure))
            row["dp_rel"] = float(np.abs(pj - pr).max() / pr.max())
        print(f"CM n={n} width {width}a: median coupled/normal "
              + ", ".join(f"{k} {ratio[k]:.1f}x" for k in methods)
              + f"; best s {json.dumps(row['best_s'])}; it {row['iterations']}; "
              f"first call s {json.dumps(compile_s)}", flush=True)
        out["cm"].append(row)

    if increments <= 0:
        return out
    n, width, mu = 105, 2.3, 0.2
    a = float(jc.Hertz(R, W, G, NU).contact_radius)
    grid = jc.Grid((n, n), width * a)
    op_f = jc.HalfSpace(grid, "full")
    scene = jc.Scene(grid, jc.Sphere(R), mat, times=jnp.arange(increments, dtype=float),
                     normal=jc.Force(W * jnp.arange(1, increments + 1) / increments),
                     friction=mu, coupling="full")
    rows = {}
    sols = {}
    for method in methods:
        first, sols[method] = _timed_once(
            lambda: jc.solve(scene, operator=op_f, solver=SOLVE_WITH[method]))
        rows[method] = dict(first_call_s=first, seconds=[])
    for _ in range(max(1, repeats // 2)):
        for method in methods:
            rows[method]["seconds"].append(
                _timed_once(lambda: jc.solve(scene, operator=op_f,
                                             solver=SOLVE_WITH[method]))[0])
    for method, sol in sols.items():
        ratio = np.asarray(sol.stick_ratio)
        rows[method].update(
            best_s=min(rows[method]["seconds"]),
            c_over_a_final=float(np.sqrt(ratio[-1])),
            iterations_total=int(np.asarray(sol.iterations).sum()),
            rounds_total=int(np.asarray(sol.rounds).sum()),
            all_converged=bool(np.asarray(sol.converged).all()))
    out["spence"] = dict(n=n, width_over_a=width, increments=increments, mu=mu,
                         methods=rows)
    if "rounds" in methods and "joint" in methods:
        pj, pr = (np.asarray(sols["joint"].pressure),
                  np.asarray(sols["rounds"].pressure))
        out["spence"].update(
            dp_rel=float(np.abs(pj - pr).max() / pr.max()),
            dstick_final=int(np.sum(np.asarray(sols["joint"].stick[-1])
                                    != np.asarray(sols["rounds"].stick[-1]))))
    print("Spence:", json.dumps(out["spence"]), flush=True)
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=128)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--skip-spence", action="store_true")
    parser.add_argument("--speed", action="store_true",
                        help="only the jc.solve timings (CM/normal at 128, 256; "
                             "Spence 90)")
    parser.add_argument("--sizes", type=int, nargs="+", default=[128, 256])
    parser.add_argument("--widths", type=float, nargs="+", default=None,
                        help="--speed: grid side / a per size (default 4)")
    parser.add_argument("--methods", nargs="+", default=["joint", "rounds"],
                        help="--speed: coupled methods to time (default both)")
    parser.add_argument("--tag", default="",
                        help="--speed: suffix of the results file "
                             "(coupled_speed<tag>.json)")
    parser.add_argument("--increments", type=int, default=90)
    parser.add_argument(
        "--out",
        default=str(ROOT / "benchmarks/results/joint_vs_rounds/joint_vs_rounds.json"))
    args = parser.parse_args()
    if args.speed:
        results = dict(
            machine=dict(platform=platform.platform(), processor=platform.processor(),
                         python=platform.python_version(), jax=jax.__version__,
                         device=str(jax.devices()[0]), dtype="float64",
                         note="2 cores shared with other jobs: compare ratios of "
                              "interleaved runs, not absolute seconds",
                         load_average_before=os.getloadavg()),
            **speed(tuple(args.sizes), args.increments, args.repeats,
                    tuple(args.methods), args.widths))
        out = Path(args.out).with_name(f"coupled_speed{args.tag}.json")
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(results, indent=2))
        print(f"wrote {out}")
        return
    n, rep = args.n, args.repeats
    ramp = jnp.arange(1, 11) / 10
    a = float(jc.Hertz(R, W, G, NU).contact_radius)
    slide = 3 * MU * W * (2 - NU) / (16 * G * a)  # Mindlin: delta_x at gross sliding
    rows = [
        case("(a) normal load, one step", n, 4.0, "full", (True, True), True,
             [W], [[0.0, 0.0]], repeats=rep),
        case("(b) Cattaneo-Mindlin F=0.5 muW", n, 4.0, "full", (True, True), True,
             [W], [[0.5 * MU * W, 0.0]], repeats=rep),
        case("(c) normal load ramp, 10 steps", n, 4.0, "full", (True, True), True,
             W * ramp, jnp.zeros((10, 2)), repeats=rep),
        case("(d) delta_x ramp to 1.5 x sliding", n, 4.0, "full", (False, True), True,
             jnp.full(10, W), jnp.stack([1.5 * slide * ramp, 0 * ramp], -1),
             repeats=rep),
        case("(e) F_x ramp to 1.2 muW (sliding)", n, 4.0, "full", (True, True), True,
             jnp.full(4, W), [[0.5 * MU * W, 0], [0.9 * MU * W, 0], [MU * W, 0],
                              [1.2 * MU * W, 0]], repeats=rep),
        case("(f) semi-coupled 'x', F=0.5 muW", n, 4.0, "x", (True,), True,
             [W], [[0.5 * MU * W, 0.0]], repeats=rep),
    ]
    if not args.skip_spence:
        inc = 30
        rows.append(case("Spence 105^2, 30 increments, mu=0.2", 105, 2.3, "full",
                         (True, True), True, W * jnp.arange(1, inc + 1) / inc,
                         jnp.zeros((inc, 2)), mu=0.2, repeats=1))
    normal = normal_reference(n, repeats=rep)
    cm = rows[1]
    ratio = dict(normal_solve_s=normal["seconds"],
                 normal_iterations=normal["iterations"],
                 rounds_over_normal=cm["rounds"]["seconds"] / normal["seconds"],
                 joint_over_normal=cm["joint"]["seconds"] / normal["seconds"])
    print("normal solve:", normal, "| coupled CM / normal:", ratio)
    results = dict(
        machine=dict(platform=platform.platform(), processor=platform.processor(),
                     python=platform.python_version(), jax=jax.__version__,
                     device=str(jax.devices()[0]), dtype="float64"),
        cases=rows, normal_reference=normal, cm_over_normal=ratio,
    )
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(results, indent=2))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
