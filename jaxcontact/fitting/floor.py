"""What ANY Prony series of the model can reach on a curve: the closed-form floor.

While the contact radius grows or holds (approach and hold), the contact model of a
sphere or a cone on a linear viscoelastic half-space is Lee & Radok's closed form
(`u = depth^m`, `m` 3/2 or 2), linear in the moduli for given relaxation times
(`jaxcontact._lee_radok`). Fitted to the RAW
samples by variable projection (times on a log grid of 20, every combination of
`arms` of them), it gives the best misfit a Prony series of `arms` arms can reach,
free of the grid's bias and of the binning. Reported in units of the raw white noise,
segment by segment, for the approach and hold fitted together and for the hold alone
(the approach still drives the history), so a verdict can say whether a misfit is the
fit's (the floor is lower) or the model's (the floor is as high: no Prony series of
this model reproduces the segment).

Creep curves (force imposed) are compared in depth, relaxation curves in force.
"""

import numpy as np

from .._lee_radok import lee_radok_columns, lee_radok_fit


SEGMENTS = ("approach", "hold")


def closed_form_floor(curve, *, arms=3, max_samples=600, exponent=1.5) -> dict:
    """The closed-form floor of an `AFMCurve` (`jc.read_afm`) with `arms` arms, for a
    probe of the law `F ~ depth^exponent` (1.5: a sphere, 2: a cone):
    `{"arms", "joint": {segment: rms / noise}, "hold_alone": rms / noise or None}`
    over the raw approach and hold samples (each thinned evenly to `max_samples`),
    `noise` the raw white noise of the fitted quantity (`AFMCurve.noise`). Empty
    dicts when the curve has too few samples."""
    keep = np.zeros(curve.time.shape, bool)
    for code in (0, 1):
        idx = np.flatnonzero(curve.segment == code)
        keep[idx[:: max(1, -(-idx.size // max_samples))]] = True
    t, f, d, s = (x[keep] for x in (curve.time, curve.force, curve.depth,
                                    curve.segment))
    mode = curve.mode
    kind = "depth" if mode == "creep" else "force"
    noise = curve.noise(kind)
    out = {"arms": arms, "joint": {}, "hold_alone": None,
           "note": (f"the closed-form Lee & Radok model ({arms} arms) fitted to the "
                    "raw samples: the best any Prony series of the model reaches, "
                    "in units of the raw white noise")}
    if t.size < 2 * arms + 4 or t[0] > 0:
        return out
    joint = _residual(t, f, d, mode, arms, 0, exponent)
    if joint is not None:
        out["joint"] = {name: float(np.sqrt(np.mean(joint[s == code] ** 2)) / noise)
                        for code, name in enumerate(SEGMENTS) if (s == code).any()}
    hold = np.flatnonzero(s == 1)
    if hold.size > 2 * arms + 2:
        alone = _residual(t, f, d, mode, arms, int(hold[0]), exponent)
        if alone is not None:
            out["hold_alone"] = float(np.sqrt(np.mean(alone[hold] ** 2)) / noise)
    return out


def _residual(t, f, d, mode, arms, start, exponent):
    """`(n,)` model - data [N or m] of the best closed-form series counted from
    sample `start` on (the model runs from the first), or None."""
    _, taus, c = lee_radok_fit(t, f, d, mode, arms=arms, start=start,
                               exponent=exponent)
    if c is None:
        return None
    u = np.clip(d, 0.0, None) ** exponent
    if mode == "relaxation":
        return lee_radok_columns(t, u, taus) @ c - f
    cols = lee_radok_columns(t, f, taus)
    cols = np.concatenate([cols[:, :1], cols[:, :1] - cols[:, 1:]], axis=1)
    return np.clip(cols @ c, 0.0, None) ** (1 / exponent) - d
