"""The command-line tool: `jaxcontact presets`, `jaxcontact run PRESET_OR_FILE`.

Called in-process through `main([...])` (exit status returned) at tiny sizes; one
subprocess call checks the real exit status of `python -m jaxcontact`. The zener runs
(preset and scene file: n = 24, 7 time points) share one compiled program; the CLI's
progress report (`jc.solve(progress=True)`) makes it a different one from
tests/test_presets.py's.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import jax
import numpy as np
import pytest

import jaxcontact as jc
from jaxcontact._cli import SOLUTION_FIELDS, main


ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "ramp_to_sliding.toml"

# A scene file that describes exactly the `zener` preset at n = 24, 7 time points.
ZENER_TOML = """
name = "zener_file"
[grid]
shape = [24, 24]
size = {size!r}
[indenter]
type = "sphere"
radius = 10e-3
[material]
type = "zener"
mu_inf = 1.93e6
mu_0 = 482500.0
tau = 0.01
poisson = 0.3
[time]
end = 0.03
steps = 7
[normal]
force = 0.15
[contact]
slip = "total"
"""


def _zener_toml(path):
    size = float(jc.presets.zener(n=24, steps=7).grid.size[0])
    path.write_text(ZENER_TOML.format(size=size))
    return path


def _load(path):
    """(arrays, metadata) of a `run` result: `.nc` (the default) or `.npz`."""
    path = Path(path)
    if path.suffix == ".npz":
        data = np.load(path)
        return {k: data[k] for k in data.files}, json.loads(str(data["metadata"]))
    ds = jc.load(path)
    arrays = {name: ds[name].values for name in ds.data_vars}
    arrays.update(x=ds["x"].values, y=ds["y"].values)
    if "time" in ds.coords:
        arrays["times"] = ds["time"].values
    return arrays, json.loads(ds.attrs["metadata"])


def test_presets_lists_every_preset(capsys):
    assert main(["presets"]) == 0
    out = capsys.readouterr().out
    for name, text in jc.presets.available().items():
        assert name in out and text in out


def test_run_hertz_prints_the_comparison_and_writes_results(tmp_path, capsys):
    assert main(["run", "hertz", "--n", "16", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    for row in ("contact radius a [m]", "peak pressure p0 [Pa]", "approach delta [m]"):
        assert row in out
    assert "float64" in out
    arrays, meta = _load(tmp_path / "hertz.nc")
    assert (tmp_path / "hertz.png").stat().st_size > 0
    assert meta["preset"] == "hertz" and meta["parameters"]["n"] == 16
    assert meta["units"] and meta["versions"]["jax"] == jax.__version__
    # Load balance: the pressure integrates to W = 0.15 N (solver rtol 1e-8).
    cell = (float(meta["size"]) / 16) ** 2
    np.testing.assert_allclose(arrays["pressure"].sum() * cell, 0.15, rtol=1e-7)
    # 16 cells over 4 a: the approach is Hertz's within 3% (coarse grid).
    np.testing.assert_allclose(
        arrays["approach"], jc.presets.table2_hertz().approach, rtol=3e-2
    )


def test_run_hertz_float32(tmp_path, capsys):
    assert main(["run", "hertz", "--n", "16", "--float32", "--out", str(tmp_path)]) == 0
    assert "float32" in capsys.readouterr().out
    arrays, meta = _load(tmp_path / "hertz.nc")
    assert arrays["pressure"].dtype == np.float32 and meta["dtype"] == "float32"
    cell = (float(meta["size"]) / 16) ** 2
    np.testing.assert_allclose(arrays["pressure"].sum() * cell, 0.15, rtol=1e-4)


def test_run_preset_writes_netcdf_metadata_and_plots(tmp_path, capsys):
    argv = ["run", "zener", "--n", "24", "--steps", "7", "--progress", "--no-cache",
            "--out", str(tmp_path)]
    assert main(argv) == 0
    captured = capsys.readouterr()
    out = captured.out
    assert "7/7 steps converged" in out
    assert "step" in out and "stick" in out  # the per-step table at the end
    # Live progress on stderr as the steps complete: the first and the last step.
    assert "jaxcontact: step 1/7" in captured.err
    assert "jaxcontact: step 7/7" in captured.err
    arrays, meta = _load(tmp_path / "zener.nc")
    assert meta["preset"] == "zener"
    assert meta["parameters"]["n"] == 24 and meta["parameters"]["steps"] == 7
    assert meta["parameters"]["ratio"] == 4.0
    assert meta["units"]["pressure"] == "Pa" and meta["converged"] is True
    assert set(meta["versions"]) >= {"jaxcontact", "jax", "numpy", "python"}
    assert arrays["pressure"].shape == (7, 24, 24)
    assert arrays["shear"].shape == (7, 2, 24, 24)
    assert arrays["times"].shape == (7,) and arrays["x"].shape == (24,)
    # Load balance at every step.
    np.testing.assert_allclose(arrays["normal_force"], 0.15, rtol=1e-7)
    for name in ("profiles", "history"):
        assert (tmp_path / f"zener_{name}.png").stat().st_size > 0
    # The netCDF file opens with plain xarray: named dimensions, units, the scene.
    import xarray as xr

    with xr.open_dataset(tmp_path / "zener.nc") as ds:
        assert ds["pressure"].dims == ("time", "x", "y")
        assert ds["shear"].dims == ("time", "component", "x", "y")
        assert (ds["pressure"].attrs["units"] == "Pa"
                and ds["time"].attrs["units"] == "s")
        assert json.loads(ds.attrs["scene"])["material"]["type"] == "Zener"
        assert ds.attrs["name"] == "zener"
    # --format npz: the same fields as plain arrays, equal to the netCDF file's.
    npz_out = tmp_path / "npz"
    assert main(argv[:-1] + [str(npz_out), "--format", "npz"]) == 0
    assert not (npz_out / "zener.nc").exists()
    plain, plain_meta = _load(npz_out / "zener.npz")
    assert plain_meta["preset"] == "zener"
    for name in SOLUTION_FIELDS + ("x", "y"):
        np.testing.assert_array_equal(plain[name], arrays[name], err_msg=name)
    # jc.load reads the npz as a Dataset with the same dimension names.
    loaded = jc.load(npz_out / "zener.npz")
    assert loaded["shear"].dims == ("time", "component", "x", "y")
    np.testing.assert_array_equal(loaded["pressure"].values, arrays["pressure"])
    assert json.loads(loaded.attrs["metadata"])["preset"] == "zener"


def test_scene_file_equals_the_preset_it_describes(tmp_path, capsys):
    # The same scene through the TOML parser and through the preset: same solution.
    path = _zener_toml(tmp_path / "zener.toml")
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out)]) == 0
    from_file, meta = _load(out / "zener_file.nc")
    assert meta["scene_file"] == str(path)
    assert meta["scene"]["material"]["type"] == "zener"
    assert main(["run", "zener", "--n", "24", "--steps", "7", "--out", str(out)]) == 0
    preset, _ = _load(out / "zener.nc")
    np.testing.assert_allclose(from_file["approach"], preset["approach"], rtol=1e-12)
    np.testing.assert_allclose(
        from_file["pressure"],
        preset["pressure"],
        rtol=0,
        atol=1e-9 * preset["pressure"].max(),
    )


def test_example_scene_file_parses_with_overrides():
    scene, options = jc.presets.from_toml(EXAMPLE)
    assert scene.grid.shape == (64, 64) and scene.times.shape == (41,)
    assert isinstance(scene.material, jc.Zener) and scene.coupling == "full"
    np.testing.assert_allclose(scene.x.values(scene.times)[-1], 20e-6)
    np.testing.assert_allclose(scene.x.values(scene.times)[20], 10e-6)  # linear ramp
    assert options == {"rtol": 1e-8}
    small, _ = jc.presets.from_toml(EXAMPLE, n=16, steps=5)
    assert small.grid.shape == (16, 16) and small.times.shape == (5,)


@pytest.mark.parametrize(
    "body, message",
    [
        ("grid = [", "malformed TOML"),
        (ZENER_TOML.replace("poisson = 0.3", "poisson = 0.7"), "poisson"),
        (ZENER_TOML.replace("tau = 0.01", "tau = -1.0"), "tau"),
        (ZENER_TOML.replace("poisson = 0.3", "poisson = 0.3\ncolour = 1"), "colour"),
        (ZENER_TOML.replace('type = "zener"', 'type = "steel"'), "steel"),
        (ZENER_TOML.replace('type = "sphere"', 'type = "cone"'), "cone"),
        (
            ZENER_TOML.replace("force = 0.15", "force = [0.1, 0.2]"),
            "one value per time",
        ),
        (ZENER_TOML.replace("force = 0.15", 'force = "heavy"'), "heavy"),
        (
            ZENER_TOML.replace("force = 0.15", "force = 0.15\ndisplacement = 1e-6"),
            "exactly one key",
        ),
        (ZENER_TOML.replace("[normal]\nforce = 0.15", ""), r"missing \[normal\]"),
        (ZENER_TOML.replace('slip = "total"', 'slip = "some"'), "slip"),
        (ZENER_TOML + "\n[extra]\na = 1\n", "extra"),
        (ZENER_TOML.replace("steps = 7", "steps = 0"), "steps"),
        # Wrong types (issue 31): each named with its table and value, exit 2.
        (ZENER_TOML.replace("shape = [24, 24]", 'shape = "big"'),
         "[grid] shape must be [nx, ny], got 'big'"),
        (ZENER_TOML.replace("end = 0.03\nsteps = 7", 'times = [0.0, "a"]'),
         "[time] times must be a number or a list of numbers, got [0.0, 'a']"),
        (ZENER_TOML.replace("force = 0.15", "force = {{t = [0, 1], value = [0, 'a']}}"),
         "[normal] force.value must be a number or a list of numbers"),
        (ZENER_TOML.replace("radius = 10e-3", 'radius = "x"'), "radius"),
        (ZENER_TOML.replace('slip = "total"', 'friction = "high"'), "'high'"),
        (ZENER_TOML.replace("[grid]", "grid = 3\n[other]"), "['other']"),
        (ZENER_TOML.replace("[time]\nend = 0.03\nsteps = 7\n", ""),
         "missing [time] table"),
        ("material = 3\n" + ZENER_TOML.replace(
            '[material]\ntype = "zener"\nmu_inf = 1.93e6\nmu_0 = 482500.0\n'
            'tau = 0.01\npoisson = 0.3\n', ""),
         "[material] must be a table, got 3"),
    ],
)
def test_bad_scene_file_exits_2_naming_the_problem(tmp_path, capsys, body, message):
    path = tmp_path / "bad.toml"
    path.write_text(body.format(size=3e-3) if "{size" in body else body)
    assert main(["run", str(path), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "bad.toml" in err
    assert message.replace("\\", "") in err or pytest.fail(err)


@pytest.mark.parametrize(
    "argv, message",
    [
        (["run", "nope"], "unknown preset 'nope'"),
        (["run", "missing.toml"], "does not exist"),
        (["run", "zener", "--n", "1"], "--n must be >= 2, got 1"),
        (["run", "zener", "--steps", "0"], "--steps must be >= 1, got 0"),
        (["run", "zener", "--param", "ratio=0.5"], "ratio"),
        (["run", "zener", "--param", "colour=1"], "colour"),
        (["run", "zener", "--param", "ratio"], "KEY=VALUE"),
        (["run", "hertz", "--steps", "3"], "one load step"),
        (["run", "weichert", "--param", "material=steel"], "steel"),
        (["run"], "PRESET_OR_SCENE_FILE"),
        (["run", "zener", "--n", "many"], "invalid int value"),
    ],
)
def test_bad_arguments_exit_2_naming_the_problem(tmp_path, capsys, argv, message):
    assert main([*argv, "--out", str(tmp_path)] if len(argv) > 1 else argv) == 2
    assert message in capsys.readouterr().err


def test_module_exit_status_is_2_for_an_unknown_preset(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "jaxcontact",
            "run",
            "no_such_preset",
            "--out",
            str(tmp_path),
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert proc.returncode == 2
    assert "unknown preset 'no_such_preset'" in proc.stderr


@pytest.mark.slow
def test_run_example_scene_file(tmp_path, capsys):
    argv = ["run", str(EXAMPLE), "--n", "24", "--steps", "9", "--out", str(tmp_path)]
    assert main(argv) == 0
    arrays, meta = _load(tmp_path / "ramp_to_sliding.nc")
    assert meta["scene_summary"]["coupling"] == "full"
    fx, w = arrays["tangential_force"][:, 0], arrays["normal_force"]
    np.testing.assert_allclose(w, 0.15, rtol=1e-7)
    assert (np.abs(fx) <= 0.3 * w * (1 + 1e-6)).all()  # Coulomb bound on the total
    assert np.all(np.diff(np.asarray(arrays["stick_ratio"][1:])) <= 1e-12)  # shrinking
    assert (tmp_path / "ramp_to_sliding_stick.png").stat().st_size > 0


# ---- Output names and the output folder (issue 31, items 5 and 10) -------------------

# The smallest scene file: elastic Hertz contact on 8 x 8 cells, one time point.
TINY_TOML = """
name = {name}
[grid]
shape = [8, 8]
size = 4e-3
[indenter]
type = "sphere"
radius = 10e-3
[material]
type = "elastic"
shear_modulus = 1.93e6
poisson = 0.3
[time]
times = [0.0]
[normal]
force = 0.15
"""


def _tiny(path, name='"tiny"'):
    path.write_text(TINY_TOML.format(name=name))
    return path


@pytest.mark.parametrize(
    "name", ['"../escaped"', '"sub/evil"', '"/abs/evil"', '".."', '""', '"a\\\\b"', "3"]
)
def test_scene_name_must_stay_inside_the_output_folder(tmp_path, capsys, name):
    # Before: "../escaped" wrote escaped.npz and PNGs beside --out and exited 0;
    # "sub/evil" crashed with a traceback after the solve.
    scene_file = _tiny(tmp_path / "scene.toml", name)
    out = tmp_path / "a" / "out"
    assert main(["run", str(scene_file), "--out", str(out)]) == 2
    captured = capsys.readouterr()
    shown = repr(eval(name))  # the name as the message quotes it
    assert f"name {shown}" in captured.err, captured.err
    assert "solving" not in captured.out  # refused before the solve
    written = sorted(
        str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*") if p.is_file()
    )
    assert written == ["scene.toml"]


def test_out_that_is_a_file_exits_2_before_the_solve(tmp_path, capsys):
    target = tmp_path / "results.txt"
    target.write_text("not a folder")
    for out in (target, target / "deeper"):
        assert main(["run", "hertz", "--n", "8", "--out", str(out)]) == 2
        captured = capsys.readouterr()
        assert captured.out == ""  # nothing solved, nothing printed
        assert str(target) in captured.err
        assert "not a directory" in captured.err
    assert target.read_text() == "not a folder"


def test_unwritable_out_exits_2_before_the_solve(tmp_path, capsys):
    if os.geteuid() == 0:  # root ignores permissions: use a read-only mount instead
        out = Path("/sys/jaxcontact-test-out")
        try:
            out.mkdir()
        except OSError:
            pass
        else:  # pragma: no cover - /sys writable here: no read-only folder to test
            out.rmdir()
            pytest.skip("no read-only folder available to root")
    else:
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o555)
        out = locked / "out"
    assert main(["run", "hertz", "--n", "8", "--out", str(out)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert f"--out {str(out)!r} is not a writable directory" in captured.err


def test_existing_outputs_are_kept_unless_overwrite(tmp_path, capsys):
    scene_file = _tiny(tmp_path / "scene.toml")
    out = tmp_path / "out"
    out.mkdir()
    (out / "tiny.nc").write_bytes(b"an earlier result")
    assert main(["run", str(scene_file), "--out", str(out)]) == 2
    captured = capsys.readouterr()
    assert "already holds tiny.nc: pass --overwrite" in captured.err
    assert "solving" not in captured.out
    assert (out / "tiny.nc").read_bytes() == b"an earlier result"
    # --overwrite replaces it with the new result (load balance 0.15 N to 1e-7).
    assert main(["run", str(scene_file), "--out", str(out), "--overwrite"]) == 0
    arrays, meta = _load(out / "tiny.nc")
    assert meta["scene"]["name"] == "tiny"
    np.testing.assert_allclose(arrays["normal_force"], [0.15], rtol=1e-7)


# ---- Scene files: a height-field indenter (issue 31, Deliver 3) ----------------------


def _surface_toml(folder, file_line, extra=""):
    body = TINY_TOML.format(name='"surf"').replace(
        'type = "sphere"\nradius = 10e-3', f'type = "surface"\n{file_line}{extra}'
    )
    path = folder / "surf.toml"
    path.write_text(body)
    return path


def _sphere_gap():
    grid = jc.Grid((8, 8), 4e-3)
    return np.asarray(jc.Sphere(10e-3).gap(grid))


def test_scene_file_surface_from_a_height_file(tmp_path, capsys, monkeypatch):
    # The sphere's own gap, stored in micrometres beside the scene file and read with
    # scale = 1e-6: the same scene as TINY_TOML's sphere (relative to the scene file's
    # folder, not to the working directory).
    folder = tmp_path / "scenes"
    folder.mkdir()
    np.save(folder / "heights.npy", _sphere_gap() * 1e6)
    np.savetxt(folder / "heights.csv", _sphere_gap() * 1e6, delimiter=",")
    monkeypatch.chdir(tmp_path)
    for name in ("heights.npy", "heights.csv"):
        path = _surface_toml(folder, f'file = "{name}"', "\nscale = 1e-6")
        scene, _ = jc.presets.from_toml(path)
        assert isinstance(scene.indenter, jc.Surface)
        np.testing.assert_allclose(scene.indenter.heights, _sphere_gap(), rtol=1e-12)
    # Solved through the CLI: the approach equals the sphere scene's (rtol 1e-10).
    assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 0
    surf, meta = _load(tmp_path / "out" / "surf.nc")
    assert meta["scene_summary"]["indenter"] == "Surface"
    # The sphere on the grid (the CLI would solve it on rings).
    sphere, _ = jc.presets.from_toml(_tiny(tmp_path / "tiny.toml"))
    tiny = jc.solve(sphere, solver=jc.Rounds())
    np.testing.assert_allclose(surf["approach"], tiny.approach, rtol=1e-10)


@pytest.mark.parametrize(
    "file_line, extra, argv, message",
    [
        ('file = "missing.npy"', "", [], "missing.npy' does not exist"),
        ('file = "small.npy"', "", [], "has shape (4, 4), the [grid] shape is (8, 8)"),
        ('file = "heights.npy"', "", ["--n", "16"], "a surface file is not resampled"),
        ('file = "heights.npy"', '\nscale = "um"', [],
         "scale must be a number, got 'um'"),
        ('file = "heights.png"', "", [], "expected .npy, .txt, .csv or .dat"),
        ("file = 3", "", [], "file must be a path, got 3"),
        ('radius = 1e-3', "", [], "unknown key(s) ['radius']"),
        ('file = "text.txt"', "", [], "text.txt' cannot be read"),
    ],
)
def test_bad_surface_file_exits_2(tmp_path, capsys, file_line, extra, argv, message):
    np.save(tmp_path / "heights.npy", _sphere_gap())
    np.save(tmp_path / "small.npy", np.zeros((4, 4)))
    (tmp_path / "heights.png").write_bytes(b"\x89PNG")
    (tmp_path / "text.txt").write_text("a b c\nd e f\n")
    path = _surface_toml(tmp_path, file_line, extra)
    assert main(["run", str(path), *argv, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert message in err, err


def test_scene_file_sphere_centre(tmp_path, capsys):
    body = TINY_TOML.format(name='"tiny"').replace(
        "radius = 10e-3", "radius = 10e-3\ncentre = [1e-4, -2e-4]"
    )
    (tmp_path / "c.toml").write_text(body)
    scene, _ = jc.presets.from_toml(tmp_path / "c.toml")
    np.testing.assert_array_equal(np.asarray(scene.indenter.centre), [1e-4, -2e-4])
    (tmp_path / "c.toml").write_text(body.replace("[1e-4, -2e-4]", "[1e-4]"))
    assert main(["run", str(tmp_path / "c.toml"), "--out", str(tmp_path / "o")]) == 2
    assert "[indenter] centre must be [x, y], got [0.0001]" in capsys.readouterr().err


def test_float32_run_checks_the_scene_in_float32(tmp_path, capsys):
    # The scene file is read in float64 and cast (--float32): the cast scene is checked
    # again. Late times collapse in float32 (before: solved, the steps wrong).
    body = TINY_TOML.format(name='"late"').replace(
        "times = [0.0]", "times = [1e5, 100000.005, 100000.01]"
    )
    path = tmp_path / "late.toml"
    path.write_text(body)
    assert main(["run", str(path), "--out", str(tmp_path / "o"), "--float32"]) == 2
    err = capsys.readouterr().err
    assert "times are not strictly increasing in float32" in err, err


def test_second_run_loads_the_compiled_program_from_the_cache(tmp_path):
    """`jaxcontact run` writes its compiled solve to the persistent cache, and a second
    process solving the same scene loads it instead of compiling (JAX's own log says
    which). A coupled scene: its program takes seconds to compile, above the cache's
    1 s threshold."""
    env = dict(os.environ, PYTHONPATH=str(ROOT), JAX_LOGGING_LEVEL="DEBUG",
               JAXCONTACT_CACHE_DIR=str(tmp_path / "cache"))
    env.pop("JAXCONTACT_NO_CACHE", None)

    def run(*extra):
        argv = [sys.executable, "-m", "jaxcontact", "run", "lc", "--n", "12", "--steps",
                "3", "--out", str(tmp_path / "out"), "--overwrite", *extra]
        proc = subprocess.run(argv, capture_output=True, text=True, env=env,
                              cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr[-2000:]
        return proc.stderr

    first = run()
    assert "PERSISTENT COMPILATION CACHE MISS for 'jit__solve'" in first
    assert "Writing jit__solve to persistent compilation cache" in first
    second = run()
    assert "Persistent compilation cache hit for 'jit__solve'" in second
    assert "MISS for 'jit__solve'" not in second


def test_no_cache_flag_and_environment_leave_the_cache_off(monkeypatch):
    """`--no-cache` (and `JAXCONTACT_NO_CACHE=1`) set no cache folder; without them
    `_setup_jax` points JAX at `JAXCONTACT_CACHE_DIR` (checked in-process on the
    parsed flag; the two-process test above shows the cache in use)."""
    from jaxcontact import _cli
    from jaxcontact._cache import cache_disabled_by_environment, default_cache_dir

    seen = []
    monkeypatch.setattr(jax.config, "update", lambda name, value: seen.append(name))
    monkeypatch.setenv("JAXCONTACT_CACHE_DIR", "/tmp/jaxcontact-cache-test")
    args = _cli._parser().parse_args(["run", "zener", "--no-cache"])
    _cli._setup_jax(False, cache=not args.no_cache)
    assert "jax_compilation_cache_dir" not in seen
    monkeypatch.setenv("JAXCONTACT_NO_CACHE", "1")
    assert cache_disabled_by_environment()
    _cli._setup_jax(False, cache=True)
    assert "jax_compilation_cache_dir" not in seen
    monkeypatch.setenv("JAXCONTACT_NO_CACHE", "0")
    assert not cache_disabled_by_environment()
    assert str(default_cache_dir()) == "/tmp/jaxcontact-cache-test"
