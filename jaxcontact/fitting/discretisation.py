"""The fitted model's own discretisation error (`FitOptions(check_grid=True)`,
`PronyFit.discretisation`, and after the fact `discretisation_error`): the RMS
difference between its curve on the fit's grid and on a grid of twice the cells per
side, same width; a bias the fit cannot remove, to compare with the noise."""

import equinox as eqx
import numpy as np

from .._scene import Scene
from .._solve import operator_for
from .._sweep import traced_directions
from .data import IndentationData, scene_for
from .model import SceneModel
from .result import PronyFit


def discretisation_rms(scene, material, model, curve):
    """RMS difference [data units] between `curve` (the model on `scene`'s grid) and
    the same model on a grid of twice the cells per side, same size."""
    g = scene.grid
    fine = eqx.tree_at(lambda sc: sc.grid, scene, type(g)(
        shape=tuple(2 * k for k in g.shape), size=g.size, periodic=g.periodic))
    fine_curve, _ = model(material,
                          (fine, operator_for(fine, traced_directions(fine))))
    return float(np.sqrt(np.mean((np.asarray(curve) - np.asarray(fine_curve)) ** 2)))


def discretisation_error(fit: PronyFit, data: IndentationData, scene_template: Scene,
                         solve_options: dict | None = None) -> float:
    """`PronyFit.discretisation` after the fact: the RMS difference [data units]
    between `fit.curve` and the fitted model on a grid of twice the cells (same
    width) for the same data and template (`solve_options` as given to the fit;
    the fit's default scheme `"linear"` unless it says otherwise)."""
    dtype = scene_template.grid.size.dtype
    scene, kind, _ = scene_for(data, scene_template, dtype)
    options = {"scheme": "linear", **dict(solve_options or {})}
    model = SceneModel(kind, tuple(sorted(options.items())))
    return discretisation_rms(scene, fit.material, model, fit.curve)
