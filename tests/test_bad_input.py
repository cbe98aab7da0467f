"""Bad input: every public constructor and function rejects it with a clear error.

Each case asserts the exception type AND that the message names the argument and shows
the bad value (or shape), so a user can see what to change. Traced values (inside
`jit`/`vmap`) are checked at run time with `eqx.error_if`. One class per public entry
point. Nothing here solves a contact problem except the edge-of-domain checks, which use
a 16 x 16 grid.
"""

import re
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxcontact as jc


NAN, INF = float("nan"), float("inf")
GRID = jc.Grid((8, 8), (1.0, 1.0))
ELASTIC = jc.Elastic(1.0, 0.3)
TIMES = jnp.linspace(0.0, 1.0, 3)


def scene(**kwargs):
    base = dict(
        grid=GRID,
        indenter=jc.Sphere(1.0),
        material=ELASTIC,
        times=TIMES,
        normal=jc.Force(0.01),
    )
    return jc.Scene(**{**base, **kwargs})


def raises(fn, exc, *fragments):
    """`fn()` raises `exc`, and its message contains every fragment (literally)."""
    with pytest.raises(exc) as info:
        fn()
    message = str(info.value)
    for fragment in fragments:
        assert fragment in message, f"{fragment!r} not in {message!r}"


def runtime_error(fn, fragment):
    """A traced check (`eqx.error_if`) fires when the compiled function runs."""
    with pytest.raises(Exception, match=re.escape(fragment)):
        jax.block_until_ready(fn())


class TestGrid:
    @pytest.mark.parametrize(
        "kwargs, exc, fragments",
        [
            (dict(shape=(1, 8), size=1.0), ValueError, ("shape", "(1, 8)")),
            (dict(shape=(8.0, 8), size=1.0), ValueError, ("shape", "8.0")),
            (dict(shape=(8, 8, 8), size=1.0), ValueError, ("shape", "(8, 8, 8)")),
            (dict(shape=(8, True), size=1.0), ValueError, ("shape", "True")),
            (dict(shape=(8, 8), size=NAN), ValueError, ("size", "nan")),
            (dict(shape=(8, 8), size=INF), ValueError, ("size", "inf")),
            (dict(shape=(8, 8), size=0.0), ValueError, ("size", "0.")),
            (dict(shape=(8, 8), size=(-1.0, 1.0)), ValueError, ("size", "-1.")),
            (dict(shape=(8, 8), size=(1.0, 1.0, 1.0)), ValueError, ("size", "(3,)")),
            (dict(shape=(8, 8), size="1mm"), TypeError, ("size", "'1mm'")),
            (dict(shape=(8, 8), size=1.0, periodic="yes"), TypeError,
             ("periodic", "'yes'")),
        ],
    )
    def test_rejects(self, kwargs, exc, fragments):
        raises(lambda: jc.Grid(**kwargs), exc, *fragments)


class TestSphere:
    @pytest.mark.parametrize(
        "args, exc, fragments",
        [
            ((0.0,), ValueError, ("radius", "0.0")),
            ((-1e-3,), ValueError, ("radius", "-0.001")),
            ((NAN,), ValueError, ("radius", "nan")),
            ((INF,), ValueError, ("radius", "inf")),
            ((np.ones(3),), ValueError, ("radius", "(3,)")),
            (("big",), TypeError, ("radius", "'big'")),
            ((1.0, (0.0, 0.0, 0.0)), ValueError, ("centre", "(3,)")),
            ((1.0, (0.0, NAN)), ValueError, ("centre", "nan")),
        ],
    )
    def test_rejects(self, args, exc, fragments):
        raises(lambda: jc.Sphere(*args), exc, *fragments)

    def test_traced_radius_checked_at_run_time(self):
        fn = jax.jit(lambda r: jc.Sphere(r).gap(GRID))
        runtime_error(lambda: fn(-1.0), "radius must be finite and > 0")
        assert np.all(np.isfinite(fn(1.0)))


class TestSurface:
    def test_rejects_non_finite_and_wrong_rank(self):
        heights = np.zeros((8, 8))
        heights[3, 4] = NAN
        raises(lambda: jc.Surface(heights), ValueError, "heights", "nan")
        heights[3, 4] = -INF
        raises(lambda: jc.Surface(heights), ValueError, "heights", "-inf")
        raises(lambda: jc.Surface(np.zeros(8)), ValueError, "heights", "(8,)")
        raises(lambda: jc.Surface("flat"), TypeError, "heights", "'flat'")

    def test_shape_against_grid(self):
        # At the scene, and at solve_normal (indenter array vs grid).
        raises(lambda: scene(indenter=np.zeros((4, 8))), ValueError, "indenter",
               "(4, 8)", "(8, 8)")
        raises(
            lambda: jc.solve_normal(GRID, np.zeros((8, 4)), ELASTIC, force=1.0),
            ValueError, "(8, 4)", "(8, 8)",
        )

    def test_unknown_indenter(self):
        raises(lambda: scene(indenter="sphere"), TypeError, "indenter", "'sphere'")


