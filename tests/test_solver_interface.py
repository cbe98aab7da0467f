"""The step-solver interface: solver objects, the driver, failures as `jc.RESULTS`,
the adjoint's failures reported, and the package's structure (no import cycle, no
tuning history in the code)."""

import ast
import pathlib
import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxcontact as jc


PACKAGE = pathlib.Path(jc.__file__).parent
R, W, G, NU, MU = 10e-3, 0.15, 1e6, 0.3, 0.3


def _module_name(path: pathlib.Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _imports(path: pathlib.Path, modules: set[str]) -> set[str]:
    """The package modules that `path` imports anywhere in it (lazy imports too)."""
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            candidates = [f"{target}.{a.name}" for a in node.names] + [target]
        elif isinstance(node, ast.Import):
            candidates = [a.name for a in node.names]
        else:
            continue
        out |= {c for c in candidates if c in modules and c != name}
    return out


def test_no_import_cycle_in_the_package():
    """No module imports, directly or through others, one that imports it back (the
    package `__init__` files, which only re-export, are left out of the walk)."""
    paths = [p for p in PACKAGE.rglob("*.py") if p.name != "__init__.py"]
    modules = {_module_name(p) for p in paths}
    graph = {_module_name(p): _imports(p, modules) for p in paths}
    assert "jaxcontact._solver.joint" in graph and graph["jaxcontact._solver.joint"]
    state = {}

    def visit(node, stack):
        state[node] = "open"
        for nxt in graph[node]:
            if state.get(nxt) == "open":
                cycle = stack[stack.index(nxt):] + [nxt]
                pytest.fail("import cycle: " + " -> ".join(cycle))
            if nxt not in state:
                visit(nxt, stack + [nxt])
        state[node] = "done"

    for node in graph:
        if node not in state:
            visit(node, [node])


def test_no_tuning_history_in_the_package():
    """Measurement history ("N -> M iterations") lives in benchmarks/notes, not in
    code."""
    pattern = re.compile(r"[0-9] *-> *[0-9]")
    found = [f"{p.name}:{i + 1}" for p in PACKAGE.rglob("*.py")
             for i, line in enumerate(p.read_text().splitlines())
             if pattern.search(line)]
    assert not found, found


def _scene(n=24, fx=0.5, coupling="full", x=None, steps=1):
    a = float(jc.Hertz(R, W, G, NU).contact_radius)
    grid = jc.Grid((n, n), 4 * a)
    x = jc.Force(fx * MU * W) if x is None else x
    return jc.Scene(grid, jc.Sphere(R), jc.Elastic(G, NU), jnp.arange(steps) * 1.0,
                    jc.Force(W), x=x, friction=MU, coupling=coupling)


def test_throw_raises_the_result_message_and_false_returns_the_flags():
    """A step that runs out of iterations: `throw=True` (the default) raises with the
    `RESULTS.max_steps_reached` message; `throw=False` returns `converged=False` and
    that result, no exception."""
    solver = jc.JointPCG(max_steps=2)
    scene = _scene()
    with pytest.raises(Exception, match="maximum number of solver steps"):
        jax.block_until_ready(jc.solve(scene, solver=solver))
    sol = jc.solve(scene, solver=solver, throw=False)
    assert not bool(sol.converged[0])
    assert sol.result == jc.RESULTS.max_steps_reached


def test_fallback_hands_over_and_counts():
    """`Fallback(JointPCG(max_steps=2), Rounds())`: the joint iteration gives up, the
    rounds finish from its iterate; the answer equals the default solver's to 2 rtol n
    of max p, one fallback is counted, and the work of both is summed."""
    scene = _scene()
    ref = jc.solve(scene)
    solver = jc.Fallback(jc.JointPCG(max_steps=2), jc.Rounds())
    sol = jc.solve(scene, solver=solver)
    assert bool(sol.converged[0]) and int(sol.fallbacks[0]) == 1
    assert int(ref.fallbacks[0]) == 0
    assert sol.result == jc.RESULTS.successful
    assert int(sol.iterations[0]) > 2
    p_max = float(ref.pressure.max())
    assert float(jnp.abs(sol.pressure - ref.pressure).max()) <= 2e-8 * 24 * p_max


def test_load_above_the_friction_limit_is_said_in_the_result():
    """F_x = 1.2 mu W under load control: no static solution; the step returns the
    sliding state (q = mu p along F, force mu W) as converged, and its result says
    that the load asked for was not carried. F_x = 0.5 mu W: successful."""
    sol = jc.solve(_scene(fx=1.2))
    assert bool(sol.converged[0]) and bool(sol.sliding[0])
    assert sol.result == jc.RESULTS.tangential_load_above_friction_limit
    np.testing.assert_allclose(float(sol.tangential_force[0, 0]), MU * W, rtol=1e-8)
    assert jc.solve(_scene(fx=0.5)).result == jc.RESULTS.successful


def test_gradient_is_finite_at_a_zero_tangential_load():
    """A tangential force program that starts at zero (the commonest ramp) gave a NaN
    gradient (`sqrt(sum(F^2))` at 0 in the adjoint residual). Now it equals central
    differences (elastic, 16^2, full coupling, 3 steps) to 1e-5."""
    grid = jc.Grid((16, 16), 2.4e-3)

    def f(c):
        scene = jc.Scene(grid, jc.Sphere(10e-3), jc.Elastic(1.93e6, 0.3),
                         jnp.linspace(0, 1, 3), jc.Force(0.15),
                         x=jc.Force(c * jnp.array([0.0, 0.02, 0.04])), friction=0.3,
                         coupling="full")
        return jc.solve(scene).tangential_displacement[-1, 0]

    grad = float(jax.grad(f)(1.0))
    h = 1e-4
    fd = (float(f(1.0 + h)) - float(f(1.0 - h))) / (2 * h)
    assert np.isfinite(grad)
    np.testing.assert_allclose(grad, fd, rtol=1e-5)


def test_a_non_converged_adjoint_is_reported():
    """An adjoint bounded to one GMRES iteration cannot converge on a coupled step:
    with `throw=True` computing the gradient raises `adjoint_not_converged`; with
    `throw=False` the gradient is NaN, never a silently wrong number."""
    def f(mu, throw):
        scene = jc.Scene(_scene().grid, jc.Sphere(R), jc.Elastic(G, NU), jnp.zeros(1),
                         jc.Force(W), x=jc.Force(0.5 * MU * W), friction=mu,
                         coupling="full")
        adjoint = jc.ImplicitAdjoint(max_steps=1, restart=1)
        return jc.solve(scene, adjoint=adjoint,
                        throw=throw).tangential_displacement[0, 0]

    with pytest.raises(Exception, match="adjoint"):
        jax.block_until_ready(jax.grad(f)(MU, True))
    assert np.isnan(float(jax.grad(f)(MU, False)))
    # The default adjoint converges there: a finite gradient.
    scene_grad = jax.grad(lambda mu: jc.solve(jc.Scene(
        _scene().grid, jc.Sphere(R), jc.Elastic(G, NU), jnp.zeros(1), jc.Force(W),
        x=jc.Force(0.5 * MU * W), friction=mu, coupling="full")
    ).tangential_displacement[0, 0])(MU)
    assert np.isfinite(float(scene_grad))


def test_solvers_reject_steps_they_cannot_solve():
    """`JointPCG` needs a coupled step; `LoadByDisplacement` a load-controlled
    direction: a clear error naming the solver, before anything runs."""
    with pytest.raises(ValueError, match="JointPCG cannot solve"):
        jc.solve(_scene(coupling="none"), solver=jc.JointPCG())
    a = float(jc.Hertz(R, W, G, NU).contact_radius)
    displaced = jc.Scene(jc.Grid((16, 16), 4 * a), jc.Sphere(R), jc.Elastic(G, NU),
                         jnp.zeros(1), jc.Force(W), x=jc.Displacement(1e-6),
                         y=jc.Displacement(0.0), friction=MU, coupling="full")
    with pytest.raises(ValueError, match="LoadByDisplacement cannot solve"):
        jc.solve(displaced, solver=jc.LoadByDisplacement(jc.JointPCG()))


def test_no_sliding_flag_without_friction_concrete_or_traced():
    """`Solution.sliding` with friction 0: False whether the zero is a number (no
    tangential step is solved) or traced under `vmap` (the step is solved with a zero
    bound: every cell 'slips', but nothing slides without friction); a traced 0.3 in
    the same batch is in partial slip (not sliding either)."""
    grid = jc.Grid((16, 16), 3e-3)
    times = jnp.linspace(0.0, 1.0, 3)

    def scene(mu):
        return jc.Scene(grid, jc.Sphere(R), jc.Elastic(G, NU), times, jc.Force(W),
                        x=jc.Displacement(jnp.linspace(0.0, 2e-6, 3)), friction=mu)

    concrete = jc.solve(scene(0.0))
    batched = jax.vmap(lambda mu: jc.solve(scene(mu), throw=False))(
        jnp.array([0.0, MU]))
    assert not np.any(np.asarray(concrete.sliding))
    assert not np.any(np.asarray(batched.sliding))
    assert np.all(np.asarray(batched.converged))
    # The frictionless member carries no shear, as the concrete zero.
    assert float(jnp.abs(batched.shear[0]).max()) == 0.0


@pytest.mark.parametrize("coupling", ["x", "full"])
def test_incompressible_coupled_scene_solves_as_uncoupled(coupling):
    """nu = 0.5: the normal-tangential blocks vanish (they scale with 1 - 2 nu), so a
    "x" or "full" scene is the uncoupled one ("full" also solves q_y with y held: the
    reference is "none" with `y=jc.Displacement(0.0)`): the same pressure and shear
    (to 1e-9 of the peak) with the same work."""
    grid = jc.Grid((24, 24), 2e-3)
    times = jnp.linspace(0.0, 1.0, 4)

    def solve(c, **y):
        return jc.solve(jc.Scene(grid, jc.Sphere(R), jc.Elastic(G, 0.5), times,
                                 jc.Force(W),
                                 x=jc.Displacement(jnp.linspace(0, 4e-6, 4)),
                                 friction=MU, coupling=c, **y))

    sol = solve(coupling)
    ref = solve("none", **({"y": jc.Displacement(0.0)} if coupling == "full" else {}))
    p_max = float(ref.pressure.max())
    np.testing.assert_allclose(sol.pressure, ref.pressure, rtol=0, atol=1e-9 * p_max)
    np.testing.assert_allclose(sol.shear, ref.shear, rtol=0, atol=1e-9 * p_max)
    # The work of the uncoupled solve (the joint solver's one step took 2000 before).
    assert int(np.sum(sol.iterations)) <= 1.1 * int(np.sum(ref.iterations))


def _held_scene(n, steps, y=None):
    """Zener (mu_inf / mu_0 = 3, tau 0.01 s), full coupling, x displaced to 25 um over
    0.02 s under W = 0.15 N: the scene of the rounds solver's near-hang."""
    times = jnp.linspace(0.0, 0.02, steps)
    material = jc.Zener(mu_inf=1.93e6, mu_0=1.93e6 / 3, tau=0.01, poisson=NU)
    return jc.Scene(jc.Grid((n, n), 2.4e-3), jc.Sphere(R), material, times, jc.Force(W),
                    x=jc.Displacement(25e-6 * times / 0.02), y=y, friction=MU,
                    coupling="full")


def test_a_solved_direction_with_no_input_is_held():
    """y = None under full coupling is solved (the coupling makes q_y) but has no
    input: it is held, delta_y = 0 exactly (it was load-controlled at F_y = 0, delta_y
    ~1e-18 m, and every failed step started a root search on it), the same program
    as `y=jc.Displacement(0.0)`; `y=jc.Force(0.0)` keeps the free indenter. On this
    symmetric scene both carry F_y = 0 (to 1e-8 mu W) and the same pressure (to
    2 rtol n of the peak, as `test_fallback_hands_over_and_counts`), with the joint
    and the rounds solvers."""
    held = _held_scene(16, 6)
    ref = jc.solve(_held_scene(16, 6, y=jc.Displacement(0.0)))
    free = jc.solve(_held_scene(16, 6, y=jc.Force(0.0)))
    for solver in (None, jc.Rounds()):
        sol = jc.solve(held, solver=solver)
        assert np.all(np.asarray(sol.converged))
        assert float(jnp.abs(sol.tangential_displacement[:, 1]).max()) == 0.0
        assert float(jnp.abs(sol.tangential_force[:, 1]).max()) <= 1e-8 * MU * W
        p_max = float(ref.pressure.max())
        np.testing.assert_allclose(sol.pressure, ref.pressure, rtol=0,
                                   atol=2e-8 * 16 * p_max)
        np.testing.assert_allclose(free.pressure, ref.pressure, rtol=0,
                                   atol=2e-8 * 16 * p_max)
    assert float(jnp.abs(free.tangential_force[:, 1]).max()) <= 1e-8 * MU * W
    # The same program: equal to round-off (XLA may compile the two calls with
    # different fusions), far inside the solver's tolerance above.
    np.testing.assert_allclose(np.asarray(jc.solve(held).pressure),
                               np.asarray(ref.pressure), rtol=0, atol=1e-12 * p_max)


def test_a_load_above_the_limit_slides_with_another_direction_held():
    """x under load control at 1.2 mu W, y held (no input, full coupling): gross
    sliding is decided on the load-controlled direction alone; the step returns the
    sliding state (q = mu p along x, F_x = mu W, q_y = 0, delta_y = 0), converged, its
    result saying the load was not carried, with both solvers."""
    for solver in (None, jc.Rounds()):
        sol = jc.solve(_scene(fx=1.2), solver=solver)
        assert bool(sol.converged[0]) and bool(sol.sliding[0])
        assert sol.result == jc.RESULTS.tangential_load_above_friction_limit
        np.testing.assert_allclose(float(sol.tangential_force[0, 0]), MU * W, rtol=1e-8)
        np.testing.assert_allclose(sol.shear[0, 0], MU * sol.pressure[0], rtol=0,
                                   atol=1e-12 * float(sol.pressure.max()))
        assert float(jnp.abs(sol.shear[0, 1]).max()) == 0.0
        assert float(sol.tangential_displacement[0, 1]) == 0.0


@pytest.mark.slow
def test_rounds_solves_a_held_direction_without_a_root_search():
    """Issue 31 item 7: the rounds solver on the 32^2 x 21 scene took 251 s and
    converged on 11 of 21 steps while y = None was load-controlled (each failed step
    ran a 40-evaluation root search on delta_y). Held, it converges on every step in
    133 rounds (bound 300 here) and agrees with the joint solver to 2 rtol n of the
    peak pressure."""
    scene = _held_scene(32, 21)
    sol = jc.solve(scene, solver=jc.Rounds())
    ref = jc.solve(scene)
    assert np.all(np.asarray(sol.converged))
    assert int(np.sum(sol.rounds)) <= 300 and int(np.sum(sol.fallbacks)) == 0
    p_max = float(ref.pressure.max())
    np.testing.assert_allclose(sol.pressure, ref.pressure, rtol=0,
                               atol=2e-8 * 32 * p_max)
