"""One AFM indentation curve fitted the way `jaxcontact fit` does it (`fit_afm_curve`).

The pipeline, shared by the command line and `jc.fit_force_map`:

1. bin the curve (`AFMFitSettings.samples` points in the approach, hold, retract; the
   bins' means weighted by `sqrt(count)`, the inverse of their noise);
2. fit `jc.fit_prony` for each arm count (`arms="auto"`: 1 to `MAX_AUTO_ARMS`, up to
   the first with a parameter at a bound; the converged fit with no parameter at a
   bound and the smallest BIC; a count whose fit raises is recorded and skipped),
   from the closed-form Lee & Radok start, relaxation times bounded to what the data
   resolve (`tau_bounds="auto"`: the raw sampling step to the data's duration);
3. judge it (`fitting.quality`): the residual of the RAW samples of each fitted segment
   against their white noise, the model's discretisation bias (at twice the rings,
   or on a grid twice as fine), parameters at a bound, the contact point's
   refinement;
4. (unless `analysis_uncertainty=False`) refit with the contact point moved by its own
   uncertainty either way and with the grid's bias removed from the target, and add
   the parameter shifts to the optimiser's Gauss-Newton standard deviations
   (`fitting.uncertainty`).

The probe (`AFMFitSettings.tip`): a sphere of radius `R` (the default) or a sharp cone
of half-angle `alpha`; every closed-form piece follows its elastic law `F = C G d^m`
(`jaxcontact._probe`: Hertz, `m = 3/2`; Sneddon, `m = 2`): the contact point
(`jc.read_afm(exponent=)`), the Lee & Radok start, the apparent modulus, the contact
point's noise depth, the closed-form floor of the verdict and the template's grid.
The contact model itself is the scene's `jc.Sphere` or `jc.Cone`, on rings by
default.

Units: SI throughout (s, N, m, Pa; the cone's half-angle in radians). Moduli are
reported as shear moduli `g` and as Young's moduli `E = 2 g (1 + nu)` at the given
Poisson's ratio.
"""

import dataclasses
import math
import warnings

import numpy as np

from .._probe import SPHERE_NOTE, TIPS, Probe
from .data import IndentationData
from .fit import fit_prony
from .options import SOLVERS, FitOptions
from .quality import (
    assess,
    at_bounds,
    model_curve,
    raw_residual,
    ring_keywords,
    youngs_moduli,
)
from .start import lee_radok_start
from .uncertainty import analysis_uncertainty


MAX_AUTO_ARMS = 3  # `arms="auto"` tries 1..3 (4 arms were never resolved on real files)

# Plausible probe radius / maximum indentation depth of a sphere: below 1e-2 the Hertz
# contact radius sqrt(R d) would exceed 10 R (a sphere's is at most R); above 1e3 the
# depth is under R / 1000, at the contact point's uncertainty. A unit slip of the
# radius (um or nm read as m) is a factor 1e3-1e9, far outside.
RADIUS_WINDOW = (1e-2, 1e3)

RADIUS_NOTE = SPHERE_NOTE

# A cone's half-angle below this [rad] (1 degree) is sharper than any AFM probe (AFM
# cones: about 10-45 degrees; a pyramid's equivalent cone 20-35): most likely a value
# in radians read as degrees on the command line.
MIN_HALF_ANGLE = math.radians(1.0)


