"""Ready-made scenes: every numerical study of the paper (Wang, de Boer & Ghanbarzadeh,
sections 3 and 4), plus a plain Hertz indentation.

Each preset is a function `jc.presets.<name>(n=..., steps=..., ...)` that returns a
`jc.Scene`. `n` is the number of grid cells per side (the paper uses 256); `steps` is
the number of time points including `t = 0` (the paper's "time steps"; `None` picks the
paper's value, or ours where the paper gives none). `dtype` (e.g. `jnp.float32`) casts
every floating-point leaf of the scene; `None` keeps JAX's default float type.

Units are SI (m, N, Pa, s). Moduli are TRUE shear moduli: the paper's tables and
equations list twice the shear modulus (its published a0 and p0 come out only with
`E* = G_paper / (1 - nu)`; docs/conventions.md, "Moduli"), so every modulus of the
paper is halved here, every compliance doubled, and viscosities halved (relaxation
times are unchanged).

Presets with friction use the paper's slip law (`slip="total"`, its Eq. 16) unless told
otherwise (`slip="incremental"`, path dependent, is `jc.Scene`'s default).

`available()` lists the names with one-line descriptions; `build(name, **kwargs)` calls
one by name; `from_toml(path)` reads a user-defined scene file (README, "Scene
files").

!!! note "Time step"
    The paper's scheme (tractions piecewise constant in time) needs steps short against
    the relaxation time `tau mu_0 / mu_inf`: under a held displacement the first step's
    discrete relaxation factor is `2 - J(dt) / J(0)`, negative (contact lost, tractions
    oscillating in time) once `J(dt) > 2 J(0)`. The paper's step counts satisfy this;
    when you cut `steps`, cut `duration` too (e.g. ratio 10 needs `dt < 0.12 tau`).
"""

import dataclasses
import inspect
import tomllib
import warnings
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from ._analytic import Hertz
from ._grid import Grid
from ._indenter import Sphere, Surface
from ._loading import Displacement, Force
from ._material.elastic import Elastic
from ._material.maxwell import Maxwell
from ._material.prony import Prony
from ._material.zener import Zener
from ._scene import Scene
from ._validate import EdgeContactWarning, check_int


# ---- The paper's parameters, converted to true shear moduli (SI) ---------------------

# Table 1 (section 3): Maxwell model, step load.
TABLE1 = dict(
    radius=3.5e-3,  # m
    force=100.0,  # N
    shear_modulus=81.92e9 / 2,  # Pa (paper: G = 81.92 GPa, twice the shear modulus)
    viscosity=81.92e9 / 2,  # Pa s (paper: 81.92 GPa s); tau = eta / G = 1 s
    poisson=0.5,
    domain=512e-6,  # m, square
    a0=117e-6,  # m, quoted Hertz contact radius
    p0=3487e6,  # Pa, quoted Hertz peak pressure
)

# Table 2 (section 4.1) and section 4.2: Zener model (paper Eqs. 29-30).
TABLE2 = dict(
    radius=10e-3,  # m
    force=0.15,  # N
    mu_inf=3.86e6 / 2,  # Pa (paper: 3.86 MPa, twice the shear modulus)
    tau=0.01,  # s, the tau of Eqs. 29-30 (the retardation time; see jc.Zener)
    poisson=0.3,
    domain_a0=5.5,  # the square side, in units of a0
    a0=588.7e-6,  # m, quoted Hertz contact radius
    p0=0.2067e6,  # Pa, quoted Hertz peak pressure
)

# PMMA (paper Eqs. 26-28, from Chen et al. 2011) and the fictitious material (Eq. 31).
PMMA = dict(
    g_inf=1429.71e6 / 2,  # Pa (paper Eq. 27 in MPa, twice the shear modulus)
    g=(184.62e6 / 2, 191.06e6 / 2),  # Pa
    tau=(8.93, 117.96),  # s, relaxation times
    poisson=0.38,
    radius=3.5e-3,  # m
    domain=1280e-6,  # m, square
)
FICTITIOUS = dict(
    # Eq. 31: Phi(t) = 0.699 - 0.5595 exp(-t/133.869) - 0.02 exp(-t/9.9404) 1/GPa, in
    # the paper's convention (compliance of 2G): the true shear compliance is twice it.
    j_inf=2 * 0.699e-9,  # 1/Pa
    j=(2 * 0.5595e-9, 2 * 0.02e-9),  # 1/Pa
    tau=(133.869, 9.9404),  # s, retardation times
    poisson=0.38,
)

