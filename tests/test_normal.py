"""Normal contact: Hertz validation, convergence, invariants, control modes, bad
input."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxcontact as jc


R, W, G, NU = 10e-3, 0.15, 1e6, 0.3
HERTZ = jc.Hertz(R, W, G, NU)
A_HZ = float(HERTZ.contact_radius)


def hertz_solve(n, *, width=4.0, periodic=False, dtype=jnp.float64, **kwargs):
    grid = jc.Grid((n, n), jnp.asarray(width * A_HZ, dtype), periodic=periodic)
    material = jc.Elastic(jnp.asarray(G, dtype), jnp.asarray(NU, dtype))
    sol = jc.solve_normal(
        grid, jc.Sphere(jnp.asarray(R, dtype)), material, force=jnp.asarray(W, dtype),
        **kwargs
    )
    return grid, sol


def contact_radius_along_axes(grid, contact):
    """Half the extent of the contact along the x and y axes through the centre
    [length]."""
    dx, dy = (float(d) for d in grid.spacing)
    nx, ny = grid.shape
    along_x = (np.asarray(contact)[:, ny // 2 - 1 : ny // 2 + 1].any(axis=1).sum()
               * dx / 2)
    along_y = (np.asarray(contact)[nx // 2 - 1 : nx // 2 + 1, :].any(axis=0).sum()
               * dy / 2)
    return along_x, along_y


def test_hertz_128():
    grid, sol = hertz_solve(128)
    assert bool(sol.converged)
    dx = float(grid.spacing[0])
    # Peak pressure, approach: 1 % (32 cells per contact radius).
    assert abs(float(sol.pressure.max()) / float(HERTZ.peak_pressure) - 1) < 1e-2
    assert abs(float(sol.approach) / float(HERTZ.approach) - 1) < 1e-2
    # Contact radius within one cell, along both axes and from the contact area.
    for a_num in contact_radius_along_axes(grid, sol.contact):
        assert abs(a_num - A_HZ) <= dx
    a_area = np.sqrt(float(jnp.sum(sol.contact)) * float(grid.cell_area) / np.pi)
    assert abs(a_area - A_HZ) <= dx
    # Pressure profile: within 2 % of p0 away from the edge (the square-root edge is
    # where a piecewise-constant pressure is least accurate), 6 % everywhere.
    x, y = grid.coordinates()
    r = np.hypot(np.asarray(x), np.asarray(y))
    ref = np.asarray(HERTZ.pressure(r))
    err = np.abs(np.asarray(sol.pressure) - ref) / float(HERTZ.peak_pressure)
    assert err[r < 0.9 * A_HZ].max() < 2e-2
    assert err.max() < 6e-2


def test_mesh_convergence_order():
    sizes = [32, 64, 128]
    errors = []
    for n in sizes:
        _, sol = hertz_solve(n)
        errors.append(abs(float(sol.approach) / float(HERTZ.approach) - 1))
    orders = np.log2(np.asarray(errors[:-1]) / np.asarray(errors[1:]))
    print(f"approach errors {errors}, observed orders {orders}")
    assert all(e1 > e2 for e1, e2 in zip(errors, errors[1:]))
    assert orders.min() > 0.8


def test_invariants_load_balance_complementarity():
    grid, sol = hertz_solve(64)
    p, g = np.asarray(sol.pressure), np.asarray(sol.gap)
    assert abs(float(sol.normal_force) / W - 1) < 1e-12
    scale = float(HERTZ.approach)
    assert p.min() >= 0
    assert g.min() >= -1e-7 * scale
    # Complementarity: in contact the gap vanishes to solver tolerance.
    assert np.abs(g[p > 0]).max() < 1e-6 * scale
    assert np.abs(p * g).max() < 1e-6 * scale * p.max()
    assert float(sol.residual) <= 1e-8


def test_load_and_displacement_control_agree():
    grid, sol_lc = hertz_solve(64)
    material = jc.Elastic(G, NU)
    sol_dc = jc.solve_normal(grid, jc.Sphere(R), material, approach=sol_lc.approach)
    assert bool(sol_dc.converged)
    assert abs(float(sol_dc.normal_force) / W - 1) < 1e-6
    np.testing.assert_allclose(sol_dc.pressure, sol_lc.pressure,
                               atol=1e-6 * float(HERTZ.peak_pressure))
    assert np.array_equal(np.asarray(sol_dc.contact), np.asarray(sol_lc.contact))


def test_periodic_small_sphere_matches_non_periodic():
    # The same cells: a sphere loaded in the middle of a periodic cell 8 contact radii
    # wide. Periodic images change the approach (the mean displacement is arbitrary)
    # but barely the pressure.
    _, iso = hertz_solve(96, width=8.0)
    _, per = hertz_solve(96, width=8.0, periodic=True)
    assert bool(per.converged)
    p0 = float(HERTZ.peak_pressure)
    diff = np.abs(np.asarray(per.pressure) - np.asarray(iso.pressure)).max() / p0
    print(f"periodic vs isolated max pressure difference / p0 = {diff:.2e}")
    assert diff < 1.5e-2
    assert abs(float(per.normal_force) / W - 1) < 1e-12


def test_zero_load_gives_zero_pressure():
    grid, sol = hertz_solve(32)
    grid = jc.Grid((32, 32), 4 * A_HZ)
    sol = jc.solve_normal(grid, jc.Sphere(R), jc.Elastic(G, NU), force=0.0)
    assert bool(sol.converged)
    assert float(jnp.abs(sol.pressure).max()) == 0.0
    assert np.isfinite(float(sol.approach))


def test_no_interference_under_displacement_control():
    grid = jc.Grid((32, 32), 4 * A_HZ)
    sol = jc.solve_normal(grid, jc.Sphere(R), jc.Elastic(G, NU), approach=-1e-6)
    assert bool(sol.converged)
    assert float(jnp.abs(sol.pressure).max()) == 0.0


def test_rough_surface_many_islands():
    key = jax.random.PRNGKey(0)
    n = 64
    noise = jax.random.normal(key, (n, n))
    k = jnp.fft.fftfreq(n)
    filt = 1 / (1e-2 + k[:, None] ** 2 + k[None, :] ** 2)
    heights = jnp.fft.ifft2(jnp.fft.fft2(noise) * filt).real
    heights = 1e-6 * (heights - heights.min()) / (heights.max() - heights.min())
    grid = jc.Grid((n, n), 1e-3, periodic=True)
    sol = jc.solve_normal(grid, heights, jc.Elastic(G, NU), force=0.05)
    assert bool(sol.converged)
    assert abs(float(sol.normal_force) / 0.05 - 1) < 1e-12
    g = np.asarray(sol.gap)
    assert g.min() >= -1e-6 * 1e-6
    assert np.isfinite(np.asarray(sol.pressure)).all()


# The contact (a ~ 0.64 mm) overflows the 1 x 0.8 mm grid: irrelevant to what this test
# checks (no recompilation), so the EdgeContactWarning is expected and ignored here.
@pytest.mark.filterwarnings("ignore::jaxcontact.EdgeContactWarning")
def test_second_call_does_not_recompile(monkeypatch):
    traces = []
    original = jc.PolonskyKeer.setup  # once a trace of the solve

    def counting(*args, **kwargs):
        traces.append(1)
        return original(*args, **kwargs)

    monkeypatch.setattr(jc.PolonskyKeer, "setup", counting)
    grid = jc.Grid((24, 20), (1e-3, 0.8e-3))
    op = jc.HalfSpace(grid)
    jc.solve_normal(grid, jc.Sphere(1e-2), jc.Elastic(1e6, 0.3), force=0.1, operator=op)
    assert len(traces) == 1
    sol = jc.solve_normal(
        grid, jc.Sphere(2e-2), jc.Elastic(3e6, 0.25), force=0.3, operator=op
    )
    assert len(traces) == 1
    assert bool(sol.converged)
    # A new grid size (a value, not a shape) does not recompile either.
    grid2 = jc.Grid((24, 20), (2e-3, 1.6e-3))
    jc.solve_normal(grid2, jc.Sphere(1e-2), jc.Elastic(1e6, 0.3), force=0.1)
    assert len(traces) == 1


def test_float32():
    grid, sol = hertz_solve(64, dtype=jnp.float32)
    assert sol.pressure.dtype == jnp.float32
    assert bool(sol.converged)
    _, sol64 = hertz_solve(64)
    rel = float(jnp.abs(sol.pressure - sol64.pressure).max() / sol64.pressure.max())
    # float32 default rtol 1e-5: pressure within 2e-3 of float64 (measured 7e-4).
    assert rel < 2e-3


def test_the_grid_dtype_is_the_solve_dtype():
    """A float32 grid with Python-float (float64 under x64) indenter, material and
    load solves in float32, as `jc.solve` does: the same pressure (the same rtol 1e-5,
    the same iterations) as with every input in float32. It used to promote to float64
    (and rtol 1e-8)."""
    grid = jc.Grid((32, 32), jnp.asarray(4.0 * A_HZ, jnp.float32))
    mixed = jc.solve_normal(grid, jc.Sphere(R), jc.Elastic(G, NU), force=W)
    _, pure = hertz_solve(32, dtype=jnp.float32)
    assert mixed.pressure.dtype == jnp.float32
    assert int(mixed.iterations) == int(pure.iterations)
    rel = float(jnp.abs(mixed.pressure - pure.pressure).max() / pure.pressure.max())
    assert rel <= 1e-5, rel
    scene = jc.Scene(grid, jc.Sphere(R), jc.Elastic(G, NU), jnp.zeros(1), jc.Force(W))
    assert jc.solve(scene).pressure.dtype == jnp.float32


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: jc.Elastic(0.0, 0.3), "shear_modulus"),
        (lambda: jc.Elastic(-1.0, 0.3), "shear_modulus"),
        (lambda: jc.Elastic(1.0, 0.6), "poisson"),
        (lambda: jc.Elastic(1.0, -1.0), "poisson"),
        (lambda: jc.Grid((32, 32), 0.0), "size"),
        (lambda: jc.Grid((32, 32), (1.0, float("nan"))), "size"),
        (lambda: jc.Grid((1, 32), 1.0), "shape"),
        (lambda: jc.Sphere(-1.0), "radius"),
        (lambda: jc.Surface(jnp.full((4, 4), jnp.nan)), "heights"),
    ],
)
def test_bad_input_constructors(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_bad_input_solve():
    grid = jc.Grid((16, 16), 1e-3)
    mat = jc.Elastic(1e6, 0.3)
    with pytest.raises(ValueError, match="force"):
        jc.solve_normal(grid, jc.Sphere(1e-2), mat, force=-1.0)
    with pytest.raises(ValueError, match="exactly one"):
        jc.solve_normal(grid, jc.Sphere(1e-2), mat)
    with pytest.raises(ValueError, match="heights"):
        jc.solve_normal(grid, np.full((16, 16), np.nan), mat, force=1.0)
    with pytest.raises(ValueError, match="shape"):
        jc.solve_normal(grid, np.zeros((8, 8)), mat, force=1.0)


def test_traced_bad_value_raises_at_run_time():
    @jax.jit
    def make(g):
        return jc.Elastic(g, 0.3).shear_modulus

    assert float(make(2.0)) == 2.0
    with pytest.raises(Exception, match="shear_modulus"):
        make(-2.0).block_until_ready()


def test_elastic_material_functions():
    mat = jc.Elastic(2.0, 0.3)
    t = jnp.linspace(0, 5, 6)
    np.testing.assert_allclose(mat.relaxation(t), 2.0)
    np.testing.assert_allclose(mat.creep(t), 0.5)
    assert float(mat.instantaneous_compliance) == 0.5


@pytest.mark.parametrize("case", ["load", "approach", "periodic", "rough"])
def test_preconditioned_matches_plain_in_fewer_iterations(case):
    # The full-plane-inverse preconditioner changes the path, not the solution: both
    # solves meet rtol 1e-10, so their pressures agree to ~1e-8 of the peak (stated
    # tolerance 1e-7), with at most half the CG iterations (measured at 64^2, plain vs
    # preconditioned: load 19 vs 6, approach 55 vs 27, periodic 26 vs 9, rough 34 vs
    # 10).
    n = 64
    periodic = case == "periodic"
    grid = jc.Grid((n, n), 4 * A_HZ, periodic=periodic)
    indenter = jc.Sphere(R)
    target = dict(force=W)
    if case == "approach":
        target = dict(approach=float(HERTZ.approach))
    if case == "rough":
        rng = np.random.default_rng(3)
        heights = rng.standard_normal((n, n)) * 1e-7
        x, y = grid.coordinates()
        indenter = jnp.asarray((x * x + y * y) / (2 * R) + heights)
    sols = {}
    for precondition in (False, True):
        solver = jc.PolonskyKeer(rtol=1e-10, precondition=precondition)
        sols[precondition] = jc.solve_normal(
            grid, indenter, jc.Elastic(G, NU), solver=solver, **target)
        assert bool(sols[precondition].converged)
    plain, pre = sols[False], sols[True]
    peak = float(plain.pressure.max())
    np.testing.assert_allclose(pre.pressure, plain.pressure, atol=1e-7 * peak)
    assert abs(float(pre.normal_force) / float(plain.normal_force) - 1) < 1e-7
    print(f"{case}: iterations plain {int(plain.iterations)}, preconditioned "
          f"{int(pre.iterations)}")
    assert 2 * int(pre.iterations) <= int(plain.iterations)


@pytest.mark.parametrize("width", [2.3, 4.0])
def test_unpadded_preconditioner_raised_to_the_continuum(width):
    # `jc.solve_normal` preconditions on the UNPADDED grid (a quarter of the padded
    # transform) with the wrapped spectrum raised to Boussinesq's continuous symbol.
    # Same solution as the padded inverse (both to rtol 1e-10: pressures within 1e-7
    # of the peak), in no more iterations; on a contact filling most of the grid the
    # wrapped spectrum alone needs more (measured at 48^2: over 2.3 a padded 15,
    # wrapped 19, raised 14; over 4 a 19, 21, 18).
    from jaxcontact._solver.normal import inverse_preconditioner, polonsky_keer
    from jaxcontact._solver.precondition import unpadded_inverse

    n = 48
    grid = jc.Grid((n, n), width * A_HZ)
    op = jc.HalfSpace(grid, "none")
    spectrum = op.normal_spectrum(NU)
    symbol = spectrum / G

    def apply(p):
        return op.inverse(op.forward(p) * symbol)

    preconditioners = dict(
        padded=inverse_preconditioner(op, spectrum),
        wrapped=unpadded_inverse(grid, spectrum),
        raised=inverse_preconditioner(op, spectrum, NU),
    )
    sols = {
        name: polonsky_keer(apply, jc.Sphere(R).gap(grid), W, grid.cell_area,
                            load_control=True, rtol=1e-10, max_steps=200,
                            self_compliance=op.diagonal(symbol), precondition=pc)
        for name, pc in preconditioners.items()
    }
    assert all(bool(s.converged) for s in sols.values())
    peak = float(sols["padded"].pressure.max())
    np.testing.assert_allclose(sols["raised"].pressure, sols["padded"].pressure,
                               atol=1e-7 * peak)
    its = {name: int(s.iterations) for name, s in sols.items()}
    print(f"width {width} a: iterations {its}")
    assert its["raised"] <= its["padded"]
    if width < 3:
        assert its["raised"] + 3 <= its["wrapped"]



def test_a_solve_that_does_not_converge_raises_unless_throw_is_false():
    """As `jc.solve`: a normal solve that stops at `max_steps` above its tolerance
    raises its `jc.RESULTS` message (and, concrete, the residual and the way out), at
    once for concrete inputs and at run time under `jit`; `throw=False` returns it
    flagged (`result`: `max_steps_reached`). (A displacement-controlled
    Hertz solve from p = 0 needs more than one iteration to reach rtol 1e-12.)"""
    stuck = jc.PolonskyKeer(rtol=1e-12, max_steps=1)
    grid = jc.Grid((32, 32), 4 * A_HZ)
    material = jc.Elastic(G, NU)
    delta = float(jc.Hertz(R, W, G, NU).approach)
    with pytest.raises(ValueError, match=r"did not converge.*max_steps=1.*throw=False"):
        jc.solve_normal(grid, jc.Sphere(R), material, approach=delta, solver=stuck)
    sol = jc.solve_normal(grid, jc.Sphere(R), material, approach=delta, solver=stuck,
                          throw=False)
    assert not bool(sol.converged) and int(sol.iterations) == 1
    assert float(sol.residual) > 1e-12
    assert sol.result == jc.RESULTS.max_steps_reached

    @jax.jit
    def traced(d):
        return jc.solve_normal(grid, jc.Sphere(R), material, approach=d,
                               solver=stuck).approach

    with pytest.raises(Exception, match="maximum number of solver steps"):
        jax.block_until_ready(traced(delta))  # jc.RESULTS' message, as jc.solve's
    converges = jax.jit(lambda d: jc.solve_normal(
        grid, jc.Sphere(R), material, approach=d).approach)
    assert abs(float(converges(delta)) - delta) == 0.0  # the approach is prescribed
    ok = jc.solve_normal(grid, jc.Sphere(R), material, approach=delta)
    assert ok.result == jc.RESULTS.successful
    with pytest.raises(TypeError, match="throw must be a bool"):
        jc.solve_normal(grid, jc.Sphere(R), material, approach=delta, throw="no")

def rough_sphere(n):
    """`benchmarks/aspher_peer.py`'s rough sphere on `n x n` cells: (grid, surface,
    material, force); about 4 % of the cells in contact, in many islands."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import aspher_peer as peer

    return (jc.Grid((n, n), peer.SIZE), jc.Surface(jnp.asarray(peer.gap_field(n))),
            jc.Elastic(peer.SHEAR, peer.NU), peer.FORCE)


