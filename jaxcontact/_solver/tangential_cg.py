r"""`TangentialCG`: tangential contact with isotropic Coulomb friction, a projected CG.

Problem (one step, pressure `p` given): find the shear traction `q` (`nd = 1` or `2`
components) with `|q_i| <= mu p_i` on every cell and the slip increment

    ds = A q + b - delta_t

equal to zero on stick cells (`|q_i| < mu p_i`) and opposite to `q` on slip cells
(`q_i = -mu p_i ds_i / |ds_i|`). `A = C K_tt` is the tangential compliance operator,
`b` collects the tangential displacement from the pressure (coupling), the loading
history and minus the previous slip (incremental law: `ds` is the slip INCREMENT), and
`delta_t` is the rigid tangential displacement: prescribed per direction
(displacement control) or the Lagrange multiplier of the load `A sum(q_d) = F_d`
(load control). These are the KKT conditions of the convex problem

    min_q  1/2 q.A q + q.(b - delta_t)   s.t.  |q_i| <= mu p_i,

so the solver is a projected CG in the spirit of Polonsky & Keer (1999):

- conjugate gradient steps on the stick set (directions made mean-free per
  load-controlled direction, which keeps the load);
- on slip cells, the projected gradient: the rotation of `q` along its disc (and the
  whole `ds` where the slip has the wrong sign, which releases the cell); the stick
  and slip parts form one search direction with an exact line search (one operator
  application);
- projection of every cell onto its friction disc; the load is then restored by a
  uniform shift of the stick cells;
- one operator application per iteration while the stick set is steady (the
  displacement is updated by linearity, and recomputed when the projection changed `q`
  outside the search direction); CG restarts when the stick set changes and after
  every exact displacement (the untracked projection and load-fix changes it takes
  in break the recurrence);
- preconditioned with one shear component (`nd = 1`, what `coupled.contact_step`
  passes on non-periodic grids): the direction on the stick and released cells is the
  full-plane inverse of `K_xx` (`precondition.shear_x_preconditioner`: the xx spectrum
  floored by the normal one, on the unpadded grid, raised to Cerruti's continuous
  symbol), made mean-free under load control (2-4x fewer iterations on
  Cattaneo-Mindlin: `benchmarks/notes/solvers.md`). With two components the diagonal
  stays: the FFT directions did not converge on a rotating oblique load history;
- convergence is tested on the Coulomb conditions AND on the loads: `residual =
  max(||violation||_2 / scale, max_d |A sum q_d - F_d| / (mu W))`, where the violation
  is `ds` on stick cells and the part of `ds` not opposite to `q` on slip cells.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from .._results import RESULTS
from .base import AbstractStepSolver, run
from .base import safe_div as _safe_div
from .residual import coulomb_residual, rigid_tangential_displacement
from .tangential import TangentialState, dot, project


def _norm(q):
    """Pointwise magnitude of an `(nd, nx, ny)` vector field."""
    return jnp.sqrt(dot(q, q))


class TangentialOperator:
    """What a tangential solve holds fixed (see `tangential_cg` for the arguments)."""

    def __init__(self, apply_fn, b, bound, force_control, target, cell_area,
                 self_compliance, *, rtol, precondition=None, skip=False):
        self.nd = nd = b.shape[0]
        if precondition is not None and nd != 1:
            raise ValueError(
                "tangential_cg: an FFT precondition needs one shear component, got "
                f"nd={nd}")
        self.apply_fn, self.b, self.bound = apply_fn, b, bound
        self.dtype = b.dtype
        self.force_control = tuple(force_control)
        self.fc = jnp.asarray(self.force_control)
        self.force_mask = self.fc[:, None, None]
        self.target = jnp.asarray(target, b.dtype)
        self.cell_area = cell_area
        self.self_compliance = self_compliance
        self.rtol = rtol
        self.precondition = precondition
        self.skip = skip  # stop at the first iterate (a batch member with no solution)
        self.contact = bound > 0
        self.bound_total = cell_area * jnp.sum(bound)  # mu W
        # A cell projected onto its disc must not count as stick by round-off (as in
        # `JointPCG.stick_tol`): 1 - 1e-10 is 1 in float32.
        self.stick_tol = max(1e-10, 64 * float(jnp.finfo(self.dtype).eps))

    def stick_of(self, q):
        return self.contact & (_norm(q) < self.bound * (1 - self.stick_tol))

    def fix_load(self, q):
        """Shift the stick cells (or, if none, all contact cells) to carry the load."""
        stick = self.stick_of(q)
        where = jnp.where(jnp.any(stick), stick, self.contact)
        count = jnp.sum(where)
        deficit = _safe_div(self.target / self.cell_area - jnp.sum(q, axis=(1, 2)),
                            count)
        shift = jnp.where(self.force_mask, deficit[:, None, None] * where[None], 0.0)
        return project(q + shift, self.bound)

    def evaluate(self, q, w):
        """`(ds, delta, stick, residual)` at the shear `q` with displacement `w`."""
        b, contact, target = self.b, self.contact, self.target
        stick = self.stick_of(q)
        q_hat = q * _safe_div(1.0, _norm(q))[None]
        delta = rigid_tangential_displacement(w, stick, q_hat, contact,
                                              self.force_control, target)
        ds = w - delta[:, None, None]
        slip_violation = ds + _norm(ds)[None] * q_hat
        scale = (jnp.sqrt(jnp.sum((w - b) ** 2))
                 + jnp.sqrt(jnp.sum(jnp.where(contact[None], b, 0) ** 2)))
        res = coulomb_residual(ds, slip_violation, stick, contact, scale,
                               self.cell_area * jnp.sum(q, axis=(1, 2)), target,
                               self.fc, self.bound_total)
        return ds, delta, stick, res


class _TangentialCGState(eqx.Module):
    q: Float[Array, "nd nx ny"]
    w: Float[Array, "nd nx ny"]  # A q + b
    ds: Float[Array, "nd nx ny"]
    t: Float[Array, "nd nx ny"]  # search direction
    g_old: Float[Array, ""]
    restart: Bool[Array, ""]
    it: Int[Array, ""]
    residual: Float[Array, ""]
    applications: Int[Array, ""]


class TangentialCG(AbstractStepSolver):
    """The uncoupled tangential projected CG (see the module docs), for a known
    pressure: the tangential half of every `jc.Rounds` round. Its problem is a
    `TangentialOperator`, not a whole step; its guess the starting shear `q0`
    `(nd, nx, ny)`; its output a `TangentialState`.

    **Arguments:** `rtol` (`None`: `1e-8` in float64, `1e-5` in float32), `max_steps`,
    `resync_every` (exact displacements this often).
    """

    rtol: float | None = eqx.field(static=True, default=None)
    max_steps: int = eqx.field(static=True, default=2000)
    resync_every: int = eqx.field(static=True, default=25)

    def supports(self, problem):
        if isinstance(problem, TangentialOperator):
            return None
        return ("it solves the tangential problem at a known pressure (a "
                "TangentialOperator); use jc.Rounds() for a whole step")

    def step_limit(self) -> int:
        return self.max_steps

    def setup(self, problem: TangentialOperator) -> TangentialOperator:
        return problem

    def init(self, problem, k: TangentialOperator, q0) -> _TangentialCGState:
        q0 = k.fix_load(project(q0, k.bound))
        w0 = k.apply_fn(q0) + k.b
        ds0, _, _, res0 = k.evaluate(q0, w0)
        return _TangentialCGState(
            q=q0, w=w0, ds=ds0, t=jnp.zeros_like(k.b), g_old=jnp.ones((), k.dtype),
            restart=jnp.array(True), it=jnp.array(0), residual=res0,
            applications=jnp.array(1))

    def terminate(self, problem, k, s):
        return (s.residual <= k.rtol) | k.skip, RESULTS.successful

    def step(self, problem, k: TangentialOperator, s: _TangentialCGState):
        nd, dtype, bound, rtol = k.nd, k.dtype, k.bound, k.rtol
        force_control, self_compliance = k.force_control, k.self_compliance
        apply_fn, b = k.apply_fn, k.b
        q, w = s.q, s.w
        stick = k.stick_of(q)
        q_hat = q * _safe_div(1.0, _norm(q))[None]
        # Free variables: stick cells (full vectors) and, on slip cells, the rotation
        # along the friction disc (tangent component). Slip cells whose slip has the
        # wrong sign (multiplier < 0) are released: free as full vectors.
        lam = -dot(s.ds, q_hat)
        slip_cells = k.contact & ~stick
        release = slip_cells & (lam < 0)
        full = stick | release
        rotate = slip_cells & ~release
        if nd == 1:
            tangent = jnp.zeros_like(q)
        else:
            tangent = jnp.stack([-q_hat[1], q_hat[0]])
        tt = jnp.where(rotate[None], tangent, 0)  # unit tangents on rotating cells
        ds = s.ds
        lam = jnp.maximum(-dot(ds, q_hat), 0.0)
        # Reduced gradient: ds on full cells, its tangential part on rotating cells.
        r = jnp.where(full[None], ds, tt * dot(tt, ds)[None])
        # Diagonal preconditioner: the rotation of a slip cell feels the disc
        # curvature lambda / bound on top of the self-compliance A_ii (the contact
        # edge, bound -> 0, would make the reduced problem ill-conditioned).
        curv_disc = jnp.where(rotate, _safe_div(lam, bound), 0.0)
        weight = jnp.where(full, 1.0, jnp.where(
            rotate, self_compliance / (self_compliance + curv_disc), 0.0))

        if k.precondition is not None:
            # Full-plane inverse on the free cells (nd = 1: no rotating cells), made
            # mean-free there under load control.
            z = jnp.where(full[None], k.precondition(r[0])[None], 0)
            if force_control[0]:
                mean = _safe_div(jnp.sum(z), jnp.sum(full))
                z = jnp.where(full[None], z - mean, 0)
        else:
            # Projection onto load-preserving directions, oblique in the
            # preconditioner's metric: z = P r - P B (B^T P B)^{-1} B^T P r
            # (symmetric, so CG stays valid).
            def basis(c):  # B c: c on full cells, (e_perp . c) e_perp on rotating ones
                return jnp.where(full[None], c[:, None, None],
                                 tt * jnp.einsum("i,iab->ab", c, tt)[None])

            eye = jnp.eye(nd, dtype=dtype)
            m = jnp.sum(jnp.where(full, weight, 0)) * eye + jnp.einsum(
                "ab,iab,jab->ij", weight, tt, tt)
            fc = k.fc
            both = fc[:, None] & fc[None, :]
            m = jnp.where(both, m, eye)
            pr = weight[None] * r
            rhs = jnp.where(fc, jnp.sum(pr, axis=(1, 2)), 0.0)
            empty = jnp.where(jnp.trace(jnp.where(both, m, 0.0)) > 0, 0.0, 1.0)
            coef = jnp.linalg.solve(m + empty * eye, rhs)
            z = pr - weight[None] * basis(jnp.where(fc, coef, 0.0))
        rz = jnp.sum(r * z)
        beta = jnp.where(s.restart, 0.0, _safe_div(rz, s.g_old))
        t = z + beta * s.t
        t = jnp.where(full[None], t, tt * dot(tt, t)[None])
        g_norm = rz
        at = apply_fn(t)
        curvature = jnp.sum(t * at) + jnp.sum(curv_disc * dot(t, t))
        tau = _safe_div(jnp.sum(r * t), curvature)
        q_step = q - tau * t
        w_new = w - tau * at
        q_new = project(q_step, bound)
        q_new = jax.lax.cond(jnp.any(k.fc), k.fix_load, lambda x: x, q_new)
        # Changes outside the search direction (projection, load fix) are not in the
        # tracked displacement: resync only when they matter at the current accuracy
        # (the final answer is always certified with an exact displacement).
        extra = jnp.max(jnp.abs(q_new - q_step))
        dirty = extra > 1e-3 * jnp.minimum(s.residual, 1.0) * jnp.max(bound)
        stick_new = k.stick_of(q_new)
        changed = jnp.any(stick_new != stick) | jnp.any(release)
        it = s.it + 1
        need_exact = dirty | (it % self.resync_every == 0)
        w_new = jax.lax.cond(need_exact, lambda: apply_fn(q_new) + b, lambda: w_new)
        ds_new, _, _, res = k.evaluate(q_new, w_new)

        def exact():
            w_e = apply_fn(q_new) + b
            ds_e, _, _, res_e = k.evaluate(q_new, w_e)
            return w_e, ds_e, res_e

        certify = (~need_exact) & (res <= rtol)
        w_new, ds_new, res = jax.lax.cond(certify, exact, lambda: (w_new, ds_new, res))
        # An exact displacement takes in the changes the recurrence did not see (the
        # projections, the load fix): the old direction is no longer conjugate.
        return _TangentialCGState(
            q=q_new, w=w_new, ds=ds_new, t=t, g_old=g_norm,
            restart=changed | need_exact | (certify & (res > rtol)), it=it,
            residual=res,
            applications=s.applications + 1 + need_exact + certify)

    def tangential_state(self, k: TangentialOperator, s) -> TangentialState:
        ds, delta, stick, res = k.evaluate(s.q, s.w)
        return TangentialState(
            shear=s.q, displacement=s.w - k.b, slip=ds, delta=delta, stick=stick,
            iterations=s.it, residual=res, converged=res <= k.rtol,
            applications=s.applications)

    def postprocess(self, problem, k, s, result) -> TangentialState:
        return self.tangential_state(k, s)


def tangential_cg(
    apply_fn,
    b: Float[Array, "nd nx ny"],
    bound: Float[Array, "nx ny"],
    force_control: tuple[bool, ...],
    target: Float[Array, " nd"],
    cell_area,
    self_compliance,
    *,
    q0: Float[Array, "nd nx ny"] | None = None,
    rtol: float,
    max_steps: int,
    resync_every: int = 25,
    precondition=None,
    skip=False,
) -> TangentialState:
    """Solve the tangential problem (see module docs) with `TangentialCG`.

    **Arguments:**

    - `apply_fn`: `q -> A q`, `(nd, nx, ny)` shear [stress] to tangential
      displacement [length].
    - `b`: fixed part of the slip increment [length], `(nd, nx, ny)`.
    - `bound`: `mu p` [stress], `(nx, ny)`; cells with `bound == 0` carry no shear.
    - `force_control`: per direction, `True` for load control (`target` is the force
      [force]) or `False` for displacement control (`target` is `delta_t` [length]).
    - `cell_area`: [length^2]; `self_compliance`: `A_ii`, the tangential displacement
      of a cell under its own unit shear [length/stress] (scales the preconditioner).
    - `q0`: warm start (projected and load-corrected).
    - `precondition`: `None` (the diagonal) or, for `nd = 1` only, `r -> M r`, an
      approximate inverse of `A_xx` on the whole grid, one component `(nx, ny) ->
      (nx, ny)` (`precondition.shear_x_preconditioner`), restricted to the
      stick and released cells and, under load control, made mean-free on them (as
      Polonsky & Keer's normal CG).
    - `skip`: a (traced) bool: stop at the first iterate (a member of a batch whose
      answer is taken from elsewhere, e.g. gross sliding).
    """
    k = TangentialOperator(apply_fn, b, bound, force_control, target, cell_area,
                           self_compliance, rtol=rtol, precondition=precondition,
                           skip=skip)
    solver = TangentialCG(rtol=rtol, max_steps=max_steps, resync_every=resync_every)
    return run(solver, k, jnp.zeros_like(b) if q0 is None else q0).output
