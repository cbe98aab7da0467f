"""`Fallback`: a solver that hands a step it could not solve to another solver."""

import equinox as eqx
import jax.numpy as jnp

from .base import AbstractStepSolver, StepGuess, StepResult


class _FallbackState(eqx.Module):
    result: StepResult
    tried: jnp.ndarray  # the secondary solver has run


class Fallback(AbstractStepSolver):
    """Solve with `primary`; if it does not converge, with `secondary`, started where
    `primary` ended (its pressure, shear and tangential displacement).

    The retry is the driver's `while_loop` of at most one pass, not a `cond`: under
    `vmap` a `cond` becomes a `select` that runs both solvers for every member, while
    the batched loop runs the secondary only while some member needs it. The result
    counts the work of both (`iterations`, `rounds`) and the fallbacks taken.
    """

    primary: AbstractStepSolver
    secondary: AbstractStepSolver

    def supports(self, problem):
        return self.primary.supports(problem) or self.secondary.supports(problem)

    def tolerance(self, dtype) -> float:
        return self.primary.tolerance(dtype)

    def step_limit(self) -> int:
        return 1

    def setup(self, problem):
        return None

    def init(self, problem, setup, guess):
        return _FallbackState(self.primary.solve(problem, guess), jnp.array(False))

    def terminate(self, problem, setup, state):
        return state.result.converged | state.tried, state.result.result

    def step(self, problem, setup, state):
        before = state.result
        after = self.secondary.solve(problem, StepGuess.from_result(before))
        return _FallbackState(after.replace(
            iterations=before.iterations + after.iterations,
            rounds=before.rounds + after.rounds,
            fallbacks=before.fallbacks + after.fallbacks + 1), jnp.array(True))

    def postprocess(self, problem, setup, state, result):
        return state.result
