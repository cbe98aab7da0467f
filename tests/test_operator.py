"""Tests of `jc.HalfSpace`: the FFT half-space operator, tractions -> displacements.

References: a dense direct convolution built from `jc.influence_coefficients`
(`u[i](x_a) = sum_b sum_j C[i, j](x_a - x_b) t[j](x_b)`), symmetry and definiteness of
the operator matrix, and (periodic grids) the non-periodic operator near a compact load.
Traction order `(q_x, q_y, p)`, displacement order `(u_x, u_y, u_z)`, unit shear
modulus.
"""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxcontact as jc


POISSONS = (0.0, 0.3, 0.5, -0.4)
# Small non-periodic grids with non-square cells: dx = 0.2, dy = 0.12 and
# dx = 3.75e-4, dy = 2e-4 (SI-like magnitudes); 17x13 pads to 35 x 25, not 2n (34 and
# 26 have the prime factors 17 and 13: `_operator.padded_shape`).
GRIDS = {"7x5": ((7, 5), (1.4, 0.6)), "8x6": ((8, 6), (3e-3, 1.2e-3)),
         "17x13": ((17, 13), (1.7, 1.04))}
COUPLED = [(2, 0), (2, 1), (0, 2), (1, 2)]  # normal-tangential blocks (i, j)


# The library functions are jitted here only to keep the test fast (one compilation
# per shape instead of one per primitive); Poisson's ratio is a traced argument.
_influence = jax.jit(jc.influence_coefficients)
_apply = eqx.filter_jit(lambda op, traction, poisson: op.apply(traction, poisson))
_apply_normal = eqx.filter_jit(lambda op, p, poisson: op.apply_normal(p, poisson))


def dense_coefficients(grid, poisson):
    """`C[i, j, a, b]`: displacement i at cell a due to unit traction j on cell b."""
    x, y = (np.asarray(c, dtype=np.float64).ravel() for c in grid.coordinates())
    dx, dy = (float(s) for s in grid.spacing)
    C = _influence(x[:, None] - x[None, :], y[:, None] - y[None, :], dx, dy, poisson)
    return np.array(C)  # a writable copy


def dense_apply(C, traction):
    """Direct convolution with the dense coefficients, `(3, nx, ny) -> (3, nx, ny)`."""
    shape = traction.shape
    t = traction.reshape(3, -1)
    return np.einsum("ijab,jb->ia", C, t).reshape(shape)


@eqx.filter_jit
def _operator_matrix(op, poisson):
    shape = op.grid.shape
    n = 3 * shape[0] * shape[1]
    cols = jax.vmap(lambda e: op.apply(e.reshape((3,) + shape), poisson).reshape(-1))(
        jnp.eye(n)
    )
    return cols.T


def operator_matrix(op, poisson):
    """The operator as a dense `(3N, 3N)` matrix: applied to each unit vector."""
    return np.asarray(_operator_matrix(op, jnp.asarray(poisson)))


def rel_err(got, ref):
    return np.max(np.abs(np.asarray(got) - ref)) / np.max(np.abs(ref))


# --------------------------------------------------------------------------------------
# Non-periodic (DC-FFT) operator against the dense direct convolution
# --------------------------------------------------------------------------------------


MODES = [
    ("normal", True),
    ("none", True),
    ("none", False),
    ("x", True),
    ("full", True),
    ("full", False),
]