class TestLoadPrograms:
    @pytest.mark.parametrize("cls", [jc.Force, jc.Displacement])
    def test_rejects(self, cls):
        name = cls.__name__
        raises(lambda: cls(NAN), ValueError, f"{name} value", "nan")
        raises(lambda: cls(np.array([0.0, INF])), ValueError, f"{name} value", "inf")
        raises(lambda: cls(np.ones((3, 2))), ValueError, f"{name} value", "(3, 2)")
        raises(lambda: cls("1N"), TypeError, f"{name} value", "'1N'")
        raises(lambda: cls(True), TypeError, f"{name} value", "True")

    def test_length_against_times(self):
        raises(lambda: scene(normal=jc.Force(np.ones(4))), ValueError, "normal", "(4,)",
               "(3)")
        raises(
            lambda: scene(x=jc.Displacement(np.ones(2)), friction=0.3),
            ValueError, "x", "(2,)",
        )
        raises(
            lambda: scene(y=jc.Force(lambda t: jnp.ones(5)), friction=0.3,
                          coupling="full"),
            ValueError, "y", "(5,)",
        )

    def test_callable_values_checked(self):
        raises(
            lambda: scene(normal=jc.Force(lambda t: jnp.log(t - 0.5))),
            ValueError, "normal must be finite", "nan",
        )
        raises(
            lambda: scene(normal=jc.Force(lambda t: 0.01 - t)),
            ValueError, "normal force", "-0.99",
        )

    def test_negative_normal_force(self):
        raises(lambda: scene(normal=jc.Force(-1.0)), ValueError, "normal force", "-1.0")
        raises(
            lambda: scene(normal=jc.Force(np.array([0.1, -0.2, 0.1]))),
            ValueError, "normal force", "-0.2",
        )

    def test_negative_normal_displacement_is_allowed(self):
        # A negative approach is a legal input (the indenter is lifted off: no contact).
        scene(normal=jc.Displacement(np.array([1e-3, -1e-3, 0.0])))


class TestScene:
    @pytest.mark.parametrize(
        "times, fragments",
        [
            (np.array([0.0, 2.0, 1.0]), ("times", "strictly increasing", "2.", "1.")),
            (np.array([0.0, 1.0, 1.0]), ("times", "strictly increasing")),
            (np.array([0.0, NAN, 1.0]), ("times", "nan")),
            (np.array([0.0, 1.0, INF]), ("times", "inf")),
            (np.zeros((2, 2)), ("times", "(2, 2)")),
            (np.zeros((0,)), ("times", "empty")),
        ],
    )
    def test_bad_times(self, times, fragments):
        raises(lambda: scene(times=times, normal=jc.Force(0.01)), ValueError,
               *fragments)

    @pytest.mark.parametrize(
        "friction, exc, fragments",
        [
            (-0.1, ValueError, ("friction", "-0.1")),
            (NAN, ValueError, ("friction", "nan")),
            (INF, ValueError, ("friction", "inf")),
            (np.array([0.1, 0.2]), ValueError, ("friction", "(2,)")),
            ("high", TypeError, ("friction", "'high'")),
        ],
    )
    def test_bad_friction(self, friction, exc, fragments):
        raises(lambda: scene(friction=friction), exc, *fragments)

    def test_unknown_strings(self):
        raises(lambda: scene(coupling="semi"), ValueError, "coupling", "'semi'")
        raises(lambda: scene(coupling="X"), ValueError, "coupling", "'X'")
        raises(lambda: scene(slip="paper"), ValueError, "slip", "'paper'")
        raises(
            lambda: scene(coupling="x", y=jc.Force(0.0), friction=0.3),
            ValueError, 'coupling="x"', "y",
        )

    def test_wrong_kinds(self):
        raises(lambda: scene(grid=(8, 8)), TypeError, "grid", "(8, 8)")
        raises(lambda: scene(material=1e6), TypeError, "material", "1000000.0")
        raises(lambda: scene(normal=0.1), TypeError, "normal", "0.1")
        raises(lambda: scene(normal=None), TypeError, "normal", "None")
        raises(lambda: scene(x=0.1, friction=0.3), TypeError, "x", "0.1")

    def test_traced_friction_checked_at_run_time(self):
        def stick(mu):
            return jc.Scene(GRID, jc.Sphere(1.0), ELASTIC, TIMES, jc.Force(0.01),
                            friction=mu).friction

        runtime_error(lambda: jax.jit(stick)(-0.5), "friction must be finite and >= 0")
        assert float(jax.jit(stick)(0.5)) == 0.5


