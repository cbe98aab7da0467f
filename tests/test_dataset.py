"""Results as xarray Datasets and netCDF files (issue 30, item 1).

Every field of `jc.Solution`, `jc.NormalSolution`, the subsurface `jc.Stress` and
`jc.PronyFit` goes through `to_xarray()` -> netCDF (h5netcdf) -> `jc.load` and comes
back bit for bit (`rtol=0`: netCDF-4 stores the IEEE values as they are) with its
dtype, named dimensions, coordinates from the grid, and `units` / `long_name` on every
variable. Scenes are tiny (12 x 12 cells) so that compilation dominates.
"""

import dataclasses
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import xarray as xr

import jaxcontact as jc
from jaxcontact._dataset import to_netcdf


GRID = jc.Grid((12, 12), 3e-3)


def _scene(dtype=jnp.float64, frictional=True):
    """Zener creep under 0.15 N, 4 time points; frictional: with a tangential
    displacement ramp (mu = 0.3, uncoupled: the cheapest frictional program)."""
    grid = jc.Grid((12, 12), jnp.asarray(3e-3, dtype))
    nt = 4
    tangential = {}
    if frictional:
        tangential = dict(x=jc.Displacement(jnp.linspace(0.0, 2e-6, nt, dtype=dtype)),
                          friction=0.3, coupling="none")
    return jc.Scene(
        grid, jc.Sphere(10e-3), jc.Zener(1.93e6, 1.93e6 / 4, 0.01, 0.3),
        jnp.linspace(0.0, 0.02, nt, dtype=dtype), jc.Force(0.15), **tangential)


def _round_trip(ds, path):
    to_netcdf(ds, path)
    back = jc.load(path)
    xr.testing.assert_identical(ds, back)  # values, dtypes, dims, coords, attrs
    return back


def _check_labels(ds):
    for name, var in ds.variables.items():
        assert var.attrs.get("long_name"), f"{name} has no long_name"
        if var.dtype.kind != "U":  # the string coordinates (component, parameter)
            assert var.attrs.get("units"), f"{name} has no units"


def _field_names(module):
    return [f.name for f in dataclasses.fields(module)]


@pytest.mark.parametrize("dtype", [jnp.float64, jnp.float32])
def test_solution_round_trip_every_field(tmp_path, dtype):
    # float32: the frictionless program (a cheaper compile); float64: with friction.
    frictional = dtype == jnp.float64
    scene = _scene(dtype, frictional)
    sol = jc.solve(scene)
    ds = sol.to_xarray(scene, solve_options={"rtol": None, "solver": jc.JointPCG()})
    back = _round_trip(ds, tmp_path / "sol.nc")
    _check_labels(back)
    assert dict(back.sizes) == {"time": 4, "x": 12, "y": 12, "component": 2}
    # Which solver ran: the frictionless sphere on rings (jc.solve's default).
    assert back.attrs["method"] == sol.method == ("grid" if frictional else "rings")
    for name in _field_names(sol):
        if name in ("result", "method"):
            continue
        want = np.asarray(getattr(sol, name))
        got = back[name].values if name != "times" else back["time"].values
        assert got.dtype == want.dtype, name
        np.testing.assert_array_equal(got, want, err_msg=name)
    np.testing.assert_array_equal(back["result"].values, np.asarray(sol.result._value))
    assert back["result"].attrs["flag_meanings"].split()[0] == "successful"
    np.testing.assert_array_equal(back["edge_contact"].values,
                                  np.asarray(sol.edge_contact))
    np.testing.assert_array_equal(back["initial_gap"].values,
                                  np.asarray(scene.indenter.gap(scene.grid)))
    assert back["pressure"].dtype == np.dtype(dtype)
    assert back["pressure"].dims == ("time", "x", "y")
    assert back["shear"].dims == ("time", "component", "x", "y")
    assert back["tangential_force"].dims == ("time", "component")
    # Coordinates: the grid's cell centres [m], the times [s].
    np.testing.assert_array_equal(back["x"].values, np.asarray(scene.grid.x))
    np.testing.assert_array_equal(back["y"].values, np.asarray(scene.grid.y))
    assert list(back["component"].values) == ["x", "y"]
    assert back["pressure"].attrs["units"] == "Pa" and back["x"].attrs["units"] == "m"
    assert back["time"].attrs["units"] == "s"
    assert back["normal_force"].attrs["units"] == "N"
    # The scene, the solve options and the versions in the attributes.
    info = json.loads(back.attrs["scene"])
    assert (info["material"]["type"] == "Zener"
            and info["material"]["mu_0"] == 1.93e6 / 4)
    assert info["material"]["units"]["tau"] == "s"
    assert info["indenter"] == {"type": "Sphere", "radius": 0.01, "centre": [0.0, 0.0],
                                "units": "m"}
    # The load programs evaluated on the times (in the scene's dtype: float32 rounds).
    rtol = 1e-7 if dtype == jnp.float32 else 0
    assert info["normal"]["type"] == "Force" and info["normal"]["units"] == "N"
    np.testing.assert_allclose(info["normal"]["values"], [0.15] * 4, rtol=rtol)
    assert info["grid"]["shape"] == [12, 12] and info["coupling"] == "none"
    assert back.attrs["coupling"] == "none" and back.attrs["slip"] == "incremental"
    if frictional:
        assert info["x"]["type"] == "Displacement" and info["x"]["units"] == "m"
        np.testing.assert_allclose(info["x"]["values"], np.linspace(0, 2e-6, 4))
        assert back.attrs["friction"] == 0.3 and info["y"] is None
        assert back["stick"].any() and back["shear"].any()
    np.testing.assert_array_equal(back.attrs["grid_shape"], [12, 12])
    options = json.loads(back.attrs["solve_options"])
    assert options["rtol"] is None and options["solver"].startswith("JointPCG(")
    assert back.attrs["jax_version"] == jax.__version__
    assert json.loads(back.attrs["versions"])["jaxcontact"] == jc.__version__
    # The plain xarray reader opens the same file with the same content.
    with xr.open_dataset(tmp_path / "sol.nc") as plain:
        xr.testing.assert_identical(plain.load(), back)


