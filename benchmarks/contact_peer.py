"""CONTACT (Vollebregt) as a peer: Spence's problem and a Cattaneo-Mindlin load.

Runs CONTACT (when its executable is given) and `jc.solve` on the same scenes, with the
same discretisation, at equal tolerance (CONTACT's EPS = jaxcontact's rtol), and writes
time, iterations, c/a and the contact and stick cells of both to JSON.

Scenes (inputs for CONTACT from `contact_inputs.py`, a copy of the peer recipe's
`make_inputs.py`; the jaxcontact scene built from the same numbers):

- Spence: a rigid sphere (R = 100) pressed on an elastic half-space (G = 0.5, nu),
  Coulomb friction mu, full normal-tangential coupling, incremental slip. Final Hertz
  radius a = 1; grid of (2 round(1.25 N) + 1)^2 cells with dx = a / N; K load stages
  F_k = F (k / K)^3. Defaults: nu in {0.3, 0.25}, mu in {0.2, 0.3}, N = 45, K = 90.
- Cattaneo-Mindlin: rigid sphere R = 10 on G = 1.93, nu = 0.5 (no coupling), W = 0.15,
  mu = 0.3, F_x = 0.5 mu W in one step from zero; N = 45 cells per Hertz radius over a
  square of half-width ~1.15 a (c/a = 0.7937 in the continuum).

The same discretisation in both codes: the jaxcontact scene is built from the numbers
CONTACT reads in its input (`read_input`: the grid line is printed with 7 decimals, so
dx = 1/45 becomes 0.0222222), and CONTACT's grid is shifted by about +5e-4 dx against
the sphere (to break the symmetry of ties), so the jaxcontact sphere is centred at
about (-5e-4 dx, -5e-4 dx). What differs: CONTACT's body 2 is "practically rigid"
(G2 = 2e5 x G1 in its input), so its normal compliance is the rigid indenter's times
(1 + G1 / G2), a relative difference of 5e-6 (1e-5 in the coupling term).

Measured per scene and tolerance:

- CONTACT: wall and CPU time (`RUSAGE_CHILDREN`) of the whole program run
  (`contact_linux64 2 NAME`: reading the input, influence coefficients, all stages,
  writing `.out` and the last stage's `.mat`), with flow output `W = 3` (the
  generator's Spence default is 1; 3 adds two lines per outer iteration, the CG
  iterations, milliseconds of output); outer (Panagiotopoulos) iterations and inner CG
  iterations of its normal and tangential solvers, summed over the stages; contact
  and stick (adhesion) cells of the last stage from its `.mat` file.
- jaxcontact: `jc.solve(scene, rtol=...)` (or `solver=jc.JointPCG(rtol=...)` with
  `--solver joint`, on the coupled scenes: it refuses uncoupled ones), `throw=False`
  so that a step that does not converge is recorded (`all_converged`,
  `steps_not_converged`) instead of ending the run; the first call after
  `jax.clear_caches()` (compile + solve, what a new process pays) and the second call
  (solve only), each to `block_until_ready`, wall and process CPU time (all threads);
  iterations, rounds and fallbacks summed over the steps.
- both: c/a = sqrt(n_stick / n_contact) on the last stage, and whether the contact and
  stick cells are identical (else how many differ).

Usage::

    python benchmarks/contact_peer.py --contact /path/to/contact_linux64
    CONTACT_EXE=/path/to/contact_linux64 python benchmarks/contact_peer.py
    python benchmarks/contact_peer.py --quick           # N = 15, K = 30: a minute
    python benchmarks/contact_peer.py --solver joint    # jc.JointPCG(rtol=...)

Without an executable CONTACT is skipped (with a message) and jaxcontact still runs.
CONTACT runs serially (one core); jaxcontact (XLA) may use every core the process is
allowed: `--one-core` pins this process and CONTACT to one CPU. Results go to
`benchmarks/results/contact_peer/<machine>.json` (`--quick`: `<machine>_quick.json`;
`--out`; layout: `results/SCHEMA.md`): a row per scene and tolerance; CONTACT's
executable and revision in `settings.contact`, the Markdown table in `summary`.
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import jax


jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402


ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import contact_inputs  # noqa: E402
from _common import header, load_results, results_path, write_results  # noqa: E402

import jaxcontact as jc  # noqa: E402


# ---- CONTACT ------------------------------------------------------------------------


def find_contact(path: str | None) -> tuple[str | None, str]:
    """The CONTACT executable and why it is (not) used."""
    path = path or os.environ.get("CONTACT_EXE")
    if not path:
        return None, (
            "CONTACT skipped: no executable given (--contact PATH or "
            "CONTACT_EXE); build it with ../shared/peers/contact/README.md"
        )
    exe = shutil.which(path) or path
    if not (os.path.isfile(exe) and os.access(exe, os.X_OK)):
        return None, f"CONTACT skipped: {path!r} is not an executable file"
    return str(Path(exe).resolve()), f"CONTACT: {Path(exe).resolve()}"


def _parse_out(text: str) -> dict:
    """Iterations, statistics and warnings from CONTACT's `.out` file."""
    cases = re.split(r"^ Case\s+\d+\s*$", text, flags=re.M)[1:]
    # one line per outer iteration when MAXOUT > 1 (FLOW >= 1); with MAXOUT = 1
    # (Cattaneo, uncoupled) no line: one pass
    outer = [max(len(re.findall(r"Panag/Out:", c)), 1) for c in cases]
    norm_cg = [
        int(v) for v in re.findall(r"Norm: final element division.*ItCG=\s*(\d+)", text)
    ]
    tang_cg = [
        int(v) for v in re.findall(r"Tang: final element division.*ItCG=\s*(\d+)", text)
    ]
    stats = None
    m = re.findall(
        r"NPOT\s+NCON\s+NADH\s+NSLIP\s+INORM\s+ITANG\s*\n\s*([-\d\s]+?)\n", text
    )
    if m:
        npot, ncon, nadh, nslip, inorm, itang = (int(v) for v in m[-1].split()[:6])
        stats = dict(
            npot=npot, ncon=ncon, nadh=nadh, nslip=nslip, inorm=inorm, itang=itang
        )
    version = re.search(r"\$Revision:\s*(\d+)", text)
    warnings = sorted(
        set(
            line.strip()
            for line in text.splitlines()
            if re.search(r"Diverges|ERROR|WARNING|MaxCG|MaxIn", line)
        )
    )
    total = re.search(
        r"^\|Total\s*\|\s*\d+\s*\|\s*([\d.]+)\s*\|\s*[\d.]+\s*\|\s*([\d.]+)",
        text,
        flags=re.M,
    )
    return dict(
        stages=len(cases),
        outer_per_stage=outer,
        outer_total=sum(outer),
        norm_cg_total=sum(norm_cg) if norm_cg else None,
        tang_cg_total=sum(tang_cg) if tang_cg else None,
        statistics=stats,
        warnings=warnings,
        revision=version.group(1) if version else None,
        timer_total_cpu_s=float(total.group(1)) if total else None,
        timer_total_wall_s=float(total.group(2)) if total else None,
    )


