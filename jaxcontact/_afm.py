"""Reading AFM force-distance files into `jc.IndentationData` (`jc.read_afm`).

One job: an instrument file (or an `afmformats` curve object) in, a clean indentation
curve out: time [s], force [N] above the baseline, indentation depth [m], the segment of
every sample (approach / hold / retract), the contact point, and the units used.

The files are read by `afmformats` (an optional dependency: `pip install
"jaxcontact[afm]"`; it reads JPK `.jpk-force`, `.jpk-force-map`, `.jpk-qi-data`, Asylum
`.ibw`, NT-MDT, WSxM, Chiaro and other formats and hands back SI columns: `time` [s],
`force` [N], `height (measured)` / `height (piezo)` [m], `segment`).

Conventions:

- Height `h` is the cantilever base's position, larger = further from the sample (as
  JPK and afmformats record it). A repulsive force `F > 0` bends the cantilever up by
  `F / k` (`k` the spring constant [N/m]), so the tip sits at `h + F / k`, and the
  indentation depth after contact is

      delta = (h_c - h) - (F - F_c) / k                                     [m]

  with `h_c`, `F_c` height and force at the contact point. Where a file has no force
  column but a `deflection` column [m], `F = k * deflection`.
- The force is returned above the baseline (`F - F_baseline`, the baseline fitted on
  the approach before contact, see below).
- Contact point: the piecewise fit of Lin, Dimitriadis & Horkay (2007): on the approach
  segment (with a pause just before it, at travel 0, which shows the baseline), for
  every candidate contact travel `x_c` of the TIP (`x = (h_0 - h) - (F - F_0) / k`:
  the base's travel less the deflection, so that the law below holds in the
  indentation), the model

      F(x) = a + b max(x - x_c, 0)^(3/2)       (+ s x: a tilted baseline, optional)

  is fitted by linear least squares in `(a, b[, s])`; the contact point is the `x_c`
  with the smallest sum of squared residuals (a grid over the approach, then a finer
  grid around the best). The 3/2 power is Hertz's for a sphere (`exponent=2`:
  Sneddon's for a cone); the baseline is the fitted `a (+ s x)`. It is overridable
  (`contact_index=`).
- Segments: each afmformats segment is classified by its height travel against the
  whole curve's: down by more than 10 % -> approach, up by more than 10 % -> retract,
  otherwise hold (between an approach and a retract) or pause (before the approach or
  after the retract; pauses are dropped).
- Kept samples: from the contact point to the end of the retract or to where the
  retract loses contact (force back to the baseline, or the depth back to 0), as the
  contact model has no adhesion.

The probe's shape is not in the files: it is an input of the fit (the scene's
`jc.Sphere(radius)` or `jc.Cone(half_angle)`; `read_afm(exponent=)` the power of its
elastic law for the contact point). Relaxation times and modulus RATIOS (g_i / g_inf)
do not depend on it; absolute moduli scale as `radius^(-1/2)` (Hertz:
`F ~ G sqrt(R) delta^(3/2)`) or `1 / tan(half_angle)` (Sneddon:
`F ~ G tan(alpha) delta^2`).

??? cite "References"

    Lin, D. C., Dimitriadis, E. K., Horkay, F. (2007). Robust strategies for automated
    AFM force curve analysis - I. Non-adhesive indentation of soft, inhomogeneous
    materials. J. Biomech. Eng. 129(3), 430-440.
"""

import dataclasses
import os

import numpy as np

from ._lee_radok import check_exponent, lee_radok_misfit


SEGMENT_NAMES = ("approach", "hold", "retract")
_TRAVEL_FRACTION = 0.1  # a segment moving less than this share of the range is a hold


def import_afmformats():
    try:
        import afmformats
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError(
            "reading AFM files needs the optional dependency afmformats: "
            'pip install "jaxcontact[afm]"'
        ) from exc
    return afmformats