def test_solution_units_are_labels_only():
    scene = _scene()
    sol = jc.solve(scene)
    ds = sol.to_xarray(scene, units={"length": "um", "force": "uN", "time": "ms"})
    assert ds["pressure"].attrs["units"] == "uN/um^2"
    assert ds["x"].attrs["units"] == "um" and ds["time"].attrs["units"] == "ms"
    np.testing.assert_array_equal(ds["x"].values, np.asarray(scene.grid.x))  # unscaled
    with pytest.raises(ValueError, match="missing \\['time'\\]"):
        sol.to_xarray(scene, units={"length": "m", "force": "N"})
    with pytest.raises(TypeError, match="needs the jc.Scene that was solved"):
        sol.to_xarray(scene.grid)
    other = jc.Scene(jc.Grid((8, 8), 3e-3), jc.Sphere(10e-3), scene.material,
                     scene.times, jc.Force(0.15))
    with pytest.raises(ValueError, match=r"expected \(nt, 8, 8\)"):
        sol.to_xarray(other)


def test_sweep_round_trip_with_batch_coordinate(tmp_path):
    scene = _scene()
    mus = jnp.array([0.2, 0.4])  # same program as the frictional round trip
    sol = jc.sweep(scene, friction=mus)
    ds = sol.to_xarray(scene, batch={"friction": mus})
    back = _round_trip(ds, tmp_path / "sweep.nc")
    _check_labels(back)
    assert back["pressure"].dims == ("batch", "time", "x", "y")
    np.testing.assert_array_equal(back["friction"].values, np.asarray(mus))
    for name in _field_names(sol):
        if name not in ("result", "times", "method"):
            np.testing.assert_array_equal(back[name].values,
                                          np.asarray(getattr(sol, name)))
    np.testing.assert_array_equal(back["time"].values, np.asarray(scene.times))
    with pytest.raises(ValueError, match="needs a leading size 2"):
        sol.to_xarray(scene, batch={"friction": jnp.array([0.2, 0.3, 0.4])})


def test_normal_solution_round_trip(tmp_path):
    material = jc.Elastic(1e6, 0.3)
    sol = jc.solve_normal(GRID, jc.Sphere(10e-3), material, force=0.15)
    ds = sol.to_xarray(GRID, material=material, indenter=jc.Sphere(10e-3))
    back = _round_trip(ds, tmp_path / "normal.nc")
    _check_labels(back)
    for name in _field_names(sol):
        if name == "result":
            continue
        want = np.asarray(getattr(sol, name))
        assert back[name].dtype == want.dtype, name
        np.testing.assert_array_equal(back[name].values, want, err_msg=name)
    # jc.RESULTS as its integer code, the flags named as for jc.Solution
    assert int(back["result"]) == int(np.asarray(sol.result._value)) == 0
    assert back["result"].attrs["flag_meanings"].split()[0] == "successful"
    assert back["pressure"].dims == ("x", "y") and back["approach"].dims == ()
    assert json.loads(back.attrs["material"])["shear_modulus"] == 1e6
    # Load balance through the file: sum(p) dx dy = W (solver rtol 1e-8).
    cell = float(np.diff(back["x"])[0] * np.diff(back["y"])[0])
    np.testing.assert_allclose(back["pressure"].sum() * cell, 0.15, rtol=1e-7)


