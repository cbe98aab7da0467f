"""`jc.fit_prony`: fit a Prony series to indentation data by running the full contact
model (`jc.solve`) and differentiating through it.

Parametrisation (positivity by construction; every parameter O(1)):

    g_inf = G_ref exp(theta_inf),  g_i = G_ref exp(theta_g[i]),
    tau_i = T_ref exp(theta_tau[i]),  poisson = 0.5 sigmoid(theta_nu)  (if fitted)

with `G_ref`, `T_ref` fixed reference scales (the initial instantaneous modulus and
the data's time span). The objective is the mean squared RELATIVE residual

    loss = mean_k ((y_model(t_k) - y_data(t_k)) / rms(y_data))^2,

dimensionless and O(1) or smaller for any initial guess of the right order.

The start (unless `init=` is given) comes from the data: one elastic run of the model
turns every sample into an apparent modulus, and a cheap least-squares Prony fit of
`G(t)` (or `1/J(t)` under load control) to those moduli gives the series (see
`_initial_guess`). The optimiser is optimistix's Levenberg-Marquardt on the residual
(default when optimistix is installed; Jacobian by forward mode through the contact
solve's implicit tangent solves, one per parameter; one compiled program), or
(`optimiser="lbfgs"`) Adam (a few steps; the best point is kept), then L-BFGS
(`optax.scale_by_lbfgs`, the direction of `optax.lbfgs`, memory 20) with an Armijo
backtracking line search driven from Python. Every model evaluation goes
through ONE compiled value-and-gradient function (the line search, the initial guess
and the sensitivities reuse it), so a fit compiles the model once, and further fits of
the same shapes (a noise study) compile nothing new.

Sensitivities are reported in two forms (`PronyFit.std`, `PronyFit.gradient`):

- `std`: the Gauss-Newton (linearised least-squares) standard deviation of each
  LOG-parameter, i.e. approximately the relative standard deviation of the parameter:
  `Cov = sigma^2 (J^T J)^-1`, `J = d(residual / rms)/d(log param)` at the optimum
  (central differences of the model, step 1e-3 in float64 and 3e-2 in float32:
  `2 p` evaluations instead of one adjoint per sample), with
  `sigma` the noise level (given as `noise_std`, or estimated from the residual as
  `sqrt(SSR / (n - p))`). A direction the data do not determine gets `inf`.
- `gradient`: `d(loss)/d(log param)` at the returned parameters (0 at an exact
  minimum; a check of convergence, not an uncertainty).
"""

import dataclasses
import functools
import math
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
from jax.flatten_util import ravel_pytree
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from ._indenter import Sphere
from ._loading import Displacement, Force
from ._material.prony import Prony, retardation_series
from ._scene import Scene
from ._solve import _operator_for, _warn_unstable_steps, solve
from ._solver.implicit import ImplicitAdjoint
from ._sweep import _AXIS, _pad, _traced_directions


_MAX_STEP = 1.0  # largest change of a log-parameter in one L-BFGS step

# --------------------------------------------------------------------------------------
# Data.


def _series(name: str, value) -> np.ndarray:
    if isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be an array of real numbers, got {value!r}")
    try:
        arr = np.asarray(value)
    except Exception as exc:  # pragma: no cover - exotic input
        raise TypeError(
            f"{name} must be an array of real numbers, got {value!r}") from exc
    if arr.dtype == object or arr.dtype.kind not in "iuf":
        raise TypeError(
            f"{name} must be an array of real numbers, got dtype {arr.dtype}")
    if arr.ndim != 1:
        raise ValueError(f"{name} must be a 1-D array, got shape {arr.shape}")
    bad = ~np.isfinite(arr)
    if bad.any():
        raise ValueError(
            f"{name} must be finite: NaN or inf at index {int(np.argmax(bad))} "
            f"(value {arr[np.argmax(bad)]!r})"
        )
    return arr


class IndentationData(eqx.Module):
    """Measured indentation curves on a common time axis.

    **Arguments:**

    - `times`: `(nt,)` strictly increasing sample times [time], at least 3.
    - `force`: optional `(nt,)` normal load `W(t)` [force].
    - `depth`: optional `(nt,)` indentation depth = rigid-body approach `delta_z(t)`
      [length], positive into the body.

    At least one of `force`, `depth` is required. Which one is fitted depends on the
    scene's control mode (see `jc.fit_prony`). Values are checked here: NaN or inf,
    repeated or decreasing times and length mismatches raise `ValueError`.
    """

    times: np.ndarray
    force: np.ndarray | None
    depth: np.ndarray | None

    def __init__(self, times, force=None, depth=None):
        times = _series("times", times).astype(float)
        if times.shape[0] < 3:
            raise ValueError(f"times needs at least 3 samples, got {times.shape[0]}")
        steps = np.diff(times)
        if not (steps > 0).all():
            k = int(np.argmax(steps <= 0))
            what = "repeated" if steps[k] == 0 else "decreasing (not monotonic)"
            raise ValueError(
                f"times must be strictly increasing: {what} at index {k + 1} "
                f"(times[{k}]={times[k]!r}, times[{k + 1}]={times[k + 1]!r})"
            )
        if force is None and depth is None:
            raise ValueError(
                "IndentationData needs force, depth, or both (got neither)")
        out = {}
        for name, value in (("force", force), ("depth", depth)):
            if value is None:
                out[name] = None
                continue
            arr = _series(name, value).astype(float)
            if arr.shape != times.shape:
                raise ValueError(
                    f"{name} must have one value per time ({times.shape[0]}), "
                    f"got length {arr.shape[0]}"
                )
            out[name] = arr
        self.times = times
        self.force = out["force"]
        self.depth = out["depth"]


# --------------------------------------------------------------------------------------
# Parametrisation.


def _to_material(theta: dict, refs: dict, fit_poisson: bool) -> Prony:
    # Fixed parameters (`fit_prony(fixed=...)`) are held in `refs["fixed"]` as log
    # values and are not among the optimised leaves of `theta`.
    theta = {**refs.get("fixed", {}), **theta}
    g_ref, t_ref = refs["g_ref"], refs["t_ref"]
    poisson = 0.5 * jax.nn.sigmoid(theta["poisson"]) if fit_poisson else refs["poisson"]
    return Prony(
        g_ref * jnp.exp(_log_scaled(theta, refs, "g_inf")),
        g_ref * jnp.exp(_log_scaled(theta, refs, "g")),
        t_ref * jnp.exp(_log_scaled(theta, refs, "tau")),
        poisson,
    )


def _log_scaled(theta, refs, key):
    """`log(value / reference)` of parameter `key`: `theta[key]` itself, or for a
    parameter with bounds (`fit_prony(bounds=...)`, held in `refs["bounds"]` as
    `(lo, hi)` in the same scaled logs) `lo + (hi - lo) sigmoid(theta[key])`."""
    bounds = refs.get("bounds", {})
    if key in bounds:
        lo, hi = bounds[key]
        return lo + (hi - lo) * jax.nn.sigmoid(theta[key])
    return theta[key]


def _bound_factors(theta, refs):
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


def _to_theta(material: Prony, refs: dict, fit_poisson: bool, dtype) -> dict:
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


# --------------------------------------------------------------------------------------
# The model: one compiled objective.


@dataclasses.dataclass(frozen=True)
class _SceneModel:
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


@eqx.filter_jit
def _objective(theta, ctx, refs, target, scale, model, fit_poisson):
    """`(loss, (curve, converged)), d loss / d theta` with
    `loss = mean(((curve - target) / scale)^2)`."""

    def loss(theta):
        curve, ok = model(_to_material(theta, refs, fit_poisson), ctx)
        return jnp.mean(((curve - target) / scale) ** 2), (curve, ok)

    return jax.value_and_grad(loss, has_aux=True)(theta)


def _residual(theta, args):
    """Relative residual `(curve - target) / scale` (the least-squares form of
    `_objective`'s loss: `loss = mean(residual^2)`)."""
    ctx, refs, target, scale, model, fit_poisson = args
    curve, _ = model(_to_material(theta, refs, fit_poisson), ctx)
    return (curve - target) / scale


@eqx.filter_jit
def _lm_solve(theta, args, rtol, atol, max_steps):
    """`optimistix.least_squares` with `LevenbergMarquardt`: `(theta, result, steps)`.
    The Jacobian comes from forward mode (`jac="fwd"`: `jax.jacfwd`, one tangent solve
    per parameter, batched; the contact model's solves in
    `ImplicitAdjoint(mode="forward")`, `_forward_model`): `p` tangent solves per LM
    step instead of one adjoint per sample. Compiled once per problem shape;
    `throw=False`: a failure is a result code."""
    return _lm_solve_unjitted(theta, args, rtol, atol, max_steps)


def _forward_model(model):
    """The contact model with its solves differentiated in forward mode (the options'
    `adjoint`, or the default one, with `mode="forward"`); other models as they are."""
    if not isinstance(model, _SceneModel):
        return model
    options = dict(model.options)
    given = options.get("adjoint") or ImplicitAdjoint()
    options["adjoint"] = dataclasses.replace(given, mode="forward")
    return _SceneModel(model.kind, tuple(sorted(options.items())))


def _lm_solve_unjitted(theta, args, rtol, atol, max_steps):
    import optimistix as optx

    ctx, refs, target, scale, model, fit_poisson = args
    args = (ctx, refs, target, scale, _forward_model(model), fit_poisson)
    sol = optx.least_squares(_residual, optx.LevenbergMarquardt(rtol=rtol, atol=atol),
                             theta, args, options={"jac": "fwd"}, max_steps=max_steps,
                             throw=False)
    return sol.value, sol.result == optx.RESULTS.successful, sol.stats["num_steps"]