@pytest.mark.parametrize("grid_name", list(GRIDS))
@pytest.mark.parametrize(
    "coupling,tangential_y", MODES, ids=[f"{m}-y{t}" for m, t in MODES]
)
def test_apply_matches_dense_convolution(grid_name, coupling, tangential_y):
    """Every coupling mode equals the dense convolution with its blocks, to 1e-12.

    "normal": only u_z from p (u_x = u_y = 0). "none": no normal-tangential blocks.
    "x" (and tangential_y=False): q_y = 0 and u_y is not computed (zeros).
    Measured: <= 2e-15 relative to max |u|.
    """
    shape, size = GRIDS[grid_name]
    grid = jc.Grid(shape, size)
    op = jc.HalfSpace(grid, coupling, tangential_y=tangential_y)
    rng = np.random.default_rng(
        [list(GRIDS).index(grid_name), MODES.index((coupling, tangential_y))]
    )
    for poisson in POISSONS:
        C = dense_coefficients(grid, poisson)
        traction = rng.standard_normal((3,) + shape)
        if coupling == "normal":
            keep = np.zeros((3, 3), bool)
            keep[2, 2] = True
            C = C * keep[:, :, None, None]
        elif coupling == "none":
            for i, j in COUPLED:
                C[i, j] = 0.0
        has_y = tangential_y and coupling not in ("normal", "x")
        if not has_y:
            traction[1] = 0.0
        ref = dense_apply(C, traction)
        if not has_y:
            ref[1] = 0.0  # u_y is not computed
        got = np.asarray(_apply(op, jnp.asarray(traction), jnp.asarray(poisson)))
        assert got.shape == (3,) + shape
        assert rel_err(got, ref) < 1e-12, (poisson, rel_err(got, ref))
        if not has_y:
            assert np.all(got[1] == 0.0)
        if coupling == "normal":
            assert np.all(got[0] == 0.0)


@pytest.mark.parametrize("grid_name", list(GRIDS))
def test_apply_normal_matches_dense_convolution(grid_name):
    """`apply_normal` equals the dense zz convolution (1e-12) in every coupling mode."""
    shape, size = GRIDS[grid_name]
    grid = jc.Grid(shape, size)
    rng = np.random.default_rng(7)
    p = rng.uniform(0.0, 1.0, shape)
    for coupling in ("normal", "none", "full"):
        op = jc.HalfSpace(grid, coupling)
        for poisson in POISSONS:
            zz = dense_coefficients(grid, poisson)[2, 2]
            ref = (zz @ p.ravel()).reshape(shape)
            got = _apply_normal(op, jnp.asarray(p), jnp.asarray(poisson))
            assert rel_err(got, ref) < 1e-12


def test_padded_lengths_hold_the_linear_convolution_and_have_small_factors():
    """`padded_shape` gives `2n` or another length `>= 2n - 1` (what an exact linear
    convolution of `n` cells needs) with no prime factor above 7, at most 7 % above
    `2n` (measured: 6.2 % at most, n = 226 -> 480, for n < 5000)."""
    from jaxcontact._operator import padded_shape

    for n in range(2, 300):
        length = padded_shape((n, n))[0]
        assert 2 * n - 1 <= length <= 1.07 * 2 * n, (n, length)
        k = length
        for prime in (2, 3, 5, 7):
            while k % prime == 0:
                k //= prime
        assert k == 1, (n, length)
    assert padded_shape((113, 64)) == (225, 128)


@pytest.mark.parametrize("shape", [(8, 6), (17, 13), (11, 22)])
def test_preconditioner_kernel_is_the_dense_kernel_wrapped_modulo_its_grid(shape):
    """`precondition.wrapped_spectra` (the unpadded preconditioners' symbols) is the
    rfft2 of the dense zz coefficients wrapped modulo the preconditioner's periodic grid
    (`preconditioner_shape`: 8x6 itself; 17x13 and 11x22 padded to 18x14 and 12x24),
    summed here offset by offset, to 1e-12 of the largest mode."""
    from jaxcontact._solver.precondition import preconditioner_shape, wrapped_spectra

    grid = jc.Grid(shape, (0.1 * shape[0], 0.13 * shape[1]))
    mx, my = preconditioner_shape(grid)
    assert (mx, my) == {(8, 6): (8, 6), (17, 13): (18, 14), (11, 22): (12, 24)}[shape]
    op = jc.HalfSpace(grid, "normal")
    got = np.asarray(wrapped_spectra(grid, op.normal_spectrum(0.3)))
    zz = dense_coefficients(grid, 0.3)[2, 2].reshape(shape + shape)
    nx, ny = shape
    kernel = np.zeros((mx, my))
    for i in range(-(nx - 1), nx):
        for j in range(-(ny - 1), ny):
            a, b = (i, 0) if i >= 0 else (0, -i)
            c, d = (j, 0) if j >= 0 else (0, -j)
            kernel[i % mx, j % my] += zz[a, c, b, d]  # u at (a, c) from p at (b, d)
    ref = np.fft.rfft2(kernel).real
    assert got.shape == ref.shape
    assert rel_err(got, ref) < 1e-12, rel_err(got, ref)


