"""Why the joint solver's late phase converges ~2-3x per iteration: GMRES diagnostics.

Once the contact, stick and slip sets of a coupled step stop changing, what is left
is a linear system: the Newton system of the frozen-set conditions at the solution,

- contact cells `C`: `u_z - delta_z = -g` (the gap);
- stick cells `S`: `u_t - delta_t = -ds` (the slip);
- slip cells `L`: `e_perp . (u_t - delta_t) + lambda dtheta = ...` (the slip direction,
  two shear components only), their shear SLAVED to the pressure: `q = mu p e(theta)`;
- the load rows `A sum p = W`, `A sum q = F` (load control) or fixed multipliers;

in the unknowns `dp` (on `C`), `dq` (on `S`), `dtheta` (on `L`), `delta_z`, `delta_t`.
This script builds that system for the converged solution of a one-step coupled scene
(`jax.linearize` of the frozen-set residual: one operator application per product),
takes as right-hand side `J v` for `v` = the converged solution minus the solver's
iterate at `rtol = 1e-4` (the error the late phase removes), and runs GMRES (right
preconditioned, no restart) with

- `block`: the joint solver's preconditioner (`precondition.block_preconditioner`:
  the full-plane inverse of the block diagonal, restricted to the sets);
- `block, normal rows only` / `block, tangential rows only`: the same with the other
  block frozen (its rows made identities): each block's own rate;
- `lower triangular`: the pressure block first, then the shear block on the
  residual left by the pressure correction (the slaved slip shear and the coupling
  included): one more operator application per iteration;

and reports the relative residual after each iteration against the joint solver's own
late phase (iterations from `rtol` 1e-4 to 1e-8, each 1.5 applications, and its mean
residual reduction per iteration). Each case is run twice: with the load rows (the
scene's load control, the multipliers preconditioned by the identity) and without
them (the multipliers fixed: the Jacobian of the same solution under displacement
control), which separates what the load constraints cost a plain GMRES (the joint
solver keeps its directions load-preserving by projection instead).

Usage::

    python benchmarks/experiments/late_phase_krylov.py [--n 128] [--iterations 12]

Results go to `benchmarks/results/late_phase_krylov/late_phase_krylov.json`.
"""

import argparse
import json
import platform
import sys
from pathlib import Path

import jax


jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from jax.flatten_util import ravel_pytree  # noqa: E402


ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

import jaxcontact as jc  # noqa: E402
from jaxcontact._solver.precondition import block_preconditioner  # noqa: E402


R, W, G = 10e-3, 0.15, 1e6


