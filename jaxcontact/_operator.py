"""The half-space compliance operator: surface tractions -> surface displacements.

`HalfSpace` holds the Fourier spectra of the influence coefficients of `_influence`
for one grid, computed once at construction, and applies them by FFT:

- non-periodic grids (DC-FFT, Liu, Wang & Liu 2000): tractions are zero-padded to
  `Lx x Ly` (`padded_shape`: `2n`, or where that has a prime factor above 7 the
  smallest length `>= 2n - 1` without one), the kernel is laid out in wrap-around
  order, and the result is cropped back to `nx x ny`. The transforms are pruned: the
  forward transform runs its row FFTs on the `nx` non-zero rows only, and the inverse
  transform runs its column FFTs on the `nx` rows that are kept. This is exactly the
  padded linear convolution, at about half the cost of `rfft2(s=(Lx, Ly))` / `irfft2`
  at large `n`.
- periodic grids: the spectra are the Fourier transforms of the continuous Boussinesq
  and Cerruti kernels, multiplied by the cell shape factor `sinc(kx dx/2) sinc(ky dy/2)`
  and summed over aliases; the mean (k = 0) displacement is set to zero (it is
  undetermined for a periodic half-space and is absorbed by the rigid-body approach).

The operator is for UNIT shear modulus and is independent of Poisson's ratio: the
spectra are stored as Poisson-independent parts and combined with `poisson` on the
fly (`_influence.combine`). Even kernels (xx, yy, zz, xy) have real spectra and odd
kernels (xz, yz) purely imaginary ones, so only real arrays are stored. Blocks that the
`coupling` mode does not need are neither stored nor applied.
"""

from typing import Literal

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from . import _influence, _validate
from ._grid import Grid


Coupling = Literal["normal", "none", "x", "full"]
_COUPLINGS = ("normal", "none", "x", "full")
# `HalfSpace.convolve` splits its transforms in two on a CPU from this many cells
# a side.
SPLIT_MIN = 256


def _concrete(grid: Grid) -> bool:
    return not _validate.is_traced(grid.size)


def fast_length(n: int) -> int:
    """The smallest integer `>= n` with no prime factor above 7.

    A linear convolution of `n` cells is exact on any padded length `>= 2n - 1`; the
    FFT of a length with a large prime factor costs several times more (Bluestein):
    at n = 113 (CONTACT's Spence grid) a length of 226 = 2 x 113 is 3x slower than 225.
    """
    m = max(int(n), 1)
    while True:
        k = m
        for p in (2, 3, 5, 7):
            while k % p == 0:
                k //= p
        if k == 1:
            return m
        m += 1


def padded_shape(shape) -> tuple[int, int]:
    """`(Lx, Ly)`: the DC-FFT padded lengths of a non-periodic grid of `shape`: `2n`
    where that has no prime factor above 7, else `fast_length(2n - 1)`."""
    def length(n):
        return 2 * n if fast_length(2 * n) == 2 * n else fast_length(2 * n - 1)
    return tuple(length(int(n)) for n in shape)


def dc_forward(field: Float[Array, "... nx ny"], fft_shape, transposed: bool = False):
    """The DC-FFT spectrum of a real field zero-padded to `fft_shape = (Lx, Ly)`
    (`padded_shape`): `(..., Lx, Ly // 2 + 1)`, or `(..., Ly // 2 + 1, Lx)` if
    `transposed` (the column transforms then run along the contiguous axis). Pruned:
    the row transforms run on the `nx` non-zero rows only."""
    lx, ly = fft_shape
    spec = jnp.fft.rfft(field, n=ly, axis=-1)
    if transposed:
        return jnp.fft.fft(jnp.swapaxes(spec, -1, -2), n=lx, axis=-1)
    return jnp.fft.fft(spec, n=lx, axis=-2)


def dc_inverse(spec, shape, fft_shape, transposed: bool = False):
    """Inverse of `dc_forward`, cropped to the grid's `shape = (nx, ny)`: the column
    transforms run on the `nx` kept rows only."""
    nx, ny = shape
    ly = fft_shape[1]
    if transposed:
        field = jnp.swapaxes(jnp.fft.ifft(spec, axis=-1)[..., :nx], -1, -2)
    else:
        field = jnp.fft.ifft(spec, axis=-2)[..., :nx, :]
    return jnp.fft.irfft(field, n=ly, axis=-1)[..., :ny]


