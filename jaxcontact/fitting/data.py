"""The measured curves (`jc.IndentationData`, checked when made) and the scene they
define: the template's scene on the data's times, its loading taken from the data,
and which curve (force or depth) is fitted."""

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._loading import Displacement, Force
from .._scene import Scene


def check_series(name: str, value) -> np.ndarray:
    if isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be an array of real numbers, got {value!r}")
    try:
        arr = np.asarray(value)
    except Exception as exc:  # pragma: no cover - exotic input
        raise TypeError(
            f"{name} must be an array of real numbers, got {value!r}") from exc
    if arr.dtype == object or arr.dtype.kind not in "iuf":
        raise TypeError(
            f"{name} must be an array of real numbers, got dtype {arr.dtype}")
    if arr.ndim != 1:
        raise ValueError(f"{name} must be a 1-D array, got shape {arr.shape}")
    bad = ~np.isfinite(arr)
    if bad.any():
        raise ValueError(
            f"{name} must be finite: NaN or inf at index {int(np.argmax(bad))} "
            f"(value {arr[np.argmax(bad)]!r})"
        )
    return arr


class IndentationData(eqx.Module):
    """Measured indentation curves on a common time axis.

    **Arguments:**

    - `times`: `(nt,)` strictly increasing sample times [time], at least 3.
    - `force`: optional `(nt,)` normal load `W(t)` [force].
    - `depth`: optional `(nt,)` indentation depth = rigid-body approach `delta_z(t)`
      [length], positive into the body.

    At least one of `force`, `depth` is required. Which one is fitted depends on the
    scene's control mode (see `jc.fit_prony`). Values are checked here: NaN or inf,
    repeated or decreasing times and length mismatches raise `ValueError`.
    """

    times: np.ndarray
    force: np.ndarray | None
    depth: np.ndarray | None

    def __init__(self, times, force=None, depth=None):
        times = check_series("times", times).astype(float)
        if times.shape[0] < 3:
            raise ValueError(f"times needs at least 3 samples, got {times.shape[0]}")
        steps = np.diff(times)
        if not (steps > 0).all():
            k = int(np.argmax(steps <= 0))
            what = "repeated" if steps[k] == 0 else "decreasing (not monotonic)"
            raise ValueError(
                f"times must be strictly increasing: {what} at index {k + 1} "
                f"(times[{k}]={times[k]!r}, times[{k + 1}]={times[k + 1]!r})"
            )
        if force is None and depth is None:
            raise ValueError(
                "IndentationData needs force, depth, or both (got neither)")
        out = {}
        for name, value in (("force", force), ("depth", depth)):
            if value is None:
                out[name] = None
                continue
            arr = check_series(name, value).astype(float)
            if arr.shape != times.shape:
                raise ValueError(
                    f"{name} must have one value per time ({times.shape[0]}), "
                    f"got length {arr.shape[0]}"
                )
            out[name] = arr
        self.times = times
        self.force = out["force"]
        self.depth = out["depth"]


def _check_program(name, value, times):
    """A loading program given as an array must have one value per data time."""
    if not callable(value) and jnp.ndim(value) == 1 and value.shape != times.shape:
        if name == "normal":
            raise ValueError(
                f"scene_template.normal holds {value.shape[0]} values but the data "
                f"have {times.shape[0]} times: give the loading as a callable of t, a "
                "scalar, or in the data (IndentationData(force=..., depth=...))"
            )
        raise ValueError(
            f"scene_template.{name} holds {value.shape[0]} values but the "
            f"data have {times.shape[0]} times: give it as a callable of t or a "
            "scalar"
        )


def scene_for(data: IndentationData, template: Scene, dtype):
    """The scene on the data's times, its loading taken from the data when given, and
    the kind of curve to fit."""
    times = jnp.asarray(data.times, dtype)
    if isinstance(template.normal, Displacement):
        kind, target, driver = "force", data.force, data.depth
        if target is None:
            raise ValueError(
                "scene_template is displacement-controlled (normal=jc.Displacement): "
                "data.force is required (the force is what is fitted)"
            )
        make = Displacement
    else:
        kind, target, driver = "depth", data.depth, data.force
        if target is None:
            raise ValueError(
                "scene_template is load-controlled (normal=jc.Force): data.depth is "
                "required (the depth is what is fitted)"
            )
        make = Force
    if driver is not None:
        normal = make(jnp.asarray(driver, dtype))
    else:
        normal = template.normal
        _check_program("normal", normal.value, times)
    for name in ("x", "y"):
        program = getattr(template, name)
        if program is not None:
            _check_program(name, program.value, times)
    scene = Scene(template.grid, template.indenter, template.material, times, normal,
                  template.x, template.y, template.friction, template.coupling,
                  template.slip)
    return scene, kind, jnp.asarray(target, dtype)