@dataclasses.dataclass(frozen=True)
class AFMCurve:
    """One indentation curve read from an AFM file (`jc.read_afm`).

    Every array is `(n,)` over the KEPT samples (from the contact point to the end of
    contact), in SI units:

    - `time`: time since the contact point [s].
    - `force`: force above the baseline [N].
    - `depth`: indentation depth (positive into the sample) [m].
    - `segment`: `(n,)` int, index into `SEGMENT_NAMES` (0 approach, 1 hold, 2
      retract).
    - `mode`: `"creep"` (force clamp during the hold: fit the depth under the measured
      force) or `"relaxation"` (height clamp: fit the force under the measured depth).
    - `spring_constant` [N/m], `contact_time` [s, file clock], `contact_height` [m],
      `baseline_force` [N] (the baseline at the contact point), `baseline_noise` [N]
      (standard deviation of the approach before contact about the baseline).
    - `path`: the file (or `None`), `metadata`: afmformats' metadata dict.
    - `raw`: dict of the whole file's columns (`time`, `force`, `height`, `segment`
      with -1 for pauses; `force_above_baseline` [N], the fitted baseline removed;
      `kept_codes`, the segment codes kept; `contact_index`, the contact sample)
      for plots and `with_contact`.
    - `contact_note`: how the contact point was found (`read_afm(contact=...)`).
    """

    time: np.ndarray
    force: np.ndarray
    depth: np.ndarray
    segment: np.ndarray
    mode: str
    spring_constant: float
    contact_time: float
    contact_height: float
    baseline_force: float
    baseline_noise: float
    path: str | None
    metadata: dict
    raw: dict
    units: tuple = (("time", "s"), ("force", "N"), ("depth", "m"))
    contact_note: str = ""

    def data(self, n_samples=None):
        """The curve as a `jc.IndentationData` (SI: s, N, m). With `n_samples`
        (dict segment name -> number of points, or one int for every segment), each
        segment is averaged in that many consecutive bins (log-spaced in time for the
        hold, where relaxation is fastest at its start; uniform elsewhere)."""
        from .fitting import IndentationData

        t, f, d, s = self.resampled(n_samples)
        return IndentationData(t, force=f, depth=d)

    def resampled(self, n_samples=None, *, return_counts=False):
        """`(time, force, depth, segment)` averaged in bins (see `data`); with
        `return_counts`, also the number of raw samples in each bin."""
        if n_samples is None:
            out = (self.time, self.force, self.depth, self.segment)
            return out + (np.ones(self.time.shape, int),) if return_counts else out
        if isinstance(n_samples, (int, np.integer)) and not isinstance(n_samples, bool):
            n_samples = {name: int(n_samples) for name in SEGMENT_NAMES}
        if not isinstance(n_samples, dict) or any(
                k not in SEGMENT_NAMES for k in n_samples):
            raise ValueError(
                f"n_samples must be an int or a dict with keys in {SEGMENT_NAMES}, got "
                f"{n_samples!r}")
        # The contact point itself (t = 0, F = 0, depth = 0 by definition) starts the
        # curve, so that the model starts from an unloaded half-space.
        first = self.time[0] <= 0
        out = [[0.0], [0.0], [0.0], [0]]
        counts = [1]
        for code, name in enumerate(SEGMENT_NAMES):
            idx = np.flatnonzero(self.segment == code)
            if idx.size == 0:
                continue
            k = n_samples.get(name, idx.size)
            if not (isinstance(k, (int, np.integer)) and k >= 1):
                raise ValueError(f"n_samples[{name!r}] must be an int >= 1, got {k!r}")
            k = min(int(k), idx.size)
            if name == "hold":
                edges = np.unique(np.round(np.geomspace(1, idx.size + 1, k + 1)).astype(
                    int)) - 1
            else:
                edges = np.unique(np.round(np.linspace(0, idx.size, k + 1)).astype(int))
            for lo, hi in zip(edges[:-1], edges[1:], strict=True):
                sel = idx[lo:hi]
                if first and sel[0] == 0:
                    sel = sel[1:]  # the contact sample is the first point already
                    if sel.size == 0:
                        continue
                out[0].append(self.time[sel].mean())
                out[1].append(self.force[sel].mean())
                out[2].append(self.depth[sel].mean())
                out[3].append(code)
                counts.append(sel.size)
        t, f, d, s = (np.asarray(v) for v in out)
        if return_counts:
            return t, f, d, s.astype(int), np.asarray(counts)
        return t, f, d, s.astype(int)

    def noise(self, kind):
        """Standard deviation of the raw samples' noise in `kind` (`"force"` [N] or
        `"depth"` [m]): from successive differences over the kept curve,
        `median(|x_{k+1} - x_k|) / (0.6745 sqrt 2)` (robust to the few fast
        changes of the signal, which is smooth at the sampling rate)."""
        x = self.force if kind == "force" else self.depth
        return float(np.median(np.abs(np.diff(x))) / (0.6745 * np.sqrt(2)))

    def with_contact(self, index):
        """This curve with the contact point moved to sample `index` of the file
        (`raw["contact_index"]` is the current one): the force and depth zeroed
        there, the baseline kept (a sensitivity study of the contact point).

        **Raises:** `ValueError` when `index` is not on the approach or leaves fewer
        than 4 samples in contact."""
        code = self.raw["segment"]
        app = np.flatnonzero(code == 0)
        if not (isinstance(index, (int, np.integer)) and app[0] <= index <= app[-1]):
            raise ValueError(f"index must be a sample index on the approach "
                             f"({app[0]}..{app[-1]}), got {index!r}")
        index = int(index)
        offset = float(self.raw["force_above_baseline"][index])
        return _curve_at_contact(
            self.raw, index, offset, mode=self.mode,
            spring_constant=self.spring_constant,
            baseline_force=float(self.raw["force"][index]),
            baseline_noise=self.baseline_noise,
            path=self.path, metadata=self.metadata,
            contact_note=f"moved to sample {index} (from "
                         f"{self.raw['contact_index']}: {self.contact_note})")

    def scene_template(self, radius=None, *, indenter=None, n=32, poisson=0.5,
                       size_factor=4.0):
        """A `jc.Scene` for `jc.fit_prony` on this curve: the probe, an `n x n` grid
        `size_factor` times its largest elastic contact radius wide (a sphere's
        `sqrt(R * max depth)`, a cone's `2 tan(alpha) max depth / pi`), a
        placeholder elastic material of Poisson's ratio `poisson` (0.5:
        incompressible, the usual assumption for cells and gels; only `G / (1 - nu)`
        is identifiable from indentation) and the control mode of the hold
        (`jc.Force` for creep, `jc.Displacement` for relaxation; the fit replaces the
        program by the data's).

        The probe: `radius` [m], a sphere (as before), or `indenter=`, a `jc.Sphere`
        or a `jc.Cone` (e.g. `curve.scene_template(indenter=jc.Cone(0.35))`), used
        as given.

        **Raises:** `ValueError` for both or neither of `radius` and `indenter`, a
        radius that is not a finite number > 0, another indenter, or a curve without
        a positive depth."""
        import jax.numpy as jnp

        from ._grid import Grid
        from ._indenter import Cone, Sphere
        from ._loading import Displacement, Force
        from ._material.elastic import Elastic
        from ._probe import Probe
        from ._scene import Scene

        if (radius is None) == (indenter is None):
            raise ValueError(
                "scene_template needs the probe: radius [m] (a sphere) or indenter= "
                f"(a jc.Sphere or jc.Cone), not both; got radius={radius!r}, "
                f"indenter={indenter!r}")
        if indenter is None:
            if not (isinstance(radius, (int, float)) and np.isfinite(radius)
                    and radius > 0):
                raise ValueError(
                    f"radius must be a finite number > 0 [m], got {radius!r}")
            probe, indenter = Probe.sphere(radius), Sphere(radius)
        else:
            if not isinstance(indenter, (Sphere, Cone)):
                raise ValueError(f"indenter must be a jc.Sphere or a jc.Cone, got "
                                 f"{type(indenter).__name__}")
            probe = Probe.of(indenter)
        depth = max(float(self.depth.max()), 0.0)
        a_max = float(probe.contact_radius(depth))
        if not a_max > 0:
            raise ValueError("the curve has no positive indentation depth")
        width = size_factor * a_max
        # A placeholder modulus of the right order: the elastic law at the largest
        # force, F = C G d^m.
        g = max(float(self.force.max()), 1e-30) / (
            probe.prefactor(poisson) * depth ** probe.exponent)
        normal = Force(0.0) if self.mode == "creep" else Displacement(0.0)
        return Scene(Grid(shape=(n, n), size=(width, width)), indenter,
                     Elastic(shear_modulus=g, poisson=poisson),
                     jnp.linspace(0.0, 1.0, 3), normal)