# Section 4.2: friction and the constant inputs of the DC and relaxation cases. The
# paper prints delta_z = 34.358 and delta_x = 6.1987 without a unit; micrometres fit
# (the Hertz approach a0^2 / R of Table 2 is 34.66 um).
FRICTION = 0.30
DELTA_X = 6.1987e-6  # m
DELTA_Z = 34.358e-6  # m


# ---- Helpers -------------------------------------------------------------------------


def _check_positive(name, value):
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
        raise TypeError(f"{name} must be a real number, got {value!r}")
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be finite and > 0, got {value!r}")
    return float(value)


def _check_choice(name, value, choices):
    if value not in choices:
        raise ValueError(f"{name} must be one of {choices}, got {value!r}")
    return value


def _steps(steps, default):
    return default if steps is None else check_int("steps", steps, 2)


def _ratio(ratio):
    ratio = _check_positive("ratio", ratio)
    if ratio < 1:
        raise ValueError(
            f"ratio (mu_inf / mu_0) must be >= 1 for a viscoelastic solid, "
            f"got {ratio!r}"
        )
    return ratio


def _cast(scene: Scene, dtype) -> Scene:
    """Cast every floating-point array leaf of `scene` to `dtype` (`None`: no cast)."""
    if dtype is None:
        return scene
    dtype = jnp.dtype(dtype)
    if not jnp.issubdtype(dtype, jnp.floating):
        raise ValueError(f"dtype must be a floating-point type, got {dtype!r}")

    def cast(leaf):
        if isinstance(leaf, jax.Array) and jnp.issubdtype(leaf.dtype, jnp.floating):
            return leaf.astype(dtype)
        return leaf

    # Rebuilt on the cast grid first, so that the scene's checks run in the dtype the
    # solve will use, on the values as given (times that collapse, moduli out of
    # range: `jc.Scene`); its warnings were given when the scene was first built.
    fields = {f.name: getattr(scene, f.name) for f in dataclasses.fields(Scene)}
    fields["grid"] = jax.tree_util.tree_map(cast, scene.grid)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EdgeContactWarning)
        Scene(**fields)
    return jax.tree_util.tree_map(cast, scene)


def _times(end, steps):
    return np.linspace(0.0, end, steps)


def table2_hertz() -> Hertz:
    """The Hertz reference of Table 2 (instantaneous modulus, W = 0.15 N)."""
    t2 = TABLE2
    return Hertz(t2["radius"], t2["force"], t2["mu_inf"], t2["poisson"])


def zener_material(ratio) -> Zener:
    """The Zener material of Table 2 with `mu_inf / mu_0 = ratio`."""
    t2 = TABLE2
    return Zener(t2["mu_inf"], t2["mu_inf"] / _ratio(ratio), t2["tau"], t2["poisson"])


def pmma_material() -> Prony:
    """PMMA, paper Eq. 27 (halved: true shear moduli)."""
    return Prony(
        PMMA["g_inf"], np.asarray(PMMA["g"]), np.asarray(PMMA["tau"]), PMMA["poisson"]
    )


def fictitious_material() -> Prony:
    """The fictitious material of the paper's Eq. 31 (compliance doubled: true G)."""
    f = FICTITIOUS
    return Prony.from_creep(
        f["j_inf"], np.asarray(f["j"]), np.asarray(f["tau"]), f["poisson"]
    )


def _table2_grid(n):
    a0 = float(table2_hertz().contact_radius)
    return Grid((n, n), TABLE2["domain_a0"] * a0)