def linear_system(scene, operator, sol, sol_coarse, nd, load_x, load_z=True):
    """`(J, M_block, M_lower, rhs, unravel, freeze)` of the frozen-set Newton system at
    `sol` (step 0), the right-hand side `J (sol - sol_coarse)`."""
    grid = scene.grid
    area = float(grid.cell_area)
    nu = scene.material.poisson
    compliance = 1.0 / scene.material.shear_modulus
    mu = scene.friction
    p = sol.pressure[0]
    q = sol.shear[0, :nd]
    C = p > 0
    S = sol.stick[0]
    L = C & ~S
    mag = jnp.sqrt(jnp.sum(q * q, axis=0))
    e = jnp.where(L[None], q / jnp.where(mag > 0, mag, 1.0)[None], 0.0)
    e_perp = jnp.stack([-e[1], e[0]]) if nd == 2 else None

    def displacement(t):
        """`(u_z, u_t...)` of the traction `(p, q...)`."""
        full = jnp.zeros((3,) + p.shape, p.dtype).at[2].set(t[0]).at[:nd].set(t[1:])
        u = compliance * operator.apply(full, nu)
        return jnp.concatenate([u[2][None], u[:nd]])

    x = jnp.concatenate([p[None], q])
    u = displacement(x)
    dt0 = sol.tangential_displacement[0, :nd]
    ds = u[1:] - dt0[:, None, None]  # first step: no history, no previous slip
    lam = jnp.where(L, -jnp.sum(e * ds, axis=0), 0.0)
    n_c = float(jnp.sum(C))
    s_w = compliance / (area * np.sqrt(n_c))  # load rows on the scale of the others
    # x under load control (or displacement, none given), y under displacement.
    fc = jnp.asarray([load_x] + [False] * (nd - 1))
    theta0 = jnp.arctan2(e[1], e[0]) if nd == 2 else None

    def traction(v):
        p1 = jnp.where(C, p + v["p"], 0.0)
        if nd == 2:
            th = theta0 + v["th"]
            e1 = jnp.stack([jnp.cos(th), jnp.sin(th)])
        else:
            e1 = e
        q1 = jnp.where(S[None], q + v["q"], jnp.where(L[None], mu * p1[None] * e1, 0.0))
        return jnp.concatenate([p1[None], q1])

    def residual(v):
        """Frozen-set conditions at `x + v` (their value at `v = 0` is ~0)."""
        t = traction(v)
        u1 = u + displacement(t - x)
        w = u1[1:] - (dt0 + v["dt"])[:, None, None]
        r = dict(p=jnp.where(C, u1[0] - v["dz"], 0.0) - jnp.where(C, u[0], 0.0),
                 q=jnp.where(S[None], w, 0.0),
                 dz=((area * jnp.sum(t[0]) - area * jnp.sum(p)) * s_w if load_z
                     else v["dz"]),
                 dt=jnp.where(fc, area * jnp.sum(t[1:] - x[1:], axis=(-2, -1)) * s_w,
                              v["dt"]))
        if nd == 2:
            th = theta0 + v["th"]
            r["th"] = jnp.where(L, -jnp.sin(th) * w[0] + jnp.cos(th) * w[1], 0.0)
        return r

    zero = dict(p=jnp.zeros_like(p), q=jnp.zeros_like(q), dz=jnp.zeros(()),
                dt=jnp.zeros(nd))
    if nd == 2:
        zero["th"] = jnp.zeros_like(p)
    _, jvp = jax.linearize(residual, zero)
    flat0, unravel = ravel_pytree(zero)

    # The solver's preconditioner (padded spectra at unit compliance, then scaled).
    nn = compliance * operator.normal_spectrum(nu)
    xx, _, yy = operator.tangential_blocks(nu)
    precondition = block_preconditioner(
        operator, nn, compliance * xx, compliance * yy if nd == 2 else None,
        coarse=True, compliance=compliance, poisson=nu)
    c_tt = float(compliance * operator.diagonal(xx))
    curvature = jnp.where(L, lam / jnp.where(L, mu * p, 1.0), 0.0)
    weight = c_tt / (c_tt + curvature)

    def block(r, rows=("p", "q")):
        rq = r["q"]
        if nd == 2:
            rq = jnp.where(L[None], e_perp * r["th"][None], rq)
        m = precondition(jnp.concatenate([r["p"][None], rq]))
        v = dict(p=jnp.where(C, m[0], 0.0), q=jnp.where(S[None], m[1:], 0.0),
                 dz=r["dz"], dt=r["dt"])
        if nd == 2:
            # As the joint solver: full-plane inverse and diagonal blended by the
            # disc curvature, then scaled by it; dtheta = (shear along the disc) / B.
            phi = weight * (weight * jnp.sum(e_perp * m[1:], axis=0)
                            + (1 - weight) * r["th"] / c_tt)
            v["th"] = jnp.where(L, phi / jnp.where(L, mu * p, 1.0), 0.0)
        shear_keys = ("q", "dt") + (("th",) if nd == 2 else ())
        for k in (("p", "dz") if "p" not in rows else ()) + (
                shear_keys if "q" not in rows else ()):
            v[k] = r[k]
        return v

    def lower(r):
        vp = block(dict(r, q=jnp.zeros_like(r["q"]), dt=jnp.zeros_like(r["dt"]),
                        **({"th": jnp.zeros_like(r["th"])} if nd == 2 else {})))
        vp = dict(vp, q=jnp.zeros_like(vp["q"]), dt=jnp.zeros_like(vp["dt"]),
                  **({"th": jnp.zeros_like(vp["th"])} if nd == 2 else {}))
        jv = jvp(vp)
        rest = dict(r, p=jnp.zeros_like(r["p"]), dz=jnp.zeros_like(r["dz"]),
                    q=r["q"] - jv["q"], dt=r["dt"] - jv["dt"])
        if nd == 2:
            rest["th"] = r["th"] - jv["th"]
        vq = block(rest)
        return dict(vq, p=vp["p"], dz=vp["dz"])

    def freeze(rows):
        """The system with only `rows` ("p" or "q") live (the others identities)."""
        def j(v):
            out = jvp(v)
            if "p" not in rows:
                out = dict(out, p=v["p"], dz=v["dz"])
            if "q" not in rows:
                out = dict(out, q=v["q"], dt=v["dt"], **({"th": v["th"]} if nd == 2
                                                          else {}))
            return out
        return j

    # The error the late phase removes: converged minus the iterate at rtol 1e-4.
    pc, qc = sol_coarse.pressure[0], sol_coarse.shear[0, :nd]
    err = dict(p=jnp.where(C, p - pc, 0.0), q=jnp.where(S[None], q - qc, 0.0),
               dz=(sol.approach[0] - sol_coarse.approach[0]) * load_z,
               dt=jnp.where(fc, dt0 - sol_coarse.tangential_displacement[0, :nd], 0.0))
    if nd == 2:
        thc = jnp.arctan2(qc[1], qc[0])
        dth = jnp.angle(jnp.exp(1j * (theta0 - thc)))
        err["th"] = jnp.where(L, dth, 0.0)
    return jvp, block, lower, freeze, err, unravel, flat0.size


