"""Every gradient of the scene space against central differences.

Each case is one scene (a 16^2 grid, 4 steps, a rigid sphere R = 10 mm on a half-space
of shear modulus G = 1.93 MPa, nu = 0.3, W = 0.15 N, mu = 0.3: Hertz radius a = 0.59 mm
on a domain of 4 a) with one value of each axis:

- `coupling`: "none", "x", "full";
- `normal`: force or displacement; `program`: constant, ramp, unload (to zero);
- `tangential`: none; a force from zero / near mu W (0.997) / past mu W (1.2) /
  negative / along y / along x and y; a displacement (partial slip) / past gross
  sliding / reversed / along y;
- `material`: Elastic, Maxwell, Zener, Prony (two arms), a Prony series built from a
  creep series (`Prony.from_creep`);
- `slip`: incremental or total; `scheme`: constant or linear; a periodic grid; a
  `jc.Surface` (a paraboloid with a bump) instead of the sphere;
- `solver`: the grid (`jc.solve`'s default with friction; `jc.Rounds()` for the
  frictionless scenes) or, for the frictionless normal scenes, the axisymmetric ring
  solver (`jc.solve`'s default there, named `rings`: its own implicit derivatives,
  reverse and forward mode);
- `parameter` (the scalar differentiated): load scale, friction, modulus scale,
  relaxation-time scale, Poisson's ratio, radius scale, bump height, tangential scale;
- `mode`: `jit` (`jit(value_and_grad)`), `grad` (`jax.grad`, eager), `jvp` (`jax.jvp`
  through the forward-mode adjoint, jitted), `vmap` (`jit(vmap(value_and_grad))` over
  three parameter values, also compared with the loop of jitted gradients), `float32`.

The output differentiated is the scene's response at the last step (the approach under
a normal force, the normal force under a displacement; plus the tangential force or
displacement of x where a tangential input is given), or `"sum"`: the sum of that
response over every step (the unloading programs, whose last step carries no load).
The reference is a central difference `(f(t + h) - f(t - h)) / 2h`, `h = 1e-4 |t|`,
of the float64 forward at `rtol = 1e-10`, Richardson-extrapolated with `h / 2`
(O(h^4)). A case is

- `right`: `|g - cd| <= tol max(|cd|, |g|) + floor` (tol 1e-5 float64, 1e-2 float32;
  floor `1e-9 |f| / |t|`);
- `kink`: the two one-sided differences disagree by more than tol (the scene sits on
  an active-set change: a cell entering or leaving contact or the stick zone), and the
  gradient matches one of them (to 1e-3, as an O(h) one-sided difference can);
- `refused`: the solve raised, with its message (a documented refusal);
- `wrong`: anything else, a silently wrong number (or NaN) and the thing to fix.

Usage::

    python benchmarks/gradient_matrix.py                  # every case
    python benchmarks/gradient_matrix.py --slice default  # the default test suite's
    python benchmarks/gradient_matrix.py --slice rings    # the ring solver's cases
    python benchmarks/gradient_matrix.py --only zener     # names containing "zener"
    python benchmarks/gradient_matrix.py --case NAME      # one case

Results: `benchmarks/results/gradient_matrix/<machine>.json` (`--slice default`:
`<machine>_default.json`, `--slice rings`: `<machine>_rings.json`, `--only` or
`--case`: `<machine>_selection.json`; or `--out`; layout: `results/SCHEMA.md`: a row
per case, the verdicts counted in `summary`), a table on stdout.
"""

import argparse
import dataclasses
import math
import os
import sys
import time
import traceback

import jax


jax.config.update("jax_enable_x64", True)
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from _common import header, write_results  # noqa: E402

import jaxcontact as jc  # noqa: E402


R, G, NU, W, MU, TAU = 10e-3, 1.93e6, 0.3, 0.15, 0.3, 0.01
N, NT = 16, 4
# The reference forward's tolerance (the joint iteration stalls near 1e-11 on some
# scenes) and the relative step of the central differences: round-off RTOL / H = 1e-6,
# truncation ~H^2.
RTOL, H = 1e-10, 1e-4
A = float(jc.Hertz(R, W, G, NU).contact_radius)
DEPTH = A * A / R  # Hertz approach at W [m]
# Tangential displacement of gross sliding (Cattaneo-Mindlin, elastic):
# mu W (2 - nu) / (4 G a).
SLIDE = MU * W * (2 - NU) / (4 * G * A)


