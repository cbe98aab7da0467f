"""The closed-form Lee-Radok fit of a loading-and-hold indentation curve (a probe of
the power law `F = C G d^m`: a sphere, `m = 3/2`, or a cone, `m = 2`;
`jaxcontact._probe`): the start of `jc.fit_prony(init="lee-radok")` and the
viscoelastic contact point of `jc.read_afm`. Plain NumPy; no contact solve."""

import itertools

import numpy as np


def lee_radok_columns(t, drive, taus):
    """`(n, 1 + m)` columns of the closed-form Lee-Radok response to a piecewise-linear
    `drive` (zero at `t[0]`): the drive itself and, for each time `tau` of `taus`,
    `h(t) = int_0^t exp(-(t - s) / tau) d drive(s)` (exact for piecewise-linear
    input; the recursion `h_k = e_k h_(k-1) + inc_k` over the samples as a prefix scan
    of its affine maps, log2(n) vectorised steps, over every `tau` at once)."""
    dt = np.diff(t)[:, None]
    e = np.exp(-dt / taus[None, :])
    a, b = e, np.diff(drive)[:, None] / dt * taus[None, :] * (1 - e)
    # After the step of `shift`, (a_k, b_k) maps h at sample k + 1 - 2 shift (clipped
    # to 0, where h = 0) to h at k + 1: composing two such maps halves the steps left.
    shift = 1
    while shift < a.shape[0]:
        a, b = (np.concatenate([a[:shift], a[shift:] * a[:-shift]]),
                np.concatenate([b[:shift], a[shift:] * b[:-shift] + b[shift:]]))
        shift *= 2
    h = np.concatenate([np.zeros((1, taus.size)), b])
    return np.concatenate([drive[:, None], h], axis=1)


def check_exponent(exponent) -> float:
    """`exponent` (the `m` of `F ~ d^m`) as a float, or a `ValueError` naming it: a
    finite number > 0 (3/2 a sphere, 2 a cone)."""
    if isinstance(exponent, bool) or not isinstance(
            exponent, (int, float, np.integer, np.floating)) or not (
            np.isfinite(exponent) and exponent > 0):
        raise ValueError(f"exponent must be a finite number > 0 (1.5: a sphere, 2: a "
                         f"cone), got {exponent!r}")
    return float(exponent)


def lee_radok_fit(time, force, depth, mode, *, arms=2, n_tau=20, start=0, weights=None,
                  positive=False, exponent=1.5):
    """The best closed-form Lee-Radok model of a loading-and-hold curve, with `arms`
    relaxation (creep) times on a log grid of `n_tau` times between the smallest
    sample step (at least 1e-3 of the span) and the span.

    Valid while the contact radius does not shrink (loading and hold). For a probe
    of the law `F = C G d^m` (`exponent` `m`: 3/2 a sphere, 2 a cone), with
    `u = depth^m`:

    - relaxation (depth imposed): `F(t) = int_0^t G_app(t - s) du(s)`,
      `G_app = c_0 + sum_i c_i exp(-t / tau_i)`;
    - creep (force imposed): `u(t) = int_0^t J_app(t - s) dF(s)`,
      `J_app = c_0 + sum_i c_i (1 - exp(-t / tau_i))`.

    Both are linear in the `c` (apparent moduli or compliances: `G_app = C G`,
    `J_app = J / C`, with `C = 8 sqrt(R) / (3 (1 - nu))` for a sphere of radius `R`,
    `4 tan(alpha) / (pi (1 - nu))` for a cone of half-angle `alpha`:
    `jaxcontact._probe.Probe.prefactor`), so each set of times costs one small
    linear least squares (normal equations from one Gram matrix).

    **Arguments:** `time`, `force`, `depth`: `(n,)`, zero at the contact; `mode`:
    `"relaxation"` or `"creep"`; `start`: the residual counts from this sample on
    (the model runs from the first); `weights`: `(n,)` sample weights (default 1);
    `positive`: only sets of times whose `c` are all > 0 (a valid series);
    `exponent`: `m` (default 1.5, a sphere).

    **Returns:** `(misfit, taus, c)`: the relative weighted misfit
    `mean((w (model - target))^2) / mean((w target)^2)` over the counted samples, the
    `(arms,)` times and the `(arms + 1,)` coefficients `c_0, c_1..` (`inf`, `None`,
    `None` when no set qualifies).

    **Raises:** `ValueError` for an `exponent` that is not a finite number > 0.
    """
    exponent = check_exponent(exponent)
    t = np.asarray(time, float)
    u = np.clip(np.asarray(depth, float), 0.0, None) ** exponent
    f = np.asarray(force, float)
    span, first = float(t[-1] - t[0]), float(np.min(np.diff(t)))
    taus = np.geomspace(max(first, 1e-3 * span), span, n_tau)
    if mode == "relaxation":
        cols, target = lee_radok_columns(t, u, taus), f
    else:
        cols = lee_radok_columns(t, f, taus)
        cols = np.concatenate([cols[:, :1], cols[:, :1] - cols[:, 1:]], axis=1)
        target = u
    w = np.ones(t.shape) if weights is None else np.asarray(weights, float)
    cols, target = cols[start:] * w[start:, None], target[start:] * w[start:]
    scale = max(float(np.sqrt(np.mean(target**2))), 1e-300)
    cols, target = cols / scale, target / scale
    gram, rhs, tt = cols.T @ cols, cols.T @ target, float(target @ target)
    # Every set of `arms` times at once: (K, arms + 1) column indices, the constant
    # column first, and one batched solve of the (K, arms + 1, arms + 1) systems.
    combos = np.array([*itertools.combinations(range(1, n_tau + 1), arms)],
                      dtype=int).reshape(-1, arms)
    idx = np.concatenate([np.zeros((combos.shape[0], 1), int), combos], axis=1)
    a = gram[idx[:, :, None], idx[:, None, :]]
    b = rhs[idx]
    system = a + 1e-12 * np.trace(a, axis1=1, axis2=2)[:, None, None] * np.eye(arms + 1)
    try:
        c = np.linalg.solve(system, b[..., None])[..., 0]
    except np.linalg.LinAlgError:  # a singular set (a degenerate grid): skip it alone
        c = np.stack([_solve_or_nan(m, v) for m, v in zip(system, b, strict=True)])
    value = (tt - 2 * np.sum(c * b, axis=1)
             + np.einsum("ki,kij,kj->k", c, a, c)) / target.size
    value = np.maximum(value, 0.0)
    ok = np.all(np.isfinite(c), axis=1)
    if positive:
        ok &= np.all(c > 0, axis=1)
    if not np.any(ok):
        return np.inf, None, None
    k = int(np.argmin(np.where(ok, value, np.inf)))
    return float(value[k]), taus[combos[k] - 1], c[k]


def _solve_or_nan(m, v):
    try:
        return np.linalg.solve(m, v)
    except np.linalg.LinAlgError:
        return np.full(v.shape, np.nan)


def lee_radok_misfit(time, force, depth, mode, *, arms=2, n_tau=20, start=0,
                     exponent=1.5):
    """The relative misfit of `lee_radok_fit` (any sign of the coefficients; the
    probe's `exponent`, default 1.5: a sphere): the contact point's objective in
    `read_afm(..., contact="viscoelastic")`."""
    return lee_radok_fit(time, force, depth, mode, arms=arms, n_tau=n_tau,
                         start=start, exponent=exponent)[0]
