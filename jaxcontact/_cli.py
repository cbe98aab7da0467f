"""Command-line tool.

    jaxcontact presets                                   list the built-in scenes
    jaxcontact run PRESET_OR_SCENE_FILE --out DIR [--n N] [--steps K] [--float32]
                   [--param KEY=VALUE ...] [--overwrite] [--format netcdf|npz]
                   [--scheme constant|linear]

`run hertz` solves the elastic Hertz indentation and prints it beside Hertz theory.
Any other preset (`jc.presets`) or a TOML scene file (schema: README, "Scene files")
is solved over its time axis with `jc.solve`; the result goes to `DIR/NAME.nc`
(netCDF-4: `Solution.to_xarray(scene)`, every field with named dimensions and units,
the scene in the attributes, and a JSON `metadata` attribute: preset or file,
parameters, units, versions; `jc.load` reads it back) or, with `--format npz`, to
`DIR/NAME.npz` (the same fields as plain arrays, the grid's `x`, `y` and the
`metadata` string), and to PNG plots. `--scheme` picks `jc.solve`'s time scheme (a
scene file's `scheme` otherwise, else `"constant"`). `DIR` is created and checked
before the solve; outputs already in it are replaced only with `--overwrite` (also for
a second run of the same command: rerun with `--overwrite` or another `--out`). Exit
status: 0 on success, 1 when a time step did not converge, 2 for bad input (unknown
preset, malformed TOML, bad values, an output folder that cannot be written, existing
outputs without `--overwrite`).

Warnings are printed on one line each (`jaxcontact: Category: message`, no source
line); the format is the CLI's only, restored when `main` returns. An option's value may
be a negative number in any notation (`--radius -5e-6`: reported as a bad value, not as
a missing one).
"""

import argparse
import ast
import json
import re
import sys
import time
import warnings
from pathlib import Path

from ._cli_output import InputError, prepare_out


UNITS = {
    "length": "m",
    "force": "N",
    "stress": "Pa",
    "time": "s",
    "times": "s",
    "x": "m",
    "y": "m",
    "pressure": "Pa",
    "shear": "Pa",
    "normal_force": "N",
    "approach": "m",
    "tangential_force": "N",
    "tangential_displacement": "m",
    "stick_ratio": "1",
}
SOLUTION_FIELDS = (
    "times",
    "pressure",
    "shear",
    "contact",
    "stick",
    "normal_force",
    "approach",
    "tangential_force",
    "tangential_displacement",
    "stick_ratio",
    "sliding",
    "converged",
    "iterations",
    "rounds",
    "residual",
)


def _num(value) -> str:
    """A setting as echoed on the console: 6 significant digits, so that a float32
    value reads as given (0.3, not 0.30000001192092896)."""
    return f"{float(value):.6g}"


def _versions() -> dict:
    from ._dataset import versions

    return versions()


def _parse_param(text: str):
    """`KEY=VALUE` -> (key, value); the value is a Python literal or else a string."""
    if "=" not in text:
        raise InputError(f"--param must be KEY=VALUE, got {text!r}")
    key, raw = text.split("=", 1)
    key = key.strip()
    if not key.isidentifier():
        raise InputError(f"--param key must be a name, got {key!r}")
    try:
        value = ast.literal_eval(raw.strip())
    except (ValueError, SyntaxError):
        value = raw.strip()
    return key, value


def _setup_jax(float32: bool, cache: bool = True):
    import jax

    from ._cache import cache_disabled_by_environment, enable_compilation_cache

    if not float32:
        jax.config.update("jax_enable_x64", True)
    if cache and not cache_disabled_by_environment():
        enable_compilation_cache()
    import jax.numpy as jnp

    return jnp.float32 if float32 else jnp.float64


# ---- Output folder and names ---------------------------------------------------------


