"""GPU benchmark: the normal solver at 512^2 to 4096^2, the paper's coupled scene, a
gradient and a sweep, on whatever device JAX sees first, in one run of a few minutes.

Cases (each written to the JSON as soon as it is measured, so a run stopped by its
time limit still reports what it finished):

- `normal`: `jc.solve_normal` (Polonsky-Keer CG, rtol 1e-6) of a Hertz sphere and of
  the rough sphere of `aspher_peer.py` (R = 10 mm, G = 1.93 MPa, nu = 0.3, W = 0.15 N,
  square of side 5.5 a, self-affine roughness of rms 0.15 x the Hertz approach), at
  each `--sizes` n, in float64 and float32. Per row: first call (trace + compile +
  solve) and best of `--repeats` solves [s], iterations, time per iteration against one
  padded FFT convolution (rfft2/irfft2 on 2n x 2n, the same dtype, the same process),
  and the relative L2 error of the pressure against a float64 rtol 1e-10 solve of the
  same scene (so the two dtypes are compared at equal accuracy).
- `coupled`: `jc.presets.lc` (the paper's LC scene, Figs. 16-19: 256^2 cells, 81 time
  steps, full coupling, Zener mu_inf / mu_0 = 4) and `jc.presets.sliding` (Fig. 24),
  float64 and float32: first and second call of `jc.solve` [s], iterations, converged.
- `gradient`: `jax.grad` through a whole fully coupled history (`gradients.py`'s
  `coupled` scene) against the forward solve.
- `sweep`: `jc.sweep` over the friction coefficient of the LC scene (a batch of B
  members) against a Python loop of `jc.solve` over the same members.

`--quick` runs every case at small sizes (for CPU, in a test); `--budget` [s] skips
the cases left once that much time has passed (recorded as skipped).

Usage::

    python benchmarks/gpu.py                  # on a GPU: < 8 minutes on one H100/H200
    python benchmarks/gpu.py --quick --out /tmp/gpu_quick.json

Results: `benchmarks/results/gpu/<machine>.json` (`--quick`: `<machine>_quick.json`;
layout: `results/SCHEMA.md`; the device's name and kind in `machine`): a row per case,
the skipped cases and the total time in `summary`.
"""

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import equinox as eqx
import jax


jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402


HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))

from _common import header, write_results  # noqa: E402
from aspher_peer import (  # noqa: E402
    FORCE,
    K_HIGH,
    NU,
    RADIUS,
    SHEAR,
    SIZE,
    gap_field,
    rel_l2,
)
from gradients import make_loss  # noqa: E402

import jaxcontact as jc  # noqa: E402


RTOL = 1e-6
TIGHT = 1e-10
CASES = ("hertz", "rough", "coupled", "gradient", "sweep")
MIN_ROUGH = 2 * K_HIGH + 1
DTYPES = {"float64": jnp.float64, "float32": jnp.float32}

FULL = dict(sizes=[512, 1024, 2048, 4096], coupled_n=256, coupled_steps=None,
            gradient=(128, 50), sweep=(64, 21, 32), repeats=3)
QUICK = dict(sizes=[48, 144], coupled_n=24, coupled_steps=6,
             gradient=(16, 5), sweep=(16, 5, 4), repeats=2)


def timed(fn, repeats: int) -> tuple[object, float, float]:
    """`fn()` once (first call: trace, compile and run), then `repeats` more times:
    (last result, first call [s], best of the repeats [s])."""
    t = time.perf_counter()
    out = jax.block_until_ready(fn())
    first = time.perf_counter() - t
    best = float("inf")
    for _ in range(repeats):
        t = time.perf_counter()
        out = jax.block_until_ready(fn())
        best = min(best, time.perf_counter() - t)
    return out, first, best