class TestMaterials:
    @pytest.mark.parametrize(
        "build, exc, fragments",
        [
            (lambda: jc.Elastic(0.0, 0.3), ValueError, ("shear_modulus", "0.0")),
            (lambda: jc.Elastic(-1e6, 0.3), ValueError,
             ("shear_modulus", "-1000000.0")),
            (lambda: jc.Elastic(NAN, 0.3), ValueError, ("shear_modulus", "nan")),
            (lambda: jc.Elastic(np.ones(2), 0.3), ValueError,
             ("shear_modulus", "(2,)")),
            (lambda: jc.Elastic(True, 0.3), TypeError, ("shear_modulus", "True")),
            (lambda: jc.Elastic("soft", 0.3), TypeError, ("shear_modulus", "'soft'")),
            (lambda: jc.Maxwell(1.0, 0.0, 0.3), ValueError, ("viscosity", "0.0")),
            (lambda: jc.Maxwell(1.0, -2.0, 0.3), ValueError, ("viscosity", "-2.0")),
            (lambda: jc.Maxwell(INF, 1.0, 0.3), ValueError, ("shear_modulus", "inf")),
            (lambda: jc.Zener(1.0, 2.0, 1.0, 0.3), ValueError,
             ("mu_0", "2.0", "mu_inf")),
            (lambda: jc.Zener(1.0, 0.0, 1.0, 0.3), ValueError, ("mu_0", "0.0")),
            (lambda: jc.Zener(1.0, 0.5, 0.0, 0.3), ValueError, ("tau", "0.0")),
            (lambda: jc.Zener(1.0, 0.5, -1.0, 0.3), ValueError, ("tau", "-1.0")),
            (lambda: jc.Zener(1.0, 0.5, NAN, 0.3), ValueError, ("tau", "nan")),
            (lambda: jc.Zener(np.ones(2), 0.5, 1.0, 0.3), ValueError,
             ("mu_inf", "(2,)")),
            (lambda: jc.Prony(1.0, [-1.0], [1.0], 0.3), ValueError, ("g", "-1.")),
            (lambda: jc.Prony(-1.0, [1.0], [1.0], 0.3), ValueError, ("g_inf", "-1.0")),
            (lambda: jc.Prony(1.0, [1.0], [0.0], 0.3), ValueError, ("tau", "0.")),
            (lambda: jc.Prony(1.0, [1.0, 1.0], [2.0, 2.0], 0.3), ValueError,
             ("tau", "distinct", "2.")),
            (lambda: jc.Prony(1.0, [1.0, 1.0], [1.0], 0.3), ValueError,
             ("g", "tau", "(2,)", "(1,)")),
            (lambda: jc.Prony(0.0, [0.0], [1.0], 0.3), ValueError,
             ("G(0)", "g_inf=0.0")),
            (lambda: jc.Prony(1.0, [NAN], [1.0], 0.3), ValueError, ("g", "nan")),
            (lambda: jc.Prony.from_creep(1.0, [2.0], [1.0], 0.3), ValueError,
             ("J(0)", "j_inf=1.0")),
            (lambda: jc.Prony.from_creep(1.0, [0.2], [1.0], 0.3, fluidity=-1.0),
             ValueError, ("fluidity", "-1.0")),
        ],
    )
    def test_rejects(self, build, exc, fragments):
        raises(build, exc, *fragments)

    @pytest.mark.parametrize("nu", [0.5000001, 0.6, -1.0, -1.5, NAN, INF])
    @pytest.mark.parametrize(
        "build",
        [
            lambda nu: jc.Elastic(1.0, nu),
            lambda nu: jc.Maxwell(1.0, 1.0, nu),
            lambda nu: jc.Zener(1.0, 0.5, 1.0, nu),
            lambda nu: jc.Prony(1.0, [1.0], [1.0], nu),
            lambda nu: jc.Prony.from_creep(1.0, [0.2], [1.0], nu),
        ],
    )
    def test_poisson_outside_interval(self, build, nu):
        raises(lambda: build(nu), ValueError, "poisson", "(-1, 0.5]", repr(nu)[:5])

    @pytest.mark.parametrize("nu", [0.5, -0.99, 0.0])
    def test_poisson_edges_accepted(self, nu):
        assert float(jc.Zener(1.0, 0.5, 1.0, nu).poisson) == nu

    def test_traced_values_checked_at_run_time(self):
        # Materials built inside jit/vmap: Python cannot inspect the values; the checks
        # fire when the program runs.
        zener = jax.jit(lambda m0: jc.Zener(1.0, m0, 1.0, 0.3).creep(1.0))
        runtime_error(lambda: zener(2.0), "mu_0 (the long-time modulus) must be <=")
        assert np.isfinite(zener(0.5))
        batch = jax.vmap(lambda nu: jc.Elastic(1.0, nu).poisson)
        runtime_error(lambda: batch(jnp.array([0.3, 0.7])), "poisson must be in")
        np.testing.assert_array_equal(batch(jnp.array([0.3, 0.4])), [0.3, 0.4])


