"""Gradients across the scene space against central differences.

The cases are `benchmarks/gradient_matrix.py`'s: the default selection runs its
`quick_slice()` (every axis value at least once: coupling, normal control and program,
tangential program, material, slip law, time scheme, periodic grid, `jc.Surface`, the
solver (grid or rings), the parameter, and `jit` / eager `grad` / forward-mode `jvp` /
`vmap` / float32), the slow selection the rest of `default_slice()` (every value twice)
and the whole matrix. Each runs in a process of its own or shares one with a few others:
the quick slice's cases in `QUICK_CHUNKS` processes (one xdist group each: the test
workers share the chunks out, and a chunk's cases share its process's start, imports and
small programs), compiled as the rest of the default selection (its quick-compile flags,
`tests/conftest.py`: a third of the compile time); every slow case alone, compiled as
users compile (without those flags, whose code generation changes round-off), so the
slow selection checks every case of the quick slice that way too
(`test_whole_gradient_matrix`).

Each gradient must be within 1e-5 (float64; 1e-2 float32) of the central difference of
a forward solved to `rtol = 1e-10`, relative to the larger of the two (plus a floor
of 1e-9 of the output over the parameter), and `vmap(grad)` equal to the loop of
gradients to 1e-8. A scene on an active-set change may instead match one of its
one-sided differences (to 1e-3): these are listed in `KNOWN_KINKS`, and must be kinks.
"""

import functools
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest


ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
import gradient_matrix as gm  # noqa: E402


# Scenes of the matrix that sit on an active-set change at their parameter value: their
# one-sided differences (Richardson, h = 1e-4 relative) differ by 0.2 % and 1.2 %, and
# the gradient equals one of them to 4e-10 and 2e-8 (benchmarks/results/
# gradient_matrix/intel_xeon.json); the first one's central difference at h = 1e-5
# equals it too.
KNOWN_KINKS = {
    "x/force-ramp/force_neg/zener/load/vmap",
    "full/force-constant/force_past/prony/friction/jit/periodic",
    "x/force-ramp/force_neg/zener/friction/jit",
}
# Scenes refused, with the text their message must carry. The first two: the forward
# fails under `jit` (the joint iteration stalls with one shear component near or past
# mu W on a viscoelastic body; a concrete `jc.solve` re-solves with fallbacks), so the
# gradient raises the forward's own message with the remedy (measured right with it).
# The third: float32 at 0.997 mu W, whose adjoint stalls at rtol 1e-5; with
# `ImplicitAdjoint(rtol=1e-4)` it gives -443.957 against float64's -444.011
# (benchmarks/notes/gradient_matrix.md).
KNOWN_REFUSALS = {
    "x/force-ramp/force_near/zener/friction/jit":
        "compile the fallback in with `solver=jc.Fallback(jc.JointPCG(), jc.Rounds())`",
    "x/force-ramp/force_past/zener/friction/jit":
        "compile the fallback in with `solver=jc.Fallback(jc.JointPCG(), jc.Rounds())`",
    "full/force-constant/force_near/zener/friction/float32":
        "or a looser `rtol`",
}


def _users_environment():
    """The environment without the quick-compile settings of `tests/conftest.py`."""
    env = dict(os.environ)
    env.pop("JAX_DISABLE_MOST_OPTIMIZATIONS", None)
    flags = env.get("XLA_FLAGS", "").replace("--xla_cpu_use_fusion_emitters=false", "")
    env["XLA_FLAGS"] = flags.strip()
    return env


def _run(case, folder):
    """The matrix row of `case`, computed in a fresh process (one per case: the test
    workers share them out)."""
    out = folder / "row.json"
    run = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "gradient_matrix.py"), "--case",
         case.name, "--out", str(out)],
        env=_users_environment(), capture_output=True, text=True, timeout=1200)
    # Exit 1 means the case is wrong (the assertions say how); anything else crashed.
    assert run.returncode in (0, 1) and out.exists(), run.stderr[-3000:]
    (row,) = json.loads(out.read_text())["rows"]
    return row