def _table2_scene(
    n,
    steps,
    duration,
    ratio,
    normal,
    x=None,
    coupling="none",
    friction=0.0,
    slip="total",
    dtype=None,
):
    times = _times(duration * TABLE2["tau"], steps)
    scene = Scene(
        _table2_grid(n),
        Sphere(TABLE2["radius"]),
        zener_material(ratio),
        times,
        normal=normal,
        x=x,
        y=None,
        friction=friction,
        coupling=coupling,
        slip=slip,
    )
    return _cast(scene, dtype)


# ---- Presets -------------------------------------------------------------------------


def hertz(n: int = 256, steps: int = 1, *, dtype=None) -> Scene:
    """Elastic Hertz indentation (the `jaxcontact run hertz` example), no friction.

    Rigid sphere R = 10 mm on an elastic half-space G = 1.93 MPa (the instantaneous
    modulus of Table 2, converted), nu = 0.3, load W = 0.15 N held over `steps` time
    points on t in [0, 1] s; the grid covers 4 a x 4 a with a = 588.7 um the Hertz
    contact radius. Not a figure of the paper: the elastic check of Table 2's a0, p0.
    """
    n = check_int("n", n, 2)
    steps = check_int("steps", steps, 1)
    t2 = TABLE2
    a = float(table2_hertz().contact_radius)
    times = _times(1.0, steps) if steps > 1 else np.zeros(1)
    scene = Scene(
        Grid((n, n), 4 * a),
        Sphere(t2["radius"]),
        Elastic(t2["mu_inf"], t2["poisson"]),
        times,
        normal=Force(t2["force"]),
    )
    return _cast(scene, dtype)


def maxwell(
    n: int = 256, steps: int | None = None, *, duration: float = 2.0, dtype=None
) -> Scene:
    """Maxwell half-space, step load (Table 1; Figs. 4-5, and 10-11 with duration=6).

    Paper: R = 3.5 mm, G = 81.92 GPa and eta = 81.92 GPa s (paper convention: here
    G = eta / (1 s) = 40.96 GPa), tau = 1 s, nu = 0.5, W = 100 N applied at t = 0 and
    held; a0 = 117 um, p0 = 3487 MPa; 512 um x 512 um, 256 x 256 cells; T = 2 tau in
    101 time points (Figs. 4-5). Figs. 10-11 extend T to 6 tau; the paper does not give
    the number of points there: `steps=None` keeps its time step (50 points per tau).

    - `duration`: T in units of tau (> 0).
    """
    n = check_int("n", n, 2)
    duration = _check_positive("duration", duration)
    steps = _steps(steps, int(round(50 * duration)) + 1)
    t1 = TABLE1
    material = Maxwell(t1["shear_modulus"], t1["viscosity"], t1["poisson"])
    tau = t1["viscosity"] / t1["shear_modulus"]
    scene = Scene(
        Grid((n, n), t1["domain"]),
        Sphere(t1["radius"]),
        material,
        _times(duration * tau, steps),
        normal=Force(t1["force"]),
    )
    return _cast(scene, dtype)


def pmma_triangle(n: int = 256, steps: int | None = None, *, dtype=None) -> Scene:
    """PMMA under the triangular load of Eq. 26 (Fig. 6, against Chen et al.).

    Paper: W(t) = 10 t H(t) - 20 (t - 10) H(t - 10) N (peak 100 N at t = 10 s, back to
    0 at t = 20 s); PMMA relaxation modulus Eq. 27, G(t) = 1429.71 + 184.62 e^{-t/8.93}
    + 191.06 e^{-t/117.96} MPa in the paper's convention (halved here), nu = 0.38;
    R = 3.5 mm; 1280 um x 1280 um, 256 x 256 cells; T = 20 s in 41 time points. No
    coupling (frictionless).
    """
    n = check_int("n", n, 2)
    steps = _steps(steps, 41)
    times = _times(20.0, steps)
    load = 10 * times - 20 * (times - 10) * (times > 10)
    scene = Scene(
        Grid((n, n), PMMA["domain"]),
        Sphere(PMMA["radius"]),
        pmma_material(),
        times,
        normal=Force(load),
    )
    return _cast(scene, dtype)


