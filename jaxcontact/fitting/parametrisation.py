"""The fit's coordinates `theta` and the Prony series they make (positivity by
construction; every parameter O(1)):

    g_inf = G_ref exp(theta_inf),  g_i = G_ref exp(theta_g[i]),
    tau_i = T_ref exp(theta_tau[i]),  poisson = 0.5 sigmoid(theta_nu)  (if fitted)

with `G_ref`, `T_ref` fixed reference scales (the initial instantaneous modulus and
the data's time span), held with Poisson's ratio in `refs`. Fixed parameters
(`fit_prony(fixed=...)`) live in `refs["fixed"]` as scaled logs, not in `theta`; a
parameter with bounds (`fit_prony(bounds=...)`) is a logit between its scaled log
bounds (`refs["bounds"]`). Here also: the checks of `fixed=` and `bounds=`.
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


def log_scaled(theta, refs, key):
    """`log(value / reference)` of parameter `key`: `theta[key]` itself, or for a
    parameter with bounds (`fit_prony(bounds=...)`, held in `refs["bounds"]` as
    `(lo, hi)` in the same scaled logs) `lo + (hi - lo) sigmoid(theta[key])`."""
    bounds = refs.get("bounds", {})
    if key in bounds:
        lo, hi = bounds[key]
        return lo + (hi - lo) * jax.nn.sigmoid(theta[key])
    return theta[key]


def bound_factors(theta, refs):
    """`d log(value) / d theta` of every leaf of `theta` (1 where unbounded)."""
    out = {}
    for key, value in theta.items():
        if key in refs.get("bounds", {}):
            lo, hi = refs["bounds"][key]
            sig = jax.nn.sigmoid(value)
            out[key] = (hi - lo) * sig * (1 - sig)
        else:
            out[key] = jnp.ones_like(value)
    return out


def to_theta(material: Prony, refs: dict, fit_poisson: bool, dtype) -> dict:
    theta = {
        "g_inf": jnp.log(jnp.asarray(material.g_inf, dtype) / refs["g_ref"]),
        "g": jnp.log(jnp.asarray(material.g, dtype) / refs["g_ref"]),
        "tau": jnp.log(jnp.asarray(material.tau, dtype) / refs["t_ref"]),
    }
    for key, (lo, hi) in refs.get("bounds", {}).items():
        # the logit coordinate, the start pulled 5 % of the range inside the bounds
        # (where the sigmoid still has slope)
        frac = jnp.clip((theta[key] - lo) / (hi - lo), 0.05, 0.95)
        theta[key] = jnp.log(frac / (1 - frac))
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