def _wraparound_offsets(n: int, length: int, d, xp):
    """Offsets `i * d` for `i = 0..n-1, (unused), -(n-1)..-1`, `length` (`>= 2n - 1`)
    entries, and the mask of the used ones."""
    i = xp.arange(length)
    used = (i < n) | (i > length - n)
    return xp.where(i < n, i, i - length) * d, used


def _dc_spectra(grid: Grid, names):
    """rfft2 of the wrap-around padded real-space coefficients, one per `names`.

    Computed in float64 NumPy when the grid is concrete (the far-field corner sums
    cancel to a small fraction of their terms: float32 would lose 1e-2 of them at 500
    cells), with `jax.numpy` when it is traced.
    """
    xp = np if _concrete(grid) else jnp
    nx, ny = grid.shape
    if xp is np:
        # From the concrete size in NumPy: inside a jit trace even operations on
        # constants are staged, so `grid.spacing` would be a tracer there.
        dx, dy = (float(v)
                  for v in np.asarray(grid.size, np.float64) / np.array([nx, ny]))
    else:
        dx, dy = grid.spacing
    lx, ly = padded_shape(grid.shape)
    ox, mx = _wraparound_offsets(nx, lx, dx, xp)
    oy, my = _wraparound_offsets(ny, ly, dy, xp)
    x, y = xp.meshgrid(ox, oy, indexing="ij")
    keep = mx[:, None] & my[None, :]
    base = dict(zip(("s1", "s2", "sxy", "szx", "szy"),
                    _influence.base_integrals(x, y, dx, dy, xp=xp)))
    out = {}
    for name in names:
        spec = xp.fft.rfft2(xp.where(keep, base[name], 0.0))
        # Even kernels have real spectra, odd kernels (szx, szy) imaginary ones.
        spec = spec.imag if name in ("szx", "szy") else spec.real
        out[name] = jnp.asarray(spec, dtype=grid.size.dtype)
    return out


def _alias_sum(grid: Grid, names, aliases: int, xp):
    nx, ny = grid.shape
    if xp is np:
        dx, dy = (float(v)
                  for v in np.asarray(grid.size, np.float64) / np.array([nx, ny]))
    else:
        dx, dy = grid.spacing
    kx0 = 2 * np.pi * xp.fft.fftfreq(nx) / dx
    ky0 = 2 * np.pi * xp.fft.rfftfreq(ny) / dy
    a = xp.arange(-aliases, aliases + 1)
    ky = ky0[None, :, None] + 2 * np.pi * a[None, None, :] / dy  # (1, nky, A)
    out = {name: 0.0 for name in names}
    for ax in range(-aliases, aliases + 1):
        kx = (kx0 + 2 * np.pi * ax / dx)[:, None, None]  # (nkx, 1, 1)
        k2 = kx * kx + ky * ky
        zero = k2 == 0
        k2 = xp.where(zero, 1.0, k2)
        k = xp.sqrt(k2)
        shape = xp.sinc(kx * dx / (2 * np.pi)) * xp.sinc(ky * dy / (2 * np.pi))
        # Fourier transforms (f^(k) = ∫ f e^{-ik.x}) of the kernels / (2 pi):
        #   1/(2pi r) -> 1/k; x^2/(2pi r^3) -> ky^2/k^3; xy/(2pi r^3) -> -kx ky/k^3;
        #   x/(2pi r^2) -> -i kx/k^2 (we store the imaginary part).
        terms = {
            "s1": lambda: kx * kx / (k2 * k),  # s1 + s2 = 1/k, s2 = ky^2/k^3
            "s2": lambda: ky * ky / (k2 * k),
            "sxy": lambda: -kx * ky / (k2 * k),
            "szx": lambda: -kx / k2,
            "szy": lambda: -ky / k2,
        }
        for name in names:
            out[name] = out[name] + xp.sum(xp.where(zero, 0.0, terms[name]() * shape),
                                           axis=-1)
    return out


