"""Shared test helpers: scene factories, conversions and checkers used by several test
files (`from helpers import ...`: pytest puts tests/ on sys.path, as for
reference_dense).

Units are SI unless stated. The defaults of the factories are the parameters of the
elastic partial-slip checks (test_partial_slip.py, test_joint.py: rigid sphere
R = 10 mm, G = 1 MPa, nu = 0.3, W = 0.15 N) and of the paper's Table 2 Zener solid
(test_viscoelastic.py, test_sweep.py: mu_inf = 1.93 MPa true shear modulus,
tau = 0.01 s, nu = 0.3). A test file that uses other values passes them explicitly.
"""

import jax
import numpy as np

import jaxcontact as jc


SOLVE_RTOL = 1e-8  # jc.solve's default rtol in float64

# The elastic partial-slip scene (the paper's elastic checks).
SPHERE_R = 10e-3  # m
ELASTIC_G = 1e6  # Pa, true shear modulus
ELASTIC_NU = 0.3
LOAD_W = 0.15  # N

# The paper's Table 2 Zener solid, in TRUE shear moduli (the table lists 2 G).
ZENER_MU_INF = 3.86e6 / 2  # Pa, instantaneous modulus G(0)
ZENER_TAU = 0.01  # s, RETARDATION time (paper Eq. 30)
ZENER_NU = 0.3


# ---- factories -----------------------------------------------------------------------


def hertz_radius(nu=ELASTIC_NU, w=LOAD_W, *, radius=SPHERE_R, g=ELASTIC_G):
    """Hertz contact radius [m] of a rigid sphere of `radius` [m] pressed with the
    force `w` [N] onto an elastic half-space of shear modulus `g` [Pa] and Poisson's
    ratio `nu` (`jc.Hertz(radius, w, g, nu).contact_radius`, as a Python float)."""
    return float(jc.Hertz(radius, w, g, nu).contact_radius)


def zener(mu_0=None, nu=ZENER_NU, *, ratio=None):
    """The paper's Table 2 Zener solid (Eqs. 29-30): mu_inf = 1.93 MPa [Pa, true shear
    modulus], tau = 0.01 s (retardation time), Poisson's ratio `nu`.

    The relaxed modulus is `mu_0` [Pa], or `mu_inf / ratio` when `ratio` (= mu_inf /
    mu_0 >= 1) is given by keyword instead (exactly one of the two). `mu_0` is the
    first positional argument so that `jax.vmap(zener)` builds a batch of materials."""
    if (ratio is None) == (mu_0 is None):
        raise TypeError("give exactly one of mu_0 and ratio")
    if mu_0 is None:
        mu_0 = ZENER_MU_INF / ratio
    return jc.Zener(ZENER_MU_INF, mu_0, ZENER_TAU, nu)


# ---- conversions and measures --------------------------------------------------------


def as_np(tree):
    """The pytree (a solution, a step result) with every leaf a NumPy array."""
    return jax.tree_util.tree_map(np.asarray, tree)


def radii(grid):
    """Cell-centre coordinates of `grid` and their distance from the origin [length]:
    `(x, y, r)`, NumPy arrays of the grid's shape."""
    x, y = (np.asarray(c) for c in grid.coordinates())
    return x, y, np.hypot(x, y)


def equivalent_radius(mask, cell_area):
    """Radius [length] of the disc with the area of the cells in `mask`:
    `sqrt(count * cell_area / pi)`, `cell_area` [length^2]. The count runs over the last
    two axes: one radius per step for a `(nt, nx, ny)` mask, a scalar for `(nx, ny)`."""
    n = np.asarray(mask).sum(axis=(-2, -1))
    return np.sqrt(n * float(cell_area) / np.pi)


def radial_profile_error(grid, pressure, reference_fn):
    """Max |p - p_ref| over the grid, relative to max(p_ref)."""
    x, y = (np.asarray(c) for c in grid.coordinates())
    ref = np.asarray(reference_fn(np.hypot(x, y)))
    return np.max(np.abs(np.asarray(pressure) - ref)) / np.max(ref)


# ---- tolerances and checkers ---------------------------------------------------------


def same(n, rtol=SOLVE_RTOL):
    """Tolerance, relative to max p (and mu max p for the shear), between two solutions
    of one discrete problem on an n x n grid reached along different iteration paths:
    `2 rtol n` (each solution is within ~rtol * n of the exact discrete one; 6.4e-7 at
    n = 32, 1e-6 at n = 48, 1.3e-6 at n = 64 for rtol = 1e-8)."""
    return 2 * rtol * n


SOLUTION_FIELDS = ("pressure", "shear", "approach", "tangential_displacement")


def check_converged(sol, finite=()):
    """Assert that every step of `sol` (a `jc.Solution`) converged (`sol.converged` all
    true: jc.solve met its rtol; no numerical tolerance of its own), and that each field
    named in `finite` (e.g. `SOLUTION_FIELDS`) is finite everywhere. The failure message
    lists the steps that did not converge with their residual, iterations and rounds."""
    bad = np.flatnonzero(~np.asarray(sol.converged))
    assert bad.size == 0, (
        f"steps {bad.tolist()} not converged: "
        f"residual {np.asarray(sol.residual)[bad]}, "
        f"iterations {np.asarray(sol.iterations)[bad]}, "
        f"rounds {np.asarray(sol.rounds)[bad]}"
    )
    for name in finite:
        assert np.all(np.isfinite(getattr(sol, name))), name


def run_on_host_devices(code: str, devices: int, timeout: float = 600):
    """Run Python `code` in a fresh process with `devices` forced CPU devices
    (`--xla_force_host_platform_device_count`) and this checkout first on its path;
    returns the `subprocess.CompletedProcess` (stdout, stderr as text)."""
    import os
    import subprocess
    import sys

    flag = f"--xla_force_host_platform_device_count={devices}"
    env = dict(os.environ, XLA_FLAGS=flag, JAX_PLATFORMS="cpu")
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env["PYTHONPATH"] = os.pathsep.join([root, env.get("PYTHONPATH", "")])
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                          text=True, timeout=timeout)
