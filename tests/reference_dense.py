r"""Small, dense, independent reference solver for frictional contact with coupling.

Used by the tests to cross-check the FFT solvers of `jaxcontact`. It shares nothing
with the package except `jaxcontact.influence_coefficients` (closed-form cell
coefficients, tested separately), which builds the dense influence matrices; all the
rest is plain numpy/scipy in float64, written for clarity rather than speed
(`n ~ 16-32` runs in seconds).

Problem
-------
A rigid indenter with initial gap `h0` (cells of an `nx x ny` grid centred on the
origin, cell area `A = dx dy`) presses on an elastic half-space (shear modulus `G`,
Poisson `nu`), Coulomb friction `mu`. Axes: x, y in the surface, z INTO the body. With
the dense `3N x 3N` matrix `C` (`C[a, b][i, j] = influence_coefficients(x_i - x_j,
y_i - y_j)[a, b]`, `N = nx ny`) the surface displacements are

    u = (1/G) C (q_x, q_y, p),

where the normal-tangential blocks `C_zx, C_zy, C_xz, C_yz` are dropped for coupling
"none", and for coupling "x" `q_y = 0` and only the x-z blocks are kept. `C` is
symmetric (reciprocity: `C_xz = C_zx^T`, `C_xy = C_yx`) and positive definite.

At each step k:

- normal: gap `g = h0 + u_z - delta_z >= 0`, `p >= 0`, `p g = 0`, with load control
  (`A sum p = W`, `delta_z` unknown) or displacement control (`delta_z` given);
- tangential: slip `s = u_t - delta_t` (t = x, y) and slip increment
  `Ds = s_k - s_{k-1}` (incremental law, the default) or `Ds = s_k` (the paper's
  "total" law, Eq. 16: `s_{k-1}` taken as 0). Coulomb: `|q| <= mu p` everywhere,
  `q = 0` out of contact; stick cells (`|q| < mu p`) have `Ds = 0`; slip cells have
  `|q| = mu p` and `q = -mu p Ds / |Ds|`. Each tangential direction is load controlled
  (`A sum q_t = F_t`, `delta_t` unknown) or displacement controlled (`delta_t` given;
  `delta_t = 0` when neither is given).

Before step 0 the body is unloaded: `p = q = 0`, `s = 0`. `s_{k-1}` is kept on every
cell, in contact or not, so a cell entering contact slips relative to where its surface
point was at the previous step. Shear unknowns: `(q_x, q_y)` with disc constraints for
coupling "none" and "full"; `q_x` alone (interval constraints) for coupling "x".

Algorithm
---------
Each step is solved by a fixed-point (block Gauss-Seidel, Panagiotopoulos) alternation
between the two convex sub-problems below, warm started from the previous step, until
`max|p_new - p| <= tol max p` and `max|q_new - q| <= tol mu max p` (at most
`max_alternations` sweeps, else `RuntimeError`):

(a) Normal problem for fixed q. With `M = C_zz / G` and `f = h0 + (C_zx q_x + C_zy
    q_y) / G` (the known part of the gap), the conditions above are the KKT conditions
    of the strictly convex QP

        min_p  1/2 p^T M p + f.p    s.t.  p >= 0   [and  sum p = W / A],

    whose gradient `M p + f - delta_z` is the gap; `delta_z` is given, or is the
    multiplier of the load constraint. Solved EXACTLY by a primal-dual active-set
    method (Hintermueller-Ito-Kunisch semismooth Newton): contact set
    `I = {p - c g > 0}`; on `I` solve `M_II p_I = delta_z - f_I` (Cholesky; with load
    control the bordered system is solved by a Schur complement for `delta_z`), `p = 0`
    off `I`; repeat until `I` no longer changes, at which point `p_I > 0` and `g >= 0`
    off `I` hold exactly (up to round-off). If it cycles or exceeds its iteration
    limit, a finite primal active-set method (Nocedal & Wright, Alg. 16.3) takes over.

(b) Tangential problem for fixed p. On the contact cells `c = {p > 0}` (q = 0
    elsewhere) let `K = C_tt[c, c] / G` (t = x, y; only x for coupling "x") and

        b = s_prev + delta_t - (C_tz p)[c] / G,

    with `s_prev = s_{k-1}` (incremental) or 0 (total). Then
    `K q - b = (C_tt q + C_tz p) / G - delta_t - s_prev = s - s_prev = Ds`, so `Ds` is
    the gradient of the strictly convex function

        Phi(q) = 1/2 q^T K q - q.b,

    and the Coulomb conditions are exactly `-Ds in N_D(q)`, the normal cone to the
    product of discs `D = {|q_i| <= mu p_i}` (intervals for coupling "x"): inside a
    disc (stick) `Ds = 0`; on its boundary `Ds = -lambda q / |q|`, `lambda >= 0`
    (slip opposite to the shear). These are the KKT conditions of `min_{q in D} Phi`.
    Solved by FISTA (accelerated projected gradient, step `1 / lambda_max(K)`, with
    O'Donoghue-Candes gradient restart, hence linear convergence) until the natural
    residual `max_i |L (q_i - P_Di(q_i - Ds_i / L))|` (a slip-increment error, in
    length units: `|Ds|` in stick cells, misalignment in slip cells) is at most
    `tol_inner = 1e-2 tol` times the displacement scale `max(|u|, |delta|)` of the step.
    Tangential load control: `A sum q_t(delta_t)` is continuous and nondecreasing in
    `delta_t` (`sum q(delta_t)` is minus the gradient of the concave dual function
    `min_q Phi(q) - delta_t.sum q`), so `delta_t` is found by bracketing and Illinois
    regula falsi to `|A sum q_t - F_t| <= tol_inner mu W` or a round-off-wide bracket
    (nested, outer on `delta_y`, when both directions are load controlled). A load with
    `|F_t| >= mu W` (gross sliding) raises `ValueError`. A load-controlled `delta_t` is
    undetermined without contact or friction; the previous value is then kept.

Outputs are per step; `stick = contact & (|q| < mu p (1 - stick_tol))`. The
alternation is a contraction for moderate `mu (1 - 2 nu) / (2 (1 - nu))` (about 10
sweeps to 1e-10 for mu = 0.3, nu = 0 .. 0.3); coupling "none" needs one sweep.
`conditions` evaluates the contact and Coulomb residuals of a computed step.
"""