# --------------------------------------------------------------------------------------
# Contact point.


def contact_point(travel, force, *, baseline="constant", exponent=1.5, grid=200):
    """Contact point of an approach curve by the piecewise fit of Lin et al. (2007).

    **Arguments:**

    - `travel`: `(n,)` travel of the cantilever base towards the sample [length],
      increasing.
    - `force`: `(n,)` force [force].
    - `baseline`: `"constant"` or `"linear"` (a tilted baseline: virtual deflection).
    - `exponent`: the power of the contact branch (3/2: Hertz, sphere; 2: Sneddon,
      cone).
    - `grid`: number of candidate contact points per pass (two passes: the whole
      approach, then between the best candidate's neighbours).

    **Returns:** `(x_c, coefficients)`: the contact travel and the fitted
    `(a, b[, s])` of `F = a + b max(x - x_c, 0)^exponent (+ s x)`.

    **Raises:** `ValueError` when the fit finds no contact (`b <= 0` at the best
    candidate, or the best candidate at the last sample).
    """
    x = np.asarray(travel, float)
    y = np.asarray(force, float)
    if x.shape != y.shape or x.ndim != 1 or x.size < 8:
        raise ValueError(f"contact_point needs two 1-D arrays of >= 8 samples, got "
                         f"shapes {x.shape}, {y.shape}")
    # Normalise: the least squares below are then O(1) whatever the units.
    x0, xs = x.min(), max(float(np.ptp(x)), 1e-300)
    ys = max(float(np.std(y)), 1e-300)
    u, v = (x - x0) / xs, (y - y.mean()) / ys

    def ssr(candidates):
        branch = np.maximum(u[None, :] - candidates[:, None], 0.0) ** exponent
        cols = [np.ones_like(branch), branch]
        if baseline == "linear":
            cols.append(np.broadcast_to(u, branch.shape))
        a = np.stack(cols, axis=-1)  # (m, n, p)
        ata = np.einsum("mnp,mnq->mpq", a, a)
        atb = np.einsum("mnp,n->mp", a, v)
        ata += 1e-12 * np.eye(a.shape[-1])[None]
        coef = np.linalg.solve(ata, atb[..., None])[..., 0]
        res = np.einsum("mnp,mp->mn", a, coef) - v[None, :]
        return np.sum(res**2, axis=1), coef

    if baseline not in ("constant", "linear"):
        raise ValueError(f"baseline must be 'constant' or 'linear', got {baseline!r}")
    lo, hi = 0.0, 1.0
    for _ in range(2):
        cand = np.linspace(lo, hi, grid)
        values, coefs = ssr(cand)
        best = int(np.argmin(values))
        step = cand[1] - cand[0]
        lo, hi = max(cand[best] - step, 0.0), min(cand[best] + step, 1.0)
    uc, coef = cand[best], coefs[best]
    if not coef[1] > 0 or uc >= u.max():
        raise ValueError("no contact found on the approach segment: the force does not "
                         "rise above its baseline")
    # Back to the caller's units.
    a = coef[0] * ys + y.mean()
    b = coef[1] * ys / xs**exponent
    out = [a, b]
    if baseline == "linear":
        s = coef[2] * ys / xs
        out = [a - s * x0, b, s]
    return x0 + uc * xs, np.asarray(out)