@eqx.filter_jit
def _lm_solve_batch(theta, args, axes, rtol, atol, max_steps):
    """`_lm_solve` over a batch of curves: `jax.vmap` of the whole Levenberg-Marquardt
    solve (one compiled program; the loop runs until its slowest member, the others
    held at their end point). `theta`: every leaf with a leading batch axis; `args`:
    `_residual`'s arguments, the leaves whose `axes` entry is 0 batched. Inputs
    sharded along the batch axis are computed where they lie (XLA's partitioner)."""
    return eqx.filter_vmap(
        lambda th, a: _lm_solve_unjitted(th, a, rtol, atol, max_steps),
        in_axes=(0, axes))(theta, args)


class _Captured(Exception):
    """`fit_prony(_lm={"capture": ...})` stops here with the set-up done."""


def _stack(trees):
    """`(stacked, axes)`: the pytrees `trees` (one structure) as one pytree whose
    array leaves that differ between the trees carry a leading batch axis (`axes`
    leaf 0); leaves equal in every tree are kept once (`axes` leaf `None`).
    Non-array leaves must be equal."""
    leaves = [jax.tree.flatten(t) for t in trees]
    treedef = leaves[0][1]
    if any(td != treedef for _, td in leaves):
        raise ValueError("fit_prony_batch: the curves' problems differ in structure "
                         "(every curve needs the same number of samples and the same "
                         "control mode, fixed parameters and bounds)")
    out, axes = [], []
    for column in zip(*(lv for lv, _ in leaves), strict=True):
        first = column[0]
        if isinstance(first, (jax.Array, np.ndarray)):
            if all(np.shape(x) == np.shape(first) and bool(np.array_equal(
                    np.asarray(x), np.asarray(first))) for x in column[1:]):
                out.append(first)
                axes.append(None)
            else:
                out.append(jnp.stack([jnp.asarray(x) for x in column]))
                axes.append(0)
        else:
            out.append(first)
            axes.append(None)
    return jax.tree.unflatten(treedef, out), jax.tree.unflatten(treedef, axes)


def fit_prony_batch(data, scene_template: Scene, n_terms: int = 2, *, weights=None,
                    lm_steps: int = 100, client=None, chunk_size: int | None = None,
                    vectorize: bool | None = None, devices=None, refit: bool = True,
                    **options) -> list:
    """Fit a Prony series to each of many curves of one shape at once: the
    Levenberg-Marquardt solves of all curves run as ONE compiled, vmapped program,
    sharded over devices (on accelerators; on a CPU one curve after another, see
    `vectorize`).

    **Main arguments:**

    - `data`: a sequence of `jc.IndentationData`, all with the same number of
      samples (their times and values may differ), e.g. the curves of a force map.
    - `scene_template`, `n_terms`: as for `jc.fit_prony` (one template for all
      curves; the data's loading replaces its program, curve by curve).

    **Other arguments:**

    - `weights`: `None`, or a sequence with one `(nt,)` weight array per curve.
    - `lm_steps`: bound on the LM steps of every curve.
    - `**options`: any other keyword of `jc.fit_prony` (`init`: `None`,
      `"lee-radok"`, or a sequence of one `jc.Prony` per curve), except `optimiser`
      (always `"lm"`).
    - `client`: a `dask.distributed.Client` (the `dask` extra): the curves are split
      into chunks of `chunk_size`, each chunk fitted by this function on a worker (one
      batched LM per chunk), the fits returned in order. As for `jc.sweep(...,
      client=...)`: a chunk whose worker dies is resubmitted, the workers turn on
      x64 for 64-bit data and copy this process's compilation-cache settings. A
      shorter last chunk compiles its own batched program (it is not padded: a
      padded curve would be fitted for nothing): prefer a `chunk_size` that divides
      the number of curves.
    - `chunk_size`: curves per chunk (a positive integer); default: the curves spread
      evenly over the workers connected now. Only with `client`.
    - `vectorize`: `True`: one vmapped LM solve of all curves; `False`: `fit_prony(...,
      optimiser="lm")` curve by curve (one compilation for all: one shape); `None`
      (default): `True` unless JAX's default backend is the CPU. Measured on 2 CPU
      cores (64^2 x 40, 16 curves, float64): the loop 412 s (230 s with today's
      tangents), the vmapped solve not finished after 37 min: under `vmap` every LM
      step and inner contact solve runs to the slowest curve's count, and a CPU has
      no idle lanes for the batch (`benchmarks/notes/fit_real_files.md`). Given
      `devices`, `None` means `True`.
    - `devices`: the devices to shard the vmapped batch over (as `jc.sweep`: the
      curves padded to a multiple of their number by repeating the last one, each
      device fitting its slice; unlike `jc.sweep` the devices step together, one LM
      loop for the whole batch, the slowest curve setting its length); default
      `jax.devices()`. Not with `vectorize=False` or `client` (each worker shards over
      its own devices).
    - `refit`: a curve whose LM fit is not certified (`converged=False`) is fitted
      again alone by `jc.fit_prony`'s default optimiser (`"auto"`: L-BFGS first), and
      the better fit kept (a certified one, else the lower loss). Measured on a real
      force map's curve: LM stopped NOT converged after 100 steps where L-BFGS
      converged in 2.3 s (`benchmarks/notes/fit_real_files.md`, section 10).

    **Returns:** a list of `jc.PronyFit`, one per curve, each as `jc.fit_prony(...,
    optimiser="lm")` would return it: the same start (from each curve's data), the
    same LM iteration, the same sensitivities and certificate (unless refitted, see
    `refit`).

    Cost: the start and the sensitivities of each curve are computed one curve at a
    time (a few model evaluations each, with the program compiled for one curve),
    the LM solves together. Under `vmap` the batched loop runs as many steps as the
    slowest curve needs. A curve whose LM ends with a parameter at a boundary of the
    parametrisation is restarted alone, as `fit_prony` does (the unbatched LM then
    compiles as well).
    """
    data = list(data)
    if not data or not all(isinstance(d, IndentationData) for d in data):
        raise TypeError("data must be a non-empty sequence of jc.IndentationData")
    if "optimiser" in options:
        raise ValueError("fit_prony_batch always uses optimiser='lm'")
    if not _have_optimistix():
        raise ImportError('fit_prony_batch needs optimistix: pip install '
                          '"jaxcontact[fit]"')
    sizes = {d.times.shape[0] for d in data}
    if len(sizes) != 1:
        raise ValueError(f"fit_prony_batch: every curve needs the same number of "
                         f"samples, got {sorted(sizes)}")
    weights = [None] * len(data) if weights is None else list(weights)
    inits = options.pop("init", None)
    if inits is None or isinstance(inits, str):  # None or "lee-radok": every curve
        inits = [inits] * len(data)
    inits = list(inits)
    if len(weights) != len(data) or len(inits) != len(data):
        raise ValueError(f"fit_prony_batch: weights and init need one entry per curve "
                         f"({len(data)})")
    if vectorize is not None and not isinstance(vectorize, bool):
        raise TypeError(f"vectorize must be True, False or None, got {vectorize!r}")
    if devices is not None and (client is not None or vectorize is False):
        raise ValueError("fit_prony_batch: devices shard the vmapped batch; not with "
                         f"client or vectorize=False, got devices={devices!r}")
    if client is not None:
        from ._sweep_dask import check_client, fit_on_client

        check_client(client, chunk_size, "jc.fit_prony_batch")
        return fit_on_client(fit_prony_batch, data, scene_template, n_terms, weights,
                             inits, lm_steps,
                             {**options, "vectorize": vectorize, "refit": refit},
                             client, chunk_size)
    if chunk_size is not None:
        raise ValueError(f"fit_prony_batch: chunk_size={chunk_size!r} needs a client")
    if vectorize is None:
        vectorize = devices is not None or jax.default_backend() != "cpu"
    devices = list(jax.devices() if devices is None else devices)
    if not devices:
        raise ValueError("fit_prony_batch: devices is empty")

    def one(i, lm):
        return fit_prony(data[i], scene_template, n_terms, weights=weights[i],
                         init=inits[i], optimiser="lm", lm_steps=lm_steps, _lm=lm,
                         **options)

    def better(i, fit):
        """`fit`, or where it is not certified, the better of it and `fit_prony`'s
        default fit of curve `i` (see `refit`)."""
        if fit.converged or not refit:
            return fit
        alone = fit_prony(data[i], scene_template, n_terms, weights=weights[i],
                          init=inits[i], lm_steps=lm_steps, **options)
        if alone.converged or alone.loss < fit.loss:
            return alone
        return fit

    if not vectorize:
        return [better(i, one(i, None)) for i in range(len(data))]

    # -- Set-up of every curve (the start from its data) -----------------------------
    thetas, args = [], []
    for i in range(len(data)):
        lm = {"capture": None}
        try:
            one(i, lm)
        except _Captured:
            pass
        theta, a = lm["capture"]
        thetas.append(theta)
        args.append(a)
    dtype = scene_template.grid.size.dtype

    # -- One batched LM solve, padded to a multiple of the devices and sharded --------
    stacked_args, axes = _stack(args)
    theta_b = jax.tree.map(lambda *x: jnp.stack(x), *thetas)
    # `jax.shard_map` (as in `jc.sweep`) fails inside lineax's linear solves (its
    # structure check compares the manual axes' shardings: lineax issue 185), so the
    # batch axis is sharded for XLA's partitioner: the devices step together.
    padded = math.ceil(len(data) / len(devices)) * len(devices)
    mesh = Mesh(np.array(devices), (_AXIS,))
    along = NamedSharding(mesh, PartitionSpec(_AXIS))
    same = NamedSharding(mesh, PartitionSpec())

    def place(x, axis):
        if axis == 0:
            return jax.device_put(_pad(x, padded), along)
        return jax.device_put(x, same) if eqx.is_array(x) else x

    theta_b = jax.tree.map(lambda x: place(x, 0), theta_b)
    stacked_args = jax.tree.map(place, stacked_args, axes, is_leaf=lambda x: x is None)
    rtol = 1e-8 if jnp.finfo(dtype).bits >= 64 else 1e-4
    new, ok, steps = _lm_solve_batch(theta_b, stacked_args, axes, rtol, 0.1 * rtol,
                                     lm_steps)

    # -- Finish up, curve by curve ---------------------------------------------------
    fits = []
    for i in range(len(data)):
        result = (jax.tree.map(lambda x, i=i: x[i], new), ok[i], steps[i])
        fits.append(better(i, one(i, {"result": result})))
    return fits


