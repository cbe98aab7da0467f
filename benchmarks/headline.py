"""The headline tables of `benchmarks/README.md` and of the project's `README.md`,
generated from `results/`: one row a number, each read from the results file named
beside it, none typed by hand. The project README's table names the script that made
each number instead of the file.

    python benchmarks/headline.py           # print the table
    python benchmarks/headline.py --write   # write both READMEs' tables
    python benchmarks/headline.py --check   # exit 1 if either README's table is stale
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import HERE, RESULTS, load_results  # noqa: E402


README = HERE / "README.md"
PROJECT_README = HERE.parent / "README.md"
BEGIN = "<!-- headline.py: begin -->"
END = "<!-- headline.py: end -->"
MACHINES = {"intel_xeon": "Intel Xeon", "amd_epyc": "AMD EPYC", "h200": "one H200",
            "unknown": "machine not recorded"}


def _row(record, part=None, **match):
    """The one row of `record` (tagged `part`, if given) whose keys equal `match`."""
    rows = [r for r in record["rows"] if (part is None or r.get("part") == part)
            and all(r.get(k) == v for k, v in match.items())]
    if len(rows) != 1:
        raise LookupError(f"{record['benchmark']}: {len(rows)} rows match "
                          f"part={part!r} {match}")
    return rows[0]


def _range(values, fmt):
    lo, hi = min(values), max(values)
    return f"{lo:{fmt}}-{hi:{fmt}}" if f"{lo:{fmt}}" != f"{hi:{fmt}}" else f"{lo:{fmt}}"


def hertz(r):
    row = _row(r, "hertz", n=512, dtype="float64")
    return (f"{row['solve_s']:.3f} s, {row['iterations']} CG iterations, peak pressure "
            f"{row['errors']['peak_pressure_rel']:+.1e}")


def peers(r):
    ratio = {c["peer"]: c["ratio_best"] for c in r["summary"]["peer_time_ratios"]
             if c["n"] == 512 and c["threads"] == "default"}
    return (f"{ratio['tamaas']:.1f}x / {ratio['contactmechanics']:.1f}x jaxcontact's "
            "time (best of the repeats)")


def coupled(r):
    row = _row(r, "normal_vs_coupled")
    return (f"{row['ratio']:.1f}x a normal solve ({row['coupled_full_s']:.2f} s, "
            f"{row['iterations']} iterations; uncoupled: "
            f"{row['ratio_uncoupled']:.1f}x)")


def spence(r):
    a, b = _row(r, "spence"), _row(r, "spence_float32")
    return (f"{a['solve_s']:.2f} / {b['solve_s']:.2f} s, {a['iterations_total']} / "
            f"{b['iterations_total']} iterations, c/a {a['c_over_a_final']:.5f} / "
            f"{b['c_over_a_final']:.5f}")


def creep(r):
    si = _row(r, "d_target_scene")["systems"]["SI (m, N, Pa)"]
    return (f"{si['solve_s']:.2f} s, {si['iterations']} iterations, contact radius "
            f"within {100 * si['a_area_rel_error_max']:.2f} % of Lee-Radok")


def contact(r):
    ratios = [row["ratio_contact_over_jaxcontact"] for row in r["rows"]
              if row["kind"] == "spence" and row["rtol"] == 1e-8]
    return f"{_range(ratios, '.2f')}x (CONTACT's time over jaxcontact's second call)"


def aspher(r):
    ratio = [r["summary"][n]["ratios"]["1e-05 best aspher / float64"]
             for n in ("512", "1024")]
    return f"{ratio[0]:.2f}x / {ratio[1]:.2f}x jaxcontact's time (float64)"


def gpu_rough(r):
    row = _row(r, case="normal", scene="rough", n=4096, dtype="float64")
    return f"{row['best_s']:.3f} s, {row['iterations']} iterations"


def joint(r):
    e, v = r["summary"]["elastic"], r["summary"]["viscoelastic"]
    return (f"{e['cases']} elastic scenes, {e['total_iterations']} iterations; "
            f"{v['cases']} viscoelastic, {v['total_iterations']}; fallbacks "
            f"{e['fallbacks'] + v['fallbacks']}")


def gradients(r):
    return f"{_range([row['ratio'] for row in r['rows']], '.2f')}x the forward run"


def gradient_matrix(r):
    c = r["summary"]["counts"]
    return (f"{len(r['rows'])} scenes: {c['right']} right, {c['kink']} on a kink, "
            f"{c['refused']} refused naming the cause, {c['wrong']} wrong")


def fit(r):
    return f"{_row(r)['fit_s_compiled']:.2f} s compiled"


def fit_cli(r):
    row = _row(r, file="creep", setting="defaults")
    e = row["E_at_approach_Pa"]
    return f"E(T) {e['value']:.0f} +- {e['std']:.0f} Pa, {row['seconds']:.0f} s"


def ring_fit(r):
    rings = _row(r, "synthetic", solver="rings", size=64)["fit_s_compiled"]
    grid = _row(r, "synthetic", solver="grid", size=64)["fit_s_compiled"]
    return f"{rings:.2f} s compiled on 64 rings ({grid:.1f} s on 64^2)"


def paper(r):
    c = r["summary"]
    return (f"{c['holds']} hold, {c['partly']} partly, {c['differs']} differ of "
            f"{c['verdicts']}; {c['seconds']:.0f} s")


def force_map(r):
    row = r["rows"][0]
    return (f"{row['wall_s'] / 60:.1f} min for {row['curves']} curves, compilation "
            f"included ({row['wall_per_curve_s']:.2f} s a curve)")


# (results file, what it measures, the function that reads its number)
ENTRIES = [
    ("run/amd_epyc_full.json", "Hertz, 512^2, float64", hertz),
    ("run/amd_epyc_full.json", "Tamaas (periodic) / ContactMechanics at matched "
     "error, 512^2", peers),
    ("cattaneo/amd_epyc.json", "fully coupled partial slip, one step, 256^2",
     coupled),
    ("cattaneo/amd_epyc.json", "Spence, 105^2, 90 increments, float64 / float32",
     spence),
    ("viscoelastic/amd_epyc.json", "standard linear solid creep, 256^2 x 150 steps",
     creep),
    ("contact_peer/intel_xeon.json", "CONTACT on Spence (4 scenes, 113^2, 90 "
     "stages), rtol 1e-8", contact),
    ("aspher_peer/amd_epyc_rough.json", "best ASPHER mode, rough sphere, equal "
     "error 1e-5, 512^2 / 1024^2", aspher),
    ("gpu/h200.json", "rough sphere, 4096^2, float64", gpu_rough),
    ("joint_robustness/unknown.json", "strong coupling, small stick zones", joint),
    ("gradients/amd_epyc_128.json", "gradient of 50 steps, 128^2, 8 scenes",
     gradients),
    ("gradient_matrix/intel_xeon.json", "gradients against central differences, "
     "grid solver", gradient_matrix),
    ("gradient_matrix/intel_xeon_rings.json", "the same, ring solver",
     gradient_matrix),
    ("fit/intel_xeon_lm.json", "Prony fit of the PMMA step, 64^2 x 40, LM", fit),
    ("fit_cli_real_files/intel_xeon.json", "`jaxcontact fit` on the creep file",
     fit_cli),
    ("rings/intel_xeon.json", "Prony fit of the PMMA step on rings, 40 samples",
     ring_fit),
    ("force_map/intel_xeon_tile64.json", "`jc.fit_force_map`, a 64 x 64 map (the "
     "QI file's 4 curves tiled, noise added)", force_map),
    ("paper/intel_xeon.json", "the paper's claims at 256^2 (`paper.py`)", paper),
]


def _when(record) -> str:
    if record["date"] != "unknown":
        return record["date"][:10]
    return f"{record['converted_from']['commit_date']} (committed)"


def _script(record) -> str:
    """The benchmark script and options that wrote `record` (its `command`)."""
    command = record.get("command", "unknown")
    return f"{record['benchmark']}.py" if command == "unknown" else command


def table(results: Path = RESULTS, project: bool = False) -> str:
    """The headline table, read from `results`; `project`: the project README's,
    naming the script (in `benchmarks/`) instead of the results file."""
    last = "benchmark" if project else "results file"
    lines = [f"| case | result | machine, date | {last} |", "|---|---|---|---|"]
    for path, case, read in ENTRIES:
        record = load_results(results / path)
        machine = MACHINES.get(record["machine"]["name"], record["machine"]["name"])
        source = _script(record) if project else path
        lines.append(f"| {case} | {read(record)} | {machine}, {_when(record)} | "
                     f"`{source}` |")
    return "\n".join(lines)


def readme_block(text: str) -> str:
    """The generated block of a README's `text` (between the markers)."""
    return text[text.index(BEGIN) + len(BEGIN):text.index(END)].strip("\n")


def _targets():
    """(README path, its table) for both READMEs."""
    return [(README, table()), (PROJECT_README, table(project=True))]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="write it into README")
    parser.add_argument("--check", action="store_true",
                        help="exit 1 if the README's table differs from results/")
    args = parser.parse_args(argv)
    if args.check:
        stale = [str(path) for path, new in _targets()
                 if readme_block(path.read_text()) != new]
        print(f"stale: {', '.join(stale)}; run benchmarks/headline.py --write"
              if stale else "current")
        return int(bool(stale))
    if args.write:
        for path, new in _targets():
            text = path.read_text()
            start, end = text.index(BEGIN) + len(BEGIN), text.index(END)
            path.write_text(text[:start] + "\n" + new + "\n" + text[end:])
            print(f"wrote {path}")
    else:
        print(table())
    return 0


if __name__ == "__main__":
    sys.exit(main())