def zener(
    ratio: float = 4.0,
    n: int = 256,
    steps: int | None = None,
    *,
    duration: float = 3.0,
    dtype=None,
) -> Scene:
    """Zener half-space, step load (Table 2; Figs. 8-9: ratio = 2, 4, 8, 10).

    Fig. 8e: ratio 10 with more `steps`; Fig. 8f: `duration=6`.

    Paper: W = 0.15 N at t = 0, held; R = 10 mm; mu_inf = 3.86 MPa (paper convention:
    1.93 MPa here), mu_0 = mu_inf / ratio, tau = 0.01 s (Eqs. 29-30), nu = 0.3;
    a0 = 588.7 um, p0 = 0.2067 MPa; 5.5 a0 x 5.5 a0, 256 x 256 cells; T = 3 tau, the
    number of time points "depending on the ratio" (not given): `steps=None` takes 20
    points per tau, plus one.

    - `ratio`: mu_inf / mu_0 (>= 1).
    - `duration`: T in units of tau (> 0).
    """
    n = check_int("n", n, 2)
    duration = _check_positive("duration", duration)
    steps = _steps(steps, int(round(20 * duration)) + 1)
    return _table2_scene(n, steps, duration, ratio, Force(TABLE2["force"]), dtype=dtype)


def weichert(
    material: str = "pmma", n: int = 256, steps: int | None = None, *, dtype=None
) -> Scene:
    """PMMA or the fictitious material of Eq. 31, 10 N step load for 600 s (Fig. 12).

    Paper: `material="pmma"` (Eq. 27/28; Fig. 12a, 61 time points) or `"fictitious"`
    (Eq. 31, creep compliance 0.699 - 0.5595 e^{-t/133.869} - 0.02 e^{-t/9.9404} 1/GPa
    in the paper's convention, doubled here; Fig. 12b, 121 time points); nu = 0.38,
    R = 3.5 mm, 1280 um x 1280 um, 256 x 256 cells.
    """
    _check_choice("material", material, ("pmma", "fictitious"))
    n = check_int("n", n, 2)
    steps = _steps(steps, 61 if material == "pmma" else 121)
    mat = pmma_material() if material == "pmma" else fictitious_material()
    scene = Scene(
        Grid((n, n), PMMA["domain"]),
        Sphere(PMMA["radius"]),
        mat,
        _times(600.0, steps),
        normal=Force(10.0),
    )
    return _cast(scene, dtype)


def coupled_normal(
    ratio: float = 3.0,
    n: int = 256,
    steps: int | None = None,
    *,
    duration: float = 2.0,
    slip: str = "total",
    dtype=None,
) -> Scene:
    """Coupled partial slip under a normal load alone (Figs. 13-15: ratio = 3, 10).

    Paper: Table 2 (W = 0.15 N at t = 0, held; R = 10 mm; mu_inf = 3.86 MPa, paper
    convention; tau = 0.01 s; nu = 0.3; 5.5 a0 square, 256 x 256 cells), mu_inf / mu_0 =
    3 or 10, Coulomb friction 0.30, no tangential input, full coupling; T = 2 tau in 81
    time points.
    """
    n = check_int("n", n, 2)
    duration = _check_positive("duration", duration)
    steps = _steps(steps, 81)
    return _table2_scene(
        n,
        steps,
        duration,
        ratio,
        Force(TABLE2["force"]),
        coupling="full",
        friction=FRICTION,
        slip=slip,
        dtype=dtype,
    )


def lc(
    ratio: float = 4.0,
    n: int = 256,
    steps: int | None = None,
    *,
    duration: float = 2.0,
    slip: str = "total",
    dtype=None,
) -> Scene:
    """LC case: constant tangential load F_x = 0.5 mu W (Figs. 16-19).

    Paper: as `coupled_normal` with mu_inf / mu_0 = 4 and F_x = 0.5 x 0.30 x 0.15 N
    (= 0.0225 N) from t = 0, full coupling; T = 2 tau in 81 time points. (The paper
    reaches the load through a displacement-controlled loop; jaxcontact controls the
    load directly.)
    """
    n = check_int("n", n, 2)
    duration = _check_positive("duration", duration)
    steps = _steps(steps, 81)
    fx = 0.5 * FRICTION * TABLE2["force"]
    return _table2_scene(
        n,
        steps,
        duration,
        ratio,
        Force(TABLE2["force"]),
        x=Force(fx),
        coupling="full",
        friction=FRICTION,
        slip=slip,
        dtype=dtype,
    )


