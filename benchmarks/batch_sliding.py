"""A batch with gross-sliding members: `vmap` over friction coefficients, normal loads
or moduli against a Python loop over the same scenes (issue 31, item 3).

Scene: elastic sphere (R = 10 mm, G = 1.93 MPa, nu = 0.3) on a 32^2 grid of 2.4 mm,
W = 0.15 N, one step, coupling `--coupling` ("none": the rounds' tangential CG;
"full": the joint solver). The batch axis (`--axis`):

- `friction`: mu per member, F_x = 0.02 N (sliding where mu W < F_x);
- `load`: W per member, mu = 0.2, F_x = 0.02 N (sliding where 0.2 W < F_x);
- `material`: G per member, mu = 0.2, the rigid displacement delta_x = 3 um (sliding
  where the body is stiff enough that the displacement exceeds the slip onset).

Under `vmap` a `cond(gross_sliding, slide, cg)` becomes a `select` that runs both
branches for every member: before the fix the CG of a sliding member (no static
solution) ran to `max_steps`. Reported: the loop's and the batch's time after
compilation (best of `--repeats`), their ratio, and the largest difference between the
two answers.

    python benchmarks/batch_sliding.py [--axis friction|load|material]
        [--coupling none|full] [--configs 8:0 8:3 8:8 64:20] [--max-steps 2000]

Results: `benchmarks/results/batch_sliding/<machine>_<axis>_<coupling>.json` (layout:
`results/SCHEMA.md`), a row per batch configuration.
"""

import argparse
import json
import sys
import time
from pathlib import Path

import jax


jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402


ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
from _common import header, write_results  # noqa: E402

import jaxcontact as jc  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--configs", nargs="+", default=["8:0", "8:3", "8:8", "64:20"],
                        help="BATCH:SLIDING pairs")
    parser.add_argument("--max-steps", type=int, default=2000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--axis", choices=["friction", "load", "material"],
                        default="friction")
    parser.add_argument("--coupling", choices=["none", "full"], default="none")
    parser.add_argument("--out", default=None, help="JSON path (default "
                        "results/batch_sliding/<machine>_<axis>_<coupling>.json)")
    args = parser.parse_args()
    record = header("batch_sliding", variant=f"{args.axis}_{args.coupling}")
    rows = [run(args, *map(int, c.split(":"))) for c in args.configs]
    settings = dict(axis=args.axis, coupling=args.coupling, configs=args.configs,
                    max_steps=args.max_steps, repeats=args.repeats)
    path = write_results(dict(**record, settings=settings, rows=rows), args.out)
    print(f"wrote {path}")


def run(args, batch_size, n_sliding):
    grid = jc.Grid((32, 32), 2.4e-3)
    w, fx, g = 0.15, 0.02, 1.93e6
    stuck, slides = batch_size - n_sliding, n_sliding
    # Member parameters: the first `stuck` in partial slip, the rest sliding.
    values = {
        "friction": np.concatenate([np.linspace(0.3, 0.5, stuck),
                                    np.linspace(0.05, 0.12, slides)]),
        "load": np.concatenate([np.linspace(0.12, 0.2, stuck),
                                np.linspace(0.04, 0.09, slides)]),
        "material": np.concatenate([np.linspace(0.5, 1.0, stuck) * g,
                                    np.linspace(6.0, 10.0, slides) * g]),
    }[args.axis]

    def solve(value):
        mu, load, modulus = 0.2, w, g
        x = jc.Force(fx)
        if args.axis == "friction":
            mu = value
        elif args.axis == "load":
            load = value
        else:
            modulus, x = value, jc.Displacement(3e-6)
        scene = jc.Scene(grid, jc.Sphere(10e-3), jc.Elastic(modulus, 0.3), jnp.zeros(1),
                         jc.Force(load), x=x, friction=mu, coupling=args.coupling)
        sol = jc.solve(scene, max_steps=args.max_steps, throw=False)
        return sol.tangential_force[0, 0], sol.sliding[0], sol.iterations[0]

    one = jax.jit(solve)
    batch = jax.jit(jax.vmap(solve))

    def loop():
        return [jax.block_until_ready(one(m)) for m in values]

    def batched():
        return jax.block_until_ready(batch(jnp.asarray(values)))

    def best(fn):
        fn()
        times = []
        for _ in range(args.repeats):
            start = time.perf_counter()
            out = fn()
            times.append(time.perf_counter() - start)
        return min(times), out

    t_loop, looped = best(loop)
    t_batch, (force, sliding, its) = best(batched)
    diff = max(abs(float(a[0]) - float(b)) for a, b in zip(looped, force))
    row = dict(axis=args.axis, coupling=args.coupling, batch=batch_size,
               sliding_members=int(np.sum(np.asarray(sliding))),
               max_steps=args.max_steps, loop_s=t_loop, vmap_s=t_batch,
               vmap_over_loop=t_batch / t_loop, force_difference_N=diff,
               iterations=np.asarray(its).tolist(), values=values.tolist())
    print(json.dumps(row), flush=True)
    return row


if __name__ == "__main__":
    main()