def gmres(apply_j, precondition, rhs, unravel, iterations):
    """Relative residuals `|J M y_k - rhs| / |rhs|`, k = 1..iterations (GMRES from 0,
    right preconditioning, modified Gram-Schmidt twice)."""
    def a(vflat):
        return ravel_pytree(apply_j(precondition(unravel(vflat))))[0]

    b = ravel_pytree(rhs)[0]
    beta = jnp.linalg.norm(b)
    basis = [b / beta]
    h = np.zeros((iterations + 1, iterations))
    out = []
    a_jit = jax.jit(a)
    for j in range(iterations):
        w = a_jit(basis[j])
        for _ in range(2):
            for i in range(j + 1):
                hij = float(jnp.dot(w, basis[i]))
                h[i, j] += hij
                w = w - hij * basis[i]
        h[j + 1, j] = float(jnp.linalg.norm(w))
        basis.append(w / h[j + 1, j])
        e1 = np.zeros(j + 2)
        e1[0] = float(beta)
        y = np.linalg.lstsq(h[:j + 2, :j + 1], e1, rcond=None)[0]
        out.append(float(np.linalg.norm(h[:j + 2, :j + 1] @ y - e1) / float(beta)))
    return out


def late_phase(scene, operator):
    """The joint solver's own late phase: iterations from rtol 1e-4 to 1e-8, and its
    mean residual reduction per iteration (from the residuals it stopped at)."""
    its, res = {}, {}
    for rtol in (1e-4, 1e-8):
        sol = jc.solve(scene, operator=operator, rtol=rtol)
        its[rtol], res[rtol] = int(sol.iterations[0]), float(sol.residual[0])
    late = its[1e-8] - its[1e-4]
    return late, its, (res[1e-4] / res[1e-8]) ** (1 / late)


def case(name, n, nu, coupling, ratio, iterations, mu=0.3, loads=True):
    a = float(jc.Hertz(R, W, G, 0.3).contact_radius)
    grid = jc.Grid((n, n), 4.0 * a)
    tangential = dict(x=jc.Force(ratio * mu * W)) if ratio > 0 else {}
    scene = jc.Scene(grid, jc.Sphere(R), jc.Elastic(G, nu), times=jnp.zeros(1),
                     normal=jc.Force(W), friction=mu, coupling=coupling, **tangential)
    operator = jc.HalfSpace(grid, coupling)
    nd = 2 if coupling == "full" else 1
    sol = jc.solve(scene, operator=operator, rtol=1e-11)
    sol4 = jc.solve(scene, operator=operator, rtol=1e-4)
    jvp, block, lower, freeze, err, unravel, size = linear_system(
        scene, operator, sol, sol4, nd, loads and ratio > 0, loads)
    rhs = jvp(err)
    late, its, joint_rate = late_phase(scene, operator)
    out = dict(name=name, load_rows=loads, n=n, poisson=nu, coupling=coupling,
               load_ratio=ratio,
               unknowns=size, joint_late_phase_iterations=late,
               joint_reduction_per_iteration=joint_rate,
               joint_reduction_per_application=joint_rate ** (1 / 1.5),
               joint_iterations=dict((f"{k:g}", v) for k, v in its.items()),
               stick_cells=int(sol.stick[0].sum()),
               slip_cells=int((sol.contact[0] & ~sol.stick[0]).sum()))
    out["gmres"] = {
        "block": gmres(jvp, block, rhs, unravel, iterations),
        "block, normal rows only": gmres(freeze("p"), lambda r: block(r, ("p",)), rhs,
                                         unravel, iterations),
        "block, tangential rows only": gmres(freeze("q"), lambda r: block(r, ("q",)),
                                             rhs, unravel, iterations),
        "lower triangular": gmres(jvp, lower, rhs, unravel, iterations),
    }
    rate = {k: (v[-1] ** (-1 / len(v))) for k, v in out["gmres"].items()}
    out["mean_reduction_per_iteration"] = rate
    print(f"{name} (load rows {loads}): joint late phase {late} iterations, "
          f"{joint_rate:.2f}x each (1.5 applications); GMRES per iteration "
          + ", ".join(f"{k} {v:.2f}x" for k, v in rate.items()), flush=True)
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=128)
    parser.add_argument("--iterations", type=int, default=12)
    args = parser.parse_args()
    cases = [
        ("Cattaneo-Mindlin F = mu W / 2, full", 0.3, "full", 0.5),
        ("Cattaneo-Mindlin F = mu W / 2, x", 0.3, "x", 0.5),
        ("Cattaneo-Mindlin F = mu W / 2, full, nu 0.49", 0.49, "full", 0.5),
        ("coupled normal load alone, full", 0.3, "full", 0.0),
    ]
    results = [case(name, args.n, nu, c, ratio, args.iterations, loads=loads)
               for name, nu, c, ratio in cases for loads in (True, False)]
    out = dict(machine=platform.processor() or platform.machine(),
               jax=jax.__version__, dtype="float64", cases=results)
    path = ROOT / "benchmarks/results/late_phase_krylov/late_phase_krylov.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=1))
    print("wrote", path)


if __name__ == "__main__":
    main()
