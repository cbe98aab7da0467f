"""The contact model as a function of the fit's coordinates, and the objective.

The objective is the mean squared RELATIVE residual

    loss = mean_k ((y_model(t_k) - y_data(t_k)) / rms(y_data))^2,

(each sample's residual times its weight, when weighted), dimensionless and O(1) or
smaller for any initial guess of the right order. Every model evaluation outside
Levenberg-Marquardt goes through ONE compiled value-and-gradient function
(`_objective`; the line search, the initial guess and the sensitivities reuse it, and
`Evaluator` counts the calls), so a fit compiles the model once, and further fits of
the same shapes (a noise study) compile nothing new.
"""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree

from .. import _validate
from .._solve import operator_for, solve
from .._sweep import traced_directions
from .parametrisation import to_material


@dataclasses.dataclass(frozen=True)
class SceneModel:
    """The contact model as `curve(material, ctx) -> ((nt,) curve, (nt,) converged)`,
    with `ctx = (scene, operator)`. Hashable (a static argument of the jitted
    objective): `kind` is `"force"` or `"depth"`, `options` the `jc.solve` keywords."""

    kind: str
    options: tuple

    def __call__(self, material, ctx):
        scene, operator = ctx
        scene = eqx.tree_at(lambda s: s.material, scene, material)
        # A fit weighs a non-converged model curve through its flags, not an exception.
        sol = solve(scene, operator=operator, **{"throw": False, **dict(self.options)})
        curve = sol.normal_force if self.kind == "force" else sol.approach
        return curve, sol.converged

    @staticmethod
    def refined(ctx, factor: int = 2):
        """`ctx` on a grid of `factor` times the cells per side, same size."""
        scene, _ = ctx
        g = scene.grid
        fine = eqx.tree_at(lambda sc: sc.grid, scene, type(g)(
            shape=tuple(factor * k for k in g.shape), size=g.size,
            periodic=g.periodic))
        return fine, operator_for(fine, traced_directions(fine))


def scene_model(scene, kind: str, solve_options: dict | None):
    """`(model, ctx)`: the contact model of `scene` with `solve_options` (scheme
    `"linear"` unless they say otherwise) and its context (the scene, its operator)."""
    # scheme "linear" by default: measured data are sampled ramps, which the
    # piecewise-constant scheme turns into staircases (a 1-arm ramp fit at 0.25 s
    # steps: the model 6 % off on loading, g_1 -17 %); it is also stable at any
    # step, whatever material the optimiser tries.
    options = {"scheme": "linear", **dict(solve_options or {})}
    model = SceneModel(kind, tuple(sorted(options.items())))
    return model, (scene, operator_for(scene, traced_directions(scene)))


def model_curve(theta, ctx, refs, model, fit_poisson):
    """`((nt,) curve, (nt,) converged)`: the model at the fit's coordinates `theta`.
    Traced without run-time input checks (`_validate.trusted_inputs`): the material is
    positive by its parametrisation and the scene was checked before the fit, and a
    program without checks (host callbacks) can be kept in the persistent
    compilation cache, so a second `jaxcontact fit` process loads it."""
    with _validate.trusted_inputs():
        return model(to_material(theta, refs, fit_poisson), ctx)


def _loss(theta, ctx, refs, target, scale, model, fit_poisson):
    """`(loss, (curve, converged))` with `loss = mean(((curve - target) / scale)^2)`."""
    curve, ok = model_curve(theta, ctx, refs, model, fit_poisson)
    return jnp.mean(((curve - target) / scale) ** 2), (curve, ok)


@eqx.filter_jit
def _objective(theta, *args):
    """`(loss, (curve, converged)), d loss / d theta` of `_loss`."""
    return jax.value_and_grad(_loss, has_aux=True)(theta, *args)


@eqx.filter_jit
def _forward(theta, *args):
    """`_loss` without its gradient (a forward solve alone: what a trial point, a
    line of the Jacobian or a stopping test needs)."""
    return _loss(theta, *args)


def relative_residual(theta, args):
    """Relative residual `(curve - target) / scale` (the least-squares form of
    `_objective`'s loss: `loss = mean(residual^2)`)."""
    ctx, refs, target, scale, model, fit_poisson = args
    curve, _ = model_curve(theta, ctx, refs, model, fit_poisson)
    return (curve - target) / scale


class Evaluator:
    """Calls the compiled objective, counts the calls."""

    def __init__(self, ctx, refs, target, scale, model, fit_poisson, dtype):
        self.args = (ctx, refs, target, scale, model, fit_poisson)
        self.scale = np.asarray(scale, float)  # () or (nt,) with weights
        self.zeros = jnp.zeros(target.shape, dtype)
        self.calls = 0

    def loss(self, theta):
        """`(loss, gradient, curve, converged)`; the loss is `inf` where the trial
        parameters make an invalid material (e.g. two equal relaxation times: the
        constructor's runtime check fires) so that the caller rejects the step."""
        self.calls += 1
        try:
            (value, (curve, ok)), grad = _objective(theta, *self.args)
        except eqx.EquinoxRuntimeError:
            inf = jnp.asarray(jnp.inf, self.zeros.dtype)
            return inf, theta, self.zeros + jnp.nan, jnp.zeros(self.zeros.shape, bool)
        return value, grad, curve, ok

    def value(self, theta):
        """`(loss, curve, converged)` as `loss` gives them, without the gradient."""
        self.calls += 1
        try:
            value, (curve, ok) = _forward(theta, *self.args)
            return value, curve, ok
        except eqx.EquinoxRuntimeError:
            inf = jnp.asarray(jnp.inf, self.zeros.dtype)
            return inf, self.zeros + jnp.nan, jnp.zeros(self.zeros.shape, bool)

    def jacobian(self, theta, step):
        """`(nt, p)` Jacobian of the relative residual in the (flattened)
        log-parameters, by central differences of step `step`: `2 p` evaluations of the
        compiled objective (cheaper than `nt` adjoint rows when `nt > 2 p`)."""
        flat, unravel = ravel_pytree(theta)
        scale = self.scale
        columns = []
        for e in np.eye(flat.shape[0]):
            e = jnp.asarray(step * e, flat.dtype)
            _, up, _ = self.value(unravel(flat + e))
            _, down, _ = self.value(unravel(flat - e))
            columns.append((np.asarray(up, float) - np.asarray(down, float))
                           / (2 * step * scale))
        return np.stack(columns, axis=1)
