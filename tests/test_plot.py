"""`jaxcontact.plot`: every figure renders to a non-empty PNG from a small real
solution, and the plotted data are the solution's values."""

import jax.numpy as jnp
import numpy as np
import pytest

import jaxcontact as jc


matplotlib = pytest.importorskip("matplotlib")
import jaxcontact.plot as jplot  # noqa: E402


PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def small():
    """A viscoelastic load-unload cycle with a tangential displacement, 24 x 24 cells:
    stick at the first step, partial slip at steps 1-5, gross sliding at the last.
    Uncoupled (the plots do not care; its program compiles in about half the time of
    a coupled one)."""
    grid = jc.Grid(shape=(24, 24), size=(3e-3, 3e-3))
    material = jc.Zener(mu_inf=1.93e6, mu_0=1.93e6 / 4, tau=0.01, poisson=0.3)
    times = jnp.linspace(0.0, 0.02, 7)
    load = 0.15 * jnp.asarray([0.3, 0.65, 1.0, 0.8, 0.6, 0.4, 0.2])
    scene = jc.Scene(
        grid=grid,
        indenter=jc.Sphere(radius=10e-3),
        material=material,
        times=times,
        normal=jc.Force(load),
        x=jc.Displacement(jnp.linspace(0.0, 8e-6, 7)),
        y=None,
        friction=0.3,
        coupling="none",
        slip="incremental",
    )
    sol = jc.solve(scene)
    assert bool(np.all(sol.converged))
    ratio = np.asarray(sol.stick_ratio)
    assert ratio[0] == 1 and ((ratio[1:6] > 0) & (ratio[1:6] < 1)).all()
    assert bool(sol.sliding[-1]) and ratio[-1] == 0
    hertz = jc.Hertz(
        radius=jnp.asarray(10e-3),
        force=jnp.asarray(0.15),
        shear_modulus=jnp.asarray(1.93e6),
        poisson=jnp.asarray(0.3),
    )
    return grid, sol, (float(hertz.contact_radius), float(hertz.peak_pressure))


def _assert_png(path):
    data = path.read_bytes()
    assert len(data) > 1000 and data[:8] == PNG_MAGIC


def test_profiles(small, tmp_path):
    grid, sol, (a0, p0) = small
    path = tmp_path / "profiles.png"
    fig = jplot.profiles(
        sol, grid, times=[0.0, 0.02 / 3, 0.02], normalise=(a0, p0), path=path
    )
    _assert_png(path)
    axp, axq = fig.axes[:2]
    assert len(axp.lines) == 3 and len(axq.lines) == 3
    # even n: the centre line is the mean of the two central columns
    p_line = 0.5 * (
        np.asarray(sol.pressure[2, :, 11]) + np.asarray(sol.pressure[2, :, 12])
    )
    q_line = 0.5 * (
        np.asarray(sol.shear[2, 0, :, 11]) + np.asarray(sol.shear[2, 0, :, 12])
    )
    np.testing.assert_allclose(axp.lines[1].get_xdata(), np.asarray(grid.x) / a0)
    np.testing.assert_allclose(axp.lines[1].get_ydata(), p_line / p0, rtol=1e-12)
    np.testing.assert_allclose(axq.lines[1].get_ydata(), q_line / p0, rtol=1e-12)
    # along y the line at x = 0 is the mean of the two central rows
    fig = jplot.profiles(sol, grid, indices=[-1], axis="y")
    p_row = 0.5 * (np.asarray(sol.pressure[-1, 11]) + np.asarray(sol.pressure[-1, 12]))
    np.testing.assert_allclose(fig.axes[0].lines[0].get_ydata(), p_row, rtol=1e-12)


