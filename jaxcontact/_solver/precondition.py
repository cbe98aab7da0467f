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
- by default it runs on the UNPADDED grid, periodically, with the even modes of the
  padded spectra (those of the kernel wrapped modulo the grid): a quarter of the
  transform size. A preconditioner need not be exact: +14 % iterations, -25 % time
  for the joint solver at 105^2;
- given the material (`compliance`, `poisson`), the unpadded spectra are raised to the
  CONTINUOUS half-space symbols where these are larger (`continuum_symbols`): on some
  of the lowest modes the wrapped spectra fall to 0.4-0.5 of the continuous symbols,
  and those modes are the ones of a contact that fills most of the grid (measurements:
  `benchmarks/notes/solvers.md`).
"""

import jax.numpy as jnp


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
    rfft2 modes of the unpadded grid, `(1 + nd, nx, ny // 2 + 1)` [length].

    Boussinesq's `(1 - nu) / |k|` and Cerruti's `(1 - nu k_x^2 / |k|^2) / |k|` (`k_y`
    for y), `k` in rad/length: times a compliance, the scale of the operator's DFT
    spectra (they agree to a few percent away from the grid's Nyquist corner). The
    mean mode takes the grid's lowest wavenumber, `2 pi / max(Lx, Ly)`.
    """
    nx, ny = grid.shape
    lx, ly = grid.size[0], grid.size[1]
    dtype = grid.size.dtype
    kx = 2 * jnp.pi * jnp.fft.fftfreq(nx).astype(dtype)[:, None] * (nx / lx)
    ky = 2 * jnp.pi * jnp.fft.rfftfreq(ny).astype(dtype)[None, :] * (ny / ly)
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


def unpadded_inverse(grid, padded_spectra, continuum=None):
    """`r -> F^-1[F[r] / spectrum]` on the UNPADDED grid (periodic, `rfft2`) of a
    non-periodic grid's padded spectra `(..., 2 nx, ny + 1)`: their even modes (the
    kernel wrapped modulo the grid), raised to `continuum` `(..., nx, ny // 2 + 1)`
    (the same scale) where that is larger, inverted by `inverse_symbol`."""
    spectra = padded_spectra[..., ::2, ::2]
    if continuum is not None:
        spectra = jnp.maximum(spectra, continuum.astype(spectra.dtype))
    m = inverse_symbol(spectra)
    shape = grid.shape
    return lambda r: jnp.fft.irfft2(jnp.fft.rfft2(r) * m, s=shape)


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
