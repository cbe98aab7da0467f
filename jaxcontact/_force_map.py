"""`jc.fit_force_map`: an AFM force map (curves on a grid of positions) in, a map of
moduli, relaxation times and per-curve quality out.

Every curve goes through the pipeline of `jaxcontact fit`
(`jaxcontact.fitting.afm.fit_afm_curve`): read by `jc.read_afm` as the command reads
a file, binned, fitted for 1..3 arms, judged against its own raw noise, flagged. A map
of one curve therefore gives the numbers `jaxcontact fit` gives for that curve.

Sharing compiled programs: every curve is fitted with the same `AFMFitSettings` (the
same grid cells `n`, bins `samples`, arm counts), so the fits of later curves reuse
the programs the first one compiled. What still compiles again: a curve whose
segment has fewer raw samples than bins (fewer bins), a raw sample count not seen
before (the quality check solves the model on the raw samples), and a fit that takes
another optimiser path (e.g. Levenberg-Marquardt after an uncertified L-BFGS).
`benchmarks/force_map.py` measures it.

With a Dask `client`, each curve (an `AFMCurve`, free of afmformats) is one task:
the workers copy this process's `jax_enable_x64` and persistent compilation cache
settings (as `jc.sweep(client=...)`), and each worker process compiles (or loads)
the programs once.
"""

import dataclasses
import json
import math
import os
import sys
import time
import warnings

import numpy as np

from ._afm import import_afmformats, read_afm


# Per-cell variables of the returned Dataset, their units and meaning.
_SCALARS = {
    "E_0": ("Pa", "Young's modulus at t = 0 (instantaneous), E = 2 G (1 + nu)"),
    "E_at_approach": ("Pa", "Young's modulus E(T) at the approach's duration T"),
    "E_inf": ("Pa", "Young's modulus at t -> infinity (relaxed)"),
    "apparent_hertz_E": ("Pa", "elastic fit of the approach's raw samples in contact "
                               "(Hertz for a sphere, Sneddon for a cone), "
                               "E = E* (1 - nu^2)"),
    "g_inf": ("Pa", "shear modulus at t -> infinity"),
    "approach_time": ("s", "the approach's duration T (from the contact point)"),
    "contact_time": ("s", "the contact point's time on the file's clock"),
    "residual_over_noise": ("1", "largest RMS of model - data over the raw samples of "
                                 "a fitted segment, in units of the raw white noise "
                                 "(1: within the noise)"),
    "seconds": ("s", "wall time of this curve's fit"),
}
QUALITY_NO_CURVE = "no curve"
QUALITY_NOT_FITTED = "not fitted"


def _grid_index(metadata, axis: str, fallback: int) -> int:
    value = metadata.get(f"grid index {axis}")
    return fallback if value is None else int(value)


def _load(source):
    """`(afmformats curve objects, name)` of a path or a sequence of curves."""
    if isinstance(source, (str, os.PathLike)):
        path = os.fspath(source)
        if not os.path.exists(path):
            raise ValueError(f"no such file: {path!r}")
        afm = import_afmformats()
        missing = getattr(getattr(afm, "errors", None), "MissingMetaDataError",
                          Exception)  # a BaseException in afmformats 0.18
        try:
            raw = list(afm.load_data(path))
        except (Exception, missing) as exc:
            raise ValueError(f"afmformats cannot read {path!r}: {exc}") from exc
        return raw, path
    return list(source), "curves"


def portable(curve):
    """`curve` (an `AFMCurve`) with its metadata made plain for pickling (a Dask
    task): afmformats' lazy values evaluated, anything else that does not pickle
    replaced by its text. The fit does not read the metadata."""
    import pickle

    meta = {}
    for key, value in curve.metadata.items():
        if type(value).__name__ == "LazyMetaValue" and callable(value):
            value = value()
        try:
            pickle.dumps(value)
        except Exception:
            value = str(value)
        meta[key] = value
    return dataclasses.replace(curve, metadata=meta)