def _check_stem(stem) -> str:
    """An output name (a scene file's `name`): one plain file-name component.

    Outputs are written as `OUT/STEM.npz` and `OUT/STEM_*.png`; a name with a path
    separator, `..` or a NUL would put them elsewhere (or fail after the solve).
    """
    if not isinstance(stem, str):
        raise InputError(f"name {stem!r} must be a string (the output file stem)")
    bad = (
        not stem
        or stem in (".", "..")
        or "/" in stem
        or "\\" in stem
        or "\0" in stem
        or Path(stem).name != stem
    )
    if bad:
        raise InputError(
            f"name {stem!r} is not a plain file name: it must be non-empty and hold no "
            "path separator ('/' or '\\') and not be '.' or '..' (outputs stay inside "
            "--out)"
        )
    return stem


_SUFFIX = {"netcdf": ".nc", "npz": ".npz"}


def _scene_outputs(stem: str, fmt: str = "netcdf") -> list:
    """Every file `_run_scene` may write for `stem` (plots only when they apply)."""
    return [f"{stem}{_SUFFIX[fmt]}"] + [
        f"{stem}_{kind}.png" for kind in ("profiles", "history", "stick")
    ]


# ---- Hertz: the main job, with its comparison table ----------------------------------


def _hertz(args, dtype) -> int:
    import jax.numpy as jnp
    import numpy as np

    import jaxcontact as jc

    if args.param:
        raise InputError("the hertz preset takes no --param")
    n = 256 if args.n is None else args.n
    if args.steps not in (None, 1):
        raise InputError(
            f"--steps: the hertz example is one load step, got {args.steps}"
        )
    if args.scheme is not None:
        raise InputError(
            f"--scheme: the hertz example is one load step (no time scheme), got "
            f"{args.scheme!r}"
        )
    result = f"hertz{_SUFFIX[args.format]}"
    out = prepare_out(Path(args.out), [result, "hertz.png"], args.overwrite)
    scene = jc.presets.hertz(n=n, dtype=dtype)
    grid, material = scene.grid, scene.material
    radius = float(scene.indenter.radius)
    force = float(scene.normal.values(scene.times)[0])
    shear_modulus, poisson = float(material.shear_modulus), float(material.poisson)
    hertz = jc.Hertz(radius, force, shear_modulus, poisson)
    a = float(hertz.contact_radius)
    size = float(grid.size[0])
    operator = jc.HalfSpace(grid)
    start = time.perf_counter()
    sol = jc.solve_normal(
        grid, scene.indenter, material, force=force, operator=operator
    )
    sol.pressure.block_until_ready()
    elapsed = time.perf_counter() - start

    a_num = float(np.sqrt(float(jnp.sum(sol.contact)) * float(grid.cell_area) / np.pi))
    rows = [
        ("contact radius a [m]", a_num, a),
        (
            "peak pressure p0 [Pa]",
            float(sol.pressure.max()),
            float(hertz.peak_pressure),
        ),
        ("approach delta [m]", float(sol.approach), float(hertz.approach)),
        ("normal force W [N]", float(sol.normal_force), force),
    ]
    precision = "float32" if dtype == jnp.float32 else "float64"
    print(
        f"Hertz indentation: rigid sphere R = {_num(radius)} m on G = "
        f"{_num(shear_modulus)} Pa, nu = {_num(poisson)}, W = {_num(force)} N; grid "
        f"{n}x{n} over {size:.3e} m ({precision})"
    )
    print(f"{'quantity':<24}{'jaxcontact':>14}{'Hertz':>14}{'rel. error':>12}")
    for name, num, ref in rows:
        print(f"{name:<24}{num:>14.6e}{ref:>14.6e}{num / ref - 1:>12.2e}")
    print(
        f"converged={bool(sol.converged)} iterations={int(sol.iterations)} "
        f"residual={float(sol.residual):.1e} time={elapsed:.2f} s (incl. compilation)"
    )

    meta = dict(
        scene="hertz",
        preset="hertz",
        parameters={"n": n, "steps": 1},
        radius=radius,
        force=force,
        shear_modulus=shear_modulus,
        poisson=poisson,
        shape=[n, n],
        size=size,
        dtype=precision,
        units="SI (m, N, Pa)",
        converged=bool(sol.converged),
        iterations=int(sol.iterations),
        residual=float(sol.residual),
        version=jc.__version__,
        versions=_versions(),
    )
    if args.format == "npz":
        np.savez(
            out / result,
            x=np.asarray(grid.x),
            y=np.asarray(grid.y),
            pressure=np.asarray(sol.pressure),
            gap=np.asarray(sol.gap),
            contact=np.asarray(sol.contact),
            approach=float(sol.approach),
            metadata=json.dumps(meta),
        )
    else:
        from ._dataset import to_netcdf

        ds = sol.to_xarray(
            grid, material=material, indenter=scene.indenter,
            attrs={"metadata": json.dumps(meta), "preset": "hertz"},
        )
        to_netcdf(ds, out / result)
    print(f"wrote {out / result}")
    plt = _pyplot()
    if plt is None:
        return 0 if bool(sol.converged) else 1
    x = np.asarray(grid.x) / a
    row = np.asarray(sol.pressure)[:, n // 2] / float(hertz.peak_pressure)
    fig, ax = plt.subplots(figsize=(5, 3.5))
    xr = np.linspace(-1.5, 1.5, 400)
    ax.plot(xr, np.sqrt(np.clip(1 - xr**2, 0, None)), "k-", label="Hertz")
    ax.plot(x, row, "o", ms=3, label=f"jaxcontact {n}x{n}")
    ax.set_xlim(-1.5, 1.5)
    ax.set_xlabel("x / a")
    ax.set_ylabel("p / p0")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "hertz.png", dpi=120)
    plt.close(fig)
    print(f"wrote {out / 'hertz.png'}")
    return 0 if bool(sol.converged) else 1