@dataclasses.dataclass(frozen=True)
class AFMFitSettings:
    """How `fit_afm_curve` fits one curve (the defaults are `jaxcontact fit`'s).

    - `radius`: the sphere's radius [m], > 0 (`tip="sphere"`, the default; required
      there, refused with a cone).
    - `tip`: the probe, `"sphere"` (default) or `"cone"` (a sharp cone, Sneddon's).
    - `half_angle`: the cone's half-angle [rad] in `(0, pi/2)`, the angle between
      its axis and its flank (`tip="cone"`: required there, refused with a
      sphere); e.g. `AFMFitSettings(tip="cone", half_angle=math.radians(20))`.
    - `arms`: number of Prony arms (1..8) or `"auto"` (1..`MAX_AUTO_ARMS`, by BIC).
    - `n`: grid cells per side of the contact model (>= 4), when it runs on the grid.
    - `solver`: `"auto"` (default: the rings, `solve_axisymmetric`, for the probe),
      `"rings"` or `"grid"` (`jc.FitOptions.solver`).
    - `rings`: rings of the ring model (>= 4; default 64).
    - `poisson`: Poisson's ratio, fixed, in (-1, 0.5].
    - `samples`: points after binning in the approach, hold and retract.
    - `segments`: the segments fitted; the approach always. Default approach and hold:
      the loading and the hold are one linear viscoelastic response of the model; a
      retract adds the unloading (Ting's problem), which soft samples with adhesion or
      plasticity do not follow (see `benchmarks/notes/fit_real_files.md`).
    - `tau_bounds`: `"auto"` (the raw sampling step to the duration of the data
      [s]: a faster time is not sampled, a slower one is degenerate with `g_inf`),
      `None` (unbounded) or `(lo, hi)` [s].
    - `start`: `"lee-radok"` (the closed-form fit of loading and hold) or `"data"`
      (`jc.fit_prony`'s default start).
    - `steps`: bound on the Levenberg-Marquardt steps of each fit (a run also stops,
      NOT converged, after 25 steps that lowered its loss by less than 1e-4 of
      itself: `jc.FitOptions.lm_steps`).
    - `check_grid`: solve the fitted model at twice the resolution (twice the rings,
      or a grid twice as fine): the model's discretisation bias.
    - `analysis_uncertainty`: add the contact point's and the grid's parameter shifts
      to the reported uncertainty (two or three more fits from the result).

    `probe` (property): the tip as a `jaxcontact._probe.Probe` (its law `F = C G
    d^m`, contact radius, `jc.Sphere` / `jc.Cone`).
    """

    radius: float | None = None
    arms: int | str = "auto"
    n: int = 32
    poisson: float = 0.5
    samples: tuple = (8, 24, 8)
    segments: tuple = ("approach", "hold")
    tau_bounds: object = "auto"
    start: str = "lee-radok"
    steps: int = 200
    check_grid: bool = True
    analysis_uncertainty: bool = True
    solver: str = "auto"
    rings: int = 64
    tip: str = "sphere"
    half_angle: float | None = None

    def __post_init__(self):
        if self.tip not in TIPS:
            raise ValueError(f"tip must be 'sphere' or 'cone', got {self.tip!r}")
        # Which of radius / half_angle goes with the tip; `Probe` checks the value.
        if self.tip == "sphere":
            if self.radius is None:
                raise ValueError("a spherical tip needs radius [m] > 0 (or give "
                                 "tip='cone' and half_angle [rad])")
            if self.half_angle is not None:
                raise ValueError(f"half_angle={self.half_angle!r} is a cone's: give "
                                 "tip='cone' (and no radius), or leave it out")
        else:
            if self.half_angle is None:
                raise ValueError("tip='cone' needs half_angle [rad] in (0, pi/2), the "
                                 "angle between the axis and the flank")
            if self.radius is not None:
                raise ValueError(f"radius={self.radius!r} is a sphere's: a cone "
                                 "(tip='cone') has half_angle only")
        Probe(self.tip, self.radius if self.tip == "sphere" else self.half_angle)
        if self.arms != "auto" and not (isinstance(self.arms, int) and
                                        1 <= self.arms <= 8):
            raise ValueError(f"arms must be an integer in 1..8 or 'auto', got "
                             f"{self.arms!r}")
        if not (isinstance(self.n, int) and self.n >= 4):
            raise ValueError(f"n must be an integer >= 4, got {self.n!r}")
        if not -1 < self.poisson <= 0.5:
            raise ValueError(f"poisson must be in (-1, 0.5], got {self.poisson!r}")
        if len(self.samples) != 3 or any(not isinstance(k, int) or k < 1
                                         for k in self.samples):
            raise ValueError(f"samples must be three integers >= 1 (approach, hold, "
                             f"retract), got {self.samples!r}")
        if "approach" not in self.segments or any(
                s not in ("approach", "hold", "retract") for s in self.segments):
            raise ValueError(f"segments must list 'approach' and any of 'hold', "
                             f"'retract', got {self.segments!r}")
        tb = self.tau_bounds
        if not (tb is None or tb == "auto" or (
                len(tb) == 2 and 0 < tb[0] < tb[1] < math.inf)):
            raise ValueError(f"tau_bounds must be 'auto', None or (lo, hi) with "
                             f"0 < lo < hi [s], got {tb!r}")
        if self.start not in ("lee-radok", "data"):
            raise ValueError(f"start must be 'lee-radok' or 'data', got {self.start!r}")
        if not (isinstance(self.steps, int) and self.steps >= 1):
            raise ValueError(f"steps must be an integer >= 1, got {self.steps!r}")
        if self.solver not in SOLVERS:
            raise ValueError(f"solver must be 'auto', 'rings' or 'grid', got "
                             f"{self.solver!r}")
        if not (isinstance(self.rings, int) and not isinstance(self.rings, bool)
                and self.rings >= 4):
            raise ValueError(f"rings must be an integer >= 4, got {self.rings!r}")

    @property
    def probe(self) -> Probe:
        """The tip as a `Probe` (`Probe.sphere(radius)` or `Probe.cone(half_angle)`)."""
        return Probe(self.tip, self.radius if self.tip == "sphere" else self.half_angle)