def _jax_settings() -> dict:
    """This process's JAX settings that a Dask worker copies (x64, compilation
    cache)."""
    from ._sweep_dask import worker_settings

    return worker_settings()


def fit_cell(curve, settings, jax_settings=None) -> dict:
    """Fit one `AFMCurve` by `fit_afm_curve` (a task of `fit_force_map`, picklable,
    run here or on a Dask worker). `jax_settings`: `jax.config` values to apply
    first (a worker starts in float32).

    **Returns:** `{"report": the fit's report (None if it failed), "error": the
    `ValueError`'s text (None if it did not), "warnings": [texts], "seconds": wall
    time [s]}`."""
    if jax_settings:
        from ._sweep_dask import apply_settings

        apply_settings(jax_settings)
    from .fitting.afm import fit_afm_curve

    start = time.perf_counter()
    report, error = None, None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            report = fit_afm_curve(curve, settings).report
        except ValueError as exc:
            error = str(exc)
    return {"report": report, "error": error, "seconds": time.perf_counter() - start,
            "warnings": [f"{w.category.__name__}: {w.message}" for w in caught
                         if issubclass(w.category, UserWarning)]}


def _cell_values(report) -> dict:
    """The Dataset's per-cell numbers from one `fit_afm_curve` report."""
    e = report["youngs_moduli"]
    p = report["parameters"]

    def std(entry):  # None: not finite (the data do not determine it)
        return math.inf if entry["std"] is None else float(entry["std"])

    out = {"quality": report["quality"]["verdict"], "flags": len(report["flags"]),
           "flag_text": "; ".join(report["flags"]),
           "converged": bool(report["converged"]), "arms": int(report["arms"]),
           "apparent_hertz_E": float(report["apparent_hertz"]["E_Pa"]),
           "approach_time": float(e["approach_time_s"]),
           "contact_time": float(report["contact_point"]["time_s"]),
           "g_inf": float(p["g_inf_Pa"]["value"]), "g_inf_std": std(p["g_inf_Pa"]),
           "g": [float(v["value"]) for v in p["g_Pa"]],
           "g_std": [std(v) for v in p["g_Pa"]],
           "tau": [float(v["value"]) for v in p["tau_s"]],
           "tau_std": [std(v) for v in p["tau_s"]],
           "residual_over_noise": max(
               report["residual_over_noise_raw"].values(), default=math.nan)}
    for key in ("E_0", "E_at_approach", "E_inf"):
        out[key] = float(e[f"{key}_Pa"]["value"])
        out[f"{key}_std"] = std(e[f"{key}_Pa"])
    return out


def _progress_line(k, n, ix, iy, result) -> str:
    head = f"[{k}/{n}] x={ix} y={iy}: "
    if result["report"] is None:
        return head + f"{QUALITY_NOT_FITTED} ({result['error']}), " \
                      f"{result['seconds']:.1f} s"
    r = result["report"]
    e = r["youngs_moduli"]["E_at_approach_Pa"]["value"]
    flags = len(r["flags"])
    return (head + f"{r['quality']['verdict']}, E(T) = {e:.4g} Pa, "
            + (f"{flags} flag(s)" if flags else "no flags")
            + f", {result['seconds']:.1f} s")


def _settings_attrs(settings, baseline, contact) -> dict:
    s = dataclasses.asdict(settings)
    # netCDF attributes hold no None: the tip's own parameters only
    tip = {k: v for k, v in settings.probe.parameters().items() if k != "shape"}
    return {"tip": settings.tip, **tip, "poisson": float(settings.poisson),
            "n": int(settings.n), "arms": str(settings.arms),
            "samples": np.asarray(settings.samples, np.int64),
            "segments": ",".join(settings.segments),
            "tau_bounds": json.dumps(s["tau_bounds"]), "start": settings.start,
            "steps": int(settings.steps), "check_grid": int(settings.check_grid),
            "analysis_uncertainty": int(settings.analysis_uncertainty),
            "solver": settings.solver, "rings": int(settings.rings),
            "baseline": baseline, "contact": contact,
            "settings_json": json.dumps({**s, "baseline": baseline,
                                         "contact": contact}, default=list)}


