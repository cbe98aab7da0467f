"""Conical probes in the AFM fitting chain (`jaxcontact fit --tip cone`).

Sneddon's cone, in the library's convention (`E* = 2 G / (1 - nu)`): `F = C G d^2`,
`C = 4 tan(alpha) / (pi (1 - nu))`, contact radius `a = 2 d tan(alpha) / pi`; its
Lee & Radok forms are the sphere's with `u = d^2` for `d^(3/2)`.

- The closed-form Lee & Radok fit with exponent 2 recovers the material of a curve
  computed in closed form here (integrals by hand, not the library's columns), in
  relaxation and in creep, and `fit_prony(init="lee-radok")`'s start converts it
  with the cone's `C`.
- The probe's law against the ring solver: the apparent (Sneddon) modulus of an
  elastic cone's curve solved on rings is its modulus.
- End to end: a relaxation file of a cone made by the ring solver (`jc.solve(...,
  solver=jc.RingPolonskyKeer())`, a one-arm Prony material, white force noise),
  read by `jc.read_afm(exponent=2)` and fitted by `fit_afm_curve` with a conical
  tip: the contact point, the moduli and the relaxation time are recovered.
- Settings and the command line: the tip's parameters are required and refused by
  name; `--half-angle` is in degrees.
"""

import json
import math
import os

import numpy as np
import pytest
from test_afm import FakeCurve

import jaxcontact as jc
from jaxcontact import _cli_fit
from jaxcontact._lee_radok import lee_radok_fit
from jaxcontact._probe import Probe
from jaxcontact.fitting import lee_radok_start
from jaxcontact.fitting.afm import (
    AFMFitSettings,
    apparent_hertz,
    fit_afm_curve,
    half_angle_warning,
)


DATA = os.path.join(os.path.dirname(__file__), "data")
RELAX = os.path.join(DATA, "fmt-jpk-sr_cell1-0008.jpk-force")

ALPHA = math.radians(20.0)  # rad: a typical AFM cone's half-angle
NU = 0.5
C_CONE = 4 * math.tan(ALPHA) / (math.pi * (1 - NU))  # F = C G d^2
TRUTH = jc.Prony(g_inf=1000.0, g=[500.0], tau=[0.3], poisson=NU)


# ---- the closed form -----------------------------------------------------------------


def _tau_grid(t, n_tau=20):
    """`lee_radok_fit`'s relaxation times for the samples `t` (its documented grid)."""
    span, first = t[-1] - t[0], np.min(np.diff(t))
    return np.geomspace(max(first, 1e-3 * span), span, n_tau)


def _cone_relaxation(t, g_inf, g, tau, v=5e-6, ramp=0.2):
    """`(depth, force)` of a one-arm cone indented at `v` [m/s] for `ramp` [s] and
    held, by hand: `F = C (g_inf d^2 + g int_0^t exp(-(t - s) / tau) d(d^2))`, the
    integral in closed form for `d^2 = v^2 s^2` up to `m = min(t, ramp)`."""
    d = v * np.minimum(t, ramp)
    m = np.minimum(t, ramp)
    conv = 2 * v**2 * (tau * m * np.exp(-(t - m) / tau)
                       - tau**2 * np.exp(-(t - m) / tau) + tau**2 * np.exp(-t / tau))
    return d, C_CONE * (g_inf * d**2 + g * conv)