def _assert_right(case, row):
    if case.name in KNOWN_REFUSALS:
        assert row["status"] == "refused", row
        assert KNOWN_REFUSALS[case.name] in row["message"], row["message"]
        return
    assert row["status"] != "refused", f"{case.name} raised: {row['message']}"
    g, cd = row["gradient"], row["cd"]
    tol = 1e-2 if case.mode == "float32" else 1e-5
    if case.name in KNOWN_KINKS:
        sides = (row["left_side"], row["right_side"])
        assert abs(sides[1] - sides[0]) > tol * max(abs(s) for s in sides), row
        assert min(abs(g - s) / abs(s) for s in sides) <= 1e-3, row
        return
    floor = 1e-9 * abs(row["value"]) / abs(case.theta0)
    assert abs(g - cd) <= tol * max(abs(cd), abs(g)) + floor, row
    assert row["extra"].get("vmap_vs_loop", 0.0) <= 1e-8, row


def test_the_default_slice_covers_every_axis_value_twice():
    """The slice meets every value of every axis of the matrix at least twice."""
    slice_ = gm.default_slice()
    for field in ("coupling", "normal", "program", "tangential", "material", "slip",
                  "scheme", "periodic", "surface", "parameter", "mode", "output",
                  "solver"):
        values = {getattr(c, field) for c in gm.all_cases()}
        for value in values:
            count = sum(getattr(c, field) == value for c in slice_)
            assert count >= 2, f"{field}={value!r} appears {count} times"
    assert len(slice_) >= 30


def test_the_quick_slice_covers_every_axis_value_once():
    """The default suite's cases (`QUICK`) meet every value of every axis of the
    matrix at least once; each is a case of the default slice."""
    quick = gm.quick_slice()
    assert len(quick) == len(gm.QUICK)
    for field in ("coupling", "normal", "program", "tangential", "material", "slip",
                  "scheme", "periodic", "surface", "parameter", "mode", "output",
                  "solver"):
        for value in {getattr(c, field) for c in gm.all_cases()}:
            assert any(getattr(c, field) == value for c in quick), (field, value)


# The quick slice in this many processes: QUICK's cases dealt out in turn, the coupled
# ones first (they take most of the compile time), so the chunks take similar times.
QUICK_CHUNKS = 4
_CHUNK = {name: k % QUICK_CHUNKS for k, name in enumerate(
    sorted(gm.QUICK, key=lambda name: name.startswith("none/")))}
# Run with `python -c`: the rows of the cases named after the output path, the file
# rewritten after each case (a crash leaves the rows before it).
_CHUNK_DRIVER = """
import json, sys
sys.path.insert(0, sys.argv[1])
import gradient_matrix as gm
cases = {c.name: c for c in gm.default_slice()}
rows = []
for name in sys.argv[3:]:
    rows.append(gm.check(cases[name]))
    with open(sys.argv[2], "w") as f:
        json.dump(rows, f)
"""


@functools.cache
def _chunk_rows(k, folder):
    """`({name: row}, stderr tail)` of the quick slice's chunk `k`, computed in one
    fresh process with this process's compile settings (once per test process: the
    chunk's tests are one xdist group); a case the process did not reach (it crashed)
    has no row."""
    names = [name for name in _CHUNK if _CHUNK[name] == k]
    out = folder / f"gradient_matrix_chunk{k}.json"
    run = subprocess.run(
        [sys.executable, "-c", _CHUNK_DRIVER, str(ROOT / "benchmarks"), str(out),
         *names], capture_output=True, text=True, timeout=1200 * len(names))
    rows = json.loads(out.read_text()) if out.exists() else []
    return {row["name"]: row for row in rows}, run.stderr[-3000:]


@pytest.mark.parametrize("case", [
    pytest.param(c, marks=pytest.mark.xdist_group(f"gradient_matrix_{_CHUNK[c.name]}"))
    if c.name in gm.QUICK else pytest.param(c, marks=pytest.mark.slow)
    for c in gm.default_slice()], ids=lambda c: c.name)
def test_gradient_against_central_differences(case, tmp_path, tmp_path_factory):
    if case.name in gm.QUICK:
        rows, stderr = _chunk_rows(_CHUNK[case.name], tmp_path_factory.getbasetemp())
        assert case.name in rows, stderr
        _assert_right(case, rows[case.name])
    else:
        _assert_right(case, _run(case, tmp_path))


@pytest.mark.slow
@pytest.mark.parametrize("case", gm.all_cases(), ids=lambda c: c.name)
def test_whole_gradient_matrix(case, tmp_path):
    _assert_right(case, _run(case, tmp_path))
