"""Restarted GMRES whose orthogonalisation touches only the Krylov vectors built so far.

This differs from `jax.scipy.sparse.linalg.gmres(..., solve_method="incremental")` in:

1. each new vector is orthogonalised (modified Gram-Schmidt, one pass) against the
   `j + 1` vectors of the cycle so far, in a loop of `j + 1` dot/axpy pairs; jax's
   classical Gram-Schmidt multiplies by the whole `(restart + 1)`-column basis, zero
   columns included, twice, so each of its iterations costs `restart` vector passes
   however early it stops (`benchmarks/notes/coupled_gradient.md`);
2. flat vectors only (`ravel_pytree` them);
3. it returns the iterations it took.

Incremental: Givens rotations keep the residual norm of the least-squares problem
(`|g_{j+1}|`), and a cycle stops as soon as it is at most `atol`; a new cycle starts
(from the true residual, as jax's) while the true residual is above `atol`. One pass
of modified Gram-Schmidt keeps GMRES backward stable (Paige, Rozloznik & Strakos 2006).
Saad & Schultz (1986); Saad, *Iterative Methods for Sparse Linear Systems*, 2nd ed.,
Alg. 6.9-6.10.
"""

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float, Int


def _givens(a, b):
    """`(c, s)` with `[c s; -s c] [a; b] = [r; 0]`."""
    r = jnp.hypot(a, b)
    safe = jnp.where(r > 0, r, 1.0)
    return jnp.where(r > 0, a / safe, 1.0), jnp.where(r > 0, b / safe, 0.0)


def restarted_gmres(
    matvec, b: Float[Array, " n"], x0: Float[Array, " n"], atol, restart: int,
    max_cycles: int,
) -> tuple[Float[Array, " n"], Int[Array, ""]]:
    """`(x, iterations)`: `x` from `x0` with the true `||matvec(x) - b|| <= atol`, or
    after `max_cycles` cycles of at most `restart` iterations. `matvec` maps a flat
    vector `(n,)` to `(n,)`; `atol` in the units of `b`."""
    n = b.shape[0]
    dtype = b.dtype

    def cycle(carry):
        x, r, beta, iterations, cycles = carry
        basis = jnp.zeros((restart + 1, n), dtype).at[0].set(
            r / jnp.where(beta > 0, beta, 1.0))
        hess = jnp.zeros((restart + 1, restart), dtype)  # rotated: upper triangular
        g = jnp.zeros(restart + 1, dtype).at[0].set(beta)
        rot = jnp.zeros((2, restart), dtype)

        def arnoldi(state):
            basis, hess, g, rot, j = state
            w = matvec(basis[j])

            def project(i, wh):
                w_, h_ = wh
                hij = jnp.dot(basis[i], w_)
                return w_ - hij * basis[i], h_.at[i].set(hij)

            w, h = jax.lax.fori_loop(0, j + 1, project,
                                     (w, jnp.zeros(restart + 1, dtype)))
            norm = jnp.linalg.norm(w)
            h = h.at[j + 1].set(norm)
            basis = basis.at[j + 1].set(w / jnp.where(norm > 0, norm, 1.0))

            def rotate(i, h_):
                c, s = rot[0, i], rot[1, i]
                hi, hk = h_[i], h_[i + 1]
                return h_.at[i].set(c * hi + s * hk).at[i + 1].set(-s * hi + c * hk)

            h = jax.lax.fori_loop(0, j, rotate, h)
            c, s = _givens(h[j], h[j + 1])
            h = h.at[j].set(c * h[j] + s * h[j + 1]).at[j + 1].set(0.0)
            g = g.at[j + 1].set(-s * g[j]).at[j].set(c * g[j])
            return (basis, hess.at[:, j].set(h), g, rot.at[:, j].set(jnp.stack([c, s])),
                    j + 1)

        def more(state):
            g, j = state[2], state[4]
            return (j < restart) & (jnp.abs(g[j]) > atol)

        basis, hess, g, rot, k = jax.lax.while_loop(
            more, arnoldi, (basis, hess, g, rot, jnp.array(0)))
        # Back substitution on the k x k triangle (the rest: identity, zero right side;
        # the rotated columns are exactly zero below their diagonal and unset from k).
        used = jnp.arange(restart) < k
        tri = hess[:restart] + jnp.diag(jnp.where(used, 0.0, 1.0))
        diag_ok = jnp.all(jnp.where(used, jnp.diagonal(tri) != 0, True))
        y = jax.scipy.linalg.solve_triangular(
            jnp.where(diag_ok, tri, jnp.eye(restart, dtype=dtype)),
            jnp.where(used, g[:restart], 0.0), lower=False)
        x = x + jnp.where(diag_ok, y, 0.0) @ basis[:restart]
        r = b - matvec(x)
        return x, r, jnp.linalg.norm(r), iterations + k, cycles + 1

    def go_on(carry):
        beta, cycles = carry[2], carry[4]
        return (cycles < max_cycles) & (beta > atol)

    r0 = b - matvec(x0)
    x, _, _, iterations, _ = jax.lax.while_loop(
        go_on, cycle, (x0, r0, jnp.linalg.norm(r0), jnp.array(0), jnp.array(0)))
    return x, iterations