def test_lee_radok_fit_with_exponent_2_recovers_a_cone_material():
    """Relaxation: a depth ramp (5 um/s for 0.2 s) and hold, the force by hand,
    `F = C (g_inf d^2 + g int exp(-(t - s) / tau) d(d^2))`; creep: a force ramp and
    hold, `d^2 = (1 / C) int J(t - s) dF` with the one-arm series' creep compliance.
    The true time is put on the fit's log grid, so the fit is exact but for the
    piecewise-linear reading of `d^2` (relaxation: O(dt^2), measured ~1e-6) and the
    `1e-12` ridge: every modulus and time to 1e-4. The same curve read as a sphere's
    (exponent 1.5) leaves a misfit > 1e4 x larger; the sphere's default is
    unchanged (exponent 1.5 given or not: the same numbers)."""
    t = np.arange(0.0, 2.0 + 5e-4, 1e-3)
    taus = _tau_grid(t)
    tau, g_inf, g = taus[12], 1000.0, 500.0  # tau = 0.157 s
    d, force = _cone_relaxation(t, g_inf, g, tau)  # relaxation
    misfit, got_tau, c = lee_radok_fit(t, force, d, "relaxation", arms=1, exponent=2)
    assert got_tau[0] == tau and misfit < 1e-10, (got_tau, misfit)
    np.testing.assert_allclose(c / C_CONE, [g_inf, g], rtol=1e-4)
    sphere = lee_radok_fit(t, force, d, "relaxation", arms=1)[0]
    assert sphere > 1e4 * max(misfit, 1e-14), (sphere, misfit)
    same = lee_radok_fit(t, force, d, "relaxation", arms=1, exponent=1.5)
    assert same[0] == sphere
    # creep: J(t) = 1 / g_inf - dJ exp(-t / tau_c), tau_c = tau (g_inf + g) / g_inf
    tau_c = taus[12]
    g0 = g_inf + g
    dj = 1 / g_inf - 1 / g0
    ramp = 0.2
    m = np.minimum(t, ramp)
    rate = 5e-9 / ramp  # N/s: 5 nN in 0.2 s
    f = rate * m
    u = rate / C_CONE * (m / g_inf - dj * tau_c * (np.exp(-(t - m) / tau_c)
                                                    - np.exp(-t / tau_c)))
    misfit, got_tau, c = lee_radok_fit(t, f, np.sqrt(u), "creep", arms=1, exponent=2)
    assert got_tau[0] == tau_c and misfit < 1e-10, (got_tau, misfit)
    np.testing.assert_allclose(c * C_CONE, [1 / g0, dj], rtol=1e-4)
    with pytest.raises(ValueError, match="exponent must be a finite number > 0"):
        lee_radok_fit(t, f, np.sqrt(u), "creep", exponent=-2)


def test_lee_radok_start_converts_with_the_cones_law():
    """`jc.fit_prony(init="lee-radok")`'s start on a cone template: the closed-form
    relaxation curve of the test above converted with the cone's `C` (not the
    sphere's) gives the generating series to 1e-4; a `jc.BluntedCone` (no closed
    form here) is refused by name."""
    t = np.arange(0.0, 2.0 + 5e-4, 1e-3)
    tau = _tau_grid(t)[12]
    d, force = _cone_relaxation(t, 1000.0, 500.0, tau)
    data = jc.IndentationData(t, force=force, depth=d)
    grid = jc.Grid((8, 8), 2e-6)
    template = jc.Scene(grid, jc.Cone(ALPHA), jc.Elastic(1e3, NU), t[:3],
                        jc.Displacement(0.0))
    start = lee_radok_start(data, template, 1, poisson=NU)
    np.testing.assert_allclose([float(start.g_inf), float(start.g[0]),
                                float(start.tau[0])], [1000.0, 500.0, tau], rtol=1e-4)
    blunt = jc.Scene(grid, jc.BluntedCone(ALPHA, 1e-7), jc.Elastic(1e3, NU), t[:3],
                     jc.Displacement(0.0))
    with pytest.raises(ValueError, match="jc.Sphere or jc.Cone indenter, got "
                                         "BluntedCone"):
        lee_radok_start(data, blunt, 1, poisson=NU)


