"""How well can a linear viscoelastic half-space under a sphere reproduce the two real
AFM files (issue 29, item 6: "the model with the fitted parameters reproduces the hold
segment to within the noise estimated from the curve, residual RMS / noise <= 1.5")?

Everything here runs on the RAW samples (1 kHz creep file, 2 kHz relaxation file),
with the closed-form Lee & Radok model, which the full contact model reproduces while
the contact radius grows or holds (approach and hold): for a sphere, `u = depth^(3/2)`,

- relaxation (depth imposed): `F(t) = int G_app(t - s) du(s)`, `G_app = c_inf + sum
  c_i exp(-t / tau_i)`;
- creep (force imposed): `u(t) = int J_app(t - s) dF(s)`, `J_app = c_0 + sum c_i (1 -
  exp(-t / tau_i))`,

linear in the `c` for given times (variable projection: the times by
`scipy.optimize.least_squares`, the `c` by linear least squares; three starts). So
the numbers are the best any Prony series with that many arms can do, free of the
full model's grid and of the fit's binning. Reported in units of the raw curve's
white noise `sigma` (successive differences, `AFMCurve.noise`):

- `floor`: approach + hold fitted together (what `jaxcontact fit` does), per arm count
  and contact method (`read_afm(contact=...)`): RMS of the residual over the hold,
  over the hold after its first 0.5 s, and over the approach; and the residual's own
  white noise (successive differences of the residual: the data's noise plus the
  input's noise carried through the model) and its low-frequency part (a 50 ms
  moving average);
- `hold_only`: the hold alone fitted (the relaxation file: approach and hold are not
  one linear viscoelastic response);
- `exponent`: the relaxation file with `u = depth^p` (a different indenter shape or a
  thickness effect), 2 arms;
- `baselines`: the curves' noise where nothing moves (the creep file's 2.8 s approach
  before contact, height detrended linearly; the relaxation file's 1 s pause): the
  standard deviation against the successive-difference estimate (equal for white
  noise);
- `full_model` (`--full`): the full contact model (`jc.solve`, scheme "linear") at
  the closed-form optimum of the binned creep data (8 + 24 bins) on 16^2, 32^2, 64^2
  grids against the closed form: the grid's bias, in units of sigma.

Usage::

    python benchmarks/fit_real_files.py [--full]

Writes `benchmarks/results/fit_real_files/<machine>.json` (without `--full`:
`<machine>_closed_form.json`; layout: `results/SCHEMA.md`: rows tagged by `part`,
`floor`, `hold_only`, `exponent`, `full_model`; the noise baselines in `summary`).
Radius 5 um and nu = 0.5 are assumed (they only scale the `c`).
"""

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np
import scipy.optimize as so
from _common import header, part_rows, write_results

import jaxcontact as jc


DATA = Path(__file__).parent.parent / "tests" / "data"
FILES = {"creep": DATA / "fmt-jpk-cc_pr14-polymergel-2021.06.30.jpk-force",
         "relaxation": DATA / "fmt-jpk-sr_cell1-0008.jpk-force"}
R, NU = 5e-6, 0.5


def columns(t, drive, taus):
    """The drive and `int exp(-(t - s) / tau) d drive(s)` per tau (piecewise linear,
    exact), the drive starting from 0 before `t[0]`."""
    t = np.r_[t[0] - 1e-9, t]
    drive = np.r_[0.0, drive]
    dt, dd = np.diff(t), np.diff(drive)
    out = [drive]
    for tau in taus:
        e = np.exp(-dt / tau)
        inc = dd / dt * tau * (1 - e)
        h = np.zeros_like(drive)
        for k in range(1, drive.size):
            h[k] = e[k - 1] * h[k - 1] + inc[k - 1]
        out.append(h)
    return np.stack(out, 1)[1:]


def design(t, f, d, taus, mode, p=1.5):
    u = np.clip(d, 0, None) ** p
    if mode == "relaxation":
        return columns(t, u, taus), f
    a = columns(t, f, taus)
    return np.concatenate([a[:, :1], a[:, :1] - a[:, 1:]], 1), u