def test_apply_under_jit_with_traced_poisson():
    """Jitted apply with a traced Poisson's ratio equals the eager result (1e-14)."""
    shape, size = GRIDS["8x6"]
    op = jc.HalfSpace(jc.Grid(shape, size), "full")
    t = jnp.asarray(np.random.default_rng(3).standard_normal((3,) + shape))
    apply = eqx.filter_jit(lambda op, t, nu: op.apply(t, nu))
    for poisson in (0.1, 0.45):
        eager = np.asarray(op.apply(t, poisson))
        jitted = apply(op, t, jnp.asarray(poisson))
        assert rel_err(jitted, eager) < 1e-14


@pytest.mark.parametrize("grid_name", list(GRIDS))
def test_full_operator_symmetric_positive_definite(grid_name):
    """The "full" operator matrix is symmetric (1e-13) and positive definite.

    Measured: asymmetry <= 2e-16 of max |A|; smallest eigenvalue >= 0.31 max |A| for
    nu in {0, 0.3, 0.5, -0.4} (lowest at nu = 0.5); we assert lambda_min > 0.1 max |A|.
    """
    shape, size = GRIDS[grid_name]
    op = jc.HalfSpace(jc.Grid(shape, size), "full")
    for poisson in POISSONS:
        A = operator_matrix(op, poisson)
        scale = np.max(np.abs(A))
        assert np.max(np.abs(A - A.T)) < 1e-13 * scale
        eigmin = np.linalg.eigvalsh(0.5 * (A + A.T))[0]
        assert eigmin > 0.1 * scale, (poisson, eigmin / scale)


@pytest.mark.parametrize("periodic", [False, True], ids=["dcfft", "periodic"])
def test_incompressible_full_equals_none(periodic):
    """For nu = 0.5 the coupling blocks vanish: "full" and "none" agree bit for bit."""
    shape, size = GRIDS["8x6"]
    grid = jc.Grid(shape, size, periodic=periodic)
    t = jnp.asarray(np.random.default_rng(11).standard_normal((3,) + shape))
    full_op, none_op = jc.HalfSpace(grid, "full"), jc.HalfSpace(grid, "none")
    full = np.asarray(full_op.apply(t, 0.5))
    none = np.asarray(none_op.apply(t, 0.5))
    np.testing.assert_array_equal(full, none)
    # ...whereas for nu = 0.3 they differ by a visible amount (> 1% of max |u|).
    full3 = np.asarray(full_op.apply(t, 0.3))
    none3 = np.asarray(none_op.apply(t, 0.3))
    assert rel_err(full3, none3) > 1e-2


# --------------------------------------------------------------------------------------
# Periodic operator
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("grid_name", list(GRIDS))
def test_periodic_operator_symmetric_semidefinite(grid_name):
    """Periodic "full" operator: symmetric (1e-13) and positive semi-definite.

    Its null space is the three uniform tractions (the mean displacement is set to
    zero): exactly three eigenvalues below 1e-12 max |A| in magnitude (measured
    <= 3e-15), and uniform tractions give zero displacement (1e-13). The others exceed
    0.1 max |A| (measured >= 0.36). Asymmetry measured <= 3e-16 of max |A|.
    """
    shape, size = GRIDS[grid_name]
    op = jc.HalfSpace(jc.Grid(shape, size, periodic=True), "full")
    for poisson in POISSONS:
        A = operator_matrix(op, poisson)
        scale = np.max(np.abs(A))
        assert np.max(np.abs(A - A.T)) < 1e-13 * scale
        eig = np.linalg.eigvalsh(0.5 * (A + A.T))
        assert np.all(np.abs(eig[:3]) < 1e-12 * scale), eig[:4] / scale
        assert eig[3] > 0.1 * scale, eig[3] / scale
        uniform = np.broadcast_to(
            np.array([0.7, -1.3, 2.0])[:, None, None], (3,) + shape
        )
        u = np.asarray(_apply(op, jnp.asarray(uniform), jnp.asarray(poisson)))
        assert np.max(np.abs(u)) < 1e-13 * scale


# Periodic vs non-periodic near a compact load: a 96 x 96 grid of 1 x 0.75 cells, a
# square patch of random positive tractions (all three components) at its centre.
N_PERIODIC = 96


