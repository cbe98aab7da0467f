"""`jc.fit_force_map` and `jaxcontact fit MAPFILE`: every curve of a force map fitted as
`jaxcontact fit` fits one file (`fit_afm_curve`), returned as a map with each curve's
status.

The committed map is afmformats 0.18.7's JPK QI test file
(`tests/data/fmt-jpk-fd_2020.02.07-16.29.05.036.jpk-qi-data`, MIT, see
tests/data/README.md): 4 force-distance curves in a row (grid indices x 0..3, y 0;
stage positions 78 nm apart), ~0.1 nN, 50-60 nm deep, 12-15 raw samples in contact on
the approach (10.7 kHz), no hold. It is fitted here at tiny settings (8^2 grid, 8
approach bins, one arm, no analysis refits, no grid check) so that each test runs in
seconds once the first fit has compiled; the defaults' numbers are in
`benchmarks/results/force_map/intel_xeon.json`.

A synthetic 2 x 2 map of the closed-form relaxation curve (tests/test_afm.py) with
its force scaled cell by cell checks the map's arithmetic: the force is linear in the
moduli, so every modulus scales with the force and the relaxation time does not.
"""

import csv
import os
import time

import numpy as np
import pytest
from test_afm import FakeCurve, synthetic_viscoelastic

import jaxcontact as jc


pytest.importorskip("xarray")

DATA = os.path.join(os.path.dirname(__file__), "data")
QI = os.path.join(DATA, "fmt-jpk-fd_2020.02.07-16.29.05.036.jpk-qi-data")
RADIUS = 5e-6  # m: an input (the file records none); 60 nm deep: depth / R ~ 0.01
TINY = dict(n=8, samples=(8, 8, 4), arms=1, analysis_uncertainty=False,
            check_grid=False)
CLI_TINY = ["--n", "8", "--samples", "8,8,4", "--arms", "1",
            "--no-analysis-uncertainty", "--no-check-grid"]
NUMBERS = ("E_0", "E_at_approach", "E_inf", "apparent_hertz_E", "g_inf",
           "contact_time", "approach_time")


def tiny(**changes):
    return jc.AFMFitSettings(radius=RADIUS, **{**TINY, **changes})


@pytest.fixture(scope="module")
def qi_map():
    """The committed map at the tiny settings: `(Dataset, reports, seconds)`."""
    pytest.importorskip("afmformats")
    start = time.perf_counter()
    ds, reports = jc.fit_force_map(QI, settings=tiny(), progress=False,
                                   return_reports=True)
    return ds, reports, time.perf_counter() - start


def report_numbers(report) -> dict:
    """The Dataset's numbers as `fit_afm_curve`'s report gives them."""
    e = report["youngs_moduli"]
    return {"E_0": e["E_0_Pa"]["value"],
            "E_at_approach": e["E_at_approach_Pa"]["value"],
            "E_inf": e["E_inf_Pa"]["value"],
            "apparent_hertz_E": report["apparent_hertz"]["E_Pa"],
            "g_inf": report["parameters"]["g_inf_Pa"]["value"],
            "contact_time": report["contact_point"]["time_s"],
            "approach_time": e["approach_time_s"]}


def test_the_committed_map_with_each_curves_status(qi_map):
    """The map's shape and positions are the file's; every curve is fitted with a
    status consistent with its report, and its moduli are physical:
    `E_inf <= E(T) <= E_0` (a Prony series relaxes; to 1e-12 relative), and where the
    model reproduces the approach within the noise ("good"), E at the approach's
    duration and the Hertz fit of that approach measure one stiffness: they agree
    within 35 % (measured 1-23 %; the curves barely relax within their 1.3 ms in
    contact). The apparent Hertz moduli at R = 5 um: 1.5-1.8 kPa (measured; +-30 %
    asserted)."""
    import afmformats

    ds, reports, seconds = qi_map
    print(f"4 curves at the tiny settings: {seconds:.1f} s, per curve "
          f"{np.round(ds.seconds.values.ravel(), 1)} s")
    raw = afmformats.load_data(QI)
    assert dict(ds.sizes) == {"y": 1, "x": 4, "arm": 1}
    assert list(ds.x.values) == [0, 1, 2, 3] and list(ds.y.values) == [0]
    for c in raw:
        cell = ds.sel(x=c.metadata["grid index x"], y=c.metadata["grid index y"])
        assert float(cell.position_x) == c.metadata["position x"]
        assert float(cell.position_y) == c.metadata["position y"]
    np.testing.assert_allclose(np.diff(ds.position_x.values[0]), 78.125e-9, rtol=1e-9)
    assert ds.attrs["curves"] == 4 and ds.attrs["fitted"] == 4
    assert ds.attrs["curve_mode"] == "relaxation" and ds.attrs["radius_m"] == RADIUS
    assert list(ds.attrs["samples"]) == [8, 8, 4] and ds.attrs["n"] == 8
    assert int((ds.flags > 0).sum()) == ds.attrs["flagged"]
    for (y, x), report in reports.items():
        cell = ds.sel(x=x, y=y)
        assert str(cell.quality.values) == report["quality"]["verdict"]
        assert int(cell.flags) == len(report["flags"])
        assert str(cell.flag_text.values) == "; ".join(report["flags"])
        assert bool(cell.converged) == report["converged"]
        if not report["converged"]:  # an unconverged fit is always flagged
            assert int(cell.flags) >= 1
            assert "not converged" in str(cell.flag_text.values)
        assert int(cell.arms) == 1 and np.isfinite(float(cell.tau[0]))
        good = str(cell.quality.values) == "good"
        assert good == (float(cell.residual_over_noise) <= 2.0)
        e0, et, einf = (float(cell[k]) for k in ("E_0", "E_at_approach", "E_inf"))
        assert einf <= et * (1 + 1e-12) and et <= e0 * (1 + 1e-12)
        hertz = float(cell.apparent_hertz_E)
        assert 1.5e3 / 1.3 < hertz < 1.8e3 * 1.3, hertz
        if good:
            assert abs(et / hertz - 1) < 0.35, (et, hertz)


