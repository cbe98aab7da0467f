"""jaxcontact against nanite on the two real AFM files (tests/data, see its README).

nanite (PyPI `nanite`, by the afmformats authors) is the AFM indentation tool users
already run: an elastic Hertz fit of the approach. This script measures, per file:

- nanite: load (`nanite.load_group`), preprocess with its command line's default
  pipeline (`PREPROCESSING`: `compute_tip_position`, `correct_force_offset`,
  `correct_tip_offset` by 'deviation_from_baseline'), fit `hertz_para` (the
  paraboloidal Hertz law: nanite's library default model, and the same indenter law as
  `jc.Sphere`) with its library defaults (`weight_cp` 1 um, the whole segment) to the
  file's approach segment, R = 5 um, nu = 0.5, free E, contact point and force
  baseline; its curve rating (`rate_quality`: Extra Trees, zef18 training set). For
  reference also: E with `correct_split_approach_retract` added (approach = segment 0
  up to the farthest point, which the rating's features assume), and E of
  `sneddon_spher_approx` (the sphere's truncated series: the default model of nanite's
  command line and of JPK's software). Wall times: the median of `--repeats` runs after
  one warm-up; load / preprocess / fit (initial parameters + lmfit) separately.
- ours: `jaxcontact fit FILE --radius 5e-6 --out DIR --overwrite`, timed as a
  subprocess (one run: interpreter start, JAX import, compilation or the persistent
  compilation cache, the fit; the cache's file count before and after says which),
  with its JSON's moduli and contact point.
- both: E ratios (ours / nanite's hertz_para) and the contact-point offsets on the
  file's own clock and height columns (positive: ours later / deeper in the approach).

nanite reads only force-distance curves by default (`nanite.read.DEFAULT_MODALITY =
"force-distance"`: `load_group` returns NO curve for these creep and relaxation files,
silently); it is set to None here, as nanite's own comment there says to.

Usage (needs `pip install "jaxcontact[afm,bench]"`; ~1-2 minutes, mostly our CLI)::

    python benchmarks/nanite_side_by_side.py [--repeats 5] [--keep DIR]

Writes `benchmarks/results/nanite_side_by_side/<machine>.json` (layout:
`results/SCHEMA.md`: a row per file, `curve` naming it; nanite's, afmformats' and
lmfit's versions beside ours).
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np


sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import header, write_results  # noqa: E402


ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "tests" / "data"
FILES = {"creep": DATA / "fmt-jpk-cc_pr14-polymergel-2021.06.30.jpk-force",
         "relaxation": DATA / "fmt-jpk-sr_cell1-0008.jpk-force"}
RADIUS, NU = 5e-6, 0.5
PREPROCESSING = ["compute_tip_position", "correct_force_offset", "correct_tip_offset"]
SPLIT = PREPROCESSING + ["correct_split_approach_retract"]
OPTIONS = {"correct_tip_offset": {"method": "deviation_from_baseline"}}
# (model, weight_cp [m]): nanite's library defaults (FP_DEFAULT) and its command line's
# (nanite.cli.profile.DEFAULTS).
LIBRARY, CLI = ("hertz_para", 1e-6), ("sneddon_spher_approx", 5e-7)


def nanite_fit(path, model=LIBRARY, preprocessing=PREPROCESSING):
    """Load, preprocess and fit the approach of one file; `(indentation, segment,
    (load, preprocess, fit) seconds)`. The approach: segment 0 after the split, else
    the file's own approach segment."""
    import nanite

    t0 = time.perf_counter()
    idnt = nanite.load_group(path)[0]
    t1 = time.perf_counter()
    segment = approach_segment(idnt) if preprocessing == PREPROCESSING else 0
    idnt.apply_preprocessing(preprocessing, options=OPTIONS)
    t2 = time.perf_counter()
    params = idnt.get_initial_fit_parameters(model_key=model[0])
    params["R"].set(value=RADIUS)
    params["nu"].set(value=NU)
    idnt.fit_model(model_key=model[0], params_initial=params, segment=segment,
                   weight_cp=model[1])
    t3 = time.perf_counter()
    if not idnt.fit_properties.get("success"):
        raise RuntimeError(f"nanite's fit of {path} failed")
    return idnt, segment, (t1 - t0, t2 - t1, t3 - t2)