def test_stick_slip_maps(small, tmp_path):
    grid, sol, (a0, p0) = small
    path = tmp_path / "map.png"
    fig = jplot.stick_slip_map(sol, 3, grid, normalise=(a0, p0), path=path)
    _assert_png(path)
    image = np.asarray(fig.axes[0].images[0].get_array()).T
    contact, stick = np.asarray(sol.contact[3]), np.asarray(sol.stick[3])
    np.testing.assert_array_equal(image == 2, stick & contact)
    np.testing.assert_array_equal(image == 1, contact & ~stick)
    np.testing.assert_array_equal(image == 0, ~contact)
    # the map's stick fraction is the solution's stick ratio
    assert (
        abs((image == 2).sum() / max((image > 0).sum(), 1) - float(sol.stick_ratio[3]))
        < 1e-12
    )
    path = tmp_path / "maps.png"
    fig = jplot.stick_slip_maps(sol, [1, 3, 5], path=path)
    _assert_png(path)
    assert len(fig.axes) == 3


def test_loads_and_load_indentation(small, tmp_path):
    grid, sol, _ = small
    path = tmp_path / "loads.png"
    fig = jplot.loads(sol, path=path)
    _assert_png(path)
    np.testing.assert_allclose(fig.axes[0].lines[0].get_ydata(), sol.normal_force)
    np.testing.assert_allclose(
        fig.axes[1].lines[0].get_ydata(), sol.tangential_force[:, 0]
    )
    np.testing.assert_allclose(fig.axes[2].lines[0].get_ydata(), sol.stick_ratio)
    np.testing.assert_allclose(fig.axes[3].lines[0].get_ydata(), sol.approach)
    path = tmp_path / "loop.png"
    fig = jplot.load_indentation(sol, path=path)
    _assert_png(path)
    line = fig.axes[0].lines[0]
    np.testing.assert_allclose(line.get_xdata(), sol.approach)
    np.testing.assert_allclose(line.get_ydata(), sol.normal_force)
    # viscoelastic hysteresis: at equal load (0.6 W on the way down vs 0.65 W on the
    # way up) the approach is larger on unloading
    assert float(sol.approach[4]) > float(sol.approach[1])


def test_subsurface_map(tmp_path):
    n = 16
    grid = jc.Grid(shape=(n, n), size=(3.0, 3.0))
    x, y = grid.coordinates()
    p = jnp.sqrt(jnp.clip(1 - x * x - y * y, 0.0, None))
    stress = jc.subsurface_stress(
        grid,
        p,
        jnp.stack([0.3 * p, 0 * p]),
        poisson=0.3,
        depth=jnp.linspace(0.0, 1.5, 7),
    )
    path = tmp_path / "vm.png"
    fig = jplot.subsurface(grid, stress, "von_mises", normalise=(1.0, 1.0), path=path)
    _assert_png(path)
    field = jplot.subsurface_field(stress, "von_mises")
    expected = 0.5 * (
        np.asarray(stress.von_mises[:, :, 7]) + np.asarray(stress.von_mises[:, :, 8])
    )
    np.testing.assert_allclose(field, expected, rtol=1e-12)
    assert fig.axes[0].yaxis_inverted()
    jplot.subsurface(grid, stress, "sxz", axis="y", path=tmp_path / "sxz.png")
    _assert_png(tmp_path / "sxz.png")


def test_draw_into_given_axes(small):
    from matplotlib.figure import Figure

    grid, sol, _ = small
    fig = Figure()
    ax = fig.subplots()
    assert jplot.load_indentation(sol, ax=ax) is fig
    with pytest.raises(ValueError, match="ax must be 2"):
        jplot.profiles(sol, grid, ax=ax)


def test_bad_input(small):
    grid, sol, _ = small
    with pytest.raises(ValueError, match="axis"):
        jplot.profiles(sol, grid, axis="z")
    with pytest.raises(ValueError, match="normalise"):
        jplot.profiles(sol, grid, normalise=(1.0, -2.0))
    with pytest.raises(ValueError, match="index"):
        jplot.stick_slip_map(sol, 99)
    with pytest.raises(TypeError, match="jc.Solution"):
        jplot.loads(grid)
    stress = jc.subsurface_stress(grid, sol.pressure[0], poisson=0.3, depth=1e-4)
    with pytest.raises(ValueError, match="several depths"):
        jplot.subsurface(grid, stress)
    with pytest.raises(ValueError, match="which"):
        jplot.subsurface(grid, stress, which="tresca")
