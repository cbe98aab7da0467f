"""Write the paper-reproduction pages from the committed results files.

`benchmarks/paper.py` writes `results/paper/<machine>.json` (the paper size, 256^2) and
`results/paper/<machine>_small.json` (64^2). This module turns the newest file of each
size into two pages with the same content: `benchmarks/paper_reproduction.md` and
`docs/paper.md` (the docs site's page; only the figure paths differ). Every study of
the paper in paper order: the paper's claim, the criterion, the quantity computed,
our number and verdict at both sizes, the cause of every `partly` and `differs`, the
figure of the paper-size run, and a final table. Every number comes from the results
files; nothing is typed by hand.

    python benchmarks/paper_page.py            # writes both pages
    python benchmarks/paper_page.py --check    # exit 1 if a page is out of date

Needs only the standard library.
"""

import argparse
import json
import re
import sys
from pathlib import Path


HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
RESULTS = HERE / "results" / "paper"
FIGURES = RESULTS / "figures"
PAGE = HERE / "paper_reproduction.md"
DOCS_PAGE = ROOT / "docs" / "paper.md"
# where each page finds the figures
FIGURE_PREFIX = {PAGE: "results/paper/figures/",
                 DOCS_PAGE: "../benchmarks/results/paper/figures/"}
SIZE_LABEL = {"paper": "256^2", "small": "64^2", "ci": "16^2"}


def load(path):
    with open(path, encoding="utf-8") as f:
        return json.load(f)


def tables():
    """{size: (path, results)}: the newest results file of each size."""
    found = {}
    for path in sorted(RESULTS.glob("*.json")):
        table = load(path)
        size = table["settings"]["size"]
        if size not in found or table["date"] > found[size][1]["date"]:
            found[size] = (path, table)
    if not {"paper", "small"} & set(found):
        raise FileNotFoundError(f"no results file in {RESULTS}: run python "
                                "benchmarks/paper.py --size paper (and --size small)")
    return found


def sizes(found):
    """(the main size, the other or None): the paper size first, where run."""
    present = [size for size in ("paper", "small") if size in found]
    return present[0], (present[1] if len(present) > 1 else None)


def figures_for(study, names):
    """The paper-size PNGs of a study: those named `paper_figNN_...` for the study's
    figure number (all of them), else the one whose range `NN_MM` holds it; the
    conclusion's `paper_conclusions_...`; none for the tables."""
    if study.startswith("Conclusions"):
        return tuple(n for n in names if n.startswith("paper_conclusions"))
    m = re.match(r"Fig\. (\d+)", study)
    if not m:
        return ()
    number = int(m.group(1))
    exact, ranged = [], []
    for name in names:
        f = re.match(r"paper_fig(\d+)(?:_(\d+))?_", name)
        if not f:
            continue
        lo = int(f.group(1))
        hi = int(f.group(2)) if f.group(2) else lo
        if lo == number:
            exact.append(name)
        elif lo <= number <= hi:
            ranged.append(name)
    return tuple(sorted(exact) or sorted(ranged)[:1])


def cell(text):
    return str(text).replace("|", "/").replace("\n", " ")


def counts(table):
    s = table["summary"]
    return (f"{s['holds']} hold, {s['partly']} partly, {s['differs']} differ of "
            f"{s['verdicts']}")


def provenance(size, path, table):
    m, st = table["machine"], table["settings"]
    load = m.get("load_before")
    return (
        f"- **{SIZE_LABEL.get(size, size)}** (`{path.relative_to(ROOT)}`): "
        f"{counts(table)}; grid {st['grid']}^2 (grid studies on "
        f"{', '.join(f'{n}^2' for n in st['grids'])}, Fig. 24's added rows on "
        f"{st['fig24_study_grid']}^2 and {st['fig24_extra_grid']}^2); "
        f"{m['processor']}, "
        f"{m['cpu_count_usable']} usable CPUs, {m['backend']}, "
        f"{st.get('threads', 1)} solve{'s' if st.get('threads', 1) > 1 else ''} "
        "at a time; "
        f"jax {table['versions']['jax']}, {st['dtype']}; "
        f"commit `{str(table['commit'])[:7]}`"
        + (" (jaxcontact/ modified)" if table["dirty"] else "")
        + f", {table['date']}; **{table['summary']['seconds']:.0f} s** for the whole "
        + (f"run, {table['summary']['cpu_seconds']:.0f} CPU seconds ("
           if "cpu_seconds" in table["summary"] else "run (")
        + f"{table['summary']['solves']} solves, "
        f"{table['summary']['checks_passed']} checks passed)"
        + (f"; load average before {load[0]:.1f}" if load else "")
        + f"; `{table['command']}`")