def test_nested_start_changes_the_path_not_the_solution():
    # The nested start (a solve on 128^2 first, its pressure repeated 2 x 2) and the
    # default Hertzian / local-interference start meet the same rtol 1e-8, so their
    # pressures agree to what that tolerance gives (measured 1e-7 from a rtol 1e-10
    # solve at 256^2); under displacement control the fine grid needs about half the
    # operator applications (measured 80 -> 40; bound 0.7x).
    grid, surface, material, force = rough_sphere(256)
    solver = jc.PolonskyKeer(rtol=1e-8)
    by_load = {start: jc.solve_normal(grid, surface, material, force=force,
                                      solver=solver, start=start)
               for start in ("hertz", "nested")}
    delta = by_load["hertz"].approach
    by_approach = {start: jc.solve_normal(grid, surface, material, approach=delta,
                                          solver=solver, start=start)
                   for start in ("hertz", "nested")}
    for sols in (by_load, by_approach):
        a, b = sols["hertz"].pressure, sols["nested"].pressure
        assert float(jnp.linalg.norm(a - b) / jnp.linalg.norm(a)) < 1e-6
    assert abs(float(by_approach["nested"].normal_force) / force - 1) < 1e-6
    assert (int(by_approach["nested"].applications)
            <= 0.7 * int(by_approach["hertz"].applications))
    # "auto" is "nested" on this grid: the same program's answer; for a sphere under
    # load control it keeps the Hertzian guess (nearly the answer there).
    auto = jc.solve_normal(grid, surface, material, force=force, solver=solver)
    assert int(auto.iterations) == int(by_load["nested"].iterations)
    sphere = {start: jc.solve_normal(grid, jc.Sphere(10e-3), material, force=force,
                                     solver=solver, start=start)
              for start in ("auto", "hertz")}
    assert int(sphere["auto"].iterations) == int(sphere["hertz"].iterations)