def lr_fit(t, f, d, mode, arms, mask=None, p=1.5):
    """Best closed-form fit over `mask`; returns `(taus, residual on every sample in
    the units of the fitted quantity: force [N] or depth [m])`."""
    mask = np.ones(t.size, bool) if mask is None else mask
    span, first = t[-1] - t[0], np.min(np.diff(t))

    def solve(lt):
        a, y = design(t, f, d, np.exp(lt), mode, p)
        c, *_ = np.linalg.lstsq(a[mask], y[mask], rcond=None)
        return a @ c - y, a @ c

    best = None
    for lo, hi in ((10 * first, span), (3 * first, 3 * span), (30 * first, span / 3)):
        start = np.log(np.geomspace(lo, hi, arms + 2)[1:-1])
        r = so.least_squares(lambda x: solve(x)[0][mask], start, method="lm",
                             max_nfev=400)
        if best is None or r.cost < best.cost:
            best = r
    res, model = solve(best.x)
    if mode == "creep":  # back to depth
        res = np.cbrt(np.clip(model, 0, None)) ** 2 - np.clip(d, 0, None)
    return np.sort(np.exp(best.x)), res


def white(x):
    return float(np.median(np.abs(np.diff(x))) / (0.6745 * np.sqrt(2)))


def summary(res, seg, t, sigma):
    hold, app = seg == 1, seg == 0
    rh = res[hold]
    smooth = np.convolve(rh, np.ones(50) / 50, mode="valid")
    late = hold & (t > t[hold][0] + 0.5)
    return {
        "hold_rms_over_sigma": float(np.sqrt(np.mean(rh**2)) / sigma),
        "hold_after_0.5s_rms_over_sigma": float(np.sqrt(np.mean(res[late] ** 2))
                                                / sigma),
        "approach_rms_over_sigma": float(np.sqrt(np.mean(res[app] ** 2)) / sigma),
        "hold_residual_white_over_sigma": white(rh) / sigma,
        "hold_low_frequency_rms_over_sigma": float(np.sqrt(np.mean(smooth**2)) / sigma),
    }


def curve_arrays(curve):
    t, f, d, s = (x.copy() for x in (curve.time, curve.force, curve.depth,
                                      curve.segment))
    f[0] = d[0] = 0.0  # the model starts unloaded at contact (as the fit does)
    return t, f, d, s


def baselines():
    out = {}
    c = jc.read_afm(FILES["creep"])
    raw = c.raw
    sel = (raw["segment"] == 0) & (raw["time"] < c.contact_time - 0.05)
    tt, f, h = raw["time"][sel], raw["force"][sel], raw["height"][sel]
    h = h - np.polyval(np.polyfit(tt, h, 1), tt)
    f = f - f.mean()
    out["creep_approach_before_contact"] = {
        "duration_s": float(tt[-1] - tt[0]),
        "force_std_N": float(f.std()), "force_white_N": white(f),
        "height_detrended_std_m": float(h.std()), "height_white_m": white(h)}
    c = jc.read_afm(FILES["relaxation"])
    raw = c.raw
    sel = raw["segment"] == -1
    f = raw["force"][sel] - raw["force"][sel].mean()
    out["relaxation_pause"] = {
        "duration_s": float(raw["time"][sel][-1] - raw["time"][sel][0]),
        "force_std_N": float(f.std()), "force_white_N": white(f)}
    return out