@functools.cache
def _ops(periodic):
    n = N_PERIODIC
    grid = jc.Grid((n, n), (1.0 * n, 0.75 * n), periodic=periodic)
    return jc.HalfSpace(grid, "full")


def _patch_load(patch):
    n = N_PERIODIC
    t = np.zeros((3, n, n))
    c = n // 2
    values = np.random.default_rng(patch).uniform(0.5, 1.5, (3, patch, patch))
    t[
        :,
        c - patch // 2 : c - patch // 2 + patch,
        c - patch // 2 : c - patch // 2 + patch,
    ] = values
    return t


def _near_field_difference_error(load, window, poisson=0.3):
    """Max |du_periodic - du_nonperiodic| / max |du_nonperiodic| within +-window cells
    of the centre, with du = u(x) - u(centre) (the periodic mean is undetermined).
    """
    c = N_PERIODIC // 2
    sl = slice(c - window, c + window + 1)
    out = []
    for periodic in (True, False):
        u = np.asarray(_apply(_ops(periodic), jnp.asarray(load), jnp.asarray(poisson)))
        out.append(u[:, sl, sl] - u[:, c : c + 1, c : c + 1])
    per, non = out
    return np.max(np.abs(per - non)) / np.max(np.abs(non))


@functools.cache
def _patch_error(patch):
    """Error within two patch widths of the centre."""
    return _near_field_difference_error(_patch_load(patch), 2 * patch)


def test_periodic_matches_nonperiodic_near_compact_load():
    """96 x 96 periodic cell, 6 x 6 patch: within +-2 patch widths of the centre the
    displacement differences agree with the non-periodic operator to 1e-2 of their
    maximum (measured 4.5e-3; the difference is the effect of the periodic images and
    of the zero-mean condition, which grows away from the patch: ~2e-3 within +-1
    patch width)."""
    err = _patch_error(6)
    assert err < 1e-2, err


def test_periodic_agreement_improves_with_cell_size_relative_to_patch():
    """The periodic-image error shrinks as the cell grows relative to the patch.

    Patch 24, 12, 6 cells in the 96-cell period (ratio 1/4, 1/8, 1/16), compared within
    +-2 patch widths. Measured: 1.2e-1, 2.2e-2, 4.5e-3, a factor ~5 per halving of the
    ratio (likewise at a fixed 6-cell patch and growing n: about 2.1e-2, 4.3e-3, 1.0e-3
    for n = 48, 96, 192). We assert a factor > 3 per halving. (Below a ~3-cell patch the
    error levels off at ~4e-4, the alias-truncation floor of the periodic spectra, see
    the next test.)
    """
    e24, e12, e6 = (_patch_error(p) for p in (24, 12, 6))
    assert e12 < e24 / 3, (e24, e12)
    assert e6 < e12 / 3, (e12, e6)