def test_a_curve_of_the_map_equals_fit_afm_curve(qi_map):
    """Curve 3 of the map (x = 3) in the whole map, and alone as a map of one curve,
    gives the numbers of `fit_afm_curve` on the curve read as `jaxcontact fit` reads
    a file (`jc.read_afm(path, contact="viscoelastic")`): the same program on the
    same inputs, so equal to 1e-12 relative (measured: identical)."""
    import afmformats

    from jaxcontact.fitting.afm import fit_afm_curve

    ds, reports, _ = qi_map
    settings = tiny()
    curve = jc.read_afm(QI, index=3, contact="viscoelastic",
                        segments=settings.segments)
    direct = fit_afm_curve(curve, settings).report
    alone = jc.fit_force_map([afmformats.load_data(QI)[3]], settings=settings,
                             progress=False)
    assert dict(alone.sizes) == {"y": 1, "x": 1, "arm": 1}
    assert int(alone.x[0]) == 3
    want = report_numbers(direct)
    for got in (ds.sel(x=3, y=0), alone.isel(x=0, y=0)):
        for key in NUMBERS:
            np.testing.assert_allclose(float(got[key]), want[key], rtol=1e-12,
                                       err_msg=key)
        np.testing.assert_allclose(float(got.tau[0]),
                                   direct["parameters"]["tau_s"][0]["value"],
                                   rtol=1e-12)
        assert str(got.quality.values) == direct["quality"]["verdict"]
        assert str(got.flag_text.values) == "; ".join(direct["flags"])
        assert bool(got.converged) == direct["converged"]
    mine = {k: v for k, v in reports[(0, 3)].items() if k != "file"}
    assert report_numbers(mine) == report_numbers(direct)


def test_the_curves_of_a_map_share_one_compilation(qi_map):
    """Every curve of a map has the same bins, so after the first curve no program
    compiles again: the ring model's operator is an argument, the raw residual is
    solved at a power-of-two length, the optimisers' updates are module-level. Two
    curves of the committed map (12-15 raw samples in contact each), through
    `fit_cell` as `jc.fit_force_map` calls it, the compilations counted from JAX's
    log (`jax_log_compiles`): none for the second curve."""
    import logging

    import afmformats
    import jax

    from jaxcontact._force_map import fit_cell

    class Count(logging.Handler):
        def __init__(self):
            super().__init__(logging.DEBUG)
            self.names = []

        def emit(self, record):
            text = record.getMessage()
            if text.startswith("Finished XLA compilation of "):
                self.names.append(text.split(" in ")[0][28:])

    raw = afmformats.load_data(QI)
    curves = [jc.read_afm(raw[k], contact="viscoelastic",
                          segments=("approach", "hold")) for k in (0, 1)]
    assert curves[0].time.size != curves[1].time.size  # different raw lengths
    counter, logger = Count(), logging.getLogger("jax")
    level = logger.level
    logger.addHandler(counter)
    logger.setLevel(logging.DEBUG)
    try:
        with jax.log_compiles(True):
            first = fit_cell(curves[0], tiny())
            compiled_first = list(counter.names)
            second = fit_cell(curves[1], tiny())
    finally:
        logger.removeHandler(counter)
        logger.setLevel(level)
    assert first["report"] is not None and second["report"] is not None
    assert first["report"]["solver"] == "rings"
    assert counter.names[len(compiled_first):] == [], counter.names