@dataclasses.dataclass(frozen=True)
class Case:
    """One scene, one scalar parameter, one way of differentiating (module docs)."""

    coupling: str = "none"
    normal: str = "force"
    program: str = "constant"
    tangential: str = "none"
    material: str = "elastic"
    slip: str = "incremental"
    scheme: str = "constant"
    periodic: bool = False
    surface: bool = False
    parameter: str = "load"
    mode: str = "jit"
    output: str = "last"
    solver: str = "grid"

    @property
    def name(self) -> str:
        parts = [self.coupling, f"{self.normal}-{self.program}", self.tangential,
                 self.material, self.parameter, self.mode]
        if self.slip != "incremental":
            parts.append("total")
        if self.scheme != "constant":
            parts.append("linear")
        if self.periodic:
            parts.append("periodic")
        if self.surface:
            parts.append("surface")
        if self.output != "last":
            parts.append(self.output)
        if self.solver != "grid":
            parts.append(self.solver)
        return "/".join(parts)

    @property
    def theta0(self) -> float:
        return {"friction": MU, "poisson": NU}.get(self.parameter, 1.0)


def _material(name, parameter, theta, dtype):
    c = lambda v: jnp.asarray(v, dtype)  # noqa: E731
    scale = theta if parameter == "modulus" else c(1.0)
    tau = theta if parameter == "tau" else c(1.0)
    nu = theta if parameter == "poisson" else c(NU)
    if name == "elastic":
        return jc.Elastic(scale * G, nu)
    if name == "maxwell":  # relaxation time 2 tau: the history matters, no runaway
        return jc.Maxwell(scale * G, scale * G * 2 * TAU * tau, nu)
    if name == "zener":
        return jc.Zener(mu_inf=scale * G, mu_0=scale * G / 3, tau=TAU * tau, poisson=nu)
    if name == "prony":
        return jc.Prony(scale * G / 2, scale * G * c([0.5, 0.25]),
                        tau * c([0.5 * TAU, 2 * TAU]), nu)
    if name == "creep":  # J(t) = (1.6 - 0.4 e^{-t/tau1} - 0.2 e^{-t/tau2}) / G
        return jc.Prony.from_creep(c(1.6) / (scale * G), c([0.4, 0.2]) / (scale * G),
                                   tau * c([TAU, 3 * TAU]), nu)
    raise ValueError(f"unknown material {name!r}")


_PROGRAMS = {"constant": [1.0, 1.0, 1.0, 1.0], "ramp": [0.4, 0.6, 0.8, 1.0],
             "unload": [0.6, 1.0, 0.5, 0.0]}
# Tangential programs as fractions of mu W (forces) or of SLIDE (displacements).
_FORCES = {"force": [0.0, 0.25, 0.5, 0.7], "force_near": [0.3, 0.6, 0.8, 0.997],
           "force_past": [0.3, 0.6, 0.9, 1.2], "force_neg": [-0.1, -0.3, -0.5, -0.7]}
_DISPLACEMENTS = {"disp": [0.1, 0.2, 0.3, 0.45], "disp_past": [0.3, 0.8, 1.5, 2.5],
                  "reversal": [0.2, 0.45, 0.2, -0.1]}