import numpy as np
import scipy.linalg as sla
from scipy.sparse.linalg import eigsh


__all__ = [
    "dense_influence",
    "grid_coordinates",
    "sphere_gap",
    "solve_history",
    "conditions",
]


# ----------------------------------------------------------------------------- grid


def _pair(v, name, cast=float):
    v = np.asarray(v)
    if v.ndim == 0:
        return cast(v), cast(v)
    if v.shape != (2,):
        raise ValueError(f"{name} must be a scalar or a pair, got shape {v.shape}")
    return cast(v[0]), cast(v[1])


def grid_coordinates(n, size):
    """Cell centres `(X, Y)` (each `(nx, ny)`, indexing "ij") and `(dx, dy)`."""
    nx, ny = _pair(n, "n", int)
    lx, ly = _pair(size, "size")
    dx, dy = lx / nx, ly / ny
    x = (np.arange(nx) - (nx - 1) / 2) * dx
    y = (np.arange(ny) - (ny - 1) / 2) * dy
    X, Y = np.meshgrid(x, y, indexing="ij")
    return X, Y, (dx, dy)


def sphere_gap(n, size, radius):
    """Initial gap `r^2 / (2 R)` of a sphere (paraboloid) centred on the origin."""
    X, Y, _ = grid_coordinates(n, size)
    return (X**2 + Y**2) / (2.0 * radius)


_JITTED = []


