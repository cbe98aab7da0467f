"""CLI defects of issue 47 (Deliver 5, and the Young's moduli and radius checks of
Deliver 4): unique output stems and no overwrite in `jaxcontact fit`, `run --scheme`,
one-line warnings, the `--float32` echo and dtype warning, the README's re-runnable
first command, Young's moduli, the probe-radius plausibility check and negative
option values.

Most checks call the pure functions or stop before any fit or solve; one tiny fit of
the relaxation file (8^2 grid, 1 arm, 4 + 8 points) covers the fit's outputs end to
end, and one subprocess the `--float32` path with JAX's default (float32) dtypes.
"""

import json
import os
import shlex
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from test_cli import TINY_TOML

import jaxcontact as jc
from jaxcontact import _cli, _cli_fit
from jaxcontact._cli import main


ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data"
RELAX = DATA / "fmt-jpk-sr_cell1-0008.jpk-force"
CREEP = DATA / "fmt-jpk-cc_pr14-polymergel-2021.06.30.jpk-force"

# Elastic Hertz contact on 8 x 8 cells, one time point, with friction 0.3 (echoed).
# test_cli's tiny elastic scene, with friction.
FRICTION_TOML = TINY_TOML.format(name='"tiny"') + "[contact]\nfriction = 0.3\n"


def _no_fit(*args, **kwargs):
    raise AssertionError("the check must come before any fit")


# ---- Output stems and overwriting (`jaxcontact fit`) ---------------------------------


def test_output_stem_is_the_name_minus_its_final_extension():
    # Before: the name cut at its first dot, "gel" for both.
    assert _cli_fit.output_stem("data/gel.001.jpk-force") == "gel.001"
    assert _cli_fit.output_stem("gel.002.jpk-force") == "gel.002"
    assert _cli_fit.output_stem(CREEP) == "fmt-jpk-cc_pr14-polymergel-2021.06.30"
    assert _cli_fit.output_stem("curve") == "curve"
    assert _cli_fit.fit_outputs("gel.001") == ["gel.001_fit.json", "gel.001_fit.png"]


def test_plan_outputs_refuses_a_shared_stem_and_existing_outputs(tmp_path):
    out = tmp_path / "out"
    stems = _cli_fit._plan_outputs(["a/gel.001.jpk-force", "a/gel.002.jpk-force"], out,
                                   overwrite=False)
    assert stems == {"a/gel.001.jpk-force": "gel.001", "a/gel.002.jpk-force": "gel.002"}
    assert out.is_dir()
    with pytest.raises(_cli.InputError, match="'a/x.jpk-force' and 'b/x.jpk-force' "
                       "would both write x_fit.json"):
        _cli_fit._plan_outputs(["a/x.jpk-force", "b/x.jpk-force"], out, False)
    (out / "gel.001_fit.json").write_text("an earlier fit")
    with pytest.raises(_cli.InputError, match="already holds gel.001_fit.json: pass "
                       "--overwrite"):
        _cli_fit._plan_outputs(["gel.001.jpk-force"], out, False)
    assert _cli_fit._plan_outputs(["gel.001.jpk-force"], out, True) == {
        "gel.001.jpk-force": "gel.001"}