def _periodic_spectra(grid: Grid, names, aliases: int = 10):
    """Continuous-kernel spectra times the cell shape factor, summed over aliases.

    The alias sums are truncated at `|a| <= aliases` per axis. Measured against 60
    aliases (32^2 grid), the real-space kernels are then accurate to about 5e-5 of
    their maximum for the normal and tangential blocks and 1.3e-3 for the
    normal-tangential coupling blocks (whose alias sums converge most slowly). The
    mean (k = 0) displacement is set to zero.
    """
    xp = np if _concrete(grid) else jnp
    nx, ny = grid.shape
    summed = _alias_sum(grid, names, aliases, xp)
    out = {}
    for name in names:
        spec = summed[name]
        if name == "szx" and nx % 2 == 0:  # odd kernels: zero Nyquist entries
            spec = (spec.at[nx // 2, :].set(0.0) if xp is jnp
                    else _zero_row(spec, nx // 2))
        if name == "szy" and ny % 2 == 0:
            spec = spec.at[:, -1].set(0.0) if xp is jnp else _zero_col(spec, -1)
        out[name] = jnp.asarray(spec, dtype=grid.size.dtype)
    return out


def _zero_row(a, i):
    a = np.array(a)
    a[i, :] = 0.0
    return a


def _zero_col(a, j):
    a = np.array(a)
    a[:, j] = 0.0
    return a


def _needed(coupling: str, tangential_y: bool):
    if coupling == "normal":
        return ("zz",)
    names = ["s1", "s2"]
    if tangential_y:
        names.append("sxy")
    if coupling in ("x", "full"):
        names.append("szx")
    if coupling == "full":
        names.append("szy")
    return tuple(names)


class HalfSpace(eqx.Module):
    """FFT influence operator of an elastic half-space with unit shear modulus.

    **Arguments:**

    - `grid`: the `jc.Grid`.
    - `coupling`: which blocks to build. `"normal"`: pressure -> normal displacement
      only. `"none"`: normal and tangential blocks, no normal-tangential coupling.
      `"x"`: adds the coupling between pressure and `q_x`. `"full"`: all nine blocks.
    - `tangential_y`: whether `q_y` and `u_y` are needed (the xy and yy blocks). Always
      `False` for `"normal"` and for `"x"` (semi-coupled: `q_y = 0`). Default `True`.

    Applying it costs one forward and one inverse FFT of the (padded) grid per traction
    and per displacement component in use.
    """

    grid: Grid
    coupling: str = eqx.field(static=True)
    tangential_y: bool = eqx.field(static=True)
    spectra: dict[str, Float[Array, "kx ky"]]

    def __init__(self, grid: Grid, coupling: Coupling = "normal",
                 tangential_y: bool = True):
        if not isinstance(grid, Grid):
            raise TypeError(f"grid must be a jc.Grid, got {grid!r}")
        if coupling not in _COUPLINGS:
            raise ValueError(f"coupling must be one of {_COUPLINGS}, got {coupling!r}")
        self.grid = grid
        self.coupling = coupling
        self.tangential_y = bool(tangential_y) and coupling not in ("normal", "x")
        names = _needed(coupling, self.tangential_y)
        raw_names = ("s1", "s2") if names == ("zz",) else names
        make = _periodic_spectra if grid.periodic else _dc_spectra
        spectra = make(grid, raw_names)
        if names == ("zz",):
            spectra = {"zz": spectra["s1"] + spectra["s2"]}
        self.spectra = spectra

    # -- transforms ------------------------------------------------------------------

    @property
    def fft_shape(self) -> tuple[int, int]:
        """`(Lx, Ly)`: the FFT grid: the grid's shape if periodic, else
        `padded_shape`."""
        return self.grid.shape if self.grid.periodic else padded_shape(self.grid.shape)

    def forward(self, field: Float[Array, "... nx ny"], transposed: bool = False):
        """Spectrum `(..., Lx, Ly // 2 + 1)` of a real field (padded and pruned for
        non-periodic grids, `dc_forward`; `transposed`: in the `(ky, kx)` layout).
        Periodic grids: `rfft2`, one layout."""
        if self.grid.periodic:
            return jnp.fft.rfft2(field)
        return dc_forward(field, self.fft_shape, transposed)

    def inverse(self, spec, transposed: bool = False) -> Float[Array, "... nx ny"]:
        """Inverse of `forward`, cropped to the grid."""
        nx, ny = self.grid.shape
        if self.grid.periodic:
            return jnp.fft.irfft2(spec, s=(nx, ny))
        return dc_inverse(spec, self.grid.shape, self.fft_shape, transposed)

    def convolve(self, field: Float[Array, "nx ny"], spectrum) -> Float[Array, "nx ny"]:
        """`inverse(forward(field) * spectrum)` for one field, with `spectrum` in
        `forward`'s layout. On a CPU, on a non-periodic grid of at least `SPLIT_MIN`
        cells a side, each transform runs as two independent halves (rows, then
        spectral columns), which XLA's CPU runtime runs on two threads at once: its
        FFT does not use a second core by itself (the normal solve 8-13 % faster at
        256^2-1024^2 on 2 cores, `benchmarks/notes/normal_reentry.md`). The same
        numbers to round-off either way."""
        nx, ny = self.grid.shape
        if (self.grid.periodic or min(nx, ny) < SPLIT_MIN or field.ndim != 2
                or jax.default_backend() != "cpu"):
            return self.inverse(self.forward(field) * spectrum)
        lx, ly = self.fft_shape
        rows, cols = nx // 2, (ly // 2 + 1) // 2
        spec = jnp.concatenate([jnp.fft.rfft(field[:rows], n=ly, axis=-1),
                                jnp.fft.rfft(field[rows:], n=ly, axis=-1)], axis=0)
        halves = [jnp.fft.ifft(jnp.fft.fft(spec[:, c], n=lx, axis=0) * spectrum[:, c],
                               axis=0)[:nx]
                  for c in (slice(None, cols), slice(cols, None))]
        spec = jnp.concatenate(halves, axis=1)
        return jnp.concatenate([jnp.fft.irfft(spec[:rows], n=ly, axis=-1)[:, :ny],
                                jnp.fft.irfft(spec[rows:], n=ly, axis=-1)[:, :ny]],
                               axis=0)

    def diagonal(self, spectrum) -> Float[Array, ""]:
        """Diagonal entry of the convolution with a real, even `spectrum` (its kernel at
        zero offset: the mean of the full spectrum, the half-spectrum weighted)."""
        full_ny = self.fft_shape[1]
        m = spectrum.shape[-1]
        weights = jnp.full((m,), 2.0, spectrum.dtype).at[0].set(1.0)
        if full_ny % 2 == 0:
            weights = weights.at[m - 1].set(1.0)
        full_nx = spectrum.shape[-2]
        return jnp.sum(spectrum * weights[None, :]) / (full_nx * full_ny)

    # -- application -----------------------------------------------------------------

    def with_transposed_spectra(self) -> "HalfSpace":
        """This operator, its spectra also held in the `(ky, kx)` layout (keys `"t:"`
        + name) that the joint coupled solver works in (`_solver/joint.py`). Build it
        once, outside a time loop: XLA does not hoist the transposes out of a loop by
        itself (the joint solver's setup at 105^2 took ~3 ms of transposes per step).
        Periodic grids (no such layout): unchanged."""
        if self.grid.periodic:
            return self
        extra = {"t:" + k: jnp.swapaxes(v, -1, -2) for k, v in self.spectra.items()
                 if not k.startswith("t:")}
        return eqx.tree_at(lambda op: op.spectra, self, {**self.spectra, **extra})

    def _spectrum(self, name, transposed=False):
        """The raw spectrum `name`, in the `(ky, kx)` layout if `transposed` (held by
        `with_transposed_spectra`, else transposed here)."""
        if not transposed:
            return self.spectra[name]
        held = self.spectra.get("t:" + name)
        return jnp.swapaxes(self.spectra[name], -1, -2) if held is None else held

    def normal_spectrum(self, poisson, transposed=False):
        """Real spectrum of the zz block for this Poisson's ratio (`transposed`: in
        the `(ky, kx)` layout)."""
        if "zz" in self.spectra:
            return (1 - poisson) * self._spectrum("zz", transposed)
        return (1 - poisson) * (self._spectrum("s1", transposed)
                                + self._spectrum("s2", transposed))

    def apply_normal(self, pressure: Float[Array, "nx ny"],
                     poisson) -> Float[Array, "nx ny"]:
        """Normal displacement `u_z` [length] due to `pressure`, unit shear modulus."""
        return self.inverse(self.forward(pressure) * self.normal_spectrum(poisson))

    def tangential_blocks(self, poisson, transposed=False):
        """Real spectra `(xx, xy, yy)` of the tangential-tangential blocks
        (`transposed`: in the `(ky, kx)` layout)."""
        nu = poisson
        s1, s2 = self._spectrum("s1", transposed), self._spectrum("s2", transposed)
        xx = (1 - nu) * s1 + s2
        if not self.tangential_y:
            return xx, None, None
        return xx, nu * self._spectrum("sxy", transposed), s1 + (1 - nu) * s2

    def apply_tangential(self, shear: Float[Array, "nd nx ny"], poisson, blocks=None):
        """Tangential displacements `(nd, nx, ny)` due to shear `(nd, nx, ny)`.

        `nd = 1` (q_x only) or `2` (q_x, q_y; needs `tangential_y`). `blocks` may be
        precomputed `tangential_blocks(poisson)`, optionally scaled by a compliance.
        """
        xx, xy, yy = self.tangential_blocks(poisson) if blocks is None else blocks
        hat = self.forward(shear)
        if shear.shape[0] == 1:
            return self.inverse(xx[None] * hat)
        ux = xx * hat[0] + xy * hat[1]
        uy = xy * hat[0] + yy * hat[1]
        return self.inverse(jnp.stack([ux, uy]))

    def coupling_spectra(self, poisson, transposed=False):
        """Imaginary parts `(zx, zy)` of the `u_z <- q` spectra (`xz = -zx`), or None
        (`transposed`: in the `(ky, kx)` layout)."""
        if self.coupling not in ("x", "full"):
            return None, None
        c = 0.5 * (1 - 2 * poisson)
        zx = c * self._spectrum("szx", transposed)
        zy = c * self._spectrum("szy", transposed) if self.coupling == "full" else None
        return zx, zy

    def apply(self, traction: Float[Array, "3 nx ny"],
              poisson) -> Float[Array, "3 nx ny"]:
        """Displacements `(u_x, u_y, u_z)` due to tractions `(q_x, q_y, p)`, unit
        modulus.

        Only the blocks of this operator's `coupling` are applied; components whose
        blocks are absent come out as zeros (e.g. `u_y` when `tangential_y=False`).
        """
        if self.coupling == "normal":
            uz = self.apply_normal(traction[2], poisson)
            return jnp.stack([jnp.zeros_like(uz), jnp.zeros_like(uz), uz])
        s = self.spectra
        nu = poisson
        c = 0.5 * (1 - 2 * nu)
        qx_hat = self.forward(traction[0])
        p_hat = self.forward(traction[2])
        ux_hat = ((1 - nu) * s["s1"] + s["s2"]) * qx_hat
        uz_hat = (1 - nu) * (s["s1"] + s["s2"]) * p_hat
        if self.coupling in ("x", "full"):
            # zx = c * szx is odd (spectrum i * c * szx); xz = -zx.
            ux_hat = ux_hat - 1j * c * s["szx"] * p_hat
            uz_hat = uz_hat + 1j * c * s["szx"] * qx_hat
        if self.tangential_y:
            qy_hat = self.forward(traction[1])
            ux_hat = ux_hat + nu * s["sxy"] * qy_hat
            uy_hat = nu * s["sxy"] * qx_hat + (s["s1"] + (1 - nu) * s["s2"]) * qy_hat
            if self.coupling == "full":
                uy_hat = uy_hat - 1j * c * s["szy"] * p_hat
                uz_hat = uz_hat + 1j * c * s["szy"] * qy_hat
            uy = self.inverse(uy_hat)
        else:
            uy = None
        ux = self.inverse(ux_hat)
        uz = self.inverse(uz_hat)
        if uy is None:
            uy = jnp.zeros_like(ux)
        return jnp.stack([ux, uy, uz])