def scene(case: Case, theta, dtype=jnp.float64) -> jc.Scene:
    """The scene of `case` at parameter value `theta` (a scalar, traced or not)."""
    c = lambda v: jnp.asarray(v, dtype)  # noqa: E731
    theta = jnp.asarray(theta, dtype)
    p = case.parameter
    radius = c(R) * (theta if p == "radius" else 1.0)
    grid = jc.Grid((N, N), c(4 * A), periodic=case.periodic)
    times = jnp.linspace(0.0, 2 * TAU, NT, dtype=dtype)
    load = theta if p == "load" else c(1.0)
    program = c(_PROGRAMS[case.program]) * load
    normal = (jc.Force(c(W) * program) if case.normal == "force"
              else jc.Displacement(c(DEPTH) * program))
    friction = theta if p == "friction" else c(MU)
    t_scale = theta if p == "tangential" else c(1.0)
    x = y = None
    kind = case.tangential
    # A tangential force is a fraction of mu W at each step (of the normal program
    # under load control; of W under displacement control).
    limit = c(MU * W) * t_scale * (c(_PROGRAMS[case.program]) if case.normal == "force"
                                   else 1.0)
    if kind in _FORCES:
        x = jc.Force(c(_FORCES[kind]) * limit)
    elif kind == "force_y":
        y = jc.Force(c(_FORCES["force"]) * limit)
    elif kind == "force_xy":
        f = c(_FORCES["force"]) * limit / math.sqrt(2)
        x, y = jc.Force(f), jc.Force(0.5 * f)
    elif kind in _DISPLACEMENTS:
        x = jc.Displacement(c(_DISPLACEMENTS[kind]) * c(SLIDE) * t_scale)
    elif kind == "disp_y":
        y = jc.Displacement(c(_DISPLACEMENTS["disp"]) * c(SLIDE) * t_scale)
    elif kind != "none":
        raise ValueError(f"unknown tangential program {kind!r}")
    if case.surface:
        xs = (jnp.arange(N, dtype=dtype) - (N - 1) / 2) * grid.size[0] / N
        r2 = xs[:, None] ** 2 + xs[None, :] ** 2
        height = theta if p == "height" else c(1.0)
        bump = c(0.1 * DEPTH) * jnp.exp(-r2 / c(0.3 * A) ** 2)
        indenter = jc.Surface(r2 / (2 * radius) - height * bump)
    else:
        indenter = jc.Sphere(radius)
    material = _material(case.material, p, theta, dtype)
    extra = {}
    if x is not None or y is not None or case.coupling != "none":
        extra = dict(friction=friction, coupling=case.coupling, slip=case.slip)
    return jc.Scene(grid, indenter, material, times, normal, x=x, y=y, **extra)


def response(case: Case, sol: jc.Solution):
    """The scalar differentiated: the responses to the scene's controls (module docs),
    scaled to order one."""
    normal = (sol.approach / DEPTH if case.normal == "force"
              else sol.normal_force / W)
    parts = [normal]
    kind = case.tangential
    if kind != "none":
        d = 1 if kind in ("force_y", "disp_y") else 0
        if kind.startswith("force"):
            parts.append(sol.tangential_displacement[:, d] / SLIDE)
        else:
            parts.append(sol.tangential_force[:, d] / (MU * W))
    total = sum(parts)
    return jnp.sum(total) if case.output == "sum" else total[-1]


def _function(case, dtype=jnp.float64, rtol=None, adjoint=None):
    def f(theta):
        kwargs = {} if rtol is None else dict(rtol=rtol)
        scene_ = scene(case, theta, dtype)
        if case.solver == "rings":  # its own implicit derivatives: no `adjoint`
            kwargs, adjoint_ = dict(solver=jc.RingPolonskyKeer(rtol=rtol)), None
        else:
            adjoint_ = adjoint
            if scene_.tangential_directions == 0:
                # The grid's rounds, which `jc.solve` leaves for the rings on a
                # frictionless sphere.
                kwargs = dict(solver=jc.Rounds(**kwargs))
        if case.scheme != "constant":
            kwargs["scheme"] = case.scheme
        return response(case, jc.solve(scene_, adjoint=adjoint_, **kwargs))
    return f


def check(case: Case) -> dict:
    """Differentiate `case` and compare (module docs); a JSON-ready dict."""
    t0 = case.theta0
    h = H * abs(t0)
    start = time.perf_counter()
    row = dict(name=case.name, **dataclasses.asdict(case), theta=t0, h=h)
    try:
        values, row["gradient"], row["extra"] = _evaluate(case, t0, h)
        f_m, f_mh, f_0, f_ph, f_p = values  # at t0 - h, - h/2, 0, + h/2, + h
        # Richardson: O(h^4) central, O(h^2) one-sided (near mu W the response is
        # strongly curved: a plain central difference at h was 7e-4 off there).
        central = (8 * (f_ph - f_mh) - (f_p - f_m)) / (6 * h)
        right = (4 * (f_ph - f_0) - (f_p - f_0)) / h
        left = (4 * (f_0 - f_mh) - (f_0 - f_m)) / h
        row.update(value=f_0, cd=central, right_side=right, left_side=left)
        row.update(_verdict(row, case))
    except Exception as exc:  # noqa: BLE001 - a refusal is a result of the matrix
        row.update(status="refused", gradient=None, message=_message(exc),
                   exception=type(exc).__name__)
        if os.environ.get("GRADIENT_MATRIX_TRACEBACK"):
            traceback.print_exc()
    row["seconds"] = round(time.perf_counter() - start, 2)
    return row