def test_probe_laws_and_the_apparent_modulus_of_an_elastic_cone_on_rings():
    """`Probe`: Sneddon's and Hertz's prefactors and contact radii as stated. An
    elastic cone (G = 1 kPa) pressed to 1 um on 512 rings (second order in the ring
    width): its force is Sneddon's to 1e-3, and the apparent modulus of that curve
    (`apparent_hertz` with the cone) is `E = 2 G (1 + nu)` to 1e-3, where the
    sphere's law read on the same curve is off by far (its exponent is wrong)."""
    from jaxcontact._solve_rings import solve_axisymmetric

    cone, sphere = Probe.cone(ALPHA), Probe.sphere(5e-6)
    assert cone.exponent == 2 and sphere.exponent == 1.5
    assert cone.prefactor(NU) == pytest.approx(C_CONE, rel=1e-15)
    assert sphere.prefactor(0.3) == pytest.approx(8 * math.sqrt(5e-6) / (3 * 0.7),
                                                  rel=1e-15)
    assert cone.contact_radius(1e-6) == pytest.approx(2e-6 * math.tan(ALPHA) / math.pi)
    assert sphere.contact_radius(1e-6) == pytest.approx(math.sqrt(5e-12))
    assert Probe.of(jc.Cone(ALPHA)) == cone and Probe.of(5e-6) == sphere
    assert Probe.of(jc.Sphere(5e-6)) == sphere
    with pytest.raises(ValueError, match=r"degrees\? 20 deg = 0.349066 rad"):
        Probe.cone(20)
    with pytest.raises(ValueError, match="not a Pyramid"):
        Probe.of(jc.Pyramid(ALPHA))
    times = np.linspace(0.0, 1.0, 11)
    depth = 1e-6 * times
    scene = jc.Scene(jc.Grid((8, 8), 2e-6), jc.Cone(ALPHA), jc.Elastic(1e3, NU), times,
                     jc.Displacement(depth))
    force = np.asarray(solve_axisymmetric(scene, rings=512, radius=1e-6)
                       .normal_force)
    np.testing.assert_allclose(force[1:], C_CONE * 1e3 * depth[1:] ** 2, rtol=1e-3)
    curve = jc.AFMCurve(time=times, force=force, depth=depth,
                        segment=np.zeros(times.size, int), mode="relaxation",
                        spring_constant=0.1, contact_time=0.0, contact_height=0.0,
                        baseline_force=0.0, baseline_noise=1e-12, path=None,
                        metadata={}, raw={})
    e = apparent_hertz(curve, cone, NU)
    assert e["E_Pa"] == pytest.approx(2 * 1e3 * (1 + NU), rel=1e-3)
    assert e["law"] == "Sneddon" and "Sneddon (cone)" in e["note"]
    assert abs(apparent_hertz(curve, 5e-6, NU)["E_Pa"] / 3e3 - 1) > 0.05


def test_a_float32_cone_fit_starts_from_lee_radok_and_runs_on_rings():
    """float32 (the package's rule: no crash where float64 is the tested path): the
    closed-form relaxation curve of a cone, a float32 cone template, `jc.fit_prony(...,
    init="lee-radok")` on 64 rings: the start converts the float32 half-angle, the
    fit stays in float32, Levenberg-Marquardt (the default on rings) converges, and it
    lands within 2 % of the truth (the 64 rings' bias against the closed form, ~3e-4,
    and float32's ring solve, rtol 1e-5)."""
    import jax.numpy as jnp

    f32 = jnp.float32
    t = np.r_[0.0, np.geomspace(0.01, 2.0, 30)]
    tau, g_inf, g = 0.3, 1000.0, 500.0
    d, force = _cone_relaxation(t, g_inf, g, tau)
    data = jc.IndentationData(t.astype(np.float32), force=force.astype(np.float32),
                              depth=d.astype(np.float32))
    template = jc.Scene(jc.Grid((8, 8), jnp.asarray(2e-6, f32)),
                        jc.Cone(jnp.asarray(ALPHA, f32)),
                        jc.Elastic(jnp.asarray(1e3, f32), jnp.asarray(NU, f32)),
                        jnp.asarray(t, f32), jc.Displacement(jnp.asarray(d, f32)))
    fit = jc.fit_prony(data, template, 1, init="lee-radok")
    assert "Levenberg-Marquardt" in fit.message and fit.converged, fit.message
    assert fit.solver == "rings" and fit.material.g.dtype == jnp.float32
    got = np.r_[fit.material.g_inf, fit.material.g, fit.material.tau].astype(float)
    np.testing.assert_allclose(got, [g_inf, g, tau], rtol=0.02)


