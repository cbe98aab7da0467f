"""`jc.FitOptions`: how `jc.fit_prony` and `jc.fit_prony_batch` optimise (which
optimiser, its step bounds and tolerances, the contact solve's keywords), as one
immutable object checked when it is made. The problem itself (data, model, start,
fixed and bounded parameters, weights, noise) stays in the fit's own keywords."""

import dataclasses
import math
from collections.abc import Mapping

import numpy as np

from .._validate import check_int


# The contact models a fit can run on (`solver`): see `FitOptions`.
SOLVERS = ("auto", "rings", "grid")


OPTIMISERS = ("auto", "lm", "lbfgs")


def _check_bool(name, value):
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be True or False, got {value!r}")
    return bool(value)


@dataclasses.dataclass(frozen=True)
class FitOptions:
    """The optimiser's settings of `jc.fit_prony` (and `jc.fit_prony_batch`), e.g.
    `jc.fit_prony(data, template, 2, options=jc.FitOptions(optimiser="lm",
    lm_steps=200))`. Immutable: `dataclasses.replace(options, lm_steps=50)` makes a
    changed copy. Every value is checked here (`TypeError` / `ValueError` naming it).

    **Arguments:**

    - `optimiser`: `"auto"` (default; `None` means the same), `"lm"` or `"lbfgs"`.
        - `"lbfgs"`: Adam, then L-BFGS with Armijo backtracking, driven from Python
          (`adam_steps` ... `precondition` are for it).
        - `"lm"`: Levenberg-Marquardt (`optimistix.LevenbergMarquardt` on the
          relative residual, Jacobian by forward mode, one compiled solve; at most
          `lm_steps` steps). Needs optimistix (`pip install "jaxcontact[fit]"`).
        - `"auto"`: L-BFGS, then LM from its result when that is not certified a
          minimum (see `jc.PronyFit.converged`) and optimistix is installed; on
          rings (`solver`), LM alone (its forward-mode Jacobian is cheap there).
      Measured (float64, quiet 2-core CPU): from the default start on the PMMA step,
      64^2 x 40, L-BFGS 6.8 s compiled (13.7 s with compilation), LM 7.1 s (18.7 s),
      13 steps: its Jacobian costs one tangent solve per parameter per step (33.1 s
      with one adjoint per sample, `benchmarks/README.md`). From far
      starts (1 arm, 1 % noise, the closed-form stand-in, 24 starts 0.2-5x off) LM
      reaches the minimum from every start; preconditioned L-BFGS stalls on creep
      data from 2 of 12 (one at its iteration bound, reported NOT converged), where
      `"auto"` hands over to LM.
    - `adam_steps` (default 10), `learning_rate`: the Adam phase (the best point is
      kept). The step size is in the optimiser's coordinates: default
      `0.1 sqrt(2 loss_0)` when preconditioned (a tenth of the distance to the
      optimum), `0.02` in log-parameters otherwise; given, a number in (0, 10).
    - `lbfgs_steps` (default 100): bound on the L-BFGS iterations. Stops early when
      the largest `|d loss / d log param|` falls below `gtol` (default `1e-12` in
      float64, `1e-6` in float32; given, a number >= 0), when a step changes no
      log-parameter by more than 1e-12, or when the line search can no longer
      decrease the loss (the model's own solver tolerance is reached).
    - `precondition` (default `True`): run Adam and L-BFGS in coordinates whitened
      by the Gauss-Newton Hessian at the start (`2 p` extra evaluations; usually
      saves many more).
    - `lm_steps` (default 100, >= 1): bound on the Levenberg-Marquardt steps of
      every LM run. A run longer than 25 steps also stops, NOT converged
      ("stalled"), after 25 steps that lowered the loss by less than 1e-4 of itself
      (a parameter creeping along a valley the data do not determine).
    - `solve_options`: keywords for `jc.solve` (`rtol`, `scheme`, ...; not
      `operator`: the fit builds it). The default scheme of a fit is `"linear"`
      (samples joined by ramps; stable at any step); `"constant"` treats every sample
      as a step, and a fit that ends with a material for which the data's steps are
      unstable under it warns (`jc.TimeStepWarning`). Held as a copy.
    - `check_grid` (default `False`): also solve the fitted model at twice the
      resolution (a grid twice as fine, or twice the rings; one more compilation)
      and report the difference (`jc.PronyFit.discretisation`).
    - `solver`: the contact model's discretisation. `"auto"` (default) solves a
      frictionless axisymmetric probe (`jc.Sphere`, `jc.Cone`, ...) on `rings`
      rings (`solve_axisymmetric`: a 1-D problem, at the grid's accuracy in a
      small fraction of its time, `benchmarks/rings.py`) and anything else on the
      template's grid; `"grid"` always solves on the template's grid; `"rings"`
      forces the rings (a `ValueError` naming why where they cannot solve the
      scene). `jc.PronyFit.solver` says which ran.
    - `rings` (default 64, >= 4): rings of equal width over `RING_MARGIN` (1.25)
      times the radius where the probe's profile reaches the deepest indentation.
    """

    optimiser: str = "auto"
    adam_steps: int = 10
    learning_rate: float | None = None
    lbfgs_steps: int = 100
    gtol: float | None = None
    precondition: bool = True
    lm_steps: int = 100
    solve_options: dict | None = None
    check_grid: bool = False
    solver: str = "auto"
    rings: int = 64

    def __post_init__(self):
        def put(name, value):
            object.__setattr__(self, name, value)

        optimiser = "auto" if self.optimiser is None else self.optimiser
        if not isinstance(optimiser, str) or optimiser not in OPTIMISERS:
            raise ValueError(
                f"optimiser must be 'auto', 'lm' or 'lbfgs', got {optimiser!r}")
        put("optimiser", optimiser)
        put("adam_steps", check_int("adam_steps", self.adam_steps, 0))
        put("lbfgs_steps", check_int("lbfgs_steps", self.lbfgs_steps, 0))
        put("lm_steps", check_int("lm_steps", self.lm_steps, 1))
        rate = self.learning_rate
        if rate is not None and not (isinstance(rate, (int, float))
                                     and not isinstance(rate, bool) and 0 < rate < 10):
            raise ValueError(f"learning_rate must be a number in (0, 10), got {rate!r}")
        gtol = self.gtol
        if gtol is not None and (isinstance(gtol, bool) or not isinstance(
                gtol, (int, float, np.integer, np.floating))
                or not 0 <= gtol < math.inf):
            raise ValueError(f"gtol must be None or a number >= 0, got {gtol!r}")
        put("precondition", _check_bool("precondition", self.precondition))
        put("check_grid", _check_bool("check_grid", self.check_grid))
        if self.solver not in SOLVERS:
            raise ValueError(f"solver must be 'auto', 'rings' or 'grid', got "
                             f"{self.solver!r}")
        put("rings", check_int("rings", self.rings, 4))
        if self.solve_options is not None:
            if not isinstance(self.solve_options, Mapping):
                raise TypeError(f"solve_options must be a dict of jc.solve keywords "
                                f"or None, got {self.solve_options!r}")
            if "operator" in self.solve_options:
                raise ValueError("fit_prony builds the operator itself: leave "
                                 "'operator' out of solve_options")
            put("solve_options", dict(self.solve_options))


_FIELDS = tuple(f.name for f in dataclasses.fields(FitOptions))


def with_legacy(options, legacy: dict, caller: str) -> FitOptions:
    """`options` with the optimiser keywords given the old way (`lm_steps=...` as a
    keyword of the fit, still accepted) put in: `dataclasses.replace`, so that they
    are checked alike; a keyword that is no field of `FitOptions` is a `TypeError`."""
    if options is None:
        options = FitOptions()
    if not isinstance(options, FitOptions):
        raise TypeError(f"options must be a jc.FitOptions, got {options!r}")
    for name in legacy:
        if name not in _FIELDS:
            raise TypeError(f"{caller}() got an unexpected keyword argument {name!r}")
    return dataclasses.replace(options, **legacy) if legacy else options
