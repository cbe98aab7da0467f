"""The fit's coordinates `theta` and the Prony series they make (positivity by
construction; every parameter O(1)):

    g_inf = G_ref exp(theta_inf),  g_i = G_ref exp(theta_g[i]),
    tau_i = T_ref exp(theta_tau[i]),  poisson = 0.5 sigmoid(theta_nu)  (if fitted)

with `G_ref`, `T_ref` fixed reference scales (the initial instantaneous modulus and
the data's time span), held with Poisson's ratio in `refs`. Fixed parameters
(`fit_prony(fixed=...)`) live in `refs["fixed"]` as scaled logs, not in `theta`; a
parameter with bounds (`fit_prony(bounds=...)`) keeps its scaled log as coordinate,
clipped to its scaled log bounds (`refs["bounds"]`), a modulus without bounds to a
floor of 1e-12 of `G_ref`: beyond a limit the value is the limit and its derivative
0, so Levenberg-Marquardt's step stops there instead of creeping along a flattening
coordinate (`project` puts a result on its limit). Here also: the checks of
`fixed=` and `bounds=`.
"""

import math

import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree

from .._material.prony import Prony


_KEYS = ("g_inf", "g", "tau")


def to_material(theta: dict, refs: dict, fit_poisson: bool) -> Prony:
    # Fixed parameters (`fit_prony(fixed=...)`) are held in `refs["fixed"]` as log
    # values and are not among the optimised leaves of `theta`.
    theta = {**refs.get("fixed", {}), **theta}
    g_ref, t_ref = refs["g_ref"], refs["t_ref"]
    poisson = 0.5 * jax.nn.sigmoid(theta["poisson"]) if fit_poisson else refs["poisson"]
    return Prony(
        g_ref * jnp.exp(log_scaled(theta, refs, "g_inf")),
        g_ref * jnp.exp(log_scaled(theta, refs, "g")),
        t_ref * jnp.exp(log_scaled(theta, refs, "tau")),
        poisson,
    )


# The moduli's floor in scaled logs: 1e-12 of the reference modulus, far below what
# any data resolve (under 1e-4 of g0 an arm is dead to the certificate) and below any
# start's share of it (a start's dead arm can inflate the reference by 1e9). Beyond
# it a modulus has no gradient: Levenberg-Marquardt leaves a dropped modulus there
# (`lm.drop_a_modulus`) instead of creeping towards 0 in its log for ever.
LOG_FLOOR = math.log(1e-12)


def limits(refs, key):
    """`(lo, hi)` of the coordinate of parameter `key` in scaled logs: its bounds
    (`fit_prony(bounds=...)`, `refs["bounds"]`), the floor for a modulus without
    bounds, `None` for an unbounded relaxation time (and Poisson's ratio)."""
    if key in refs.get("bounds", {}):
        return refs["bounds"][key]
    if key in ("g_inf", "g"):
        return LOG_FLOOR, math.inf
    return None


def log_scaled(theta, refs, key):
    """`log(value / reference)` of parameter `key`: `theta[key]` clipped to its
    `limits` (on a limit the derivative is the inside's, 1; beyond it 0)."""
    lim = limits(refs, key)
    if lim is None:
        return theta[key]
    lo, hi = lim
    x = theta[key]
    return jnp.where(x < lo, lo, jnp.where(x > hi, hi, x))


def project(theta, refs) -> dict:
    """`theta` with every coordinate clipped to its `limits` (the same material: a
    coordinate beyond a limit stands for the limit)."""
    return {key: log_scaled(theta, refs, key) for key in theta}


def inside(theta, refs, margin: float) -> dict:
    """`theta` with every limited coordinate at least `margin` inside its limits (a
    central difference of step `margin` there sees the inside's slope, not half of
    it)."""
    out = dict(theta)
    for key in out:
        lim = limits(refs, key)
        if lim is not None and float(lim[1] - lim[0]) > 2 * margin:
            out[key] = jnp.clip(out[key], lim[0] + margin, lim[1] - margin)
    return out


