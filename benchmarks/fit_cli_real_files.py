"""`jaxcontact fit` on the two real AFM files: the numbers the README and the fitting
guide quote, from the command they show, and the two-settings check of the
uncertainty.

For each file of `tests/data/` (creep: polymer gel, force clamp; relaxation: cell,
height clamp; probe radius 5 um as everywhere in the docs) it runs, as a user would,

    jaxcontact fit FILE --radius 5e-6 --out DIR --overwrite        (the defaults)
    jaxcontact fit FILE --radius 5e-6 --samples 16,48,8 ...        (twice the bins)
    jaxcontact fit FILE --radius 5e-6 --rings 128 ...              (twice the rings)
    jaxcontact fit FILE --radius 5e-6 --solver grid [--n 48] ...   (grid 32^2, 48^2)
    jaxcontact fit FILE --radius 5e-6 --segments approach,hold,retract ...

and keeps from each JSON the quality verdict, the flags, the Young's moduli with their
total standard deviation (optimiser, contact point, grid), the apparent Hertz modulus,
the wall time and the console summary. The check: a modulus `q` of two settings
agrees when `|log q_a - log q_b| <= sqrt(s_a^2 + s_b^2)` (`s`: each run's reported std
of `log q`), i.e. the difference is within the reported uncertainty.

    python benchmarks/fit_cli_real_files.py [--only creep|relaxation] [--settings a,b]
                                            [--write-docs] [--tables]

Writes `benchmarks/results/fit_cli_real_files/<machine>.json` (`--out`; layout:
`results/SCHEMA.md`: a row per file and setting, with its console text; the agreement
checks in `summary`) and prints the tables; `--write-docs` also writes
them into `docs/guides/fitting.md` (between its markers), so no number there is typed
by hand.
About 20 minutes on a 2-core CPU (the fits).
"""

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path


sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import header, load_results, results_path, write_results  # noqa: E402


ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "tests" / "data"
FILES = {"creep": DATA / "fmt-jpk-cc_pr14-polymergel-2021.06.30.jpk-force",
         "relaxation": DATA / "fmt-jpk-sr_cell1-0008.jpk-force"}
SETTINGS = {"defaults": [], "bins x2": ["--samples", "16,48,8"],
            "rings 128": ["--rings", "128"],
            "grid 32": ["--solver", "grid"], "n 48": ["--solver", "grid", "--n", "48"],
            "with retract": ["--segments", "approach,hold,retract"]}
MODULI = ("E_at_approach_Pa", "E_inf_Pa", "E_0_Pa")
BEGIN = "<!-- fit_cli_real_files.py: begin -->"
END = "<!-- fit_cli_real_files.py: end -->"


def run_cli(path, extra, out):
    """One `jaxcontact fit` process: (report dict, console text, seconds, exit)."""
    cmd = [sys.executable, "-m", "jaxcontact", "fit", str(path), "--radius", "5e-6",
           "--out", str(out), "--overwrite", *extra]
    start = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    seconds = time.perf_counter() - start
    if proc.returncode not in (0, 1):
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{proc.stderr}")
    report = json.loads((Path(out) / f"{path.stem}_fit.json").read_text())
    return report, proc.stdout, seconds, proc.returncode


def agreement(a, b):
    """`{modulus: {a, b, std_log_a, std_log_b, z}}`, `z = |log a - log b| /
    sqrt(s_a^2 + s_b^2)`: the two settings agree within their uncertainty at z <= 1."""
    out = {}
    for key in MODULI:
        ea, eb = a["youngs_moduli"][key], b["youngs_moduli"][key]
        sa, sb = ea["std_log"], eb["std_log"]
        diff = abs(math.log(ea["value"] / eb["value"]))
        scale = math.hypot(sa, sb) if sa is not None and sb is not None else math.inf
        out[key] = {"a": ea["value"], "b": eb["value"], "std_log_a": sa,
                    "std_log_b": sb, "log_difference": diff,
                    "z": diff / scale if scale > 0 else math.inf}
    return out


