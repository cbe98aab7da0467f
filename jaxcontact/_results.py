"""`jc.RESULTS`: how a contact step (or its adjoint) ended."""

import lineax as lx


class RESULTS(lx.RESULTS):  # pyright: ignore[reportGeneralTypeIssues]
    """How a contact step ended: `successful`, or one member per way of failing (or
    of not meeting a target), each message saying what to change. Extends
    `lineax.RESULTS` (`successful`, `max_steps_reached`, ...)."""

    stalled = (
        "The contact iteration stopped making progress (its residual did not halve "
        "for many iterations). A concrete `jc.solve` then solves the scene again with "
        "fallback solvers, which failed too; under `jit`, `vmap` or `grad` no second "
        "solve runs: compile the fallback in with "
        "`solver=jc.Fallback(jc.JointPCG(), jc.Rounds())`. Or try a looser `rtol`, a "
        "finer time discretisation (smaller load increments), or "
        "`solver=jc.Rounds()`."
    )
    tangential_load_above_friction_limit = (
        "A tangential load at or above the friction limit mu W: there is no static "
        "solution; the indenter slides and the shear is mu p along the load (the "
        "solution returned, with `sliding`), so the tangential force is mu W, not the "
        "load asked for. Prescribe a tangential displacement to follow gross sliding."
    )
    adjoint_not_converged = (
        "The adjoint (implicit gradient) linear solve did not converge. Try "
        "`adjoint=jc.ImplicitAdjoint(max_steps=...)` with more steps, or a looser "
        "`rtol`."
    )