def _pyplot():
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed: no plots (pip install 'jaxcontact[plot]')")
        return None
    return plt


# ---- Any scene: a preset or a TOML file ----------------------------------------------


def _scene_from_args(args, dtype):
    """(stem, scene, solve options, metadata) for a preset name or a TOML file."""
    import jaxcontact as jc

    target = args.target
    params = dict(_parse_param(p) for p in args.param)
    if target.endswith(".toml") or Path(target).is_file():
        if params:
            raise InputError("--param applies to presets only; edit the scene file")
        path = Path(target)
        if not path.is_file():
            raise InputError(f"scene file {target!r} does not exist")
        try:
            spec = jc.presets.read_toml(path)
            scene, options = jc.presets.from_spec(
                spec, n=args.n, steps=args.steps, dtype=dtype, base=path.parent
            )
        except (ValueError, TypeError) as exc:
            raise InputError(f"scene file {target}: {exc}") from exc
        stem = _check_stem(spec.get("name", path.stem))
        meta = {
            "scene_file": str(path),
            "scene": spec,
            "description": spec.get("description", ""),
        }
        return stem, scene, options, meta
    if target not in jc.presets.available():
        raise InputError(
            f"unknown preset {target!r} (and no such scene file); "
            f"available presets: {', '.join(jc.presets.available())}"
        )
    if args.n is not None:
        params["n"] = args.n
    if args.steps is not None:
        params["steps"] = args.steps
    try:
        full = jc.presets.parameters(target, **params)
        scene = jc.presets.build(target, **params, dtype=dtype)
    except (ValueError, TypeError) as exc:
        raise InputError(f"preset {target}: {exc}") from exc
    full.pop("dtype", None)
    full["steps"] = int(scene.times.shape[0])
    meta = {
        "preset": target,
        "parameters": full,
        "description": jc.presets.available()[target],
    }
    return target, scene, {}, meta


def _describe(scene) -> dict:
    import numpy as np

    def leaves(module):
        out = {}
        for name, value in vars(module).items():
            arr = np.asarray(value)
            out[name] = arr.item() if arr.size == 1 else arr.tolist()
        return out

    return {
        "shape": list(scene.grid.shape),
        "size": np.asarray(scene.grid.size).tolist(),
        "material": {"type": type(scene.material).__name__, **leaves(scene.material)},
        "indenter": type(scene.indenter).__name__,
        "normal": type(scene.normal).__name__,
        "x": None if scene.x is None else type(scene.x).__name__,
        "y": None if scene.y is None else type(scene.y).__name__,
        "friction": float(scene.friction),
        "coupling": scene.coupling,
        "slip": scene.slip,
        "nt": int(scene.times.shape[0]),
    }