@dataclasses.dataclass(frozen=True)
class AFMFit:
    """The result of `fit_afm_curve`: `report` (a JSON-ready dict: parameters with
    their uncertainty, Young's moduli, quality verdict and flags, contact point,
    apparent Hertz modulus, settings; units in `report["units"]`), `fit` (the chosen
    `jc.PronyFit`) and `segment` (`(nt,)` segment code of each binned sample: 0
    approach, 1 hold, 2 retract)."""

    report: dict
    fit: object
    segment: np.ndarray

    @property
    def ok(self) -> bool:
        """A certified fit with nothing flagged (`report["flags"]` empty)."""
        return not self.report["flags"]


def radius_warning(radius, depth):
    """The warning text when the probe radius `radius` [m] is implausible against the
    curve's maximum indentation depth `depth` [m], else None.

    Plausible: `RADIUS_WINDOW[0] <= radius / depth <= RADIUS_WINDOW[1]`. Outside, the
    text names the radius, the depth, the rule and, for a radius too large, the
    reading in um, nm or mm that falls inside the window (the radius is read in m).
    """
    lo, hi = RADIUS_WINDOW
    if not depth > 0:  # no indentation to compare with
        return None
    ratio = radius / depth
    if lo <= ratio <= hi:
        return None
    text = (f"--radius {radius:g} m is {ratio:.3g} x the maximum indentation depth "
            f"{depth:.3g} m; a spherical probe's radius is {lo:g} to {hi:g} x the "
            "depth (below, its Hertz contact radius sqrt(R d) would exceed 10 R; "
            "above, the depth is at the contact point's uncertainty)")
    if ratio > hi:
        for scale, unit in ((1e-6, "micrometres"), (1e-9, "nanometres"),
                            (1e-3, "millimetres")):
            if lo <= ratio * scale <= hi:
                return (text + f": the radius is in metres; if {radius:g} was meant in "
                        f"{unit}, pass --radius {radius * scale:g}")
    return text + ": check the radius's unit (metres) and the contact point"


