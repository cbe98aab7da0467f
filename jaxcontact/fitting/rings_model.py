"""The contact model on rings (`solve_axisymmetric`): the fit's forward model for a
frictionless axisymmetric probe (a sphere, a cone, any tip of revolution).

A pressure that depends on the radius alone needs `n` rings, not `n^2` cells: the
same fit at the grid's accuracy costs a fraction of its time (`benchmarks/notes/
rings.md`). `RingModel` has the interface of `SceneModel` (`curve(material, ctx)`,
hashable, a static argument of the compiled objective); its context is
`(scene, RingOperator)`, the operator built once, in NumPy, outside the traced
function. The rings cover `[0, radius]` with `radius` from the data (`ring_radius`):
`RING_MARGIN` times the radius where the probe's profile reaches the deepest
indentation (the geometric intersection, beyond any elastic contact of a convex
tip). A new radius with the same ring count reuses the compiled program.
"""

import dataclasses

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._indenter import AbstractAxisymmetricIndenter
from .._loading import Displacement
from .._ring_operator import RingOperator
from .._scene import Scene, normal_targets
from .._solve_rings import axisymmetric_support, solve_axisymmetric
from .._solver.rings import RingPolonskyKeer
from .options import SOLVERS


# Rings of a fit by default: 64 rings of equal width put 30-40 in the largest contact,
# a bias of ~4e-4 of the force (the grid's 64^2), far below an AFM curve's noise; the
# fit reports it (at twice the rings) and flags it above the noise.
DEFAULT_FIT_RINGS = 64

# The rings' outer radius over the profile's intersection radius at the deepest
# indentation: the elastic contact radius of a sphere is 1 / sqrt(2) of it, a cone's
# 2 / pi, so 1.25 leaves room for a trial material that indents deeper.
RING_MARGIN = 1.25

# radii evaluated at once by each narrowing of `intersection_radius`'s bracket
_SAMPLES = 1025

# `jc.solve` keywords the ring model honours (`rtol`, `max_steps`: its step solver's);
# `adjoint` is dropped (the ring solve's derivatives are implicit in both modes).
_RING_KEYWORDS = ("scheme", "history", "rtol", "max_steps", "adjoint")


def ring_options(solve_options: dict) -> dict | None:
    """`solve_axisymmetric` keywords for the fit's `solve_options` (`jc.solve`
    keywords), or `None` when one of them has no ring counterpart (a grid `solver`,
    `max_rounds`, ...)."""
    options = dict(solve_options)
    if any(k not in _RING_KEYWORDS for k in options):
        return None
    out = {k: options[k] for k in ("scheme", "history") if k in options}
    step = {k: options[k] for k in ("rtol", "max_steps") if options.get(k) is not None}
    if step:
        out["solver"] = RingPolonskyKeer(**step)
    return out


def rings_unsupported(scene: Scene, solve_options: dict) -> str | None:
    """`None` when the fit of `scene` can run on rings, else why not (a sentence)."""
    if not isinstance(scene.indenter, AbstractAxisymmetricIndenter):
        return f"the indenter {type(scene.indenter).__name__} is not axisymmetric"
    why = axisymmetric_support(scene)
    if why is not None:
        return why
    if ring_options(solve_options) is None:
        return (f"solve_options {sorted(solve_options)} include a grid solver's "
                "keyword (the rings take scheme, history, rtol, max_steps)")
    return None


def choose_solver(solver: str, scene: Scene, solve_options: dict) -> str:
    """`"rings"` or `"grid"` for the fit's `solver` setting: `"auto"` is the rings
    where they can solve the scene; a forced `"rings"` that cannot is a
    `ValueError` naming why."""
    if solver not in SOLVERS:
        raise ValueError(f"solver must be 'auto', 'rings' or 'grid', got {solver!r}")
    if solver == "grid":
        return "grid"
    why = rings_unsupported(scene, solve_options)
    if why is None:
        return "rings"
    if solver == "rings":
        raise ValueError(f'solver="rings" cannot fit this scene: {why}')
    return "grid"