def test_fit_command_on_the_map_writes_a_row_a_curve(qi_map, tmp_path, capsys):
    """`jaxcontact fit MAP`: `STEM_map.csv` with a row a curve holding the numbers of
    `jc.fit_force_map` at the same settings (to 1e-12 relative: the same pipeline),
    `STEM_map.nc` (xarray's scipy engine) that reads back the same, the PNG with
    matplotlib, a progress line a curve on stderr, and exit status 1 exactly when a
    curve is flagged; a second run without --overwrite is refused (status 2) before
    any fit."""
    import xarray as xr

    from jaxcontact._cli import main

    ds, _, _ = qi_map
    stem = "fmt-jpk-fd_2020.02.07-16.29.05.036"
    code = main(["fit", QI, "--radius", str(RADIUS), "--out", str(tmp_path)]
                + CLI_TINY)
    out, err = capsys.readouterr()
    assert code == (1 if int((ds.flags > 0).sum()) else 0), out
    assert "4 curves, a force map" in out
    assert [ln.split(":")[0] for ln in err.splitlines() if ln.startswith("[")] == [
        f"[{k}/4] x={k - 1} y=0" for k in range(1, 5)]
    with open(tmp_path / f"{stem}_map.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [(int(r["x"]), int(r["y"])) for r in rows] == [(x, 0) for x in range(4)]
    columns = {"E_0": "E_0_Pa", "E_at_approach": "E_at_approach_Pa",
               "E_inf": "E_inf_Pa", "apparent_hertz_E": "apparent_hertz_E_Pa",
               "contact_time": "contact_time_s", "approach_time": "approach_time_s"}
    for r in rows:
        cell = ds.sel(x=int(r["x"]), y=0)
        for key, column in columns.items():
            np.testing.assert_allclose(float(r[column]), float(cell[key]), rtol=1e-12,
                                       err_msg=key)
        assert int(r["flags"]) == int(cell.flags)
        assert r["quality"] == str(cell.quality.values)
        np.testing.assert_allclose(float(r["taus_s"]), float(cell.tau[0]), rtol=1e-5)
    assert (code == 1) == any(int(r["flags"]) for r in rows)
    with xr.open_dataset(tmp_path / f"{stem}_map.nc", engine="scipy") as back:
        np.testing.assert_array_equal(back.E_at_approach.values,
                                      ds.E_at_approach.values)
        assert list(back.quality.values.ravel()) == list(ds.quality.values.ravel())
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        pass
    else:
        assert (tmp_path / f"{stem}_map.png").stat().st_size > 1000
    start = time.perf_counter()
    again = main(["fit", QI, "--radius", str(RADIUS), "--out", str(tmp_path)]
                 + CLI_TINY)
    assert again == 2 and time.perf_counter() - start < 5
    assert "already holds" in capsys.readouterr().err


def scaled_map(scales):
    """The closed-form relaxation curve with its force scaled by `scales[(x, y)]`,
    with grid indices and stage positions in the metadata as afmformats gives them."""
    base = synthetic_viscoelastic()
    curves = []
    for (x, y), s in scales.items():
        cols = dict(base._c, force=s * base["force"])
        curves.append(FakeCurve(cols, dict(base.metadata, **{
            "grid index x": x, "grid index y": y,
            "position x": 1e-5 * x, "position y": -2e-5 * y})))
    return curves


SCALES = {(0, 0): 1.0, (1, 0): 2.0, (0, 1): 0.5, (1, 1): 1.5}  # (x, y) -> factor


@pytest.fixture(scope="module")
def scaled():
    """The synthetic 2 x 2 map fitted here: `(curves, settings, Dataset, stderr)`."""
    import contextlib
    import io

    curves, settings = scaled_map(SCALES), tiny(samples=(10, 15, 4))
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        ds = jc.fit_force_map(curves, 5e-6, settings=settings)
    return curves, settings, ds, err.getvalue()


def test_fit_force_map_recovers_each_cells_scale(scaled):
    """A 2 x 2 map of the closed-form relaxation curve with its force scaled by (1,
    2 / 0.5, 1.5) cell by cell (noiseless): the map on (y, x), every cell fitted,
    Young's moduli E_0, E(T), E_inf in the ratio of the scales and the relaxation
    time the same in every cell (to 1e-3: the fit's tolerance), the apparent Hertz
    modulus in that ratio to 1e-4 (a linear least-squares fit of a scaled force,
    but the depth is the travel minus the cantilever's deflection F / k, which
    scales: < 0.2 nm of 4 um at k = 100 N/m; measured 2.8e-5),
    the positions as recorded, a progress line a curve; the refusals: no curve, two
    curves at one grid position, mixed modes, a radius that disagrees with the
    settings."""
    curves, settings, ds, err = scaled
    assert sum(ln.startswith("[") and "/4] x=" in ln and " s" in ln
               for ln in err.splitlines()) == 4, err
    assert ds.g_inf.dims == ("y", "x") and ds.tau.dims == ("y", "x", "arm")
    assert list(ds.x.values) == [0, 1] and list(ds.y.values) == [0, 1]
    assert ds.attrs["curve_mode"] == "relaxation" and ds.attrs["radius_m"] == 5e-6
    assert set(np.asarray(ds.quality.values).ravel()) <= {"good", "systematic misfit"}
    ref = ds.sel(x=0, y=0)
    for (x, y), s in SCALES.items():
        cell = ds.sel(x=x, y=y)
        for key in ("E_0", "E_at_approach", "E_inf", "g_inf"):
            np.testing.assert_allclose(float(cell[key]) / float(ref[key]), s,
                                       rtol=1e-3, err_msg=key)
        np.testing.assert_allclose(float(cell.apparent_hertz_E)
                                   / float(ref.apparent_hertz_E), s, rtol=1e-4)
        np.testing.assert_allclose(float(cell.tau[0]), float(ref.tau[0]), rtol=1e-3)
        assert float(cell.position_x) == 1e-5 * x
        assert float(cell.position_y) == -2e-5 * y
    with pytest.raises(ValueError, match="share a grid position"):
        jc.fit_force_map(curves[:1] * 2, 5e-6, settings=settings)
    with pytest.raises(ValueError, match="holds no curve"):
        jc.fit_force_map([], 5e-6)
    creep = FakeCurve(curves[1]._c, dict(curves[1].metadata,
                                         **{"imaging mode": "creep-compliance"}))
    with pytest.raises(ValueError, match=r"mix modes \['creep', 'relaxation'\]"):
        jc.fit_force_map([curves[0], creep], 5e-6, settings=settings)
    with pytest.raises(ValueError, match="disagrees with settings.radius"):
        jc.fit_force_map(curves, 1e-6, settings=settings)


def test_fit_force_map_on_a_dask_cluster_gives_the_same_map(scaled):
    """The synthetic map with `client=`: each curve fitted on a worker process of a
    Dask `LocalCluster` (float64 there too: the worker copies `jax_enable_x64`) gives
    the map fitted in this process: the same program on the same inputs, so every
    number equal to 1e-12 relative (measured: identical), the same statuses."""
    distributed = pytest.importorskip("distributed")
    curves, settings, ref, _ = scaled
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as cluster, \
            distributed.Client(cluster) as client:
        ds = jc.fit_force_map(curves, 5e-6, settings=settings, client=client,
                              progress=False)
    for key in NUMBERS + ("E_0_std", "E_inf_std", "g", "tau"):
        np.testing.assert_allclose(ds[key].values, ref[key].values, rtol=1e-12,
                                   err_msg=key)
    for key in ("quality", "flags", "flag_text", "converged", "arms"):
        np.testing.assert_array_equal(ds[key].values, ref[key].values, err_msg=key)
    with pytest.raises(TypeError, match="dask.distributed.Client"):
        jc.fit_force_map(curves, 5e-6, settings=settings, client="local")


def test_a_curve_without_contact_is_reported_not_fitted(scaled):
    """A map cell whose curve has no contact (a flat force: `jc.read_afm` refuses it)
    does not stop the map: it is `"not fitted"` with one flag naming the reason and
    NaN numbers, while its neighbour is fitted as in the 2 x 2 map (to 1e-12: the
    same program); a map with no readable curve is refused, naming the reason."""
    curves, settings, ref, _ = scaled
    base = synthetic_viscoelastic()
    flat = np.full_like(base["force"], 0.4e-9)
    blank = FakeCurve(dict(base._c, force=flat), dict(base.metadata, **{
        "grid index x": 2, "grid index y": 0}))
    ds = jc.fit_force_map([curves[0], blank], 5e-6, settings=settings,
                          progress=False)
    assert list(ds.x.values) == [0, 2] and ds.attrs["fitted"] == 1
    cell = ds.sel(x=2, y=0)
    assert str(cell.quality.values) == "not fitted" and int(cell.flags) == 1
    assert "no contact" in str(cell.flag_text.values)
    assert np.isnan(float(cell.E_at_approach)) and not bool(cell.converged)
    assert ds.attrs["flagged"] == 1 + int(ref.flags.sel(x=0, y=0) > 0)
    np.testing.assert_allclose(float(ds.E_at_approach.sel(x=0, y=0)),
                               float(ref.E_at_approach.sel(x=0, y=0)), rtol=1e-12)
    with pytest.raises(ValueError, match="no curve of 'curves' could be read.*no "
                                         "contact"):
        jc.fit_force_map([blank], 5e-6, settings=settings)