def half_angle_warning(half_angle):
    """The warning text when a cone's half-angle `half_angle` [rad] is implausible
    for an AFM probe (below `MIN_HALF_ANGLE`, 1 degree: sharper than any AFM cone;
    most likely radians read as degrees), else None. The text names the angle, the
    rule and the reading in degrees of the value taken as radians."""
    if half_angle >= MIN_HALF_ANGLE:
        return None
    deg = math.degrees(half_angle)
    return (f"--half-angle {deg:.4g} degrees ({half_angle:.4g} rad) is sharper than "
            f"any AFM cone (half-angles about 10-45 degrees; the rule: at least "
            f"{math.degrees(MIN_HALF_ANGLE):g} degree): the half-angle is in degrees "
            f"on the command line; if {deg:.4g} was meant in radians, pass "
            f"--half-angle {math.degrees(deg):.4g}")


def tip_warning(probe, depth):
    """`radius_warning` (a sphere: `probe.size` against the maximum depth `depth`
    [m]) or `half_angle_warning` (a cone) of a `Probe`: a text, or None."""
    if probe.tip == "sphere":
        return radius_warning(probe.size, depth)
    return half_angle_warning(probe.size)


def apparent_hertz(curve, probe, poisson) -> dict:
    """The elastic fit of the approach, `F = k E / (1 - nu^2) delta^m` (the probe's
    law: Hertz for a sphere, `k = 4/3 sqrt(R)`, `m = 3/2`; Sneddon for a cone,
    `k = 2 tan(alpha) / pi`, `m = 2`) by least squares over the approach's raw
    samples in contact (depth > 0), at this curve's contact point. `probe`: a
    sphere's radius [m] (a number, as before), a `Probe`, a `jc.Sphere` or a
    `jc.Cone`. `E_Pa` [Pa] is the number AFM tools (e.g. nanite) report for an
    elastic sample; on a viscoelastic one it is a modulus between `E(t)` at the
    approach's duration and `E_0`. The report keeps the key `apparent_hertz` for
    both tips; `law` says which."""
    probe = Probe.of(probe)
    app = (curve.segment == 0) & (curve.depth > 0)
    x = curve.depth[app] ** probe.exponent
    e_star = float(np.sum(curve.force[app] * x) / np.sum(x * x)) / probe.factor
    name = "Hertz (sphere)" if probe.tip == "sphere" else "Sneddon (cone)"
    return {"E_Pa": e_star * (1 - poisson**2), "samples": int(app.sum()),
            "law": probe.law,
            "note": f"{name} fitted to the approach at this contact point, "
                    "E = E* (1 - nu^2)"}


def _check_template(template, probe):
    """A ValueError unless the template's indenter is `probe`'s tip (same shape,
    radius or half-angle within 1e-6: a float32 template): the closed-form parts of
    the fit follow the settings' tip, the contact model the template's."""
    try:
        got = Probe.of(template.indenter)
    except ValueError as exc:
        raise ValueError(f"template: {exc}") from None
    if got.tip != probe.tip or abs(got.size - probe.size) > 1e-6 * probe.size:
        raise ValueError(f"the template's indenter ({got.text()}) is not the settings' "
                         f"tip ({probe.text()}): the contact point, start and apparent "
                         "modulus follow the settings")


