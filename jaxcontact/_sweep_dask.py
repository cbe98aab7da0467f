"""`jc.sweep(..., client=...)` and `jc.fit_prony_batch(..., client=...)`: a batch split
into chunks, each solved on a Dask worker by the ordinary (compiled, vmapped,
device-sharded) program, the results gathered along the batch axis.

How it is built, and why:

- The scene template and each chunk's batched values travel inside the task itself
  (not `client.scatter`): the scheduler keeps a task's arguments, so a chunk whose
  worker dies is resubmitted elsewhere with nothing lost. Scattered data held only by
  the dead worker would be gone.
- Arrays travel as NumPy arrays and become JAX arrays on the worker only after the
  worker has turned on `jax_enable_x64` where this process has it on: a worker
  process starts with JAX's default (float32), and a float64 JAX array unpickled
  there first would be truncated. The results come back as they are (JAX arrays):
  this process has x64 on wherever they are float64.
- Every chunk has the same size (the last one padded by repeating its last entry, as
  `jc.sweep` pads for devices): one program shape, compiled once per worker process
  or loaded from the persistent compilation cache (`jc.enable_compilation_cache`)
  when the workers share its folder.
"""

import math
import uuid

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np


_EXTRA = 'pip install "jaxcontact[dask]"'
# The compilation-cache settings of the calling process that a worker copies.
_CACHE_OPTIONS = ("jax_compilation_cache_dir",
                  "jax_persistent_cache_min_compile_time_secs",
                  "jax_persistent_cache_min_entry_size_bytes",
                  "jax_compilation_cache_max_size")


def check_client(client, chunk_size, who: str):
    """Import `distributed`, check `client` (a `distributed.Client`) and `chunk_size`
    (`None` or a positive integer). **Raises:** `ImportError` naming the extra where
    dask is missing; `TypeError` / `ValueError` naming the bad value."""
    try:
        import distributed
    except ImportError as error:
        raise ImportError(
            f"{who}(client=...) needs dask.distributed: {_EXTRA}") from error
    if not isinstance(client, distributed.Client):
        raise TypeError(
            f"{who}: client must be a dask.distributed.Client, got {client!r}")
    if chunk_size is not None and (isinstance(chunk_size, bool)
                                   or not isinstance(chunk_size, (int, np.integer))
                                   or chunk_size <= 0):
        raise ValueError(f"{who}: chunk_size must be a positive integer or None, got "
                         f"{chunk_size!r}")


def _chunks(size: int, chunk_size, client) -> list[tuple[int, int]]:
    """`[(start, stop), ...]` covering `range(size)`; default chunk size: the batch
    spread evenly over the workers the scheduler knows now (at least one)."""
    if chunk_size is None:
        workers = len(client.nthreads())  # {worker address: threads}
        chunk_size = math.ceil(size / max(workers, 1))
    chunk_size = int(chunk_size)
    return [(a, min(a + chunk_size, size)) for a in range(0, size, chunk_size)]


def _to_numpy(tree):
    return jax.tree.map(lambda x: np.asarray(x) if isinstance(x, jax.Array) else x,
                        tree)


def _to_jax(tree):
    return jax.tree.map(lambda x: jnp.asarray(x) if isinstance(x, np.ndarray) else x,
                        tree)


def worker_settings() -> dict:
    """The JAX settings a worker copies from this process: `jax_enable_x64` where it
    is on here (a float64 scene stays float64 on the worker), and the persistent
    compilation cache where it is on here."""
    settings = {"jax_enable_x64": True} if jax.config.jax_enable_x64 else {}
    if jax.config.jax_compilation_cache_dir:
        settings.update({name: getattr(jax.config, name) for name in _CACHE_OPTIONS})
    return settings


def apply_settings(settings: dict) -> None:
    """On the worker, before any array is built: `jax.config.update` each setting
    that differs. x64 is only ever turned on, never off (another task in the same
    worker process may need it). The cache settings take effect before the process's
    first compilation."""
    for name, value in settings.items():
        if getattr(jax.config, name) != value:
            jax.config.update(name, value)