def test_fit_refuses_existing_outputs_before_fitting(tmp_path, capsys, monkeypatch):
    # Before: fitted and replaced gel_fit.json without a word.
    pytest.importorskip("afmformats")
    monkeypatch.setattr(_cli_fit, "_fit_one", _no_fit)
    path = tmp_path / "gel.001.jpk-force"
    shutil.copy(RELAX, path)
    out = tmp_path / "out"
    out.mkdir()
    (out / "gel.001_fit.json").write_text("an earlier fit")
    assert main(["fit", str(path), "--radius", "5e-6", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "already holds gel.001_fit.json: pass --overwrite" in err, err
    assert (out / "gel.001_fit.json").read_text() == "an earlier fit"
    # Two files that would write the same outputs: refused, nothing fitted.
    (tmp_path / "b").mkdir()
    twin = tmp_path / "b" / "gel.001.jpk-force"
    shutil.copy(RELAX, twin)
    argv = ["fit", str(path), str(twin), "--radius", "5e-6", "--overwrite"]
    assert main([*argv, "--out", str(out)]) == 2
    assert "would both write gel.001_fit.json" in capsys.readouterr().err


# ---- `run --scheme`, echoes, warnings ------------------------------------------------


def test_run_scheme_reaches_solve_and_float32_echo_is_rounded(tmp_path, capsys,
                                                               monkeypatch):
    # Before: --scheme was unknown (exit 2) and friction echoed as 0.30000001192092896.
    seen = {}
    solve = jc.solve

    def spy(scene, **options):
        seen.update(options)
        return solve(scene, **options)

    monkeypatch.setattr(jc, "solve", spy)
    scene_file = tmp_path / "tiny.toml"
    scene_file.write_text(FRICTION_TOML)
    argv = ["run", str(scene_file), "--out", str(tmp_path / "o"), "--float32"]
    assert main([*argv, "--scheme", "linear"]) == 0
    out = capsys.readouterr().out
    assert seen["scheme"] == "linear"
    assert "friction=0.3, scheme=linear, float32" in out, out
    assert "0.3000000" not in out
    ds = jc.load(tmp_path / "o" / "tiny.nc")
    assert json.loads(ds.attrs["metadata"])["solve_options"]["scheme"] == "linear"
    assert main([*argv, "--scheme", "quadratic"]) == 2
    assert "invalid choice: 'quadratic'" in capsys.readouterr().err
    assert main(["run", "hertz", "--scheme", "linear", "--out", str(tmp_path)]) == 2
    assert "--scheme: the hertz example is one load step" in capsys.readouterr().err


def test_echoed_settings_have_six_significant_digits():
    assert _cli._num(np.float32(0.3)) == "0.3"
    assert _cli._num(np.float32(10e-3)) == "0.01"
    assert _cli._num(1.93e6) == "1.93e+06"


@pytest.mark.filterwarnings("default::UserWarning")
def test_warnings_print_on_one_line_inside_main_only(tmp_path, capsys, monkeypatch):
    # Before: "path/to/file.py:123: TimeStepWarning: ..." and the source line below.
    def warn(args, dtype):
        warnings.warn('a time step of 0.1 is too long:\n  use scheme="linear"',
                      jc.TimeStepWarning, stacklevel=1)
        return 0

    monkeypatch.setattr(_cli, "_hertz", warn)
    before = warnings.showwarning
    assert main(["run", "hertz", "--no-cache", "--out", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert err == ('jaxcontact: TimeStepWarning: a time step of 0.1 is too long: use '
                   'scheme="linear"\n'), err
    assert warnings.showwarning is before  # library users keep their own format


def test_float32_run_has_no_dtype_warning_and_rounded_echo(tmp_path):
    """In a fresh process with JAX's default dtypes (float32: the test process runs in
    float64). Before: a two-line dtype `UserWarning` on stderr and `R =
    0.009999999776482582 m`, `nu = 0.30000001192092896` in the echo."""
    env = dict(os.environ, PYTHONPATH=str(ROOT), JAXCONTACT_NO_CACHE="1")
    env.pop("JAX_ENABLE_X64", None)
    proc = subprocess.run(
        [sys.executable, "-m", "jaxcontact", "run", "hertz", "--n", "8", "--float32",
         "--out", str(tmp_path)],
        capture_output=True, text=True, env=env, timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "rigid sphere R = 0.01 m on G = 1.93e+06 Pa, nu = 0.3, W = 0.15 N" in (
        proc.stdout), proc.stdout
    assert "Warning" not in proc.stderr, proc.stderr


def test_readme_first_command_runs_twice(tmp_path, capsys, monkeypatch):
    # Before: the second run exited 2 (out/hertz.nc exists). Run at n = 8 here.
    readme = (ROOT / "README.md").read_text()
    line = next(s for s in readme.splitlines() if "jaxcontact run hertz" in s)
    command = line.split("&&")[-1]
    argv = shlex.split(command, comments=True)
    assert argv[0] == "jaxcontact" and "--overwrite" in argv
    monkeypatch.chdir(tmp_path)
    for _ in range(2):
        assert main([*argv[1:], "--n", "8", "--no-cache"]) == 0
    capsys.readouterr()
    assert (tmp_path / "out" / "hertz.nc").is_file()


# ---- Negative values, the radius check, Young's moduli -------------------------------


def test_negative_option_values_reach_the_option_check(tmp_path, capsys):
    # Before: "argument --radius: expected one argument".
    assert _cli._attach_negative_values(
        ["fit", "f", "--radius", "-5e-6", "--poisson", "-.3", "--n", "8"]
    ) == ["fit", "f", "--radius=-5e-6", "--poisson=-.3", "--n", "8"]
    # A flag or the "--" separator keeps its neighbour; a non-number stays apart.
    assert _cli._attach_negative_values(["--", "-5", "--out", "-x"]) == [
        "--", "-5", "--out", "-x"]
    args = _cli._parser().parse_args(_cli._attach_negative_values(
        ["fit", "f", "--radius", "5e-6", "--poisson", "-3e-1"]))
    assert args.poisson == -0.3
    assert main(["fit", str(RELAX), "--radius", "-5e-6", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "radius must be positive, got -5e-06" in err, err


def test_radius_plausibility_rule():
    lo, hi = _cli_fit.RADIUS_WINDOW
    assert (lo, hi) == (1e-2, 1e3)
    # The README's 5 um probe on both real files (depths 1.7 um and 19.9 um): quiet.
    assert _cli_fit.radius_warning(5e-6, 1.71e-6) is None
    assert _cli_fit.radius_warning(5e-6, 1.99e-5) is None
    # 5 meant in micrometres: named, with the rule and the likely reading.
    text = _cli_fit.radius_warning(5.0, 1.71e-6)
    assert text.startswith("--radius 5 m is 2.92e+06 x the maximum indentation depth "
                           "1.71e-06 m"), text
    assert "0.01 to 1000 x the depth" in text
    assert text.endswith("if 5 was meant in micrometres, pass --radius 5e-06")
    assert _cli_fit.radius_warning(5e-3, 1.71e-6).endswith(
        "if 0.005 was meant in millimetres, pass --radius 5e-06")
    assert _cli_fit.radius_warning(5e-9, 1.99e-5).endswith(
        "check the radius's unit (metres) and the contact point")
    assert _cli_fit.radius_warning(5e-6, 0.0) is None


@pytest.mark.filterwarnings("default:.*--radius:UserWarning")
def test_fit_writes_a_unique_stem_youngs_moduli_and_the_radius_warning(
        tmp_path, capsys):
    """One tiny fit of a copy of the relaxation file named `cell.001.jpk-force` with
    `--radius 5` (a unit slip: the problem is the 5 um one scaled, so the fit runs as
    well): `cell.001_fit.json` (before: `cell_fit.json`) with Young's moduli beside
    the shear moduli and the radius warning, printed on one line of stderr; a second
    run without `--overwrite` is refused before fitting and keeps the outputs."""
    pytest.importorskip("afmformats")
    path = tmp_path / "cell.001.jpk-force"
    shutil.copy(RELAX, path)
    out = tmp_path / "out"
    argv = ["fit", str(path), "--radius", "5", "--n", "8", "--arms", "1",
            "--samples", "4,8,1", "--segments", "approach,hold", "--no-cache",
            "--out", str(out)]
    assert main(argv) in (0, 1)
    captured = capsys.readouterr()
    written = out / "cell.001_fit.json"
    js = json.loads(written.read_text())
    # The radius check: one line on stderr, in the JSON too.
    lines = captured.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith(
        f"jaxcontact: UserWarning: {path}: --radius 5 m is "), captured.err
    assert lines[0].endswith("if 5 was meant in micrometres, pass --radius 5e-06")
    assert js["radius_warning"] in lines[0]
    # Young's moduli at nu = 0.5: E = 3 G, in the JSON and on the console.
    p, e = js["parameters"], js["youngs_moduli"]
    assert e["E_inf_Pa"]["value"] == pytest.approx(3 * p["g_inf_Pa"]["value"])
    assert e["E_Pa"][0]["value"] == pytest.approx(3 * p["g_Pa"][0]["value"])
    assert e["E_0_Pa"]["value"] == pytest.approx(3 * js["instantaneous_modulus_Pa"])
    assert js["units"]["youngs_modulus"] == "Pa"
    text = captured.out
    assert "Young's moduli E = 2 g (1 + nu) [Pa] at nu = 0.5" in text
    assert f"E_inf = {e['E_inf_Pa']['value']:.4g} +- " in text, text
    assert f"E_0 = {e['E_0_Pa']['value']:.4g} +- " in text
    # No overwrite without --overwrite: refused before any fit, the JSON kept.
    before = written.read_text()
    assert main(argv) == 2
    assert "already holds cell.001_fit.json" in capsys.readouterr().err
    assert written.read_text() == before
