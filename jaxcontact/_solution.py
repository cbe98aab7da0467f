"""`jc.Solution`: the result of `jc.solve`, with time as the leading axis."""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from ._dataset import solution_dataset
from ._results import RESULTS as RESULTS


class Solution(eqx.Module):
    """Result of `jc.solve(scene)`. Leading axis: the scene's `times` (`nt`).

    - `times`: `(nt,)` [time].
    - `pressure`: `(nt, nx, ny)` contact pressure `p >= 0` [stress].
    - `shear`: `(nt, 2, nx, ny)` shear traction `(q_x, q_y)` on the half-space [stress].
    - `contact`: `(nt, nx, ny)` mask `p > 0`.
    - `stick`: `(nt, nx, ny)` mask of stick cells (`|q| < mu p`); all of the contact
      when nothing drives a tangential solve and `mu > 0`; empty when `mu = 0`.
    - `normal_force`: `(nt,)` load `W` [force]; `approach`: `(nt,)` rigid-body approach
      `delta_z` [length].
    - `tangential_force`: `(nt, 2)` `(F_x, F_y)` [force];
      `tangential_displacement`: `(nt, 2)` rigid tangential displacement
      `(delta_x, delta_y)` [length] (0 in a direction that is not solved).
    - `stick_ratio`: `(nt,)` stick area / contact area (0 with no contact).
    - `sliding`: `(nt,)` gross sliding (contact but no stick cell). Under strong
      coupling a load below `mu W` can leave no stick cell too (the shear directions
      fan out; e.g. nu = 0.1, F = 0.99 mu W in one step): it is flagged the same way.
      Never with friction 0 (concrete or traced).
    - `converged`, `iterations`, `rounds`, `residual`: `(nt,)` per-step solver status
      (inner CG iterations summed over the normal/tangential rounds).
    - `result`: `(nt,)` `jc.RESULTS`, how each step ended (`successful`, or why not);
      `fallbacks`: `(nt,)` secondary solvers run (`jc.Fallback`).
    - `method`: which solver ran: `"grid"` (the step solvers on the grid) or
      `"rings"` (the axisymmetric ring solver of a frictionless scene with an
      axisymmetric indenter, its ring pressures mapped onto the grid's cells).
    - `edge_contact` (property): `(nt,)` contact reaches the outer ring of cells.
    """

    times: Float[Array, " nt"]
    pressure: Float[Array, "nt nx ny"]
    shear: Float[Array, "nt 2 nx ny"]
    contact: Bool[Array, "nt nx ny"]
    stick: Bool[Array, "nt nx ny"]
    normal_force: Float[Array, " nt"]
    approach: Float[Array, " nt"]
    tangential_force: Float[Array, "nt 2"]
    tangential_displacement: Float[Array, "nt 2"]
    stick_ratio: Float[Array, " nt"]
    sliding: Bool[Array, " nt"]
    converged: Bool[Array, " nt"]
    iterations: Int[Array, " nt"]
    rounds: Int[Array, " nt"]
    residual: Float[Array, " nt"]
    result: RESULTS
    fallbacks: Int[Array, " nt"]
    method: str = eqx.field(static=True, default="grid")

    @property
    def edge_contact(self) -> Bool[Array, " nt"]:
        """`(nt,)`: some contact cell lies in the outer ring of cells of the grid.

        On a non-periodic grid this means the contact area reached the edge of the
        domain, so the solution of the isolated contact is truncated (wrong): enlarge
        the grid. (On a periodic grid there is no edge; ignore it.)
        """
        return edge_ring(self.contact)

    def to_xarray(self, scene, *, units=None, solve_options=None, batch=None,
                  attrs=None):
        """This solution as a labelled `xarray.Dataset` (write it with
        `ds.to_netcdf(path)`, read it back with `jc.load(path)`).

        **Main arguments:**

        - `scene`: the `jc.Scene` that was solved (the solution does not hold the
          grid): it gives the coordinates and the attributes.

        **Other arguments:**

        - `units`: the unit labels of the scene's inputs. jaxcontact is unit-agnostic
          (any consistent set; stress = force / length^2), so this only labels:
          `None` or `"SI"` (default: m, N, Pa, s, as the presets use) or a dict
          `{"length": "um", "force": "uN", "time": "s"}` (`"stress"` optional).
        - `solve_options`: the keyword arguments given to `jc.solve`, recorded as the
          JSON attribute `solve_options` (solver objects by their `repr`).
        - `batch`: for a `jc.sweep` result (a leading batch axis), coordinates along
          the `batch` dimension, e.g. `{"friction": mus}`.
        - `attrs`: extra global attributes (strings or numbers).

        **Returns:** an `xarray.Dataset` with

        - dimensions `time` (`nt`), `x` (`nx`), `y` (`ny`), `component` (`"x"`,
          `"y"`), and `batch` first for a sweep;
        - coordinates `time` [time], `x`, `y` (cell centres, `grid.x`, `grid.y`)
          [length], `component`; for a sweep whose `times` differ per member a 2-D
          coordinate `times` (batch, time) instead of `time`;
        - one variable per field of this class, same names and shapes (`shear` and
          the tangential vectors along `component`), plus `result` (the integer
          `jc.RESULTS` code, CF `flag_values` / `flag_meanings`), `edge_contact`
          and `initial_gap` (`(x, y)`, the indenter's gap `h0` [length]); each with
          `units` and `long_name` attributes (masks, counts and ratios: `"1"`);
        - attributes: `scene` (JSON: grid, indenter, material, the loads evaluated
          at the times, friction, coupling, slip), `material`, `indenter`, `loads`
          (JSON), `grid_shape`, `grid_size`, `grid_periodic`, `friction`, `coupling`,
          `slip`, `solve_options` (JSON), `dtype`, `jaxcontact_version`,
          `jax_version`, `versions` (JSON), `unit_system` (JSON).

        Booleans stay `bool` in memory; in a netCDF file xarray stores them as int8
        and `jc.load` / `xarray.open_dataset` decode them back.
        """
        return solution_dataset(self, scene, units=units, solve_options=solve_options,
                                batch=batch, attrs=attrs)


def edge_ring(contact: Bool[Array, "... nx ny"]) -> Bool[Array, "..."]:
    """True where any cell of the outer ring of the last two axes is set."""
    rows = jnp.any(contact[..., 0, :], axis=-1) | jnp.any(contact[..., -1, :], axis=-1)
    cols = jnp.any(contact[..., :, 0], axis=-1) | jnp.any(contact[..., :, -1], axis=-1)
    return rows | cols


def stick_ratio(contact: Bool[Array, "... nx ny"], stick: Bool[Array, "... nx ny"]
                ) -> Float[Array, "..."]:
    """Stick cells / contact cells over the last two axes (0 with no contact)."""
    n_contact = jnp.sum(contact, axis=(-2, -1))
    n_stick = jnp.sum(stick, axis=(-2, -1))
    return jnp.where(n_contact > 0, n_stick / jnp.maximum(n_contact, 1), 0.0)