def padded_convolution_s(n: int, dtype, repeats: int) -> float:
    """Best time of one padded convolution: rfft2 on 2n x 2n, a product, irfft2, crop
    (the FFT floor of one CG iteration); the loop runs 20 of them inside one program."""
    spectrum = jnp.ones((2 * n, n + 1), dtype) * 0.5
    x0 = jnp.ones((n, n), dtype)

    @jax.jit
    def loop(p):
        def body(_, p):
            q = jnp.fft.irfft2(jnp.fft.rfft2(p, s=(2 * n, 2 * n)) * spectrum,
                               s=(2 * n, 2 * n))
            return q[:n, :n] + x0
        return jax.lax.fori_loop(0, 20, body, p)

    _, _, best = timed(lambda: loop(x0), repeats)
    return best / 20


def normal_case(kind: str, n: int, dtype_name: str, repeats: int, reference) -> dict:
    dtype = DTYPES[dtype_name]
    grid = jc.Grid((n, n), jnp.asarray(SIZE, dtype))
    material = jc.Elastic(jnp.asarray(SHEAR, dtype), jnp.asarray(NU, dtype))
    indenter = (jc.Sphere(jnp.asarray(RADIUS, dtype)) if kind == "hertz"
                else jc.Surface(jnp.asarray(gap_field(n), dtype)))
    force = jnp.asarray(FORCE, dtype)
    operator = jax.block_until_ready(jc.HalfSpace(grid))

    def solve(rtol):
        return jc.solve_normal(grid, indenter, material, force=force,
                               solver=jc.PolonskyKeer(rtol=rtol), operator=operator,
                               throw=False)

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sol, first, best = timed(lambda: solve(RTOL), repeats)
    if reference is None:  # float64 tight solve of the same scene
        reference = np.asarray(solve(TIGHT).pressure, np.float64)
    iterations = int(sol.iterations)
    conv = padded_convolution_s(n, dtype, repeats)
    return {
        "case": "normal", "scene": kind, "n": n, "dtype": dtype_name, "rtol": RTOL,
        "first_call_s": first, "best_s": best, "iterations": iterations,
        "converged": bool(sol.converged),
        "error_vs_float64_tight": rel_l2(sol.pressure, reference),
        "contact_fraction": float(jnp.mean(sol.pressure > 0)),
        "padded_convolution_s": conv,
        "time_per_iteration_over_convolution": best / max(iterations, 1) / conv,
        "warnings": [str(w.message)[:200] for w in caught],
    }, reference


def coupled_case(preset: str, n: int, steps, dtype_name: str) -> dict:
    kwargs = dict(n=n, dtype=DTYPES[dtype_name])
    if steps is not None:
        kwargs["steps"] = steps
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")  # e.g. --quick's long steps: recorded
        scene = jc.presets.build(preset, **kwargs)
        sol, first, best = timed(lambda: jc.solve(scene, throw=False), 1)
    return {
        "case": "coupled", "preset": preset, "n": n, "dtype": dtype_name,
        "steps": int(scene.times.shape[0]), "first_call_s": first,
        "second_call_s": best,
        "iterations_total": int(jnp.sum(sol.iterations)),
        "converged": bool(jnp.all(sol.converged)),
        "stick_ratio_last": float(sol.stick_ratio[-1]),
        "warnings": sorted({str(w.message)[:200] for w in caught}),
    }


def gradient_case(n: int, nt: int, repeats: int) -> dict:
    forward, loss = make_loss(n, nt, "coupled")
    params = jnp.array([SHEAR / 4, 0.01, NU, FORCE])
    fwd, grad = jax.jit(forward), jax.jit(jax.grad(loss))
    sol, first_fwd, t_fwd = timed(lambda: fwd(params), repeats)
    g, first_grad, t_grad = timed(lambda: grad(params), repeats)
    return {
        "case": "gradient", "scene": "coupled (gradients.py)", "n": n, "nt": nt,
        "dtype": "float64", "forward_s": t_fwd, "gradient_s": t_grad,
        "ratio": t_grad / t_fwd, "first_call_forward_s": first_fwd,
        "first_call_gradient_s": first_grad,
        "converged": bool(jnp.all(sol.converged)),
        "gradient_finite": bool(jnp.all(jnp.isfinite(g))),
    }