def _message(exc) -> str:
    """The first line of the message a user reads (a `jc.RESULTS` one where raised
    from a compiled program, which wraps it in a callback's traceback)."""
    text = str(exc)
    marker = "EquinoxRuntimeError: "
    if marker in text:
        text = text[text.rindex(marker) + len(marker):]
    lines = [line.strip() for line in text.strip().splitlines() if line.strip()]
    return (lines[0] if lines else repr(exc))[:600]


def _evaluate(case: Case, t0: float, h: float):
    """`(values at t0 - h, - h/2, 0, + h/2, + h (float64, rtol RTOL), gradient at t0,
    extra)` by the case's mode, compiling as few programs as the mode allows (the
    values come from the gradient's own program where it has them); `extra`:
    mode-specific numbers."""
    points = [t0 - h, t0 - h / 2, t0, t0 + h / 2, t0 + h]
    f = _function(case, rtol=RTOL)
    if case.mode == "jit":
        value_and_grad = jax.jit(jax.value_and_grad(f))
        pairs = [value_and_grad(t) for t in points]
        return [float(v) for v, _ in pairs], float(pairs[2][1]), {}
    if case.mode == "jvp":
        forward_mode = _function(case, rtol=RTOL,
                                 adjoint=jc.ImplicitAdjoint(mode="forward"))
        jvp = jax.jit(lambda t: jax.jvp(forward_mode, (t,), (jnp.ones_like(t),)))
        pairs = [jvp(jnp.float64(t)) for t in points]
        return [float(v) for v, _ in pairs], float(pairs[2][1]), {}
    if case.mode == "vmap":
        batch = jnp.asarray(points[::2])
        _, batched = jax.jit(jax.vmap(jax.value_and_grad(f)))(batch)
        single = jax.jit(jax.value_and_grad(f))
        pairs = [single(t) for t in points]
        loop = np.asarray([float(g) for _, g in pairs[::2]])
        spread = float(np.max(np.abs(np.asarray(batched) - loop))
                       / max(np.max(np.abs(loop)), 1e-300))
        return ([float(v) for v, _ in pairs], float(batched[1]),
                dict(vmap_vs_loop=spread))
    forward = jax.jit(f)
    values = [float(forward(t)) for t in points]
    if case.mode == "grad":
        return values, float(jax.grad(f)(t0)), {}
    if case.mode == "float32":
        g = jax.jit(jax.grad(_function(case, jnp.float32)))(jnp.float32(t0))
        return values, float(g), dict(dtype=str(g.dtype))
    raise ValueError(f"unknown mode {case.mode!r}")


def _verdict(row, case):
    g, cd = row["gradient"], row["cd"]
    tol = 1e-2 if case.mode == "float32" else 1e-5
    floor = 1e-9 * abs(row["value"]) / abs(case.theta0)
    error = abs(g - cd) / max(abs(cd), abs(g), 1e-300)
    out = dict(error=error)
    if not math.isfinite(g):
        return dict(out, status="wrong", message="NaN or inf gradient")
    vmap_ok = row["extra"].get("vmap_vs_loop", 0.0) <= 1e-8
    if abs(g - cd) <= tol * max(abs(cd), abs(g)) + floor and vmap_ok:
        return dict(out, status="right")
    sides = (row["left_side"], row["right_side"])
    jump = abs(sides[1] - sides[0]) / max(abs(sides[0]), abs(sides[1]), 1e-300)
    one_sided = min(abs(g - s) / max(abs(s), 1e-300) for s in sides)
    if jump > tol and one_sided <= 1e-3 and vmap_ok:
        return dict(out, status="kink", one_sided_error=one_sided, jump=jump)
    if not vmap_ok:
        return dict(out, status="wrong", message="vmap(grad) differs from the loop")
    return dict(out, status="wrong", one_sided_error=one_sided, jump=jump)


