"""`jc.sweep`: a batch of scenes solved by one vmapped, sharded program.

Reference: the same scenes solved one by one with `jc.solve`. Both run at
`rtol = 1e-12`, so each is within ~1e-11 of the exact discrete solution and the two
agree to 1e-10 (at the default rtol = 1e-8 two CG runs that round differently agree
only to ~1e-8, the tolerance).
"""

import functools
import json
import os
import textwrap

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import run_on_host_devices, zener

import jaxcontact as jc


# The tests share cached solutions and their compiled programs (functools.cache):
# one test process runs them all (an xdist group, see tests/conftest.py).
pytestmark = pytest.mark.xdist_group("sweep")

RTOL = 1e-12
MU_0 = (0.25e6, 0.5e6, 1.0e6)  # Pa: three Zener materials (paper Eqs. 29-30 family)
# Three steps of 2/3 tau: too long for the piecewise-constant scheme with these
# materials (jc.TimeStepWarning); the piecewise-linear one is stable.
SCHEME = "linear"


def base_scene():
    grid = jc.Grid((16, 16), (3e-3, 3e-3))
    return jc.Scene(grid, jc.Sphere(10e-3), zener(MU_0[0]), jnp.linspace(0.0, 0.02, 4),
                    normal=jc.Force(0.15))


@functools.cache
def individual():
    """Each Zener material solved on its own: `(nb, nt, ...)` NumPy arrays."""
    scene = base_scene()
    sols = [jc.solve(eqx.tree_at(lambda s: s.material, scene, zener(m)), rtol=RTOL,
                     scheme=SCHEME)
            for m in MU_0]
    return {name: np.stack([np.asarray(getattr(s, name)) for s in sols])
            for name in ("pressure", "normal_force", "approach", "converged")}


def assert_matches(out, ref):
    assert np.all(ref["converged"]) and np.all(np.asarray(out["converged"]))
    p, p_ref = np.asarray(out["pressure"]), ref["pressure"]
    scale = np.max(p_ref, axis=(1, 2, 3), keepdims=True)
    assert np.max(np.abs(p - p_ref) / scale) < 1e-10
    np.testing.assert_allclose(out["normal_force"], ref["normal_force"], rtol=1e-10,
                               atol=0)
    np.testing.assert_allclose(out["approach"], ref["approach"], rtol=1e-10, atol=0)


def test_sweep_material_built_by_a_function_matches_individual_solves():
    make = jax.vmap(zener)  # a batched material, built by its constructor under vmap
    out = jc.sweep(base_scene(), material=make(jnp.asarray(MU_0)),
                   solve_options={"rtol": RTOL, "scheme": SCHEME})
    assert out.pressure.shape == (3, 4, 16, 16) and out.normal_force.shape == (3, 4)
    assert_matches({k: getattr(out, k) for k in individual()}, individual())
    # The loads are met and the softer material (smaller mu_0 = more creep) sinks
    # deeper: a physical ordering, not a copy of the reference.
    np.testing.assert_allclose(out.normal_force[:, 1:], 0.15, rtol=1e-9)
    assert np.all(np.diff(np.asarray(out.approach[:, -1])) < 0)


_SUBPROCESS = textwrap.dedent(
    """
    import json, sys
    import jax, jax.numpy as jnp, numpy as np
    jax.config.update("jax_enable_x64", True)
    sys.path.insert(0, {tests!r})
    import test_sweep as t
    import jaxcontact as jc
    assert len(jax.devices()) == 4, jax.devices()
    out = jc.sweep(t.base_scene(), material__mu_0=jnp.asarray(t.MU_0),
                   solve_options={{"rtol": t.RTOL, "scheme": t.SCHEME}})
    np.savez({path!r}, pressure=out.pressure, normal_force=out.normal_force,
             approach=out.approach, converged=out.converged)
    print(json.dumps({{"devices": len(jax.devices())}}))
    """
)


def test_sweep_shards_over_four_cpu_devices(tmp_path):
    """3 scenes padded to 4 and sharded over 4 forced host devices, in a fresh
    process; a nested field (`material__mu_0`) is batched this time."""
    path = str(tmp_path / "out.npz")
    code = _SUBPROCESS.format(tests=os.path.dirname(__file__), path=path)
    done = run_on_host_devices(code, 4)
    assert done.returncode == 0, done.stderr[-3000:]
    assert json.loads(done.stdout.strip().splitlines()[-1])["devices"] == 4
    with np.load(path) as out:
        assert_matches(dict(out), individual())


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({}, "at least one batched field"),
        ({"grid": jc.Grid((8, 8), 1.0)}, "cannot batch 'grid'"),
        ({"coupling": "x"}, "cannot batch 'coupling'"),
        ({"material__nope": jnp.ones(2)}, "no field 'material.nope'"),
        ({"friction": jnp.asarray(0.3)}, "leading batch axis"),
        ({"friction": jnp.ones(2), "material__mu_0": jnp.ones(3)}, "same leading"),
        ({"friction": jnp.ones(0)}, "empty"),
        ({"friction": None}, "got None"),
    ],
)
def test_sweep_rejects_bad_batches(kwargs, match):
    with pytest.raises(ValueError, match=match):
        jc.sweep(base_scene(), **kwargs)


def test_sweep_rejects_bad_options():
    with pytest.raises(TypeError, match="jc.Scene"):
        jc.sweep("scene", friction=jnp.ones(2))
    with pytest.raises(ValueError, match="operator"):
        jc.sweep(base_scene(), friction=jnp.ones(2), solve_options={"operator": None})


@pytest.mark.slow
def test_sweep_friction_coupled_partial_slip_matches_individual_solves():
    grid = jc.Grid((32, 32), (3e-3, 3e-3))
    scene = jc.Scene(grid, jc.Sphere(10e-3), jc.Elastic(1.93e6, 0.3),
                     jnp.linspace(0.0, 1.0, 5), normal=jc.Force(0.15),
                     x=jc.Displacement(jnp.linspace(0.0, 6e-6, 5)), friction=0.3,
                     coupling="full")
    mus = jnp.array([0.2, 0.3, 0.5])
    out = jc.sweep(scene, friction=mus, solve_options={"rtol": RTOL})
    for i, mu in enumerate(mus):
        ref = jc.solve(eqx.tree_at(lambda s: s.friction, scene, mu), rtol=RTOL)
        assert bool(np.all(ref.converged)) and bool(np.all(out.converged[i]))
        for name in ("pressure", "shear"):
            a, b = np.asarray(getattr(out, name)[i]), np.asarray(getattr(ref, name))
            assert np.max(np.abs(a - b)) < 1e-10 * np.max(np.abs(b)), name
        np.testing.assert_allclose(out.tangential_force[i], ref.tangential_force,
                                   rtol=1e-10, atol=1e-10 * 0.15)
    # More friction, more stick (Cattaneo-Mindlin ordering).
    assert np.all(np.diff(np.asarray(out.stick_ratio[:, -1])) > 0)
