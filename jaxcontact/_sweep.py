"""`jc.sweep`: solve a batch of variants of one scene, compiled once, sharded over
the available devices."""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from ._scene import Scene
from ._solution import Solution
from ._solve import operator_for, solve
from ._solve_rings import axisymmetric_support


# Fields that may be swept. `grid` (it fixes the operator and the array shapes),
# `coupling` and `slip` (static: they choose the program) may not.
_SWEEPABLE = ("indenter", "material", "times", "normal", "x", "y", "friction")
BATCH_AXIS = "batch"


def _getter(path: tuple[str, ...]):
    def get(scene):
        node = scene
        for name in path:
            node = getattr(node, name)
        return node

    return get


def _replace(scene: Scene, values: dict) -> Scene:
    """The scene with each `path -> value` of `values` put in (by `eqx.tree_at`)."""
    for path, value in values.items():
        scene = eqx.tree_at(_getter(path), scene, value, is_leaf=lambda x: x is None)
    return scene


def _parse(scene: Scene, batched: dict) -> tuple[dict, int]:
    """Check the batched fields; return `{path: value}` with array leaves and `B`."""
    if not batched:
        raise ValueError(
            "jc.sweep needs at least one batched field, e.g. "
            "jc.sweep(scene, friction=jnp.array([0.1, 0.2]))"
        )
    values, sizes = {}, {}
    for key, value in batched.items():
        path = tuple(key.split("__"))
        if path[0] not in _SWEEPABLE:
            raise ValueError(
                f"jc.sweep cannot batch {key!r}: the batched fields are {_SWEEPABLE} "
                "(or a nested field as material__g_inf); grid, coupling and slip fix "
                "the compiled program"
            )
        try:
            _getter(path)(scene)
        except AttributeError:
            raise ValueError(
                f"jc.sweep: the scene has no field {'.'.join(path)!r} (from {key!r})"
            ) from None
        if value is None:
            raise ValueError(f"jc.sweep: {key} must be a batched value, got None")
        value = jax.tree.map(
            lambda x: x if (eqx.is_array(x) or callable(x)) else jnp.asarray(x), value
        )
        leaves = [x for x in jax.tree.leaves(value) if eqx.is_array(x)]
        if not leaves:
            raise ValueError(
                f"jc.sweep: {key} holds no array to batch over, got {value!r}")
        for leaf in leaves:
            if leaf.ndim == 0:
                raise ValueError(
                    f"jc.sweep: every array in {key} needs a leading batch axis, got a "
                    f"scalar {leaf!r}"
                )
            sizes.setdefault(key, set()).add(int(leaf.shape[0]))
        values[path] = value
    all_sizes = {size for s in sizes.values() for size in s}
    if len(all_sizes) != 1:
        got = {key: sorted(s) for key, s in sizes.items()}
        raise ValueError(
            "jc.sweep: every batched array must have the same leading (batch) size, "
            f"got {got}"
        )
    size = all_sizes.pop()
    if size == 0:
        raise ValueError("jc.sweep: the batch is empty (leading size 0)")
    return values, size


def traced_directions(scene: Scene) -> int:
    """The tangential directions `jc.solve` picks when the friction is traced (as it is
    inside the sweep, where no concrete zero can switch the tangential solve off)."""
    found = []

    def probe(friction):
        traced = eqx.tree_at(lambda s: s.friction, scene, friction)
        found.append(traced.tangential_directions)
        return friction

    jax.eval_shape(probe, scene.friction)
    return found[0]


def pad_batch(x, padded: int):
    """Pad the leading axis to `padded` by repeating the last entry (a valid
    problem)."""
    extra = padded - x.shape[0]
    if extra == 0:
        return x
    return jnp.concatenate([x, jnp.repeat(x[-1:], extra, axis=0)], axis=0)


@eqx.filter_jit
def _run(arrays, fixed, dynamic, static, options, mesh):
    spec = PartitionSpec(BATCH_AXIS)

    def local(arrays, dynamic):
        scene, operator = eqx.combine(dynamic, static)
        batched = eqx.combine(arrays, fixed)

        def one(values):
            return solve(_replace(scene, values), operator=operator, **dict(options))

        return jax.vmap(one)(batched)

    sharded = jax.shard_map(
        local, mesh=mesh, in_specs=(spec, PartitionSpec()), out_specs=spec,
        # The solver loops mix replicated and per-device values in their carries;
        # every device runs its own slice, nothing is reduced across devices.
        check_vma=False,
    )
    return sharded(arrays, dynamic)


