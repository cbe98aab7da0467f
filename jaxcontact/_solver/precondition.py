"""Full-plane inverse preconditioners of the tangential / coupled operator blocks.

`normal.inverse_preconditioner` inverts one spectrum on the operator's padded FFT grid.
Here the blocks of the normal-tangential operator: `block_preconditioner` applies the
inverse of its block diagonal (`zz`, `xx`, `yy` symbols; the coupling and `xy` blocks
are left out), with two differences:

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
  for the joint solver at 105^2.
"""

import jax.numpy as jnp


def inverse_symbol(spectrum):
    """`1 / spectrum` of a real, even spectrum, entries at or below `1e-12` of the
    largest magnitude (the zero mode of a periodic grid, whose mean displacement is set
    to zero) dropped (0) rather than inverted."""
    floor = 1e-12 * jnp.max(jnp.abs(spectrum))
    return jnp.where(spectrum > floor, 1 / jnp.where(spectrum > floor, spectrum, 1), 0)


def block_preconditioner(operator, nn, xx, yy=None, *, coarse=True):
    """`r -> M r` for a field `(r_z, r_x[, r_y])`, `(1 + nd, nx, ny)`.

    `nn`, `xx`, `yy`: the real spectra of the `zz`, `xx`, `yy` blocks in the layout of
    `operator.forward`, with a common scale (e.g. times a compliance); `yy=None` for
    one shear component. Inverted by `inverse_symbol`. `coarse`: apply on the
    unpadded grid (non-periodic grids; periodic ones are unpadded anyway).
    """
    blocks = [inverse_symbol(nn), inverse_symbol(jnp.maximum(xx, nn))]
    if yy is not None:
        blocks.append(inverse_symbol(jnp.maximum(yy, nn)))
    m = jnp.stack(blocks)
    grid = operator.grid
    if grid.periodic or not coarse:
        return lambda r: operator.inverse(operator.forward(r) * m)
    m = m[:, ::2, ::2]
    shape = grid.shape
    return lambda r: jnp.fft.irfft2(jnp.fft.rfft2(r) * m, s=shape)