# ---- settings and template -----------------------------------------------------------


def test_settings_and_template_describe_the_tip():
    """`AFMFitSettings` takes a sphere (the radius, as before: positionally too) or a
    cone (`tip="cone"`, `half_angle` in radians); a missing parameter, a parameter of
    the other tip, or a half-angle in degrees is refused by name. The cone's
    template: a `jc.Cone`, its grid 4 x Sneddon's contact radius at the deepest
    sample, its placeholder modulus Sneddon's at the largest force."""
    assert AFMFitSettings(5e-6).probe == Probe.sphere(5e-6)
    cone = AFMFitSettings(tip="cone", half_angle=ALPHA)
    assert cone.probe == Probe.cone(ALPHA) and cone.radius is None
    for kwargs, match in (
            ({}, "a spherical tip needs radius"),
            ({"tip": "cone"}, "tip='cone' needs half_angle"),
            ({"tip": "cone", "half_angle": ALPHA, "radius": 5e-6},
             "radius=5e-06 is a sphere's"),
            ({"radius": 5e-6, "half_angle": ALPHA}, "is a cone's: give tip='cone'"),
            ({"tip": "cone", "half_angle": 20.0}, r"half_angle must be in \(0, pi/2\)"),
            ({"tip": "pyramid", "half_angle": ALPHA}, "tip must be 'sphere' or 'cone'"),
    ):
        with pytest.raises(ValueError, match=match):
            AFMFitSettings(**kwargs)
    times = np.linspace(0.0, 1.0, 11)
    depth = 1e-6 * times
    force = C_CONE * 600.0 * depth**2
    curve = jc.AFMCurve(time=times, force=force, depth=depth,
                        segment=np.zeros(11, int), mode="relaxation",
                        spring_constant=0.1, contact_time=0.0, contact_height=0.0,
                        baseline_force=0.0, baseline_noise=1e-12, path=None,
                        metadata={}, raw={})
    tmpl = curve.scene_template(indenter=jc.Cone(ALPHA), n=16)
    assert isinstance(tmpl.indenter, jc.Cone)
    width = 4 * 2 * 1e-6 * math.tan(ALPHA) / math.pi
    np.testing.assert_allclose(np.asarray(tmpl.grid.size), [width, width], rtol=1e-12)
    assert float(tmpl.material.relaxation(0.0)) == pytest.approx(600.0, rel=1e-12)
    sphere = curve.scene_template(5e-6, n=16)  # the historical call
    assert isinstance(sphere.indenter, jc.Sphere)
    with pytest.raises(ValueError, match="radius \\[m\\] \\(a sphere\\) or indenter="):
        curve.scene_template(5e-6, indenter=jc.Cone(ALPHA))
    with pytest.raises(ValueError, match="jc.Sphere or a jc.Cone, got BluntedCone"):
        curve.scene_template(indenter=jc.BluntedCone(ALPHA, 1e-7))
    # a template whose indenter is not the settings' tip is refused
    with pytest.raises(ValueError, match="is not the settings' tip"):
        fit_afm_curve(curve, AFMFitSettings(radius=5e-6), template=tmpl)
    # the half-angle check: radians read as degrees on the command line
    assert half_angle_warning(ALPHA) is None
    text = half_angle_warning(math.radians(0.35))
    assert text.startswith("--half-angle 0.35 degrees") and text.endswith(
        "if 0.35 was meant in radians, pass --half-angle 20.05"), text