def dense_influence(n, size, poisson):
    """Dense influence matrices `C`, `(3, 3, N, N)`, unit shear modulus, float64.

    `C[a, b][i, j]` = displacement `a` at the centre of cell `i` due to a unit uniform
    traction `b` on cell `j` (order x, y, z; cells flattened in C order of `(nx, ny)`).
    The `(2nx - 1) x (2ny - 1)` lattice of offsets is evaluated once (padded to a
    multiple of 64 so that one compilation serves every small grid) and gathered.
    """
    import jax

    from jaxcontact import influence_coefficients

    if not _JITTED:
        _JITTED.append(jax.jit(influence_coefficients))
    nx, ny = _pair(n, "n", int)
    _, _, (dx, dy) = grid_coordinates(n, size)
    mx, my = 2 * nx - 1, 2 * ny - 1
    px, py = -(-mx // 64) * 64, -(-my // 64) * 64
    ox = (np.arange(px) - (nx - 1)) * dx
    oy = (np.arange(py) - (ny - 1)) * dy
    OX, OY = np.meshgrid(ox, oy, indexing="ij")
    with jax.enable_x64(True):
        lattice = np.asarray(
            _JITTED[0](OX, OY, dx, dy, float(poisson)), dtype=np.float64
        )[:, :, :mx, :my]
    ix, iy = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    ix, iy = ix.ravel(), iy.ravel()
    di = ix[:, None] - ix[None, :] + nx - 1
    dj = iy[:, None] - iy[None, :] + ny - 1
    return lattice[:, :, di, dj]


# ------------------------------------------------------------------ normal problem


def _eqp(M, f, act, load, value, cache=None):
    """Solve the equality-constrained sub-problem on the set `act` (p = 0 elsewhere).

    `cache` (a dict) keeps the Cholesky factor of `M[act, act]` between calls.
    """
    p = np.zeros_like(f)
    idx = np.flatnonzero(act)
    if idx.size == 0:
        if load:
            raise RuntimeError("empty contact set under load control")
        return p, value
    key = idx.tobytes()
    if cache is not None and key in cache:
        cf, a = cache[key]
    else:
        cf = sla.cho_factor(M[np.ix_(idx, idx)])
        a = sla.cho_solve(cf, np.ones(idx.size))
        if cache is not None:
            if len(cache) > 64:
                cache.clear()
            cache[key] = (cf, a)
    if load:
        b = sla.cho_solve(cf, f[idx])
        delta = (value + b.sum()) / a.sum()
        p[idx] = delta * a - b
    else:
        delta = value
        p[idx] = sla.cho_solve(cf, delta - f[idx])
    return p, delta


def _normal_primal_active_set(M, f, load, value, maxit):
    """Finite primal active-set method (Nocedal & Wright, Alg. 16.3)."""
    N = f.size
    free = np.zeros(N, bool)
    p = np.zeros(N)
    if load:
        i0 = int(np.argmin(f))
        free[i0] = True
        p[i0] = value
    scale = np.abs(f).max() + abs(value) * (np.abs(M).max() if load else 1.0) + 1e-300
    for _ in range(maxit):
        pn, delta = _eqp(M, f, free, load, value)
        neg = free & (pn < 0)
        if not neg.any():
            p = pn
            g = M @ p + f - delta
            gz = np.where(free, np.inf, g)
            j = int(np.argmin(gz))
            if gz[j] >= -1e-14 * (scale + abs(delta)):
                return p, delta
            free[j] = True
        else:
            i_neg = np.flatnonzero(neg)
            alphas = p[i_neg] / (p[i_neg] - pn[i_neg])
            k = int(np.argmin(alphas))
            p = p + alphas[k] * (pn - p)
            p[i_neg[k]] = 0.0
            free[i_neg[k]] = False
    raise RuntimeError("normal primal active-set method did not converge")


def _solve_normal(M, f, load, value, act0=None, maxit=100, cache=None):
    """`min 1/2 p^T M p + f.p, p >= 0` [`sum p = value` under load control].

    Returns `(p, delta_z)`; `delta_z = value` under displacement control.
    """
    if load and value <= 0.0:
        if value < 0.0:
            raise ValueError("negative normal load")
        return np.zeros_like(f), float(np.min(f))  # just touching
    if act0 is not None and act0.any():
        act = act0.copy()
    elif load:
        act = f <= f.min() + 1e-12 * (np.abs(f).max() + 1e-300)
    else:
        act = f < value
    if not load and not act.any():
        return np.zeros_like(f), value
    c = 1.0 / np.mean(np.diag(M))
    seen = set()
    for _ in range(maxit):
        p, delta = _eqp(M, f, act, load, value, cache)
        g = M @ p + f - delta
        new = p - c * g > 0
        if load and not new.any():
            break
        if np.array_equal(new, act):
            return p, delta
        key = new.tobytes()
        if key in seen:
            break  # cycling
        seen.add(key)
        act = new
    return _normal_primal_active_set(M, f, load, value, maxit=20 * f.size)


# -------------------------------------------------------------- tangential problem


def _lambda_max(K):
    """Largest eigenvalue of the SPD matrix `K`, slightly overestimated."""
    if K.shape[0] <= 64:
        return float(np.linalg.eigvalsh(K)[-1]) * (1 + 1e-10)
    v0 = np.ones(K.shape[0])
    lam = eigsh(K, k=1, which="LA", tol=1e-8, v0=v0, return_eigenvectors=False)[0]
    return float(lam) * (1 + 1e-6)


class _Tangential:
    """FISTA for `min 1/2 q^T K q - q.b` over discs `|q_i| <= r_i` (intervals if dim 1).

    Variables are ordered component-major: `(q_x[c], q_y[c])`.
    """

    def __init__(self, K, L, radii, dim):
        self.K = K
        self.L = L  # >= lambda_max(K)
        self.r = radii
        self.dim = dim
        self.m = radii.size

    def proj(self, z):
        if self.dim == 1:
            return np.clip(z, -self.r, self.r)
        m = self.m
        zx, zy = z[:m], z[m:]
        nrm = np.hypot(zx, zy)
        scale = np.where(nrm > self.r, self.r / np.where(nrm > 0, nrm, 1.0), 1.0)
        return np.concatenate([zx * scale, zy * scale])

    def residual(self, x, g):
        """Natural residual per cell, in the units of `g` (slip increment)."""
        r = self.L * (x - self.proj(x - g / self.L))
        if self.dim == 1:
            return np.abs(r)
        return np.hypot(r[: self.m], r[self.m :])

    def solve(self, b, x0, tol_abs, maxit=20000):
        K, L = self.K, self.L
        x = self.proj(x0)
        gx = K @ x - b
        if self.residual(x, gx).max(initial=0.0) <= tol_abs:
            return x, 0
        y, gy, t = x, gx, 1.0
        for it in range(1, maxit + 1):
            xn = self.proj(y - gy / L)
            gxn = K @ xn - b
            if self.residual(xn, gxn).max(initial=0.0) <= tol_abs:
                return xn, it
            if np.dot(y - xn, xn - x) > 0:  # gradient restart
                t = 1.0
                y, gy = xn, gxn
            else:
                tn = 0.5 * (1.0 + np.sqrt(1.0 + 4.0 * t * t))
                beta = (t - 1.0) / tn
                y = xn + beta * (xn - x)
                gy = gxn + beta * (gxn - gx)
                t = tn
            x, gx = xn, gxn
        raise RuntimeError(
            f"tangential FISTA did not converge in {maxit} iterations "
            f"(residual {self.residual(x, gx).max():.3e}, target {tol_abs:.3e})"
        )


def _monotone_root(fun, x0, h, ftol, maxit=300):
    """Root of a continuous nondecreasing `fun`: bracket by doubling from `x0`, then
    Illinois regula falsi. Stops at `|fun| <= ftol` or a bracket of round-off width
    (then returns the end with the smaller `|fun|`). Values are never re-evaluated, so
    noise in `fun` near the root cannot break the bracket."""
    f0 = fun(x0)
    if abs(f0) <= ftol:
        return x0
    direction = -np.sign(f0)
    xa, fa = x0, f0
    for _ in range(100):
        xb = x0 + direction * h
        fb = fun(xb)
        if abs(fb) <= ftol:
            return xb
        if np.sign(fb) != np.sign(f0):
            break
        xa, fa = xb, fb
        h *= 2.0
    else:
        raise RuntimeError("could not bracket the tangential load")
    if xa > xb:
        xa, fa, xb, fb = xb, fb, xa, fa  # now fa < 0 < fb
    side = 0
    for _ in range(maxit):
        x = (xa * fb - xb * fa) / (fb - fa)
        if not xa < x < xb:
            x = 0.5 * (xa + xb)
        fx = fun(x)
        if abs(fx) <= ftol:
            return x
        if fx < 0:
            xa, fa = x, fx
            if side == -1:
                fb *= 0.5
            side = -1
        else:
            xb, fb = x, fx
            if side == 1:
                fa *= 0.5
            side = 1
        if xb - xa <= 4e-16 * max(abs(xa), abs(xb)):
            return xa if abs(fa) < abs(fb) else xb
    raise RuntimeError("tangential load root search did not converge")


# ----------------------------------------------------------------------- history


def _as_steps(name, v, nt):
    if v is None:
        return None
    v = np.asarray(v, dtype=np.float64)
    if v.ndim == 0:
        return np.full(nt, float(v))
    if v.shape != (nt,):
        raise ValueError(
            f"{name} must be a scalar or have shape ({nt},), got {v.shape}"
        )
    return v


def solve_history(
    n,
    size,
    h0,
    G,
    nu,
    mu,
    W=None,
    delta_z=None,
    Fx=None,
    delta_x=None,
    Fy=None,
    delta_y=None,
    coupling="full",
    law="incremental",
    tol=1e-10,
    stick_tol=1e-8,
    max_alternations=200,
    C=None,
):
    """Solve a loading history of coupled frictional contact (dense reference).

    **Arguments:**

    - `n`: cells per side (int) or `(nx, ny)`; `size`: side length or `(Lx, Ly)`.
    - `h0`: initial gap, `(nx, ny)`; `G`: shear modulus; `nu`: Poisson's ratio;
      `mu`: friction coefficient.
    - Normal input, exactly one of `W` (load) or `delta_z` (approach); tangential input
      per direction at most one of `Fx`/`delta_x` (and `Fy`/`delta_y`); neither means
      `delta_t = 0`. Each a scalar or an array over steps (`nt` = their common length).
    - `coupling`: "none" | "x" | "full"; `law`: "incremental" | "total".
    - `tol`: relative tolerance of the normal/tangential alternation (inner tangential
      solves use `tol / 100`); `stick_tol`: relative margin of the stick test.
    - `C`: optional precomputed `dense_influence(n, size, nu)`.

    **Returns:** a dict of float64 numpy arrays over steps: `p` (nt, nx, ny), `q`
    (nt, 2, nx, ny), `u` (nt, 3, nx, ny), `gap`, `s`, `ds` (slip increment),
    `contact`, `stick`, `slip` masks, `delta_z`, `delta_x`, `delta_y`, `W`, `Fx`, `Fy`
    (nt,), `alternations` (nt,), plus the inputs `mu`, `G`, `nu`, `law`, `coupling`,
    `cell_area`, `x`, `y`.
    """
    if coupling not in ("none", "x", "full"):
        raise ValueError(f"coupling must be 'none', 'x' or 'full', got {coupling!r}")
    if law not in ("incremental", "total"):
        raise ValueError(f"law must be 'incremental' or 'total', got {law!r}")
    if (W is None) == (delta_z is None):
        raise ValueError("give exactly one of W and delta_z")
    if Fx is not None and delta_x is not None or Fy is not None and delta_y is not None:
        raise ValueError("give at most one of Fx/delta_x and of Fy/delta_y")
    if coupling == "x" and (Fy is not None or delta_y is not None):
        raise ValueError("coupling 'x' has q_y = 0: no y input allowed")
    lengths = {
        np.size(v)
        for v in (W, delta_z, Fx, delta_x, Fy, delta_y)
        if v is not None and np.ndim(v) > 0
    }
    if len(lengths) > 1:
        raise ValueError(f"inputs over steps have different lengths {lengths}")
    nt = lengths.pop() if lengths else 1
    W, delta_z, Fx, delta_x, Fy, delta_y = (
        _as_steps(k, v, nt)
        for k, v in zip(
            ("W", "delta_z", "Fx", "delta_x", "Fy", "delta_y"),
            (W, delta_z, Fx, delta_x, Fy, delta_y),
        )
    )
    if Fx is None and delta_x is None:
        delta_x = np.zeros(nt)
    if Fy is None and delta_y is None:
        delta_y = np.zeros(nt)

    X, Y, (dx, dy) = grid_coordinates(n, size)
    shape = X.shape
    N = X.size
    A = dx * dy
    h0 = np.asarray(h0, dtype=np.float64)
    if h0.shape != shape:
        raise ValueError(f"h0 must have shape {shape}, got {h0.shape}")
    h0 = h0.ravel()
    if C is None:
        C = dense_influence(n, size, nu)
    C = np.array(C, dtype=np.float64)  # copy: blocks may be zeroed below
    if C.shape != (3, 3, N, N):
        raise ValueError(f"C must have shape (3, 3, {N}, {N}), got {C.shape}")
    if coupling == "none":
        C[2, 0] = C[2, 1] = C[0, 2] = C[1, 2] = 0.0
    elif coupling == "x":
        C[2, 1] = C[1, 2] = 0.0
    C = C / G
    dim = 1 if coupling == "x" else 2
    Czz = C[2, 2]
    Ctt = C[:dim, :dim]  # (dim, dim, N, N)
    Ctz = C[:dim, 2]  # (dim, N, N)
    Czt = C[2, :dim]  # (dim, N, N)

    tol_in = 1e-2 * tol
    out = {
        k: []
        for k in ("p", "q", "u", "gap", "s", "ds", "delta_z", "delta_t", "alternations")
    }

    p = np.zeros(N)
    q = np.zeros((dim, N))
    s_prev = np.zeros((dim, N))
    dt_prev = np.zeros(dim)
    tang_cache = {}
    chol_cache = {}

    for k in range(nt):
        load = W is not None
        nval = W[k] / A if load else delta_z[k]
        tgt = []  # per direction: ("load", F) or ("disp", delta)
        for Fv, dv in ((Fx, delta_x), (Fy, delta_y))[:dim]:
            tgt.append(("load", Fv[k]) if Fv is not None else ("disp", dv[k]))
        dt = np.array(
            [v if kind == "disp" else dt_prev[j] for j, (kind, v) in enumerate(tgt)]
        )
        sp = s_prev if law == "incremental" else np.zeros_like(s_prev)

        for it in range(1, max_alternations + 1):
            # (a) normal problem for fixed q
            f = h0 + sum(Czt[j] @ q[j] for j in range(dim))
            p_new, dz = _solve_normal(Czz, f, load, nval, act0=p > 0, cache=chol_cache)
            # (b) tangential problem for fixed p
            cells = np.flatnonzero(p_new > 0)
            q_new = np.zeros((dim, N))
            if cells.size and mu > 0:
                key = cells.tobytes()
                if key not in tang_cache:
                    tang_cache.clear()
                    Kc = np.block(
                        [
                            [Ctt[a, b][np.ix_(cells, cells)] for b in range(dim)]
                            for a in range(dim)
                        ]
                    )
                    tang_cache[key] = (Kc, _lambda_max(Kc))
                solver = _Tangential(*tang_cache[key], mu * p_new[cells], dim)
                base = (sp - np.stack([Ctz[j] @ p_new for j in range(dim)]))[
                    :, cells
                ]  # (dim, m)
                uscale = max(
                    abs(dz),
                    np.abs(Czz @ p_new).max(),
                    np.abs(base).max(),
                    np.abs(dt).max(),
                    1e-300,
                )
                tol_abs = tol_in * uscale
                state = {"x": q[:, cells].ravel()}
                memo = {}

                def solve_q(dvec):
                    key_d = tuple(dvec)
                    if key_d not in memo:
                        b = (base + dvec[:, None]).ravel()
                        x, _ = solver.solve(b, state["x"], tol_abs)
                        state["x"] = x
                        memo[key_d] = x.reshape(dim, -1)
                    return memo[key_d]

                loads = [j for j, (kind, _) in enumerate(tgt) if kind == "load"]
                Wc = A * p_new.sum()
                if loads:
                    Ft = np.array([tgt[j][1] for j in loads])
                    if np.hypot.reduce(Ft) >= mu * Wc * (1 - 1e-12):
                        raise ValueError(
                            f"step {k}: tangential load {Ft} >= mu W = {mu * Wc}: "
                            "gross sliding"
                        )
                    a_eff = np.sqrt(A * cells.size / np.pi)
                    h_step = (
                        (2 - nu)
                        / (8 * G * a_eff)
                        * max(np.abs(Ft).max(), 1e-3 * mu * Wc)
                    )
                    ftol = tol_in * mu * Wc

                    def root_1d(j, dvec):
                        """Copy of dvec with dvec[j] such that A sum q_j = F_j."""
                        dvec = dvec.copy()

                        def fun(d):
                            dv = dvec.copy()
                            dv[j] = d
                            return A * solve_q(dv)[j].sum() - tgt[j][1]

                        dvec[j] = _monotone_root(fun, dvec[j], h_step, ftol)
                        return dvec

                    if len(loads) == 1:
                        dt = root_1d(loads[0], dt)
                    else:  # nested: inner on delta_x, outer on delta_y
                        inner = {}

                        def fun_y(d):
                            dv = dt.copy()
                            dv[1] = d
                            inner[d] = dv = root_1d(0, dv)
                            return A * solve_q(dv)[1].sum() - tgt[1][1]

                        dt = inner[_monotone_root(fun_y, dt[1], h_step, ftol)]
            elif any(kind == "load" and v != 0 for kind, v in tgt):
                raise ValueError(
                    f"step {k}: tangential load without friction or contact: "
                    "gross sliding"
                )
            if cells.size and mu > 0:
                q_new[:, cells] = solve_q(dt)

            pmax = max(p_new.max(), 1e-300)
            dp = np.abs(p_new - p).max()
            dq = np.abs(q_new - q).max() if mu > 0 else 0.0
            p, q = p_new, q_new
            if coupling == "none":
                break  # p does not depend on q: one sweep is exact
            if it > 1 and dp <= tol * pmax and dq <= tol * mu * pmax:
                break
        else:
            raise RuntimeError(
                f"step {k}: normal/tangential alternation did not converge in "
                f"{max_alternations} sweeps (dp/pmax = {dp / pmax:.2e}, dq/(mu pmax) = "
                f"{dq / (mu * pmax) if mu > 0 else 0:.2e})"
            )

        u = np.stack(
            [sum(C[a, b] @ q[b] for b in range(dim)) + C[a, 2] @ p for a in range(3)]
        )
        s = u[:dim] - dt[:, None]
        ds = s - sp
        if law == "incremental":
            s_prev = s
        dt_prev = dt.copy()
        out["p"].append(p.reshape(shape))
        qq = np.zeros((2, N))
        qq[:dim] = q
        out["q"].append(qq.reshape((2,) + shape))
        out["u"].append(u.reshape((3,) + shape))
        out["gap"].append((h0 + u[2] - dz).reshape(shape))
        s2 = np.zeros((2, N))
        ds2 = np.zeros((2, N))
        s2[:dim], ds2[:dim] = s, ds
        out["s"].append(s2.reshape((2,) + shape))
        out["ds"].append(ds2.reshape((2,) + shape))
        out["delta_z"].append(dz)
        d2 = np.zeros(2)
        d2[:dim] = dt
        out["delta_t"].append(d2)
        out["alternations"].append(it)

    res = {k: np.asarray(v) for k, v in out.items()}
    dtv = res.pop("delta_t")
    res["delta_x"], res["delta_y"] = dtv[:, 0], dtv[:, 1]
    res["W"] = A * res["p"].sum(axis=(1, 2))
    res["Fx"] = A * res["q"][:, 0].sum(axis=(1, 2))
    res["Fy"] = A * res["q"][:, 1].sum(axis=(1, 2))
    res["contact"] = res["p"] > 0
    qn = np.hypot(res["q"][:, 0], res["q"][:, 1])
    res["stick"] = res["contact"] & (qn < mu * res["p"] * (1 - stick_tol))
    res["slip"] = res["contact"] & ~res["stick"]
    res.update(mu=mu, G=G, nu=nu, law=law, coupling=coupling, cell_area=A, x=X, y=Y)
    return res


# ------------------------------------------------------------------- diagnostics


def conditions(res, k):
    """Pointwise contact and Coulomb residuals of step `k` (dimensionless, relative).

    - `p_min`: `min p / max p` (>= 0 expected); `gap_min`: `min gap / uscale`;
    - `complementarity`: `max p |gap| / (max p uscale)`;
    - `friction_excess`: `max (|q| - mu p) / (mu max p)` (<= 0 up to round-off);
    - `q_outside`: `max |q|` out of contact `/ (mu max p)`;
    - `stick_slip`: `max |Ds|` over stick cells `/ uscale`;
    - `slip_misalignment`: max over slip cells of `|q + mu p Ds/|Ds|| / (mu max p)`, for
      cells with `|Ds| > 1e-7 uscale` (direction of a vanishing increment is undefined);
    - `slip_natural`: max over slip cells of `|Ds + (|Ds| / (mu p)) q| / uscale` (zero
      iff Ds is a nonpositive multiple of q; well defined for any |Ds|);
    with `uscale = max(|u|, |delta_z|)` of the step.
    """
    p, q, ds, gap = res["p"][k], res["q"][k], res["ds"][k], res["gap"][k]
    mu = res["mu"]
    contact, stick, slip = res["contact"][k], res["stick"][k], res["slip"][k]
    pmax = max(p.max(), 1e-300)
    uscale = max(np.abs(res["u"][k]).max(), abs(res["delta_z"][k]))
    uscale = uscale if uscale > 0 else max(np.abs(gap).max(), 1e-300)
    qn = np.hypot(q[0], q[1])
    dsn = np.hypot(ds[0], ds[1])
    out = {
        "p_min": p.min() / pmax,
        "gap_min": gap.min() / uscale,
        "complementarity": np.max(p * np.abs(gap)) / pmax / uscale,
        "friction_excess": np.max(qn - mu * p) / (mu * pmax) if mu > 0 else 0.0,
        "q_outside": np.max(np.where(contact, 0.0, qn)) / (mu * pmax)
        if mu > 0
        else 0.0,
        "stick_slip": np.max(np.where(stick, dsn, 0.0)) / uscale,
    }
    big = slip & (dsn > 1e-7 * uscale)
    safe = np.where(dsn > 0, dsn, 1.0)
    mis = np.hypot(q[0] + mu * p * ds[0] / safe, q[1] + mu * p * ds[1] / safe)
    out["slip_misalignment"] = (
        np.max(np.where(big, mis, 0.0)) / (mu * pmax) if mu > 0 else 0.0
    )
    denom = mu * p
    ratio = np.divide(dsn, denom, out=np.zeros_like(dsn), where=slip & (denom > 0))
    nat = np.hypot(ds[0] + ratio * q[0], ds[1] + ratio * q[1])
    out["slip_natural"] = np.max(np.where(slip, nat, 0.0)) / uscale
    return out
