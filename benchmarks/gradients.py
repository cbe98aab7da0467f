"""Cost of one reverse-mode gradient through a whole history, against the forward solve.

Scenes (float64, rtol 1e-8, rigid sphere R = 10 mm, W = 0.15 N ramped, Zener
mu_inf = 1.93 MPa, mu_inf / mu_0 = 4, tau = 0.01 s, nu = 0.3, domain 4 a):

- `normal`: frictionless creep indentation, n^2 grid x nt steps;
- `slip`: the same with mu = 0.3 and a tangential displacement ramped over the
  history (coupling "none": partial slip in x);
- `coupled`: `slip` with coupling "full" (p, q_x, q_y interact; GMRES adjoint);
- `coupled_x`: `slip` with coupling "x".

`--controls force,displacement`: the normal load ramped as a force (default) or as the
Hertz approach of that force (displacement control), for every kind.

For each: forward time (`jc.solve`, jitted, after compilation, best of repeats),
gradient time (`jax.grad` of a scalar of the solution w.r.t. (mu_0, tau, poisson, W),
jitted, after compilation), their ratio, and XLA's compiled memory analysis of both
programs (temporary + argument + output bytes: the peak device buffer footprint XLA
plans).

Usage::

    python benchmarks/gradients.py  # 128^2 x 100 steps (the issue's scene)
    python benchmarks/gradients.py --n 64 --nt 40
    python benchmarks/gradients.py --n 64 --nt 50 \
        --kinds normal,slip,coupled_x,coupled \
        --controls force,displacement

Results go to `benchmarks/results/gradients/<machine>_<n>.json` (`--variant`, `--out`;
layout: `results/SCHEMA.md`): a row per kind and control.
"""

import argparse
import json
import os
import time

import jax


jax.config.update("jax_enable_x64", True)
import jax.numpy as jnp  # noqa: E402
from _common import header, write_results  # noqa: E402

import jaxcontact as jc  # noqa: E402


R, W, G, NU = 10e-3, 0.15, 1.93e6, 0.3


def make_loss(n, nt, kind, control="force"):
    a = float(jc.Hertz(R, W, G, NU).contact_radius)
    grid = jc.Grid((n, n), 4 * a)
    times = jnp.linspace(0.0, 0.04, nt)
    ramp = jnp.minimum(1.0, 0.2 + times / 0.02)

    def normal(load):
        if control == "force":
            return jc.Force(load * ramp)
        # The Hertz approach of the load at mu_inf, ramped the same way.
        return jc.Displacement((load / W) * (a * a / R) * ramp)

    def scene_of(params):
        mu_0, tau, poisson, load = params
        material = jc.Zener(mu_inf=G, mu_0=mu_0, tau=tau, poisson=poisson)
        extra = {}
        if kind == "slip":
            extra = dict(x=jc.Displacement(1.5e-6 * times / times[-1]), friction=0.3)
        elif kind in ("coupled", "coupled_x"):
            extra = dict(x=jc.Displacement(1.5e-6 * times / times[-1]), friction=0.3,
                         coupling="full" if kind == "coupled" else "x")
        return jc.Scene(grid, jc.Sphere(R), material, times, normal(load), **extra)

    def forward(params):
        scene = scene_of(params)
        # The grid's gradients: `jc.solve` would put a frictionless sphere on rings.
        return jc.solve(scene, solver=jc.Rounds()
                        if scene.tangential_directions == 0 else None)

    def loss(params):
        sol = forward(params)
        return (1e6 * jnp.sum(sol.approach) + jnp.sum(sol.normal_force)
                + jnp.sum(sol.tangential_force))

    return forward, loss


def _best(fn, arg, repeats):
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(fn(arg))
        best = min(best, time.perf_counter() - start)
    return best


def _memory(compiled):
    try:
        analysis = compiled.memory_analysis()
        return {
            "temp_bytes": int(analysis.temp_size_in_bytes),
            "argument_bytes": int(analysis.argument_size_in_bytes),
            "output_bytes": int(analysis.output_size_in_bytes),
        }
    except Exception as error:  # memory analysis is backend dependent
        return {"error": repr(error)}


def _compiled(fn, arg):
    """`(compiled program, seconds to lower and compile it)`: one compilation serves
    the timings and XLA's memory analysis."""
    start = time.perf_counter()
    compiled = jax.jit(fn).lower(arg).compile()
    return compiled, time.perf_counter() - start


def run_case(n, nt, kind, repeats, control="force"):
    forward, loss = make_loss(n, nt, kind, control)
    params = jnp.array([G / 4, 0.01, NU, W])
    fwd, compile_fwd = _compiled(forward, params)
    grad, compile_grad = _compiled(jax.grad(loss), params)
    sol = jax.block_until_ready(fwd(params))
    g = jax.block_until_ready(grad(params))
    t_fwd = _best(fwd, params, repeats)
    t_grad = _best(grad, params, repeats)
    return {
        "kind": kind, "control": control, "n": n, "nt": nt,
        "forward_s": t_fwd, "gradient_s": t_grad, "ratio": t_grad / t_fwd,
        "compile_forward_s": compile_fwd, "compile_gradient_s": compile_grad,
        "forward_iterations_total": int(jnp.sum(sol.iterations)),
        "all_converged": bool(jnp.all(sol.converged)),
        "gradient": [float(v) for v in g],
        "memory_forward": _memory(fwd),
        "memory_gradient": _memory(grad),
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=128)
    parser.add_argument("--nt", type=int, default=100)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--kinds", default="normal,slip")
    parser.add_argument("--controls", default="force",
                        help="normal control(s): force, displacement or both")
    parser.add_argument("--variant", default=None,
                        help="the file's name after the machine's (default: --n)")
    parser.add_argument("--out", default=None,
                        help="JSON path (default results/gradients/<machine>_<n>.json)")
    args = parser.parse_args()
    load_before = os.getloadavg()
    cases = []
    for kind, control in [(k, c) for c in args.controls.split(",")
                          for k in args.kinds.split(",")]:
        case = run_case(args.n, args.nt, kind, args.repeats, control)
        print(json.dumps({k: v for k, v in case.items() if not k.startswith("memory")}))
        print("  memory forward", case["memory_forward"], "gradient",
              case["memory_gradient"])
        cases.append(case)
    result = header("gradients", variant=args.variant or str(args.n))
    result["machine"]["load_average_before"] = load_before
    result["settings"] = {"dtype": "float64", "rtol": 1e-8, "n": args.n,
                          "nt": args.nt, "repeats": args.repeats,
                          "kinds": args.kinds, "controls": args.controls}
    result["rows"] = cases
    print("wrote", write_results(result, args.out))


if __name__ == "__main__":
    main()
