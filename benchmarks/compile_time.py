"""Compile and solve time of every preset's first and second `jc.solve` call.

Each preset is built at `--n` (64) with its steps cut to `--steps` (21) where it takes
a `steps` argument, and solved in a FRESH process per (preset, solver) so that no
compiled program is shared: the first call (tracing + XLA compilation + the solve)
and a second call on the same scene (the solve alone). The solvers compared:

- `default`: what `jc.solve` picks (coupled scenes: `JointPCG()` since session 20;
  `Fallback(JointPCG(), Rounds())` before);
- `joint`: `jc.JointPCG()` alone on coupled scenes (the default elsewhere).

Usage::

    python benchmarks/compile_time.py                 # every preset, both solvers
    python benchmarks/compile_time.py --presets lc sliding --solvers default

Results: `benchmarks/results/compile_time/<machine>.json` (`--variant`: a name after
the machine's, e.g. for an older tree's `--root`; layout: `results/SCHEMA.md`; per
row: preset, solver, first and second call [s], compile = first - second, iterations,
converged; the machine block with its load average, since compile time on a shared
2-core machine varies ~2x).
"""

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path


ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _common import header, write_results  # noqa: E402


_CHILD = r"""
import inspect, json, sys, time
import jax
jax.config.update("jax_enable_x64", True)
sys.path.insert(0, {root!r})
import jaxcontact as jc
name, solver_name, n, steps = {name!r}, {solver!r}, {n}, {steps}
build = jc.presets._lookup(name)
kwargs = dict(n=n)
if "steps" in inspect.signature(build).parameters:
    kwargs["steps"] = steps
scene = jc.presets.build(name, **kwargs)
coupled = scene.tangential_directions > 0 and scene.coupling != "none"
solver = jc.JointPCG() if (solver_name == "joint" and coupled) else None
def run():
    sol = jc.solve(scene, solver=solver, throw=False)
    jax.block_until_ready(sol)
    return sol
t = time.perf_counter(); sol = run(); first = time.perf_counter() - t
t = time.perf_counter(); sol = run(); second = time.perf_counter() - t
print(json.dumps(dict(preset=name, solver=solver_name, coupled=bool(coupled),
                      steps=int(scene.times.shape[0]), first_call_s=first,
                      second_call_s=second, compile_s=first - second,
                      iterations=int(sol.iterations.sum()),
                      converged=bool(sol.converged.all()))))
"""


def main():
    import jaxcontact as jc  # noqa: F401  (the checkout's, for the preset names)

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presets", nargs="+", default=None)
    parser.add_argument("--solvers", nargs="+", default=["default", "joint"])
    parser.add_argument("--n", type=int, default=64)
    parser.add_argument("--steps", type=int, default=21)
    parser.add_argument("--out", default=None,
                        help="JSON path (default results/compile_time/<machine>.json)")
    parser.add_argument("--variant", default=None,
                        help="the file's name after the machine's")
    parser.add_argument("--root", default=str(ROOT),
                        help="the checkout whose jaxcontact is measured (e.g. an older "
                             "commit's `git archive`, for a before/after table)")
    parser.add_argument("--label", default=None,
                        help="a name for this tree in the JSON")
    args = parser.parse_args()
    names = args.presets or list(jc.presets.available())
    rows = []
    load_before = os.getloadavg()
    for name in names:
        for solver in args.solvers:
            code = _CHILD.format(root=args.root, name=name, solver=solver, n=args.n,
                                 steps=args.steps)
            out = subprocess.run([sys.executable, "-c", code], capture_output=True,
                                 text=True, cwd=ROOT)
            if out.returncode != 0:
                rows.append(dict(preset=name, solver=solver,
                                 error=out.stderr.strip().splitlines()[-1]))
            else:
                rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
            print(json.dumps(rows[-1]), flush=True)
    # `commit` is this checkout's, not `--root`'s
    result = header("compile_time", variant=args.variant)
    result["machine"]["load_average_before"] = load_before
    result["settings"] = dict(n=args.n, steps=args.steps, solvers=args.solvers,
                              label=args.label, root=args.root)
    result["rows"] = rows
    print(f"wrote {write_results(result, args.out)}")


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    main()