def _pad_chunk(tree, start: int, stop: int, length: int):
    """Entries `start:stop` of every array leaf (leading axis), padded to `length` by
    repeating the last one."""
    def cut(x):
        if not eqx.is_array(x):
            return x
        x = np.asarray(x)[start:stop]
        extra = length - x.shape[0]
        return x if extra == 0 else np.concatenate([x, np.repeat(x[-1:], extra, 0)])

    return jax.tree.map(cut, tree)


def _sweep_chunk(settings, sweep, scene, batched, solve_options):
    """One chunk on a worker: `sweep` (`jc.sweep`, called without a client) of `scene`
    over `batched` (`{keyword: value}`, NumPy leaves); its `jc.Solution`."""
    apply_settings(settings)
    return sweep(_to_jax(scene), solve_options=_to_jax(solve_options),
                 **_to_jax(batched))


def sweep_on_client(sweep, scene, values: dict, size: int, options: dict, client,
                    chunk_size):
    """`jc.sweep`'s work on a Dask cluster. `sweep`: `jc.sweep` itself (passed in, not
    imported: this module is imported by `_sweep`, and functions travel to the workers
    by reference); `values`: `{path: value}` as `_parse` returns it (leading batch size
    `size`); `options`: the `jc.solve` keywords.
    **Returns:** the `jc.Solution` of the whole batch (JAX arrays, leading axis
    `size`)."""
    spans = _chunks(size, chunk_size, client)
    length = spans[0][1] - spans[0][0]
    scene_np = _to_numpy(scene)
    options_np = _to_numpy(options)
    settings = worker_settings()
    token = uuid.uuid4().hex[:12]
    futures = []
    for k, (start, stop) in enumerate(spans):
        batched = {"__".join(path): _pad_chunk(value, start, stop, length)
                   for path, value in values.items()}
        futures.append(client.submit(
            _sweep_chunk, settings, sweep, scene_np, batched, options_np,
            key=f"jaxcontact-sweep-{token}-{k}"))
    # A worker that dies mid-chunk is replaced (its nanny restarts it) and the
    # scheduler resubmits the chunk, up to `distributed.scheduler.allowed-failures`
    # times; then `gather` raises `distributed.KilledWorker`.
    parts = client.gather(futures)
    parts = [jax.tree.map(lambda x, n=stop - start: x[:n], part)
             for part, (start, stop) in zip(parts, spans, strict=True)]
    return jax.tree.map(lambda *xs: jnp.concatenate(xs), *parts)


def _fit_chunk(settings, fit_prony_batch, data, scene_template, n_terms, weights,
               options):
    """One chunk of curves on a worker: `fit_prony_batch` (`jc.fit_prony_batch`,
    called without a client)."""
    apply_settings(settings)
    return fit_prony_batch(_to_jax(data), _to_jax(scene_template), n_terms,
                           weights=_to_jax(weights), **_to_jax(options))


def fit_on_client(fit_prony_batch, data: list, scene_template, n_terms: int,
                  weights: list, inits: list, options: dict, client,
                  chunk_size) -> list:
    """`jc.fit_prony_batch`'s work on a Dask cluster: the curves in chunks, each
    chunk's batched Levenberg-Marquardt solve on a worker by `fit_prony_batch` (passed
    in, as `jc.sweep` is to `sweep_on_client`; `options`: its other keywords, the
    `jc.FitOptions` among them). **Returns:** the list of `jc.PronyFit`, one per
    curve, in order."""
    spans = _chunks(len(data), chunk_size, client)
    settings = worker_settings()
    scene_np, options_np = _to_numpy(scene_template), _to_numpy(options)
    token = uuid.uuid4().hex[:12]
    futures = []
    for k, (start, stop) in enumerate(spans):
        # A short last chunk compiles its own batched program (fits cannot be padded
        # with repeats without fitting the repeats): pick chunk_size dividing the
        # batch to avoid it.
        chunk_opts = dict(options_np, init=_to_numpy(inits[start:stop]))
        futures.append(client.submit(
            _fit_chunk, settings, fit_prony_batch, _to_numpy(data[start:stop]),
            scene_np, n_terms,
            _to_numpy(weights[start:stop]), chunk_opts,
            key=f"jaxcontact-fit-{token}-{k}"))
    parts = client.gather(futures)  # resubmitted on a worker's death, as in the sweep
    return [fit for part in parts for fit in part]
