"""The coupled gradient with the adjoint's GMRES "incremental" against "batched"
(restart 20 and 40), timed, and the transposed applications counted in a separate run
(a host callback per application). `python benchmarks/experiments/gmres_method_probe.py
N` writes `$OUT/gmres_probe_N.json` (gradients.py's scenes, 50 steps, float64). Run on
one H200 at 256^2 (`git show
cb0b2ae:benchmarks/results/gradients_gmres_method_h200_256.json`); the finding is in
`benchmarks/notes/coupled_gradient.md`."""
import json
import os
import sys


sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import gradients as gb
import jax
import jax.numpy as jnp

import jaxcontact._solver.implicit as imp


orig = imp._right_preconditioned_gmres
count = {"mv": 0}

def variant(method, restart_override, counting):
    def gmres(mv, precondition, b, x0, rtol, restart, max_steps, method_=None):
        def mv2(v):
            if counting:
                jax.debug.callback(lambda: count.__setitem__("mv", count["mv"] + 1))
            return mv(v)
        if method == "incremental":
            return orig(mv2, precondition, b, x0, rtol, restart, max_steps,
                        "incremental")
        r = restart_override
        r0 = jax.tree.map(jnp.subtract, b, mv2(x0))
        bn = jnp.sqrt(imp._tree_dot(b, b))
        y, _ = jax.scipy.sparse.linalg.gmres(
            lambda y: mv2(precondition(y)), r0, jax.tree.map(jnp.zeros_like, r0),
            tol=0.0, atol=rtol * bn, restart=r, maxiter=max(1, -(-max_steps // r)),
            solve_method="batched")
        x = jax.tree.map(jnp.add, x0, precondition(y))
        res = jax.tree.map(jnp.subtract, mv2(x), b)
        r2 = imp._tree_dot(res, res)
        return x, jnp.isfinite(r2) & (r2 <= (rtol * bn) ** 2)
    return gmres

out = []
n = int(sys.argv[1])
for kind in ("coupled", "coupled_x"):
    for method, r in (("incremental", 40), ("batched", 20), ("batched", 40)):
        imp._right_preconditioned_gmres = variant(method, r, False)
        forward, loss = gb.make_loss(n, 50, kind)
        params = jnp.array([gb.G / 4, 0.01, gb.NU, gb.W])
        fwd, grad = jax.jit(forward), jax.jit(jax.grad(loss))
        jax.block_until_ready(fwd(params))
        g = jax.block_until_ready(grad(params))
        t_f = gb._best(fwd, params, 2)
        t_g = gb._best(grad, params, 2)
        jax.clear_caches()
        imp._right_preconditioned_gmres = variant(method, r, True)
        count["mv"] = 0
        jax.block_until_ready(jax.jit(jax.grad(gb.make_loss(n, 50, kind)[1]))(params))
        mv = count["mv"]
        row = dict(kind=kind, n=n, method=method, restart=r, forward_s=t_f,
                   gradient_s=t_g, ratio=t_g / t_f, applications=mv,
                   gradient=[float(v) for v in g],
                   device=str(jax.devices()[0]), jax=jax.__version__)
        print(json.dumps(row)[:300], flush=True)
        out.append(row)
        jax.clear_caches()
os.makedirs(os.environ.get("OUT", "."), exist_ok=True)
json.dump(out, open(os.path.join(os.environ.get("OUT", "."), f"gmres_probe_{n}.json"),
                    "w"), indent=1)
