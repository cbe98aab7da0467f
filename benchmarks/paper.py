"""Reproduce the paper (Wang, de Boer & Ghanbarzadeh) at a chosen size, in one command.

Runs `notebooks/paper_reproduction.py` (every study of the paper, one verdict per
claim, each with its criterion), then writes

- the results file `results/paper/<machine>.json` (`<machine>_<size>.json` below the
  paper size) in the layout of `results/SCHEMA.md`: one row per verdict (study, claim,
  criterion, quantity, verdict, our number as text, the paper's, the cause of a
  `partly` or `differs`, then the numbers behind it), the counts and the wall time in
  `summary`, and two more lists: `checks` (every physical check the notebook asserted)
  and `solves` (every solve: grid, time points, seconds, steps not converged, whether
  the step was unstable);
- the figures, `results/paper/figures/` at the paper size (committed; the pages show
  them), `out/paper_<size>/` otherwise;
- the pages generated from the results files, `benchmarks/paper_reproduction.md` and
  `docs/paper.md` (`paper_page.py`).

    python benchmarks/paper.py --size paper     # 256^2, the committed table
    python benchmarks/paper.py --size small     # 64^2
    python benchmarks/paper.py --size ci --out /tmp/paper   # 16^2, a smoke run

Sizes: `ci` (16^2, 9 time points), `small` (64^2) and `paper` (256^2, the paper's
grid), with the paper's time steps at the last two (the notebook's header).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import runpy
import sys
import tempfile
import time
import traceback
from pathlib import Path


ROOT = Path(__file__).resolve().parent.parent
# Reproduce with the checkout this script lives in (the package need not be installed).
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _common import RESULTS, header, write_results  # noqa: E402


NOTEBOOK = ROOT / "notebooks" / "paper_reproduction.py"
SIZES = ("ci", "small", "paper")
VALUES = ("holds", "partly", "differs")
# the fields of a verdict row before its numbers
FIELDS = ("study", "claim", "quantity", "criterion", "verdict", "ours", "paper", "why")


def rows_of(verdicts) -> list[dict]:
    """One flat row per verdict: the verdict's text fields, then its numbers."""
    rows = []
    for v in verdicts:
        row = {key: v[key] for key in FIELDS}
        clash = set(v["values"]) & set(row)
        if clash:
            raise ValueError(f"{v['study']}: value names {sorted(clash)} clash with "
                             "the row's fields")
        rows.append(row | v["values"])
    return rows


def run(size: str, figures: Path, verdicts: Path) -> str | None:
    """Run the notebook at `size`, its figures into `figures`, its verdicts, checks
    and solves into `verdicts` (written as it goes); the error if it failed."""
    figures.mkdir(parents=True, exist_ok=True)
    os.environ.update(JAXCONTACT_NOTEBOOK_SIZE=size,
                      JAXCONTACT_NOTEBOOK_OUT=str(figures),
                      JAXCONTACT_NOTEBOOK_VERDICTS=str(verdicts))
    os.environ.setdefault("MPLBACKEND", "Agg")
    print(f"verdicts so far -> {verdicts}", flush=True)
    try:
        runpy.run_path(str(NOTEBOOK), run_name="__main__")
    except Exception as error:  # a failed check: keep what ran, say so, exit 1
        traceback.print_exc()
        return f"{type(error).__name__}: {error}"
    return None


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", choices=SIZES, default="small")
    parser.add_argument("--out", type=Path, default=RESULTS / "paper",
                        help="folder of the results file (default results/paper)")
    parser.add_argument("--figures", type=Path, default=None,
                        help="folder of the figures (default: results/paper/figures "
                        "at the paper size, out/paper_<size> otherwise)")
    parser.add_argument("--name", default=None,
                        help="results file name without .json (default: the "
                        "machine's, with _<size> below the paper size)")
    parser.add_argument("--no-pages", action="store_true",
                        help="do not regenerate the pages from results/paper")
    args = parser.parse_args(argv)

    figures = args.figures or (RESULTS / "paper" / "figures" if args.size == "paper"
                               else ROOT / "out" / f"paper_{args.size}")
    load_before = list(os.getloadavg())
    partial = Path(tempfile.gettempdir()) / f"paper_{args.size}_{os.getpid()}.json"
    start = time.perf_counter()
    error = run(args.size, figures, partial)
    seconds = time.perf_counter() - start
    with open(partial, encoding="utf-8") as f:
        nb = json.load(f)

    variant = None if args.size == "paper" else args.size
    result = header("paper", argv, variant=variant)
    result["machine"]["load_before"] = load_before
    result["machine"]["load_after"] = list(os.getloadavg())
    verdicts = nb["verdicts"]
    counts = {value: sum(v["verdict"] == value for v in verdicts) for value in VALUES}
    result["settings"] = dict(
        size=args.size, grid=nb["grid"], grids=nb["grids"], study_grid=nb["study_grid"],
        fig24_study_grid=nb["fig24_grids"][0], fig24_extra_grid=nb["fig24_grids"][1],
        dtype="float64", threads=nb.get("threads", 1),
        notebook=str(NOTEBOOK.relative_to(ROOT)),
        figures=str(figures.relative_to(ROOT)) if figures.is_relative_to(ROOT)
        else str(figures))
    result["rows"] = rows_of(verdicts)
    usage = resource.getrusage(resource.RUSAGE_SELF)
    result["summary"] = dict(
        verdicts=len(verdicts), **counts, seconds=round(seconds, 1),
        # CPU seconds of the process (user + system): the machine's load inflates the
        # wall time, not this
        cpu_seconds=round(usage.ru_utime + usage.ru_stime, 1),
        # the solves' own wall times: with two at a time their sum exceeds `seconds`
        solve_seconds=round(sum(s["seconds"] for s in nb["solves"]), 1),
        solves=len(nb["solves"]),
        checks_passed=sum(c["passed"] for c in nb["checks"]))
    result["notes"] = ([f"FAILED: {error}"] if error else []) + [
        f"{s['label']}: {s['not_converged']} steps not converged"
        for s in nb["solves"] if s["not_converged"]] + [
        f"{s['label']}: jc.TimeStepWarning (an unstable step: Fig. 8d's, or the 9 "
        "points of the CI size)"
        for s in nb["solves"] if s["time_step_warning"]]
    result["checks"] = nb["checks"]
    result["solves"] = nb["solves"]

    name = args.name or (result["machine"]["name"]
                         + ("" if variant is None else f"_{variant}"))
    path = write_results(result, args.out / f"{name}.json")
    print(f"wrote {path}: " + ", ".join(f"{n} {v}" for v, n in counts.items())
          + f" of {len(verdicts)} at {nb['grid']}^2, {seconds:.0f} s")
    if error:
        print(f"the run FAILED ({error}): the results file says so; pages not "
              "regenerated", file=sys.stderr)
        return 1
    if not args.no_pages and args.out.resolve() == (RESULTS / "paper").resolve():
        import paper_page

        paper_page.main([])
    return 0


if __name__ == "__main__":
    sys.exit(main())