@pytest.mark.parametrize("depth", [jnp.array([0.0, 2e-4, 5e-4]), 2e-4])
def test_stress_round_trip(tmp_path, depth):
    sol = jc.solve_normal(GRID, jc.Sphere(10e-3), jc.Elastic(1e6, 0.3), force=0.15)
    shear = 0.2 * jnp.stack([sol.pressure, jnp.zeros_like(sol.pressure)])
    stress = jc.subsurface_stress(GRID, sol.pressure, shear, poisson=0.3, depth=depth)
    back = _round_trip(stress.to_xarray(GRID), tmp_path / "stress.nc")
    _check_labels(back)
    multi = np.ndim(depth) == 1
    assert back["szz"].dims == (("depth", "x", "y") if multi else ("x", "y"))
    np.testing.assert_array_equal(back["depth"].values, np.asarray(depth))
    for name in ("sxx", "syy", "szz", "sxy", "sxz", "syz", "von_mises", "max_shear"):
        np.testing.assert_array_equal(back[name].values,
                                      np.asarray(getattr(stress, name)))
    assert back["szz"].attrs["units"] == "Pa"


def test_fit_round_trip(tmp_path):
    # A PronyFit built by hand (the dataset maps fields; fitting is tested elsewhere).
    names = ("g_inf", "g_1", "g_2", "tau_1", "tau_2")
    times = np.linspace(0.0, 1.0, 5)
    fit = jc.PronyFit(
        material=jc.Prony(100.0, jnp.array([50.0, 20.0]), jnp.array([0.1, 2.0]), 0.5),
        initial=jc.Prony(80.0, jnp.array([40.0, 40.0]), jnp.array([0.2, 1.0]), 0.5),
        loss=1e-4, loss_history=np.array([1.0, 1e-2, 1e-4]), adam_steps=2,
        lbfgs_steps=1, lm_steps=0, optimiser="lbfgs", evaluations=7, converged=True,
        message="done", solves_converged=True, times=times, target=times * 1e-6,
        curve=times * 1.01e-6, residual=times * 0.01e-6, kind="depth",
        std={"g_inf": 0.1, "g": np.array([0.2, 0.3]), "tau": np.array([0.4, 0.5])},
        covariance=np.diag([0.01, 0.04, 0.09, 0.16, 0.25]), parameter_names=names,
        gradient={"g_inf": 1e-9, "g": np.array([2e-9, 3e-9]),
                  "tau": np.array([4e-9, 5e-9])},
        noise=1e-9, discretisation=None,
    )
    back = _round_trip(fit.to_xarray(), tmp_path / "fit.nc")
    _check_labels(back)
    for name in ("target", "curve", "residual", "loss_history", "covariance"):
        np.testing.assert_array_equal(back[name].values, np.asarray(getattr(fit, name)))
    np.testing.assert_array_equal(back["time"].values, times)
    np.testing.assert_array_equal(back["g"].values, [50.0, 20.0])
    np.testing.assert_array_equal(back["tau"].values, [0.1, 2.0])
    np.testing.assert_array_equal(back["initial_tau"].values, [0.2, 1.0])
    assert float(back["g_inf"]) == 100.0 and float(back["poisson"]) == 0.5
    # Young's moduli at nu = 0.5: E = 3 G
    assert float(back["E_inf"]) == 300.0 and float(back["E_0"]) == 510.0
    np.testing.assert_array_equal(back["E"].values, [150.0, 60.0])
    assert back["E"].attrs["units"] == "Pa"
    np.testing.assert_array_equal(back["log_std"].values, [0.1, 0.2, 0.3, 0.4, 0.5])
    np.testing.assert_array_equal(back["gradient"].sel(parameter="tau_2"), 5e-9)
    assert list(back["parameter"].values) == list(names)
    assert back["target"].attrs["units"] == "m" and back["g"].attrs["units"] == "Pa"
    assert back["tau"].attrs["units"] == "s"
    assert back.attrs["converged"] == 1 and back.attrs["kind"] == "depth"
    assert back.attrs["message"] == "done" and np.isnan(back.attrs["discretisation"])


def test_load_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="no such result file"):
        jc.load(tmp_path / "missing.nc")
    bad = tmp_path / "bad.nc"
    bad.write_text("not a netCDF file")
    with pytest.raises(ValueError, match="is not a netCDF file"):
        jc.load(bad)
