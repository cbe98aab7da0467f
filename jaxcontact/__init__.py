"""jaxcontact: a JAX-accelerated, differentiable contact solver.

A rigid indenter against a linear (visco)elastic half-space, by influence
coefficients, DC-FFT and conjugate-gradient contact solvers.
"""

from . import _version
from . import presets as presets
from ._afm import AFMCurve as AFMCurve
from ._afm import read_afm as read_afm
from ._analytic import Hertz as Hertz
from ._analytic import LeeRadok as LeeRadok
from ._cache import enable_compilation_cache as enable_compilation_cache
from ._dataset import load as load
from ._force_map import fit_force_map as fit_force_map
from ._grid import Grid as Grid
from ._history import time_step_amplification as time_step_amplification
from ._indenter import AbstractAxisymmetricIndenter as AbstractAxisymmetricIndenter
from ._indenter import AbstractIndenter as AbstractIndenter
from ._indenter import AxisymmetricProfile as AxisymmetricProfile
from ._indenter import BluntedCone as BluntedCone
from ._indenter import Cone as Cone
from ._indenter import Pyramid as Pyramid
from ._indenter import Sphere as Sphere
from ._indenter import Surface as Surface
from ._influence import influence_coefficients as influence_coefficients
from ._loading import Displacement as Displacement
from ._loading import Force as Force
from ._material.base import AbstractMaterial as AbstractMaterial
from ._material.base import CreepSeries as CreepSeries
from ._material.elastic import Elastic as Elastic
from ._material.maxwell import Maxwell as Maxwell
from ._material.prony import Prony as Prony
from ._material.zener import Zener as Zener
from ._operator import HalfSpace as HalfSpace
from ._results import RESULTS as RESULTS
from ._scene import Scene as Scene
from ._solution import Solution as Solution
from ._solve import solve as solve
from ._solve_normal import NormalSolution as NormalSolution
from ._solve_normal import solve_normal as solve_normal
from ._solver.base import AbstractStepSolver as AbstractStepSolver
from ._solver.base import StepGuess as StepGuess
from ._solver.base import StepProblem as StepProblem
from ._solver.base import StepResult as StepResult
from ._solver.fallback import Fallback as Fallback
from ._solver.implicit import ImplicitAdjoint as ImplicitAdjoint
from ._solver.joint import JointPCG as JointPCG
from ._solver.load_search import LoadByDisplacement as LoadByDisplacement
from ._solver.normal import PolonskyKeer as PolonskyKeer
from ._solver.rings import RingPolonskyKeer as RingPolonskyKeer
from ._solver.rounds import Rounds as Rounds
from ._subsurface import Stress as Stress
from ._subsurface import subsurface_stress as subsurface_stress
from ._surface import surface_displacement as surface_displacement
from ._sweep import sweep as sweep
from ._validate import EdgeContactWarning as EdgeContactWarning
from ._validate import TimeStepWarning as TimeStepWarning
from .fitting.afm import AFMFit as AFMFit
from .fitting.afm import AFMFitSettings as AFMFitSettings
from .fitting.afm import fit_afm_curve as fit_afm_curve
from .fitting.batch import fit_prony_batch as fit_prony_batch
from .fitting.data import IndentationData as IndentationData
from .fitting.fit import fit_prony as fit_prony
from .fitting.options import FitOptions as FitOptions
from .fitting.result import PronyFit as PronyFit


__version__ = _version.__version__

# The public API (what the documentation's API reference lists; tests/test_docs.py
# checks that it names every public re-export above and nothing else).
__all__ = [
    # Scenes and solving
    "Grid", "Sphere", "Surface", "AbstractIndenter", "Force", "Displacement",
    "Cone", "BluntedCone", "Pyramid", "AxisymmetricProfile",
    "AbstractAxisymmetricIndenter",
    "Scene", "solve", "Solution", "RESULTS", "sweep",
    "solve_normal", "NormalSolution", "HalfSpace", "influence_coefficients",
    "subsurface_stress", "Stress", "surface_displacement", "load",
    "enable_compilation_cache", "time_step_amplification",
    # Materials
    "AbstractMaterial", "Elastic", "Maxwell", "Zener", "Prony", "CreepSeries",
    # Step solvers and gradients
    "AbstractStepSolver", "PolonskyKeer", "Rounds", "JointPCG", "Fallback",
    "RingPolonskyKeer",
    "LoadByDisplacement", "ImplicitAdjoint", "StepProblem", "StepGuess", "StepResult",
    # Analytic references, fitting, AFM files
    "Hertz", "LeeRadok", "fit_prony", "fit_prony_batch", "FitOptions",
    "IndentationData", "PronyFit",
    "read_afm",
    "fit_afm_curve", "AFMFitSettings", "AFMFit",
    "fit_force_map",
    "AFMCurve",
    # Presets and warnings
    "presets", "EdgeContactWarning", "TimeStepWarning",
]