def _progress_table(sol, rows: int = 10) -> str:
    """Every ~nt/rows steps: time, loads, stick ratio and solver status."""
    import numpy as np

    nt = sol.times.shape[0]
    stride = max(1, int(np.ceil(nt / rows)))
    head = (
        f"{'step':>6}{'t [s]':>12}{'W [N]':>12}{'delta_z [m]':>13}"
        f"{'F_x [N]':>12}{'stick':>8}{'ok':>4}{'iter':>6}"
    )
    lines = [head]
    for k in sorted(set(range(0, nt, stride)) | {nt - 1}):
        lines.append(
            f"{k:>6}{sol.times[k]:>12.4g}{sol.normal_force[k]:>12.4g}"
            f"{sol.approach[k]:>13.4g}{sol.tangential_force[k, 0]:>12.4g}"
            f"{sol.stick_ratio[k]:>8.3f}{'y' if sol.converged[k] else 'N':>4}"
            f"{sol.iterations[k]:>6d}"
        )
    return "\n".join(lines)


def _run_scene(args, dtype) -> int:
    import jax
    import numpy as np

    import jaxcontact as jc

    stem, scene, options, meta = _scene_from_args(args, dtype)
    if args.scheme is not None:
        options = {**options, "scheme": args.scheme}
    outputs = _scene_outputs(stem, args.format)
    out = prepare_out(Path(args.out), outputs, args.overwrite)
    info = _describe(scene)
    nt = info["nt"]
    precision = np.dtype(dtype).name
    print(f"{stem}: {meta['description']}".rstrip(": "))
    print(
        f"grid {info['shape'][0]}x{info['shape'][1]} over "
        f"{info['size'][0]:.4g} m x {info['size'][1]:.4g} m, {nt} time points, "
        f"{info['material']['type']}, coupling={info['coupling']}, "
        f"friction={_num(info['friction'])}, "
        f"scheme={options.get('scheme', 'constant')}, {precision}"
    )
    print(
        f"solving {nt} time steps (one compiled program; compilation included) ...",
        flush=True,
    )
    start = time.perf_counter()
    from ._validate import clear_runtime_errors

    try:
        with clear_runtime_errors():  # a failed run-time check: exit 2, message first
            sol = jc.solve(scene, progress=args.progress and nt > 1, throw=False,
                           **options)
            sol = jax.tree_util.tree_map(np.asarray, sol)
    except (ValueError, TypeError) as exc:
        raise InputError(f"{stem}: {exc}") from exc
    elapsed = time.perf_counter() - start
    print(_progress_table(sol))
    n_bad = int((~sol.converged).sum())
    print(
        f"done in {elapsed:.2f} s on the {sol.method}: {nt - n_bad}/{nt} steps "
        f"converged, "
        f"max residual {float(sol.residual.max()):.1e}"
    )

    meta.update(
        scene_summary=info,
        dtype=precision,
        units=UNITS,
        versions=_versions(),
        solve_options=options,
        wall_time_s=elapsed,
        converged=n_bad == 0,
    )
    result = out / f"{stem}{_SUFFIX[args.format]}"
    if args.format == "npz":
        arrays = {name: np.asarray(getattr(sol, name)) for name in SOLUTION_FIELDS}
        np.savez(
            result,
            x=np.asarray(scene.grid.x),
            y=np.asarray(scene.grid.y),
            metadata=json.dumps(meta, default=str),
            **arrays,
        )
    else:
        from ._dataset import to_netcdf

        ds = sol.to_xarray(
            scene, solve_options=options,
            attrs={"metadata": json.dumps(meta, default=str), "name": stem},
        )
        to_netcdf(ds, result)
    print(f"wrote {result}")
    for path in _standard_plots(scene, sol, out, stem):
        print(f"wrote {path}")
    if n_bad:
        print(
            f"warning: {n_bad} time step(s) did not converge (see 'converged' in the "
            f"{result.name})",
            file=sys.stderr,
        )
        return 1
    return 0


