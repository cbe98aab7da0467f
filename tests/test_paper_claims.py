"""The paper's claims: `notebooks/paper_reproduction.py` at CI size, and the committed
results of `benchmarks/paper.py` (`benchmarks/results/paper/`).

The default tests run the notebook once at CI size (16^2, 9 time points: every study's
code at the least cost) and check that it ran every study, saved its figures, gives a
criterion with every verdict, passed its physical checks, and decided the claims that
do not hinge on a few boundary cells as the committed 64^2 and 256^2 runs did. The
verdicts themselves are checked on the committed results files, computed at sizes
where they mean something: their numbers against closed forms (Lee & Radok, the
correspondence solution) and each verdict against its own criterion. `-m slow` reruns
the 64^2 size and compares it with the committed 64^2 file.
"""

import importlib.util
import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest


ROOT = Path(__file__).resolve().parents[1]
NOTEBOOK = ROOT / "notebooks" / "paper_reproduction.py"
RESULTS = ROOT / "benchmarks" / "results" / "paper"
VALUES = ("holds", "partly", "differs")
SCHEMA_KEYS = ("benchmark", "date", "command", "machine", "commit", "dirty", "versions",
               "settings", "rows", "summary")

# Claims that the CI size decides as the 64^2 and 256^2 runs do: closed forms, exact
# identities and differences far above a boundary cell.
AGREE = (
    "Table 1", "Table 2", "Fig. 4", "Fig. 5", "Fig. 6", "Fig. 7", "Fig. 9", "Fig. 10",
    "Fig. 11", "Fig. 13a", "Fig. 14", "Fig. 16a (loads)", "Fig. 21b", "Fig. 22",
    "Fig. 25b",
)


def committed(size):
    """The newest committed results file of `size` ({study: row}, the whole file)."""
    found = []
    for path in RESULTS.glob("*.json"):
        with open(path, encoding="utf-8") as f:
            table = json.load(f)
        if table["settings"]["size"] == size:
            found.append(table)
    assert found, f"no {size}-size results file in {RESULTS}"
    table = max(found, key=lambda t: t["date"])
    return {row["study"]: row for row in table["rows"]}, table


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("paper")
    env = dict(
        os.environ,
        JAXCONTACT_NOTEBOOK_SIZE="ci",
        JAXCONTACT_NOTEBOOK_OUT=str(out),
        MPLBACKEND="Agg",
        PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
    )
    proc = subprocess.run(
        [sys.executable, str(NOTEBOOK)], cwd=out, env=env, capture_output=True,
        text=True, timeout=1800,
    )
    assert proc.returncode == 0, (
        f"paper_reproduction.py failed (exit {proc.returncode}):\n"
        f"{proc.stdout[-3000:]}\n{proc.stderr[-5000:]}"
    )
    assert "Traceback" not in proc.stderr
    with open(out / "paper_verdicts.json", encoding="utf-8") as f:
        table = json.load(f)
    return out, {v["study"]: v for v in table["verdicts"]}, table


def test_runs_every_study_with_a_criterion(run):
    out, verdicts, table = run
    assert len(list(out.glob("paper_*.png"))) >= 22
    studies = " ".join(verdicts)
    for fig in range(4, 28):
        assert f"Fig. {fig}" in studies, f"no verdict for Fig. {fig}"
    assert "Table 1" in verdicts and "Table 2" in verdicts
    for v in verdicts.values():
        assert v["verdict"] in VALUES, v["study"]
        assert len(v["criterion"]) > 20 and "holds if" in v["criterion"], v["study"]
    assert table["checks"] and all(c["passed"] for c in table["checks"])
    assert all(s["not_converged"] == 0 for s in table["solves"])


def test_tables_and_hertz(run):
    _, v, _ = run
    for table in ("Table 1", "Table 2"):
        assert v[table]["verdict"] == "holds"
        assert abs(v[table]["values"]["a_rel"]) < 1e-3
        assert abs(v[table]["values"]["p_rel"]) < 1e-3


def test_maxwell_creep_and_surface(run):
    _, v, _ = run
    fig4, fig5, fig7 = (v["Fig. 4"]["values"], v["Fig. 5"]["values"],
                        v["Fig. 7"]["values"])
    # 16^2: a x1.41 against Lee-Radok's x1.44, u_z x2.10; the surface from the
    # tractions closes the gap in the contact to ~1e-8 of the approach.
    assert abs(fig4["radius_growth"] - fig4["lee_radok_growth"]) < 0.1
    assert fig4["uz_growth"] > 1.5
    assert fig5["approach_err"] < 0.01  # 0.20 % measured
    assert fig7["flatness"] < 1e-6
    # Fig. 10: the approach rate falls as (1 + t/tau)^(2/3) (0.52 at 6 tau; 0.59 here)
    rate = v["Fig. 10"]["values"]["approach_rate_ratio"]
    assert v["Fig. 10"]["verdict"] == "differs" and 0.45 < rate < 0.7


