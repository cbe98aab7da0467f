"""Command-line tool: `jaxcontact run hertz --out DIR`.

Runs a built-in example scene, prints the numerical result beside the analytic
reference, and writes the results (`.npz` with metadata) and a plot.
"""

import argparse
import json
import sys
import time
from pathlib import Path


def _hertz(args) -> int:
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp
    import numpy as np

    import jaxcontact as jc

    radius, force, shear_modulus, poisson = 10e-3, 0.15, 1.93e6, 0.3
    hertz = jc.Hertz(radius, force, shear_modulus, poisson)
    a = float(hertz.contact_radius)
    n = args.n
    grid = jc.Grid((n, n), 4 * a)
    material = jc.Elastic(shear_modulus, poisson)
    operator = jc.HalfSpace(grid)
    start = time.perf_counter()
    sol = jc.solve_normal(grid, jc.Sphere(radius), material, force=force, operator=operator)
    sol.pressure.block_until_ready()
    elapsed = time.perf_counter() - start

    a_num = float(np.sqrt(float(jnp.sum(sol.contact)) * float(grid.cell_area) / np.pi))
    rows = [
        ("contact radius a [m]", a_num, a),
        ("peak pressure p0 [Pa]", float(sol.pressure.max()), float(hertz.peak_pressure)),
        ("approach delta [m]", float(sol.approach), float(hertz.approach)),
        ("normal force W [N]", float(sol.normal_force), force),
    ]
    print(f"Hertz indentation: rigid sphere R = {radius} m on G = {shear_modulus} Pa, "
          f"nu = {poisson}, W = {force} N; grid {n}x{n} over {4 * a:.3e} m (float64)")
    print(f"{'quantity':<24}{'jaxcontact':>14}{'Hertz':>14}{'rel. error':>12}")
    for name, num, ref in rows:
        print(f"{name:<24}{num:>14.6e}{ref:>14.6e}{num / ref - 1:>12.2e}")
    print(f"converged={bool(sol.converged)} iterations={int(sol.iterations)} "
          f"residual={float(sol.residual):.1e} time={elapsed:.2f} s (incl. compilation)")

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    meta = dict(
        scene="hertz", radius=radius, force=force, shear_modulus=shear_modulus,
        poisson=poisson, shape=[n, n], size=4 * a, units="SI (m, N, Pa)",
        converged=bool(sol.converged), iterations=int(sol.iterations),
        residual=float(sol.residual), version=jc.__version__,
    )
    np.savez(
        out / "hertz.npz",
        x=np.asarray(grid.x), y=np.asarray(grid.y), pressure=np.asarray(sol.pressure),
        gap=np.asarray(sol.gap), contact=np.asarray(sol.contact),
        approach=float(sol.approach), metadata=json.dumps(meta),
    )
    print(f"wrote {out / 'hertz.npz'}")
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed: no plot (pip install 'jaxcontact[plot]')")
        return 0 if bool(sol.converged) else 1
    x = np.asarray(grid.x) / a
    row = np.asarray(sol.pressure)[:, n // 2] / float(hertz.peak_pressure)
    fig, ax = plt.subplots(figsize=(5, 3.5))
    xr = np.linspace(-1.5, 1.5, 400)
    ax.plot(xr, np.sqrt(np.clip(1 - xr**2, 0, None)), "k-", label="Hertz")
    ax.plot(x, row, "o", ms=3, label=f"jaxcontact {n}x{n}")
    ax.set_xlim(-1.5, 1.5)
    ax.set_xlabel("x / a")
    ax.set_ylabel("p / p0")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "hertz.png", dpi=120)
    print(f"wrote {out / 'hertz.png'}")
    return 0 if bool(sol.converged) else 1


EXAMPLES = {"hertz": _hertz}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="jaxcontact", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run a built-in example")
    run.add_argument("example", help=f"one of {sorted(EXAMPLES)}")
    run.add_argument("--out", default="jaxcontact-out", help="output directory")
    run.add_argument("--n", type=int, default=256, help="grid cells per side")
    sub.add_parser("examples", help="list the built-in examples")
    args = parser.parse_args(argv)
    if args.command == "examples":
        print("\n".join(sorted(EXAMPLES)))
        return 0
    if args.example not in EXAMPLES:
        parser.error(f"unknown example {args.example!r}; choose from {sorted(EXAMPLES)}")
    if args.n < 2:
        parser.error(f"--n must be >= 2, got {args.n}")
    return EXAMPLES[args.example](args)


if __name__ == "__main__":
    sys.exit(main())