def all_cases() -> list[Case]:
    """The whole matrix (module docs): every axis value against the others it meets."""
    cases = []
    add = cases.append
    # Frictionless normal problems: every program, control and material.
    for normal in ("force", "displacement"):
        for program in ("constant", "ramp", "unload"):
            for material in ("elastic", "maxwell", "zener", "prony", "creep"):
                parameter = "load" if material == "elastic" else "tau"
                add(Case(normal=normal, program=program, material=material,
                         parameter=parameter,
                         output="sum" if program == "unload" else "last"))
    # Tangential programs under each coupling, elastic and Zener.
    tangentials = ("force", "force_near", "force_past", "force_neg", "disp",
                   "disp_past", "reversal")
    for coupling in ("none", "x", "full"):
        for tangential in tangentials:
            for material in ("elastic", "zener"):
                parameter = "friction" if tangential != "reversal" else "tangential"
                add(Case(coupling=coupling, tangential=tangential, material=material,
                         parameter=parameter, program="ramp"))
        add(Case(coupling=coupling, tangential="disp", normal="displacement",
                 material="prony", parameter="modulus"))
        add(Case(coupling=coupling, tangential="force", normal="force",
                 program="unload", material="zener", parameter="load", output="sum"))
        for slip_law in ("total",):
            add(Case(coupling=coupling, tangential="disp", slip=slip_law,
                     material="elastic", parameter="friction"))
            add(Case(coupling=coupling, tangential="force", slip=slip_law,
                     material="zener", parameter="load"))
    # Two shear components (full coupling only).
    for tangential in ("force_y", "force_xy", "disp_y"):
        for material in ("elastic", "prony"):
            add(Case(coupling="full", tangential=tangential, material=material,
                     parameter="friction"))
    # Parameters.
    for parameter in ("load", "friction", "modulus", "tau", "poisson", "radius",
                      "tangential"):
        add(Case(coupling="x", tangential="disp", material="prony", parameter=parameter,
                 program="ramp"))
    for parameter in ("poisson", "radius", "modulus"):
        add(Case(normal="displacement", material="maxwell", parameter=parameter,
                 program="ramp"))
    # Scheme, periodic grid, surfaces.
    add(Case(material="zener", scheme="linear", parameter="tau", program="ramp"))
    add(Case(coupling="full", tangential="disp", material="zener", scheme="linear",
             parameter="friction"))
    add(Case(periodic=True, material="prony", parameter="load", program="ramp"))
    add(Case(periodic=True, coupling="full", tangential="force", material="elastic",
             parameter="friction"))
    add(Case(surface=True, material="zener", parameter="height"))
    add(Case(surface=True, coupling="x", tangential="disp", material="elastic",
             parameter="height"))
    add(Case(surface=True, normal="displacement", material="creep", parameter="tau"))
    # Outputs summed over the history.
    add(Case(material="elastic", program="ramp", output="sum"))
    add(Case(coupling="full", tangential="force", material="prony", output="sum",
             parameter="friction"))
    # The ring solver: frictionless normal scenes, every program, control and
    # material, the sphere's parameters, every mode.
    for normal in ("force", "displacement"):
        for program in ("constant", "ramp", "unload"):
            for material in ("elastic", "maxwell", "zener", "prony", "creep"):
                parameter = "load" if material == "elastic" else "tau"
                add(Case(normal=normal, program=program, material=material,
                         parameter=parameter, solver="rings",
                         output="sum" if program == "unload" else "last"))
    for parameter in ("poisson", "radius", "modulus"):
        add(Case(normal="displacement", material="maxwell", parameter=parameter,
                 program="ramp", solver="rings"))
    add(Case(material="zener", scheme="linear", parameter="tau", program="ramp",
             solver="rings"))
    for mode in ("grad", "jvp", "vmap", "float32"):
        add(Case(material="elastic", program="ramp", mode=mode, solver="rings"))
        add(Case(material="zener", normal="displacement", parameter="tau", mode=mode,
                 solver="rings"))
    # Modes.
    for mode in ("grad", "jvp", "vmap", "float32"):
        add(Case(material="elastic", program="ramp", mode=mode))
        add(Case(material="zener", normal="displacement", parameter="tau", mode=mode))
        add(Case(coupling="none", tangential="disp", material="elastic",
                 parameter="friction", mode=mode))
        add(Case(coupling="x", tangential="force_past", material="elastic",
                 parameter="friction", mode=mode))
        add(Case(coupling="full", tangential="force", material="zener",
                 parameter="friction", mode=mode))
        add(Case(coupling="full", tangential="force_near", material="zener",
                 parameter="friction", mode=mode))
    return cases