class TestSolve:
    @pytest.mark.parametrize(
        "kwargs, exc, fragments",
        [
            (dict(max_steps=0), ValueError, ("max_steps", "0")),
            (dict(max_steps=-5), ValueError, ("max_steps", "-5")),
            (dict(max_steps=10.0), TypeError, ("max_steps", "10.0")),
            (dict(max_steps=True), TypeError, ("max_steps", "True")),
            (dict(max_rounds=0), ValueError, ("max_rounds", "0")),
            (dict(resync_every=0), ValueError, ("resync_every", "0")),
            (dict(resync_every=2.5), TypeError, ("resync_every", "2.5")),
            (dict(rtol=0.0), ValueError, ("rtol", "0.0")),
            (dict(rtol=1.0), ValueError, ("rtol", "1.0")),
            (dict(rtol=-1e-8), ValueError, ("rtol", "-1e-08")),
            (dict(rtol=NAN), ValueError, ("rtol", "nan")),
            (dict(rtol="1e-8"), TypeError, ("rtol", "'1e-8'")),
            (dict(history="fast"), ValueError, ("history", "'fast'")),
            (dict(precondition=1), TypeError, ("precondition", "1")),
            (dict(scheme="cubic"), ValueError, ("scheme", "'cubic'")),
            (dict(operator="fft"), TypeError, ("operator", "'fft'")),
        ],
    )
    def test_rejects_options(self, kwargs, exc, fragments):
        raises(lambda: jc.solve(scene(), **kwargs), exc, *fragments)

    def test_rejects_scene_and_mismatched_operator(self):
        raises(lambda: jc.solve(GRID), TypeError, "scene", "Grid")
        other = jc.HalfSpace(jc.Grid((4, 4), 1.0))
        raises(lambda: jc.solve(scene(), operator=other), ValueError, "operator",
               "(4, 4)", "(8, 8)")
        normal_only = jc.HalfSpace(GRID, "normal")
        coupled = scene(x=jc.Force(0.0), friction=0.3, coupling="full")
        raises(lambda: jc.solve(coupled, operator=normal_only), ValueError, "operator",
               "'normal'", "'full'")

    def test_linear_scheme_needs_a_creep_series(self):
        # The direct (tabulated) history has no linear scheme.
        mat = jc.Zener(1.0, 0.5, 1.0, 0.3)
        raises(lambda: jc.solve(scene(material=mat), history="direct", scheme="linear"),
               ValueError, "scheme", "linear")


class TestSolveNormal:
    def test_rejects(self):
        sphere = jc.Sphere(1.0)
        raises(lambda: jc.solve_normal(GRID, sphere, ELASTIC), ValueError, "force=",
               "approach=")
        raises(lambda: jc.solve_normal(GRID, sphere, ELASTIC, force=1.0, approach=0.1),
               ValueError, "force=1.0", "approach=0.1")
        raises(lambda: jc.solve_normal(GRID, sphere, ELASTIC, force=-1.0), ValueError,
               "force", "-1.0")
        raises(lambda: jc.solve_normal(GRID, sphere, ELASTIC, force=NAN), ValueError,
               "force", "nan")
        raises(lambda: jc.solve_normal(GRID, sphere, ELASTIC, approach=INF), ValueError,
               "approach", "inf")
        raises(lambda: jc.solve_normal(GRID, sphere, ELASTIC, force=np.ones(2)),
               ValueError, "force", "(2,)")
        raises(lambda: jc.solve_normal((8, 8), sphere, ELASTIC, force=1.0), TypeError,
               "grid", "(8, 8)")
        raises(lambda: jc.solve_normal(GRID, sphere, "rubber", force=1.0), TypeError,
               "material", "'rubber'")
        raises(lambda: jc.solve_normal(GRID, sphere, ELASTIC, force=1.0, solver=3),
               TypeError, "solver", "3")
        raises(lambda: jc.solve_normal(GRID, sphere, ELASTIC, force=1.0,
                                       operator="fft"),
               TypeError, "operator", "'fft'")
        raises(
            lambda: jc.solve_normal(GRID, sphere, ELASTIC, force=1.0,
                                    operator=jc.HalfSpace(jc.Grid((4, 4), 1.0))),
            ValueError, "operator",
        )

    @pytest.mark.parametrize(
        "kwargs, exc, fragments",
        [
            (dict(rtol=2.0), ValueError, ("rtol", "2.0")),
            (dict(rtol=NAN), ValueError, ("rtol", "nan")),
            (dict(max_steps=0), ValueError, ("max_steps", "0")),
            (dict(max_steps=2.5), ValueError, ("max_steps", "2.5")),
            (dict(resync_every=0), ValueError, ("resync_every", "0")),
            (dict(precondition="yes"), TypeError, ("precondition", "'yes'")),
            (dict(mixed_precision=1), TypeError, ("mixed_precision", "1")),
        ],
    )
    def test_polonsky_keer_options(self, kwargs, exc, fragments):
        raises(lambda: jc.PolonskyKeer(**kwargs), exc, *fragments)