def approach_segment(idnt):
    """The file's own approach segment (afmformats' numbering): the first whose height
    falls by more than half the curve's range (segment 1 after a pause)."""
    seg, h = idnt["segment"], idnt["height (measured)"]
    return next(int(s) for s in np.unique(seg)
                if h[seg == s][0] - h[seg == s][-1] > 0.5 * np.ptp(h))


def on_approach(idnt, segment, cp):
    """Time [s] and height (measured) [m] where the tip first reaches the tip position
    `cp` on the approach `segment`, between samples linearly; and the approach's
    `(time, tip position)` arrays."""
    sel = idnt["segment"] == segment
    t, h, tip = (idnt[c][sel] for c in ("time", "height (measured)", "tip position"))
    j = int(np.argmax(tip <= cp))
    if j == 0:
        return float(t[0]), float(h[0]), (t, tip)
    w = (tip[j - 1] - cp) / (tip[j - 1] - tip[j])
    return (float(t[j - 1] + w * (t[j] - t[j - 1])),
            float(h[j - 1] + w * (h[j] - h[j - 1])), (t, tip))


def rating(idnt):
    """nanite's rating (0..10) of a fitted curve, its error text, its seconds."""
    t0 = time.perf_counter()
    try:
        score, error = float(idnt.rate_quality(regressor="Extra Trees",
                                               training_set="zef18")), None
    except Exception as exc:  # noqa: BLE001 - reported, not raised
        score, error = None, f"{type(exc).__name__}: {exc}"
    return score, error, time.perf_counter() - t0


def run_nanite(path, repeats):
    nanite_fit(path)  # warm-up (imports, lmfit, file cache)
    times = np.array([nanite_fit(path)[2] for _ in range(repeats)])
    idnt, segment, _ = nanite_fit(path)
    p = idnt.fit_properties["params_fitted"]
    t_c, h_c, _ = on_approach(idnt, segment, p["contact_point"].value)
    rate, rate_error, rate_s = rating(idnt)
    split = nanite_fit(path, preprocessing=SPLIT)[0]
    sneddon = nanite_fit(path, model=CLI)[0].fit_properties["params_fitted"]
    med = np.median(times, axis=0)
    return idnt, segment, {
        "imaging_mode": idnt.metadata.get("imaging mode"),
        "segment": segment,
        "approach_samples": int(np.sum(idnt["segment"] == segment)),
        "E_Pa": p["E"].value,
        "E_std_Pa": p["E"].stderr,
        "contact_point_tip_m": p["contact_point"].value,
        "contact_time_s": t_c,
        "contact_height_m": h_c,
        "baseline_N": p["baseline"].value,
        "rating": rate,
        "rating_error": rate_error,
        "with_split": {"E_Pa": split.fit_properties["params_fitted"]["E"].value,
                       "approach_samples": int(np.sum(split["segment"] == 0)),
                       "rating": rating(split)[0]},
        "sneddon_spher_approx": {"E_Pa": sneddon["E"].value,
                                 "contact_point_tip_m": sneddon["contact_point"].value},
        "time_s": {"load": med[0], "preprocess": med[1], "fit": med[2],
                   "total": float(np.median(times.sum(axis=1))), "rating": rate_s,
                   "repeats": repeats, "statistic": "median after one warm-up"},
    }


def value(entry):
    """A modulus from our JSON: a number, or an entry dict's "value"; None if absent."""
    return entry.get("value") if isinstance(entry, dict) else entry


def cache_entries():
    """Files in our persistent compilation cache (warm or cold before a run)."""
    folder = Path(os.environ.get("JAXCONTACT_CACHE_DIR",
                                 Path.home() / ".cache" / "jaxcontact" / "xla"))
    return len(list(folder.glob("*"))) if folder.is_dir() else 0