def row(name, setting, report, seconds, code):
    e = report["youngs_moduli"]
    return {
        "file": name, "setting": setting, "seconds": seconds, "exit": code,
        "arms": report["arms"], "quality": report["quality"]["verdict"],
        "by_segment": report["quality"]["by_segment"], "flags": report["flags"],
        "caveats": report["caveats"],
        **{key: {"value": e[key]["value"], "std": e[key]["std"],
                 "std_log": e[key]["std_log"],
                 "components": e[key].get("std_log_components")} for key in MODULI},
        "apparent_hertz_E_Pa": report["apparent_hertz"]["E_Pa"],
        "taus_s": [t["value"] for t in report["parameters"]["tau_s"]],
        "grid_bias_over_noise": report["discretisation_over_noise"],
        "contact_uncertainty_samples": (report["uncertainty"] or {}).get(
            "components", {}).get("contact", {}).get("samples"),
    }


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--only", choices=sorted(FILES), help="one file only")
    p.add_argument("--settings", default=",".join(SETTINGS),
                   help=f"comma-separated among {list(SETTINGS)}")
    p.add_argument("--write-docs", action="store_true",
                   help="write the tables into docs/guides/fitting.md")
    p.add_argument("--tables", action="store_true",
                   help="print the tables of the stored result (--out) only (no fits)")
    p.add_argument("--out", default=None, help="JSON path (default "
                   "results/fit_cli_real_files/<machine>.json)")
    args = p.parse_args()
    if args.tables:
        result = load_results(args.out or results_path("fit_cli_real_files"))
        print(tables(result))
        if args.write_docs:
            write_docs(result)
        return
    names = [args.only] if args.only else list(FILES)
    chosen = [s.strip() for s in args.settings.split(",")]
    rows, checks = [], {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            reports = {}
            for setting in chosen:
                report, text, seconds, code = run_cli(
                    FILES[name], SETTINGS[setting], Path(tmp) / setting)
                reports[setting] = report
                rows.append({**row(name, setting, report, seconds, code),
                             "console": text})
                print(text, f"[{seconds:.0f} s, exit {code}]", flush=True)
            for other in chosen[1:]:
                checks[f"{name}: defaults vs {other}"] = agreement(
                    reports[chosen[0]], reports[other])
    partial = args.only or len(chosen) < len(SETTINGS)
    variant = "_".join(([args.only] if args.only else []) + (
        [s.replace(" ", "") for s in chosen] if len(chosen) < len(SETTINGS) else []))
    result = {**header("fit_cli_real_files", variant=variant if partial else None),
              "settings": {"cli": {k: SETTINGS[k] for k in chosen}, "radius_m": 5e-6},
              "rows": rows, "summary": {"agreement": checks}}
    print(f"-> {write_results(result, args.out)}")
    print(tables(result))
    if args.write_docs:
        write_docs(result)


def tables(result) -> str:
    """The Markdown tables of a result: a row a run, then the agreement checks."""
    m = result["machine"]
    lines = [f"`jaxcontact fit FILE --radius 5e-6` on {m['cpu_count']} cores "
             f"({m['processor']}), jaxcontact {result['commit'][:7]}, float64; +- the "
             "reported total std (optimiser, contact point, grid); s: the whole "
             "process's wall time.", "",
             "| file | setting | arms | quality (approach, hold x the noise) | "
             "E(T_app) [Pa] | E_inf [Pa] | E_0 [Pa] | Hertz E [Pa] | flags | s |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in result["rows"]:
        cells = [f"{r[k]['value']:.4g} +- {r[k]['std']:.2g}" if r[k]["std"] is not None
                 else f"{r[k]['value']:.4g}" for k in MODULI]
        seg = ", ".join(f"{v:.3g}" for v in r["by_segment"].values())
        lines.append(f"| {r['file']} | {r['setting']} | {r['arms']} | {r['quality']} "
                     f"({seg}) | " + " | ".join(cells)
                     + f" | {r['apparent_hertz_E_Pa']:.4g} | {len(r['flags'])} | "
                     f"{r['seconds']:.0f} |")
    lines += ["", "Agreement of each setting with the defaults: `z = |log a - log b| / "
              "sqrt(s_a^2 + s_b^2)` (within the reported uncertainty at z <= 1).", "",
              "| check | " + " | ".join(f"z {k.removesuffix('_Pa')}" for k in MODULI)
              + " |", "|---|" + "---|" * len(MODULI)]
    for name, c in result["summary"]["agreement"].items():
        lines.append(f"| {name} | " + " | ".join(f"{c[k]['z']:.2f}" for k in MODULI)
                     + " |")
    return "\n".join(lines)


def write_docs(result):
    """Replace the generated block of docs/guides/fitting.md by `tables(result)`."""
    path = ROOT / "docs" / "guides" / "fitting.md"
    text = path.read_text()
    start, end = text.index(BEGIN) + len(BEGIN), text.index(END)
    path.write_text(text[:start] + "\n" + tables(result) + "\n" + text[end:])
    print(f"-> {path}")


if __name__ == "__main__":
    main()