def dc(
    ratio: float = 4.0,
    n: int = 256,
    steps: int | None = None,
    *,
    duration: float = 2.0,
    slip: str = "total",
    dtype=None,
) -> Scene:
    """DC case: constant delta_x = 6.1987 um, constant load (Figs. 16-22).

    Displacement-constant case: Figs. 16-19 (ratio 4), Fig. 20 (ratios 3, 5, 10) and
    the creep case of Figs. 21-22 (ratio 4).

    Paper: Table 2 (W = 0.15 N from t = 0), friction 0.30, full coupling, delta_x =
    6.1987 (um) from t = 0; T = 2 tau in 81 time points.
    """
    n = check_int("n", n, 2)
    duration = _check_positive("duration", duration)
    steps = _steps(steps, 81)
    return _table2_scene(
        n,
        steps,
        duration,
        ratio,
        Force(TABLE2["force"]),
        x=Displacement(DELTA_X),
        coupling="full",
        friction=FRICTION,
        slip=slip,
        dtype=dtype,
    )


def relaxation(
    ratio: float = 4.0,
    n: int = 256,
    steps: int | None = None,
    *,
    duration: float = 2.0,
    slip: str = "total",
    dtype=None,
) -> Scene:
    """Relaxation case: constant delta_z and delta_x (Figs. 21-22).

    delta_z = 34.358 um and delta_x = 6.1987 um; compared with the creep case, `dc`.

    Paper: Table 2 material with mu_inf / mu_0 = 4, friction 0.30, full coupling, both
    displacements held from t = 0; T = 2 tau in 81 time points.
    """
    n = check_int("n", n, 2)
    duration = _check_positive("duration", duration)
    steps = _steps(steps, 81)
    return _table2_scene(
        n,
        steps,
        duration,
        ratio,
        Displacement(DELTA_Z),
        x=Displacement(DELTA_X),
        coupling="full",
        friction=FRICTION,
        slip=slip,
        dtype=dtype,
    )


def sliding(
    ratio: float = 10.0,
    n: int = 256,
    steps: int | None = None,
    *,
    rate: float = 1e-3,
    coupling: str = "full",
    normal: str = "displacement",
    duration: float = 2.0,
    slip: str = "total",
    dtype=None,
) -> Scene:
    """Tangential displacement delta_x = rate t up to gross sliding (Figs. 23-27).

    Paper: Table 2 material, friction 0.30, constant normal displacement delta_z =
    34.358 um (`normal="displacement"`; Figs. 23-25) or constant load W = 0.15 N
    (`normal="force"`; Figs. 26-27 compare the two); semi-coupled (`coupling="x"`, Fig.
    23) or fully coupled (`coupling="full"`, Figs. 24-27); several rates and time steps
    (Fig. 24b varies `steps`). The paper names one rate, v = 1e3 um/s (Fig. 25; the
    default `rate=1e-3` m/s), but not the others, the time window or the number of
    points: `duration=2` (tau) and 81 points are our choices. With the default rate,
    delta_x reaches 20 um at t = 2 tau, beyond the ~13 um of gross sliding of an
    elastic Cattaneo-Mindlin contact of the same a0.

    - `ratio`: mu_inf / mu_0 (>= 1). `rate`: d(delta_x)/dt [m/s] (> 0).
    - `coupling`: `"x"` or `"full"`. `normal`: `"displacement"` or `"force"`.
    - `duration`: T in units of tau (> 0).
    """
    n = check_int("n", n, 2)
    steps = _steps(steps, 81)
    rate = _check_positive("rate", rate)
    duration = _check_positive("duration", duration)
    _check_choice("coupling", coupling, ("x", "full"))
    _check_choice("normal", normal, ("displacement", "force"))
    normal_input = (
        Displacement(DELTA_Z) if normal == "displacement" else Force(TABLE2["force"])
    )
    times = _times(duration * TABLE2["tau"], steps)
    return _table2_scene(
        n,
        steps,
        duration,
        ratio,
        normal_input,
        x=Displacement(rate * times),
        coupling=coupling,
        friction=FRICTION,
        slip=slip,
        dtype=dtype,
    )


