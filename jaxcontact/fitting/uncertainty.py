"""The uncertainty of a fitted AFM curve that covers the analysis, not only the noise.

The optimiser's Gauss-Newton standard deviations (`PronyFit.std`) say how well the
binned data pin the parameters for a GIVEN analysis. Two choices of the analysis move
the parameters more on real files (`benchmarks/notes/fit_real_files.md`):

- the contact point: refit with it moved by its own uncertainty either way. That
  uncertainty, in samples, is the larger of (a) the distance between the piecewise
  (Lin et al.) and the viscoelastic contact points, two reasonable methods, and (b)
  the approach samples before the elastic force of the apparent modulus rises above
  the baseline's noise, `delta_sigma = (sigma_F / (k E*))^(1/m)` for the probe's law
  `F = k E* d^m` (a sphere: `k = 4/3 sqrt(R)`, `m = 3/2`; a cone: `k = 2 tan(alpha) /
  pi`, `m = 2`): a contact closer than that cannot be told from the baseline; at
  least 2 samples.
- the grid: refit to the data with the grid's bias at the result (the model's curve
  on the fit's grid minus on one twice as fine) removed from the target; the shift is
  the bias's effect on the parameters (a defect correction: the refit estimates the
  fit on the finer grid).

Each refit starts from the result and keeps the fit's shapes (no new compilation).
Every reported quantity `q` gets the shift `|log q(refit) - log q(result)|` of each
refit (the larger one of the two contact refits), added in quadrature to its
Gauss-Newton std (`fitting.quality`).
"""

import dataclasses
import math

import numpy as np

from .._probe import Probe


MIN_CONTACT_SHIFT = 2  # samples


@dataclasses.dataclass
class AnalysisUncertainty:
    """The refits of one fitted curve: `material` (the result) and `refits`
    (`{component: [jc.Prony, ...]}`), `details` (JSON-ready: how each component was
    set up, the refits' convergence) and `flags` (a refit that did not converge)."""

    material: object
    refits: dict
    details: dict
    flags: list

    def log_shifts(self, quantity) -> dict:
        """`{component: max |log q(refit) - log q(result)|}` for `q = quantity(m)`
        (a positive number of a `jc.Prony`)."""
        q0 = quantity(self.material)
        return {name: max(abs(math.log(quantity(m) / q0)) for m in materials)
                for name, materials in self.refits.items() if materials}

    def summary(self) -> dict:
        return {"components": self.details,
                "note": ("std = sqrt(optimiser^2 + contact^2 + grid^2) of the log of "
                         "each quantity; contact: the parameters' shift when the "
                         "contact point moves by its uncertainty either way; grid: "
                         "their shift when the grid's bias is removed from the "
                         "target")}


def contact_shift(curve, probe, poisson, e_apparent):
    """`(samples, why)`: the contact point's uncertainty in samples of the file (see
    the module notes). `probe`: a sphere's radius [m] (a number), a `Probe`, a
    `jc.Sphere` or a `jc.Cone`; `e_apparent` [Pa]: the apparent Young's modulus."""
    probe = Probe.of(probe)
    ic = int(curve.raw["contact_index"])
    piecewise = int(curve.raw.get("piecewise_contact_index", ic))
    methods = abs(ic - piecewise)
    e_star = e_apparent / (1 - poisson**2)
    sigma_f = curve.baseline_noise
    noise_samples = 0
    if math.isfinite(sigma_f) and sigma_f > 0 and e_star > 0:
        depth_sigma = (sigma_f / (probe.factor * e_star)) ** (1 / probe.exponent)
        app = curve.depth[curve.segment == 0]
        noise_samples = int(np.argmax(app >= depth_sigma)) if (
            app >= depth_sigma).any() else app.size
    else:
        depth_sigma = math.nan
    shift = max(methods, noise_samples, MIN_CONTACT_SHIFT)
    return shift, {"samples": shift, "methods_samples": methods,
                   "noise_samples": noise_samples,
                   "noise_depth_m": depth_sigma if math.isfinite(depth_sigma) else None}


def analysis_uncertainty(problem, fit, curve, bias, e_apparent):
    """The refits of `fit` (a `jc.PronyFit` of `problem`, a `fitting.afm._Problem` of
    `curve`) for the contact point and, given its grid bias `bias` (`(nt,)`,
    `problem.grid_bias(fit)`, or None), the grid; returns an `AnalysisUncertainty`."""
    settings = problem.settings
    arms = int(np.asarray(fit.material.g).shape[0])
    refits, details, flags = {}, {}, []
    shift, details["contact"] = contact_shift(curve, settings.probe, settings.poisson,
                                              e_apparent)
    ic = int(curve.raw["contact_index"])
    dt = float(np.median(np.diff(curve.time)))
    details["contact"]["time_s"] = shift * dt
    refits["contact"] = []
    first = int(np.flatnonzero(curve.raw["segment"] == 0)[0])
    for index in (ic - shift, ic + shift):
        if index < first:  # no earlier contact than the approach's first sample
            details["contact"]["earlier"] = ("not refitted: the contact is within "
                                             f"{shift} samples of the approach's start")
            continue
        try:
            moved = curve.with_contact(index)
        except ValueError as exc:
            flags.append(f"contact point moved to sample {index}: {exc}")
            continue
        moved_problem = dataclasses.replace(
            type(problem).of(moved, settings, template=problem.template),
            tau_bounds=problem.tau_bounds)
        if moved_problem.times.shape != problem.times.shape:
            flags.append(f"contact point moved to sample {index}: binning changed "
                         "the number of samples; not refitted")
            continue
        refit = moved_problem.fit(arms, init=fit.material)
        _note(refit, f"contact at sample {index}", flags)
        refits["contact"].append(refit.material)
    if bias is not None:  # `(nt,)` problem.grid_bias(fit), computed by the caller
        target = ({"depth": problem.depth - bias} if fit.kind == "depth"
                  else {"force": problem.force - bias})
        refit = problem.fit(arms, init=fit.material, data=problem.data(**target))
        _note(refit, "grid-bias-corrected target", flags)
        refits["grid"] = [refit.material]
        details["grid"] = {"bias_rms": float(np.sqrt(np.mean(bias**2))),
                           "refined": ([2 * k for k in problem.template.grid.shape]
                                       if fit.solver == "grid" else None),
                           "refined_rings": (2 * fit.rings if fit.solver == "rings"
                                             else None)}
    return AnalysisUncertainty(fit.material, refits, details, flags)


def _note(refit, what, flags):
    if not refit.converged:
        flags.append(f"uncertainty refit ({what}) did not converge: {refit.message}")