# ---- end to end ----------------------------------------------------------------------


def synthetic_cone_file(noise=5e-12, seed=0, k=0.1, pre=100, material=TRUTH):
    """The columns of a relaxation file of a cone (half-angle 20 deg) made by the
    ring solver: 1 kHz; `pre` samples of approach before contact (the tip 5 um/s,
    force 0), then the depth ramps to 1 um in 0.2 s and holds for 1.8 s. The force is
    `jc.solve(..., solver=jc.RingPolonskyKeer())` (128 rings over 1.25 x the cone's
    radius at 1 um: half the ring width of the fit's 64 over the same radius), scheme
    "linear", plus white noise `noise` [N] (0.4 % of the largest force); the height
    is the base's, `h_c - depth - F / k` (the piezo sees no force noise). Returns the
    afmformats-like curve and the contact's file time [s]."""
    dt, v, d_max = 1e-3, 5e-6, 1e-6
    t = np.arange(0.0, 2.0 + dt / 2, dt)
    depth = np.minimum(v * t, d_max)
    width = 2 * 1.25 * d_max * math.tan(ALPHA)
    scene = jc.Scene(jc.Grid((8, 8), width), jc.Cone(ALPHA), material, t,
                     jc.Displacement(depth))
    force = np.asarray(jc.solve(scene, solver=jc.RingPolonskyKeer(),
                                scheme="linear").normal_force)
    t_pre = -dt * np.arange(pre, 0, -1)
    h_c = 30e-6
    time = np.r_[t_pre, t] + pre * dt
    f_true = np.r_[np.zeros(pre), force]
    height = np.r_[h_c - v * t_pre, h_c - depth - force / k]
    rng = np.random.default_rng(seed)
    columns = {"time": time, "force": f_true + noise * rng.standard_normal(time.size),
               "height (measured)": height,
               "segment": np.r_[np.zeros(pre, int), (t > 0.2 + 1e-12).astype(int)]}
    meta = {"spring constant": k, "imaging mode": "stress-relaxation"}
    return FakeCurve(columns, meta), pre * dt


CONE_SETTINGS = dict(tip="cone", half_angle=ALPHA, arms=1)


@pytest.fixture(scope="module")
def cone_fit():
    """`(raw curve, true contact time, AFMCurve, AFMFit)`: `synthetic_cone_file` read
    as `jaxcontact fit --tip cone` reads it and fitted with `CONE_SETTINGS`."""
    raw, t_contact = synthetic_cone_file()
    curve = jc.read_afm(raw, contact="viscoelastic", segments=("approach", "hold"),
                        exponent=2)
    return raw, t_contact, curve, fit_afm_curve(curve, AFMFitSettings(**CONE_SETTINGS))