def lee_radok_start(data: IndentationData, scene_template: Scene, n_terms: int, *,
                    poisson: float, weights=None) -> Prony:
    """A Prony series of `n_terms` arms from the closed-form Lee & Radok model of the
    data (`jc.fit_prony(init="lee-radok")`).

    The samples up to the first where the depth falls below 98 % of its running
    maximum (the loading and the hold: the contact radius does not shrink, and the
    full contact model is the closed form there, up to its grid) are fitted by
    `jaxcontact._lee_radok.lee_radok_fit` (times on a log grid of 20 over the span,
    coefficients > 0, the fit's `weights`); the apparent moduli (compliances) are
    converted with the sphere's radius `R` and `poisson`:
    `G = 3 (1 - nu) G_app / (8 sqrt(R))` (relaxation, displacement control),
    `J = 8 sqrt(R) J_app / (3 (1 - nu))` (creep, load control; then
    `jc.Prony.from_creep`).

    **Raises:** `ValueError` without a `jc.Sphere` indenter, without both force and
    depth in `data`, or where no set of times gives positive coefficients.
    """
    from ._lee_radok import lee_radok_fit

    if not isinstance(scene_template.indenter, Sphere):
        raise ValueError("init='lee-radok' needs a jc.Sphere indenter")
    if data.force is None or data.depth is None:
        raise ValueError("init='lee-radok' needs both data.force and data.depth")
    depth = np.asarray(data.depth, float)
    below = depth < 0.98 * np.maximum.accumulate(depth)
    end = int(np.argmax(below)) if below.any() else depth.size
    if end < 2 * n_terms + 3:
        raise ValueError(f"init='lee-radok': {end} loading samples are too few for "
                         f"{n_terms} arms")
    mode = "relaxation" if isinstance(scene_template.normal, Displacement) else "creep"
    w = None if weights is None else np.asarray(weights, float)[:end]
    _, taus, c = lee_radok_fit(data.times[:end], np.asarray(data.force)[:end],
                               depth[:end], mode, arms=n_terms, weights=w,
                               positive=True)
    if c is None:
        raise ValueError("init='lee-radok': no closed-form series with positive moduli "
                         "fits the data")
    radius = float(scene_template.indenter.radius)
    factor = 8 * math.sqrt(radius) / (3 * (1 - poisson))
    if mode == "relaxation":
        return Prony(c[0] / factor, c[1:] / factor, taus, poisson)
    return Prony.from_creep(c.sum() * factor, c[1:] * factor, taus, poisson)


def _have_optimistix() -> bool:
    try:
        import optimistix  # noqa: F401
    except ImportError:
        return False
    return True


class _Evaluator:
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

    def jacobian(self, theta, step):
        """`(nt, p)` Jacobian of the relative residual in the (flattened)
        log-parameters, by central differences of step `step`: `2 p` evaluations of the
        compiled objective (cheaper than `nt` adjoint rows when `nt > 2 p`)."""
        flat, unravel = ravel_pytree(theta)
        scale = self.scale
        columns = []
        for e in np.eye(flat.shape[0]):
            e = jnp.asarray(step * e, flat.dtype)
            _, _, up, _ = self.loss(unravel(flat + e))
            _, _, down, _ = self.loss(unravel(flat - e))
            columns.append((np.asarray(up, float) - np.asarray(down, float))
                           / (2 * step * scale))
        return np.stack(columns, axis=1)


# --------------------------------------------------------------------------------------
# Result.


class PronyFit(eqx.Module):
    """The result of `jc.fit_prony`.

    - `material`: the fitted `jc.Prony` (`g_inf`, `g`, `tau` sorted by `tau`).
    - `initial`: the `jc.Prony` the optimiser started from.
    - `loss`: the final loss (mean squared residual relative to `rms(target)`).
    - `loss_history`: loss at the start and after every accepted Adam and L-BFGS
      step (`(n_iter + 1,)`), or (LM) at the start and the end of every LM run.
    - `optimiser`: what ran: `"lm"`, `"lbfgs"` or `"lbfgs+lm"` (auto, LM took over);
      `adam_steps`, `lbfgs_steps`, `lm_steps`:
      iterations taken; `evaluations`: model evaluations outside the LM solve (one
      forward and one adjoint solve each; a whole LM solve counts as one).
    - `converged`: `True` when the result is certified a minimum: the Gauss-Newton
      step at the result (from the Jacobian of `std`) promises less than a 1e-3
      relative decrease of the loss, no parameter at a boundary of the
      log-parametrisation can lower it, and every contact solve converged;
      `message` says why the optimiser stopped and what the certificate found.
    - `solves_converged`: every contact step of the final model run converged.
    - `times`, `target`, `curve`: `(nt,)` data times, fitted data (force or depth)
      and the fitted model's curve; `residual = curve - target`. `kind`: `"force"` or
      `"depth"`.
    - `std`: dict `g_inf`, `g`, `tau` (and `poisson` when fitted): Gauss-Newton
      standard deviation of the natural LOG of each parameter (~ relative standard
      deviation), from `noise_std` or the residual (see the module notes).
    - `covariance`: `(p, p)` Gauss-Newton covariance of the natural logs of the
      parameters, in the order `parameter_names` (`g_inf`, `g_1..g_n`, `tau_1..tau_n`
      sorted by tau, then `poisson` when fitted); `std` is the root of its diagonal;
      `inf` in the rows of undetermined parameters.
    - `gradient`: dict with the same keys: `d(loss)/d(log param)` at the result.
    - `noise`: the noise level used for `std` [units of the data].
    - `discretisation`: with `check_grid=True`, the RMS difference between the
      fitted model's curve on the fit's grid and on a grid twice as fine (same
      width) [units of the data]: the model's own discretisation error, a bias the
      fit cannot remove; compare it with `noise`. `None` otherwise.
    """

    material: Prony
    initial: Prony
    loss: float
    loss_history: np.ndarray
    adam_steps: int
    lbfgs_steps: int
    lm_steps: int
    optimiser: str
    evaluations: int
    converged: bool
    message: str
    solves_converged: bool
    times: np.ndarray
    target: np.ndarray
    curve: np.ndarray
    residual: np.ndarray
    kind: str
    std: dict
    covariance: np.ndarray
    parameter_names: tuple
    gradient: dict
    noise: float
    discretisation: float | None = None

    def to_xarray(self, *, units=None, attrs=None):
        """This fit as a labelled `xarray.Dataset`.

        **Arguments:**

        - `units`: unit labels, `None` / `"SI"` (m, N, Pa, s) or a dict (see
          `jc.Solution.to_xarray`); nothing is converted.
        - `attrs`: extra global attributes.

        **Returns:** a Dataset with dimensions `time` (the data's times [time]),
        `arm` (the Maxwell arms, by increasing `tau`), `parameter` and `parameter_2`
        (`parameter_names`), `iteration`; variables `target`, `curve`, `residual`
        (on `time`, in force or length units by `kind`), the fitted `g_inf`, `g`,
        `tau`, `poisson` and the starting `initial_*` values, `log_std` (this class's
        `std`; renamed: `Dataset.std` is a method) and `gradient` (of the natural
        logs, dimensionless), `covariance` (`parameter` x
        `parameter_2`) and `loss_history`; attributes `kind`, `loss`, `converged`
        and `solves_converged` (0 or 1: netCDF has no boolean attribute), `message`,
        `optimiser`, the step counts, `noise`, `discretisation` (NaN when not
        computed) and `material` (JSON).
        """
        from ._dataset import fit_dataset

        return fit_dataset(self, units=units, attrs=attrs)


# --------------------------------------------------------------------------------------
# Set-up helpers.


