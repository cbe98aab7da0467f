"""Fitting a Prony series to indentation data through the full contact model
(`jc.fit_prony`, `jc.fit_prony_batch`, `jaxcontact fit`), one job per module:

- `data`: `IndentationData` and the scene on the data's times;
- `options`: `FitOptions`, the optimiser's settings;
- `parametrisation`: the fit's coordinates <-> `jc.Prony` (logs, bounds, fixed);
- `model`: the contact model as a function of them, the compiled objective;
- `rings_model`: the same model on rings (`solve_axisymmetric`) for a frictionless
  axisymmetric probe, and the choice between rings and grid (`FitOptions.solver`);
- `start`: the start from the data, `lee_radok_start`;
- `lbfgs`, `lm`: the optimisers (Adam + L-BFGS from Python; Levenberg-Marquardt);
- `certificate`: boundary probes, the convergence certificate, the covariance;
- `result`: `PronyFit`; `discretisation`: the grid check;
- `fit`: `fit_prony`, the driver; `batch`: `fit_prony_batch`;
- `afm`: one AFM curve fitted as `jaxcontact fit` does (`fit_afm_curve`,
  `AFMFitSettings`), shared by the command line and `jc.fit_force_map`;
- `quality`: the quality verdict, flags and Young's moduli of a fitted AFM curve;
- `uncertainty`: the contact point's and the grid's share of its uncertainty.
"""

from .batch import fit_prony_batch as fit_prony_batch
from .data import IndentationData as IndentationData
from .discretisation import discretisation_error as discretisation_error
from .fit import fit_prony as fit_prony
from .options import FitOptions as FitOptions
from .result import PronyFit as PronyFit
from .start import lee_radok_start as lee_radok_start


__all__ = ["FitOptions", "IndentationData", "PronyFit", "discretisation_error",
           "fit_prony", "fit_prony_batch", "lee_radok_start"]
