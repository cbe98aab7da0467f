"""`jc.fit_force_map`: an AFM force map (curves on a grid of positions) in, a map of
Prony parameters out, through `jc.fit_prony_batch` (one compiled fit for all curves)."""

import os

import numpy as np

from ._afm import SEGMENT_NAMES, _afmformats, read_afm
from .fitting import IndentationData, fit_prony_batch


def _grid_index(metadata, axis: str, fallback: int) -> int:
    value = metadata.get(f"grid index {axis}")
    return fallback if value is None else int(value)


def fit_force_map(source, radius, n_terms: int = 2, *, samples=None, n: int = 24,
                  poisson: float = 0.5, contact: str = "piecewise",
                  baseline: str = "constant", segments=SEGMENT_NAMES, **options):
    """Fit a Prony series to every curve of a force map and return the parameters as a
    map.

    **Main arguments:**

    - `source`: a path to a multi-curve file that `afmformats` reads (a JPK
      `.jpk-force-map`, a QI series, ...), or a sequence of afmformats curve objects.
    - `radius`: the probe (sphere) radius [m]; absolute moduli scale as
      `radius^(-1/2)`, relaxation times and modulus ratios do not depend on it.
    - `n_terms`: Maxwell arms of the series.

    **Other arguments:**

    - `samples`: points after binning, a dict segment name -> count (as
      `AFMCurve.data`); default 16 per segment. Every curve is binned alike, so that
      all have the same number of samples (one compiled fit).
    - `n`: grid cells per side of the contact model. One scene template serves every
      curve: that of the curve indented deepest (`AFMCurve.scene_template`), so that
      its grid holds every contact; shallower curves have fewer cells in contact.
    - `poisson`, `contact`, `baseline`, `segments`: as `jc.read_afm` /
      `AFMCurve.scene_template`.
    - `**options`: keywords of `jc.fit_prony_batch` (`init`, `lm_steps`, `vectorize`,
      `devices`, `client`, `solve_options`, ...). Each curve's samples are weighted by
      `sqrt` of their bins' counts (bin means: the inverse of their noise).

    **Returns:** an `xarray.Dataset` on the map's grid indices `y`, `x` (and `arm`):
    `g_inf`, `g`, `tau` [Pa, s], `log_std_g_inf`, `log_std_g`, `log_std_tau` (standard
    deviations of the natural logs), `converged` (bool), `loss`, `lm_steps`,
    `position_x`, `position_y` [m] (the stage positions the file records, NaN where
    absent) and `contact_time` [s]; cells without a curve are NaN (`converged`
    False). Attributes: `radius_m`, `poisson`, `mode` (creep or relaxation), `source`.

    **Raises:** `ValueError` for a file without curves, curves of different modes
    (creep and relaxation), or two curves at one grid position; what `jc.read_afm`
    and `jc.fit_prony_batch` raise for a bad curve or option.
    """
    import xarray as xr

    # -- The curves --------------------------------------------------------------------
    if isinstance(source, (str, os.PathLike)):
        path = os.fspath(source)
        if not os.path.exists(path):
            raise ValueError(f"no such file: {path!r}")
        try:
            raw = list(_afmformats().load_data(path))
        except Exception as exc:
            raise ValueError(f"afmformats cannot read {path!r}: {exc}") from exc
        name = path
    else:
        raw, name = list(source), "curves"
    if not raw:
        raise ValueError(f"fit_force_map: {name!r} holds no curve")
    curves = [read_afm(c, contact=contact, baseline=baseline, segments=segments)
              for c in raw]
    modes = {c.mode for c in curves}
    if len(modes) != 1:
        raise ValueError(f"fit_force_map: the curves mix modes {sorted(modes)}")
    ix = [_grid_index(c.metadata, "x", i) for i, c in enumerate(raw)]
    iy = [_grid_index(c.metadata, "y", 0) for c in raw]
    if len(set(zip(ix, iy, strict=True))) != len(raw):
        raise ValueError("fit_force_map: two curves share a grid position")

    # -- One batched fit ---------------------------------------------------------------
    samples = {k: 16 for k in SEGMENT_NAMES} if samples is None else samples
    data, weights = [], []
    for c in curves:
        t, f, d, _, counts = c.resampled(samples, return_counts=True)
        data.append(IndentationData(t, force=f, depth=d))
        weights.append(np.sqrt(counts))
    deepest = int(np.argmax([float(np.max(c.depth)) for c in curves]))
    template = curves[deepest].scene_template(radius, n=n, poisson=poisson)
    fits = fit_prony_batch(data, template, n_terms, weights=weights, **options)

    # -- The map -----------------------------------------------------------------------
    xs, ys = sorted(set(ix)), sorted(set(iy))
    shape = (len(ys), len(xs))

    def empty(*extra, fill=np.nan, dtype=float):
        return np.full(shape + extra, fill, dtype)

    g_inf, log_std_g_inf, loss = empty(), empty(), empty()
    g, tau = empty(n_terms), empty(n_terms)
    log_std_g, log_std_tau = empty(n_terms), empty(n_terms)
    px, py, t_contact = empty(), empty(), empty()
    converged = empty(fill=False, dtype=bool)
    steps = empty(fill=-1, dtype=int)
    for k, (fit, c, m) in enumerate(zip(fits, curves, raw, strict=True)):
        j, i = ys.index(iy[k]), xs.index(ix[k])
        g_inf[j, i] = float(fit.material.g_inf)
        g[j, i] = np.asarray(fit.material.g)
        tau[j, i] = np.asarray(fit.material.tau)
        log_std_g_inf[j, i] = float(fit.std["g_inf"])
        log_std_g[j, i] = np.asarray(fit.std["g"])
        log_std_tau[j, i] = np.asarray(fit.std["tau"])
        converged[j, i] = bool(fit.converged)
        loss[j, i] = float(fit.loss)
        steps[j, i] = int(fit.lm_steps)
        px[j, i] = m.metadata.get("position x", np.nan)
        py[j, i] = m.metadata.get("position y", np.nan)
        t_contact[j, i] = c.contact_time
    dims, arm = ("y", "x"), ("y", "x", "arm")
    return xr.Dataset(
        {
            "g_inf": (dims, g_inf, {"units": "Pa"}),
            "g": (arm, g, {"units": "Pa"}),
            "tau": (arm, tau, {"units": "s"}),
            "log_std_g_inf": (dims, log_std_g_inf),
            "log_std_g": (arm, log_std_g),
            "log_std_tau": (arm, log_std_tau),
            "converged": (dims, converged),
            "loss": (dims, loss),
            "lm_steps": (dims, steps),
            "position_x": (dims, px, {"units": "m"}),
            "position_y": (dims, py, {"units": "m"}),
            "contact_time": (dims, t_contact, {"units": "s"}),
        },
        coords={"y": ys, "x": xs, "arm": np.arange(n_terms)},
        attrs={"radius_m": float(radius), "poisson": float(poisson),
               "mode": curves[0].mode, "source": str(name)},
    )
