"""Full-plane inverse preconditioners of the contact operators.

`normal.inverse_preconditioner` inverts one spectrum: on the operator's padded FFT
grid, or (given `poisson`, what the normal solvers use) with `unpadded_inverse` below.
Here the blocks of the normal-tangential operator: `block_preconditioner` applies the
inverse of its block diagonal (`zz`, `xx`, `yy` symbols; the coupling and `xy` blocks
are left out), with these differences:

- the padded (DC-FFT) tangential spectra are NOT positive: the truncated kernels give a
  few percent of the modes near-zero or negative values (min -4e-3 of max 100 for unit
  modulus at n = 105), whose inverses would dominate `M r` (a restricted CG then gains
  much less: tests/test_joint.py). The continuous symbols satisfy `K_xx, K_yy >=
  K_zz` (Cerruti against Boussinesq: `(1 - nu k_x^2 / k^2) / |k|` against
  `(1 - nu) / |k|`), so the tangential spectra are floored by the normal one, which
  only touches the broken modes;
- by default it runs on the UNPADDED grid, periodically, with the kernel wrapped
  modulo the grid (the even modes of the padded spectra when these are `2n` long): a
  quarter of the transform size. A grid length with a prime factor above 7 is
  extended by zeros to the next length without one (`preconditioner_shape`; 113 ->
  120: the transform of a prime length costs ~3.5x more). A preconditioner need not
  be exact: +14 % iterations, -25 % time for the joint solver at 105^2;
- given the material (`compliance`, `poisson`), the unpadded spectra are raised to the
  CONTINUOUS half-space symbols where these are larger (`continuum_symbols`): on some
  of the lowest modes the wrapped spectra fall to 0.4-0.5 of the continuous symbols,
  and those modes are the ones of a contact that fills most of the grid (measurements:
  `benchmarks/notes/solvers.md`).
"""

import jax.numpy as jnp

from .._operator import fast_length, padded_shape


def inverse_symbol(spectrum):
    """`1 / spectrum` of a real, even spectrum, entries at or below `1e-12` of the
    largest magnitude (the zero mode of a periodic grid, whose mean displacement is set
    to zero) dropped (0) rather than inverted."""
    floor = 1e-12 * jnp.max(jnp.abs(spectrum))
    return jnp.where(spectrum > floor, 1 / jnp.where(spectrum > floor, spectrum, 1), 0)


def padded_inverse(operator, spectra):
    """`r -> F^-1[F[r] / spectra]` on the operator's own FFT grid (padded unless
    periodic), `spectra` in the layout of `operator.forward`, inverted by
    `inverse_symbol`."""
    m = inverse_symbol(spectra)
    return lambda r: operator.inverse(operator.forward(r) * m)


def continuum_symbols(grid, poisson, nd):
    """Block diagonal of the continuous half-space symbols per unit compliance on the
    rfft2 modes of the preconditioner grid (`preconditioner_shape`, the unpadded
    grid for most sizes), `(1 + nd, mx, my // 2 + 1)` [length].

    Boussinesq's `(1 - nu) / |k|` and Cerruti's `(1 - nu k_x^2 / |k|^2) / |k|` (`k_y`
    for y), `k` in rad/length: times a compliance, the scale of the operator's DFT
    spectra (they agree to a few percent away from the grid's Nyquist corner). The
    mean mode takes the grid's lowest wavenumber, `2 pi / max(Lx, Ly)`.
    """
    nx, ny = preconditioner_shape(grid)
    dx, dy = grid.spacing
    lx, ly = nx * dx, ny * dy
    dtype = grid.size.dtype
    kx = 2 * jnp.pi * jnp.fft.fftfreq(nx).astype(dtype)[:, None] / dx
    ky = 2 * jnp.pi * jnp.fft.rfftfreq(ny).astype(dtype)[None, :] / dy
    k2 = kx * kx + ky * ky
    mean = k2 == 0
    k_min = 2 * jnp.pi / jnp.maximum(lx, ly)
    k = jnp.sqrt(jnp.where(mean, k_min * k_min, k2))
    cos2_x = jnp.where(mean, 0.5, kx * kx / jnp.where(mean, 1.0, k2))
    blocks = [(1 - poisson) / k, (1 - poisson * cos2_x) / k]
    if nd == 2:
        blocks.append((1 - poisson * (1 - cos2_x)) / k)
    return jnp.stack(blocks)