def _standard_plots(scene, sol, out: Path, stem: str) -> list:
    """Pressure (and shear) profiles along x, loads against time, stick/slip map."""
    import numpy as np

    plt = _pyplot()
    if plt is None:
        return []
    x = np.asarray(scene.grid.x)
    nx, ny = scene.grid.shape
    j = ny // 2
    nt = sol.times.shape[0]
    picks = sorted(set(np.linspace(0, nt - 1, min(nt, 5)).round().astype(int)))
    frictional = bool(sol.shear.any())
    paths = []

    fig, axes = plt.subplots(
        1, 2 if frictional else 1, figsize=(9 if frictional else 5, 3.5), squeeze=False
    )
    for k in picks:
        axes[0, 0].plot(
            x * 1e6, sol.pressure[k, :, j] / 1e6, label=f"t = {sol.times[k]:.3g} s"
        )
        if frictional:
            axes[0, 1].plot(x * 1e6, sol.shear[k, 0, :, j] / 1e6)
    axes[0, 0].set_xlabel("x [um]")
    axes[0, 0].set_ylabel("pressure p [MPa] (y = 0)")
    axes[0, 0].legend(fontsize=7)
    if frictional:
        axes[0, 1].set_xlabel("x [um]")
        axes[0, 1].set_ylabel("shear q_x [MPa] (y = 0)")
    fig.tight_layout()
    paths.append(out / f"{stem}_profiles.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)

    if nt > 1:
        fig, ax = plt.subplots(1, 3, figsize=(12, 3.3))
        ax[0].plot(sol.times, sol.normal_force, ".-")
        ax[0].set_ylabel("normal force W [N]")
        ax[1].plot(sol.times, sol.approach * 1e6, ".-")
        ax[1].set_ylabel("approach delta_z [um]")
        ax[2].plot(sol.times, sol.tangential_force[:, 0], ".-", label="F_x [N]")
        ax[2].set_ylabel("F_x [N]")
        twin = ax[2].twinx()
        twin.plot(sol.times, sol.stick_ratio, "r.--")
        twin.set_ylabel("stick ratio", color="r")
        for a in ax:
            a.set_xlabel("t [s]")
        fig.tight_layout()
        paths.append(out / f"{stem}_history.png")
        fig.savefig(paths[-1], dpi=110)
        plt.close(fig)

    if frictional or sol.stick.any():
        fig, axes = plt.subplots(
            1, len(picks), figsize=(2.6 * len(picks), 2.8), squeeze=False
        )
        extent = [
            x[0] * 1e6,
            x[-1] * 1e6,
            float(scene.grid.y[0]) * 1e6,
            float(scene.grid.y[-1]) * 1e6,
        ]
        for a, k in zip(axes[0], picks):
            state = sol.contact[k].astype(int) + sol.stick[k].astype(int)
            a.imshow(
                state.T, origin="lower", extent=extent, cmap="Greys", vmin=0, vmax=2
            )
            a.set_title(f"t = {sol.times[k]:.3g} s", fontsize=8)
            a.set_xlabel("x [um]", fontsize=8)
        axes[0, 0].set_ylabel("y [um]  (dark: stick, grey: slip)", fontsize=8)
        fig.tight_layout()
        paths.append(out / f"{stem}_stick.png")
        fig.savefig(paths[-1], dpi=110)
        plt.close(fig)
    return paths


# ---- Entry point ---------------------------------------------------------------------


def _parser():
    parser = argparse.ArgumentParser(
        prog="jaxcontact",
        description="jaxcontact: contact scenes from the command line.",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="solve a preset or a TOML scene file")
    run.add_argument(
        "target",
        metavar="PRESET_OR_SCENE_FILE",
        help="a preset name (see `jaxcontact presets`) or a .toml scene file",
    )
    run.add_argument(
        "--out",
        default="jaxcontact-out",
        help="output directory (created if missing; checked before the solve)",
    )
    run.add_argument(
        "--overwrite",
        action="store_true",
        help="replace outputs of the same name already in --out (default: refuse)",
    )
    run.add_argument(
        "--n",
        type=int,
        default=None,
        help="grid cells per side (default: the preset's / file's)",
    )
    run.add_argument(
        "--steps",
        type=int,
        default=None,
        help="time points including t = 0 (default: the preset's / file's)",
    )
    run.add_argument(
        "--float32", action="store_true", help="single precision (default: float64)"
    )
    run.add_argument(
        "--format",
        choices=("netcdf", "npz"),
        default="netcdf",
        help="result file: netcdf (default; NAME.nc, read with jc.load or "
        "xarray.open_dataset) or npz (NAME.npz, plain arrays and a JSON metadata "
        "string)",
    )
    run.add_argument(
        "--scheme",
        choices=("constant", "linear"),
        default=None,
        help="time scheme of jc.solve: constant (tractions piecewise constant in "
        "time, the paper's; the default) or linear (piecewise linear: what a "
        "TimeStepWarning advises); overrides a scene file's scheme",
    )
    run.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a preset argument, e.g. --param ratio=10 (repeatable)",
    )
    run.add_argument(
        "--progress", action="store_true",
        help="report each step on stderr as it completes (a host callback: that "
             "program is not written to the compilation cache)")
    from ._cache import add_cache_argument

    add_cache_argument(run)
    sub.add_parser("presets", help="list the built-in presets")
    sub.add_parser("examples", help="same as `presets`")
    from ._cli_fit import add_parser as add_fit_parser

    add_fit_parser(sub)
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """`warnings.showwarning` for the CLI: `jaxcontact: Category: message` on one line
    of stderr (no file, line number or source line: they point into the library)."""
    text = " ".join(str(message).split())
    stream = sys.stderr if file is None else file
    try:
        stream.write(f"jaxcontact: {category.__name__}: {text}\n")
    except OSError:  # stderr closed: drop the warning, as warnings.showwarning does
        pass