# ---- Registry ------------------------------------------------------------------------

_PRESETS = {
    "hertz": hertz,
    "maxwell": maxwell,
    "pmma_triangle": pmma_triangle,
    "zener": zener,
    "weichert": weichert,
    "coupled_normal": coupled_normal,
    "lc": lc,
    "dc": dc,
    "relaxation": relaxation,
    "sliding": sliding,
}


def available() -> dict[str, str]:
    """`{name: one-line description}` of every preset (the first docstring line)."""
    return {name: fn.__doc__.strip().splitlines()[0] for name, fn in _PRESETS.items()}


def parameters(name: str, **kwargs) -> dict:
    """The full argument set `build(name, **kwargs)` would use, defaults filled in
    (`steps=None` stays `None`: the scene's `times` holds the resolved value)."""
    fn = _lookup(name)
    signature = inspect.signature(fn)
    try:
        bound = signature.bind(**kwargs)
    except TypeError as exc:
        raise TypeError(
            f"preset {name!r}: {exc}; it takes {list(signature.parameters)}"
        ) from None
    bound.apply_defaults()
    return dict(bound.arguments)


def _lookup(name):
    if name not in _PRESETS:
        raise ValueError(f"unknown preset {name!r}; available: {sorted(_PRESETS)}")
    return _PRESETS[name]


def build(name: str, **kwargs) -> Scene:
    """Call the preset `name` with `kwargs` (ValueError for an unknown name, TypeError
    for an argument it does not take)."""
    parameters(name, **kwargs)
    return _lookup(name)(**kwargs)


# ---- Scene files (TOML) --------------------------------------------------------------

_MATERIALS = {
    # type: (constructor, required keys, optional keys)
    "elastic": (Elastic, ("shear_modulus", "poisson"), ()),
    "maxwell": (Maxwell, ("shear_modulus", "viscosity", "poisson"), ()),
    "zener": (Zener, ("mu_inf", "mu_0", "tau", "poisson"), ()),
    "prony": (Prony, ("g_inf", "g", "tau", "poisson"), ()),
    "prony_creep": (Prony.from_creep, ("j_inf", "j", "tau", "poisson"), ("fluidity",)),
}
_SECTIONS = (
    "name",
    "description",
    "grid",
    "indenter",
    "material",
    "time",
    "normal",
    "x",
    "y",
    "contact",
    "solver",
)
_SOLVER_KEYS = ("rtol", "max_steps", "max_rounds", "resync_every", "history", "scheme")


def read_toml(path) -> dict:
    """Read a TOML scene file into a dict (ValueError naming the file if malformed)."""
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"malformed TOML in {path}: {exc}") from exc


def _table(spec, name, required=True):
    value = spec.get(name)
    if value is None:
        if required:
            raise ValueError(f"missing [{name}] table")
        return None
    if not isinstance(value, dict):
        raise ValueError(f"[{name}] must be a table, got {value!r}")
    return value


def _keys(section, table, required, optional=()):
    unknown = sorted(set(table) - set(required) - set(optional))
    if unknown:
        raise ValueError(
            f"[{section}] has unknown key(s) {unknown}; expected {list(required)}"
            + (f" and optionally {list(optional)}" if optional else "")
        )
    missing = [k for k in required if k not in table]
    if missing:
        raise ValueError(f"[{section}] is missing {missing}")


def _floats(where, value):
    """A TOML number or (nested) list of numbers as a float array (ValueError naming
    `where` and the value otherwise: strings, booleans, ragged lists)."""
    def bad(v):
        if isinstance(v, list):
            return any(bad(x) for x in v)
        return isinstance(v, bool) or not isinstance(v, int | float)

    if bad(value):
        raise ValueError(
            f"{where} must be a number or a list of numbers, got {value!r}")
    try:
        return np.asarray(value, dtype=float)
    except ValueError:  # ragged
        raise ValueError(f"{where} must be a rectangular list, got {value!r}") from None