def pinned(theta, grad, refs) -> dict:
    """`{key: bool array}`: the coordinates of `theta` on (or beyond) a limit that
    the loss's gradient `grad` (same layout) pushes outwards: the active set of the
    constrained minimum, whose columns a Gauss-Newton step must leave out."""
    out = {}
    for key, value in theta.items():
        lim = limits(refs, key)
        if lim is None:
            out[key] = jnp.zeros(jnp.shape(value), bool)
            continue
        lo, hi = lim
        out[key] = ((value <= lo) & (grad[key] >= 0)) | ((value >= hi)
                                                         & (grad[key] <= 0))
    return out


def to_theta(material: Prony, refs: dict, fit_poisson: bool, dtype) -> dict:
    theta = {
        "g_inf": jnp.log(jnp.asarray(material.g_inf, dtype) / refs["g_ref"]),
        "g": jnp.log(jnp.asarray(material.g, dtype) / refs["g_ref"]),
        "tau": jnp.log(jnp.asarray(material.tau, dtype) / refs["t_ref"]),
    }
    for key in _KEYS:
        # a start beyond a limit starts on it (where the coordinate still moves)
        lim = limits(refs, key)
        if lim is not None and key in theta:
            theta[key] = jnp.clip(theta[key], *lim)
    if fit_poisson:
        nu = jnp.asarray(material.poisson, dtype)
        theta["poisson"] = jnp.log(nu / (0.5 - nu))  # logit(2 nu)
    return theta


def split(theta: dict, values: np.ndarray) -> dict:
    """Per-parameter pieces of a flat vector laid out like `ravel_pytree(theta)`."""
    _, unravel = ravel_pytree(theta)
    return {k: np.asarray(v) for k, v in unravel(jnp.asarray(values)).items()}


def check_fixed(fixed, n: int) -> dict:
    """`fit_prony(fixed=...)` checked: `{key: array > 0}` of `g_inf` (a number), `g`
    and `tau` (`n` numbers each)."""
    out = {}
    for key, value in dict(fixed or {}).items():
        if key not in _KEYS:
            raise ValueError(f"fixed: unknown parameter {key!r} (g_inf, g, tau; "
                             "Poisson's ratio is fixed by default)")
        shape = () if key == "g_inf" else (n,)
        arr = np.asarray(value, float)
        if arr.shape != shape or not np.all(np.isfinite(arr)) or not np.all(arr > 0):
            raise ValueError(f"fixed[{key!r}] must be "
                             f"{'a number' if not shape else f'{n} numbers'}"
                             f" > 0, got {value!r}")
        out[key] = arr
    return out


def check_bounds(bounds, fixed: dict) -> dict:
    """`fit_prony(bounds=...)` checked: `{key: (lo, hi)}`, `0 < lo < hi < inf`, of
    parameters that are not `fixed`."""
    out = {}
    for key, value in dict(bounds or {}).items():
        if key not in _KEYS:
            raise ValueError(f"bounds: unknown parameter {key!r} (g_inf, g, tau)")
        if key in fixed:
            raise ValueError(f"bounds[{key!r}]: the parameter is fixed")
        try:
            lo, hi = (float(v) for v in value)
        except (TypeError, ValueError):
            raise ValueError(f"bounds[{key!r}] must be a pair (lo, hi), got {value!r}")
        if not (0 < lo < hi < math.inf):
            raise ValueError(f"bounds[{key!r}] must satisfy 0 < lo < hi < inf, got "
                             f"{value!r}")
        out[key] = (lo, hi)
    return out


def make_refs(g_ref: float, t_ref: float, poisson, fixed: dict, bounds: dict,
              dtype) -> dict:
    """The reference scales, Poisson's ratio and the fixed values and bounds in scaled
    logs: what `to_material` needs besides `theta`."""
    refs = {
        "g_ref": jnp.asarray(g_ref, dtype),
        "t_ref": jnp.asarray(t_ref, dtype),
        "poisson": jnp.asarray(poisson, dtype),
    }
    scales = {"g_inf": refs["g_ref"], "g": refs["g_ref"], "tau": refs["t_ref"]}
    if fixed:
        refs["fixed"] = {k: jnp.log(jnp.asarray(v, dtype) / scales[k])
                         for k, v in fixed.items()}
    if bounds:
        refs["bounds"] = {k: (jnp.log(jnp.asarray(lo, dtype) / scales[k]),
                              jnp.log(jnp.asarray(hi, dtype) / scales[k]))
                          for k, (lo, hi) in bounds.items()}
    return refs