def render(found, prefix):
    main, other = sizes(found)
    paper = found[main][1]
    small = found[other][1] if other else {"rows": []}
    by_small = {v["study"]: v for v in small["rows"]}
    by_paper = {v["study"]: v for v in paper["rows"]}
    names = sorted(p.name for p in FIGURES.glob("paper_*.png"))
    order = [v["study"] for v in paper["rows"]]
    order += [s for s in by_small if s not in order]

    out = [
        "# The paper, study by study",
        "",
        "<!-- generated by benchmarks/paper_page.py from benchmarks/results/paper/; "
        "do not edit by hand -->",
        "",
        "Wang, de Boer & Ghanbarzadeh, *A Numerical Model for Investigating the Effect "
        "of Viscoelasticity on the Partial Slip Solution*, reproduced with "
        "`jaxcontact` by `notebooks/paper_reproduction.py`: every study in the "
        "paper's order, with the paper's claim, the criterion (what counts as `holds`, "
        "with the threshold and the grid, step or step-to-step spread it is compared "
        "with), the quantity computed, our number and the verdict: `holds`, `partly` "
        "(part of the claim holds, part does not or is below resolution) or "
        "`differs`, with the cause the run computes. Moduli are true shear moduli "
        "(the paper lists 2 G); the slip law is the paper's total form (Eq. 16) "
        "unless a study says otherwise. The figures are those of the paper-size run.",
        "",
        "One command reproduces it and regenerates this page:",
        "",
        "```bash",
        "python benchmarks/paper.py --size paper   # or small (64^2), ci (16^2)",
        "```",
        "",
        "Results files:",
        "",
    ]
    for size in (main, other):
        if size:
            out.append(provenance(size, *found[size]))
    out.append("")

    sections = []  # (figures, [studies]) in the order of first appearance
    for study in order:
        figs = figures_for(study, names)
        key = figs or (study,)
        if sections and sections[-1][0] == key:
            sections[-1][1].append(study)
        else:
            sections.append((key, [study]))
    for key, studies in sections:
        title = ", ".join(studies)
        out += [f"## {title}", ""]
        for name in key:
            if name.endswith(".png"):
                out += [f"![{name}]({prefix}{name})", ""]
        for study in studies:
            vp, vs = by_paper.get(study), by_small.get(study)
            v = vp or vs
            if len(studies) > 1:
                out += [f"### {study}", ""]
            out += [
                f"- **The paper:** {v['claim']}.",
                f"- **Criterion:** {v['criterion']}.",
                f"- **Computed:** {v['quantity']}.",
            ]
            for size, row in ((main, vp), (other, vs)):
                if size is None:
                    continue
                text = ("not run at this size" if row is None
                        else f"**{row['verdict']}**: {row['ours']}")
                if row and row["verdict"] != "holds":
                    text += f" (the paper: {row['paper']})"
                out.append(f"- **{SIZE_LABEL[size]}:** {text}")
            why = (vp or {}).get("why") or (vs or {}).get("why")
            if why:
                differs = (vp or vs)["verdict"] == "differs"
                label = "Why it differs" if differs else "Why"
                out.append(f"- **{label}:** {why}.")
            out.append("")

    out += [
        "## The verdict table",
        "",
        f"| study | the paper's claim | criterion | {SIZE_LABEL.get(other, '-')} | "
        f"{SIZE_LABEL[main]} | ours at {SIZE_LABEL[main]} |",
        "|---|---|---|---|---|---|",
    ]
    for study in order:
        vp, vs = by_paper.get(study), by_small.get(study)
        v = vp or vs
        out.append(
            f"| {cell(study)} | {cell(v['claim'])} | {cell(v['criterion'])} | "
            f"{vs['verdict'] if vs else '-'} | **{vp['verdict'] if vp else '-'}** | "
            f"{cell(vp['ours']) if vp else '-'} |")
    out.append("")
    return "\n".join(out)


def pages():
    found = tables()
    return {page: render(found, prefix) for page, prefix in FIGURE_PREFIX.items()}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true",
                        help="exit 1 if a page differs from what the results give")
    args = parser.parse_args(argv)
    stale = []
    for page, text in pages().items():
        current = page.read_text(encoding="utf-8") if page.exists() else ""
        if args.check:
            if current != text:
                stale.append(page)
            continue
        page.write_text(text, encoding="utf-8")
        print(f"wrote {page}")
    for page in stale:
        print(f"{page} is out of date: run python benchmarks/paper_page.py",
              file=sys.stderr)
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