class TestEdgeOfDomain:
    """A sphere whose contact cannot fit on a non-periodic grid: warned before the solve
    (an upper estimate of the contact radius), flagged exactly after it."""

    G, NU, R = 1e6, 0.3, 1e-2
    GRID16 = jc.Grid((16, 16), 2e-3)  # half-width 1 mm, outer ring from 0.875 mm

    def hertz_force(self, a):
        e_star = 2 * self.G / (1 - self.NU)
        return 4 * e_star * a**3 / (3 * self.R)

    def test_solve_normal_warns_and_flags(self):
        mat = jc.Elastic(self.G, self.NU)
        with pytest.warns(jc.EdgeContactWarning, match="contact radius"):
            sol = jc.solve_normal(self.GRID16, jc.Sphere(self.R), mat,
                                  force=self.hertz_force(1.2e-3))
        assert bool(sol.edge_contact)
        # Well inside: no warning (filterwarnings=error would fail), no flag.
        sol = jc.solve_normal(self.GRID16, jc.Sphere(self.R), mat,
                              force=self.hertz_force(0.5e-3))
        assert not bool(sol.edge_contact)
        # Displacement control: a = sqrt(R delta) for any material.
        with pytest.warns(jc.EdgeContactWarning):
            jc.Scene(self.GRID16, jc.Sphere(self.R), mat, TIMES,
                     normal=jc.Displacement(1.0e-3**2 / self.R))

    def test_off_centre_sphere_warns(self):
        mat = jc.Elastic(self.G, self.NU)
        with pytest.warns(jc.EdgeContactWarning):
            jc.Scene(self.GRID16, jc.Sphere(self.R, centre=(0.6e-3, 0.0)), mat, TIMES,
                     normal=jc.Force(self.hertz_force(0.4e-3)))
        jc.Scene(self.GRID16, jc.Sphere(self.R), mat, TIMES,
                 normal=jc.Force(self.hertz_force(0.4e-3)))  # centred: fits

    def test_scene_uses_the_long_time_compliance(self):
        # Zener ratio 10: J grows 10x, the contact radius 10^(1/3) ~ 2.15x. A load that
        # fits at the instantaneous modulus no longer fits after a long hold.
        mat = jc.Zener(self.G, self.G / 10, 1.0, self.NU)
        force = jc.Force(self.hertz_force(0.6e-3))
        jc.Scene(self.GRID16, jc.Sphere(self.R), mat, jnp.linspace(0.0, 0.01, 3), force)
        with pytest.warns(jc.EdgeContactWarning):
            jc.Scene(self.GRID16, jc.Sphere(self.R), mat, jnp.linspace(0.0, 10.0, 3),
                     force)

    def test_periodic_grid_never_warns(self):
        grid = jc.Grid((16, 16), 2e-3, periodic=True)
        jc.Scene(grid, jc.Sphere(self.R), jc.Elastic(self.G, self.NU), TIMES,
                 normal=jc.Force(self.hertz_force(1.5e-3)))

    def test_solution_flag_per_step(self):
        # A surface (warned by its bearing-area estimate) carries the exact flag from
        # the solve. A load ramp whose last step spreads the contact to the edge of a
        # flat-ish surface.
        x, y = self.GRID16.coordinates()
        heights = x**2 + y**2  # a flat paraboloid, R = 0.5 m
        loads = np.array([1e-6, 1e-3, 1e1])
        with pytest.warns(jc.EdgeContactWarning,
                          match="contact of the surface indenter"):
            sc = jc.Scene(self.GRID16, heights, jc.Elastic(self.G, self.NU),
                          jnp.arange(3.0), normal=jc.Force(loads))
        sol = jc.solve(sc)
        assert bool(jnp.all(sol.converged))
        np.testing.assert_array_equal(np.asarray(sol.edge_contact),
                                      [False, False, True])