def default_slice() -> list[Case]:
    """The default test suite's slice: every axis value at least twice. The modes
    other than `jit` (each compiles more than one program) meet the cheaper scenes."""
    return [
        # Frictionless: controls, programs, materials, modes.
        Case(program="ramp"),
        Case(program="unload", normal="displacement", material="creep", parameter="tau",
             output="sum"),
        Case(program="unload", material="maxwell", parameter="tau", output="sum"),
        Case(normal="displacement", material="prony", parameter="poisson"),
        Case(program="ramp", normal="displacement", material="maxwell",
             parameter="radius"),
        Case(material="elastic", program="ramp", mode="grad"),
        Case(material="zener", normal="displacement", parameter="tau", mode="grad"),
        Case(material="prony", parameter="load", program="ramp", output="sum",
             mode="jvp"),
        Case(material="elastic", program="ramp", mode="vmap"),
        Case(material="zener", parameter="tau", scheme="linear", mode="vmap"),
        Case(material="elastic", program="ramp", mode="float32"),
        Case(material="elastic", normal="displacement", parameter="modulus",
             program="ramp", mode="float32"),
        Case(periodic=True, material="prony", parameter="load", program="ramp"),
        Case(material="zener", parameter="height", surface=True, periodic=True),
        # Coupling "none".
        Case(coupling="none", tangential="force", material="elastic",
             parameter="friction"),
        Case(coupling="none", tangential="disp", material="zener", parameter="friction",
             slip="total"),
        Case(coupling="none", tangential="force_past", material="prony",
             parameter="load"),
        Case(coupling="none", tangential="reversal", material="creep",
             parameter="tangential", mode="jvp"),
        Case(coupling="none", tangential="reversal", material="elastic",
             parameter="tangential", program="ramp"),
        Case(coupling="none", tangential="force_neg", material="zener",
             parameter="friction", program="ramp"),
        Case(coupling="none", tangential="disp_past", material="zener",
             parameter="friction", program="ramp"),
        Case(coupling="none", tangential="disp", material="elastic", parameter="height",
             surface=True),
        # Coupling "x".
        Case(coupling="x", tangential="force", material="zener", parameter="friction",
             program="ramp"),
        Case(coupling="x", tangential="force_past", material="elastic",
             parameter="friction"),
        Case(coupling="x", tangential="force_near", material="elastic",
             parameter="friction", program="ramp"),
        Case(coupling="x", tangential="disp", material="prony", parameter="modulus",
             scheme="linear"),
        Case(coupling="x", tangential="disp_past", material="maxwell",
             parameter="friction", program="unload", output="sum"),
        Case(coupling="x", tangential="reversal", material="prony", parameter="poisson",
             slip="total"),
        Case(coupling="x", tangential="disp", material="prony", parameter="radius",
             program="ramp"),
        # Coupling "full": the second shear component.
        Case(coupling="full", tangential="force_near", material="zener",
             parameter="friction"),
        Case(coupling="full", tangential="force_y", material="creep",
             parameter="poisson"),
        Case(coupling="full", tangential="force_y", material="zener",
             parameter="friction"),
        Case(coupling="full", tangential="force_xy", material="prony",
             parameter="friction"),
        Case(coupling="full", tangential="force_xy", material="elastic",
             parameter="load"),
        Case(coupling="full", tangential="disp_y", material="zener", parameter="tau",
             normal="displacement"),
        Case(coupling="full", tangential="disp_y", material="elastic",
             parameter="friction", normal="displacement", slip="total"),
        Case(coupling="full", tangential="force_neg", material="maxwell",
             parameter="modulus", normal="displacement", program="ramp"),
        # The ring solver.
        Case(material="zener", parameter="tau", program="ramp", mode="jvp",
             solver="rings"),
        Case(normal="displacement", program="unload", material="prony",
             parameter="tau", output="sum", solver="rings"),
    ]


