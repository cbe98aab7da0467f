"""`jc.PronyFit`, the result of a fit, and the layout of its per-parameter values:
the arms sorted by relaxation time, fixed parameters given zeros, the covariance
permuted from the optimiser's order to `PronyFit.parameter_names`."""

import equinox as eqx
import numpy as np

from .._material.prony import Prony
from .parametrisation import split


class PronyFit(eqx.Module):
    """The result of `jc.fit_prony`.

    - `material`: the fitted `jc.Prony` (`g_inf`, `g`, `tau` sorted by `tau`).
    - `initial`: the `jc.Prony` the optimiser started from.
    - `loss`: the final loss (mean squared residual relative to `rms(target)`).
    - `loss_history`: loss at the start and after every accepted Adam and L-BFGS
      step (`(n_iter + 1,)`), or (LM) at the start and the end of every LM run.
    - `optimiser`: what ran: `"lm"`, `"lbfgs"` or `"lbfgs+lm"` (auto, LM took over);
      `adam_steps`, `lbfgs_steps`, `lm_steps`:
      iterations taken; `evaluations`: model evaluations outside the LM solve (one
      forward and one adjoint solve each; a whole LM solve counts as one).
    - `converged`: `True` when the result is certified a minimum: the Gauss-Newton
      step at the result (from the Jacobian of `std`) promises less than a 1e-3
      relative decrease of the loss, no parameter at a boundary of the
      log-parametrisation can lower it, and every contact solve converged;
      `message` says why the optimiser stopped and what the certificate found.
    - `solves_converged`: every contact step of the final model run converged.
    - `times`, `target`, `curve`: `(nt,)` data times, fitted data (force or depth)
      and the fitted model's curve; `residual = curve - target`. `kind`: `"force"` or
      `"depth"`.
    - `std`: dict `g_inf`, `g`, `tau` (and `poisson` when fitted): Gauss-Newton
      standard deviation of the natural LOG of each parameter (~ relative standard
      deviation): `Cov = sigma^2 (J^T J)^-1` with `J` the Jacobian of the relative
      residual in the logs (central differences, `2 p` evaluations) and `sigma` the
      noise (`noise_std`, or estimated from the residual as `sqrt(SSR / (n - p))`);
      `inf` for a parameter the data do not determine.
    - `covariance`: `(p, p)` Gauss-Newton covariance of the natural logs of the
      parameters, in the order `parameter_names` (`g_inf`, `g_1..g_n`, `tau_1..tau_n`
      sorted by tau, then `poisson` when fitted); `std` is the root of its diagonal;
      `inf` in the rows of undetermined parameters.
    - `gradient`: dict with the same keys: `d(loss)/d(log param)` at the result (0 at
      an exact minimum: a check of convergence, not an uncertainty).
    - `noise`: the noise level used for `std` [units of the data].
    - `discretisation`: with `check_grid=True`, the RMS difference between the
      fitted model's curve on the fit's grid and on a grid twice as fine (same
      width) [units of the data]: the model's own discretisation error, a bias the
      fit cannot remove; compare it with `noise`. `None` otherwise. On rings: the
      difference to twice the rings over the same radius.
    - `solver`: the contact model that ran, `"rings"` (`solve_axisymmetric`) or
      `"grid"` (`jc.solve` on the template's grid); `rings`, `ring_radius`: its
      ring count and outer radius [length] (`None` on the grid).
    """

    material: Prony
    initial: Prony
    loss: float
    loss_history: np.ndarray
    adam_steps: int
    lbfgs_steps: int
    lm_steps: int
    optimiser: str
    evaluations: int
    converged: bool
    message: str
    solves_converged: bool
    times: np.ndarray
    target: np.ndarray
    curve: np.ndarray
    residual: np.ndarray
    kind: str
    std: dict
    covariance: np.ndarray
    parameter_names: tuple
    gradient: dict
    noise: float
    discretisation: float | None = None
    solver: str = "grid"
    rings: int | None = None
    ring_radius: float | None = None

    def to_xarray(self, *, units=None, attrs=None):
        """This fit as a labelled `xarray.Dataset`.

        **Arguments:**

        - `units`: unit labels, `None` / `"SI"` (m, N, Pa, s) or a dict (see
          `jc.Solution.to_xarray`); nothing is converted.
        - `attrs`: extra global attributes.

        **Returns:** a Dataset with dimensions `time` (the data's times [time]),
        `arm` (the Maxwell arms, by increasing `tau`), `parameter` and `parameter_2`
        (`parameter_names`), `iteration`; variables `target`, `curve`, `residual`
        (on `time`, in force or length units by `kind`), the fitted `g_inf`, `g`,
        `tau`, `poisson` and the starting `initial_*` values, the Young's moduli
        `E_inf`, `E` (by arm) and `E_0` (`E = 2 G (1 + nu)`), `log_std` (this class's
        `std`; renamed: `Dataset.std` is a method) and `gradient` (of the natural
        logs, dimensionless), `covariance` (`parameter` x
        `parameter_2`) and `loss_history`; attributes `kind`, `loss`, `converged`
        and `solves_converged` (0 or 1: netCDF has no boolean attribute), `message`,
        `optimiser`, the step counts, `noise`, `discretisation` (NaN when not
        computed) and `material` (JSON).
        """
        from .._dataset import fit_dataset

        return fit_dataset(self, units=units, attrs=attrs)


def sorted_by_tau(material: Prony):
    """`(material, order)`: the arms sorted by relaxation time, and the order."""
    order = np.argsort(np.asarray(material.tau))
    return Prony(material.g_inf, material.g[order], material.tau[order],
                 material.poisson), order


def parameter_names(n: int, fit_poisson: bool) -> tuple:
    return (("g_inf",) + tuple(f"g_{i + 1}" for i in range(n))
            + tuple(f"tau_{i + 1}" for i in range(n))
            + (("poisson",) if fit_poisson else ()))


def sorted_split(theta, values, fixed: dict, order) -> dict:
    """The flat `values` (laid out like `theta`) per parameter, the arms in `order`;
    fixed parameters (not fitted: no spread, no gradient) zeros."""
    out = split(theta, values)
    for key in fixed:
        out[key] = np.zeros(np.shape(fixed[key]))
    out["g"], out["tau"] = out["g"][order], out["tau"][order]
    return out


def sorted_covariance(cov, theta, fixed: dict, order, fit_poisson: bool):
    """The covariance in the order g_inf, g_1..g_n, tau_1..tau_n (sorted by tau)
    [, poisson]: a permutation of ravel_pytree's (alphabetical keys) layout. Fixed
    parameters get rows and columns of zeros (index p: a padding slot)."""
    p_free = cov.shape[0]
    index = split(theta, np.arange(p_free))
    for key in fixed:
        index[key] = np.full(np.shape(fixed[key]), p_free)
    perm = np.concatenate([np.atleast_1d(index["g_inf"]), index["g"][order],
                           index["tau"][order]]
                          + ([np.atleast_1d(index["poisson"])] if fit_poisson else [])
                          ).astype(int)
    cov = np.pad(cov, ((0, 1), (0, 1)))
    return cov[np.ix_(perm, perm)]