def test_error_if_is_used_for_traced_values():
    # Documented rule: no Python `if` on a tracer. Building every constructor under
    # jit with traced arguments must trace without a ConcretizationTypeError.
    def build(g, nu, mu, r, w):
        mat = jc.Zener(g, g / 2, 1.0, nu)
        sc = jc.Scene(GRID, jc.Sphere(r), mat, TIMES, jc.Force(w), friction=mu)
        return sc.friction + sc.material.mu_0 + sc.indenter.radius

    out = eqx.filter_jit(build)(1.0, 0.3, 0.2, 1.0, 0.01)
    assert float(out) == pytest.approx(0.2 + 0.5 + 1.0)


class TestHertzAndHalfSpace:
    @pytest.mark.parametrize("args, name, shown", [
        ((-1e-2, 0.15, 1e6, 0.3), "radius", "-0.01"),
        ((1e-2, -0.15, 1e6, 0.3), "force", "-0.15"),
        ((1e-2, 0.15, 0.0, 0.3), "shear_modulus", "0.0"),
        ((1e-2, 0.15, 1e6, 0.7), "poisson", "0.7"),
        ((1e-2, NAN, 1e6, 0.3), "force", "nan"),
    ])
    def test_hertz_rejects_bad_values(self, args, name, shown):
        with pytest.raises(ValueError, match=rf"{name}.*{re.escape(shown)}"):
            jc.Hertz(*args)

    def test_hertz_broadcasts_arrays(self):
        # a^3 is linear in W: one Hertz object per array of loads.
        h = jc.Hertz(1e-2, jnp.array([0.1, 0.8]), 1e6, 0.3)
        np.testing.assert_allclose(float(h.contact_radius[1] / h.contact_radius[0]),
                                   2.0, rtol=1e-12)

    def test_half_space_needs_a_grid(self):
        with pytest.raises(TypeError, match=r"grid must be a jc.Grid.*\(8, 8\)"):
            jc.HalfSpace((8, 8))


# ---- Issue 31: traced checks, the solve's dtype, tau round-off, surfaces -------------


class TestTracedChecksFire:
    """Under `jax.jit` the constructors cannot see values; the checks must still fire
    (`eqx.error_if`) when the compiled solve runs. Before: a traced tension and traced
    repeated or unsorted times were solved silently."""

    @staticmethod
    def approach(times, w):
        sc = jc.Scene(GRID, jc.Sphere(1.0), ELASTIC, times, jc.Force(w))
        return jc.solve(sc).approach[-1]

    def test_traced_negative_normal_force(self):
        fn = jax.jit(self.approach)
        runtime_error(lambda: fn(TIMES, -0.01), "normal force must be finite and >= 0")
        assert float(fn(TIMES, 0.01)) > 0  # the same program, a valid load

    def test_traced_negative_force_program(self):
        # A callable program: only its traced output can be checked (in the solve).
        def approach(w):
            program = jc.Force(lambda t: w * (t - 0.5))
            sc = jc.Scene(GRID, jc.Sphere(1.0), ELASTIC, TIMES, program)
            return jc.solve(sc).approach[-1]

        runtime_error(lambda: jax.jit(approach)(0.01),
                      "normal force must be finite and >= 0 at every time")

    @pytest.mark.parametrize("times", [[0.0, 1.0, 1.0], [0.0, 2.0, 1.0]])
    def test_traced_repeated_or_unsorted_times(self, times):
        fn = jax.jit(self.approach)
        runtime_error(lambda: fn(jnp.asarray(times), 0.01),
                      "times must be strictly increasing")

    def test_a_scene_changed_after_construction_is_checked_by_the_solve(self):
        # eqx.tree_at skips the constructor: the solve's own check fires.
        sc = scene()
        sc = eqx.tree_at(lambda s: s.normal.value, sc, jnp.asarray(-0.01))
        runtime_error(lambda: jc.solve(sc), "normal force must be finite and >= 0")
        sc = eqx.tree_at(lambda s: s.times, scene(), jnp.asarray([0.0, 1.0, 0.5]))
        runtime_error(lambda: jc.solve(sc), "times must be strictly increasing")