def _scene_for(data: IndentationData, template: Scene, dtype):
    """The scene on the data's times, its loading taken from the data when given, and
    the kind of curve to fit."""
    times = jnp.asarray(data.times, dtype)
    if isinstance(template.normal, Displacement):
        kind, target, driver = "force", data.force, data.depth
        if target is None:
            raise ValueError(
                "scene_template is displacement-controlled (normal=jc.Displacement): "
                "data.force is required (the force is what is fitted)"
            )
        make = Displacement
    else:
        kind, target, driver = "depth", data.depth, data.force
        if target is None:
            raise ValueError(
                "scene_template is load-controlled (normal=jc.Force): data.depth is "
                "required (the depth is what is fitted)"
            )
        make = Force
    if driver is not None:
        normal = make(jnp.asarray(driver, dtype))
    else:
        normal = template.normal
        value = normal.value
        if not callable(value) and jnp.ndim(value) == 1 and value.shape != times.shape:
            raise ValueError(
                f"scene_template.normal holds {value.shape[0]} values but the data "
                f"have {times.shape[0]} times: give the loading as a callable of t, a "
                "scalar, or in the data (IndentationData(force=..., depth=...))"
            )
    for name in ("x", "y"):
        program = getattr(template, name)
        if program is not None and not callable(program.value) and jnp.ndim(
                program.value) == 1 and program.value.shape != times.shape:
            raise ValueError(
                f"scene_template.{name} holds {program.value.shape[0]} values but the "
                f"data have {times.shape[0]} times: give it as a callable of t or a "
                "scalar"
            )
    scene = Scene(template.grid, template.indenter, template.material, times, normal,
                  template.x, template.y, template.friction, template.coupling,
                  template.slip)
    return scene, kind, jnp.asarray(target, dtype)


def _initial_times(times: np.ndarray, n: int) -> np.ndarray:
    """`n` log-spaced times strictly inside [first step, span] of the data."""
    span = float(times[-1] - times[0])
    first = float(times[1] - times[0])
    return np.geomspace(first, span, n + 2)[1:-1]


_PREFIT_CLIP = 30.0  # |log(value / reference)| the prefit can reach


@functools.partial(jax.jit, static_argnums=0)
def _prefit_loss(kind, theta, lag, apparent, g_ref, t_ref):
    # Clipped exponents and no constructor checks: the line search may probe wild
    # points, which must come back as large losses, not errors.
    clip = _PREFIT_CLIP
    g_inf, g, tau = (c * jnp.exp(jnp.clip(theta[k], -clip, clip)) for c, k in (
        (g_ref, "g_inf"), (g_ref, "g"), (t_ref, "tau")))
    if kind == "force":  # a held indentation: G_app(t) = G(t - t_0)
        relaxation = g_inf + jnp.sum(g[None, :] * jnp.exp(-lag[:, None] / tau[None, :]),
                                     axis=1)
        return jnp.mean((relaxation / apparent - 1) ** 2)
    creep = retardation_series(g_inf, g, tau)(lag)  # held load: G_app = 1 / J
    return jnp.mean((creep * apparent - 1) ** 2)


_PREFIT_OPT = optax.lbfgs()


@functools.partial(jax.jit, static_argnums=0)
def _prefit_step(kind, theta, state, *args):
    def fn(th):
        return _prefit_loss(kind, th, *args)

    value, grad = optax.value_and_grad_from_state(fn)(theta, state=state)
    updates, state = _PREFIT_OPT.update(grad, state, theta, value=value, grad=grad,
                                        value_fn=fn)
    return optax.apply_updates(theta, updates), state, value


def _prefit(kind, lag, apparent, g_inf, arms, t_init, g_ref, t_ref, steps=200):
    """Least-squares Prony fit of `G(lag)` (or `1 / J(lag)` under load control) to
    the apparent moduli: a cheap curve fit, no contact model; optax L-BFGS with its
    zoom line search, bounded."""
    theta = {"g_inf": jnp.log(jnp.asarray(g_inf / g_ref)),
             "g": jnp.log(jnp.full(t_init.shape, arms / t_init.shape[0]) / g_ref),
             "tau": jnp.log(jnp.asarray(t_init) / t_ref)}
    args = (jnp.asarray(lag), jnp.asarray(apparent), g_ref, t_ref)
    opt = _PREFIT_OPT
    step = functools.partial(_prefit_step, kind)
    state = opt.init(theta)
    start = float(_prefit_loss(kind, theta, *args))
    for _ in range(steps):
        new, state, value = step(theta, state, *args)
        if not all(bool(jnp.all(jnp.isfinite(x))) for x in jax.tree.leaves(new)):
            break
        theta = new
    if not float(_prefit_loss(kind, theta, *args)) < start:
        return None
    # The values the loss saw: beyond the clip its gradient is zero and a line search
    # can leave a log far out (-800 on an H200: tau = 0, and the start crashed).
    theta = {k: np.clip(np.asarray(v), -_PREFIT_CLIP, _PREFIT_CLIP)
             for k, v in theta.items()}
    tau = t_ref * np.exp(theta["tau"])
    if np.any(np.diff(np.sort(tau)) <= 1e-6 * tau.max()):
        return None  # merged times: keep the plain heuristic
    return g_ref * float(np.exp(theta["g_inf"])), g_ref * np.exp(theta["g"]), tau


def _initial_guess(ev: _Evaluator, refs, fit_poisson, kind, times, target, n, t_init,
                   dtype, poisson, driver=None):
    """A starting Prony series from apparent elastic moduli along the curve.

    One (or, under load control, two) evaluations of the model with an effectively
    elastic series (arms 1e-9 of the modulus) at a trial modulus `G`: under
    displacement control the force is proportional to `G`, under load control the
    depth goes as `G^(-2/3)` (Hertz); this turns each sample into an apparent modulus
    `G_app(t_k)`. Then `g_inf = min G_app`, `sum(g) = max G_app - g_inf` spread evenly
    over the arms at `t_init`, refined by a least-squares Prony fit of `G(t - t_0)` to
    `G_app(t)` (`t_0`: the first loaded sample). For a held indentation `G_app` is
    `G(t - t_0)` itself (Lee & Radok); for other programs a blurred version: a
    heuristic, refined by the real fit. Pass `init=` to override.

    Only samples where the imposed input (`driver`: the depth under displacement
    control, the force under load control) is within 2 % of its running maximum
    enter: on unloading the apparent elastic modulus means nothing (it falls towards
    0 as the viscoelastic force drops faster than the elastic one, and a start with
    `g_inf ~ 0` is a trap of the log-parametrisation: on a ramp-hold-unload curve it
    led to `g_inf = 2e-10 Pa`).
    """
    loading = np.ones(np.shape(target), bool)
    if driver is not None:
        d = np.asarray(driver, float)
        loading = d >= 0.98 * np.maximum.accumulate(d)
    g_trial = float(refs["g_ref"])
    tgt = np.asarray(target)
    apparent, use = None, None
    for _ in range(1 if kind == "force" else 2):
        trial = Prony(g_trial, np.full(n, 1e-9 * g_trial), t_init, poisson)
        _, _, curve, _ = ev.loss(_to_theta(trial, refs, fit_poisson, dtype))
        curve = np.asarray(curve, dtype=float)
        if kind == "force":
            ok = (np.abs(curve) > 0.05 * np.max(np.abs(curve))) & (tgt > 0) & loading
            ratio = tgt[ok] / curve[ok]
        else:
            ok = (tgt > 0.05 * np.max(tgt)) & (curve > 0) & loading
            ratio = (curve[ok] / tgt[ok]) ** 1.5
        if not ok.any() or not np.all(np.isfinite(ratio)):
            break
        apparent, use = g_trial * ratio, ok
        g_trial = float(np.median(apparent))
    if apparent is None:
        return Prony(g_trial, np.full(n, 0.1 * g_trial / n), t_init, poisson)
    g0, g_inf = float(np.max(apparent)), float(np.min(apparent))
    arms = max(g0 - g_inf, 0.05 * g0)
    refined = None
    if apparent.shape[0] > 1 + 2 * n:
        lag = times[use] - times[np.argmax(use)]
        refined = _prefit(kind, lag, apparent, g_inf, arms, t_init, g0,
                          float(times[-1] - times[0]))
    if refined is None:
        return Prony(g_inf, np.full(n, arms / n), t_init, poisson)
    return Prony(*refined, poisson)


_GN_TOL = 1e-3  # largest relative loss decrease a Gauss-Newton step may promise
_MAX_RESTARTS = 3  # restarts from boundary probes


def _predicted_decrease(jac, r):
    """Relative loss decrease `(|r|^2 - |r + J d|^2) / |r|^2` of the Gauss-Newton
    step `d` (least squares, cut-off 1e-10); `inf` where `J` is not finite."""
    if not np.all(np.isfinite(jac)) or not np.all(np.isfinite(r)):
        return float("inf")
    rr = float(np.sum(r**2))
    if rr == 0:
        return 0.0
    d = np.linalg.lstsq(jac, -r, rcond=1e-10)[0]
    return max(rr - float(np.sum((r + jac @ d) ** 2)), 0.0) / rr