def test_a_cone_curve_made_on_rings_is_fitted_to_its_truth(cone_fit):
    """The ring solver's cone curve (`synthetic_cone_file`), read with the cone's
    exponent and the viscoelastic contact point, fitted with `tip="cone"` (1 arm, the
    defaults otherwise: 64 rings, 8 + 24 bins, the analysis uncertainty).

    - the contact point within 3 samples (15 nm of depth) of the true one (measured:
      2 samples early, seeds 0-2); read with the sphere's exponent instead, it lands
      > 20 samples off (measured 44-55 ms late): the tip's law sets it;
    - the fit converged and good (the raw approach and hold within 2 x their noise:
      measured 1.06-1.16 and 0.94-0.99), nothing flagged; the cone reported (tip,
      Sneddon's apparent modulus, no radius, no depth-over-radius caveat);
    - `g_inf`, `g_1`, `tau_1` within 3 reported (total) standard deviations of the
      truth, and outright within 4 % (moduli) and 3 % (time). The budget is the
      contact point's: n samples early overstate the depth by 5n nm of 1 um, `d^2`
      by 1 % a sample, the moduli by as much the other way (measured, seeds 0-2:
      g_inf -1.1 to -1.6 %, g_1 -1.9 to -2.3 %, tau_1 -0.1 to +0.7 %, with the
      contact 2 samples early); the noise (0.4 % per raw sample) adds ~0.3 % on a
      modulus (the optimiser's std), the 64 rings against the generator's 128 ~3e-4.
    """
    raw, t_contact, curve, result = cone_fit
    assert abs(curve.contact_time - t_contact) <= 3.5e-3, curve.contact_time
    assert "refined" in curve.contact_note, curve.contact_note
    as_sphere = jc.read_afm(raw, contact="viscoelastic",
                            segments=("approach", "hold"))
    assert abs(as_sphere.contact_time - t_contact) > 20e-3, as_sphere.contact_time
    r = result.report
    assert r["tip"] == {"shape": "cone", "half_angle_rad": ALPHA,
                        "half_angle_deg": pytest.approx(20.0)}
    assert r["radius_m"] is None and r["radius_warning"] is None
    assert "1 / tan(half-angle)" in r["tip_note"]
    assert r["apparent_hertz"]["law"] == "Sneddon"
    assert r["solver"] == "rings" and r["converged"], r["message"]
    assert r["quality"]["verdict"] == "good", r["quality"]
    assert r["flags"] == [], r["flags"]
    assert not any("radius" in c for c in r["caveats"]), r["caveats"]
    p = r["parameters"]
    for entry, truth, tol in ((p["g_inf_Pa"], 1000.0, 0.04),
                              (p["g_Pa"][0], 500.0, 0.04),
                              (p["tau_s"][0], 0.3, 0.03)):
        err = abs(math.log(entry["value"] / truth))
        assert err < 3 * entry["std_log"], (entry, truth)
        assert err < tol, (entry, truth)


def test_a_force_map_of_the_cone_curve_is_its_fit(cone_fit):
    """`jc.fit_force_map` with the cone's settings reads each curve with the cone's
    exponent (its contact point is the direct read's) and gives `fit_afm_curve`'s
    numbers; its attributes name the cone (no radius: netCDF holds no None), and a
    radius given with a cone's settings is refused."""
    pytest.importorskip("xarray")
    raw, _, curve, result = cone_fit
    settings = AFMFitSettings(**CONE_SETTINGS)
    ds, reports = jc.fit_force_map([raw], settings=settings, progress=False,
                                   return_reports=True)
    report = reports[(0, 0)]
    assert report["contact_point"] == result.report["contact_point"]
    for key in ("g_inf_Pa",):
        assert report["parameters"][key]["value"] == pytest.approx(
            result.report["parameters"][key]["value"], rel=1e-9)
    assert report["parameters"]["tau_s"][0]["value"] == pytest.approx(
        result.report["parameters"]["tau_s"][0]["value"], rel=1e-9)
    assert ds.attrs["tip"] == "cone" and "radius_m" not in ds.attrs
    assert ds.attrs["half_angle_rad"] == ALPHA
    assert ds.attrs["half_angle_deg"] == pytest.approx(20.0)
    assert float(ds.apparent_hertz_E.values[0, 0]) == pytest.approx(
        result.report["apparent_hertz"]["E_Pa"], rel=1e-12)
    with pytest.raises(ValueError, match="is a sphere's, but the settings describe"):
        jc.fit_force_map([raw], 5e-6, settings=settings)


# ---- the command line ----------------------------------------------------------------


