"""Run every notebook (`notebooks/*.py`, jupytext percent scripts) with plain python at
CI size (`JAXCONTACT_NOTEBOOK_SIZE=ci`, `MPLBACKEND=Agg`).

A notebook whose first line is `# slow` runs only with `-m slow`. A notebook passes
when it exits 0: each one asserts its own checks against theory (Hertz, Lee-Radok,
Cattaneo-Mindlin); ours also write their figures to `JAXCONTACT_NOTEBOOK_OUT`.
"""

import os
import subprocess
import sys
from pathlib import Path

import pytest


ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.py"))
# The notebooks of tests/test_notebooks.py's owner save figures; others may not.
SAVE_FIGURES = {"quickstart", "paper_reproduction", "parameter_sweep", "fit_prony"}


def _is_slow(path: Path) -> bool:
    with open(path, encoding="utf-8") as f:
        first = f.readline().strip()
    return first == "# slow" or first.startswith("# slow ")


# paper_reproduction runs in tests/test_paper_claims.py, which also checks its figures
# and asserts its verdicts: one CI-size run (~7 min on a shared 2-core CPU) is enough.
RUN_ELSEWHERE = {"paper_reproduction"}


def _params():
    for path in NOTEBOOKS:
        if path.stem in RUN_ELSEWHERE:
            continue
        marks = [pytest.mark.slow] if _is_slow(path) else []
        yield pytest.param(path, marks=marks, id=path.stem)


def test_notebooks_exist():
    names = {p.stem for p in NOTEBOOKS}
    assert {"quickstart", "paper_reproduction", "parameter_sweep"} <= names


@pytest.mark.parametrize("path", list(_params()))
def test_notebook_runs(path, tmp_path):
    env = dict(
        os.environ,
        JAXCONTACT_NOTEBOOK_SIZE="ci",
        JAXCONTACT_NOTEBOOK_OUT=str(tmp_path),
        MPLBACKEND="Agg",
        PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
    )
    proc = subprocess.run(
        [sys.executable, str(path)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=1800,
    )
    assert proc.returncode == 0, (
        f"{path.name} failed (exit {proc.returncode}):\n{proc.stdout[-3000:]}\n"
        f"{proc.stderr[-5000:]}"
    )
    assert "Traceback" not in proc.stderr
    if path.stem in SAVE_FIGURES:
        assert list(tmp_path.glob("*.png")), f"{path.name} saved no figure"