class TestSolveDtype:
    """Values valid in float64 but not in the float32 the solve uses (a float32 grid):
    checked after the cast (before: checked before it, then silently wrong)."""

    GRID32 = jc.Grid((8, 8), jnp.float32(1.0))

    def scene32(self, **kwargs):
        base = dict(grid=self.GRID32, indenter=jc.Sphere(1.0), material=ELASTIC,
                    times=TIMES, normal=jc.Force(0.01))
        return jc.Scene(**{**base, **kwargs})

    def test_times_that_collapse_in_float32(self):
        # The creep came out 13 % off: float32's spacing near 1e5 is 0.0078.
        times = 1e5 + jnp.linspace(0.0, 0.02, 5)
        raises(lambda: self.scene32(times=times), ValueError,
               "times are not strictly increasing in float32", "100000.02")
        scene(times=times)  # float64 grid: fine

    def test_times_whose_steps_round_in_float32(self):
        times = 1e5 + jnp.linspace(0.0, 0.2, 5)  # steps 0.05 -> 0.0547 / 0.0469
        raises(lambda: self.scene32(times=times), ValueError,
               "times lose precision in float32", "off, more than 1%")
        self.scene32(times=jnp.linspace(0.0, 1.0, 2001))  # 2000 steps from 0: fine

    @pytest.mark.parametrize("modulus, shown", [(1e38, "J(0) = 1e-38"),
                                                (1e-30, "J(0) = 1e+30")])
    def test_moduli_out_of_float32_range(self, modulus, shown):
        # Before: jc.Elastic(1e38, 0.3) on a float32 grid gave a NaN approach with
        # converged=True.
        raises(lambda: self.scene32(material=jc.Elastic(modulus, 0.3)), ValueError,
               shown, "float32")
        if modulus > 1:
            scene(material=jc.Elastic(modulus, 0.3))  # float64: within range

    def test_modulus_that_overflows_float32(self):
        raises(lambda: self.scene32(material=jc.Elastic(1e39, 0.3)), ValueError,
               "shear_modulus=1e+39 overflows in float32")

    def test_relaxation_times_equal_in_float32(self):
        mat = jc.Prony(1.0, [0.5, 0.5], [1.0, 1.0000001], 0.3)  # distinct in float64
        raises(lambda: self.scene32(material=mat), ValueError,
               "material in float32", "tau must be pairwise distinct")

    def test_load_that_overflows_float32(self):
        raises(lambda: self.scene32(normal=jc.Force(1e39)), ValueError,
               "normal force 1e+39 overflows in float32")
        raises(lambda: self.scene32(x=jc.Displacement([0.0, 1.0, 1e39])), ValueError,
               "x displacement [0.e+00 1.e+00 1.e+39] overflows in float32")

    def test_solve_normal_checks_in_the_grid_dtype(self):
        raises(lambda: jc.solve_normal(self.GRID32, jc.Sphere(1.0),
                                       jc.Elastic(1e38, 0.3), force=0.01),
               ValueError, "J(0) = 1e-38", "float32")
        raises(lambda: jc.solve_normal(self.GRID32, jc.Sphere(1.0), ELASTIC,
                                       force=1e39),
               ValueError, "force 1e+39 overflows in float32")

    def test_a_preset_cast_to_float32_is_checked_again(self):
        # jc.presets cast with dtype=: the scene is rebuilt in float32, so its checks
        # run in the solve's dtype.
        sc = jc.presets.hertz(n=8)
        sc = eqx.tree_at(lambda s: s.times, sc, jnp.asarray([1e5]))  # one point: fine
        jc.presets._cast(sc, jnp.float32)
        sc = eqx.tree_at(lambda s: s.normal, sc, jc.Force(jnp.asarray([0.15, 0.15])))
        sc = eqx.tree_at(lambda s: s.times, sc, jnp.asarray([1e5, 1e5 + 1e-3]))
        raises(lambda: jc.presets._cast(sc, jnp.float32), ValueError,
               "not strictly increasing in float32")


def test_relaxation_times_repeated_to_round_off():
    # 1 + 1e-15 is 4.5 units of float64 rounding from 1: the same time.
    for build in (lambda tau: jc.Prony(1.0, [0.5, 0.5], tau, 0.3),
                  lambda tau: jc.Prony.from_creep(2.0, [0.5, 0.5], tau, 0.3)):
        raises(lambda: build([1.0, 1.000000000000001]), ValueError,
               "tau must be pairwise distinct beyond rounding", "1.000000000000001")
        build([1.0, 1.00000000000001])  # 45 units apart: two arms
    # Traced (under jit): the same rule through eqx.error_if.
    fn = jax.jit(lambda tau: jc.Prony(1.0, jnp.array([0.5, 0.5]), tau, 0.3).creep(1.0))
    runtime_error(lambda: fn(jnp.array([1.0, 1.000000000000001])),
                  "tau must be pairwise distinct beyond rounding")