def test_coupled_normal_load(run):
    _, v, _ = run
    fig13 = v["Fig. 13a"]["values"]
    # the coupling raises the peak above the frictionless one on the same grid
    assert 1.0 < fig13["peak0"] / fig13["peak0_frictionless"] < 1.15
    assert v["Fig. 14"]["verdict"] == "holds"


def test_lc_dc_and_relaxation(run):
    _, v, _ = run
    stick = v["Fig. 16a (stick)"]["values"]
    # DC's relaxed tangential load leaves MORE stick than LC's (0.280 vs 0.240 at 16^2,
    # within the jitter of one boundary cell there: not `holds` in either case)
    assert v["Fig. 16a (stick)"]["verdict"] in ("partly", "differs")
    assert stick["stick_dc"] > stick["stick_lc"]
    # held displacements: F_x / (mu W) and the stick pattern fixed (exact)
    assert v["Fig. 21a"]["values"]["f_range"] < 1e-5
    assert v["Fig. 21b"]["verdict"] == "holds"
    fig22 = v["Fig. 22"]["values"]
    # held displacements: the magnitude falls with G(t), the shape is exactly fixed
    assert fig22["mag_rel"] < 0.8 and fig22["shape_rel"] < 1e-6
    assert fig22["shape_creep"] > 1e-2


def test_transition_to_sliding(run):
    _, v, _ = run
    f24 = v["Fig. 24a (time, load)"]["values"]
    assert f24["f_full"] < f24["f_semi"]  # 0.905 vs 1.000 at 16^2
    abrupt = v["Fig. 24a (abrupt)"]["values"]
    # the largest one-step drop shrinks with the step (9 -> 17 points at 16^2, where
    # the stick zone is a few cells: the verdict itself is checked at 64^2 and 256^2)
    assert abrupt["drop_fine"] < abrupt["drop_coarse"]
    assert v["Fig. 25b"]["verdict"] == "holds"


@pytest.mark.parametrize("size", ["paper", "small"])
def test_committed_results_are_complete(size):
    """The committed results file: the layout of results/SCHEMA.md, every study with
    a criterion, every verdict short of `holds` with its cause, every check passed and
    every step converged."""
    rows, table = committed(size)
    for key in SCHEMA_KEYS:
        assert key in table, key
    assert table["benchmark"] == "paper" and table["commit"]
    assert table["settings"]["grid"] == {"paper": 256, "small": 64}[size]
    studies = " ".join(rows)
    for fig in range(4, 28):
        assert f"Fig. {fig}" in studies, f"no verdict for Fig. {fig}"
    for row in rows.values():
        assert row["verdict"] in VALUES and "holds if" in row["criterion"], row["study"]
        if row["verdict"] != "holds":
            assert row["why"], row["study"]
    s = table["summary"]
    assert s["holds"] + s["partly"] + s["differs"] == s["verdicts"] == len(rows)
    assert s["seconds"] > 0 and s["checks_passed"] == len(table["checks"])
    assert all(c["passed"] for c in table["checks"])
    assert all(x["not_converged"] == 0 for x in table["solves"])


def test_committed_paper_size_numbers():
    """The 256^2 numbers against closed forms and exact identities."""
    rows, _ = committed("paper")
    # Lee & Radok: a(t) / a(0) and the approach of a Maxwell body under a step load
    fig4 = rows["Fig. 4"]
    assert abs(fig4["radius_growth"] / fig4["lee_radok_growth"] - 1) < 0.01
    assert rows["Fig. 5"]["approach_err"] < 1e-3
    # Maxwell: delta ~ (1 + t / tau)^(2/3), whose rate at 6 tau is 7^(-1/3) x the first
    # (the discrete first step is a secant, hence the tolerance)
    assert abs(rows["Fig. 10"]["approach_rate_ratio"] - 7 ** (-1 / 3)) < 0.03
    # the correspondence solution: one stick ratio at every time for both materials
    assert rows["Fig. 15b"]["spread"] < 0.01
    # held displacements: the pattern never changes, the shape is exactly fixed
    assert rows["Fig. 21b"]["changed"] == 0 and rows["Fig. 22"]["shape_rel"] < 1e-5
    # Fig. 24: continuous, the largest one-step drop about halving as the step halves
    abrupt = rows["Fig. 24a (abrupt)"]
    assert abrupt["verdict"] == "differs" and abrupt["crit_over_c0"] < 0.25
    # at 321 points the last stick ratio before sliding is a few cells of c(0) (on
    # 128^2, the refinement's grid at paper size, one cell is 0.4 % of c(0))
    assert abrupt["crit_fine_slow"] < 0.05 and abrupt["crit_fine_fast"] < 0.05
    assert abrupt["shrink_slow"] < 0.6 and abrupt["shrink_fast"] < 0.6