def test_nested_start_bad_input():
    mat = jc.Elastic(1e6, 0.3)
    with pytest.raises(ValueError, match="start must be one of"):
        jc.solve_normal(jc.Grid((16, 16), 1e-3), jc.Sphere(1e-2), mat, force=1.0,
                        start="coarse")
    for shape in ((200, 200), (256, 255), (128, 128)):
        with pytest.raises(ValueError, match=rf"got shape \({shape[0]}, {shape[1]}\)"):
            jc.solve_normal(jc.Grid(shape, 1e-3), jc.Sphere(1e-2), mat, force=1.0,
                            start="nested")


@pytest.mark.slow
def test_rough_sphere_from_the_hertzian_guess_converges_on_a_fine_grid():
    """The rough sphere of benchmarks/aspher_peer.py at 1024^2 (about 4 % of the grid
    in contact, in many islands 14+ cells per shortest wavelength): from the Hertzian
    guess (8.7 % of the cells) the preconditioned CG once re-entered whole patches of
    penetrating cells each with its own local closure, overshot, and stalled at a
    residual ~0.3 for 2000 iterations (n >= 896; 768 converged in 38). Penetrating
    cells now join the step's direction: 31 iterations to rtol 1e-6 (measured); the
    bound leaves 2x. The answer agrees with a tight (rtol 1e-10) solve to what rtol
    1e-6 gives on this scene."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import aspher_peer as peer

    n = 1024
    grid = jc.Grid((n, n), peer.SIZE)
    surface = jc.Surface(jnp.asarray(peer.gap_field(n)))
    material = jc.Elastic(peer.SHEAR, peer.NU)
    sol = jc.solve_normal(grid, surface, material, force=peer.FORCE,
                          solver=jc.PolonskyKeer(rtol=1e-6, max_steps=200),
                          start="hertz")
    assert bool(sol.converged)
    assert int(sol.iterations) <= 62
    fraction = float(jnp.mean(sol.pressure > 0))
    assert 0.035 < fraction < 0.045  # the converged contact (0.0401), not the guess
    tight = jc.solve_normal(grid, surface, material, force=peer.FORCE,
                            solver=jc.PolonskyKeer(rtol=1e-10, max_steps=400))
    assert bool(tight.converged)
    err = float(jnp.linalg.norm(sol.pressure - tight.pressure)
                / jnp.linalg.norm(tight.pressure))
    assert err < 1e-4  # 2.0e-5 measured (benchmarks/results/gpu/h200.json)


@pytest.mark.parametrize("case", ["rough", "periodic_plain"])
def test_mixed_precision_answers_in_float64(case):
    # A float64 solve applies the operator in float32 while its residual is above 1e-5
    # and certifies in float64: the returned displacement is the float64 convolution
    # of the returned pressure (a float32 application is off by ~1e-8 of max |u|;
    # stated 1e-12), the pressure meets rtol 1e-10 like the float64-only solve (the
    # two within 1e-7 of the peak), and it costs at most 2 more iterations (measured:
    # rough 0, periodic_plain 1: the case whose stale conjugacy once stalled).
    n = 64
    periodic = case == "periodic_plain"
    grid = jc.Grid((n, n), 4 * A_HZ, periodic=periodic)
    indenter = jc.Sphere(R)
    if case == "rough":
        heights = np.random.default_rng(3).standard_normal((n, n)) * 1e-7
        x, y = grid.coordinates()
        indenter = jnp.asarray((x * x + y * y) / (2 * R) + heights)
    sols = {}
    for mixed in (False, True):
        solver = jc.PolonskyKeer(rtol=1e-10, precondition=not periodic,
                                 mixed_precision=mixed)
        sols[mixed] = jc.solve_normal(grid, indenter, jc.Elastic(G, NU), force=W,
                                      solver=solver)
        assert float(sols[mixed].residual) <= 1e-10
    plain, mixed = sols[False], sols[True]
    u = jc.HalfSpace(grid).apply_normal(mixed.pressure, NU) / G
    scale = float(jnp.abs(u).max())
    np.testing.assert_allclose(mixed.displacement, u, rtol=0, atol=1e-12 * scale)
    peak = float(plain.pressure.max())
    np.testing.assert_allclose(mixed.pressure, plain.pressure, rtol=0, atol=1e-7 * peak)
    assert int(mixed.iterations) <= int(plain.iterations) + 2


def test_operators_are_cached_and_concrete_under_jit():
    # `jc.solve_normal` keeps the HalfSpace of a concrete grid (and of the nested
    # start's coarse grids) in a cache. Built under a jit (the grid closed over), the
    # cached spectra must be concrete arrays, not that trace's tracers: a later eager
    # solve on the same grid reuses them (a leaked tracer would raise).
    from jaxcontact import _solve_normal

    grid = jc.Grid((256, 256), 4 * A_HZ)
    mat = jc.Elastic(G, NU)
    _solve_normal._cached_operator.cache_clear()

    @jax.jit
    def force(load):
        return jc.solve_normal(grid, jc.Sphere(R), mat, force=load, start="nested",
                               solver=jc.PolonskyKeer(rtol=1e-8)).normal_force

    np.testing.assert_allclose(float(force(W)), W, rtol=1e-10)
    built = _solve_normal._cached_operator.cache_info()
    assert built.currsize == 2  # the 256^2 grid and its 128^2 level
    cached = _solve_normal.normal_operator(grid)  # a cache hit
    assert not isinstance(cached.spectra["zz"], jax.core.Tracer)
    sol = jc.solve_normal(grid, jc.Sphere(R), mat, force=W, start="nested",
                          solver=jc.PolonskyKeer(rtol=1e-8))
    assert _solve_normal._cached_operator.cache_info().hits == built.hits + 3
    np.testing.assert_allclose(float(sol.normal_force), W, rtol=1e-10)