def fit_force_map(source, radius=None, *, settings=None, client=None,
                  progress=True, baseline="constant", contact="viscoelastic",
                  return_reports=False):
    """Fit every curve of an AFM force map as `jaxcontact fit` fits one file, and
    return the results as a map.

    **Main arguments:**

    - `source`: a path to a multi-curve file that `afmformats` reads (a JPK
      `.jpk-force-map` or `.jpk-qi-data`, ...), or a sequence of afmformats curve
      objects (e.g. `afmformats.load_data(path)`).
    - `radius`: the probe (sphere) radius [m]; absolute moduli scale as
      `radius^(-1/2)`, relaxation times and modulus ratios do not depend on it. May
      be left out when `settings` gives it (and must be, for a cone).
    - `settings`: a `jc.AFMFitSettings` (default `AFMFitSettings(radius=radius)`:
      the command line's defaults), shared by every curve; a conical probe:
      `AFMFitSettings(tip="cone", half_angle=...)` (radians; moduli scale as
      `1 / tan(half_angle)`), whose exponent (2) the contact points use too. Its
      `segments` must suit the file: the default `("approach", "hold")` fits a
      force-distance curve's approach alone (it has no hold); `("approach",
      "retract")` adds the unloading up to the loss of contact.

    **Other arguments:**

    - `client`: a `dask.distributed.Client`: each curve is fitted on a worker
      (`fit_cell`, one task a curve; same results as here).
    - `progress`: print one line per curve to stderr, `[k/N] x=.. y=..: quality,
      E(T) = .. Pa, flags, seconds` (in the order the fits finish).
    - `baseline`, `contact`: the contact point's baseline and method, as
      `jc.read_afm` (the command line's defaults).
    - `return_reports`: also return `{(y, x): report}`, the full `fit_afm_curve`
      report of each fitted curve (the JSON `jaxcontact fit` writes).

    Run with `jax.config.update("jax_enable_x64", True)`, as `jaxcontact fit` does,
    for its numbers (float32 fits are coarser).

    **Returns:** an `xarray.Dataset` on the map's grid indices `y`, `x` (as the file
    records them; the curve's index along `x` where absent) and `arm` (the largest
    arm count fitted; NaN beyond a curve's own count):

    - `quality` (str): the verdict, `"good"` or `"systematic misfit"`;
      `"not fitted"` for a curve that could not be read or fitted (no contact, too
      few samples: the reason in `flag_text`), `"no curve"` for a grid position
      without a curve;
    - `flags` (int): number of flags (a curve not fitted counts 1), `flag_text`
      (str, "; "-joined); `converged` (bool), `arms` (int, 0 where not fitted);
    - `E_0`, `E_at_approach`, `E_inf` [Pa]: Young's moduli `E = 2 G (1 + nu)` at
      t = 0, at the approach's duration `approach_time` [s] and relaxed, each with
      `<name>_std` [Pa] (the report's total standard deviation; inf where the data
      do not determine it); `apparent_hertz_E` [Pa];
    - `g_inf`, `g` [Pa], `tau` [s] (shear Prony series; `g`, `tau` on `arm`), with
      `_std`; `residual_over_noise` [1]; `contact_time` [s, the file's clock];
      `position_x`, `position_y` [m] (the stage positions the file records, NaN
      where absent); `seconds` [s]: each fit's wall time.

    Missing numbers are NaN. Attributes: the settings (`tip`, then `radius_m` for a
    sphere or `half_angle_rad` and `half_angle_deg` for a cone, `poisson`, `n`,
    `arms`, `samples`, `segments`, `tau_bounds`, ..., `baseline`, `contact`,
    `settings_json`), `curve_mode` (creep or relaxation; not `mode`, which scipy's
    netCDF writer reserves), `source`, `curves` (the number of curves), `fitted`,
    `flagged` (the number of curves with a flag, a curve not fitted included).

    **Raises:** `ValueError` for a file afmformats cannot read or without curves,
    curves of different modes (creep and relaxation), two curves at one grid
    position, no curve that `jc.read_afm` can read (the first reason named), or
    `radius` disagreeing with `settings.radius` (or given with a cone's settings);
    `ImportError` without afmformats / xarray (or dask with `client`).
    """
    import xarray as xr

    from .fitting.afm import AFMFitSettings

    # -- Settings ----------------------------------------------------------------------
    if settings is None:
        if radius is None:
            raise ValueError("fit_force_map: give radius [m] (a sphere) or settings "
                             "(a cone: AFMFitSettings(tip='cone', half_angle=...))")
        settings = AFMFitSettings(radius=radius)
    elif not isinstance(settings, AFMFitSettings):
        raise TypeError(f"fit_force_map: settings must be a jc.AFMFitSettings, got "
                        f"{type(settings).__name__}")
    elif radius is not None and settings.tip != "sphere":
        raise ValueError(f"fit_force_map: radius={radius!r} is a sphere's, but the "
                         f"settings describe a {settings.probe.text()}: leave radius "
                         "out")
    elif radius is not None and float(radius) != float(settings.radius):
        raise ValueError(f"fit_force_map: radius={radius!r} disagrees with "
                         f"settings.radius={settings.radius!r}")
    if client is not None:
        from ._sweep_dask import check_client

        check_client(client, None, "jc.fit_force_map")

    # -- The curves --------------------------------------------------------------------
    raw, name = _load(source)
    if not raw:
        raise ValueError(f"fit_force_map: {name!r} holds no curve")
    ix = [_grid_index(c.metadata, "x", i) for i, c in enumerate(raw)]
    iy = [_grid_index(c.metadata, "y", 0) for c in raw]
    seen = {}
    for k, pos in enumerate(zip(ix, iy, strict=True)):
        if pos in seen:
            raise ValueError(f"fit_force_map: two curves share a grid position: "
                             f"curves {seen[pos]} and {k} at x={pos[0]}, y={pos[1]}")
        seen[pos] = k
    curves, read_errors = [], {}
    for k, c in enumerate(raw):
        try:
            curves.append(read_afm(c, contact=contact, baseline=baseline,
                                   segments=settings.segments,
                                   exponent=settings.probe.exponent))
        except ValueError as exc:  # no contact, no approach: this curve only
            curves.append(None)
            read_errors[k] = f"jc.read_afm: {exc}"
    read = [c for c in curves if c is not None]
    if not read:
        raise ValueError(f"fit_force_map: no curve of {name!r} could be read "
                         f"(curve 0: {read_errors[0]})")
    modes = {c.mode for c in read}
    if len(modes) != 1:
        raise ValueError(f"fit_force_map: the curves mix modes {sorted(modes)} (one "
                         "map is fitted in one mode)")

    # -- The fits ----------------------------------------------------------------------
    n = len(raw)
    results = [None] * n
    todo = [k for k in range(n) if curves[k] is not None]
    done, started = 0, time.perf_counter()

    def finished(k, result):
        nonlocal done
        results[k] = result
        done += 1
        if progress:
            elapsed = time.perf_counter() - started
            # the remaining curves at the mean rate so far (the first curve's
            # compilation included: an overestimate early on)
            eta = elapsed / done * (n - done)
            print(_progress_line(done, n, ix[k], iy[k], result)
                  + f" [{elapsed:.0f} s elapsed, ~{eta:.0f} s left]", file=sys.stderr,
                  flush=True)

    for k, text in read_errors.items():
        finished(k, {"report": None, "error": text, "seconds": 0.0, "warnings": []})
    if client is None:
        for k in todo:
            finished(k, fit_cell(curves[k], settings))
            curves[k] = None  # its raw columns are no longer needed
    else:
        import distributed

        jax_settings = _jax_settings()
        futures = {client.submit(fit_cell, portable(curves[k]), settings,
                                 jax_settings, pure=False): k for k in todo}
        for future in distributed.as_completed(list(futures)):
            finished(futures[future], future.result())

    # -- The map -----------------------------------------------------------------------
    xs, ys = sorted(set(ix)), sorted(set(iy))
    shape = (len(ys), len(xs))
    values = [None if r["report"] is None else _cell_values(r["report"])
              for r in results]
    arms = max([v["arms"] for v in values if v is not None], default=1)
    data = {key: np.full(shape, np.nan) for key in _SCALARS}
    for key in ("E_0", "E_at_approach", "E_inf", "g_inf"):
        data[f"{key}_std"] = np.full(shape, np.nan)
    for key in ("g", "tau", "g_std", "tau_std"):
        data[key] = np.full(shape + (arms,), np.nan)
    data.update(position_x=np.full(shape, np.nan), position_y=np.full(shape, np.nan))
    quality = np.full(shape, QUALITY_NO_CURVE, dtype=object)
    flag_text = np.full(shape, "", dtype=object)
    flags = np.zeros(shape, np.int64)
    arm_count = np.zeros(shape, np.int64)
    converged = np.zeros(shape, bool)
    reports, warned = {}, []
    for k in range(n):
        j, i = ys.index(iy[k]), xs.index(ix[k])
        meta = raw[k].metadata
        data["position_x"][j, i] = meta.get("position x", np.nan)
        data["position_y"][j, i] = meta.get("position y", np.nan)
        data["seconds"][j, i] = results[k]["seconds"]
        warned += [f"x={ix[k]} y={iy[k]}: {w}" for w in results[k]["warnings"]]
        v = values[k]
        if v is None:
            quality[j, i] = QUALITY_NOT_FITTED
            flag_text[j, i] = results[k]["error"]
            flags[j, i] = 1
            continue
        reports[(iy[k], ix[k])] = results[k]["report"]
        quality[j, i], flag_text[j, i] = v["quality"], v["flag_text"]
        flags[j, i], arm_count[j, i] = v["flags"], v["arms"]
        converged[j, i] = v["converged"]
        for key in data:
            if key in v and key not in ("seconds",):
                target = data[key][j, i]
                if np.ndim(target):
                    target[: len(v[key])] = v[key]
                else:
                    data[key][j, i] = v[key]
    if warned:
        warnings.warn(f"fit_force_map: {len(warned)} warning(s) from the fits, e.g. "
                      f"{warned[0]} (the flags of each curve say the same)",
                      UserWarning, stacklevel=2)

    dims, arm = ("y", "x"), ("y", "x", "arm")
    units = {k: u for k, (u, _) in _SCALARS.items()}
    units.update({f"{k}_std": "Pa" for k in ("E_0", "E_at_approach", "E_inf",
                                            "g_inf")},
                 g="Pa", g_std="Pa", tau="s", tau_std="s", position_x="m",
                 position_y="m")
    variables = {}
    for key, value in data.items():
        attrs = {"units": units[key]}
        if key in _SCALARS:
            attrs["long_name"] = _SCALARS[key][1]
        variables[key] = (arm if value.ndim == 3 else dims, value, attrs)
    variables.update(
        quality=(dims, quality.astype(str), {"long_name": "quality verdict"}),
        flags=(dims, flags, {"long_name": "number of flags (0: nothing flagged)"}),
        flag_text=(dims, flag_text.astype(str),
                   {"long_name": "the flags, '; '-joined"}),
        converged=(dims, converged),
        arms=(dims, arm_count, {"long_name": "Prony arms fitted"}),
    )
    fitted = int(sum(v is not None for v in values))
    ds = xr.Dataset(
        variables,
        coords={"y": ys, "x": xs, "arm": np.arange(1, arms + 1)},
        attrs={**_settings_attrs(settings, baseline, contact),
               "curve_mode": next(iter(modes)), "source": str(name), "curves": n,
               "fitted": fitted, "flagged": int((flags > 0).sum())},
    )
    return (ds, reports) if return_reports else ds