def _program(section, table, times):
    """A `Force` or `Displacement` from `{force = ...}` or `{displacement = ...}`."""
    kinds = [k for k in ("force", "displacement") if k in table]
    if len(kinds) != 1 or len(table) != 1:
        raise ValueError(
            f"[{section}] must have exactly one key, force or displacement; got "
            f"{sorted(table)}"
        )
    kind = kinds[0]
    value = table[kind]
    if isinstance(value, dict):  # piecewise-linear {t = [...], value = [...]}
        _keys(f"{section}.{kind}", value, ("t", "value"))
        t = _floats(f"[{section}] {kind}.t", value["t"])
        v = _floats(f"[{section}] {kind}.value", value["value"])
        if t.ndim != 1 or t.shape != v.shape or t.size < 1:
            raise ValueError(
                f"[{section}] {kind}: t and value must be lists of equal length, got "
                f"{value['t']!r} and {value['value']!r}"
            )
        if not (np.diff(t) > 0).all():
            raise ValueError(
                f"[{section}] {kind}: t must be increasing, got {value['t']!r}"
            )
        values = np.interp(np.asarray(times), t, v)
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        values = float(value)
    elif isinstance(value, list):
        values = _floats(f"[{section}] {kind}", value)
        if values.shape != (len(times),):
            raise ValueError(
                f"[{section}] {kind}: a list needs one value per time point "
                f"({len(times)}), got {value!r}"
            )
    else:
        raise ValueError(
            f"[{section}] {kind} must be a number, a list (one value per time) or "
            f"{{t = [...], value = [...]}}, got {value!r}"
        )
    return Force(values) if kind == "force" else Displacement(values)


def _heights_file(path: Path) -> np.ndarray:
    """An `(nx, ny)` height field [length] from `.npy` (NumPy) or a text table (`.txt`,
    `.csv`, `.dat`: rows along x, columns along y; commas or whitespace)."""
    if not path.is_file():
        raise ValueError(f"[indenter] file {str(path)!r} does not exist")
    suffix = path.suffix.lower()
    try:
        if suffix == ".npy":
            heights = np.load(path, allow_pickle=False)
        elif suffix in (".txt", ".csv", ".dat"):
            heights = np.loadtxt(path, delimiter="," if suffix == ".csv" else None,
                                 ndmin=2)
        else:
            raise ValueError(
                f"[indenter] file {str(path)!r}: expected .npy, .txt, .csv or .dat, "
                f"got {suffix!r}"
            )
    except (OSError, ValueError) as exc:
        if str(exc).startswith("[indenter]"):
            raise
        raise ValueError(
            f"[indenter] file {str(path)!r} cannot be read: {exc}") from None
    if heights.dtype.kind not in "iuf":
        raise ValueError(
            f"[indenter] file {str(path)!r} must hold real numbers, got dtype "
            f"{heights.dtype}"
        )
    return np.asarray(heights, dtype=float)


def _indenter(table, grid, base, n):
    """`[indenter]`: `type = "sphere"` with `radius` (and optional `centre`), or
    `type = "surface"` with `file` (a height field, relative to the scene file) and
    optional `scale` (multiplies the file's values: e.g. 1e-6 for micrometres)."""
    kind = table.get("type")
    if kind == "sphere":
        _keys("indenter", table, ("type", "radius"), ("centre",))
        centre = table.get("centre", (0.0, 0.0))
        if not isinstance(centre, list | tuple) or len(centre) != 2:
            raise ValueError(f"[indenter] centre must be [x, y], got {centre!r}")
        return Sphere(table["radius"], centre=np.asarray(centre, dtype=float))
    if kind == "surface":
        _keys("indenter", table, ("type", "file"), ("scale",))
        if not isinstance(table["file"], str):
            raise ValueError(f"[indenter] file must be a path, got {table['file']!r}")
        path = Path(table["file"])
        if not path.is_absolute():
            path = Path(base) / path
        heights = _heights_file(path)
        scale = table.get("scale", 1.0)
        if isinstance(scale, bool) or not isinstance(scale, int | float):
            raise ValueError(f"[indenter] scale must be a number, got {scale!r}")
        if n is not None and heights.shape != grid.shape:
            raise ValueError(
                f"--n / n={n}: a surface file is not resampled; {str(path)!r} has "
                f"shape {heights.shape}"
            )
        if heights.shape != grid.shape:
            raise ValueError(
                f"[indenter] file {str(path)!r} has shape {heights.shape}, the [grid] "
                f"shape is {grid.shape}"
            )
        return Surface(heights * float(scale))
    raise ValueError(f'[indenter] type must be "sphere" or "surface", got {kind!r}')


