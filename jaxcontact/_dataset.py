"""Results as labelled `xarray.Dataset`s, and netCDF files (`jc.load`).

`Solution.to_xarray(scene)`, `NormalSolution.to_xarray(grid)`,
`Stress.to_xarray(grid)` and `PronyFit.to_xarray()` build a Dataset with named
dimensions (`time`, `x`, `y`, `component`, and `batch`, `depth`, `parameter` where
they apply), coordinates in the units of the inputs, and `units` and `long_name`
attributes on every variable and numeric coordinate. The scene that produced a result
(grid, indenter, material, loads, contact law, solver options, versions) goes into
the Dataset's attributes: numbers and strings as they are, nested values as JSON
strings (a netCDF attribute holds only a string, a number or a 1-D numeric array).

Units: jaxcontact is unit-agnostic (any consistent set: length, force, time; stress =
force / length^2). The Datasets label their variables with the units the caller names
(`units=`), SI (m, N, Pa, s) by default, as every preset and example uses. The labels
are only labels: nothing is converted.

Files: `Dataset.to_netcdf(path)` with the `h5netcdf` engine (netCDF-4 / HDF5: pure
Python over h5py, whose wheels carry HDF5 on every platform; netCDF-4 holds float32
and int64 as they are, compresses, and xarray stores booleans as int8 flagged for
decoding). `jc.load(path)` reads a `.nc` file back (or a `jaxcontact run` `.npz`) as
an in-memory Dataset; `xarray.open_dataset(path)` opens the same files.
"""

from __future__ import annotations

import json
import platform
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np


if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr


SI = {"length": "m", "force": "N", "stress": "Pa", "time": "s"}
ENGINE = "h5netcdf"  # see the module docstring for the choice

# Compress the large per-cell fields (mostly zeros outside the contact).
_COMPRESS = {"zlib": True, "complevel": 4}
_COMPRESS_MIN_SIZE = 4096

# (dimension kinds, unit kind, long_name) of every `jc.Solution` field, time leading.
# A unit kind is one of SI's keys or "1" (dimensionless, a count or a flag).
_SOLUTION_FIELDS = {
    "pressure": (("time", "x", "y"), "stress", "contact pressure p (compressive >= 0)"),
    "shear": (
        ("time", "component", "x", "y"),
        "stress",
        "shear traction (q_x, q_y) on the half-space",
    ),
    "contact": (("time", "x", "y"), "1", "contact mask (p > 0)"),
    "stick": (("time", "x", "y"), "1", "stick mask (|q| < mu p)"),
    "normal_force": (("time",), "force", "normal load W"),
    "approach": (("time",), "length", "rigid-body approach delta_z (into the body)"),
    "tangential_force": (("time", "component"), "force", "tangential force (F_x, F_y)"),
    "tangential_displacement": (
        ("time", "component"),
        "length",
        "rigid tangential displacement (delta_x, delta_y)",
    ),
    "stick_ratio": (("time",), "1", "stick area / contact area"),
    "sliding": (("time",), "1", "gross sliding (contact without a stick cell)"),
    "converged": (("time",), "1", "step converged"),
    "iterations": (("time",), "1", "inner solver iterations (summed over rounds)"),
    "rounds": (("time",), "1", "normal/tangential rounds"),
    "residual": (("time",), "1", "relative contact residual"),
    "fallbacks": (("time",), "1", "secondary solvers run (jc.Fallback)"),
}
SOLUTION_VARIABLES = tuple(_SOLUTION_FIELDS) + ("result", "edge_contact")

_NORMAL_FIELDS = {
    "pressure": (("x", "y"), "stress", "contact pressure p (compressive >= 0)"),
    "gap": (("x", "y"), "length", "gap after deformation h0 + u_z - delta"),
    "contact": (("x", "y"), "1", "contact mask (p > 0)"),
    "displacement": (("x", "y"), "length", "normal surface displacement u_z"),
    "approach": ((), "length", "rigid-body approach delta (into the body)"),
    "normal_force": ((), "force", "normal load W"),
    "iterations": ((), "1", "conjugate-gradient iterations"),
    "residual": ((), "1", "relative contact residual"),
    "converged": ((), "1", "solve converged"),
    "applications": ((), "1", "operator applications (padded FFT convolutions)"),
}

