"""Plots of `jc.Solution` and `jc.subsurface_stress` results (matplotlib).

`import jaxcontact.plot` (not imported by `jaxcontact` itself): matplotlib is imported
lazily inside each function, so the core package never needs it (`pip install
".[plot]"`). Figures are built with `matplotlib.figure.Figure` (no pyplot state), so
they work in scripts, on headless machines and in notebooks (a returned Figure is
displayed by Jupyter).

Every function returns the `Figure`. `ax` draws into existing axes instead (one
`Axes`, or a sequence of them where a plot has several panels); `path` also saves the
figure there (any format matplotlib knows from the suffix, e.g. `.png`, `.pdf`).

Lines "through the centre" are the central row or column of cells; for an even number
of cells there is no central one, and the mean of the two central rows (columns) is
shown, which is the value on the centre line for a field symmetric about it and a
second-order interpolation otherwise.
"""

import numpy as np


__all__ = [
    "profiles",
    "stick_slip_map",
    "stick_slip_maps",
    "loads",
    "load_indentation",
    "subsurface",
]

# State codes of `stick_slip_state`.
NO_CONTACT, SLIP, STICK = 0, 1, 2


# ----------------------------------------------------------------------------------
# Helpers
# ----------------------------------------------------------------------------------


def _new_axes(ax, count, figsize):
    """`(fig, axes)`: the given axes (checked) or a new Figure with `count` panels."""
    from matplotlib.figure import Figure

    if ax is None:
        fig = Figure(figsize=figsize, layout="constrained")
        axes = fig.subplots(1, count, squeeze=False)[0]
        return fig, list(axes)
    axes = (
        [ax]
        if count == 1 and not isinstance(ax, (list, tuple, np.ndarray))
        else list(np.ravel(ax))
    )
    if len(axes) != count:
        raise ValueError(f"ax must be {count} matplotlib Axes, got {len(axes)}")
    return axes[0].figure, axes


def _finish(fig, path):
    if path is not None:
        fig.savefig(path)
    return fig


def _check_solution(solution):
    for name in ("times", "pressure", "shear", "contact", "stick", "normal_force"):
        if not hasattr(solution, name):
            raise TypeError(
                f"solution must be a jc.Solution (from jc.solve), got "
                f"{type(solution).__name__} without a {name!r} field"
            )


def _normalise(normalise):
    if normalise is None:
        return 1.0, 1.0
    try:
        a0, p0 = (float(v) for v in normalise)
    except (TypeError, ValueError) as exc:
        raise ValueError(
            f"normalise must be a pair (a0, p0), got {normalise!r}"
        ) from exc
    if not (a0 > 0 and p0 > 0 and np.isfinite(a0) and np.isfinite(p0)):
        raise ValueError(
            f"normalise must be two positive numbers (a0, p0), got {normalise!r}"
        )
    return a0, p0


def _indices(solution, times, indices, default_count=4):
    """Time-step indices: nearest to `times`, or `indices`, or evenly spaced."""
    t = np.asarray(solution.times)
    nt = t.shape[0]
    if times is not None and indices is not None:
        raise ValueError("give times or indices, not both")
    if times is not None:
        values = np.atleast_1d(np.asarray(times, dtype=float))
        if not np.all(np.isfinite(values)):
            raise ValueError(f"times must be finite, got {times!r}")
        return [int(np.argmin(np.abs(t - v))) for v in values]
    if indices is not None:
        out = [int(i) for i in np.atleast_1d(indices)]
        for i in out:
            if not -nt <= i < nt:
                raise ValueError(f"index {i} out of range for {nt} time steps")
        return [i % nt for i in out]
    return sorted(
        set(np.linspace(0, nt - 1, min(default_count, nt)).round().astype(int))
    )