@pytest.mark.parametrize("argv, match", [
    ([], "--radius is required for a spherical probe (--tip sphere, the default)"),
    (["--tip", "cone"], "--tip cone needs --half-angle DEG"),
    (["--tip", "cone", "--half-angle", "20", "--radius", "5e-6"],
     "--radius 5e-06 is a sphere's"),
    (["--radius", "5e-6", "--half-angle", "20"], "--half-angle 20 is a cone's"),
    (["--tip", "cone", "--half-angle", "90"], "--half-angle must be in (0, 90) deg"),
    (["--tip", "cone", "--half-angle", "-5"], "--half-angle must be in (0, 90) deg"),
    (["--tip", "cone", "--half-angle", "nan"], "--half-angle must be in (0, 90)"),
])
def test_fit_command_refuses_a_tip_without_its_parameter(argv, match, tmp_path,
                                                         capsys):
    from jaxcontact._cli import main

    assert main(["fit", RELAX, "--out", str(tmp_path), *argv]) == 2
    assert match in capsys.readouterr().err


def test_fit_command_takes_the_half_angle_in_degrees():
    """`--tip cone --half-angle 20`: the settings hold 20 degrees in radians (no
    radius), and the curve is read with the cone's exponent."""
    from jaxcontact._cli import _attach_negative_values, _parser

    args = _parser().parse_args(_attach_negative_values(
        ["fit", RELAX, "--tip", "cone", "--half-angle", "20"]))
    samples, segments = _cli_fit._check(args)
    settings = _cli_fit._settings(args, samples, segments)
    assert settings.tip == "cone" and settings.radius is None
    assert settings.half_angle == pytest.approx(ALPHA, rel=1e-15)
    assert settings.probe.exponent == 2


def test_fit_command_fits_a_cone_and_its_moduli_scale_as_1_over_tan(tmp_path, capsys,
                                                                    monkeypatch):
    """The relaxation file fitted as a cone at half-angles 15 and 30 degrees (tiny: 1
    arm, 4 + 8 bins, no analysis refits, no grid check): exit 0 or 1 (the file's
    known misfit), the JSON names the cone, the console its note and Sneddon's
    modulus; the relaxation time agrees and every modulus (the apparent one too)
    scales as 1 / tan(alpha) between the two, to 1e-3 (the contact point does not
    depend on the angle, and the ring model's radius scales with tan(alpha): two
    similar discrete problems; the fits' own tolerance)."""
    pytest.importorskip("afmformats")
    from jaxcontact._cli import main

    monkeypatch.setenv("JAXCONTACT_CACHE_DIR", str(tmp_path / "xla"))
    out = {}
    for deg in (15.0, 30.0):
        d = tmp_path / f"a{deg:g}"
        code = main(["fit", RELAX, "--tip", "cone", "--half-angle", str(deg),
                     "--arms", "1", "--samples", "4,8,1", "--no-analysis-uncertainty",
                     "--no-check-grid", "--out", str(d)])
        assert code in (0, 1)
        text = capsys.readouterr().out
        assert "scale as 1 / tan(half-angle)" in text
        assert "apparent Sneddon E (approach)" in text
        js = json.loads((d / "fmt-jpk-sr_cell1-0008_fit.json").read_text())
        assert js["tip"]["shape"] == "cone"
        assert js["tip"]["half_angle_deg"] == pytest.approx(deg)
        assert js["settings"]["tip"] == "cone" and js["radius_m"] is None
        assert js["solver"] == "rings" and js["arms"] == 1
        out[deg] = js
    a, b = out[15.0], out[30.0]
    ratio = math.tan(math.radians(15.0)) / math.tan(math.radians(30.0))
    pa, pb = a["parameters"], b["parameters"]
    assert pb["tau_s"][0]["value"] / pa["tau_s"][0]["value"] == pytest.approx(
        1.0, abs=1e-3)
    for key in ("g_inf_Pa",):
        assert pb[key]["value"] / pa[key]["value"] == pytest.approx(ratio, rel=1e-3)
    assert pb["g_Pa"][0]["value"] / pa["g_Pa"][0]["value"] == pytest.approx(
        ratio, rel=1e-3)
    assert (b["apparent_hertz"]["E_Pa"] / a["apparent_hertz"]["E_Pa"]
            == pytest.approx(ratio, rel=1e-12))
