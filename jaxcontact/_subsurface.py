r"""Subsurface stresses in the half-space from the surface tractions (DC-FFT).

A uniform unit traction on one rectangular surface cell `[-dx/2, dx/2] x [-dy/2, dy/2]`
produces a stress field at depth `z` whose closed form is a "corner sum"
`F(x+a, y+b) - F(x-a, y+b) - F(x+a, y-b) + F(x-a, y-b)` (`a = dx/2`, `b = dy/2`) of a
function `F(u, v, z)` with `d^2 F / du dv` equal to the point-force stress kernel
(Love 1929 for the pressure; the same construction for the Cerruti problem, cf.
Johnson 1985, sections 3.2-3.5, and Liu & Wang 2002).

**How the corner functions were obtained.** The Boussinesq and Cerruti displacements
(Johnson eqs. 3.19, 3.86-3.87; unit shear modulus) are sums of `z^k` times derivatives
of three harmonic potentials, `phi1 = 1/rho`, `phi2 = ln(rho + z)` and
`phi3 = z ln(rho + z) - rho` (`rho^2 = u^2 + v^2 + z^2`, `d/dz phi3 = phi2`,
`d/dz phi2 = phi1`). Hooke's law turns them into stress kernels of the same kind; the
z-derivatives of `phi2`, `phi3` are lowered with the chain above and the others with
harmonicity. Each remaining term `d^(i,j) phi` is integrated over the cell in closed
form with the partial antiderivatives

- `int phi1 dv = ln(v + rho)`,
- `int int d_z phi1 du dv = -atan(u v / (z rho))`,
- `int d_u phi2 dv = atan(v/u) - atan(v z / (u rho)) = W(u, v)`,
- `int d_u phi3 dv = -u ln(v + rho) + z W(u, v)`,

and their mirror images `u <-> v` (the derivation was done symbolically and each
antiderivative checked by differentiation). Functions of `u` alone or `v` alone are
dropped: they cancel in the corner sum. All corner functions stay bounded for
`z >= 0` at the corners `u = x +- dx/2 != 0`, `v != 0` of a cell-centred grid, so the
surface `z = 0` is included as the limit `z -> 0+` (where, under a loaded cell,
`s_zz = -p`, `s_xz = -q_x`, `s_yz = -q_y` exactly).

Accuracy: the coefficients are exact for piecewise-constant tractions; the tests check
them against Gauss quadrature of the point-force displacement kernels differentiated by
finite differences (agreement about 5e-9 per unit traction). The error of a stress
field then comes from the piecewise-constant representation of the traction: for a
Hertz pressure on a 128 x 128 grid of side 3a (about 85 cells across the contact),
2e-4 p0 on the axis for z >= 0.05 a; for a sliding Hertz contact (q = mu p) 5e-3 p0
at the surface inside 0.9 a (9e-3 p0 at 64 x 64), where the cell-wise constant
traction matters most.

Convolution: the non-periodic DC-FFT of `_operator.py`, its layout and transforms
(`padded_shape`, `dc_forward`, `dc_inverse`: zero padding, kernel in wrap-around
order); kernels are built in float64 NumPy when the
grid, depths and Poisson's ratio are concrete and with `jax.numpy` when traced.

Sign conventions (docs/conventions.md): z points into the body; the pressure `p >= 0`
pushes the half-space in +z; the shear `(q_x, q_y)` is the traction on the half-space.
Stresses are positive in tension, so under a pressure `s_zz = -p` at the surface.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from . import _validate
from ._grid import Grid
from ._operator import dc_forward, dc_inverse, padded_shape


COMPONENTS = ("sxx", "syy", "szz", "sxy", "sxz", "syz")
# Component names under the exchange of the x and y axes.
_SWAP = {
    "sxx": "syy",
    "syy": "sxx",
    "szz": "szz",
    "sxy": "sxy",
    "sxz": "syz",
    "syz": "sxz",
}


# ----------------------------------------------------------------------------------
# Corner functions (each a dict over COMPONENTS, times 4 pi)
# ----------------------------------------------------------------------------------


def _log_plus(v, rho, rest2, xp):
    """`ln(v + rho)`, with `rest2 = rho^2 - v^2 > 0`, without cancellation for v < 0."""
    return xp.where(v >= 0, xp.log(v + rho), xp.log(rest2 / (rho - v)))


def _inv_plus(v, rho, rest2, xp):
    """`1 / (v + rho)`, stable for v < 0 (`rest2 = rho^2 - v^2 > 0`)."""
    return xp.where(v >= 0, 1.0 / (v + rho), (rho - v) / rest2)


def _w(u, v, z, rho, xp):
    """`W = atan(v/u) - atan(v z / (u rho))` as one bounded arctangent."""
    return xp.arctan2(u * v * (u * u + v * v), (rho + z) * (u * u * rho + v * v * z))


def _w_u(u, v, z, rho, xp):
    """`d W / du = v (z rho - u^2) / (rho (rho + z) (u^2 + z^2))`."""
    return v * (z * rho - u * u) / (rho * (rho + z) * (u * u + z * z))


def _pressure_corner(u, v, z, nu, xp):
    """Corner functions of the stresses due to a unit pressure (force +z), x 4 pi."""
    rho = xp.sqrt(u * u + v * v + z * z)
    uz2, vz2 = u * u + z * z, v * v + z * z
    inv_v = _inv_plus(v, rho, uz2, xp)  # 1 / (v + rho)
    inv_u = _inv_plus(u, rho, vz2, xp)  # 1 / (u + rho)
    w_uv = _w(u, v, z, rho, xp)  # int d_u phi2 dv
    w_vu = _w(v, u, z, rho, xp)  # int d_v phi2 du
    # int int d_z phi1 = -atan(u v / (z rho)); atan2 gives the z -> 0+ limit.
    zeta = -xp.arctan2(u * v, z * rho)
    a_u = u * inv_v / rho  # d_u ln(v + rho)
    a_v = v * inv_u / rho  # d_v ln(u + rho)
    return {
        "sxx": -2 * z * a_u + 2 * (nu - 1) * w_uv - 2 * nu * w_vu + 2 * nu * zeta,
        "syy": -2 * z * a_v + 2 * (nu - 1) * w_vu - 2 * nu * w_uv + 2 * nu * zeta,
        "szz": 2 * z * (a_u + a_v) - 2 * nu * (w_uv + w_vu) + 2 * (1 - nu) * zeta,
        "sxy": -2 * z / rho + 2 * (2 * nu - 1) * xp.log(rho + z),
        "sxz": -2 * z * z * inv_v / rho,
        "syz": -2 * z * z * inv_u / rho,
    }


def _shear_x_corner(u, v, z, nu, xp):
    """Corner functions of the stresses due to a unit shear q_x (force +x), x 4 pi."""
    rho = xp.sqrt(u * u + v * v + z * z)
    uz2, vz2 = u * u + z * z, v * v + z * z
    inv_v = _inv_plus(v, rho, uz2, xp)
    log_v = _log_plus(v, rho, uz2, xp)  # ln(v + rho)
    log_u = _log_plus(u, rho, vz2, xp)  # ln(u + rho)
    zeta = -xp.arctan2(u * v, z * rho)
    w_u = _w_u(u, v, z, rho, xp)  # int d_uu phi2 dv
    # int d_uu phi3 dv = d_u [-u ln(v + rho) + z W]
    w3_u = -log_v - u * u * inv_v / rho + z * w_u
    inv_z = 1.0 / (rho + z)
    return {
        "sxx": 4 * (nu + 1) * log_v - 2 * z * w_u + 4 * nu * w3_u,
        "syy": 2 * z * w_u - 4 * nu * w3_u + 2 * z * z * inv_v / rho,
        "szz": -2 * z * z * inv_v / rho,
        "sxy": 2 * log_u - 2 * z * u * inv_z / rho - 4 * nu * u * inv_z,
        "sxz": 2 * zeta - 2 * z * u * inv_v / rho,
        "syz": -2 * z / rho,
    }


def _corner_sum(corner_fn, x, y, a, b, z, nu, xp):
    out = {}
    parts = [
        (corner_fn(x + a, y + b, z, nu, xp), 1.0),
        (corner_fn(x - a, y + b, z, nu, xp), -1.0),
        (corner_fn(x + a, y - b, z, nu, xp), -1.0),
        (corner_fn(x - a, y - b, z, nu, xp), 1.0),
    ]
    for name in COMPONENTS:
        out[name] = sum(sign * part[name] for part, sign in parts) / (4 * np.pi)
    return out


def cell_stress(x, y, z, dx, dy, poisson, xp=jnp):
    """Stresses at `(x, y, z)` due to unit uniform tractions on the cell at the origin.

    **Arguments:**

    - `x`, `y`: field-point coordinates relative to the cell centre [length], arrays
      of one shape; the point must not lie on a cell edge line (`|x| = dx/2` or
      `|y| = dy/2`) when `z = 0`.
    - `z`: depth >= 0 [length] (scalar).
    - `dx`, `dy`: cell side lengths [length]; `poisson`: Poisson's ratio.
    - `xp`: array namespace (`numpy` for float64 even when JAX runs in float32).

    **Returns:** a dict `{"p": ..., "qx": ..., "qy": ...}`, each a dict over
    `("sxx", "syy", "szz", "sxy", "sxz", "syz")` of arrays shaped like `x`: the stress
    per unit traction (dimensionless) due to a unit pressure (force into the body),
    a unit shear traction along +x, and along +y. Tension positive.
    """
    a, b = dx / 2, dy / 2
    p = _corner_sum(_pressure_corner, x, y, a, b, z, poisson, xp)
    qx = _corner_sum(_shear_x_corner, x, y, a, b, z, poisson, xp)
    # q_y: the q_x field with the roles of x and y exchanged.
    swapped = _corner_sum(_shear_x_corner, y, x, b, a, z, poisson, xp)
    qy = {_SWAP[k]: val for k, val in swapped.items()}
    return {"p": p, "qx": qx, "qy": qy}


# ----------------------------------------------------------------------------------
# Result object
# ----------------------------------------------------------------------------------


@jax.jit
def _von_mises(sxx, syy, szz, sxy, sxz, syz):
    d = (sxx - syy) ** 2 + (syy - szz) ** 2 + (szz - sxx) ** 2
    return jnp.sqrt(0.5 * d + 3 * (sxy**2 + sxz**2 + syz**2))


@jax.jit
def _principal(sxx, syy, szz, sxy, sxz, syz):
    """Eigenvalues (ascending, last axis) of symmetric 3 x 3 tensors.

    Closed form (trigonometric solution of the characteristic cubic; Smith 1961):
    vectorised and much cheaper than `jnp.linalg.eigvalsh` on many small matrices.
    Where two principal stresses coincide the error is about `sqrt(eps)` of the
    deviatoric stress (1e-8 in float64, 3e-4 in float32).
    """
    q = (sxx + syy + szz) / 3
    dxx, dyy, dzz = sxx - q, syy - q, szz - q
    p = jnp.sqrt((dxx**2 + dyy**2 + dzz**2 + 2 * (sxy**2 + sxz**2 + syz**2)) / 6)
    safe = jnp.where(p > 0, p, 1.0)
    det = (
        dxx * (dyy * dzz - syz**2)
        - sxy * (sxy * dzz - syz * sxz)
        + sxz * (sxy * syz - dyy * sxz)
    )
    r = jnp.clip(det / (2 * safe**3), -1.0, 1.0)
    phi = jnp.arccos(r) / 3
    high = q + 2 * p * jnp.cos(phi)
    low = q + 2 * p * jnp.cos(phi + 2 * jnp.pi / 3)
    return jnp.stack([low, 3 * q - high - low, high], axis=-1)


class Stress(eqx.Module):
    """Stress tensor below the surface, returned by `jc.subsurface_stress`.

    Each component has shape `(nx, ny)` for a scalar `depth`, or `(nz, nx, ny)` for
    `nz` depths; units of the tractions; tension positive; z into the body.

    - `sxx`, `syy`, `szz`, `sxy`, `sxz`, `syz`: the six components.
    - `depth`: `()` or `(nz,)` [length].
    - `von_mises` (property): `sqrt(((sxx-syy)^2 + (syy-szz)^2 + (szz-sxx)^2)/2
      + 3 (sxy^2 + sxz^2 + syz^2))`.
    - `principal` (property): principal stresses, ascending, shape `(..., 3)`.
    - `max_shear` (property): `(s_max - s_min) / 2` (Tresca; Johnson's `tau_1`).
    """

    sxx: Float[Array, "*nz nx ny"]
    syy: Float[Array, "*nz nx ny"]
    szz: Float[Array, "*nz nx ny"]
    sxy: Float[Array, "*nz nx ny"]
    sxz: Float[Array, "*nz nx ny"]
    syz: Float[Array, "*nz nx ny"]
    depth: Float[Array, "*nz"]

    @property
    def von_mises(self) -> Float[Array, "*nz nx ny"]:
        return _von_mises(self.sxx, self.syy, self.szz, self.sxy, self.sxz, self.syz)

    @property
    def tensor(self) -> Float[Array, "*nz nx ny 3 3"]:
        """The symmetric tensor, shape `(..., 3, 3)` (axes x, y, z)."""
        rows = [
            jnp.stack([self.sxx, self.sxy, self.sxz], axis=-1),
            jnp.stack([self.sxy, self.syy, self.syz], axis=-1),
            jnp.stack([self.sxz, self.syz, self.szz], axis=-1),
        ]
        return jnp.stack(rows, axis=-2)

    @property
    def principal(self) -> Float[Array, "*nz nx ny 3"]:
        """Principal stresses, ascending, `(..., 3)` (see `_principal`)."""
        return _principal(self.sxx, self.syy, self.szz, self.sxy, self.sxz, self.syz)

    @property
    def max_shear(self) -> Float[Array, "*nz nx ny"]:
        s = self.principal
        return 0.5 * (s[..., 2] - s[..., 0])

    def to_xarray(self, grid, *, units=None, attrs=None):
        """This stress field as a labelled `xarray.Dataset`.

        **Arguments:**

        - `grid`: the `jc.Grid` of the tractions (for the `x`, `y` coordinates).
        - `units`: unit labels, `None` / `"SI"` (m, Pa) or a dict (see
          `jc.Solution.to_xarray`); nothing is converted.
        - `attrs`: extra global attributes.

        **Returns:** a Dataset with dimensions `depth` (when several depths were
        asked for; else `depth` is a scalar coordinate), `x`, `y`; coordinates
        `depth`, `x`, `y` [length]; variables `sxx`, `syy`, `szz`, `sxy`, `sxz`,
        `syz`, `von_mises` and `max_shear` [stress, tension positive], each with
        `units` and `long_name`.
        """
        from ._dataset import stress_dataset

        return stress_dataset(self, grid, units=units, attrs=attrs)


# ----------------------------------------------------------------------------------
# Convolution
# ----------------------------------------------------------------------------------


def _corner_differences(f, xp):
    """`f[s+1, t+1] - f[s, t+1] - f[s+1, t] + f[s, t]` over the last two axes."""
    return f[..., 1:, 1:] - f[..., :-1, 1:] - f[..., 1:, :-1] + f[..., :-1, :-1]


def _kernel_spectra(grid: Grid, z, poisson, loads, xp):
    """The stress coefficients at depth `z` in `dc_forward`'s layout: `{load: (6, Lx,
    Ly // 2 + 1)}` (`(Lx, Ly) = padded_shape`).

    The corner functions are evaluated once on the `(2nx+1) x (2ny+1)` cell corners of
    the offsets `-nx .. nx-1` (each corner is shared by four cells), differenced into
    cell coefficients and laid out in wrap-around order (offsets `-(n-1) .. n-1`: the
    linear convolution of `n` cells uses no other).
    """
    nx, ny = grid.shape
    lx, ly = padded_shape(grid.shape)
    dx, dy = grid.spacing
    if xp is np:
        dx, dy, z, poisson = float(dx), float(dy), float(z), float(poisson)
    cx = (xp.arange(2 * nx + 1) - nx - 0.5) * dx
    cy = (xp.arange(2 * ny + 1) - ny - 0.5) * dy
    u, v = xp.meshgrid(cx, cy, indexing="ij")
    corners = {}
    if "p" in loads:
        corners["p"] = _pressure_corner(u, v, z, poisson, xp)
    if "qx" in loads:
        corners["qx"] = _shear_x_corner(u, v, z, poisson, xp)
        # q_y: the q_x field with the roles of x and y exchanged.
        swapped = _shear_x_corner(v, u, z, poisson, xp)
        corners["qy"] = {_SWAP[k]: val for k, val in swapped.items()}
    dtype = grid.size.dtype
    cdtype = jnp.result_type(dtype, jnp.complex64)
    out = {}
    for load in loads:
        f = xp.stack([corners[load][c] for c in COMPONENTS]) / (4 * np.pi)
        coeff = _corner_differences(f, xp)  # offsets -n .. n-1, sorted
        coeff = _wraparound(_wraparound(coeff, nx, lx, -2, xp), ny, ly, -1, xp)
        out[load] = jnp.asarray(xp.fft.rfft2(coeff), dtype=cdtype)
    return out


def _wraparound(coeff, n, length, axis, xp):
    """Sorted offsets `-n .. n-1` along `axis` to wrap-around order on `length >=
    2n - 1` entries: `0 .. n-1`, zeros, `-(n-1) .. -1`."""
    coeff = xp.moveaxis(coeff, axis, -1)
    zeros = xp.zeros(coeff.shape[:-1] + (length - 2 * n + 1,), coeff.dtype)
    out = xp.concatenate([coeff[..., n:], zeros, coeff[..., 1:n]], axis=-1)
    return xp.moveaxis(out, -1, axis)


def _tractions_hat(pressure, shear):
    """Padded spectra of the tractions in use: `{"p": ..., ["qx": ..., "qy": ...]}`."""
    fft_shape = padded_shape(pressure.shape)
    out = {"p": dc_forward(pressure, fft_shape)}
    if shear is not None:
        out["qx"] = dc_forward(shear[0], fft_shape)
        out["qy"] = dc_forward(shear[1], fft_shape)
    return out


def _stress_from_spectra(spectra, traction_hat, nx, ny):
    """`(6, nx, ny)` stresses: sum over loads of kernel spectrum x traction spectrum."""
    total = 0.0
    for load, t_hat in traction_hat.items():
        total = total + spectra[load] * t_hat[None]
    return dc_inverse(total, (nx, ny), padded_shape((nx, ny)))


@jax.jit
def _concrete_depth(spectra, pressure, shear):
    """One depth from precomputed kernel spectra (jitted: one compile per grid
    shape)."""
    nx, ny = pressure.shape
    return _stress_from_spectra(spectra, _tractions_hat(pressure, shear), nx, ny)


@jax.jit
def _split(stacked):
    return tuple(stacked[..., i, :, :] for i in range(len(COMPONENTS)))


def subsurface_stress(
    grid: Grid,
    pressure: Float[Array, "nx ny"],
    shear: Float[Array, "2 nx ny"] | None = None,
    *,
    poisson,
    depth,
) -> Stress:
    """Stress tensor in the half-space at one or several depths below the surface.

    **Main arguments:**

    - `grid`: the (non-periodic) `jc.Grid` of the tractions.
    - `pressure`: `(nx, ny)` contact pressure `p` (compressive, pushes into the body)
      [stress], e.g. `sol.pressure[k]`.
    - `shear`: optional `(2, nx, ny)` shear traction `(q_x, q_y)` on the half-space
      [stress], e.g. `sol.shear[k]`. `None`: frictionless.

    **Other arguments:**

    - `poisson`: Poisson's ratio of the half-space (the stress due to given tractions
      does not depend on the shear modulus, nor on time for a viscoelastic material
      with constant Poisson's ratio).
    - `depth`: a depth `z >= 0` [length] (scalar), or a 1-D array of `nz` depths
      (e.g. `jnp.linspace(0, 2 * a, 41)` for an x-z map). `z = 0` is the limit from
      inside the body.

    **Returns:** a `Stress` whose components have shape `(nx, ny)` (scalar depth) or
    `(nz, nx, ny)`, in the units of the tractions, tension positive. The stress is
    evaluated at the cell-centre positions `(grid.x, grid.y)` at each depth.

    Cost per depth: one kernel build (`2nx x 2ny` closed forms, 3 x 6 rfft2) and 6
    inverse FFTs of the padded grid (`padded_shape`). Several depths are processed
    one after another (`lax.map` when traced), so memory does not grow with `nz`.

    **Raises:** `ValueError` for a periodic grid, shape mismatches, a negative or
    non-finite depth, or a Poisson's ratio outside `(-1, 0.5]`; `TypeError` for
    non-real input.
    """
    if not isinstance(grid, Grid):
        raise TypeError(f"grid must be a jc.Grid, got {type(grid).__name__}")
    if grid.periodic:
        raise ValueError(
            "subsurface_stress supports non-periodic grids only (DC-FFT), got a "
            "periodic grid"
        )
    nx, ny = grid.shape
    dtype = grid.size.dtype
    pressure = _validate.as_float_array("pressure", pressure, dtype=dtype)
    if pressure.shape != (nx, ny):
        raise ValueError(
            f"pressure must have the grid's shape {(nx, ny)}, got {pressure.shape}"
        )
    if shear is not None:
        shear = _validate.as_float_array("shear", shear, dtype=dtype)
        if shear.shape != (2, nx, ny):
            raise ValueError(
                f"shear must have shape (2, nx, ny) = {(2, nx, ny)}, got {shear.shape}"
            )
    poisson = _validate.scalar(
        "poisson",
        _validate.poisson_ratio(
            "poisson", _validate.as_float_array("poisson", poisson, dtype=dtype)
        ),
    )
    depth = _validate.non_negative(
        "depth", _validate.as_float_array("depth", depth, dtype=dtype)
    )
    if depth.ndim > 1:
        raise ValueError(
            f"depth must be a scalar or a 1-D array, got shape {depth.shape}"
        )

    loads = ("p",) if shear is None else ("p", "qx", "qy")
    depths = jnp.atleast_1d(depth)
    concrete = not _validate.is_traced((grid.size, depth, poisson))
    if concrete:
        # Kernels in float64 NumPy, one depth at a time (memory independent of nz).
        stacked = jnp.stack(
            [
                _concrete_depth(
                    _kernel_spectra(grid, z, poisson, loads, np), pressure, shear
                )
                for z in np.asarray(depths, dtype=np.float64)
            ]
        )
    else:
        traction_hat = _tractions_hat(pressure, shear)

        def one_depth(z):
            spectra = _kernel_spectra(grid, z, poisson, loads, jnp)
            return _stress_from_spectra(spectra, traction_hat, nx, ny)

        stacked = jax.lax.map(one_depth, depths)
    if depth.ndim == 0:
        stacked = stacked[0]
    return Stress(depth=depth, **dict(zip(COMPONENTS, _split(stacked))))