def sweep(scene: Scene, /, *, solve_options: dict | None = None, devices=None,
          client=None, chunk_size: int | None = None, **batched) -> Solution:
    """Solve a batch of variants of `scene`: `jax.vmap` over `jc.solve`, compiled once
    for the batch and sharded over devices.

    **Main arguments:**

    - `scene`: the `jc.Scene` every variant starts from.
    - `**batched`: the fields to vary, by their constructor names, each with a leading
      batch axis of the same size `B` on every array it holds:
        - an array: `friction=jnp.array([0.1, 0.2, 0.3])` (shape `(B,)`);
        - a batched module: `material=jax.vmap(lambda g: jc.Zener(g, g / 4, 0.01, 0.3))(
          mu_inf)`; `normal=jc.Force(loads)` with `loads` of shape `(B,)` or `(B, nt)`;
        - a nested field, path parts joined by a double underscore:
          `material__mu_0=jnp.array([...])` (the template's other fields stay).
      `grid`, `coupling` and `slip` cannot be swept (they fix the compiled program).

    **Other arguments:**

    - `solve_options`: keyword arguments passed on to `jc.solve` (`rtol`, `max_steps`,
      `history`, `scheme`, ...; not `operator`).
    - `devices`: the devices to shard the batch over; default `jax.devices()`. The
      batch is padded to a multiple of their number by repeating its last entry, put on
      a 1-D mesh with `NamedSharding`, and each device solves its slice with `vmap`
      (`shard_map`: the devices do not wait for each other inside a solve).
      With `client`, each worker uses its own devices: leave `devices` out.
    - `client`: a `dask.distributed.Client` (needs the `dask` extra:
      `pip install "jaxcontact[dask]"`). The batch is split into chunks of
      `chunk_size` members, each chunk solved by this same function on a worker (its
      program compiled once per worker process, or loaded from the persistent
      compilation cache where this process has turned it on with
      `jc.enable_compilation_cache` and the workers see the same folder), and the
      results concatenated along the batch axis: the same `jc.Solution` as without a
      client. A chunk whose worker dies is resubmitted by Dask. The workers turn on
      `jax_enable_x64` themselves where this process has it on.
    - `chunk_size`: members per chunk (a positive integer; the last chunk is padded
      to it by repeating its last member, so every chunk runs one program shape).
      Default: the batch spread evenly over the workers connected now. Only with
      `client`.

    **Returns:** a `jc.Solution` whose every field has a leading batch axis `B` (then
    time, as for `jc.solve`). Entry `b` equals `jc.solve` of the scene with entry `b`
    of every batched field (up to rounding).

    !!! note
        The scene's `friction` is a traced value inside the sweep, so a concrete
        `friction=0` does not switch the tangential solve off as it does in `jc.solve`
        (the answer is the same; the work is not). Under `vmap` a solver loop runs
        until the slowest entry of a device's slice converges: batch similar problems.
        The operator (the kernel spectra) is built once for the whole sweep. A
        frictionless axisymmetric scene is swept on rings, as `jc.solve` solves it
        (`solve_options={"solver": jc.Rounds()}`: on the grid).
    """
    if not isinstance(scene, Scene):
        raise TypeError(f"scene must be a jc.Scene, got {scene!r}")
    options = dict(solve_options or {})
    # A batch reports its failures per member (`converged`, `result`) rather than
    # raising for the whole batch; `throw=True` in solve_options raises.
    options.setdefault("throw", False)
    if "operator" in options:
        raise ValueError("jc.sweep builds the operator once itself: leave 'operator' "
                         "out of solve_options")
    values, size = _parse(scene, batched)
    if client is not None:
        from ._sweep_dask import check_client, sweep_on_client

        check_client(client, chunk_size, "jc.sweep")
        if devices is not None:
            raise ValueError("jc.sweep: devices and client exclude each other (each "
                             f"worker shards over its own devices), got {devices!r}")
        return sweep_on_client(sweep, scene, values, size, options, client, chunk_size)
    if chunk_size is not None:
        raise ValueError(f"jc.sweep: chunk_size={chunk_size!r} needs a client (the "
                         "batch is only split into chunks for Dask workers)")
    devices = list(jax.devices() if devices is None else devices)
    if not devices:
        raise ValueError("jc.sweep: devices is empty")

    # Initial set-up: the operator the traced solve needs, from entry 0.
    first = _replace(scene, jax.tree.map(lambda x: x[0] if eqx.is_array(x) else x,
                                         values))
    directions = traced_directions(first)
    # A frictionless axisymmetric scene runs on rings, as `jc.solve` runs it: no grid
    # operator to build (a grid solver in solve_options keeps the grid).
    on_rings = (options.get("solver") is None and directions == 0
                and axisymmetric_support(first) is None)
    operator = None if on_rings else operator_for(first, directions)
    # Callables (e.g. a jc.Force(lambda t: ...) value) stay static.
    dynamic, static = eqx.partition((scene, operator), eqx.is_array)

    # Pad to a multiple of the device count and shard the batch axis.
    n_dev = len(devices)
    padded = math.ceil(size / n_dev) * n_dev
    mesh = Mesh(np.array(devices), (BATCH_AXIS,))
    arrays, fixed = eqx.partition(values, eqx.is_array)
    arrays = jax.tree.map(lambda x: pad_batch(x, padded), arrays)
    arrays = jax.device_put(arrays, NamedSharding(mesh, PartitionSpec(BATCH_AXIS)))
    dynamic = jax.device_put(dynamic, NamedSharding(mesh, PartitionSpec()))
    fixed_options = tuple(sorted(options.items()))

    out = _run(arrays, fixed, dynamic, static, fixed_options, mesh)
    return jax.tree.map(lambda x: x[:size], out)