class TestSurfaceEdge:
    """A `jc.Surface` whose contact reaches the edge of a non-periodic grid, or covers
    it, warns like a `jc.Sphere` (before: no warning)."""

    G, NU, R = 1e6, 0.3, 1e-2
    GRID16 = TestEdgeOfDomain.GRID16

    def paraboloid(self):
        x, y = self.GRID16.coordinates()
        return (x * x + y * y) / (2 * self.R)

    def test_flat_surface_covers_the_grid(self):
        flat = jc.Surface(jnp.zeros((16, 16)))
        with pytest.warns(jc.EdgeContactWarning, match="covers every cell of the grid"):
            jc.Scene(self.GRID16, flat, jc.Elastic(self.G, self.NU), TIMES,
                     normal=jc.Force(1e-3))

    @pytest.mark.parametrize("a, warns", [(0.5e-3, False), (0.95e-3, True)])
    def test_paraboloid_agrees_with_the_sphere(self, a, warns):
        # The bearing-area estimate is Hertz's for a paraboloid: a Hertz radius of
        # 0.95 mm covers the centres of the outer ring's cells (0.9375 mm out); the
        # sphere's warning (radius > 0.875 mm, the ring's inner edge) agrees at both.
        force = jc.Force(TestEdgeOfDomain.hertz_force(self, a))
        mat = jc.Elastic(self.G, self.NU)
        for indenter in (jc.Surface(self.paraboloid()), jc.Sphere(self.R)):
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", jc.EdgeContactWarning)
                jc.Scene(self.GRID16, indenter, mat, TIMES, normal=force)
            assert (len(caught) == 1) == warns, (indenter, caught)

    def test_displacement_control_and_offset(self):
        # Approach delta: the contact edge estimated at h = delta / 2 above the lowest
        # point (heights + 1 mm offset: the approach counts from height 0).
        mat = jc.Elastic(self.G, self.NU)
        heights = self.paraboloid() + 1e-3
        edge_h = float(self.paraboloid()[0, 8])  # the outer ring on the x axis
        jc.Scene(self.GRID16, heights, mat, TIMES,
                 normal=jc.Displacement(1e-3 + 1.9 * edge_h))
        with pytest.warns(jc.EdgeContactWarning, match="reaches the outer ring"):
            jc.Scene(self.GRID16, heights, mat, TIMES,
                     normal=jc.Displacement(1e-3 + 2.1 * edge_h))

    def test_solve_normal_warns_and_periodic_does_not(self):
        flat = jnp.zeros((16, 16))
        mat = jc.Elastic(self.G, self.NU)
        with pytest.warns(jc.EdgeContactWarning, match="covers every cell of the grid"):
            jc.solve_normal(self.GRID16, flat, mat, force=1e-3)
        periodic = jc.Grid((16, 16), 2e-3, periodic=True)
        jc.Scene(periodic, flat, mat, TIMES, normal=jc.Force(1e-3))


class TestRuntimeMessageFirst:
    """What a user sees of a traced check (measured): under `jax.jit` the first line is
    "INTERNAL: CpuCallback error ..." and the message sits ~50 lines down; under
    `eqx.filter_jit` / `jc.solve` the first line is equinox's "Above is the stack ...".
    `_validate.clear_runtime_errors` re-raises it as a ValueError whose first line is
    the message."""

    @staticmethod
    def build(w):
        sc = jc.Scene(GRID, jc.Sphere(1.0), ELASTIC, TIMES, jc.Force(w))
        return jc.solve(sc).approach[-1]

    def first_line(self, fn):
        with pytest.raises(Exception) as info:
            jax.block_until_ready(fn())
        return str(info.value).splitlines()[0], info.value

    def test_jax_jit(self):
        from jaxcontact._validate import clear_runtime_errors

        fn = jax.jit(self.build)
        line, exc = self.first_line(lambda: fn(-0.01))
        assert line.startswith("INTERNAL: CpuCallback error")  # what users see today
        assert "normal force must be" in str(exc)

        def clear():
            with clear_runtime_errors():
                return jax.block_until_ready(fn(-0.01))

        line, exc = self.first_line(clear)
        assert isinstance(exc, ValueError)
        assert line == "normal force must be finite and >= 0"

    def test_solve_of_a_changed_scene(self):
        """`jc.solve` itself runs its program inside `clear_runtime_errors`: the
        message is the first line (equinox's "Above is the stack ..." before)."""
        sc = eqx.tree_at(lambda s: s.times, scene(), jnp.asarray([0.0, 1.0, 0.5]))
        line, exc = self.first_line(lambda: jc.solve(sc))
        assert isinstance(exc, ValueError)
        # A concrete scene is checked in Python before the program (the bad times
        # named).
        assert line.startswith(
            "times must be strictly increasing (in the grid's dtype)")
        assert "0.5" in line

    def test_other_errors_pass_through(self):
        from jaxcontact._validate import clear_runtime_errors

        with pytest.raises(KeyError, match="other"):
            with clear_runtime_errors():
                raise KeyError("other")