def _boundary_probe(ev, theta, refs, fit_poisson, times):
    """`theta` with the parameters that sit at a boundary of the log-parametrisation
    moved back inside, if that lowers the loss by more than 0.1 %; else `None`.
    Boundaries: a modulus below 1e-4 of the instantaneous modulus `g_inf + sum g`;
    a relaxation time below 1e-2 of the first time step or above 1e2 of the span.
    Each is tried alone, and a dead arm (modulus ~ 0 or time out of range) also
    revived whole; a parameter with bounds pressed against one is tried at the middle
    of its range (one evaluation each); the best is returned."""
    value = float(ev.loss(theta)[0])
    material = _to_material(theta, refs, fit_poisson)
    free, theta = theta, {**refs.get("fixed", {}), **theta}  # trials on all, kept: free
    g_inf, g, tau = (np.asarray(x, float) for x in (material.g_inf, material.g,
                                                    material.tau))
    span, first = float(times[-1] - times[0]), float(np.min(np.diff(times)))
    # g0 of the arms the data can see: a dead arm (tau far outside the data's times)
    # may carry any modulus (2.8e18 Pa at tau = 3e-18 s on the creep file, 1 arm)
    live = (tau >= 1e-2 * first) & (tau <= 1e2 * span)
    g0 = float(g_inf + g[live].sum()) if float(g_inf + g[live].sum()) > 0 else float(
        g_inf + g.sum())
    g_ref, t_ref = float(refs["g_ref"]), float(refs["t_ref"])
    trials = []
    mid = math.log(math.sqrt(first * span) / t_ref)
    for i in range(g.shape[0]):
        if (tau[i] < 1e-2 * first or tau[i] > 1e2 * span) and "tau" not in refs.get(
                "bounds", {}):
            trials.append({**theta, "tau": theta["tau"].at[i].set(mid)})
    bounded = set(refs.get("bounds", {}))

    def from_x(key, x):  # a scaled log -> the optimiser's coordinate of `key`
        if key in bounded:  # logit, kept 5 % inside the bounds
            lo, hi = refs["bounds"][key]
            f = jnp.clip((x - lo) / (hi - lo), 0.05, 0.95)
            return jnp.log(f / (1 - f))
        return x

    def shifted(key, delta):
        return from_x(key, _log_scaled(theta, refs, key) + delta)

    def set_at(key, i, x):
        return from_x(key, _log_scaled(theta, refs, key).at[i].set(x))

    for frac in (1e-2, 1e-1, 0.5):
        # the modulus to `frac` of g0, the others scaled to keep g0 (the instantaneous
        # modulus, which the data fix best: the trap sits in a valley along it); 0.5
        # for a dead arm that must carry a real share to beat what it mimics (a dead
        # arm with a huge modulus makes J(0) ~ 0: a one-step lag)
        inside = math.log(frac * g0 / g_ref)
        shrink = math.log(1 - frac)
        if g_inf < 1e-4 * g0:
            trials.append({**theta, "g_inf": from_x("g_inf", jnp.full_like(
                theta["g_inf"], inside)), "g": shifted("g", shrink)})
        for i in range(g.shape[0]):
            tau_out = tau[i] < 1e-2 * first or tau[i] > 1e2 * span
            if g[i] < 1e-4 * g0 or tau_out:
                # a dead arm (no modulus, or a time the data cannot see): revived
                # whole, its time at the middle of the data's time scales
                g_new = from_x("g", (_log_scaled(theta, refs, "g") + shrink).at[i].set(
                    inside))
                trials.append({**theta, "g_inf": shifted("g_inf", shrink), "g": g_new,
                               "tau": set_at("tau", i, mid)})
            if g[i] < 1e-4 * g0 and not tau_out:
                g_new = from_x("g", (_log_scaled(theta, refs, "g") + shrink).at[i].set(
                    inside))
                trials.append({**theta, "g_inf": shifted("g_inf", shrink), "g": g_new})
    best, best_value = None, value * (1 - 1e-3)
    # a bounded parameter pressed against a bound (within 1 % of the range: the
    # sigmoid is flat there, the same trap) is tried at the middle of its range
    for key in bounded & set(free):
        frac = np.asarray(jax.nn.sigmoid(theta[key]), float).reshape(-1)
        for i in np.flatnonzero((frac < 0.01) | (frac > 0.99)):
            moved = theta[key].reshape(-1).at[i].set(0.0).reshape(theta[key].shape)
            trials.append({**theta, key: moved})
    trials = [{k: t[k] for k in free} for t in trials]
    trials = [t for t in trials if any(
        not bool(jnp.array_equal(t[k], free[k])) for k in free)]
    for trial in trials:
        v = float(ev.loss(trial)[0])
        if np.isfinite(v) and v < best_value:
            best, best_value = trial, v
    return best


def _at_boundary(material, times, refs):
    """Names of the parameters at a boundary of the log-parametrisation (see
    `_boundary_probe`): a modulus below 1e-4 of the live arms' g0, an (unbounded)
    relaxation time below 1e-2 of the first step or above 1e2 of the span."""
    g_inf, g, tau = (np.asarray(x, float) for x in (material.g_inf, material.g,
                                                    material.tau))
    span, first = float(times[-1] - times[0]), float(np.min(np.diff(times)))
    live = (tau >= 1e-2 * first) & (tau <= 1e2 * span)
    g0 = float(g_inf + g[live].sum()) or float(g_inf + g.sum())
    out = ["g_inf"] if g_inf < 1e-4 * g0 else []
    for i in range(g.shape[0]):
        if g[i] < 1e-4 * g0:
            out.append(f"g_{i + 1} (tau {tau[i]:.3g})")
        if not live[i] and "tau" not in refs.get("bounds", {}):
            out.append(f"tau_{i + 1} = {tau[i]:.3g}")
    return out


def _discretisation(scene, material, model, curve):
    """RMS difference [data units] between `curve` (the model on `scene`'s grid) and
    the same model on a grid of twice the cells per side, same size."""
    g = scene.grid
    fine = eqx.tree_at(lambda sc: sc.grid, scene, type(g)(
        shape=tuple(2 * k for k in g.shape), size=g.size, periodic=g.periodic))
    fine_curve, _ = model(material,
                          (fine, _operator_for(fine, _traced_directions(fine))))
    return float(np.sqrt(np.mean((np.asarray(curve) - np.asarray(fine_curve)) ** 2)))


def discretisation_error(fit: "PronyFit", data: IndentationData, scene_template: Scene,
                         solve_options: dict | None = None) -> float:
    """`PronyFit.discretisation` after the fact: the RMS difference [data units]
    between `fit.curve` and the fitted model on a grid of twice the cells (same
    width) for the same data and template (`solve_options` as given to the fit;
    the fit's default scheme `"linear"` unless it says otherwise)."""
    dtype = scene_template.grid.size.dtype
    scene, kind, _ = _scene_for(data, scene_template, dtype)
    options = {"scheme": "linear", **dict(solve_options or {})}
    model = _SceneModel(kind, tuple(sorted(options.items())))
    return _discretisation(scene, fit.material, model, fit.curve)


def _check_int(name, value, minimum):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an integer, got {value!r}")
    if value < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {value!r}")
    return int(value)


def _split(theta: dict, values: np.ndarray) -> dict:
    """Per-parameter pieces of a flat vector laid out like `ravel_pytree(theta)`."""
    _, unravel = ravel_pytree(theta)
    return {k: np.asarray(v) for k, v in unravel(jnp.asarray(values)).items()}


# --------------------------------------------------------------------------------------
# The entry point.