# The default test suite's cases: every axis value at least once, chosen greedily from
# `default_slice()` by value covered per measured second (472 of its 1185 CPU-seconds
# in the suite of 2026-11-29); the rest of the slice runs with the slow tests.
QUICK = (
    "none/displacement-constant/none/zener/tau/grad",
    "none/force-ramp/none/prony/load/jvp/sum",
    "full/displacement-constant/disp_y/elastic/friction/jit/total",
    "none/displacement-ramp/none/maxwell/radius/jit",
    "none/force-constant/none/zener/height/jit/periodic/surface",
    "none/force-constant/reversal/creep/tangential/jvp",
    "none/force-constant/none/zener/tau/vmap/linear",
    "none/displacement-ramp/none/elastic/modulus/float32",
    "x/force-unload/disp_past/maxwell/friction/jit/sum",
    "none/displacement-constant/none/prony/poisson/jit",
    "none/force-constant/disp/elastic/height/jit/surface",
    "full/force-constant/force_xy/elastic/load/jit",
    "full/displacement-ramp/force_neg/maxwell/modulus/jit",
    "full/force-constant/force_y/zener/friction/jit",
    "none/force-constant/force/elastic/friction/jit",
    "x/force-ramp/force_near/elastic/friction/jit",
    "x/force-constant/force_past/elastic/friction/jit",
    "none/force-ramp/none/zener/tau/jvp/rings",
)


def quick_slice() -> list[Case]:
    """The cases of `default_slice()` named in `QUICK`: every axis value once."""
    return [c for c in default_slice() if c.name in QUICK]


def table(rows) -> str:
    lines = ["| case | status | gradient | central difference | error | s |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        g = "-" if r.get("gradient") is None else f"{r['gradient']:.6g}"
        cd = "-" if r.get("cd") is None else f"{r['cd']:.6g}"
        err = "-" if r.get("error") is None else f"{r['error']:.1e}"
        shown = r["status"] in ("refused", "wrong") and r.get("message")
        status = r["status"] + (f": {r['message']}" if shown else "")
        lines.append(
            f"| {r['name']} | {status} | {g} | {cd} | {err} | {r['seconds']} |")
    return "\n".join(lines)


def _or_nan(value):
    return float("nan") if value is None else value


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--slice", choices=("all", "default", "rings"), default="all",
                        help="every case, the default suite's, or the ring solver's")
    parser.add_argument("--only", default=None,
                        help="names containing one of these comma-separated texts")
    parser.add_argument("--case", default=None, help="the one case of this name")
    parser.add_argument("--out", default=None, help="JSON path")
    args = parser.parse_args(argv)
    cases = {"all": all_cases, "default": default_slice,
             "rings": lambda: [c for c in all_cases() if c.solver == "rings"]}[
                 args.slice]()
    if args.case:
        cases = [c for c in all_cases() + default_slice() if c.name == args.case][:1]
        if not cases:
            parser.error(f"no case named {args.case!r}")
    if args.only:  # comma-separated parts of names
        parts = args.only.split(",")
        cases = [c for c in cases if any(part in c.name for part in parts)]
    variant = ("selection" if args.case or args.only
               else None if args.slice == "all" else args.slice)
    record = header("gradient_matrix", argv, variant)
    record["settings"] = dict(grid=N, steps=NT, dtype="float64", slice=args.slice,
                              forward_rtol=RTOL, h_relative=1e-5)
    rows = []
    for i, case in enumerate(cases):
        rows.append(check(case))
        r = rows[-1]
        print(f"[{i + 1}/{len(cases)}] {r['name']}: {r['status']} "
              f"(error {_or_nan(r.get('error')):.1e}, {r['seconds']} s)"
              + (f" {r.get('message', '')}" if r["status"] != "right" else ""),
              file=sys.stderr, flush=True)
        counts = {s: sum(x["status"] == s for x in rows)
                  for s in ("right", "kink", "refused", "wrong")}
        write_results({**record, "rows": rows, "summary": {"counts": counts}},
                      args.out)
    print(table(rows))
    print(counts)
    return 0 if counts["wrong"] == 0 else 1


if __name__ == "__main__":
    raise SystemExit(main())