_STRESS_NAMES = {
    "sxx": "normal stress sigma_xx",
    "syy": "normal stress sigma_yy",
    "szz": "normal stress sigma_zz",
    "sxy": "shear stress sigma_xy",
    "sxz": "shear stress sigma_xz",
    "syz": "shear stress sigma_yz",
    "von_mises": "von Mises equivalent stress",
    "max_shear": "maximum shear stress (s_max - s_min) / 2 (Tresca)",
}

# Units of material parameters, by field name.
_MATERIAL_UNITS = {
    "shear_modulus": "stress",
    "mu_inf": "stress",
    "mu_0": "stress",
    "g_inf": "stress",
    "g": "stress",
    "tau": "time",
    "viscosity": "stress*time",
    "poisson": "1",
}


# ---- Helpers -------------------------------------------------------------------------


def _xarray():
    try:
        import xarray as xr
    except ImportError as exc:  # pragma: no cover - a dependency
        raise ImportError(
            "to_xarray and jc.load need xarray (a dependency of jaxcontact: "
            "pip install xarray h5netcdf)"
        ) from exc
    return xr


def unit_table(units: dict | str | None) -> dict:
    """The unit labels: `{"length", "force", "time", "stress"}` -> a unit string.

    `None` or `"SI"`: m, N, s, Pa. A dict must name `length`, `force` and `time`;
    `stress` defaults to `force/length^2`.
    """
    if units is None or (isinstance(units, str) and units.upper() == "SI"):
        return dict(SI)
    if not isinstance(units, dict):
        raise TypeError(
            f"units must be None, 'SI' or a dict of unit names, got {units!r}"
        )
    missing = {"length", "force", "time"} - set(units)
    unknown = set(units) - set(SI)
    if missing or unknown:
        raise ValueError(
            "units needs the keys 'length', 'force', 'time' (and optionally 'stress'); "
            f"missing {sorted(missing)}, unknown {sorted(unknown)}"
        )
    out = {key: str(value) for key, value in units.items()}
    out.setdefault("stress", f"{out['force']}/{out['length']}^2")
    return out


def _unit(kind: str, table: dict) -> str:
    """A unit kind (`"stress"`, `"stress*time"`, `"1"`, ...) as a unit string."""
    if kind == "1":
        return "1"
    parts = [table[part] for part in kind.split("*")]
    return " ".join(parts)


def _attrs(kind: str, long_name: str, table: dict, **extra) -> dict:
    return {"units": _unit(kind, table), "long_name": long_name, **extra}


def _np(value) -> np.ndarray:
    return np.asarray(value)


