"""The committed benchmark results: every file under `benchmarks/results/` has the one
layout of `benchmarks/results/SCHEMA.md` and the name of its machine and variant, every
results file the benchmarks README (and the docs and tests) cite exists, and the
READMEs' headline tables are the ones `benchmarks/headline.py` generates from them.
"""

import itertools
import re
import sys
from pathlib import Path

import pytest


ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = ROOT / "benchmarks"
RESULTS = BENCHMARKS / "results"
sys.path.insert(0, str(BENCHMARKS))
import _common  # noqa: E402
import headline  # noqa: E402


FILES = sorted(RESULTS.rglob("*.json"))
IDS = [str(p.relative_to(RESULTS)) for p in FILES]


def test_there_are_results_files():
    assert len(FILES) >= 30  # 36 when the layout was introduced (issue 50)


@pytest.mark.parametrize("path", FILES, ids=IDS)
def test_results_file_follows_the_schema(path):
    record = _common.load_results(path)  # raises, naming what breaks the schema
    rel = path.relative_to(RESULTS)
    assert len(rel.parts) == 2, f"{rel}: not results/<benchmark>/<file>.json"
    assert record["benchmark"] == rel.parts[0]
    name, variant = record["machine"]["name"], record["variant"]
    assert re.fullmatch(r"[a-z0-9_]+", name), name
    assert path.stem == name + (f"_{variant}" if variant else "")
    # Where the file records the processor (a CPU) or the device kind (a GPU), its
    # name is the one they give.
    recorded = _common.machine_name(record["machine"])
    assert recorded in ("unknown", name), (recorded, name)
    # A time is a number of seconds, never negative.
    for row in record["rows"]:
        for key, value in row.items():
            if key.endswith("_s") and isinstance(value, (int, float)):
                assert value >= 0, (key, value)


def test_no_results_file_outside_a_benchmark_folder():
    flat = [p.name for p in RESULTS.glob("*.json")]
    assert flat == []


def _cited(text: str) -> set[str]:
    """The `.json` names and `results/...` paths in backticks, braces expanded."""
    names = set()
    for token in re.findall(r"`([^`\s]*(?:\.json|results/[^`\s]*))`", text):
        parts = re.split(r"\{([^}]*)\}", token)
        choices = [[p] if i % 2 == 0 else p.split(",") for i, p in enumerate(parts)]
        names |= {"".join(c) for c in itertools.product(*choices)}
    return names


def _exists(name: str) -> bool:
    if "<" in name or "*" in name:  # a pattern (`results/<script>/...`), not a file
        return True
    name = name.removeprefix("benchmarks/").removeprefix("results/")
    if "/" in name:
        return (RESULTS / name).exists()
    return any(RESULTS.rglob(name))  # a file named beside its folder in the text


def test_every_results_file_the_readme_cites_exists():
    cited = _cited((BENCHMARKS / "README.md").read_text())
    assert len([c for c in cited if c.endswith(".json")]) >= 15
    missing = sorted(c for c in cited if not _exists(c))
    assert missing == []


def test_every_results_path_the_docs_and_tests_cite_exists():
    texts = [p.read_text() for p in [*(ROOT / "docs").rglob("*.md"),
                                     *(ROOT / "tests").glob("*.py")]]
    paths = {m for t in texts for m in re.findall(
        r"benchmarks/results/[A-Za-z0-9_./{},<>-]*[A-Za-z0-9_>}]", t)}
    missing = sorted(p for p in paths
                     if not any(_exists(c) for c in _cited(f"`{p}`")))
    assert missing == []


def test_headline_tables_are_the_ones_generated_from_the_results():
    """Both READMEs' headline tables (the benchmarks' and the project's) are
    `headline.py`'s, read from the committed results: no hand-typed number."""
    for readme, project in ((BENCHMARKS / "README.md", False),
                            (ROOT / "README.md", True)):
        block = headline.readme_block(readme.read_text())
        assert block == headline.table(project=project), (
            f"{readme.name} stale: run python benchmarks/headline.py --write")
    # Every script the project README's table names is a benchmark of the repository.
    for script in re.findall(r"\| `([a-z_]+\.py)[^`]*` \|$",
                             headline.table(project=True), re.M):
        assert (BENCHMARKS / script).exists(), script


def test_the_writer_refuses_a_record_that_breaks_the_schema(tmp_path):
    record = {"benchmark": "demo", "variant": None, "date": "2026-11-29T00:00:00+00:00",
              "command": "demo.py", "commit": "0" * 40, "dirty": False,
              "machine": {"name": "amd_epyc", "platform": "Linux", "processor":
                          "AMD EPYC 7B13", "cpu_count": 2, "device_kind": "cpu",
                          "backend": "cpu"},
              "versions": dict.fromkeys(_common.VERSION_KEYS, "1.0"),
              "settings": {"n": 8}, "rows": [{"n": 8, "solve_s": 0.5}]}
    path = _common.write_results(record, tmp_path / "demo.json")
    assert _common.load_results(path) == record
    for key, bad in (("rows", []), ("rows", [1.0]), ("settings", None)):
        with pytest.raises(ValueError, match=key):
            _common.write_results({**record, key: bad}, tmp_path / "bad.json")
    without = {k: v for k, v in record.items() if k != "versions"}
    with pytest.raises(ValueError, match="versions"):
        _common.write_results(without, tmp_path / "bad.json")
    assert not (tmp_path / "bad.json").exists()


def test_results_path_is_benchmark_machine_and_variant():
    assert _common.results_path("hertz", None, "amd_epyc") == (
        RESULTS / "hertz" / "amd_epyc.json")
    assert _common.results_path("gpu", "quick", "h200") == (
        RESULTS / "gpu" / "h200_quick.json")


@pytest.mark.parametrize("machine, name", [
    ({"backend": "cpu", "processor": "Intel(R) Xeon(R) Processor"}, "intel_xeon"),
    ({"backend": "cpu", "processor": "AMD EPYC 7B13 64-Core Processor"}, "amd_epyc"),
    ({"backend": "gpu", "device_kind": "NVIDIA H200", "processor": "x86_64"}, "h200"),
    ({"backend": "cpu", "processor": ""}, "unknown"),
    ({"processor": "unknown", "device_kind": "unknown"}, "unknown"),
])
def test_machine_name(machine, name):
    assert _common.machine_name(machine) == name