def intersection_radius(indenter, depth: float, start: float) -> float:
    """The radius [length] where `indenter.profile` reaches `depth` [length] > 0
    (the profile increases with r), searched from `start` [length] > 0: the bracket
    doubled until the profile is deeper, then narrowed by evaluating the profile on
    `_SAMPLES` radii at once (a few calls of the profile, not one per bisection step),
    to a relative width of 1e-9."""
    def h(r):
        r = np.atleast_1d(np.asarray(r, np.float64))
        return np.asarray(indenter.profile(jnp.asarray(r, jnp.float64)), np.float64)

    hi = start
    for _ in range(60):  # double until the profile is deeper than `depth`
        if h(hi)[0] >= depth:
            break
        hi *= 2.0
    else:
        raise ValueError(f"the probe's profile does not reach the depth {depth!r} "
                         f"within {hi!r}")
    lo = 0.0
    while hi - lo > 1e-9 * hi:
        radii = np.linspace(lo, hi, _SAMPLES)
        k = int(np.searchsorted(h(radii) >= depth, True))  # first radius as deep
        lo, hi = radii[max(k - 1, 0)], radii[k]
    return float(hi)


def max_depth(scene: Scene, depth=None) -> float:
    """The deepest indentation [length] of a fit: of the measured `depth` when given,
    else of the scene's imposed approach (displacement control); NaN if neither."""
    if depth is not None:
        return float(np.max(np.asarray(depth, float)))
    if isinstance(scene.normal, Displacement):
        return float(np.max(np.asarray(normal_targets(scene, False), float)))
    return float("nan")


def ring_radius(scene: Scene, depth=None) -> float:
    """The outer radius [length] of the fit's rings (module notes), from the deepest
    indentation (`max_depth`); half the smaller side of the scene's grid where that
    is unknown or not positive (a load-controlled fit always has its depth)."""
    half = float(np.min(np.asarray(scene.grid.size))) / 2
    deepest = max_depth(scene, depth)
    if not (np.isfinite(deepest) and deepest > 0):
        return half
    return RING_MARGIN * intersection_radius(scene.indenter, deepest, 0.1 * half)


def ring_context(scene: Scene, rings: int, radius: float):
    """`(scene, RingOperator)`: `rings` rings of equal width over `[0, radius]`, in the
    grid's dtype."""
    return scene, RingOperator.uniform(radius, rings, dtype=scene.grid.size.dtype)


@dataclasses.dataclass(frozen=True)
class RingModel:
    """The contact model on rings as `curve(material, ctx) -> ((nt,) curve,
    (nt,) converged)`, `ctx = (scene, RingOperator)`. Hashable: `kind` is `"force"`
    or `"depth"`, `options` the `solve_axisymmetric` keywords. A step whose contact
    reaches the outermost ring counts as not converged (the contact may extend
    beyond the rings)."""

    kind: str
    options: tuple

    def __call__(self, material, ctx):
        scene, operator = ctx
        scene = eqx.tree_at(lambda s: s.material, scene, material)
        sol = solve_axisymmetric(scene, operator=operator,
                                 **{**dict(self.options), "throw": False})
        curve = sol.normal_force if self.kind == "force" else sol.approach
        return curve, sol.converged & ~sol.edge_contact

    @staticmethod
    def refined(ctx, factor: int = 2):
        """`ctx` with `factor` times the rings over the same radius."""
        scene, operator = ctx
        radius = float(np.asarray(operator.edges)[-1])
        return ring_context(scene, factor * operator.rings, radius)


def ring_model(scene: Scene, kind: str, solve_options: dict | None, *,
               rings: int = DEFAULT_FIT_RINGS, depth=None):
    """`(model, ctx)`: the ring model of `scene` (scheme `"linear"` unless
    `solve_options` say otherwise, as `scene_model`) on `rings` rings over
    `ring_radius(scene, depth)`."""
    options = {"scheme": "linear", **dict(solve_options or {})}
    converted = ring_options(options)
    if converted is None:
        raise ValueError(f"solve_options {sorted(options)} have no ring counterpart")
    model = RingModel(kind, tuple(sorted(converted.items(), key=lambda kv: kv[0])))
    return model, ring_context(scene, rings, ring_radius(scene, depth))