def read_mat(path: Path, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Contact and adhesion (stick) masks `(m, m)`, indexed `[ix, iy]`, from CONTACT's
    `.mat` file: its element rows (after the `% I IGS ...` header) list the elements
    in contact, `I = ix + m (iy - 1)` (1-based), `IGS` 1 = adhesion, 2 = slip."""
    lines = path.read_text().splitlines()
    start = next(i for i, line in enumerate(lines) if re.match(r"%\s+I\s+IGS", line))
    contact = np.zeros((m, m), bool)
    stick = np.zeros((m, m), bool)
    for line in lines[start + 1 :]:
        if not line.strip() or line.startswith("%"):
            continue
        fields = line.split()
        i, igs = int(fields[0]) - 1, int(fields[1])
        ix, iy = i % m, i // m
        contact[ix, iy] = igs >= 1
        stick[ix, iy] = igs == 1
    return contact, stick


def run_contact(exe: str, text: str, name: str, workdir: Path, m: int, repeats: int):
    """Run CONTACT on one input (best wall time of `repeats`): the `_parse_out` numbers,
    times, and the last stage's contact and stick masks."""
    case = workdir / name
    case.mkdir(parents=True, exist_ok=True)
    (case / f"{name}.inp").write_text(text)
    times, cpu = [], []
    for _ in range(repeats):
        for old in case.glob(f"{name}.*.mat"):
            old.unlink()
        usage = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        proc = subprocess.run(
            [exe, "2", name], cwd=case, capture_output=True, text=True
        )
        times.append(time.perf_counter() - start)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu.append(after.ru_utime + after.ru_stime - usage.ru_utime - usage.ru_stime)
        if proc.returncode != 0:
            raise RuntimeError(
                f"CONTACT failed on {name} (rc {proc.returncode}): "
                f"{proc.stdout[-2000:]}{proc.stderr[-2000:]}"
            )
    out = _parse_out((case / f"{name}.out").read_text(errors="replace"))
    mats = sorted(case.glob(f"{name}.*.mat"))
    contact, stick = read_mat(mats[-1], m)
    res = dict(
        wall_s=min(times),
        wall_s_all=times,
        cpu_s=cpu[int(np.argmin(times))],
        cpu_s_all=cpu,
        **out,
        n_contact=int(contact.sum()),
        n_stick=int(stick.sum()),
        c_over_a=float(np.sqrt(stick.sum() / contact.sum())),
        mat_file=mats[-1].name,
    )
    if out["statistics"] and (
        out["statistics"]["ncon"] != res["n_contact"]
        or out["statistics"]["nadh"] != res["n_stick"]
    ):
        res["warnings"].append("the .mat file's cells differ from CONTACT STATISTICS")
    return res, contact, stick


# ---- jaxcontact ---------------------------------------------------------------------


def read_input(text: str) -> dict:
    """The numbers CONTACT reads from an input of `contact_inputs` (as printed: the grid
    line has 7 decimals, so DX = 1/45 is read as 0.0222222, 1e-6 short; the jaxcontact
    scene uses these numbers, not the generator's unrounded ones): grid `m`, `dx`, `xl`
    (left edge), sphere radius `R = 1 / (2 B1)`, `nu`, `G1`, `mu` and per stage the
    first four numbers of the force line (`FN, CKSI, CETA, CPHI` or
    `FN, FX, FY, CPHI`)."""
    lines = text.splitlines()

    def numbers(tag, offset=0):
        i = next(i for i, line in enumerate(lines) if tag in line) + offset
        return [
            float(v)
            for v in re.findall(
                r"[-+]?\d*\.?\d+(?:[eE][-+]?\d+)?", lines[i].split("%")[0]
            )
        ]

    mx, my, xl, yl, dx, dy = numbers("MX,MY,XL,YL,DX,DY")[:6]
    if (mx, xl, dx) != (my, yl, dy):
        raise ValueError("contact_peer expects a square grid")
    b = numbers("QUADRATIC UNDEFORMED DISTANCE", 1)
    if b[0] != b[2] or any(b[i] for i in (1, 3, 4, 5)):
        raise ValueError(f"not a centred sphere: B = {b}")
    poiss = numbers("POISS 1,2")
    forces = [
        [float(v) for v in line.split()[:4]]
        for line in lines
        if re.search(r"\bFN, (CKSI|FX)", line)
    ]
    return dict(
        m=int(mx),
        dx=dx,
        xl=xl,
        radius=1 / (2 * b[0]),
        nu=poiss[0],
        g1=poiss[2],
        mu=numbers("FSTAT, FKIN")[0],
        forces=np.array(forces),
    )


def _grid_and_sphere(inp: dict):
    """CONTACT's grid: cell centres at `xl + (i + 1/2) dx` with the sphere at the
    origin; jaxcontact's at `(i - (m - 1) / 2) dx`: the sphere goes to
    `-(xl + m dx / 2)` (about -5e-4 dx) on both axes."""
    m, dx = inp["m"], inp["dx"]
    shift = -(inp["xl"] + 0.5 * m * dx)
    return jc.Grid((m, m), m * dx), jc.Sphere(inp["radius"], centre=(shift, shift))


def spence_scene(text: str) -> jc.Scene:
    """The jaxcontact scene of a `contact_inputs.spence_input` text: the stages' FN as
    a load over `times = 0, 1, ..., K - 1`, full coupling, incremental slip."""
    inp = read_input(text)
    grid, sphere = _grid_and_sphere(inp)
    loads = inp["forces"][:, 0]
    return jc.Scene(
        grid,
        sphere,
        jc.Elastic(inp["g1"], inp["nu"]),
        times=jnp.arange(len(loads), dtype=jnp.float64),
        normal=jc.Force(jnp.asarray(loads)),
        friction=inp["mu"],
        coupling="full",
        slip="incremental",
    )


def cattaneo_scene(text: str) -> jc.Scene:
    """The jaxcontact scene of a `contact_inputs.cattaneo_input` text: one step from
    zero, F_x = (FX / (mu FN)) mu FN, F_y = 0; no coupling at nu = 0.5.

    `y=jc.Force(0.0)`, not `None`: CONTACT solves for both shear components (q_y free,
    its total zero: PY reaches 1.8 % of the peak pressure in the slip zone), while with
    `y=None` jaxcontact solves for q_x alone (q_y = 0, the Coulomb bound on |q_x|), a
    different problem: 10 more stick cells (4024 against 4014 at N = 45), |q| up to
    0.24 % of the peak pressure apart."""
    inp = read_input(text)
    grid, sphere = _grid_and_sphere(inp)
    ((fn, fx_rel, fy_rel, _),) = inp["forces"]
    if fy_rel != 0:
        raise ValueError("contact_peer's Cattaneo scene has F_y = 0")
    return jc.Scene(
        grid,
        sphere,
        jc.Elastic(inp["g1"], inp["nu"]),
        times=jnp.zeros(1),
        normal=jc.Force(fn),
        x=jc.Force(fx_rel * inp["mu"] * fn),
        y=jc.Force(0.0),
        friction=inp["mu"],
        coupling="none" if inp["nu"] == 0.5 else "full",
    )


def run_jaxcontact(
    scene: jc.Scene, rtol: float, solver: str
) -> tuple[dict, np.ndarray, np.ndarray]:
    if solver == "joint" and scene.coupling == "none":
        solver = "default (JointPCG needs coupling)"  # it refuses uncoupled steps
    if solver == "joint":
        options = dict(solver=jc.JointPCG(rtol=rtol))
    else:
        options = dict(rtol=rtol)

    def call():
        return jc.solve(scene, throw=False, **options)

    jax.clear_caches()
    start, cpu = time.perf_counter(), time.process_time()
    sol = call()
    jax.block_until_ready(sol)
    first, first_cpu = time.perf_counter() - start, time.process_time() - cpu
    start, cpu = time.perf_counter(), time.process_time()
    sol = call()
    jax.block_until_ready(sol)
    second, second_cpu = time.perf_counter() - start, time.process_time() - cpu
    contact = np.asarray(sol.contact[-1])
    stick = np.asarray(sol.stick[-1]) & contact
    res = dict(
        solver=solver,
        first_call_s=first,
        second_call_s=second,
        compile_s=first - second,
        first_call_cpu_s=first_cpu,
        second_call_cpu_s=second_cpu,
        iterations_total=int(sol.iterations.sum()),
        rounds_total=int(sol.rounds.sum()),
        fallbacks_total=int(sol.fallbacks.sum()),
        all_converged=bool(sol.converged.all()),
        steps_not_converged=[int(k) for k in np.nonzero(~np.asarray(sol.converged))[0]],
        steps_with_fallback=[int(k) for k in np.nonzero(np.asarray(sol.fallbacks))[0]],
        n_contact=int(contact.sum()),
        n_stick=int(stick.sum()),
        c_over_a=float(np.sqrt(stick.sum() / contact.sum())),
        stick_ratio_last=float(sol.stick_ratio[-1]),
        edge_contact=bool(np.any(np.asarray(sol.edge_contact)))
        if hasattr(sol, "edge_contact")
        else None,
    )
    return res, contact, stick


# ---- driver -------------------------------------------------------------------------


def scenes(args) -> list[tuple[str, str, dict]]:
    """`(name, kind, parameters)` of every scene asked for."""
    out = []
    for nu in args.nu if "spence" in args.scenes else []:
        for mu in args.mu:
            out.append(
                (
                    f"spence_nu{nu:g}_mu{mu:g}_N{args.N}_K{args.K}",
                    "spence",
                    dict(nu=nu, mu=mu, N=args.N, K=args.K),
                )
            )
    if args.cattaneo_N and "cattaneo" in args.scenes:
        out.append(
            (f"cattaneo_N{args.cattaneo_N}", "cattaneo", dict(N=args.cattaneo_N))
        )
    return out


def one_case(kind, params, rtol, args, exe, workdir, name):
    if kind == "spence":
        text, meta = contact_inputs.spence_input(
            params["nu"], params["mu"], params["N"], params["K"], eps=rtol, wflow=3
        )
        scene = spence_scene(text)
    else:
        # the generator's default flow output here is W = 3
        text, meta = contact_inputs.cattaneo_input(params["N"], eps=rtol)
        scene = cattaneo_scene(text)
    row = dict(
        scene=name,
        kind=kind,
        rtol=rtol,
        eps=rtol,
        grid=[meta["M"], meta["M"]],
        parameters={k: v for k, v in meta.items()},
        load_before=os.getloadavg(),
    )
    c_masks = None
    if exe:
        row["contact"], *c_masks = run_contact(
            exe, text, f"{name}_eps{rtol:g}", workdir, meta["M"], args.repeats
        )
    row["jaxcontact"], j_contact, j_stick = run_jaxcontact(scene, rtol, args.solver)
    row["load_after"] = os.getloadavg()
    if c_masks is not None:
        c_contact, c_stick = c_masks
        row["contact_cells_identical"] = bool(np.array_equal(c_contact, j_contact))
        row["stick_cells_identical"] = bool(np.array_equal(c_stick, j_stick))
        row["contact_cells_differing"] = int(np.sum(c_contact != j_contact))
        row["stick_cells_differing"] = int(np.sum(c_stick != j_stick))
        row["ratio_contact_over_jaxcontact"] = (
            row["contact"]["wall_s"] / row["jaxcontact"]["second_call_s"]
        )
        row["ratio_cpu_contact_over_jaxcontact"] = (
            row["contact"]["cpu_s"] / row["jaxcontact"]["second_call_cpu_s"]
        )
        row["ratio_contact_over_jaxcontact_first_call"] = (
            row["contact"]["wall_s"] / row["jaxcontact"]["first_call_s"]
        )
    return row


def print_row(row):
    j = row["jaxcontact"]
    line = (
        f"{row['scene']:32s} tol {row['rtol']:.0e}  jc {j['first_call_s']:6.2f} / "
        f"{j['second_call_s']:6.2f} s it {j['iterations_total']:5d} c/a "
        f"{j['c_over_a']:.4f} ({j['n_contact']}/{j['n_stick']})"
    )
    if not j["all_converged"]:
        line += f" NOT CONVERGED at steps {j['steps_not_converged'][:5]}"
    if "contact" in row:
        c = row["contact"]
        line += (
            f" | CONTACT {c['wall_s']:6.2f} s outer {c['outer_total']} CG "
            f"{c['norm_cg_total']}+{c['tang_cg_total']} c/a {c['c_over_a']:.4f} "
            f"({c['n_contact']}/{c['n_stick']}) same cells "
            f"{row['contact_cells_identical'] and row['stick_cells_identical']} "
            f"ratio {row['ratio_contact_over_jaxcontact']:.2f} (cpu "
            f"{c['cpu_s']:.1f} / {j['second_call_cpu_s']:.1f} s: "
            f"{row['ratio_cpu_contact_over_jaxcontact']:.2f})"
        )
    print(line, flush=True)


def markdown_table(rows) -> str:
    """Times as wall / CPU seconds; the ratios CONTACT over jaxcontact's second call."""
    head = (
        "| scene | tol | CONTACT wall / cpu [s] | CONTACT outer / CG it (n + t) "
        "| jc first call [s] | jc second call wall / cpu [s] | jc it | c/a CONTACT "
        "| c/a jc | contact cells C / jc | stick cells C / jc | cells identical "
        "| ratio wall | ratio cpu |"
    )
    lines = [head, "|" + "---|" * 14]
    for r in rows:
        j = r["jaxcontact"]
        c = r.get("contact")
        jc_it = str(j["iterations_total"]) + (
            "" if j["all_converged"] else " (not converged)"
        )
        if c:
            same = (
                "yes"
                if r["contact_cells_identical"] and r["stick_cells_identical"]
                else f"no ({r['contact_cells_differing']} / "
                f"{r['stick_cells_differing']} differ)"
            )
            cells = (
                f"{c['wall_s']:.2f} / {c['cpu_s']:.2f}",
                f"{c['outer_total']} / {c['norm_cg_total']} + {c['tang_cg_total']}",
                f"{c['c_over_a']:.4f}",
                f"{c['n_contact']} / {j['n_contact']}",
                f"{c['n_stick']} / {j['n_stick']}",
                same,
                f"{r['ratio_contact_over_jaxcontact']:.2f}",
                f"{r['ratio_cpu_contact_over_jaxcontact']:.2f}",
            )
        else:
            cells = (
                "",
                "",
                "",
                f"- / {j['n_contact']}",
                f"- / {j['n_stick']}",
                "",
                "",
                "",
            )
        lines.append(
            f"| {r['scene']} | {r['rtol']:.0e} | {cells[0]} | {cells[1]} | "
            f"{j['first_call_s']:.2f} | {j['second_call_s']:.2f} / "
            f"{j['second_call_cpu_s']:.2f} | {jc_it} | {cells[2]} | "
            f"{j['c_over_a']:.4f} | "
            f"{cells[3]} | {cells[4]} | {cells[5]} | {cells[6]} | {cells[7]} |"
        )
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--contact",
        default=None,
        help="CONTACT executable (default: $CONTACT_EXE; none: skipped)",
    )
    parser.add_argument(
        "--scenes",
        nargs="+",
        choices=["spence", "cattaneo"],
        default=["spence", "cattaneo"],
    )
    parser.add_argument(
        "--update",
        action="store_true",
        help="replace only these rows (scene, tol) in --out",
    )
    parser.add_argument("--nu", type=float, nargs="+", default=[0.3, 0.25])
    parser.add_argument("--mu", type=float, nargs="+", default=[0.2, 0.3])
    parser.add_argument(
        "--N", type=int, default=45, help="Spence: cells per final radius"
    )
    parser.add_argument("--K", type=int, default=90, help="Spence: load stages")
    parser.add_argument(
        "--cattaneo-N",
        type=int,
        default=45,
        help="Cattaneo-Mindlin: cells per Hertz radius (0: skip)",
    )
    parser.add_argument(
        "--rtols",
        type=float,
        nargs="+",
        default=[1e-6, 1e-8],
        help="jaxcontact rtol = CONTACT EPS",
    )
    parser.add_argument("--solver", choices=["default", "joint"], default="default")
    parser.add_argument(
        "--repeats", type=int, default=1, help="CONTACT runs per case (best wall time)"
    )
    parser.add_argument("--quick", action="store_true", help="N = 15, K = 30")
    parser.add_argument(
        "--one-core",
        action="store_true",
        help="pin this process (and CONTACT) to one CPU",
    )
    parser.add_argument(
        "--workdir",
        default=None,
        help="keep CONTACT's files here (default: a temporary folder)",
    )
    parser.add_argument(
        "--out", default=None,
        help="JSON path (default results/contact_peer/<machine>.json)",
    )
    args = parser.parse_args()
    if args.quick:
        args.N, args.K = 15, 30
        args.cattaneo_N = min(args.cattaneo_N, 15) if args.cattaneo_N else 0
    if args.one_core:
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    exe, why = find_contact(args.contact)
    print(why, flush=True)
    workdir = Path(args.workdir or tempfile.mkdtemp(prefix="contact_peer_"))
    workdir.mkdir(parents=True, exist_ok=True)

    out = Path(args.out or results_path("contact_peer",
                                        "quick" if args.quick else None))
    results = header("contact_peer", variant="quick" if args.quick else None)
    results["machine"].update(
        load_average_start=os.getloadavg(),
        niceness=os.nice(0),
        affinity=sorted(os.sched_getaffinity(0)),
    )
    results.update(
        settings=dict(
            contact=dict(executable=exe, note=why),
            nu=args.nu,
            mu=args.mu,
            N=args.N,
            K=args.K,
            cattaneo_N=args.cattaneo_N,
            rtols=args.rtols,
            solver=args.solver,
            repeats=args.repeats,
            one_core=args.one_core,
        ),
        rows=[],
        summary={},
    )
    start = time.perf_counter()
    for name, kind, params in scenes(args):
        for rtol in args.rtols:
            row = one_case(kind, params, rtol, args, exe, workdir, name)
            results["rows"].append(row)
            print_row(row)
    results["machine"]["load_average_end"] = os.getloadavg()
    results["summary"]["total_s"] = time.perf_counter() - start
    if exe and results["rows"]:
        results["settings"]["contact"]["revision"] = (
            results["rows"][0]["contact"]["revision"])
    this = {k: results[k] for k in ("date", "commit", "machine", "settings")}
    this["total_s"] = results["summary"]["total_s"]
    if args.update and out.exists():
        # keep the earlier run, replace its rows of the same (scene, tol), and keep this
        # run's settings and machine block beside it
        old = load_results(out)
        updates = old["summary"].setdefault("updates", [])
        new = {(r["scene"], r["rtol"]): r for r in results["rows"]}
        for r in results["rows"]:
            r["from_update"] = len(updates)
        old["rows"] = [new.pop((r["scene"], r["rtol"]), r) for r in old["rows"]]
        old["rows"] += list(new.values())
        updates.append(this)
        results = old
    table = markdown_table(results["rows"])
    results["summary"]["table_markdown"] = table
    path = write_results(results, out)
    print(table)
    print(
        f"load average start {this['machine']['load_average_start']} end "
        f"{this['machine']['load_average_end']}; total {this['total_s']:.0f} s"
    )
    print(f"wrote {path}; CONTACT files in {workdir}")


if __name__ == "__main__":
    main()
