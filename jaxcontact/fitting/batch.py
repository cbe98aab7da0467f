"""`jc.fit_prony_batch`: many curves of one shape fitted at once, their
Levenberg-Marquardt solves one compiled, vmapped program sharded over devices (or, on
a CPU, one curve after another; or in chunks on a Dask cluster). Each curve's set-up
and finish are `jc.fit_prony`'s own (`set_up`, `fit_problem`), the batched LM result
handed in as the curve's first LM run."""

import dataclasses
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from .._scene import Scene
from .._sweep import BATCH_AXIS, pad_batch
from .data import IndentationData
from .fit import fit_problem, fit_prony, set_up
from .lm import have_optimistix, lm_rtol, lm_solve_batch, run_steps
from .options import FitOptions, with_legacy


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
                    init=None, poisson=None, fit_poisson: bool = False,
                    fixed: dict | None = None, bounds: dict | None = None,
                    noise_std: float | None = None,
                    options: FitOptions = FitOptions(), client=None,
                    chunk_size: int | None = None, vectorize: bool | None = None,
                    devices=None, refit: bool = True, _model=None, **legacy) -> list:
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
    - `init`: `None`, `"lee-radok"`, or a sequence of one `jc.Prony` per curve.
    - `options`: a `jc.FitOptions`; `lm_steps` bounds the LM steps of every curve.
      The batch always runs LM (`optimiser="lbfgs"` is refused); a refit (see
      `refit`) runs `"auto"`. Its fields are still accepted as keywords
      (`lm_steps=50`), except `optimiser`; `options=` is the way.
    - `poisson`, `fit_poisson`, `fixed`, `bounds`, `noise_std`: as for
      `jc.fit_prony`, the same for every curve.
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
    if "optimiser" in legacy:
        raise ValueError("fit_prony_batch always uses optimiser='lm'")
    options = with_legacy(options, legacy, "fit_prony_batch")
    if options.optimiser == "lbfgs":
        raise ValueError("fit_prony_batch always uses optimiser='lm' (a refit "
                         "'auto'), got options.optimiser='lbfgs'")
    problem = dict(poisson=poisson, fit_poisson=fit_poisson, fixed=fixed,
                   bounds=bounds, noise_std=noise_std, _model=_model)
    data, weights, inits = _check_batch(data, weights, init, vectorize, devices, client)
    if client is not None:
        from .._sweep_dask import check_client, fit_on_client

        check_client(client, chunk_size, "jc.fit_prony_batch")
        return fit_on_client(fit_prony_batch, data, scene_template, n_terms, weights,
                             inits, {**problem, "options": options,
                                     "vectorize": vectorize, "refit": refit},
                             client, chunk_size)
    if chunk_size is not None:
        raise ValueError(f"fit_prony_batch: chunk_size={chunk_size!r} needs a client")
    if vectorize is None:
        vectorize = devices is not None or jax.default_backend() != "cpu"
    devices = list(jax.devices() if devices is None else devices)
    if not devices:
        raise ValueError("fit_prony_batch: devices is empty")
    lm = dataclasses.replace(options, optimiser="lm")
    curves = [dict(problem, data=d, weights=w, init=i)
              for d, w, i in zip(data, weights, inits, strict=True)]
    if not vectorize:
        fits = [fit_prony(**c, scene_template=scene_template, n_terms=n_terms,
                          options=lm) for c in curves]
    else:
        fits = _vectorized(curves, scene_template, n_terms, lm, devices)
    if not refit:
        return fits
    auto = dataclasses.replace(options, optimiser="auto")
    return [_better(fit, c, scene_template, n_terms, auto)
            for fit, c in zip(fits, curves, strict=True)]


def _check_batch(data, weights, inits, vectorize, devices, client):
    """`(data, weights, inits)` as lists of one entry per curve, checked."""
    data = list(data)
    if not data or not all(isinstance(d, IndentationData) for d in data):
        raise TypeError("data must be a non-empty sequence of jc.IndentationData")
    if not have_optimistix():
        raise ImportError('fit_prony_batch needs optimistix: pip install '
                          '"jaxcontact[fit]"')
    sizes = {d.times.shape[0] for d in data}
    if len(sizes) != 1:
        raise ValueError(f"fit_prony_batch: every curve needs the same number of "
                         f"samples, got {sorted(sizes)}")
    weights = [None] * len(data) if weights is None else list(weights)
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
    return data, weights, inits


def _better(fit, curve: dict, scene_template, n_terms, auto: FitOptions):
    """`fit`, or where it is not certified, the better of it and `fit_prony`'s
    default fit of the curve (see `refit`)."""
    if fit.converged:
        return fit
    alone = fit_prony(**curve, scene_template=scene_template, n_terms=n_terms,
                      options=auto)
    if alone.converged or alone.loss < fit.loss:
        return alone
    return fit


def _vectorized(curves, scene_template, n_terms, options: FitOptions, devices):
    """The LM fits of `curves` (`fit_prony` keywords), their first LM solve one
    vmapped program, padded to a multiple of the devices and sharded over them."""
    # -- Set-up of every curve (the start from its data) -----------------------------
    problems = []
    for c in curves:
        c = dict(c)
        model = c.pop("_model", None)
        problems.append(set_up(scene_template=scene_template, n_terms=n_terms,
                               options=options, model=model, **c))
    dtype = scene_template.grid.size.dtype

    # -- One batched LM solve --------------------------------------------------------
    stacked_args, axes = _stack([p.ev.args for p in problems])
    theta_b = jax.tree.map(lambda *x: jnp.stack(x), *[p.theta for p in problems])
    # `jax.shard_map` (as in `jc.sweep`) fails inside lineax's linear solves (its
    # structure check compares the manual axes' shardings: lineax issue 185), so the
    # batch axis is sharded for XLA's partitioner: the devices step together.
    padded = math.ceil(len(curves) / len(devices)) * len(devices)
    mesh = Mesh(np.array(devices), (BATCH_AXIS,))
    along = NamedSharding(mesh, PartitionSpec(BATCH_AXIS))
    same = NamedSharding(mesh, PartitionSpec())

    def place(x, axis):
        if axis == 0:
            return jax.device_put(pad_batch(x, padded), along)
        return jax.device_put(x, same) if eqx.is_array(x) else x

    theta_b = jax.tree.map(lambda x: place(x, 0), theta_b)
    stacked_args = jax.tree.map(place, stacked_args, axes, is_leaf=lambda x: x is None)
    rtol = lm_rtol(dtype)
    # The first compiled LM run of every curve (`LMRun`), batched; a curve that needs
    # more continues on its own in `fit_problem`.
    new, ok, steps = lm_solve_batch(theta_b, stacked_args, axes, rtol, 0.1 * rtol,
                                    run_steps(options.lm_steps))

    # -- Finish up, curve by curve ---------------------------------------------------
    return [fit_problem(p, options, lm_ready=(jax.tree.map(lambda x, i=i: x[i], new),
                                              ok[i], steps[i]))
            for i, p in enumerate(problems)]