def _json_value(value):
    """A JSON-ready copy of numbers, arrays and containers (arrays -> lists)."""
    if isinstance(value, dict):
        return {str(k): _json_value(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_value(v) for v in value]
    if value is None or isinstance(value, (str, bool, int, float)):
        return value
    try:
        arr = np.asarray(value)
    except Exception:  # noqa: BLE001 - anything else: its repr
        return repr(value)
    if arr.dtype == object:
        return repr(value)
    return arr.item() if arr.ndim == 0 else arr.tolist()


def _json(value) -> str:
    return json.dumps(_json_value(value), default=repr, sort_keys=True)


def versions() -> dict:
    """Versions of jaxcontact, jax, jaxlib, equinox, numpy, xarray and Python."""
    import equinox
    import jax
    import jaxlib

    from ._version import __version__

    out = {
        "jaxcontact": __version__,
        "jax": jax.__version__,
        "jaxlib": jaxlib.__version__,
        "equinox": equinox.__version__,
        "numpy": np.__version__,
        "python": platform.python_version(),
    }
    try:
        import xarray

        out["xarray"] = xarray.__version__
    except ImportError:  # pragma: no cover
        pass
    return out


def describe_material(material, table: dict | None = None) -> dict:
    """`{"type": ..., field: value, ..., "units": {field: unit}}` of a material."""
    table = unit_table(None) if table is None else table
    fields = {name: _json_value(value) for name, value in vars(material).items()}
    units = {
        name: _unit(_MATERIAL_UNITS[name], table)
        for name in fields
        if name in _MATERIAL_UNITS
    }
    return {"type": type(material).__name__, **fields, "units": units}


def describe_indenter(indenter, table: dict) -> dict:
    """A sphere's radius and centre; for a surface only its type (the heights go into
    the Dataset as `initial_gap`)."""
    from ._indenter import Sphere

    if isinstance(indenter, Sphere):
        return {
            "type": "Sphere",
            "radius": _json_value(indenter.radius),
            "centre": _json_value(indenter.centre),
            "units": table["length"],
        }
    return {"type": type(indenter).__name__}


def _program(program, times, kind_force: str, kind_length: str, table) -> Any:
    from ._loading import Force

    if program is None:
        return None
    force = isinstance(program, Force)
    return {
        "type": type(program).__name__,
        "values": _json_value(program.values(times)),
        "units": table[kind_force if force else kind_length],
    }


def describe_scene(scene, table: dict | None = None) -> dict:
    """Everything that defines `scene`, JSON-ready (loads evaluated on its times)."""
    table = unit_table(None) if table is None else table
    times = scene.times
    return {
        "grid": {
            "shape": list(scene.grid.shape),
            "size": _json_value(scene.grid.size),
            "periodic": bool(scene.grid.periodic),
            "units": table["length"],
        },
        "indenter": describe_indenter(scene.indenter, table),
        "material": describe_material(scene.material, table),
        "normal": _program(scene.normal, times, "force", "length", table),
        "x": _program(scene.x, times, "force", "length", table),
        "y": _program(scene.y, times, "force", "length", table),
        "friction": _json_value(scene.friction),
        "coupling": scene.coupling,
        "slip": scene.slip,
        "nt": int(np.shape(times)[0]),
    }


def _common_attrs(table: dict, kind: str) -> dict:
    v = versions()
    return {
        "title": f"jaxcontact {kind}",
        "source": f"jaxcontact {v['jaxcontact']}",
        "jaxcontact_version": v["jaxcontact"],
        "jax_version": v["jax"],
        "versions": _json(v),
        "unit_system": _json(table),
        "units_note": (
            "jaxcontact is unit-agnostic: the unit labels are those the caller named "
            "(to_xarray(units=...), SI by default), not a conversion"
        ),
    }


def _grid_coords(grid, table: dict) -> dict:
    return {
        "x": ("x", _np(grid.x), _attrs("length", "cell-centre x", table)),
        "y": ("y", _np(grid.y), _attrs("length", "cell-centre y", table)),
    }


def _component_coord() -> dict:
    return {
        "component": (
            "component",
            np.array(["x", "y"]),
            {"long_name": "in-plane direction"},
        )
    }


def _result_attrs() -> dict:
    from ._results import RESULTS

    items = RESULTS._name_to_item  # name -> item; item._value the integer code
    return {
        "flag_values": np.array([int(item._value) for item in items.values()],
                                np.int32),
        "flag_meanings": " ".join(items),
    }


def _encoding(ds) -> dict:
    """Compression for the large variables of `ds` (netCDF-4)."""
    return {
        name: dict(_COMPRESS)
        for name, var in ds.data_vars.items()
        if var.size >= _COMPRESS_MIN_SIZE and var.dtype.kind in "fiub"
    }


# ---- Builders ------------------------------------------------------------------------


def solution_dataset(
    sol, scene, *, units=None, solve_options: dict | None = None, batch=None,
    attrs: dict | None = None,
) -> xr.Dataset:
    """The Dataset of a `jc.Solution`: see `jc.Solution.to_xarray`."""
    xr = _xarray()
    from ._scene import Scene

    if not isinstance(scene, Scene):
        raise TypeError(
            "to_xarray needs the jc.Scene that was solved (the solution does not hold "
            f"the grid), got {type(scene).__name__}"
        )
    table = unit_table(units)
    nx, ny = scene.grid.shape
    pressure = _np(sol.pressure)
    batched = pressure.ndim == 4
    if pressure.ndim not in (3, 4) or pressure.shape[-2:] != (nx, ny):
        raise ValueError(
            f"the solution's pressure has shape {pressure.shape}: expected (nt, {nx}, "
            f"{ny}) for this scene's grid, or (batch, nt, {nx}, {ny}) for a jc.sweep"
        )
    lead = ("batch",) if batched else ()
    data_vars = {}
    for name, (dims, kind, long_name) in _SOLUTION_FIELDS.items():
        data_vars[name] = (lead + dims, _np(getattr(sol, name)),
                           _attrs(kind, long_name, table))
    data_vars["result"] = (
        lead + ("time",),
        _np(sol.result._value).astype(np.int32),
        _attrs("1", "how each step ended (jc.RESULTS)", table, **_result_attrs()),
    )
    data_vars["edge_contact"] = (
        lead + ("time",),
        _np(sol.edge_contact),
        _attrs("1", "contact reaches the outer ring of cells", table),
    )
    data_vars["initial_gap"] = (
        ("x", "y"),
        _np(scene.indenter.gap(scene.grid)),
        _attrs("length", "initial gap h0 of the indenter (its heights)", table),
    )
    coords = {**_grid_coords(scene.grid, table), **_component_coord()}
    times = _np(sol.times)
    time_attrs = _attrs("time", "time", table)
    if not batched:
        coords["time"] = ("time", times, time_attrs)
    elif np.all(times == times[:1]):
        coords["time"] = ("time", times[0], time_attrs)
    else:  # swept times: a 2-D coordinate beside the step index
        coords["times"] = (("batch", "time"), times, time_attrs)
    if batched:
        nb = pressure.shape[0]
        coords["batch"] = ("batch", np.arange(nb),
                           {"units": "1", "long_name": "batch member"})
        for key, values in (batch or {}).items():
            values = _np(values)
            if values.shape[:1] != (nb,):
                raise ValueError(
                    f"batch coordinate {key!r} needs a leading size {nb}, got shape "
                    f"{values.shape}"
                )
            kind = _MATERIAL_UNITS.get(key.split("__")[-1], "1")
            coords[key] = (("batch",)
                           + tuple(f"{key}_{i}" for i in range(values.ndim - 1)),
                           values, _attrs(kind, f"swept {key}", table))
    elif batch:
        raise ValueError("batch= labels a jc.sweep result (a leading batch axis)")
    scene_info = describe_scene(scene, table)
    out_attrs = {
        **_common_attrs(table, "solution"),
        "scene": _json(scene_info),
        "material": _json(scene_info["material"]),
        "indenter": _json(scene_info["indenter"]),
        "loads": _json({k: scene_info[k] for k in ("normal", "x", "y")}),
        "grid_shape": np.array(scene.grid.shape, np.int64),
        "grid_size": _np(scene.grid.size),
        "grid_periodic": int(scene.grid.periodic),
        "friction": float(np.asarray(scene.friction).ravel()[0])
        if np.size(scene.friction) == 1 else _json(scene.friction),
        "coupling": scene.coupling,
        "slip": scene.slip,
        "solve_options": _json(solve_options or {}),
        "dtype": str(pressure.dtype),
        "method": sol.method,
    }
    out_attrs.update(attrs or {})
    return xr.Dataset(data_vars, coords, out_attrs)


def normal_dataset(
    sol, grid, *, material=None, indenter=None, units=None, attrs: dict | None = None
) -> xr.Dataset:
    """The Dataset of a `jc.NormalSolution`: see `jc.NormalSolution.to_xarray`."""
    xr = _xarray()
    from ._grid import Grid

    if not isinstance(grid, Grid):
        raise TypeError(f"grid must be the jc.Grid that was solved, got {grid!r}")
    table = unit_table(units)
    if _np(sol.pressure).shape != grid.shape:
        raise ValueError(
            f"the solution's pressure has shape {_np(sol.pressure).shape}, the grid is "
            f"{grid.shape}"
        )
    data_vars = {
        name: (dims, _np(getattr(sol, name)), _attrs(kind, long_name, table))
        for name, (dims, kind, long_name) in _NORMAL_FIELDS.items()
    }
    data_vars["edge_contact"] = (
        (),
        _np(sol.edge_contact),
        _attrs("1", "contact reaches the outer ring of cells", table),
    )
    data_vars["result"] = (
        (),
        _np(sol.result._value).astype(np.int32),
        _attrs("1", "how the solve ended (jc.RESULTS)", table, **_result_attrs()),
    )
    out_attrs = {
        **_common_attrs(table, "normal solution"),
        "grid_shape": np.array(grid.shape, np.int64),
        "grid_size": _np(grid.size),
        "grid_periodic": int(grid.periodic),
        "dtype": str(_np(sol.pressure).dtype),
    }
    if material is not None:
        out_attrs["material"] = _json(describe_material(material, table))
    if indenter is not None:
        from ._indenter import as_indenter

        out_attrs["indenter"] = _json(describe_indenter(as_indenter(indenter), table))
    out_attrs.update(attrs or {})
    return xr.Dataset(data_vars, _grid_coords(grid, table), out_attrs)


def stress_dataset(stress, grid, *, units=None,
                   attrs: dict | None = None) -> xr.Dataset:
    """The Dataset of a subsurface `Stress`: see `Stress.to_xarray`."""
    xr = _xarray()
    from ._grid import Grid

    if not isinstance(grid, Grid):
        raise TypeError(f"grid must be the jc.Grid of the tractions, got {grid!r}")
    table = unit_table(units)
    depth = _np(stress.depth)
    dims = ("depth", "x", "y") if depth.ndim == 1 else ("x", "y")
    data_vars = {
        name: (
            dims,
            _np(getattr(stress, name)),
            _attrs("stress", long_name, table,
                   sign="tension positive, z into the body"),
        )
        for name, long_name in _STRESS_NAMES.items()
    }
    coords = {
        **_grid_coords(grid, table),
        "depth": (
            ("depth",) if depth.ndim == 1 else (),
            depth,
            _attrs("length", "depth z below the surface (into the body)", table),
        ),
    }
    out_attrs = {
        **_common_attrs(table, "subsurface stress"),
        "grid_shape": np.array(grid.shape, np.int64),
        "grid_size": _np(grid.size),
        **(attrs or {}),
    }
    return xr.Dataset(data_vars, coords, out_attrs)


def fit_dataset(fit, *, units=None, attrs: dict | None = None) -> xr.Dataset:
    """The Dataset of a `jc.PronyFit`: see `jc.PronyFit.to_xarray`."""
    xr = _xarray()
    table = unit_table(units)
    data_kind = "force" if fit.kind == "force" else "length"
    names = list(fit.parameter_names)
    n = (len(names) - 1 - int("poisson" in names)) // 2

    def by_name(values: dict, name: str):
        if name in ("g_inf", "poisson"):
            return float(np.asarray(values[name]))
        key, index = name.rsplit("_", 1)
        return float(np.asarray(values[key])[int(index) - 1])

    std = [by_name(fit.std, name) for name in names]
    gradient = [by_name(fit.gradient, name) for name in names]
    what = "force W" if fit.kind == "force" else "depth (approach delta_z)"
    data_vars = {
        "target": ("time", _np(fit.target), _attrs(data_kind, f"fitted data: {what}",
                                                    table)),
        "curve": ("time", _np(fit.curve), _attrs(data_kind, f"fitted model: {what}",
                                                  table)),
        "residual": ("time", _np(fit.residual),
                     _attrs(data_kind, "model - data", table)),
    }
    for prefix, material, label in (("", fit.material, "fitted"),
                                    ("initial_", fit.initial, "starting")):
        data_vars[prefix + "g_inf"] = ((), _np(material.g_inf), _attrs(
            "stress", f"{label} long-time shear modulus g_inf", table))
        data_vars[prefix + "g"] = ("arm", _np(material.g), _attrs(
            "stress", f"{label} arm shear moduli g_i", table))
        data_vars[prefix + "tau"] = ("arm", _np(material.tau), _attrs(
            "time", f"{label} relaxation times tau_i", table))
        data_vars[prefix + "poisson"] = ((), _np(material.poisson), _attrs(
            "1", f"{label} Poisson's ratio", table))
    # Young's moduli E = 2 G (1 + nu) at the fitted Poisson's ratio (AFM users read E).
    m = fit.material
    factor = 2 * (1 + float(np.asarray(m.poisson)))
    data_vars["E_inf"] = ((), factor * _np(m.g_inf), _attrs(
        "stress", "Young's long-time modulus E_inf = 2 (1 + nu) g_inf", table))
    data_vars["E"] = ("arm", factor * _np(m.g), _attrs(
        "stress", "Young's arm moduli E_i = 2 (1 + nu) g_i", table))
    data_vars["E_0"] = ((), factor * (_np(m.g_inf) + np.sum(_np(m.g))), _attrs(
        "stress", "instantaneous Young's modulus E_0 = E_inf + sum E_i", table))
    data_vars.update({
        "log_std": ("parameter", np.array(std),
                _attrs("1", "Gauss-Newton standard deviation of ln(parameter)", table)),
        "gradient": ("parameter", np.array(gradient),
                     _attrs("1", "d(loss) / d(ln parameter) at the result", table)),
        "covariance": (
            ("parameter", "parameter_2"),
            _np(fit.covariance),
            _attrs("1", "Gauss-Newton covariance of ln(parameters)", table),
        ),
        "loss_history": ("iteration", _np(fit.loss_history),
                         _attrs("1", "loss (mean squared relative residual)", table)),
    })
    coords = {
        "time": ("time", _np(fit.times), _attrs("time", "time", table)),
        "arm": ("arm", np.arange(1, n + 1), {"units": "1", "long_name": "Maxwell arm"}),
        "parameter": ("parameter", np.array(names), {"long_name": "parameter"}),
        "parameter_2": ("parameter_2", np.array(names), {"long_name": "parameter"}),
        "iteration": ("iteration", np.arange(len(fit.loss_history)),
                      {"units": "1", "long_name": "optimiser step"}),
    }
    out_attrs = {
        **_common_attrs(table, "Prony fit"),
        "kind": fit.kind,
        "arms": n,
        "material": _json(describe_material(fit.material, table)),
        "initial_material": _json(describe_material(fit.initial, table)),
        "loss": float(fit.loss),
        "converged": int(bool(fit.converged)),
        "solves_converged": int(bool(fit.solves_converged)),
        "message": str(fit.message),
        "optimiser": str(fit.optimiser),
        "adam_steps": int(fit.adam_steps),
        "lbfgs_steps": int(fit.lbfgs_steps),
        "lm_steps": int(fit.lm_steps),
        "evaluations": int(fit.evaluations),
        "noise": float(fit.noise),
        "noise_units": table[data_kind],
        "discretisation": float("nan") if fit.discretisation is None
        else float(fit.discretisation),
    }
    out_attrs.update(attrs or {})
    return xr.Dataset(data_vars, coords, out_attrs)


# ---- Files ---------------------------------------------------------------------------


def to_netcdf(ds, path) -> Path:
    """Write `ds` to `path` (netCDF-4, `h5netcdf`, the large variables compressed)."""
    path = Path(path)
    ds.to_netcdf(path, engine=ENGINE, encoding=_encoding(ds))
    return path


_NPZ_DIMS = {
    **{name: dims for name, (dims, _, _) in _SOLUTION_FIELDS.items()},
    "times": ("time",),
    "gap": ("x", "y"),
}


def _npz_dataset(path: Path):
    xr = _xarray()
    with np.load(path) as data:
        arrays = {key: data[key] for key in data.files}
    meta = json.loads(str(arrays.pop("metadata", "{}")))
    units = meta.get("units")
    table = dict(SI)
    if isinstance(units, dict):
        table.update({k: units[k] for k in ("length", "force", "stress", "time")
                      if k in units})
    coords = {}
    for axis in ("x", "y"):
        if axis in arrays:
            coords[axis] = (axis, arrays.pop(axis),
                            _attrs("length", f"cell-centre {axis}", table))
    if "times" in arrays:
        coords["time"] = ("time", arrays.pop("times"), _attrs("time", "time", table))
    if "shear" in arrays or "tangential_force" in arrays:
        coords.update(_component_coord())
    data_vars = {}
    for key, value in arrays.items():
        if key in _SOLUTION_FIELDS and value.ndim == len(_SOLUTION_FIELDS[key][0]):
            dims, kind, long_name = _SOLUTION_FIELDS[key]
        elif key in _NORMAL_FIELDS and value.ndim == len(_NORMAL_FIELDS[key][0]):
            dims, kind, long_name = _NORMAL_FIELDS[key]
        else:
            dims, kind, long_name = (tuple(f"{key}_{i}" for i in range(value.ndim)),
                                     "1", key)
        data_vars[key] = (dims, value, _attrs(kind, long_name, table))
    attrs = {"metadata": json.dumps(meta), "source_file": str(path)}
    return xr.Dataset(data_vars, coords, attrs)


def load(path) -> xr.Dataset:
    """Read a result file back as an `xarray.Dataset`, in memory (the file is closed).

    **Arguments:**

    - `path`: a netCDF file written by `jaxcontact run` or by
      `Dataset.to_netcdf` of a `to_xarray()` result (`.nc`), or a `jaxcontact run
      --format npz` file (`.npz`: its arrays get the same dimension names and units
      as the netCDF file; its JSON `metadata` string goes into `attrs["metadata"]`).

    **Returns:** the `xarray.Dataset`: booleans decoded back to `bool`, float32 kept,
    every attribute as written (nested values as JSON strings: `json.loads(
    ds.attrs["scene"])`).

    **Raises:** `FileNotFoundError` for a missing file; `ValueError` for a file that
    is neither netCDF nor `.npz`.
    """
    xr = _xarray()
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no such result file: {str(path)!r}")
    if path.suffix == ".npz":
        return _npz_dataset(path)
    try:
        with xr.open_dataset(path) as ds:
            return ds.load()
    except (OSError, ValueError) as exc:
        raise ValueError(
            f"{str(path)!r} is not a netCDF file that xarray can read ({exc})"
        ) from exc