def block_preconditioner(operator, nn, xx, yy=None, *, coarse=True, compliance=None,
                         poisson=None):
    """`r -> M r` for a field `(r_z, r_x[, r_y])`, `(1 + nd, nx, ny)`.

    `nn`, `xx`, `yy`: the real spectra of the `zz`, `xx`, `yy` blocks in the layout of
    `operator.forward`, with a common scale (e.g. times a compliance); `yy=None` for
    one shear component. Inverted by `inverse_symbol`. `coarse`: apply on the
    unpadded grid (non-periodic grids; periodic ones are unpadded anyway); there, with
    `compliance` [1/stress] (the scale of the spectra) and `poisson`, each spectrum is
    raised to `compliance` times its `continuum_symbols` where these are larger.
    """
    spectra = [nn, jnp.maximum(xx, nn)]
    if yy is not None:
        spectra.append(jnp.maximum(yy, nn))
    spectra = jnp.stack(spectra)
    grid = operator.grid
    if grid.periodic or not coarse:
        return padded_inverse(operator, spectra)
    continuum = None
    if poisson is not None:
        continuum = compliance * continuum_symbols(grid, poisson, len(spectra) - 1)
    return unpadded_inverse(grid, spectra, continuum)


def preconditioner_shape(grid) -> tuple[int, int]:
    """`(mx, my)`: the periodic grid the unpadded preconditioners run on: the grid's
    cells, extended by zeros to lengths with no prime factor above 7
    (`_operator.fast_length`; the grid itself for most sizes)."""
    return tuple(fast_length(n) for n in grid.shape)


def _fold(kernel, n: int, m: int, axis: int):
    """Kernel values of offsets `0..n-1` (first `n` entries along `axis`) and
    `-(n-1)..-1` (last `n - 1`) summed modulo `m` (`>= n`): the kernel of the periodic
    grid of `m` cells."""
    kernel = jnp.moveaxis(kernel, axis, -1)
    length = kernel.shape[-1]
    widths = [(0, 0)] * (kernel.ndim - 1)
    positive = jnp.pad(kernel[..., :n], widths + [(0, m - n)])
    negative = jnp.pad(kernel[..., length - n + 1:], widths + [(m - n + 1, 0)])
    return jnp.moveaxis(positive + negative, -1, axis)


def wrapped_spectra(grid, padded_spectra):
    """The rfft2 `(..., mx, my // 2 + 1)` on the periodic preconditioner grid
    (`preconditioner_shape`) of the kernel wrapped modulo that grid, from real, even
    padded spectra `(..., Lx, Ly // 2 + 1)`.

    With `L = 2m` these are the even modes of the padded spectra; otherwise the kernel
    is transformed back, folded (offset `d` onto `d mod m`) and transformed again.
    """
    lx, ly = padded_shape(grid.shape)
    mx, my = preconditioner_shape(grid)
    if (lx, ly) == (2 * mx, 2 * my):
        return padded_spectra[..., ::2, ::2]
    kernel = jnp.fft.irfft2(padded_spectra, s=(lx, ly))
    kernel = _fold(_fold(kernel, grid.shape[0], mx, -2), grid.shape[1], my, -1)
    return jnp.fft.rfft2(kernel).real


def unpadded_inverse(grid, padded_spectra, continuum=None):
    """`r -> F^-1[F[r] / spectrum]` on the periodic preconditioner grid
    (`preconditioner_shape`: the UNPADDED grid for most sizes), `r` zero-extended to
    it and the result cropped, from a non-periodic grid's padded spectra
    `(..., Lx, Ly // 2 + 1)`: the kernel wrapped modulo that grid
    (`wrapped_spectra`), raised to `continuum` `(..., mx, my // 2 + 1)` (the same
    scale) where that is larger, inverted by `inverse_symbol`."""
    spectra = wrapped_spectra(grid, padded_spectra)
    if continuum is not None:
        spectra = jnp.maximum(spectra, continuum.astype(spectra.dtype))
    m = inverse_symbol(spectra)
    shape = preconditioner_shape(grid)
    nx, ny = grid.shape
    return lambda r: jnp.fft.irfft2(jnp.fft.rfft2(r, s=shape) * m,
                                    s=shape)[..., :nx, :ny]


def shear_x_preconditioner(operator, poisson):
    """`r -> M r` for one shear component `(nx, ny)`: the full-plane inverse of the
    `xx` block per unit compliance. Non-periodic grids: the padded spectrum floored by
    the normal one, on the unpadded grid, raised to Cerruti's continuous symbol
    (`unpadded_inverse`); periodic grids: `1 / spectrum` on the grid."""
    xx = operator.tangential_blocks(poisson)[0]
    grid = operator.grid
    if grid.periodic:
        return padded_inverse(operator, xx)
    floored = jnp.maximum(xx, operator.normal_spectrum(poisson))
    return unpadded_inverse(grid, floored, continuum_symbols(grid, poisson, 1)[1])
