"""Would a cascadic (nested-grid) start pay for the normal CG? (issue 32, item 2)

On `aspher_peer.py`'s rough sphere at each n of argv[1] (comma separated), float64,
rtol 1e-6: `default` is `jc.solve_normal`'s path (the Hertzian guess on the fine grid);
`nested <rtol>` solves on grids halved down to argv[2] (default 128; the gap averaged
over 2 x 2 blocks), each from the previous level's pressure repeated 2 x 2, the coarse
levels to <rtol>, the fine one to 1e-6. Prints iterations per level, best of 2 wall
times after a compile, and the pressure's relative L2 error against a rtol 1e-10 solve
from the default start. `jc.solve_normal(start="nested")` is the variant with
coarsest 128 and coarse rtol 1e-4 (session 26); this script compares the settings.

Usage: python benchmarks/experiments/nested_start.py 512,1024 128
"""

import sys
import time
from pathlib import Path


sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
import jax  # noqa: E402


jax.config.update("jax_enable_x64", True)
import aspher_peer as ap  # noqa: E402
import jax.numpy as jnp  # noqa: E402

import jaxcontact as jc  # noqa: E402
from jaxcontact._solve_normal import (  # noqa: E402
    _block_mean,
    _repeat,
    _solve,
)
from jaxcontact._solver.normal import hertzian_guess  # noqa: E402


def solve_from(operator, h, compliance, poisson, target, solver, p0):
    """`jc.solve_normal`'s jitted load-controlled solve started from `p0`:
    (pressure, iterations, converged)."""
    sol = _solve(operator, h, compliance, poisson, target, True, solver, p0)
    return sol.pressure, sol.iterations, sol.converged


def hertz_p0(h, n, comp, nu):
    g = jc.Grid((n, n), ap.SIZE)
    return hertzian_guess(h, ap.FORCE, 2 / (comp * (1 - nu)), g.cell_area)


comp = 1 / ap.SHEAR
nu = ap.NU
levels_min = int(sys.argv[2]) if len(sys.argv) > 2 else 128
for n in [int(a) for a in sys.argv[1].split(",")]:
    h = jnp.asarray(ap.gap_field(n))
    ops = {}
    hs = {}
    m = n
    hh = h
    while m >= levels_min:
        ops[m] = jc.HalfSpace(jc.Grid((m, m), ap.SIZE))
        hs[m] = hh
        m //= 2
        hh = _block_mean(hh)
    solver = jc.PolonskyKeer(rtol=1e-6)
    tight = jc.PolonskyKeer(rtol=1e-10)
    ref, _, _ = solve_from(
        ops[n], h, comp, nu, ap.FORCE, tight, hertz_p0(h, n, comp, nu)
    )

    def default():
        return solve_from(
            ops[n], h, comp, nu, ap.FORCE, solver, hertz_p0(h, n, comp, nu)
        )

    def nested(coarse_rtol):
        ms = sorted(ops)
        p = hertz_p0(hs[ms[0]], ms[0], comp, nu)
        its = []
        for m in ms:
            s = solver if m == n else jc.PolonskyKeer(rtol=coarse_rtol)
            if m != ms[0]:
                p = _repeat(p)
            p, it, c = solve_from(ops[m], hs[m], comp, nu, ap.FORCE, s, p)
            its.append(int(it))
        return p, its, c

    for name, fn in (
        ("default", default),
        ("nested 1e-4", lambda: nested(1e-4)),
        ("nested 1e-6", lambda: nested(1e-6)),
    ):
        out = fn()
        jax.block_until_ready(out[0])
        best = 1e9
        for _ in range(2):
            t = time.perf_counter()
            out = fn()
            jax.block_until_ready(out[0])
            best = min(best, time.perf_counter() - t)
        p, it, c = out
        err = float(jnp.linalg.norm(p - ref) / jnp.linalg.norm(ref))
        print(
            n,
            name,
            it if isinstance(it, list) else int(it),
            bool(c),
            f"{best:.3f} s",
            f"err {err:.1e}",
            flush=True,
        )