def fit_afm_curve(curve, settings: AFMFitSettings, *, template=None) -> AFMFit:
    """Fit a Prony series to one `AFMCurve` (`jc.read_afm`) as `jaxcontact fit` does
    (the module notes list the steps); returns an `AFMFit`. `template`: the scene
    whose grid and indenter the fit uses (default
    `curve.scene_template(indenter=settings.probe.indenter(), n=settings.n,
    poisson=settings.poisson)`: the sphere or cone on a grid 4 x its largest
    contact radius wide; a given template's indenter must be the settings' tip,
    else `ValueError`).

    The curve should be read with the tip's exponent (`jc.read_afm(...,
    exponent=settings.probe.exponent)`, as `jaxcontact fit` and `jc.fit_force_map`
    do): its contact point assumes it."""
    probe = settings.probe
    if template is not None:
        _check_template(template, probe)
    tip_note = tip_warning(probe, float(np.max(curve.depth)))
    if tip_note is not None:
        warnings.warn(tip_note, UserWarning, stacklevel=2)
    problem = _Problem.of(curve, settings, template=template)
    fits, failed = {}, {}
    for k in ([settings.arms] if settings.arms != "auto" else
              range(1, MAX_AUTO_ARMS + 1)):
        if problem.times.size <= 2 * k + 2:
            break
        try:
            fit = problem.fit(k)
        except ValueError as exc:  # e.g. a start with a non-finite loss: next count
            failed[k] = str(exc)
            continue
        fits[k] = (fit, *_information(fit, 1 + 2 * k),
                   at_bounds(fit.material, problem.tau_bounds))
        if fits[k][3] and settings.arms == "auto":
            break  # an arm the data do not resolve: more arms resolve less
    if not fits:
        reasons = "; ".join(f"{k} arm(s): {m}" for k, m in failed.items())
        raise ValueError(f"{problem.times.size} samples are too few to fit"
                         if not failed else f"no arm count could be fitted ({reasons})")
    best = _choose(fits)
    fit = fits[best][0]
    bias = problem.grid_bias(fit) if settings.check_grid else None
    disc = None if bias is None else float(np.sqrt(np.mean(bias**2)))
    _, raw_res, raw_seg = raw_residual(fit.material, fit.kind, curve, problem.template,
                                       **ring_keywords(fit))
    hertz = apparent_hertz(curve, probe, settings.poisson)
    uncertainty = (analysis_uncertainty(problem, fit, curve, bias, hertz["E_Pa"])
                   if settings.analysis_uncertainty else None)
    report = {
        "file": curve.path, "mode": curve.mode, "fitted": fit.kind,
        "tip": probe.parameters(), "tip_note": probe.scaling_note(),
        "tip_warning": tip_note,
        # a sphere's, as before (None for a cone)
        "radius_m": settings.radius,
        "radius_note": RADIUS_NOTE if probe.tip == "sphere" else None,
        "radius_warning": tip_note if probe.tip == "sphere" else None,
        "poisson": settings.poisson,
        "settings": _settings_json(settings),
        "tau_bounds_s": list(problem.tau_bounds) if problem.tau_bounds else None,
        "solver": fit.solver,
        "grid": [settings.n, settings.n] if fit.solver == "grid" else None,
        "rings": None if fit.solver == "grid" else {
            "rings": fit.rings, "radius_m": fit.ring_radius},
        "arms": best, "samples": int(
            problem.times.size),
        "converged": bool(fit.converged), "message": fit.message,
        "information_criteria": {
            **{str(k): {"aic": v[1], "bic": v[2], "loss": v[0].loss,
                        "converged": bool(v[0].converged), "at_bounds": v[3]}
               for k, v in fits.items()},
            **{str(k): {"error": message} for k, message in failed.items()}},
        "contact_point": {
            "time_s": curve.contact_time, "height_m": curve.contact_height,
            "force_N": curve.baseline_force,
            "index": int(curve.raw["contact_index"]), "note": curve.contact_note},
        "contact_time_s": curve.contact_time,
        "contact_note": curve.contact_note,
        "spring_constant_N_per_m": curve.spring_constant,
        "apparent_hertz": hertz,
        "units": {"time": "s", "force": "N", "depth": "m", "modulus": "Pa (shear)",
                  "youngs_modulus": "Pa"},
    }
    report.update(assess(fit, curve, problem, raw_res, raw_seg, disc, tip_note,
                         uncertainty))
    report["youngs_moduli"] = youngs_moduli(report["parameters"], fit.material,
                                            settings.poisson, problem.approach_time,
                                            uncertainty, fit.covariance)
    return AFMFit(report, fit, problem.segment)