def fit_prony(
    data: IndentationData,
    scene_template: Scene,
    n_terms: int,
    *,
    init: Prony | None = None,
    poisson=None,
    fit_poisson: bool = False,
    adam_steps: int = 10,
    learning_rate: float | None = None,
    lbfgs_steps: int = 100,
    gtol: float | None = None,
    noise_std: float | None = None,
    precondition: bool = True,
    solve_options: dict | None = None,
    optimiser: str | None = None,
    lm_steps: int = 100,
    check_grid: bool = False,
    fixed: dict | None = None,
    weights=None,
    bounds: dict | None = None,
    _model: Callable | None = None,
    _lm: dict | None = None,
) -> PronyFit:
    """Fit a Prony series `G(t) = g_inf + sum_i g_i exp(-t / tau_i)` to indentation
    data, through the full contact model.

    **Main arguments:**

    - `data`: a `jc.IndentationData` (times, and force and/or depth).
    - `scene_template`: a `jc.Scene` giving the grid, the indenter, the control mode
      and (unless the data give it) the loading program; its `times` are replaced by
      `data.times` and its material by the fitted one.
        - displacement control (`normal=jc.Displacement(...)`): the FORCE is fitted
          (`data.force` required); the approach is `data.depth` if given, else the
          template's program evaluated at `data.times` (a callable or a scalar).
        - load control (`normal=jc.Force(...)`): the DEPTH (approach) is fitted
          (`data.depth` required); the load is `data.force` if given, else the
          template's program. Giving both force and depth fits a load-depth loop.
      Tangential inputs, friction and coupling of the template are kept.
    - `n_terms`: number of Maxwell arms `n >= 1`.

    **Other arguments:**

    - `init`: the starting `jc.Prony` (`n_terms` arms). Default: from the data
      (apparent elastic moduli, then a cheap Prony fit to them, starting from
      relaxation times log-spaced strictly inside [first time step, time span]; see
      `_initial_guess`). `"lee-radok"`: the best closed-form Lee & Radok model of the
      data's loading and hold (`lee_radok_start`: a sphere, both `data.force` and
      `data.depth`; the model the contact solve reproduces while the contact grows or
      holds, so the start is at the full model's optimum up to the grid's bias and
      the unloading). On the creep file at 32^2 with 2 arms, LM from it converged in
      43 steps where from the default start it stopped at its 100-step bound.
    - `poisson`: Poisson's ratio (fixed unless `fit_poisson`); default: that of the
      template's material. Under normal indentation alone only `G / (1 - nu)` is
      identifiable: fitting it needs tangential data (`fit_poisson=True`
      parametrises it in (0, 0.5)).
    - `adam_steps`, `learning_rate`: the Adam phase (the best point is kept). The
      step size is in the optimiser's coordinates: default `0.1 sqrt(2 loss_0)` when
      preconditioned (a tenth of the distance to the optimum), `0.02` in
      log-parameters otherwise.
    - `lbfgs_steps`: bound on the L-BFGS iterations. Stops early when the largest
      `|d loss / d log param|` falls below `gtol` (default `1e-12` in float64, `1e-6`
      in float32), when a step changes no log-parameter by more than 1e-12, or when
      the line search can no longer decrease the loss (the model's own solver
      tolerance is reached).
    - `precondition`: run the optimisers in coordinates whitened by the Gauss-Newton
      Hessian at the start (`2 p` extra evaluations; usually saves many more).
    - `fixed`: parameters held at given values, not fitted: a dict with any of
      `"g_inf"` (a number > 0 [Pa]), `"g"` and `"tau"` (`n_terms` values > 0, [Pa]
      and [s]); e.g. `fixed={"tau": [0.1, 10.0]}` fits the moduli of given times.
      Their `std` is 0. (A modulus cannot be fixed at 0: the series is positive by
      construction; fit fewer arms instead.) Poisson's ratio is fixed unless
      `fit_poisson`.
    - `bounds`: `{"g_inf" | "g" | "tau": (lo, hi)}`, `0 < lo < hi < inf` [Pa or s]:
      the parameter (every arm for `g`, `tau`) is kept in `[lo, hi]` by the
      parametrisation `log v = log lo + (log hi - log lo) sigmoid(theta)`. E.g.
      `bounds={"tau": (dt, 10 * span)}` keeps relaxation times where the data can see
      them (a time far beyond the data is degenerate with `g_inf`). A parameter at a
      bound is a constrained minimum (`converged` can be `True` there); its `std` is
      that of the linearised, unconstrained problem.
    - `weights`: `(nt,)` positive weights of the samples (e.g. `sqrt(count)` for bin
      means of `count` raw samples: the inverse of each sample's noise); normalised to
      a mean square of 1. Default: equal. The loss is then
      `mean((w (curve - target) / rms(target))^2)`, `noise` (and `noise_std`) is the
      noise of a sample of weight 1.
    - `check_grid`: also solve the fitted model on a grid twice as fine (one more
      compilation and a solve 4x as large) and report the difference
      (`PronyFit.discretisation`).
    - `noise_std`: the data's noise standard deviation [data units] for `std`;
      default: estimated from the residual.
    - `optimiser`: `"auto"` (default), `"lm"` or `"lbfgs"`.
        - `"lbfgs"`: Adam, then L-BFGS with Armijo backtracking, driven from Python
          (the arguments `adam_steps` ... `precondition` are for it).
        - `"lm"`: Levenberg-Marquardt (`optimistix.LevenbergMarquardt` on the
          relative residual, Jacobian by forward mode, one compiled solve; at most
          `lm_steps` steps). Needs optimistix (`pip install "jaxcontact[fit]"`).
        - `"auto"`: L-BFGS, then LM from its result when that is not certified a
          minimum (see `PronyFit.converged`) and optimistix is installed.
      Measured (float64, quiet 2-core CPU): from the default start on the PMMA step,
      64^2 x 40, L-BFGS 6.8 s compiled (13.7 s with compilation), LM 7.1 s (18.7 s),
      13 steps: its Jacobian costs one tangent solve per parameter per step (33.1 s
      with one adjoint per sample, `benchmarks/README.md`). From far
      starts (1 arm, 1 % noise, the closed-form stand-in, 24 starts 0.2-5x off) LM
      reaches the minimum from every start; preconditioned L-BFGS stalls on creep
      data from 2 of 12 (one at its iteration bound, reported NOT converged), where
      `"auto"` hands over to LM.
    - `solve_options`: keywords for `jc.solve` (`rtol`, `scheme`, ...). The
      default scheme here is `"linear"` (samples joined by ramps; stable at any step);
      `"constant"` treats every sample as a step, and a fit that ends with a material
      for which the data's steps are unstable under it warns (`jc.TimeStepWarning`).

    **Returns:** a `jc.PronyFit` (fitted material, loss history, sensitivities).

    **Raises:** `ValueError` for data that cannot be fitted (missing force/depth for
    the control mode, fewer samples than parameters, a target that is zero throughout,
    times that do not match the template's loading arrays), `TypeError` for wrong
    argument types.

    Cost: every iteration is one forward solve and one adjoint (implicit) solve of
    the whole time history; the start takes one or two, the sensitivities `2 p`.
    """
    # -- Initial set-up ----------------------------------------------------------------
    if not isinstance(data, IndentationData):
        raise TypeError(f"data must be a jc.IndentationData, got {data!r}")
    if not isinstance(scene_template, Scene):
        raise TypeError(f"scene_template must be a jc.Scene, got {scene_template!r}")
    n = _check_int("n_terms", n_terms, 1)
    adam_steps = _check_int("adam_steps", adam_steps, 0)
    lbfgs_steps = _check_int("lbfgs_steps", lbfgs_steps, 0)
    lm_steps = _check_int("lm_steps", lm_steps, 1)
    if optimiser is None:
        optimiser = "auto"
    if optimiser not in ("auto", "lm", "lbfgs"):
        raise ValueError(
            f"optimiser must be 'auto', 'lm' or 'lbfgs', got {optimiser!r}")
    if optimiser == "lm" and not _have_optimistix():
        raise ImportError(
            'optimiser="lm" needs optimistix: pip install "jaxcontact[fit]"')
    if learning_rate is not None and not (
            isinstance(learning_rate, (int, float)) and 0 < learning_rate < 10):
        raise ValueError(
            f"learning_rate must be a number in (0, 10), got {learning_rate!r}")
    if noise_std is not None and not (np.isfinite(noise_std) and noise_std > 0):
        raise ValueError(f"noise_std must be finite and > 0, got {noise_std!r}")
    if isinstance(init, str):
        if init != "lee-radok":
            raise ValueError(f"init must be a jc.Prony, None or 'lee-radok', got "
                             f"{init!r}")
        nu = float(scene_template.material.poisson) if poisson is None else poisson
        init = lee_radok_start(data, scene_template, n, poisson=nu, weights=weights)
    if init is not None and (not isinstance(init, Prony) or init.g.shape != (n,)):
        raise ValueError(f"init must be a jc.Prony with n_terms={n} arms, got {init!r}")
    dtype = scene_template.grid.size.dtype
    if gtol is None:
        gtol = 1e-12 if jnp.finfo(dtype).bits >= 64 else 1e-6
    fixed_values = {}
    for key, value in dict(fixed or {}).items():
        if key not in ("g_inf", "g", "tau"):
            raise ValueError(f"fixed: unknown parameter {key!r} (g_inf, g, tau; "
                             "Poisson's ratio is fixed by default)")
        shape = () if key == "g_inf" else (n,)
        arr = np.asarray(value, float)
        if arr.shape != shape or not np.all(np.isfinite(arr)) or not np.all(arr > 0):
            raise ValueError(f"fixed[{key!r}] must be "
                             f"{'a number' if not shape else f'{n} numbers'}"
                             f" > 0, got {value!r}")
        fixed_values[key] = arr
    bound_values = {}
    for key, value in dict(bounds or {}).items():
        if key not in ("g_inf", "g", "tau"):
            raise ValueError(f"bounds: unknown parameter {key!r} (g_inf, g, tau)")
        if key in fixed_values:
            raise ValueError(f"bounds[{key!r}]: the parameter is fixed")
        try:
            lo, hi = (float(v) for v in value)
        except (TypeError, ValueError):
            raise ValueError(f"bounds[{key!r}] must be a pair (lo, hi), got {value!r}")
        if not (0 < lo < hi < math.inf):
            raise ValueError(f"bounds[{key!r}] must satisfy 0 < lo < hi < inf, got "
                             f"{value!r}")
        bound_values[key] = (lo, hi)
    n_params = 1 + 2 * n + int(bool(fit_poisson)) - sum(
        int(np.size(v)) for v in fixed_values.values())
    if data.times.shape[0] <= n_params:
        raise ValueError(
            f"{n_params} parameters need more than {n_params} samples, got "
            f"{data.times.shape[0]} (use more samples or fewer terms)"
        )
    scene, kind, target = _scene_for(data, scene_template, dtype)
    rms_target = jnp.sqrt(jnp.mean(target**2))
    if weights is not None:
        w = _series("weights", weights).astype(float)
        if w.shape != target.shape or not np.all(w > 0):
            raise ValueError(f"weights must be {target.shape[0]} numbers > 0 (one per "
                             f"time), got shape {w.shape}, min {w.min()!r}")
        w = w / np.sqrt(np.mean(w**2))  # mean w^2 = 1: the loss keeps its scale
    else:
        w = np.ones(target.shape)
    # Residual k is (curve - target)_k w_k / rms(target): `scale` holds rms / w.
    scale = rms_target / jnp.asarray(w, dtype)
    if not float(rms_target) > 0:
        raise ValueError(f"data.{kind} is zero at every time: nothing to fit")
    if poisson is None:
        poisson = float(scene_template.material.poisson)
    if fit_poisson and not 0 < poisson < 0.5:
        raise ValueError(f"poisson must be in (0, 0.5) to be fitted, got {poisson!r}")
    if not -1 < poisson <= 0.5:
        raise ValueError(f"poisson must be in (-1, 0.5], got {poisson!r}")

    if _model is None:
        # scheme "linear" by default: measured data are sampled ramps, which the
        # piecewise-constant scheme turns into staircases (a 1-arm ramp fit at 0.25 s
        # steps: the model 6 % off on loading, g_1 -17 %); it is also stable at any
        # step, whatever material the optimiser tries.
        options = {"scheme": "linear", **dict(solve_options or {})}
        if "operator" in options:
            raise ValueError("fit_prony builds the operator itself: leave 'operator' "
                             "out of solve_options")
        model = _SceneModel(kind, tuple(sorted(options.items())))
        ctx = (scene, _operator_for(scene, _traced_directions(scene)))
    else:  # a stand-in model (tests): `_model = (callable, ctx)`
        model, ctx = _model
    g_ref = float(init.relaxation(0.0)) if init is not None else float(
        scene_template.material.relaxation(0.0))
    refs = {
        "g_ref": jnp.asarray(g_ref, dtype),
        "t_ref": jnp.asarray(float(data.times[-1] - data.times[0]), dtype),
        "poisson": jnp.asarray(poisson, dtype),
    }
    if fixed_values:
        scales = {"g_inf": refs["g_ref"], "g": refs["g_ref"], "tau": refs["t_ref"]}
        refs["fixed"] = {k: jnp.log(jnp.asarray(v, dtype) / scales[k])
                         for k, v in fixed_values.items()}
    if bound_values:
        scales = {"g_inf": refs["g_ref"], "g": refs["g_ref"], "tau": refs["t_ref"]}
        refs["bounds"] = {k: (jnp.log(jnp.asarray(lo, dtype) / scales[k]),
                              jnp.log(jnp.asarray(hi, dtype) / scales[k]))
                          for k, (lo, hi) in bound_values.items()}
    ev = _Evaluator(ctx, refs, target, scale, model, bool(fit_poisson), dtype)
    if init is None:
        init = _initial_guess(ev, refs, fit_poisson, kind, data.times, target, n,
                              _initial_times(data.times, n), dtype, poisson,
                              data.depth if kind == "force" else data.force)
    theta = _to_theta(init, refs, fit_poisson, dtype)
    theta = {k: v for k, v in theta.items() if k not in fixed_values}
    theta_start = theta

    fd_step = 1e-3 if jnp.finfo(dtype).bits >= 64 else 3e-2
    history = []

    def optimise(theta, adam_steps):
        """Adam, then L-BFGS, from `theta`: `(theta, converged, message, adam steps,
        L-BFGS steps)`; appends the losses to `history`."""
        # -- Preconditioning -----------------------------------------------------------
        # The optimisers run on z with theta = theta_0 + M z, M = H^(-1/2) for the
        # Gauss-Newton Hessian H = (2 / nt) J^T J of the loss at the start (J by central
        # differences, 2 p evaluations). The loss is then about isotropic in z: L-BFGS
        # does not crawl along the g-tau valleys of a Prony fit (at 32^2 x 24, noiseless
        # PMMA: 43 L-BFGS steps without, a handful with).
        # Far from the optimum H changes: when L-BFGS has cut the loss 100-fold since M
        # was built, M is rebuilt there and L-BFGS restarts (at most 4 times).
        flat0, unravel = ravel_pytree(theta)

        def whitening(theta):
            if precondition:
                jac = ev.jacobian(theta, fd_step)
                if np.all(np.isfinite(jac)):
                    lam, vec = np.linalg.eigh(2 / jac.shape[0] * jac.T @ jac)
                    lam = np.maximum(lam, max(1e-10 * float(lam.max()), 1e-300))
                    return jnp.asarray((vec / np.sqrt(lam)) @ vec.T, flat0.dtype)
            return jnp.eye(flat0.shape[0], dtype=flat0.dtype)

        precond = whitening(theta)

        def to_theta(z):
            return unravel(flat0 + precond @ z)

        def z_grad(grad):
            return precond @ ravel_pytree(grad)[0]  # M is symmetric

        # -- Adam ----------------------------------------------------------------------
        z = jnp.zeros_like(flat0)
        value, grad, _, _ = ev.loss(theta)
        if not np.isfinite(float(value)):
            raise ValueError(
                f"the model gives a non-finite loss at the initial guess {init!r}")
        value = float(value)
        history.append(value)
        if learning_rate is None:
            # Whitened: loss ~ loss_min + |z - z*|^2 / 2, so the optimum is within
            # sqrt(2 loss_0) of the start; Adam moves each z by ~lr per step.
            lr = 0.1 * math.sqrt(2 * value) if precondition else 0.02
        else:
            lr = learning_rate
        adam = optax.adam(lr)
        adam_update = jax.jit(adam.update)
        state = adam.init(z)
        best = (value, z, grad)
        steps_adam = 0
        for _ in range(adam_steps):
            updates, state = adam_update(z_grad(grad), state, z)
            trial = z + updates
            value_t, grad_t, _, _ = ev.loss(to_theta(trial))
            if not np.isfinite(float(value_t)):
                break  # keep the best finite point; L-BFGS takes over from there
            z, value, grad = trial, float(value_t), grad_t
            steps_adam += 1
            history.append(value)
            if value < best[0]:
                best = (value, z, grad)
        value, z, grad = best

        # -- L-BFGS with Armijo backtracking -------------------------------------------
        lbfgs = optax.scale_by_lbfgs(memory_size=20)
        lbfgs_update = jax.jit(lbfgs.update)
        state = lbfgs.init(z)
        g_theta = ravel_pytree(grad)[0]
        converged, message = (
            False, f"stopped at the iteration bound lbfgs_steps={lbfgs_steps}")
        steps_lbfgs, refreshes, value_at_precond = 0, 0, value
        for _ in range(lbfgs_steps):
            if precondition and refreshes < 4 and value < 1e-2 * value_at_precond:
                flat0 = flat0 + precond @ z
                precond = whitening(unravel(flat0))
                z, state = jnp.zeros_like(z), lbfgs.init(z)
                refreshes, value_at_precond = refreshes + 1, value
            if float(jnp.max(jnp.abs(g_theta))) <= gtol:
                converged, message = True, f"gradient below gtol={gtol:g}"
                break
            g_z = precond @ g_theta
            direction, state = lbfgs_update(g_z, state, z)
            slope = float(jnp.vdot(g_z, direction))
            if not slope > 0:  # not a descent direction: restart from steepest descent
                state = lbfgs.init(z)
                direction, slope = g_z, float(jnp.vdot(g_z, g_z))
            # At most a factor e^MAX_STEP per parameter per iteration: a first L-BFGS
            # step can be long, and exp() would overflow.
            longest = float(jnp.max(jnp.abs(precond @ direction)))
            alpha, accepted = min(1.0, _MAX_STEP / max(longest, 1e-300)), False
            for _ in range(30):  # bounded backtracking
                trial = z - alpha * direction
                value_t, grad_t, _, _ = ev.loss(to_theta(trial))
                if (np.isfinite(float(value_t))
                        and float(value_t) <= value - 1e-4 * alpha * slope):
                    accepted = True
                    break
                alpha *= 0.5
            if not accepted:
                message = "the line search cannot decrease the loss further"
                break
            step_size = alpha * longest
            z, value, g_theta = trial, float(value_t), ravel_pytree(grad_t)[0]
            steps_lbfgs += 1
            history.append(value)
            if step_size < 1e-12:
                converged, message = True, "step below 1e-12 (log-parameters)"
                break
        else:
            if lbfgs_steps and float(jnp.max(jnp.abs(g_theta))) <= gtol:
                converged, message = True, f"gradient below gtol={gtol:g}"
        theta = to_theta(z)
        return theta, converged, message, steps_adam, steps_lbfgs

    lm_total = 0

    def optimise_lm(theta):
        """Levenberg-Marquardt from `theta` (see `_lm_solve`)."""
        nonlocal lm_total
        if not np.isfinite(float(ev.loss(theta)[0])):
            raise ValueError(f"the model gives a non-finite loss at the start {init!r}")
        rtol = 1e-8 if jnp.finfo(dtype).bits >= 64 else 1e-4
        try:
            if _lm is not None and "result" in _lm and not _lm.get("used"):
                # `fit_prony_batch`: this curve's LM ran in the batched program
                _lm["used"] = True
                new, ok, steps = _lm["result"]
            else:
                new, ok, steps = _lm_solve(theta, ev.args, rtol, 0.1 * rtol, lm_steps)
        except eqx.EquinoxRuntimeError as exc:  # a trial made an invalid material
            first_line = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
            return theta, False, ("Levenberg-Marquardt stopped: a trial step made an "
                                  f"invalid material ({first_line})"), 0, 0
        ev.calls += 1
        lm_total += int(steps)
        value = float(ev.loss(new)[0])
        if not np.isfinite(value):  # keep the start rather than a broken end point
            return theta, False, "Levenberg-Marquardt ended at a non-finite loss", 0, 0
        history.append(value)
        message = (f"Levenberg-Marquardt: {'converged' if bool(ok) else 'stopped'} "
                   f"after {int(steps)} steps")
        return new, bool(ok), message, 0, 0

    # -- Boundary probes ---------------------------------------------------------------
    # Positivity by exp() has a trap: a modulus driven towards 0 (or a relaxation time
    # far outside the data's times) has a vanishing gradient in its log and never
    # comes back, and the optimiser stops there. (Ramp-hold-unload, 1 % noise, 16^2: the
    # default start went to g_inf = 2e-10 Pa, loss 0.098 against 3e-4 at the truth.)
    # So every parameter sitting at such a boundary is moved back inside (a modulus to
    # 1 % or 10 % of the instantaneous one, the others scaled to keep it; a time to the
    # middle of the data's time scales), and if that lowers the loss the optimiser
    # restarts there (at most `_MAX_RESTARTS` times).
    def with_probes(run, theta, adam_steps):
        theta, _, message, n_adam, n_lbfgs = run(theta, adam_steps)
        restarts = 0
        while True:
            probe = _boundary_probe(ev, theta, refs, fit_poisson, data.times)
            if probe is None or restarts >= _MAX_RESTARTS:
                break
            theta, _, message, a_more, l_more = run(probe, 0)
            n_adam, n_lbfgs, restarts = n_adam + a_more, n_lbfgs + l_more, restarts + 1
        if restarts:
            message += (f" (after {restarts} restart(s) from a parameter at its "
                        "boundary)")
        if probe is not None:
            message += ("; a parameter at a boundary of the parametrisation (a "
                        "modulus ~ 0 or a time far outside the data's) can still lower "
                        "the loss")
        return theta, message, probe, n_adam, n_lbfgs

    def run_lm(theta, adam_steps):
        del adam_steps
        return optimise_lm(theta)

    used = optimiser
    if _lm is not None and "capture" in _lm:  # `fit_prony_batch`: set-up only
        _lm["capture"] = (theta, ev.args)
        raise _Captured
    if optimiser == "lm":
        history.append(float(ev.loss(theta)[0]))
        theta, message, probe, steps_adam, steps_lbfgs = with_probes(run_lm, theta, 0)
    else:
        theta, message, probe, steps_adam, steps_lbfgs = with_probes(
            optimise, theta, adam_steps)
        used = "lbfgs"
        if optimiser == "auto" and _have_optimistix():
            # L-BFGS is fast from a good start (64^2 x 40, PMMA step, float64: 6.8 s
            # against 7.1 s for LM, whose Jacobian costs one tangent solve per
            # parameter per step); LM reaches the minimum from starts where L-BFGS
            # stalls.
            # So LM takes over where L-BFGS' result is not certified (see below).
            _, _, c_auto, _ = ev.loss(theta)
            r_auto = ((np.asarray(c_auto) - np.asarray(target))
                      / np.asarray(scale, float))
            pred = _predicted_decrease(ev.jacobian(theta, fd_step), r_auto)
            value_auto = float(np.mean(r_auto**2))
            floor = 1e-18 if jnp.finfo(dtype).bits >= 64 else 1e-10
            stuck_auto = _at_boundary(_to_material(theta, refs, fit_poisson),
                                      data.times, refs)
            if (probe is not None or stuck_auto
                    or not (pred < _GN_TOL or pred * value_auto < floor)):
                # LM from L-BFGS' end AND from the start (L-BFGS may have walked into a
                # dead arm, where no gradient leads out: the creep file at 16^2, 1 arm,
                # sent tau_1 to 3e-18 s, while LM from the start converges); the lower
                # loss
                start_lm = with_probes(run_lm, theta_start, 0)
                end_lm = with_probes(run_lm, theta, 0)
                best_lm = min((start_lm, end_lm), key=lambda r: float(ev.loss(r[0])[0]))
                theta, message_lm, probe, _, _ = best_lm
                why = (f"at a boundary ({', '.join(stuck_auto)})" if stuck_auto else
                       f"Gauss-Newton predicts {pred:.2g}")
                message = (f"L-BFGS: {message}; not certified ({why}), then, from "
                           f"{'the start' if best_lm is start_lm else 'its end'}, "
                           f"{message_lm}")
                used = "lbfgs+lm"

    # -- Finish up: curve, sensitivities -----------------------------------------------
    value, grad, curve, ok = ev.loss(theta)
    nt = target.shape[0]
    rows = ev.jacobian(theta, fd_step)
    residual = np.asarray(curve) - np.asarray(target)
    scale_f = float(rms_target)
    rel = residual / np.asarray(scale, float)  # weighted, relative
    if noise_std is None:
        sigma_rel = math.sqrt(float(np.sum(rel**2)) / (nt - n_params))
    else:
        sigma_rel = float(noise_std) / scale_f
    # The Jacobian in the logs of the parameters (bounded ones are optimised in a
    # logit coordinate): std and covariance are those of the log-parameters.
    factor = np.asarray(ravel_pytree(_bound_factors(theta, refs))[0], float)
    # a bounded parameter with its sigmoid saturated (factor 0) is undetermined
    factor = np.where(factor > 0, factor, np.inf)
    rows_log = rows / factor[None, :]
    if np.all(np.isfinite(rows_log)):
        eigval, eigvec = np.linalg.eigh(rows_log.T @ rows_log)
        keep = eigval > 1e-14 * max(float(eigval.max()), 1e-300)
        inv = np.where(keep, 1 / np.where(keep, eigval, 1), 0.0)
        var = np.sum(eigvec**2 * inv[None, :], axis=1)
        # a parameter with a component along an undetermined direction: inf
        var = np.where(np.any((eigvec**2 > 0) & ~keep[None, :], axis=1), np.inf, var)
        std = np.where(np.isinf(var), np.inf, np.sqrt(var) * sigma_rel)
        cov = sigma_rel**2 * (eigvec * inv[None, :]) @ eigvec.T
        cov = np.where(np.isinf(var)[:, None] | np.isinf(var)[None, :], np.inf, cov)
    else:
        std = np.full(rows.shape[1], np.nan)
        cov = np.full((rows.shape[1],) * 2, np.nan)
        message += "; the model's Jacobian is not finite: std is NaN"
    # Certification: converged means the Gauss-Newton model at the result predicts no
    # decrease of the loss worth having (relative decrease < `_GN_TOL`), and no
    # parameter at a boundary could lower it (the probes above); whichever test of the
    # optimiser stopped it. A fit stopped away from the minimum says so.
    # At an exact fit (noiseless data) the residual is round-off and its relative
    # decrease means nothing: an absolute floor on the predicted decrease of the loss
    # (mean squared relative residual) covers it.
    predicted = _predicted_decrease(rows, rel)
    floor = 1e-18 if jnp.finfo(dtype).bits >= 64 else 1e-10
    small = predicted < _GN_TOL or predicted * float(value) < floor
    # A parameter left at a boundary is not an interior minimum the certificate can
    # see (its log's column is ~0): NOT converged, and said why.
    stuck = [x for x in _at_boundary(_to_material(theta, refs, fit_poisson), data.times,
                                     refs)
             if x.split("_")[0] + ("_inf" if x.startswith("g_inf") else "")
             not in fixed_values]
    if stuck:
        message += (f"; at a boundary of the parametrisation: {', '.join(stuck)} (the "
                    "data do not determine it: fewer arms, fixed= or bounds=)")
    converged = (bool(small) and bool(np.all(np.asarray(ok))) and probe is None
                 and not stuck)
    verdict = "converged" if converged else "NOT converged"
    message += (f"; Gauss-Newton predicts a further {predicted:.2g} relative decrease "
                f"of the loss {float(value):.3g} ({verdict}: the bound is {_GN_TOL:g}, "
                f"or {floor:g} absolute)")
    discretisation = None
    if check_grid and _model is None and not isinstance(scene.indenter, Sphere):
        message += ("; check_grid needs a jc.Sphere indenter (a surface array is per "
                    "grid)")
    elif check_grid and _model is None:
        discretisation = _discretisation(scene, _to_material(theta, refs, fit_poisson),
                                         model, curve)
    material = _to_material(theta, refs, fit_poisson)
    if _model is None and dict(model.options).get("scheme") == "constant":
        # Inside the fit the material is traced and jc.solve cannot check its steps;
        # check the result (the fits sat at an amplification of 1.14 unseen).
        _warn_unstable_steps(material, scene.times)
    order = np.argsort(np.asarray(material.tau))
    material = Prony(material.g_inf, material.g[order], material.tau[order],
                     material.poisson)

    # The covariance in the order g_inf, g_1..g_n, tau_1..tau_n (sorted by tau)
    # [, poisson]: a permutation of ravel_pytree's (alphabetical keys) layout.
    # Fixed parameters get rows and columns of zeros (index p: a padding slot).
    p_free = rows.shape[1]
    index = _split(theta, np.arange(p_free))
    for key in fixed_values:
        index[key] = np.full(np.shape(fixed_values[key]), p_free)
    perm = np.concatenate([np.atleast_1d(index["g_inf"]), index["g"][order],
                           index["tau"][order]]
                          + ([np.atleast_1d(index["poisson"])] if fit_poisson else [])
                          ).astype(int)
    cov = np.pad(cov, ((0, 1), (0, 1)))
    names = (("g_inf",) + tuple(f"g_{i + 1}" for i in range(n))
             + tuple(f"tau_{i + 1}" for i in range(n))
             + (("poisson",) if fit_poisson else ()))

    def sorted_split(values):
        out = _split(theta, values)
        for key in fixed_values:  # not fitted: no spread, no gradient
            out[key] = np.zeros(np.shape(fixed_values[key]))
        out["g"], out["tau"] = out["g"][order], out["tau"][order]
        return out

    return PronyFit(
        material=material,
        initial=init,
        loss=float(value),
        loss_history=np.asarray(history),
        adam_steps=steps_adam,
        lbfgs_steps=steps_lbfgs,
        lm_steps=lm_total,
        optimiser=used,
        evaluations=ev.calls,
        converged=converged,
        message=message,
        solves_converged=bool(np.all(np.asarray(ok))),
        times=np.asarray(data.times),
        target=np.asarray(target),
        curve=np.asarray(curve),
        residual=residual,
        kind=kind,
        std=sorted_split(std),
        covariance=cov[np.ix_(perm, perm)],
        parameter_names=names,
        gradient=sorted_split(np.asarray(ravel_pytree(grad)[0]) / factor),
        noise=sigma_rel * scale_f,
        discretisation=discretisation,
    )
