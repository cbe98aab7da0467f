"""Peer contact solvers for `benchmarks/run.py` (Tamaas, ContactMechanics) and for
`benchmarks/aspher_peer.py` (ASPHER).

This file is run by a Python that has the peers installed (they need not share an
environment with jaxcontact: `pip install ".[peers]"`, or a separate virtual
environment, e.g. `python -m venv /tmp/peers-venv && /tmp/peers-venv/bin/pip install
tamaas contactmechanics`). It imports neither jax nor jaxcontact, only NumPy and the
peer, and nothing from the peers goes into jaxcontact.

It solves the Hertz problem of `benchmarks/hertz.py` (a rigid sphere of radius R
pressed with a load W on an elastic half-space of plane-strain modulus E*, square
domain of side L, n x n cells centred on the origin) with

- ContactMechanics (`FreeFFTElasticHalfSpace`: non-periodic, zero padding to 2n x 2n,
  Love's influence coefficients of uniformly loaded cells, as jaxcontact's DC-FFT;
  solved by its `constrained_conjugate_gradients` (Polonsky & Keer) under load control,
  tolerance `pentol` on the penetration [length]);
- Tamaas (`model_type.basic_2d`: periodic, Westergaard's spectral kernel at the grid
  points; solved by `PolonskyKeerRey` under load control (mean pressure W / L^2),
  relative tolerance `tol`).

Usage::

    python benchmarks/peers.py --probe          # JSON: which peers import, versions
    python benchmarks/peers.py --serve          # JSON-lines server (stdin -> stdout)

A request is one JSON object per line::

    {"code": "contactmechanics" | "tamaas", "n": 256, "size": L, "radius": R,
     "force": W, "e_star": E*, "poisson": nu, "tol": 1e-8, "repeats": 3,
     "save": "/path/to/pressure.npy" (optional), "warm": false (optional)}

and the answer one line: the solve times [s] (each solve from the peer's own initial
state, or with "warm": true from the Hertz pressure scaled to W, the kind of guess
jaxcontact's load-control solve starts from; set-up such as the kernel spectra is built
once per (code, n, size) and not timed), the peak pressure [stress], the number of cells
in contact (pressure > 0), the rigid-body approach [length] (ContactMechanics only:
Tamaas is periodic and its mean displacement is a gauge), the iteration count where the
peer reports it, and the process's peak resident memory (`ru_maxrss`). `{"cmd": "quit"}`
ends the server.

ASPHER (`pip install aspher`, built from its sdist; it needs Eigen) takes a different
request, since it is posed in its own units (unit square domain, E* = 1, mean pressure
`p_nominal` = W / (L^2 E*), initial gap in units of L) on an arbitrary gap field::

    {"code": "aspher", "n": 256, "gap_file": "/path/gap.npy" ((n, n), units of L),
     "p_nominal": W / (L^2 E*), "tol": 1e-6, "mode": "plain" | "nested",
     "precision": "double" | "single", "backend": "fft" (default) | "h2",
     "coarsest": 64, "repeats": 1, "save": "/path/to/pressure.npy" (optional)}

- `mode: "plain"`: `aspher.ContactSolver(n, backend=...)` (built once per (n, backend),
  untimed) and `.solve(gap, p_nominal, tol, precond="fourier")`: Polonsky-Keer CG
  with its |q| Fourier preconditioner on the n x n grid, from its own initial state.
  Double precision only.
- `mode: "nested"`: `aspher.solve_nested(grid_size=n, gap, p_nominal, backend=...,
  coarsest=..., tol, precision="double" | "float")`: the nested-grid (cascadic)
  solve, coarsest -> n; it builds its operators inside the call, so they are timed.
  `precision: "single"` is ASPHER's float mode with double reductions; it cannot
  reach a tolerance below its `float_floor` (2e-6), so it runs with
  `allow_tolerance_relaxation=True` and the answer records `effective_tol`.

`backend: "fft"` is the exact zero-padded Love-kernel convolution (jaxcontact's
discretisation); ASPHER's default `"h2"` is a matrix-free approximation. The saved
pressure is in ASPHER's units (of E*), shape (n, n).

Tamaas on an arbitrary gap field (SI units; periodic `basic_2d`, PolonskyKeerRey from
zero traction, the model built once per (n, size) and not timed)::

    {"code": "tamaas_gap", "n": 256, "size": L, "gap_file": "/path/gap.npy" ((n, n)
     [length]), "e_star": E*, "poisson": nu, "force": W, "tol": 1e-6, "repeats": 1,
     "save": "/path/to/pressure.npy" (optional, [stress])}
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time
import traceback

import numpy as np


def _maxrss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def probe() -> dict:
    """Which peers import here, with their versions or the exact import error."""
    out = {"python": sys.version.split()[0], "numpy": np.__version__}
    try:
        import tamaas

        out["tamaas"] = {
            "available": True,
            "version": tamaas.__version__,
            "backend": getattr(tamaas.TamaasInfo, "backend", None),
        }
    except Exception as exc:  # report exactly why
        out["tamaas"] = {"available": False, "error": f"{type(exc).__name__}: {exc}"}
    try:
        import ContactMechanics

        out["contactmechanics"] = {
            "available": True,
            "version": ContactMechanics.__version__,
        }
    except Exception as exc:
        out["contactmechanics"] = {
            "available": False,
            "error": f"{type(exc).__name__}: {exc}",
        }
    try:
        import importlib.metadata as md

        import aspher  # noqa: F401

        out["aspher"] = {"available": True, "version": md.version("aspher")}
    except Exception as exc:
        out["aspher"] = {"available": False, "error": f"{type(exc).__name__}: {exc}"}
    return out


def sphere_heights(n: int, size: float, radius: float) -> np.ndarray:
    """Heights of the rigid sphere, -r^2 / (2R), at the cell centres
    x_i = (i - (n - 1) / 2) dx (jaxcontact's grid); shape (n, n) [length]."""
    dx = size / n
    c = (np.arange(n) - (n - 1) / 2) * dx
    x, y = np.meshgrid(c, c, indexing="ij")
    return -(x * x + y * y) / (2 * radius)


def hertz_guess(n: int, size: float, radius: float, force: float, e_star: float):
    """Hertz pressure p0 sqrt(1 - r^2/a^2) at the cell centres, scaled so that its sum
    times the cell area is `force`: the same kind of initial guess as jaxcontact's
    load-control solve starts from; shape (n, n) [stress]."""
    a = (3 * force * radius / (4 * e_star)) ** (1 / 3)
    dx = size / n
    c = (np.arange(n) - (n - 1) / 2) * dx
    x, y = np.meshgrid(c, c, indexing="ij")
    p = np.sqrt(np.maximum(1 - (x * x + y * y) / (a * a), 0.0))
    return p * force / (p.sum() * dx * dx)


class ContactMechanicsHertz:
    """Non-periodic Hertz with ContactMechanics (set-up once, solves timed)."""

    name = "contactmechanics"

    def __init__(self, req):
        import ContactMechanics as CM
        from ContactMechanics.Optimization import constrained_conjugate_gradients
        from SurfaceTopography import Topography

        self.n, self.size = int(req["n"]), float(req["size"])
        self.cell_area = (self.size / self.n) ** 2
        sizes = (self.size, self.size)
        self.substrate = CM.FreeFFTElasticHalfSpace(
            (self.n, self.n), young=float(req["e_star"]), physical_sizes=sizes
        )
        self.topography = Topography(
            sphere_heights(self.n, self.size, float(req["radius"])),
            physical_sizes=sizes,
        )
        self.solver = constrained_conjugate_gradients
        self.radius, self.e_star = float(req["radius"]), float(req["e_star"])

    def solve(self, force: float, tol: float, warm: bool = False):
        initial = None
        if warm:
            # Its pixel forces are negative in compression, on the 2n x 2n domain.
            initial = np.zeros(self.substrate.nb_domain_grid_pts)
            initial[: self.n, : self.n] = -self.cell_area * hertz_guess(
                self.n, self.size, self.radius, force, self.e_star
            )
        res = self.solver(
            self.substrate,
            self.topography,
            external_force=force,
            pentol=tol,
            maxiter=100000,
            initial_forces=initial,
        )
        # Pixel forces on the 2n x 2n computational grid, compressive < 0 or > 0
        # depending on the version's sign convention: take the sign of the total.
        f = np.asarray(res.jac)[: self.n, : self.n]
        if f.sum() < 0:
            f = -f
        return {
            "pressure": f / self.cell_area,
            "approach": float(res.offset),
            "iterations": int(res.nit),
            "converged": bool(res.success),
        }


class TamaasHertz:
    """Periodic Hertz with Tamaas' PolonskyKeerRey (set-up once, solves timed)."""

    name = "tamaas"

    def __init__(self, req):
        import tamaas as tm

        tm.set_log_level(tm.LogLevel.error)
        self.tm = tm
        self.n, self.size = int(req["n"]), float(req["size"])
        nu = float(req["poisson"])
        self.model = tm.ModelFactory.createModel(
            tm.model_type.basic_2d, [self.size, self.size], [self.n, self.n]
        )
        # Tamaas takes Young's modulus and Poisson's ratio: E* = E / (1 - nu^2).
        self.model.E = float(req["e_star"]) * (1 - nu * nu)
        self.model.nu = nu
        self.heights = sphere_heights(self.n, self.size, float(req["radius"]))
        self.radius, self.e_star = float(req["radius"]), float(req["e_star"])

    def solve(self, force: float, tol: float, warm: bool = False):
        # PolonskyKeerRey starts from the model's current traction.
        self.model.traction[...] = (
            hertz_guess(self.n, self.size, self.radius, force, self.e_star)
            if warm
            else 0.0
        )
        self.model.displacement[...] = 0.0
        solver = self.tm.PolonskyKeerRey(self.model, self.heights, tol)
        solver.max_iter = 100000
        err = solver.solve(force / self.size**2)
        p = np.array(self.model.traction)
        return {
            "pressure": p,
            "approach": None,
            "iterations": None,
            "converged": bool(err <= tol),
            "final_error": float(err),
        }


PEERS = {"contactmechanics": ContactMechanicsHertz, "tamaas": TamaasHertz}


def handle_tamaas_gap(req, cache: dict) -> dict:
    """Tamaas' PolonskyKeerRey on a given gap field (SI units), periodic `basic_2d`,
    from zero traction (its own start); the model is built once per (n, size), untimed.
    The gap `h` is Tamaas' surface `-h` (heights towards the indenter)."""
    import tamaas as tm

    n, size = int(req["n"]), float(req["size"])
    key = ("tamaas_gap", n, size, float(req["e_star"]), float(req["poisson"]))
    t0 = time.perf_counter()
    if key not in cache:
        for k in [k for k in cache if isinstance(k, tuple) and k[0] == "tamaas_gap"]:
            del cache[k]  # one model at a time, beside ASPHER's solvers
        tm.set_log_level(tm.LogLevel.error)
        model = tm.ModelFactory.createModel(tm.model_type.basic_2d, [size, size],
                                            [n, n])
        nu = float(req["poisson"])
        model.E = float(req["e_star"]) * (1 - nu * nu)
        model.nu = nu
        cache[key] = model
    model = cache[key]
    surface = -np.asarray(np.load(req["gap_file"]), dtype=np.float64)
    if surface.shape != (n, n):
        raise ValueError(f"gap has shape {surface.shape}, expected {(n, n)}")
    setup_s = time.perf_counter() - t0
    force, tol = float(req["force"]), float(req["tol"])
    times, err = [], None
    for _ in range(max(1, int(req.get("repeats", 1)))):
        model.traction[...] = 0.0
        model.displacement[...] = 0.0
        t = time.perf_counter()
        solver = tm.PolonskyKeerRey(model, surface, tol)
        solver.max_iter = 100000
        err = solver.solve(force / size**2)
        times.append(time.perf_counter() - t)
    p = np.array(model.traction, dtype=np.float64).reshape(n, n)
    if req.get("save"):
        np.save(req["save"], p)
    return {
        "code": "tamaas_gap", "n": n, "tol": tol, "times_s": times,
        "setup_s": setup_s, "peak_pressure": float(p.max()),
        "contact_cells": int(np.count_nonzero(p > 0)),
        "total_force": float(p.sum() * (size / n) ** 2),
        "finite": bool(np.isfinite(p).all()), "maxrss_mib": _maxrss_mib(),
        "iterations": None, "converged": bool(err <= tol), "final_error": float(err),
    }


class AspherSolve:
    """ASPHER on a given gap field, in its units (unit domain, E* = 1)."""

    name = "aspher"

    def __init__(self):
        import aspher

        self.aspher = aspher
        self.solvers: dict = {}  # (n, backend) -> ContactSolver, built untimed
        self.gaps: dict = {}  # gap_file -> flattened float64 gap

    def gap(self, path: str, n: int) -> np.ndarray:
        if path not in self.gaps:
            g = np.asarray(np.load(path), dtype=np.float64)
            if g.shape != (n, n):
                raise ValueError(f"gap {path} has shape {g.shape}, expected {(n, n)}")
            self.gaps[path] = np.ascontiguousarray(g.ravel())
        return self.gaps[path]

    def solver(self, n: int, backend: str):
        key = (n, backend)
        if key not in self.solvers:
            self.solvers.clear()  # one operator at a time
            self.solvers[key] = self.aspher.ContactSolver(grid_size=n, backend=backend)
        return self.solvers[key]

    def solve(self, req) -> dict:
        n = int(req["n"])
        gap = self.gap(req["gap_file"], n)
        p_nom, tol = float(req["p_nominal"]), float(req["tol"])
        mode = req.get("mode", "plain")
        precision = req.get("precision", "double")
        backend = req.get("backend", "fft")
        max_iter = int(req.get("max_iter", 20000))
        if mode == "plain":
            if precision != "double":
                raise ValueError(
                    "ASPHER's ContactSolver.solve is double precision only")
            s = self.solver(n, backend)
            t = time.perf_counter()
            res = s.solve(gap, p_nominal=p_nom, tol=tol, max_iter=max_iter,
                          precond="fourier")
            dt = time.perf_counter() - t
        elif mode == "nested":
            kw = {}
            if precision == "single":
                kw = {"precision": "float", "allow_tolerance_relaxation": True}
            elif precision == "double":
                kw = {"precision": "double"}
            else:
                raise ValueError(
                    f"precision must be double or single, got {precision!r}")
            t = time.perf_counter()
            res = self.aspher.solve_nested(
                grid_size=n, gap=gap, p_nominal=p_nom, backend=backend,
                coarsest=int(req.get("coarsest", 64)), tol=tol, max_iter=max_iter,
                **kw)
            dt = time.perf_counter() - t
        else:
            raise ValueError(f"mode must be plain or nested, got {mode!r}")
        p = np.asarray(res.pressure, dtype=np.float64).reshape(n, n)
        return {
            "time_s": dt,
            "pressure": p,
            "iterations": int(res.iterations),
            "converged": bool(res.converged),
            "status": str(res.status),
            "fw_error": float(res.fw_error),
            "effective_tol": float(res.effective_tol),
            "mean_pressure": float(res.mean_pressure),
            "contact_area": float(res.contact_area),
            # Operator applications and the time in them (nested: the finest level's
            # only): the per-application cost beside ours.
            "matvec_count": int(getattr(res, "matvec_count", -1)),
            "matvec_s": float(getattr(res, "timings", {}).get("matvec", float("nan"))),
        }


def handle_aspher(req, cache: dict) -> dict:
    t0 = time.perf_counter()
    if "aspher" not in cache:
        cache.clear()
        cache["aspher"] = AspherSolve()
    peer = cache["aspher"]
    if req.get("mode", "plain") == "plain":
        peer.solver(int(req["n"]), req.get("backend", "fft"))
    setup_s = time.perf_counter() - t0
    times, out = [], None
    for _ in range(max(1, int(req.get("repeats", 1)))):
        out = peer.solve(req)
        times.append(out.pop("time_s"))
    p = out.pop("pressure")
    if req.get("save"):
        np.save(req["save"], p)
    return {
        "code": "aspher",
        "n": int(req["n"]),
        "tol": float(req["tol"]),
        "mode": req.get("mode", "plain"),
        "precision": req.get("precision", "double"),
        "backend": req.get("backend", "fft"),
        "times_s": times,
        "setup_s": setup_s,
        "peak_pressure": float(p.max()),
        "contact_cells": int(np.count_nonzero(p > 0)),
        "finite": bool(np.isfinite(p).all()),
        "maxrss_mib": _maxrss_mib(),
        **out,
    }


def handle(req, cache: dict) -> dict:
    code = req["code"]
    if code == "aspher":
        return handle_aspher(req, cache)
    if code == "tamaas_gap":
        return handle_tamaas_gap(req, cache)
    key = (
        code,
        int(req["n"]),
        float(req["size"]),
        float(req["radius"]),
        float(req["e_star"]),
        float(req["poisson"]),
    )
    t0 = time.perf_counter()
    if key not in cache:
        cache.clear()  # one set-up at a time keeps the memory figure per problem
        cache[key] = PEERS[code](req)
    setup_s = time.perf_counter() - t0
    peer = cache[key]
    force, tol = float(req["force"]), float(req["tol"])
    times, out = [], None
    for _ in range(max(1, int(req.get("repeats", 1)))):
        t = time.perf_counter()
        out = peer.solve(force, tol, warm=bool(req.get("warm", False)))
        times.append(time.perf_counter() - t)
    p = out.pop("pressure")
    if req.get("save"):
        np.save(req["save"], p)
    return {
        "code": code,
        "n": peer.n,
        "tol": tol,
        "times_s": times,
        "setup_s": setup_s,
        "peak_pressure": float(p.max()),
        "contact_cells": int(np.count_nonzero(p > 0)),
        "total_force": float(p.sum() * (peer.size / peer.n) ** 2),
        "finite": bool(np.isfinite(p).all()),
        "maxrss_mib": _maxrss_mib(),
        **out,
    }


def serve() -> int:
    cache: dict = {}
    for line in sys.stdin:
        line = line.strip()
        if not line:
            continue
        try:
            req = json.loads(line)
            if req.get("cmd") == "quit":
                break
            if req.get("cmd") == "probe":
                ans = probe()
            else:
                ans = handle(req, cache)
        except Exception as exc:  # answer, don't die: the caller records it
            ans = {
                "error": f"{type(exc).__name__}: {exc}",
                "traceback": traceback.format_exc(limit=5),
            }
        sys.stdout.write(json.dumps(ans) + "\n")
        sys.stdout.flush()
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    group = ap.add_mutually_exclusive_group(required=True)
    group.add_argument(
        "--probe", action="store_true", help="print which peers import (JSON) and exit"
    )
    group.add_argument(
        "--serve",
        action="store_true",
        help="answer JSON requests, one per line, on stdin",
    )
    args = ap.parse_args(argv)
    if args.probe:
        print(json.dumps(probe()))
        return 0
    return serve()


if __name__ == "__main__":
    sys.exit(main())