def centre_line(field, axis: str = "x"):
    """Values along the line through the centre: `field[..., :, centre]` for
    `axis="x"` (varying x at y = 0), `field[..., centre, :]` for `"y"`; the mean of
    the two central rows/columns when their number is even. `field`: `(..., nx, ny)`."""
    field = np.asarray(field)
    if axis not in ("x", "y"):
        raise ValueError(f'axis must be "x" or "y", got {axis!r}')
    dim = -1 if axis == "x" else -2
    n = field.shape[dim]
    picked = np.take(field, [n // 2] if n % 2 else [n // 2 - 1, n // 2], axis=dim)
    return picked.mean(axis=dim)


def stick_slip_state(solution, index):
    """`(nx, ny)` integer map at step `index`: 0 no contact, 1 slip, 2 stick."""
    contact = np.asarray(solution.contact[index])
    stick = np.asarray(solution.stick[index]) & contact
    return np.where(stick, STICK, np.where(contact, SLIP, NO_CONTACT))


def _extent(grid, scale):
    if grid is None:
        return None, ("cell i", "cell j")
    x, y = np.asarray(grid.x) / scale, np.asarray(grid.y) / scale
    dx, dy = (np.asarray(grid.spacing) / scale).tolist()
    extent = (x[0] - dx / 2, x[-1] + dx / 2, y[0] - dy / 2, y[-1] + dy / 2)
    return extent, ("x / a0", "y / a0") if scale != 1.0 else ("x", "y")


# ----------------------------------------------------------------------------------
# Solution plots
# ----------------------------------------------------------------------------------


def profiles(
    solution,
    grid,
    *,
    times=None,
    indices=None,
    axis: str = "x",
    normalise=None,
    ax=None,
    path=None,
):
    """Pressure and shear traction along a line through the centre, several times.

    **Arguments:**

    - `solution`: a `jc.Solution`; `grid`: its `jc.Grid` (for the coordinates).
    - `times`: times [time] to show (the nearest steps are used), or `indices`: step
      indices; default: four evenly spaced steps.
    - `axis`: `"x"` (the line y = 0, varying x) or `"y"`.
    - `normalise`: `(a0, p0)`, e.g. the Hertz contact radius and peak pressure, as in
      the paper's figures: positions are divided by `a0`, tractions by `p0`.
    - `ax`: two Axes (pressure, shear); `path`: save the figure there.

    The left panel shows `p`, the right panel the shear component along `axis`
    (`q_x` for `"x"`, `q_y` for `"y"`), both on the half-space (the sign
    conventions of docs/conventions.md).
    """
    _check_solution(solution)
    a0, p0 = _normalise(normalise)
    idx = _indices(solution, times, indices)
    coord = np.asarray(grid.x if axis == "x" else grid.y) / a0
    component = 0 if axis == "x" else 1
    fig, (axp, axq) = _new_axes(ax, 2, (9.0, 3.6))
    t = np.asarray(solution.times)
    for i in idx:
        label = f"t = {t[i]:.4g}"
        p = centre_line(solution.pressure[i], axis) / p0
        q = centre_line(solution.shear[i, component], axis) / p0
        axp.plot(coord, p, label=label)
        axq.plot(coord, q, label=label)
    unit = "/ a0" if normalise is not None else ""
    other = "y" if axis == "x" else "x"
    axp.set_xlabel(f"{axis} {unit}".strip())
    axq.set_xlabel(f"{axis} {unit}".strip())
    axp.set_ylabel("p / p0" if normalise is not None else "p")
    name = f"q_{axis}"
    axq.set_ylabel(f"{name} / p0" if normalise is not None else name)
    axp.set_title(f"pressure on {other} = 0")
    axq.set_title(f"shear {name} on {other} = 0")
    axp.legend(fontsize="small")
    return _finish(fig, path)


def stick_slip_map(
    solution, index: int, grid=None, *, normalise=None, ax=None, path=None
):
    """Map of the stick, slip and no-contact cells at step `index`.

    `grid` (optional) gives physical axes (divided by `a0` of `normalise=(a0, p0)`);
    without it the axes are cell indices. The image data are `stick_slip_state`
    (0 no contact, 1 slip, 2 stick), shown with x horizontal.
    """
    _check_solution(solution)
    return stick_slip_maps(
        solution, [index], grid, normalise=normalise, ax=ax, path=path
    )


def stick_slip_maps(
    solution, indices, grid=None, *, normalise=None, ax=None, path=None
):
    """Stick/slip maps (see `stick_slip_map`) at several steps, one panel each."""
    from matplotlib.colors import BoundaryNorm, ListedColormap
    from matplotlib.patches import Patch

    _check_solution(solution)
    idx = _indices(solution, None, indices)
    a0, _ = _normalise(normalise)
    extent, labels = _extent(grid, a0)
    fig, axes = _new_axes(ax, len(idx), (3.2 * len(idx) + 0.8, 3.4))
    colours = ["#f2f2f2", "#e4572e", "#2e86ab"]
    cmap = ListedColormap(colours)
    norm = BoundaryNorm([-0.5, 0.5, 1.5, 2.5], cmap.N)
    t = np.asarray(solution.times)
    ratio = np.asarray(solution.stick_ratio)
    for a, i in zip(axes, idx):
        # imshow's first image axis is vertical: transpose so that x is horizontal.
        a.imshow(
            stick_slip_state(solution, i).T,
            origin="lower",
            extent=extent,
            cmap=cmap,
            norm=norm,
            interpolation="nearest",
        )
        a.set_title(f"t = {t[i]:.4g}, stick ratio {ratio[i]:.2f}", fontsize="small")
        a.set_xlabel(labels[0])
        a.set_ylabel(labels[1])
    handles = [
        Patch(color=c, label=s)
        for c, s in zip(colours, ("no contact", "slip", "stick"))
    ]
    axes[-1].legend(handles=handles, fontsize="small", loc="upper right")
    return _finish(fig, path)


def loads(solution, *, ax=None, path=None):
    """Normal force, tangential forces, stick ratio and approach against time.

    Four panels (`ax`: four Axes): `W`; `F_x`, `F_y`; stick area / contact area;
    rigid-body approach `delta_z`. Units: those of the solution.
    """
    _check_solution(solution)
    t = np.asarray(solution.times)
    fig, (a1, a2, a3, a4) = _new_axes(ax, 4, (13.0, 3.2))
    a1.plot(t, np.asarray(solution.normal_force), marker=".")
    a1.set_ylabel("normal force W")
    f = np.asarray(solution.tangential_force)
    a2.plot(t, f[:, 0], marker=".", label="F_x")
    a2.plot(t, f[:, 1], marker=".", label="F_y")
    a2.set_ylabel("tangential force")
    a2.legend(fontsize="small")
    a3.plot(t, np.asarray(solution.stick_ratio), marker=".")
    a3.set_ylabel("stick ratio")
    a3.set_ylim(-0.02, 1.02)
    a4.plot(t, np.asarray(solution.approach), marker=".")
    a4.set_ylabel("approach")
    for a in (a1, a2, a3, a4):
        a.set_xlabel("t")
    return _finish(fig, path)


def load_indentation(solution, *, ax=None, path=None):
    """Normal force `W` against the approach `delta_z` (hysteresis loops of a
    viscoelastic loading-unloading cycle); the first step is marked."""
    _check_solution(solution)
    fig, (a,) = _new_axes(ax, 1, (4.6, 3.6))
    d = np.asarray(solution.approach)
    w = np.asarray(solution.normal_force)
    a.plot(d, w, marker=".")
    a.plot(d[:1], w[:1], marker="o", linestyle="none", color="k", label="start")
    a.set_xlabel("approach delta_z")
    a.set_ylabel("normal force W")
    a.legend(fontsize="small")
    return _finish(fig, path)


# ----------------------------------------------------------------------------------
# Subsurface stress
# ----------------------------------------------------------------------------------

_WHICH = ("von_mises", "max_shear", "sxx", "syy", "szz", "sxy", "sxz", "syz")


def subsurface_field(stress, which: str = "von_mises", axis: str = "x"):
    """`(nz, n)` section of a `jc.subsurface_stress` result on the plane through the
    centre (`axis="x"`: the x-z plane at y = 0; `"y"`: the y-z plane)."""
    if which not in _WHICH:
        raise ValueError(f"which must be one of {_WHICH}, got {which!r}")
    field = np.asarray(getattr(stress, which))
    if field.ndim != 3:
        raise ValueError(
            "stress must hold several depths (call jc.subsurface_stress with a 1-D "
            f"array of depths), got a field of shape {field.shape}"
        )
    return centre_line(field, axis)


def subsurface(
    grid,
    stress,
    which: str = "von_mises",
    *,
    axis: str = "x",
    normalise=None,
    levels: int = 20,
    ax=None,
    path=None,
):
    """Map of a subsurface stress on the x-z (or y-z) plane through the centre.

    **Arguments:**

    - `grid`: the `jc.Grid`; `stress`: `jc.subsurface_stress(grid, ..., depth=zs)`
      with a 1-D array `zs` of depths.
    - `which`: `"von_mises"`, `"max_shear"` (Tresca) or a component `"sxx"` ...
      `"syz"`.
    - `axis`: `"x"` (x-z plane at y = 0) or `"y"`.
    - `normalise`: `(a0, p0)`: lengths / a0, stresses / p0.
    - `levels`: number of filled contour levels; `ax`: one Axes; `path`: save there.

    Depth increases downwards. The contour data are `subsurface_field(...) / p0`.
    """
    if which not in _WHICH:
        raise ValueError(f"which must be one of {_WHICH}, got {which!r}")
    a0, p0 = _normalise(normalise)
    field = subsurface_field(stress, which, axis) / p0
    z = np.asarray(stress.depth) / a0
    coord = np.asarray(grid.x if axis == "x" else grid.y) / a0
    if field.shape != (z.shape[0], coord.shape[0]):
        raise ValueError(
            f"stress of shape {field.shape} (depth x {axis}) does not match the grid "
            f"({coord.shape[0]} cells along {axis})"
        )
    fig, (a,) = _new_axes(ax, 1, (6.0, 3.8))
    cs = a.contourf(coord, z, field, levels=levels, cmap="viridis")
    fig.colorbar(
        cs, ax=a, label=f"{which}" + (" / p0" if normalise is not None else "")
    )
    if not a.yaxis_inverted():
        a.invert_yaxis()
    unit = " / a0" if normalise is not None else ""
    a.set_xlabel(f"{axis}{unit}")
    a.set_ylabel(f"depth z{unit}")
    a.set_title(f"{which} on the {axis}-z plane through the centre", fontsize="small")
    return _finish(fig, path)