def full_model(n_list=(16, 32, 64)):
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp

    c = jc.read_afm(FILES["creep"], segments=("approach", "hold"),
                    contact="viscoelastic")
    t, f, d, s, counts = c.resampled({"approach": 8, "hold": 24}, return_counts=True)
    w = np.sqrt(counts)

    def solve(lt):
        a, y = design(t, f, d, np.exp(lt), "creep")
        cc, *_ = np.linalg.lstsq(a * w[:, None], y * w, rcond=None)
        return (a @ cc - y) * w, cc

    best = min((so.least_squares(lambda x: solve(x)[0], np.log(st), method="lm")
                for st in ([0.1, 1.0], [0.01, 0.3])), key=lambda r: r.cost)
    taus, cc = np.exp(best.x), solve(best.x)[1]
    scale = 3 * (1 - NU) / (8 * np.sqrt(R))
    material = jc.Prony.from_creep((cc[0] + cc[1:].sum()) / scale, cc[1:] / scale, taus,
                                   NU)
    a, _ = design(t, f, d, taus, "creep")
    closed = np.cbrt(np.clip(a @ cc, 0, None)) ** 2
    sigma = c.noise("depth")
    hold = s == 1
    rows = []
    for n in n_list:
        template = c.scene_template(R, n=n)
        scene = jc.Scene(template.grid, template.indenter, material, jnp.asarray(t),
                         jc.Force(jnp.asarray(f)))
        start = time.perf_counter()
        sol = jc.solve(scene, scheme="linear", throw=False)
        approach = np.asarray(sol.approach)
        rows.append({"n": n, "solve_s_incl_compile": time.perf_counter() - start,
                     "converged": bool(np.all(sol.converged)),
                     "hold_rms_full_minus_closed_over_sigma": float(
                         np.sqrt(np.mean((approach - closed)[hold] ** 2)) / sigma),
                     "approach_rms_full_minus_closed_over_sigma": float(
                         np.sqrt(np.mean((approach - closed)[~hold] ** 2)) / sigma)})
        print(json.dumps(rows[-1]), flush=True)
    return {"sigma_m": sigma, "taus_s": taus.tolist(), "rows": rows}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--full", action="store_true",
                        help="also the full-model grid bias")
    parser.add_argument("--out", default=None, help="JSON path (default "
                        "results/fit_real_files/<machine>.json)")
    args = parser.parse_args()
    record = header("fit_real_files", variant=None if args.full else "closed_form")
    record["machine"]["load_average_before"] = os.getloadavg()
    record["settings"] = {"radius_m": R, "poisson": NU, "full": args.full}
    result = {"baselines": baselines(), "floor": [], "hold_only": [], "exponent": []}
    print(json.dumps(result["baselines"], indent=1), flush=True)
    for name, path in FILES.items():
        for contact in ("piecewise", "viscoelastic"):
            c = jc.read_afm(path, segments=("approach", "hold"), contact=contact)
            t, f, d, s = curve_arrays(c)
            kind = "force" if c.mode == "relaxation" else "depth"
            sigma = c.noise(kind)
            for arms in (1, 2, 3, 4):
                taus, res = lr_fit(t, f, d, c.mode, arms)
                row = {"file": name, "contact": contact,
                       "contact_time_s": c.contact_time, "arms": arms,
                       "sigma": sigma, "taus_s": taus.tolist(),
                       **summary(res, s, t, sigma)}
                result["floor"].append(row)
                print(json.dumps(row), flush=True)
    c = jc.read_afm(FILES["relaxation"], segments=("approach", "hold"))
    t, f, d, s = curve_arrays(c)
    sigma = c.noise("force")
    for arms in (1, 2, 3, 4, 5):
        taus, res = lr_fit(t, f, d, c.mode, arms, mask=s == 1)
        row = {"file": "relaxation", "arms": arms, "taus_s": taus.tolist(),
               **summary(res, s, t, sigma)}
        result["hold_only"].append(row)
        print(json.dumps(row), flush=True)
    for p in (1.25, 1.5, 1.75, 2.0):
        taus, res = lr_fit(t, f, d, c.mode, 2, p=p)
        row = {"file": "relaxation", "arms": 2, "exponent": p,
               **summary(res, s, t, sigma)}
        result["exponent"].append(row)
        print(json.dumps(row), flush=True)
    record["summary"] = {"baselines": result["baselines"]}
    record["rows"] = [row for part in ("floor", "hold_only", "exponent")
                      for row in part_rows(part, result[part])]
    if args.full:
        full = full_model()
        record["rows"] += part_rows("full_model", full.pop("rows"))
        record["summary"]["full_model"] = full
    record["machine"]["load_average_after"] = os.getloadavg()
    print("wrote", write_results(record, args.out))


if __name__ == "__main__":
    main()