@pytest.mark.parametrize("component", [0, 1, 2], ids=["qx", "qy", "p"])
def test_periodic_single_cell_near_field(component):
    """A single loaded cell in a 96 x 96 periodic cell: displacement differences within
    +-2 cells match the closed-form (non-periodic) coefficients to 1e-3.

    Measured: <= 4.1e-4. The residual does not decrease with n (it is the same at
    n = 192): it comes from truncating the alias sum of the periodic spectra, not from
    the periodic images.
    """
    n = N_PERIODIC
    load = np.zeros((3, n, n))
    load[component, n // 2, n // 2] = 1.0
    err = _near_field_difference_error(load, window=2)
    assert err < 1e-3, err


def test_periodic_translation_invariance():
    """Shifting the load with np.roll shifts the displacement identically (1e-12)."""
    n = N_PERIODIC
    op = _ops(True)
    rng = np.random.default_rng(5)
    for load in (_patch_load(6), rng.standard_normal((3, n, n))):
        u = np.asarray(_apply(op, jnp.asarray(load), jnp.asarray(0.3)))
        for shift in [(17, -29), (-48, 5), (1, 0)]:
            rolled = np.roll(load, shift, axis=(1, 2))
            u_rolled = np.asarray(_apply(op, jnp.asarray(rolled), jnp.asarray(0.3)))
            assert rel_err(u_rolled, np.roll(u, shift, axis=(1, 2))) < 1e-12


# --------------------------------------------------------------------------------------
# float32
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("periodic", [False, True], ids=["dcfft", "periodic"])
@pytest.mark.parametrize("coupling", ["normal", "full"])
def test_float32_matches_float64(periodic, coupling):
    """A float32 grid gives a float32 operator; apply matches float64 to 1e-5 relative.

    The 8 x 6 grid of GRIDS (non-square cells, SI magnitudes), random positive
    tractions, eager calls with a Python-float Poisson's ratio. Measured: <= 1e-6.
    """
    shape, size = GRIDS["8x6"]
    size = np.asarray(size)
    g64 = jc.Grid(shape, size, periodic=periodic)
    g32 = jc.Grid(shape, size.astype(np.float32), periodic=periodic)
    op64 = jc.HalfSpace(g64, coupling)
    op32 = jc.HalfSpace(g32, coupling)
    assert all(s.dtype == jnp.float32 for s in op32.spectra.values())
    t = np.random.default_rng(2).uniform(0.0, 1.0, (3,) + shape)
    for poisson in (0.0, 0.3):
        u64 = np.asarray(op64.apply(jnp.asarray(t), poisson))
        u32 = op32.apply(jnp.asarray(t, dtype=jnp.float32), poisson)
        assert u32.dtype == jnp.float32
        assert rel_err(np.asarray(u32, dtype=np.float64), u64) < 1e-5
        w64 = np.asarray(op64.apply_normal(jnp.asarray(t[2]), poisson))
        w32 = op32.apply_normal(jnp.asarray(t[2], dtype=jnp.float32), poisson)
        assert w32.dtype == jnp.float32
        assert rel_err(np.asarray(w32, dtype=np.float64), w64) < 1e-5


@pytest.mark.parametrize("coupling", ["x", "full"])
def test_transposed_spectra_are_the_blocks_in_ky_kx_layout(coupling):
    """`with_transposed_spectra` (built by `jc.solve` for the joint solver) holds every
    block in the `(ky, kx)` layout: each equals the transpose of the `(kx, ky)` one,
    exactly (a transpose moves entries), whether held or transposed on the fly; the
    `(kx, ky)` blocks are unchanged, and periodic grids get the operator itself."""
    size, length = GRIDS["8x6"]
    op = jc.HalfSpace(jc.Grid(size, length), coupling)
    held = op.with_transposed_spectra()
    nu = 0.3
    for name in ("normal_spectrum", "tangential_blocks", "coupling_spectra"):
        plain = jax.tree_util.tree_leaves(getattr(op, name)(nu))
        for source in (op, held):  # on the fly, and held
            swapped = jax.tree_util.tree_leaves(
                getattr(source, name)(nu, transposed=True))
            assert len(swapped) == len(plain) > 0
            for a, b in zip(plain, swapped):
                np.testing.assert_array_equal(np.swapaxes(np.asarray(a), -1, -2), b)
        for a, b in zip(plain, jax.tree_util.tree_leaves(getattr(held, name)(nu))):
            np.testing.assert_array_equal(a, b)
    periodic = jc.HalfSpace(jc.Grid(size, length, periodic=True), coupling)
    assert periodic.with_transposed_spectra() is periodic


@pytest.mark.parametrize("shape", [(256, 256), (257, 300)])
def test_convolve_in_two_halves_is_the_same_convolution(shape):
    # On a CPU from 256 cells a side `convolve` runs its transforms as two halves each
    # (`SPLIT_MIN`): the same sums in another grouping, so equal to round-off (1e-15
    # measured), on even and odd, square and oblong grids, inside jit.
    grid = jc.Grid(shape, (1e-3, 1.2e-3))
    operator = jc.HalfSpace(grid)
    field = jnp.asarray(np.random.default_rng(1).random(shape))
    spectrum = operator.normal_spectrum(0.3)
    split = jax.jit(lambda f: operator.convolve(f, spectrum))(field)
    whole = jax.jit(lambda f: operator.inverse(operator.forward(f) * spectrum))(field)
    assert split.shape == shape
    scale = float(jnp.max(jnp.abs(whole)))
    assert float(jnp.max(jnp.abs(split - whole))) <= 1e-13 * scale
