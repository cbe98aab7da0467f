"""The fitted model's own discretisation error (`FitOptions(check_grid=True)`,
`PronyFit.discretisation`, and after the fact `discretisation_error`): the RMS
difference between its curve on the fit's grid and on a grid of twice the cells per
side, same width; a bias the fit cannot remove, to compare with the noise."""

import numpy as np

from .._scene import Scene
from .._solve import operator_for
from .._sweep import traced_directions
from .data import IndentationData, scene_for
from .model import SceneModel
from .result import PronyFit
from .rings_model import ring_context, ring_model


def discretisation_rms(scene, material, model, curve, ctx=None):
    """RMS difference [data units] between `curve` (the model on `scene`'s grid, or
    on the context `ctx` it was fitted on: e.g. rings) and the same model at twice
    the resolution (`model.refined`: twice the cells per side or twice the rings,
    same size)."""
    if ctx is None:
        ctx = (scene, operator_for(scene, traced_directions(scene)))
    fine_curve, _ = model(material, model.refined(ctx))
    return float(np.sqrt(np.mean((np.asarray(curve) - np.asarray(fine_curve)) ** 2)))


def discretisation_error(fit: PronyFit, data: IndentationData, scene_template: Scene,
                         solve_options: dict | None = None) -> float:
    """`PronyFit.discretisation` after the fact: the RMS difference [data units]
    between `fit.curve` and the fitted model on a grid of twice the cells (same
    width; a fit on rings: twice its rings over its radius) for the same data and
    template (`solve_options` as given to the fit;
    the fit's default scheme `"linear"` unless it says otherwise)."""
    dtype = scene_template.grid.size.dtype
    scene, kind, _ = scene_for(data, scene_template, dtype)
    if getattr(fit, "solver", "grid") == "rings":  # twice the fit's rings
        model, _ = ring_model(scene, kind, solve_options, rings=fit.rings,
                              depth=data.depth)
        ctx = ring_context(scene, fit.rings, fit.ring_radius)
        return discretisation_rms(scene, fit.material, model, fit.curve, ctx=ctx)
    options = {"scheme": "linear", **dict(solve_options or {})}
    model = SceneModel(kind, tuple(sorted(options.items())))
    return discretisation_rms(scene, fit.material, model, fit.curve)
