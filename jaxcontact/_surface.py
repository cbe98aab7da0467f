r"""`jc.surface_displacement`: the surface displacements of a solved scene, every step.

The displacement that `jc.solve` holds the gap and the slip to, rebuilt from the
solved tractions `tau_k = (q_x, q_y, p)` at the steps `t_k`:

    u(t_k) = K1 [ J_step(k) tau_k + H_k ]                    (paper Eqs. 12-13, 19-21)

with `K1` the half-space operator for unit shear modulus (`jc.HalfSpace`), `J_step`
the step's compliance and `H_k` the history traction of the past increments, both from
the hereditary scheme that `jc.solve` uses (`_history`: none for an elastic material,
`J_step = 1 / G`; the O(Nt) recursion for a creep series; the direct sum otherwise).
Because `K1` is linear, `J_step K1 tau_k + K1 H_k` is ONE operator application per
step. The pieces are those of `jc.solve` (`_history.history_for`,
`_solve.history_displacement`), so the field is the solver's, not a re-derivation of
it.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ._history import history_for
from ._operator import HalfSpace
from ._scene import Scene
from ._solution import Solution
from ._solve import history_displacement


_COUPLINGS = ("none", "x", "full")


def _as_dtype(tree, dtype):
    """Every floating array leaf of `tree` cast to `dtype` (as `jc.solve` does with the
    material: the time-stepping carry keeps the grid's dtype)."""
    return jax.tree_util.tree_map(
        lambda leaf: leaf.astype(dtype)
        if isinstance(leaf, (jax.Array, np.ndarray))
        and jnp.issubdtype(leaf.dtype, jnp.floating)
        else leaf,
        tree,
    )


@eqx.filter_jit
def _displacements(operator, material, times, traction, history, scheme):
    dtype = traction.dtype
    nt = times.shape[0]
    material = _as_dtype(material, dtype)
    poisson = material.poisson
    hereditary = history_for(material, times, history, scheme)
    steps_dt = jnp.concatenate([jnp.zeros((1,), dtype), jnp.diff(times)])
    nd = 0 if operator.coupling == "normal" else 2

    def step(carry, inputs):
        tau_prev, state = carry
        tau_new, k, dt = inputs
        prepared = hereditary.prepare(state, tau_prev, k, dt)
        combined = prepared.compliance.astype(dtype) * tau_new
        if prepared.traction is not None:
            combined = combined + prepared.traction
        u = history_displacement(operator, poisson, combined, nd)
        state = hereditary.update(state, tau_prev, tau_new, k, dt)
        return (tau_new, state), u

    shape = traction.shape[1:]
    init = (jnp.zeros(shape, dtype), hereditary.init(shape, dtype))
    _, u = jax.lax.scan(step, init, (traction, jnp.arange(nt), steps_dt))
    return u


def surface_displacement(
    scene: Scene,
    solution: Solution,
    *,
    coupling: str | None = None,
    scheme: str = "constant",
    history: str = "auto",
    operator: HalfSpace | None = None,
) -> Float[Array, "nt 3 nx ny"]:
    """Surface displacements `(u_x, u_y, u_z)` of the half-space at every step.

    **Main arguments:**

    - `scene`: the `jc.Scene` that was solved.
    - `solution`: its `jc.Solution` (from `jc.solve(scene)`).

    **Other arguments:**

    - `coupling`: which normal-tangential blocks of the half-space operator to apply.
      `None` (default): the scene's `coupling` (`"none"`, `"x"` or `"full"`), the
      displacement the solver held the gap and the slip to: with it, inside the contact
      `u_z = approach - h0` (the gap closes) and in the stick zone `u_x, u_y` follow the
      rigid tangential displacement. `"full"`: all nine blocks whatever the scene's
      model, e.g. the inward radial displacement that a pressure causes in a
      compressible body (`nu < 0.5`), which a `coupling="none"` scene neglects (with
      shear present the gap then need not close exactly in the contact).
    - `scheme`, `history`: the hereditary scheme and sum, as passed to `jc.solve`
      (defaults the same: `"constant"`, `"auto"`). They must match the solve's:
      `"linear"` and `"constant"` give different displacements from the same tractions.
    - `operator`: a prebuilt `jc.HalfSpace` for the scene's grid (its `coupling` then
      decides, `coupling` must be `None`); built here if omitted.

    **Returns:** an `(nt, 3, nx, ny)` array [length], the components `(u_x, u_y, u_z)`
    at the cell centres, `u_z > 0` into the body (the convention of the gap
    `h = h0 + u_z - approach`, paper Eq. 15). A component whose blocks the coupling does
    not include comes out as zeros (`u_y` for `coupling="x"`; `u_x`, `u_y` of a
    frictionless `coupling="none"` scene).

    **Cost:** one operator application (a forward and an inverse FFT per traction and
    displacement component in use) per step: for an elastic material `u = K1 tau / G`;
    for a viscoelastic one the hereditary integral
    `u(t_k) = K1 sum_{n <= k} J(t_k - t_n) (tau_n - tau_{n-1})` (paper Eqs. 12-13),
    carried step to step by the same recursion as `jc.solve` (the direct O(Nt^2) sum
    for a material without a creep series), so every step costs one convolution of a
    combined traction, never one per past step. Memory: the result,
    `nt * 3 * nx * ny` numbers.

    **Raises:** `TypeError` for a scene, solution or operator of the wrong kind;
    `ValueError` for a solution of another shape or time axis than the scene's, an
    operator built for another grid, or an unknown `coupling`, `scheme` or `history`.
    """
    if not isinstance(scene, Scene):
        raise TypeError(f"scene must be a jc.Scene, got {scene!r}")
    if not isinstance(solution, Solution):
        raise TypeError(f"solution must be a jc.Solution, got {solution!r}")
    if scheme not in ("constant", "linear"):
        raise ValueError(f'scheme must be "constant" or "linear", got {scheme!r}')
    if history not in ("auto", "recursive", "direct"):
        raise ValueError(
            f'history must be "auto", "recursive" or "direct", got {history!r}')
    grid = scene.grid
    dtype = grid.size.dtype
    nx, ny = grid.shape
    nt = scene.times.shape[0]
    pressure = jnp.asarray(solution.pressure)
    shear = jnp.asarray(solution.shear)
    if pressure.shape != (nt, nx, ny) or shear.shape != (nt, 2, nx, ny):
        raise ValueError(
            f"solution has pressure {pressure.shape} and shear {shear.shape}; the "
            f"scene needs ({nt}, {nx}, {ny}) and ({nt}, 2, {nx}, {ny}) (its times and "
            "grid)")
    if operator is not None:
        if not isinstance(operator, HalfSpace):
            raise TypeError(f"operator must be a jc.HalfSpace, got {operator!r}")
        if coupling is not None:
            raise ValueError("give coupling or operator, not both (the operator's "
                             "coupling decides)")
        g = operator.grid
        if g.shape != grid.shape or g.periodic != grid.periodic:
            raise ValueError(
                f"operator was built for a {g.shape} grid (periodic={g.periodic}), the "
                f"scene's grid is {grid.shape} (periodic={grid.periodic})")
    else:
        coupling = scene.coupling if coupling is None else coupling
        if coupling not in _COUPLINGS:
            raise ValueError(
                f"coupling must be None or one of {_COUPLINGS}, got {coupling!r}")
        # Every displacement component the coupling has: u_y too for `"none"` (from
        # q_x through the xy block, which a solve in x alone does not need); `"x"`
        # holds no y blocks (semi-coupled: q_y = 0, u_y not modelled).
        operator = HalfSpace(grid, coupling, tangential_y=True)
    times = jnp.asarray(scene.times).astype(dtype)
    traction = jnp.concatenate(
        [shear.astype(dtype), pressure.astype(dtype)[:, None]], axis=1)
    return _displacements(operator, scene.material, times, traction, history, scheme)