@dataclasses.dataclass
class _Problem:
    """One curve's binned data, template and bounds: what every fit of it shares (the
    refits of the uncertainty reuse its shapes, so nothing compiles again)."""

    settings: AFMFitSettings
    template: object
    times: np.ndarray
    force: np.ndarray
    depth: np.ndarray
    segment: np.ndarray
    counts: np.ndarray
    tau_bounds: tuple | None
    approach_time: float

    @classmethod
    def of(cls, curve, settings, template=None):
        names = ("approach", "hold", "retract")
        t, f, d, seg, counts = curve.resampled(
            dict(zip(names, settings.samples, strict=True)), return_counts=True)
        if template is None:
            template = curve.scene_template(indenter=settings.probe.indenter(),
                                            n=settings.n, poisson=settings.poisson)
        tau_bounds = settings.tau_bounds
        if tau_bounds == "auto":
            raw_step = float(np.median(np.diff(curve.time)))
            tau_bounds = (raw_step, float(t[-1] - t[0]))
        app = curve.segment == 0
        return cls(settings, template, t, f, d, seg, counts,
                   None if tau_bounds is None else tuple(tau_bounds),
                   float(curve.time[app].max()))

    def data(self, force=None, depth=None):
        return IndentationData(self.times, force=self.force if force is None
                               else force, depth=self.depth if depth is None
                               else depth)

    def fit(self, arms, *, init=None, data=None):
        """`jc.fit_prony` of `arms` arms on these bins (or on `data`, same times)."""
        data = self.data() if data is None else data
        weights = np.sqrt(self.counts)
        if init is None and self.settings.start == "lee-radok":
            try:
                init = lee_radok_start(data, self.template, arms,
                                       poisson=self.settings.poisson, weights=weights)
            except ValueError:  # too few loading samples: the default start
                init = None
        bounds = {"tau": self.tau_bounds} if self.tau_bounds else None
        return fit_prony(data, self.template, arms, weights=weights, init=init,
                         bounds=bounds,
                         options=FitOptions(lm_steps=self.settings.steps,
                                            solver=self.settings.solver,
                                            rings=self.settings.rings))

    def grid_bias(self, fit):
        """`(nt,)` the fitted model's curve at the fit's resolution minus at twice it
        (twice the rings over the same radius, or twice the cells per side, same
        width) [data units]: the bias of the model's discretisation."""
        drive = dict(times=self.times, force=self.force, depth=self.depth,
                     kind=fit.kind, **ring_keywords(fit))
        return (model_curve(fit.material, self.template, **drive)
                - model_curve(fit.material, self.template, refine=2, **drive))


def _information(fit, n_params):
    """AIC and BIC of a least-squares fit with Gaussian noise of unknown variance."""
    n = fit.residual.shape[0]
    ssr = float(np.sum(fit.residual**2))
    base = n * math.log(max(ssr, 1e-300) / n)
    return base + 2 * n_params, base + n_params * math.log(n)


def _choose(fits):
    """The arm count with the smallest BIC among the converged fits with no parameter
    at a bound (an arm at a bound is not resolved by the data; an unconverged fit's
    BIC is not its model's), else among the converged, else among all. `fits`:
    {arms: (fit, aic, bic, at_bounds)}."""
    for keep in (lambda v: v[0].converged and not v[3], lambda v: v[0].converged,
                 lambda v: True):
        pool = [k for k, v in fits.items() if keep(v)]
        if pool:
            return min(pool, key=lambda k: fits[k][2])
    raise AssertionError("unreachable")


def _settings_json(settings):
    out = dataclasses.asdict(settings)
    out["samples"] = list(settings.samples)
    out["segments"] = list(settings.segments)
    if isinstance(settings.tau_bounds, tuple):
        out["tau_bounds"] = list(settings.tau_bounds)
    return out
