"""Why `jc.JointPCG` alone failed on a contact of a few cells and on nu = 0.5 (issue
27): a reproducer that steps the solver by hand and prints, per iteration, the residual
under the frozen scales, the certification gate, the frozen tangential scale and the
exact one of the iterate.

Scenes (float64, rtol 1e-8), each the second step of a two-step sequence solved the
way `jc.solve` steps (warm start from the first step's answer, its slip carried):

- `spence`: Spence's problem at 15 cells per radius, K = 30 (G = 0.5, nu = 0.3,
  mu = 0.2, R = 100, Hertz a = 1, full coupling, incremental slip): stage 1 touches
  one cell (no shear), stage 2 five;
- `incompressible`: nu = 0.5, coupling "full" (or `--coupling x`), 24^2 over 2 mm,
  R = 10 mm, W = 0.15 N, G = 1 MPa, mu = 0.3, x displaced by 0 then 1.33e-6 m.

Before the fix the frozen tangential scale was 4e-22 (`spence`) or 0
(`incompressible`) against an exact scale of ~1e-5: the residual under it never
reached rtol, so the step was never certified (152 iterations then `stalled`, or the
iteration bound). See `benchmarks/notes/joint.md` (2026-11-26).

Usage::

    python benchmarks/experiments/joint_certification.py spence
    python benchmarks/experiments/joint_certification.py incompressible --coupling x
"""

import argparse

import jax


jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import jaxcontact as jc  # noqa: E402
from jaxcontact._solver.normal import hertzian_guess  # noqa: E402


def spence():
    g, nu, mu, radius, cells = 0.5, 0.3, 0.2, 100.0, 15
    m = 2 * round(1.25 * cells) + 1
    force = 8 * g / (3 * radius * (1 - nu))  # Hertz a = 1
    loads = force * (np.arange(1, 3) / 30) ** 3
    grid = jc.Grid((m, m), m / cells)
    steps = [(w, jnp.zeros(2)) for w in loads]
    return grid, jc.Sphere(radius), g, nu, mu, "full", steps, (True, True), (True, True)


def incompressible(coupling):
    g, nu, mu, radius, w = 1e6, 0.5, 0.3, 10e-3, 0.15
    grid = jc.Grid((24, 24), 2e-3)
    nd = 2 if coupling == "full" else 1
    # x displaced (delta_x 0, then 4e-6 / 3), y (if solved) loaded with zero force
    steps = [(w, jnp.array([d, 0.0])[:nd]) for d in (0.0, 4e-6 / 3)]
    fc = (False, True)[:nd]
    return grid, jc.Sphere(radius), g, nu, mu, coupling, steps, fc, (True,) * nd


def run(scene, iterations):
    grid, sphere, g, nu, mu, coupling, steps, fc, _ = scene
    nd = len(fc)
    n = grid.shape
    op = jc.HalfSpace(grid, coupling, tangential_y=nd == 2).with_transposed_spectra()
    h0 = sphere.gap(grid)
    solver = jc.JointPCG(rtol=1e-8, max_steps=iterations)

    def problem(w, t, slip):
        return jc.StepProblem(op, jnp.asarray(1 / g), jnp.asarray(nu), jnp.asarray(mu),
                              h0, jnp.zeros((3, *n)), jnp.asarray(w), t, slip, nd, True,
                              True, fc)

    (w0, t0), (w1, t1) = steps
    first = problem(w0, t0, jnp.zeros((nd, *n)))
    guess0 = hertzian_guess(h0, w0, 2 * g / (1 - nu), grid.cell_area)
    res0 = solver.solve(first, jc.StepGuess(jnp.zeros(n), jnp.zeros((nd, *n)),
                                            normal=guess0))
    print(f"step 1: {int(res0.iterations)} iterations, converged "
          f"{bool(res0.converged)}, {int(jnp.sum(res0.pressure > 0))} contact cells, "
          f"max |q| "
          f"{float(jnp.abs(res0.shear).max()):.3g}")
    second = problem(w1, t1, res0.slip)
    k = solver.setup(second)
    state = solver.init(second, k, jc.StepGuess(res0.pressure, res0.shear))
    step = jax.jit(lambda s: solver.step(second, k, s))
    exact = jax.jit(lambda x: k.exact(x)[1])
    print("step 2: it  certified  residual(frozen)  gate      frozen s_t  exact s_t")
    for _ in range(iterations):
        state = step(state)
        print(f"        {int(state.it):3d} {bool(state.certified)!s:>9}  "
              f"{float(state.ev.residual):.3e}        {float(state.ev.gate):.3e} "
              f"{float(state.scales[1]):.3e}  {float(exact(state.x)[1]):.3e}")
        done, result = solver.terminate(second, k, state)
        if bool(done):
            break
    out = solver.postprocess(second, k, state, result)
    print(f"step 2: {int(out.iterations)} iterations, converged {bool(out.converged)}, "
          f"{int(jnp.sum(out.pressure > 0))} contact cells")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", choices=["spence", "incompressible"])
    parser.add_argument("--coupling", choices=["x", "full"], default="full")
    parser.add_argument("--iterations", type=int, default=40)
    args = parser.parse_args()
    scene = spence() if args.scene == "spence" else incompressible(args.coupling)
    run(scene, args.iterations)


if __name__ == "__main__":
    main()