def sweep_case(n: int, steps: int, batch: int) -> dict:
    scene = jc.presets.lc(n=n, steps=steps)
    friction = jnp.linspace(0.1, 0.5, batch)
    swept, first_sweep, t_sweep = timed(
        lambda: jc.sweep(scene, friction=friction), 1)

    def loop():
        return [jc.solve(eqx.tree_at(lambda s: s.friction, scene, f), throw=False)
                for f in friction]

    looped, first_loop, t_loop = timed(loop, 1)
    gap = max(float(jnp.max(jnp.abs(swept.tangential_force[b] - s.tangential_force)))
              for b, s in enumerate(looped))
    return {
        "case": "sweep", "preset": "lc", "n": n, "steps": steps, "batch": batch,
        "dtype": "float64", "sweep_s": t_sweep, "loop_s": t_loop,
        "loop_over_sweep": t_loop / t_sweep, "first_call_sweep_s": first_sweep,
        "first_call_loop_s": first_loop,
        "all_converged": bool(jnp.all(swept.converged)),
        "max_tangential_force_difference_N": gap,
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true",
                        help="small sizes (CPU, tests): " + json.dumps(QUICK))
    parser.add_argument("--sizes", type=int, nargs="+", default=None)
    parser.add_argument("--budget", type=float, default=420.0,
                        help="seconds after which the remaining cases are skipped")
    parser.add_argument("--cases", nargs="+", default=list(CASES), choices=CASES,
                        help="which groups of cases to run (default: all)")
    parser.add_argument("--out", default=None,
                        help="JSON path (default results/gpu/<machine>.json)")
    args = parser.parse_args(argv)
    plan = dict(QUICK if args.quick else FULL)
    if args.sizes:
        plan["sizes"] = args.sizes
    start = time.perf_counter()
    result = header("gpu", argv, variant="quick" if args.quick else None)
    result["machine"]["device_count"] = jax.device_count()
    result["settings"] = {"plan": plan, "quick": args.quick, "groups": args.cases}
    result["rows"] = []
    result["summary"] = {"skipped": [], "total_s": 0.0}
    out = None

    def record(name, fn):
        nonlocal out
        if not set(name.split()[:2]) & set(args.cases):
            return
        if time.perf_counter() - start > args.budget:
            result["summary"]["skipped"].append(name)
            print(f"skipped {name} (budget)", flush=True)
        else:
            try:
                row = fn()
            except Exception as error:  # one failed case must not lose the others
                row = {"case": name, "error": repr(error)[:500]}
            row["elapsed_s"] = time.perf_counter() - start
            result["rows"].append(row)
            print(json.dumps(row), flush=True)
        result["summary"]["total_s"] = time.perf_counter() - start
        if result["rows"]:  # after each case: a run cut short keeps what it measured
            out = write_results(result, args.out)

    repeats = plan["repeats"]
    for kind in ("hertz", "rough"):
        for n in plan["sizes"]:
            if kind == "rough" and n < MIN_ROUGH:
                continue  # the roughness needs n > 2 x its highest wavenumber
            reference = None
            for dtype_name in ("float64", "float32"):
                def run(kind=kind, n=n, dtype_name=dtype_name):
                    nonlocal reference
                    row, reference = normal_case(kind, n, dtype_name, repeats,
                                                 reference)
                    return row
                record(f"normal {kind} {n} {dtype_name}", run)
    def coupled(preset, dtype_name):
        record(f"coupled {preset} {dtype_name}", lambda: coupled_case(
            preset, plan["coupled_n"], plan["coupled_steps"], dtype_name))

    # The gross-sliding scene last: its cost is the least predictable.
    coupled("lc", "float64")
    coupled("lc", "float32")
    record("gradient", lambda: gradient_case(*plan["gradient"], repeats))
    record("sweep", lambda: sweep_case(*plan["sweep"]))
    coupled("sliding", "float64")
    coupled("sliding", "float32")
    errors = [c for c in result["rows"] if "error" in c]
    print(f"done in {result['summary']['total_s']:.1f} s: {len(result['rows'])} "
          f"cases, {len(errors)} errors, {len(result['summary']['skipped'])} skipped "
          f"-> {out}")
    return 1 if errors else 0


if __name__ == "__main__":
    raise SystemExit(main())
