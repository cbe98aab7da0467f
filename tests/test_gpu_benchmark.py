"""benchmarks/gpu.py --quick runs every case of the GPU benchmark on the CPU at small
sizes (about a minute on 2 cores): the script a GPU session runs is exercised here, and
its rows state facts that hold on any device."""

import importlib.util
import json
from pathlib import Path

import pytest


ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.slow
def test_gpu_benchmark_quick_mode_runs_every_case(tmp_path):
    spec = importlib.util.spec_from_file_location("gpu", ROOT / "benchmarks" / "gpu.py")
    gpu = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gpu)
    out = tmp_path / "gpu.json"
    assert gpu.main(["--quick", "--out", str(out)]) == 0
    result = json.loads(out.read_text())
    assert result["machine"]["backend"] in ("cpu", "gpu", "cuda", "rocm", "tpu")
    assert result["summary"]["skipped"] == []
    kinds = {(c["case"], c.get("scene") or c.get("preset")) for c in result["rows"]}
    assert {("normal", "hertz"), ("normal", "rough"), ("coupled", "lc"),
            ("coupled", "sliding"), ("gradient", "coupled (gradients.py)"),
            ("sweep", "lc")} <= kinds
    for case in result["rows"]:
        assert case.get("converged", case.get("all_converged")) is True, case
    for case in (c for c in result["rows"] if c["case"] == "normal"):
        # rtol 1e-6 on the gap; the pressure within 1e-4 of the float64 tight solve
        # (float32 included: its round-off floor is ~1e-6 here)
        assert case["error_vs_float64_tight"] < 1e-4, case
    grad = next(c for c in result["rows"] if c["case"] == "gradient")
    assert grad["gradient_finite"]
    sweep = next(c for c in result["rows"] if c["case"] == "sweep")
    # the batched solve equals the loop of single solves to round-off (forces ~0.02 N)
    assert sweep["max_tangential_force_difference_N"] < 1e-12
    sliding = [c for c in result["rows"] if c.get("preset") == "sliding"]
    assert all(c["stick_ratio_last"] == 0 for c in sliding)  # gross sliding reached