def _refine_contact(time, f_rel, height, code, ic, k, mode, *, exponent=1.5,
                    max_candidates=60, max_hold=1000):
    """`(index, offset, note)`: the contact sample near `ic` that minimises
    `lee_radok_misfit` (2 arms) of the curve zeroed there, and the force above the
    baseline at it (`f_rel[index]`, the new zero). Every candidate's model runs from
    its own contact; the misfit is counted over the same samples for all (the
    approach from the last candidate on, and the hold, thinned to at most `max_hold`
    samples), so that a later contact is not rewarded for dropping samples."""
    app = np.flatnonzero(code == 0)
    after = app[app >= ic]
    w = max(5, after.size // 4)
    lo = max(int(app[0]), ic - w)
    hi = min(int(app[-1]) - 8, ic + w)  # at least 8 approach samples in contact
    if hi <= lo:
        return ic, float(f_rel[ic]), "too few approach samples to refine the contact"
    candidates = np.unique(np.linspace(lo, hi, min(max_candidates, hi - lo + 1)).astype(
        int))
    hold = np.flatnonzero(code == 1)
    hold = hold[:: max(1, -(-hold.size // max_hold))]
    best, best_value = ic, np.inf
    for j in candidates:
        idx = np.concatenate([app[app >= j], hold])
        f = f_rel[idx] - f_rel[j]
        d = (height[j] - height[idx]) - f / k
        value = lee_radok_misfit(time[idx] - time[j], f, d, mode, arms=2,
                                 start=int(np.sum(app[app >= j] < candidates[-1])),
                                 exponent=exponent)
        if value < best_value:
            best, best_value = int(j), value
    if best in (candidates[0], candidates[-1]) and best != ic:
        # no minimum inside the window: the approach is not the viscoelastic model's
        # there (a misfit still falling at the window's edge); the piecewise result
        # is kept as it is (zeroing the force there made the relaxation file's
        # closed-form hold misfit worse: see benchmarks/notes/fit_real_files.md)
        return ic, 0.0, (
            "viscoelastic refinement found no minimum within its window (the misfit "
            "falls towards its edge: the approach is not reproduced by the model); "
            "kept the piecewise contact and baseline")
    return best, float(f_rel[best]), (
        f"piecewise contact refined by {best - ic:+d} samples "
        f"({float(time[best] - time[ic]):+.3g} s) by the closed-form viscoelastic "
        "model")


# --------------------------------------------------------------------------------------
# Segments.


def classify_segments(height, segment):
    """Names of the file's segments from their height travel: `{segment id: name}`
    with names in `("approach", "hold", "retract", "pause")` (see the module notes)."""
    ids = np.unique(segment)
    span = max(float(np.ptp(height)), 1e-300)
    moves = {}
    for i in ids:
        h = height[segment == i]
        moves[int(i)] = (float(h[-1] - h[0])) / span
    names, seen_approach, seen_retract = {}, False, False
    for i in ids:
        m = moves[int(i)]
        if m < -_TRAVEL_FRACTION and not seen_approach:
            names[int(i)], seen_approach = "approach", True
        elif m > _TRAVEL_FRACTION and seen_approach and not seen_retract:
            names[int(i)], seen_retract = "retract", True
        elif seen_approach and not seen_retract and abs(m) <= _TRAVEL_FRACTION:
            names[int(i)] = "hold"
        else:
            names[int(i)] = "pause"
    return names


# --------------------------------------------------------------------------------------
# Reader.


def _column(curve, names):
    for name in names:
        if name in curve.columns:
            return name, np.asarray(curve[name], float)
    return None, None


def read_afm(source, *, index=0, contact_index=None, baseline="constant",
             segments=SEGMENT_NAMES, mode=None, contact="piecewise",
             exponent=1.5) -> AFMCurve:
    """Read one force-distance curve from an AFM file into an `AFMCurve`.

    **Arguments:**

    - `source`: a path to any file `afmformats` reads (e.g. `.jpk-force`), or an
      afmformats curve object (`afmformats.load_data(path)[i]`).
    - `index`: which curve of a multi-curve file (a force map).
    - `contact_index`: override the contact point: the sample index (into the whole
      file) of contact. Default: found by `contact_point` on the approach.
    - `baseline`: `"constant"` or `"linear"` baseline for the contact point fit.
    - `segments`: the segments to keep, a subset of `("approach", "hold",
      "retract")`.
    - `mode`: `"creep"` or `"relaxation"`; default: from the file's imaging mode
      (afmformats' `creep-compliance` / `stress-relaxation`), else from the hold
      (height held within 1 % of the depth: relaxation).
    - `contact`: how the contact point is found (unless `contact_index` is given):
        - `"piecewise"` (default): the baseline + Hertz fit of Lin et al. (2007) on
          the approach (see the module notes); the force is measured from the fitted
          baseline.
        - `"viscoelastic"`: that point refined by the closed-form viscoelastic
          (Lee-Radok) model that the fit itself assumes: among the approach samples
          around it (a quarter of the in-contact approach either way, at most 60
          candidates), the one where a curve zeroed there (force and depth 0 at
          contact: the model starts unloaded) is best reproduced over the approach and
          hold by `lee_radok_misfit` with 2 arms (where the misfit has no minimum
          inside that window, the piecewise result is kept; `contact_note` says
          which). On a soft sample with a foot (the
          force creeping up before the Hertz law holds) the elastic piecewise fit puts
          the contact where the force is already above its baseline, and a model that
          starts unloaded cannot follow (see `benchmarks/notes/fit_real_files.md`).
    - `exponent`: the power `m` of the probe's elastic law `F ~ depth^m` that both
      contact-point methods assume: 1.5 (default) a sphere (Hertz), 2 a cone
      (Sneddon); `jc.AFMFitSettings(...).probe.exponent` is the tip's.

    **Returns:** an `AFMCurve` (SI units: s, N, m).

    **Raises:** `ValueError` for a file without time, height, or force/deflection
    columns, without a spring constant when one is needed, without an approach
    segment, or without a contact, or an `exponent` that is not a number > 0;
    `ImportError` without afmformats.
    """
    exponent = check_exponent(exponent)
    # -- Initial set-up ----------------------------------------------------------------
    path = None
    if isinstance(source, (str, os.PathLike)):
        path = os.fspath(source)
        if not os.path.exists(path):
            raise ValueError(f"no such file: {path!r}")
        afm = import_afmformats()
        try:
            curves = afm.load_data(path)
        except Exception as exc:
            raise ValueError(f"afmformats cannot read {path!r}: {exc}") from exc
        if not 0 <= index < len(curves):
            raise ValueError(f"index={index!r} out of range: {path!r} holds "
                             f"{len(curves)} curve(s)")
        curve = curves[index]
    else:
        curve = source
        if not hasattr(curve, "columns") or not hasattr(curve, "metadata"):
            raise TypeError(f"source must be a path or an afmformats curve, got "
                            f"{type(source).__name__}")
        path = curve.metadata.get("path") if hasattr(curve.metadata, "get") else None
        path = None if path is None else os.fspath(path)
    bad = [s for s in segments if s not in SEGMENT_NAMES]
    if bad or "approach" not in segments:
        raise ValueError(f"segments must include 'approach' and be among "
                         f"{SEGMENT_NAMES}, got {segments!r}")
    metadata = dict(curve.metadata)
    k = metadata.get("spring constant")

    # -- Columns -----------------------------------------------------------------------
    _, time = _column(curve, ("time",))
    _, height = _column(curve, ("height (measured)", "height (piezo)"))
    _, force = _column(curve, ("force",))
    if force is None:
        _, deflection = _column(curve, ("deflection",))
        if deflection is not None:
            if not (k is not None and np.isfinite(k) and k > 0):
                raise ValueError(f"the file has a deflection but no valid spring "
                                 f"constant (got {k!r}): cannot compute the force")
            force = float(k) * deflection
    missing = [name for name, col in (("time", time), ("height", height),
                                      ("force or deflection", force)) if col is None]
    if missing:
        raise ValueError(f"the curve lacks the column(s) {missing} (has "
                         f"{list(curve.columns)})")
    if not (k is not None and np.isfinite(k) and k > 0):
        raise ValueError(f"the file records no valid spring constant (got {k!r})")
    k = float(k)
    seg_ids = np.asarray(curve["segment"] if "segment" in curve.columns
                         else np.zeros(time.shape, int), int)
    names = classify_segments(height, seg_ids)
    code = np.full(time.shape, -1)
    for i, name in names.items():
        if name in SEGMENT_NAMES:
            code[seg_ids == i] = SEGMENT_NAMES.index(name)
    if not (code == 0).any():
        raise ValueError("the curve has no approach segment (the height never moves "
                         "towards the sample by more than 10 % of its range)")

    # -- Contact point ---------------------------------------------------------------
    app = np.flatnonzero(code == 0)
    # A pause just before the approach (same height: travel 0) belongs to the baseline.
    before = [i for i in names if i < int(seg_ids[app[0]])]
    if before and names[before[-1]] == "pause":
        app = np.concatenate([np.flatnonzero(seg_ids == before[-1]), app])
    # The fit runs in the TIP's travel (base travel minus the deflection F / k), where
    # the 3/2 (sphere) or 2 (cone) law holds; in the base's travel a stiff sample
    # bends it (a 40 nm early contact on the synthetic curve of tests/test_afm.py, 5 %
    # deflection).
    travel = height[app[0]] - height[app] - (force[app] - force[app[0]]) / k
    if contact_index is None:
        xc, coef = contact_point(travel, force[app], baseline=baseline,
                                 exponent=exponent)
        ic = app[min(int(np.argmax(travel >= xc)) if (travel >= xc).any() else app.size,
                     app.size - 1)]
        # On the approach proper: the tip's travel fluctuates about 0 in a pause
        # before it (noise / k), and a contact at its start must not land there.
        ic = max(int(ic), int(np.flatnonzero(code == 0)[0]))
    else:
        if not (isinstance(contact_index, (int, np.integer)) and app[0] <= contact_index
                <= app[-1]):
            raise ValueError(f"contact_index must be a sample index on the approach "
                             f"({app[0]}..{app[-1]}), got {contact_index!r}")
        ic = int(contact_index)
        pre = app[app < ic]
        if pre.size >= 2:
            coef = np.array([force[pre].mean(), 0.0])
            if baseline == "linear":
                s, a = np.polyfit(travel[: pre.size], force[pre], 1)
                coef = np.array([a, 0.0, s])
        else:
            coef = np.array([force[ic], 0.0])
    tr_all = height[app[0]] - height - (force - force[app[0]]) / k

    def base(idx):
        b = coef[0] * np.ones(np.shape(idx))
        if coef.size == 3:
            b = b + coef[2] * tr_all[idx]
        return b

    # A tilted baseline (virtual deflection: a function of the base's position) is
    # evaluated at every sample's own travel; a constant one is the same everywhere.
    f_base = base(np.arange(time.size))
    # the depth from the piecewise fit's contact (for the mode of a hold)
    depth_pl = (height[ic] - height) - (force - f_base) / k
    # -- Mode --------------------------------------------------------------------------
    if mode is None:
        imaging = str(metadata.get("imaging mode", ""))
        if "creep" in imaging:
            mode = "creep"
        elif "relaxation" in imaging:
            mode = "relaxation"
        elif (code == 1).any():
            hold = code == 1
            mode = "relaxation" if np.ptp(height[hold]) < 0.01 * max(
                float(depth_pl[hold].max()), 1e-300) else "creep"
        else:
            mode = "relaxation"
    if mode not in ("creep", "relaxation"):
        raise ValueError(f"mode must be 'creep' or 'relaxation', got {mode!r}")

    pre = app[app < ic]
    noise = float(np.std(force[pre] - base(pre))) if pre.size >= 2 else float("nan")
    if contact not in ("piecewise", "viscoelastic"):
        raise ValueError(f"contact must be 'piecewise' or 'viscoelastic', got "
                         f"{contact!r}")
    offset = 0.0  # force above the baseline at contact, removed ("viscoelastic")
    law = {1.5: "Hertz", 2.0: "Sneddon (cone)"}.get(exponent, f"d^{exponent:g}")
    contact_note = ("given (contact_index)" if contact_index is not None else
                    f"piecewise baseline + {law} fit (Lin et al. 2007)")
    piecewise_ic = ic
    if contact == "viscoelastic" and contact_index is None:
        ic, offset, contact_note = _refine_contact(
            time, force - f_base, height, code, ic, k, mode, exponent=exponent)
    keep_codes = tuple(SEGMENT_NAMES.index(s) for s in segments)
    raw = {"time": time, "force": force, "height": height, "segment": code,
           "force_above_baseline": force - f_base, "kept_codes": keep_codes,
           "piecewise_contact_index": int(piecewise_ic)}
    return _curve_at_contact(raw, ic, offset, mode=mode, spring_constant=k,
                             baseline_force=float(base(ic)) + offset,
                             baseline_noise=noise, path=path, metadata=metadata,
                             contact_note=contact_note)


def _curve_at_contact(raw, ic, offset, *, mode, spring_constant, baseline_force,
                      baseline_noise, path, metadata, contact_note) -> "AFMCurve":
    """The `AFMCurve` of a file's columns `raw` (see `AFMCurve.raw`) in contact from
    sample `ic` on, the force measured from the baseline plus `offset` [N]."""
    time, height, code = raw["time"], raw["height"], raw["segment"]
    k = spring_constant
    f_rel = raw["force_above_baseline"] - offset
    depth = (height[ic] - height) - f_rel / k
    keep = np.isin(code, raw["kept_codes"]) & (np.arange(time.size) >= ic) & (code >= 0)
    ret = np.flatnonzero(keep & (code == 2))
    if ret.size:
        # The model has no adhesion: stop where the retract loses contact.
        lost = (f_rel[ret] <= 0) | (depth[ret] <= 0)
        if lost.any():
            keep[ret[int(np.argmax(lost)):]] = False
    kept = np.flatnonzero(keep)
    if kept.size < 4 or not (depth[kept] > 0).any():
        raise ValueError("no contact: fewer than 4 samples with the probe in contact")
    return AFMCurve(
        time=time[kept] - time[ic],
        force=f_rel[kept],
        depth=depth[kept],
        segment=code[kept],
        mode=mode,
        spring_constant=k,
        contact_time=float(time[ic]),
        contact_height=float(height[ic]),
        baseline_force=baseline_force,
        baseline_noise=baseline_noise,
        path=path,
        metadata=metadata,
        raw={**raw, "contact_index": int(ic)},
        contact_note=contact_note,
    )