# A negative number in any notation: argparse (3.11) takes "-5e-6" for an option.
_NEGATIVE_NUMBER = re.compile(r"-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?|-inf|-nan", re.I)


def _attach_negative_values(argv) -> list:
    """`--opt -5e-6` -> `--opt=-5e-6`, so that argparse reads a negative number as the
    option's value (and the option's own check names it) instead of failing with
    "expected one argument"."""
    out = []
    for arg in argv:
        prev = out[-1] if out else ""
        if (_NEGATIVE_NUMBER.fullmatch(arg) and prev.startswith("--") and prev != "--"
                and "=" not in prev):
            out[-1] = f"{prev}={arg}"
        else:
            out.append(arg)
    return out


def main(argv=None) -> int:
    """Run the command line `argv` (default: `sys.argv[1:]`); return the exit status."""
    # The CLI's one-line warnings, restored on return: library users keep their own.
    with warnings.catch_warnings():
        warnings.showwarning = _show_warning
        return _main(sys.argv[1:] if argv is None else list(argv))


def _main(argv) -> int:
    parser = _parser()
    try:
        args = parser.parse_args(_attach_negative_values(argv))
    except SystemExit as exc:  # argparse: 2 for bad usage, 0 for --help
        return int(exc.code or 0)
    if args.command == "fit":
        from ._cli_fit import run_fit

        return run_fit(args)
    try:
        if args.command in ("presets", "examples"):
            from . import presets

            for name, text in presets.available().items():
                print(f"{name:<16}{text}")
            return 0
        if args.n is not None and args.n < 2:
            raise InputError(f"--n must be >= 2, got {args.n}")
        if args.steps is not None and args.steps < 1:
            raise InputError(f"--steps must be >= 1, got {args.steps}")
        if args.float32:
            # The presets are defined in float64 and cast: the truncation is the
            # point of --float32, not news to its user.
            warnings.filterwarnings(
                "ignore", "Explicitly requested dtype float64", UserWarning
            )
        dtype = _setup_jax(args.float32, cache=not args.no_cache)
        if args.target == "hertz":
            return _hertz(args, dtype)
        return _run_scene(args, dtype)
    except InputError as exc:
        print(f"jaxcontact: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # a file that cannot be read or written: name it
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"jaxcontact: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