def test_committed_verdicts_follow_their_criteria():
    """The re-graded verdicts at 256^2 against their stated rule, from the row's own
    numbers (a consistency check of the committed file, not a recomputation)."""
    rows, _ = committed("paper")
    r = rows["Fig. 20b"]
    gaps, res = (r["gap_3_5"], r["gap_5_10"]), r["resolution"]
    expected = ("holds" if min(gaps) > res and r["spread"] < 0.1 else
                "differs" if min(gaps) < -res or r["spread"] >= 0.1 else "partly")
    assert r["verdict"] == expected
    assert res >= max(r["grid_change"], r["step_change"], r["jitter"])
    r = rows["Fig. 23a"]
    if r["verdict"] == "holds":
        assert r["largest_rise_cells"] > 2 and r["largest_rise_share"] > 0.01
    r = rows["Fig. 8d"]
    assert r["edge_swings_fine"] <= 1 or r["verdict"] == "differs"
    r = rows["Fig. 26"]
    if r["verdict"] == "holds":
        assert math.isfinite(r["t_creep"]) and r["t_creep"] > r["t_relax"]
    r = rows["Fig. 19"]
    shares = (r["share_abs"], r["share_signed"])
    assert r["verdict"] == ("holds" if min(shares) == 1.0 else
                            "partly" if max(shares) == 1.0 else "differs")
    for study in ("Fig. 18 (rear/front)", "Fig. 18 (peak)"):
        if rows[study]["verdict"] == "holds":
            assert rows[study]["share"] == 1.0


def test_ci_decides_as_the_committed_runs(run):
    _, v, _ = run
    paper, _ = committed("paper")
    small, _ = committed("small")
    for study in AGREE:
        assert small[study]["verdict"] == paper[study]["verdict"], study
        assert v[study]["verdict"] == paper[study]["verdict"], study
    # the headline: no jump at either size
    assert small["Fig. 24a (abrupt)"]["verdict"] == "differs"
    assert paper["Fig. 24a (abrupt)"]["verdict"] == "differs"


def test_pages_are_generated_from_the_committed_results():
    """benchmarks/paper_reproduction.md and docs/paper.md are what
    benchmarks/paper_page.py makes of the committed results (no hand-typed numbers),
    every study of the paper-size file is on them, and every figure they show is
    committed."""
    spec = importlib.util.spec_from_file_location(
        "paper_page", ROOT / "benchmarks" / "paper_page.py")
    page = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(page)
    assert page.main(["--check"]) == 0, "run: python benchmarks/paper_page.py"
    rows, _ = committed("paper")
    for path, prefix in page.FIGURE_PREFIX.items():
        text = path.read_text(encoding="utf-8")
        for study in rows:
            assert f"| {study} |" in text, study
        shown = re.findall(r"\]\(" + re.escape(prefix) + r"([^)]+)\)", text)
        assert len(set(shown)) >= 22
        for name in shown:
            assert (page.FIGURES / name).is_file(), name


@pytest.mark.slow
def test_small_size_reproduces_the_committed_verdicts(tmp_path):
    """`benchmarks/paper.py --size small` (64^2, ~15 min on 2 CPU cores) decides every
    claim as the committed 64^2 file does."""
    proc = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "paper.py"), "--size", "small",
         "--out", str(tmp_path), "--figures", str(tmp_path / "figures"),
         "--name", "rerun", "--no-pages"],
        cwd=ROOT, capture_output=True, text=True, timeout=3600,
        env=dict(os.environ, MPLBACKEND="Agg"),
    )
    assert proc.returncode == 0, proc.stderr[-5000:]
    with open(tmp_path / "rerun.json", encoding="utf-8") as f:
        rerun = {row["study"]: row for row in json.load(f)["rows"]}
    small, _ = committed("small")
    assert set(rerun) == set(small)
    for study, row in small.items():
        assert rerun[study]["verdict"] == row["verdict"], study