def run_ours(path, out):
    cmd = [sys.executable, "-m", "jaxcontact", "fit", str(path.relative_to(ROOT)),
           "--radius", str(RADIUS), "--out", str(out), "--overwrite"]
    before = cache_entries()
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - t0
    js = Path(out) / f"{path.stem}_fit.json"
    row = {"command": " ".join(["jaxcontact"] + cmd[3:]), "wall_s": wall,
           "returncode": proc.returncode,
           "compilation_cache_files": [before, cache_entries()]}
    if not js.is_file():
        return {**row, "error": proc.stderr[-2000:]}
    r = json.loads(js.read_text())
    y = r["youngs_moduli"]
    return {**row, "converged": r.get("converged"), "arms": r.get("arms"),
            "E_0_Pa": value(y["E_0_Pa"]), "E_inf_Pa": value(y["E_inf_Pa"]),
            "E_at_approach_Pa": value(y.get("E_at_approach_Pa")),
            "apparent_hertz_E_Pa": (r.get("apparent_hertz") or {}).get("E_Pa"),
            "contact_time_s": r["contact_time_s"],
            "contact_point": r.get("contact_point"),
            "contact_note": r.get("contact_note")}


def compare(idnt, segment, nan, ours):
    """Ratios ours / nanite of E, and contact offsets (positive: ours deeper)."""
    def ratio(key):
        v = ours.get(key)
        return None if v is None else v / nan["E_Pa"]

    out = {f"{k}_over_nanite_E": ratio(k) for k in
           ("apparent_hertz_E_Pa", "E_at_approach_Pa", "E_0_Pa", "E_inf_Pa")}
    if ours.get("contact_time_s") is None:
        return out
    t_o = ours["contact_time_s"]
    _, _, (t, tip) = on_approach(idnt, segment, nan["contact_point_tip_m"])
    h_o = float(np.interp(t_o, idnt["time"], idnt["height (measured)"]))
    out.update({
        "contact_later_s": t_o - nan["contact_time_s"],
        "contact_deeper_height_m": nan["contact_height_m"] - h_o,
        "contact_deeper_tip_m": nan["contact_point_tip_m"] - float(np.interp(t_o, t,
                                                                              tip)),
        "note": ("height: height (measured) at each contact time; tip: nanite's tip "
                 "position (its own offset) at our contact time against its fitted "
                 "contact point"),
    })
    return out


def peer_versions():
    import importlib.metadata as md

    return {p: md.version(p) for p in ("nanite", "afmformats", "lmfit")}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--keep", help="folder for our CLI's outputs (default: temporary)")
    args = ap.parse_args()
    import nanite.read

    nanite.read.DEFAULT_MODALITY = None  # also creep / relaxation curves
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(args.keep or tmp)
        for name, path in FILES.items():
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                idnt, segment, nan = run_nanite(path, args.repeats)
            nan["warnings"] = sorted({f"{w.category.__name__}: {w.message}"
                                      for w in caught})
            ours = run_ours(path, out)
            rows.append({"curve": name, "file": str(path.relative_to(ROOT)),
                         "nanite": nan, "ours": ours,
                         "comparison": compare(idnt, segment, nan, ours)})
            print(json.dumps({name: rows[-1]["comparison"]}, indent=1), flush=True)
    result = header("nanite_side_by_side")
    result["versions"].update(peer_versions())
    result.update({
        "settings": {"what": __doc__.split("\n\n")[0],
                     "radius_m": RADIUS, "poisson": NU,
                     "nanite": {"preprocessing": PREPROCESSING, "options": OPTIONS,
                                "model": LIBRARY[0], "weight_cp_m": LIBRARY[1],
                                "segment": "the file's approach (afmformats)",
                                "range": "the whole segment",
                                "with_split": SPLIT,
                                "reference_model": {"model": CLI[0],
                                                    "weight_cp_m": CLI[1]},
                                "DEFAULT_MODALITY": None},
                     "ours": "jaxcontact fit defaults (1-3 arms by BIC, 32^2 grid, "
                             "viscoelastic contact, approach+hold, analysis "
                             "uncertainty)"},
        "rows": rows,
    })
    print(f"-> {write_results(result)}")


if __name__ == "__main__":
    main()