def from_spec(
    spec: dict,
    *,
    n: int | None = None,
    steps: int | None = None,
    dtype=None,
    base=".",
) -> tuple[Scene, dict]:
    """Build `(scene, solve_options)` from a scene-file dict (see `read_toml` and the
    README section "Scene files"). `n` overrides the grid shape with `(n, n)`; `steps`
    the number of time points (only with `[time] end = ...`); `base` is the folder that
    relative file names (a surface's `file`) are read from (`from_toml`: the scene
    file's folder)."""
    if not isinstance(spec, dict):
        raise TypeError(f"spec must be a dict, got {spec!r}")
    unknown = sorted(set(spec) - set(_SECTIONS))
    if unknown:
        raise ValueError(
            f"unknown top-level key(s) {unknown}; expected {list(_SECTIONS)}"
        )

    grid_t = _table(spec, "grid")
    _keys("grid", grid_t, ("shape", "size"), ("periodic",))
    shape = grid_t["shape"]
    if not (isinstance(shape, list) and len(shape) == 2):
        raise ValueError(f"[grid] shape must be [nx, ny], got {shape!r}")
    if n is not None:
        shape = (check_int("n", n, 2),) * 2
    grid = Grid(shape, grid_t["size"], periodic=grid_t.get("periodic", False))

    indenter = _indenter(_table(spec, "indenter"), grid, base, n)

    mat = dict(_table(spec, "material"))
    kind = mat.pop("type", None)
    if kind not in _MATERIALS:
        raise ValueError(
            f"[material] type must be one of {sorted(_MATERIALS)}, got {kind!r}"
        )
    ctor, required, optional = _MATERIALS[kind]
    _keys("material", mat, required, optional)
    material = ctor(
        **{
            k: _floats(f"[material] {k}", v) if isinstance(v, list) else v
            for k, v in mat.items()
        }
    )

    time_t = _table(spec, "time")
    if "times" in time_t:
        _keys("time", time_t, ("times",))
        if steps is not None:
            raise ValueError("steps cannot override an explicit [time] times list")
        times = _floats("[time] times", time_t["times"])
    else:
        _keys("time", time_t, ("end", "steps"))
        nt = check_int("steps", time_t["steps"] if steps is None else steps, 1)
        end = _check_positive("[time] end", time_t["end"])
        times = _times(end, nt) if nt > 1 else np.zeros(1)

    normal = _program("normal", _table(spec, "normal"), times)
    tangential = {}
    for direction in ("x", "y"):
        table = _table(spec, direction, required=False)
        tangential[direction] = (
            None if table is None else _program(direction, table, times)
        )

    contact = _table(spec, "contact", required=False) or {}
    _keys("contact", contact, (), ("friction", "coupling", "slip"))
    solver = _table(spec, "solver", required=False) or {}
    _keys("solver", solver, (), _SOLVER_KEYS)

    scene = Scene(
        grid,
        indenter,
        material,
        times,
        normal=normal,
        x=tangential["x"],
        y=tangential["y"],
        friction=contact.get("friction", 0.0),
        coupling=contact.get("coupling", "none"),
        slip=contact.get("slip", "incremental"),
    )
    return _cast(scene, dtype), dict(solver)


def from_toml(
    path, *, n: int | None = None, steps: int | None = None, dtype=None
) -> tuple[Scene, dict]:
    """`(scene, solve_options)` from a TOML scene file; solve with
    `jc.solve(scene, **solve_options)`."""
    return from_spec(
        read_toml(path), n=n, steps=steps, dtype=dtype, base=Path(path).parent
    )
