# slow (~2-4 min at ci size, kept out of the default run for the CI time budget;
# test_fit.py and test_afm.py cover the same paths)
# %% [markdown]
# # Fitting a Prony series to indentation tests
#
# Part A starts from a real instrument file: an AFM creep test on a polymer gel (JPK,
# from afmformats' test data, `tests/data/`). We read it (`jc.read_afm`: segments,
# contact point, force above the baseline, indentation depth), fit a Prony series
# `G(t) = g_inf + sum_i g_i exp(-t / tau_i)` through the full contact model
# (`jc.fit_prony`: every contact step solved, exact implicit gradients), and compare it
# with an independent closed-form fit (Lee & Radok's hereditary integral, valid while
# the contact grows) on the loading and the hold, and on the retract, where Lee & Radok
# no longer holds (Ting's unloading) and the contact model does.
#
# Part B is a synthetic experiment with a known material (the paper's PMMA): how well
# the parameters are recovered, and how their errors follow the noise.
#
# `JAXCONTACT_NOTEBOOK_SIZE`: `ci` (tiny), `small` (default) or `paper` (64 x 64 x 40,
# the target size); `JAXCONTACT_NOTEBOOK_OUT=DIR` saves the figures as PNG.

# %%
import os
import time
from pathlib import Path

import jax


jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import scipy.optimize  # noqa: E402

import jaxcontact as jc  # noqa: E402


SIZE = os.environ.get("JAXCONTACT_NOTEBOOK_SIZE", "small")
if SIZE not in ("ci", "small", "paper"):
    raise ValueError(
        f"JAXCONTACT_NOTEBOOK_SIZE must be ci, small or paper, got {SIZE!r}")
N = {"ci": 16, "small": 32, "paper": 64}[SIZE]
NT = {"ci": 16, "small": 24, "paper": 40}[SIZE]
NOISE_LEVELS = {"ci": (0.0, 0.01), "small": (0.0, 0.003, 0.01, 0.03),
                "paper": (0.0, 0.001, 0.003, 0.01, 0.03)}[SIZE]
AFM_N = {"ci": 12, "small": 24, "paper": 48}[SIZE]          # grid of the real-file fit
AFM_BINS = {"ci": {"approach": 6, "hold": 14, "retract": 5},
            "small": {"approach": 8, "hold": 24, "retract": 8},
            "paper": {"approach": 12, "hold": 40, "retract": 12}}[SIZE]
# Figures are saved to JAXCONTACT_NOTEBOOK_OUT, by default out/notebooks (a notebook
# also shows them inline).
OUT = os.environ.get("JAXCONTACT_NOTEBOOK_OUT") or os.path.join("out", "notebooks")
print(f"figures -> {os.path.abspath(OUT)}")
DATA = (Path(globals().get("__file__", "notebooks/x.py")).resolve().parents[1]
        / "tests" / "data")


def show(fig, name):
    os.makedirs(OUT, exist_ok=True)
    fig.savefig(os.path.join(OUT, f"fit_prony_{name}.png"), dpi=100)


# %% [markdown]
# # Part A: a real AFM creep test
#
# ## A1. Reading the file
#
# `jc.read_afm` reads the file through afmformats (`pip install ".[afm]"`), classifies
# the segments by the height's travel (approach / hold / retract), finds the contact
# point on the approach (piecewise fit of a baseline and a Hertz `x^(3/2)` branch in
# the tip's travel, Lin et al. 2007), subtracts the baseline and computes the
# indentation `(h_c - h) - (F - F_c) / k`. The retract is cut where the contact is
# lost: the model has no adhesion (this gel pulls ~10 nN on the way out).
#
# The probe radius is NOT in the file: we take R = 5 um. Relaxation times and modulus
# ratios do not depend on it; absolute moduli scale as R^(-1/2).

# %%
RADIUS = 5e-6  # m (assumed: the file does not record it)
curve = jc.read_afm(DATA / "fmt-jpk-cc_pr14-polymergel-2021.06.30.jpk-force")
raw = curve.raw
print(f"mode: {curve.mode}, spring constant {curve.spring_constant} N/m, contact at "
      f"t = {curve.contact_time:.3f} s, baseline noise {curve.baseline_noise:.2g} N")
print("kept samples per segment (approach, hold, retract):", np.bincount(curve.segment))
fig, ax = plt.subplots(1, 2, figsize=(10, 3.6))
for code, name in enumerate(("approach", "hold", "retract")):
    sel = raw["segment"] == code
    ax[0].plot(raw["time"][sel], raw["force"][sel] * 1e9, lw=0.8, label=name)
    kept = curve.segment == code
    ax[1].plot(curve.time[kept], curve.depth[kept] * 1e6, lw=0.8, label=name)
ax[0].axvline(curve.contact_time, color="k", ls=":", label="contact")
ax[0].set(xlabel="t [s] (file clock)", ylabel="force [nN]", title="raw force")
ax[1].set(xlabel="t since contact [s]", ylabel="depth [um]", title="indentation (kept)")
ax[0].legend(fontsize=8)
fig.tight_layout()
show(fig, "afm_raw")
hold = curve.segment == 1
assert curve.mode == "creep" and abs(curve.spring_constant - 0.061) < 1e-9
assert curve.depth[hold][-50:].mean() > curve.depth[hold][:50].mean()  # it creeps

# %% [markdown]
# ## A2. The fit through the contact model
#
# The curve is binned (log-spaced bins in the hold, where the creep is fastest at its
# start) and fitted under load control: the measured force drives the model, the
# depth is fitted. `scene_template` sizes the grid to 4 Hertz contact radii. One arm:
# two are not identifiable from a 3 s hold (the second arm's time runs beyond the
# hold, degenerate with `g_inf`; that fit is reported NOT converged).

# %%
t_b, f_b, d_b, seg_b, counts = curve.resampled(AFM_BINS, return_counts=True)
afm_data = jc.IndentationData(t_b, force=f_b, depth=d_b)
afm_template = curve.scene_template(RADIUS, n=AFM_N)
start = time.perf_counter()
# one arm: the 3 s hold cannot separate g_inf from a second, slower arm (a 2-arm fit
# runs into that degeneracy and is reported NOT converged); bins weighted by sqrt(count)
afm_fit = jc.fit_prony(afm_data, afm_template, 1, weights=np.sqrt(counts))
print(f"fit ({AFM_N}^2, {t_b.size} samples, {afm_fit.optimiser}): "
      f"{time.perf_counter() - start:.1f} s with compilation; {afm_fit.message}")
m = afm_fit.material
g0 = float(m.g_inf + jnp.sum(m.g))
print(f"g_inf = {float(m.g_inf):.4g} Pa (+- {afm_fit.std['g_inf']:.2g} in log), "
      f"g = {np.asarray(m.g)} Pa, tau = {np.asarray(m.tau)} s, G(0) = {g0:.4g} Pa")
assert afm_fit.converged, afm_fit.message
print(f"ratios g_i / G(0) = {np.asarray(m.g) / g0} (independent of the radius)")
sigma = curve.noise("depth") / np.sqrt(counts)  # noise of each bin mean
chi = np.sqrt(np.mean((afm_fit.residual / sigma) ** 2))
print(f"residual RMS {np.sqrt(np.mean(afm_fit.residual**2)):.3g} m = {chi:.0f} x the "
      f"noise of the binned data (raw depth noise {curve.noise('depth'):.2g} m)")

# %% [markdown]
# ## A3. An independent closed-form fit: Lee & Radok
#
# While the contact grows (approach and hold under a constant force) the depth of a
# rigid sphere obeys Lee & Radok's integral
# `delta(t)^(3/2) = 3 (1 - nu) / (8 sqrt(R)) int J(t - s) dW(s)`,
# with `J` the shear creep compliance. We fit `J(t) = J_0 + sum_i J_i (1 - exp(-t /
# lambda_i))` to the RAW samples (every 5th) of the approach and the hold with
# SciPy's least squares: no contact solver, no jaxcontact code. Both fits should give
# the same `J(t)` over the hold's times; on the retract Lee & Radok does not apply
# (the contact shrinks: Ting 1966), the contact model does.

# %%
NU = float(afm_template.material.poisson)
loading = curve.segment <= 1
t_lr, w_lr, d_lr = (x[loading][::5] for x in (curve.time, curve.force, curve.depth))
lag = t_lr[:, None] - t_lr[None, :]
d_w = np.diff(w_lr, prepend=0.0)


def lee_radok_depth(p, n=2):
    j0, ji, lam = np.exp(p[0]), np.exp(p[1:1 + n]), np.exp(p[1 + n:])

    def creep(s):
        return j0 + np.sum(ji * (1 - np.exp(-s[..., None] / lam)), axis=-1)

    kernel = np.where(lag >= 0, creep(np.maximum(lag, 0)), 0)
    x = 3 * (1 - NU) / (8 * np.sqrt(RADIUS)) * (kernel @ d_w)
    return np.maximum(x, 0) ** (2 / 3)


p0 = np.log([1 / g0, 0.3 / g0, 0.3 / g0, 0.05, 1.0])
lr = scipy.optimize.least_squares(lambda p: (lee_radok_depth(p) - d_lr) / d_lr.max(),
                                  p0)
j_lr = lambda s: np.exp(lr.x[0]) + np.sum(  # noqa: E731
    np.exp(lr.x[1:3]) * (1 - np.exp(-np.asarray(s)[..., None] / np.exp(lr.x[3:]))),
    axis=-1)
t_hold = curve.time[hold]
s_cmp = np.geomspace(max(t_hold[0] - 0.0, 0.02), t_hold[-1], 50)
j_model = np.asarray(m.creep(jnp.asarray(s_cmp)))
j_closed = j_lr(s_cmp)
rel = np.max(np.abs(j_model / j_closed - 1))
print(f"Lee-Radok closed form: J_0 = {np.exp(lr.x[0]):.3g} 1/Pa, J_i = "
      f"{np.exp(lr.x[1:3])}, lambda = {np.exp(lr.x[3:])} s; residual RMS "
      f"{np.sqrt(np.mean((lee_radok_depth(lr.x) - d_lr) ** 2)):.3g} m")
print(f"J(t) of the contact-model fit against the closed form, 0.02 "
      f"s..{t_hold[-1]:.1f} s: largest relative difference {rel:.3f}")

fig, ax = plt.subplots(1, 2, figsize=(10, 3.8))
ax[0].semilogx(s_cmp, j_model * 1e3, "C1-", label=f"contact model ({AFM_N}$^2$)")
ax[0].semilogx(s_cmp, j_closed * 1e3, "k--", label="Lee-Radok closed form")
ax[0].set(xlabel="t [s]", ylabel="J(t) [1/kPa]", title="creep compliance (R = 5 um)")
ax[0].xaxis.set_minor_formatter(plt.NullFormatter())
ax[0].legend(fontsize=8)
for code, name in enumerate(("approach", "hold", "retract")):
    sel = seg_b == code
    ax[1].plot(t_b[sel], d_b[sel] * 1e6, "o", ms=3, label=f"data ({name})")
ax[1].plot(t_b, afm_fit.curve * 1e6, "k-", lw=1, label="contact model")
# Lee & Radok continued through the retract with the closed-form J: wrong there
t_all, w_all = curve.time[::5], curve.force[::5]
lag_all = t_all[:, None] - t_all[None, :]
kern = np.where(lag_all >= 0, j_lr(np.maximum(lag_all, 0)), 0)
x_all = 3 * (1 - NU) / (8 * np.sqrt(RADIUS)) * (kern @ np.diff(w_all, prepend=0.0))
ax[1].plot(t_all, np.maximum(x_all, 0) ** (2 / 3) * 1e6, "C3:", lw=1.2,
           label="Lee-Radok (continued)")
ax[1].set(xlabel="t since contact [s]", ylabel="depth [um]", title="fits on the data")
ax[1].legend(fontsize=8)
fig.tight_layout()
show(fig, "afm_fit")
assert rel < 0.15, rel  # the two fits agree on J(t) over the hold (grid: ci 12^2)

# %% [markdown]
# # Part B: a synthetic test with a known material
#
# ## 1. The true material: PMMA
#
# The paper gives PMMA's creep compliance (Eq. 28, from Chen et al. 2011) in 1/GPa of
# its modulus `2 G`; in true shear moduli `J = 2 J_paper`. `jc.Prony.from_creep`
# converts it exactly to the relaxation series of Eq. 27 (halved):
# `g_inf = 714.9 MPa, g = (92.3, 95.5) MPa, tau = (8.93, 117.96) s`, `nu = 0.38`.

# %%
creep_form = jc.Prony.from_creep(2e-9 * 0.699, 2e-9 * np.array([0.0838, 0.06174]),
                                 np.array([133.869, 9.9404]), 0.38)
order = np.argsort(np.asarray(creep_form.tau))
true = jc.Prony(creep_form.g_inf, creep_form.g[order], creep_form.tau[order], 0.38)


def describe(m):
    return (f"g_inf = {float(m.g_inf) / 1e6:8.3f} MPa, g = "
            f"{np.array2string(np.asarray(m.g) / 1e6, precision=3)} MPa, tau = "
            f"{np.array2string(np.asarray(m.tau), precision=3)} s")


def params(m):
    return np.concatenate([[float(m.g_inf)], np.asarray(m.g), np.asarray(m.tau)])


NAMES = ["g_inf", "g_1", "g_2", "tau_1", "tau_2"]
print("true:", describe(true))
np.testing.assert_allclose(params(true), [714.855e6, 92.31e6, 95.53e6, 8.93, 117.96],
                           rtol=2e-3)  # the paper's Eq. 27, halved, to its digits

# %% [markdown]
# ## 2. A synthetic relaxation test
#
# Displacement control: the approach jumps to 20 um at t = 0+ and is held for 500 s.
# Samples are log-spaced from 0.5 s so that both relaxation times are seen. The grid
# covers the paper's 1280 um square. Noise: Gaussian, a fraction of the RMS force.

# %%
R = 3.5e-3
grid = jc.Grid((N, N), 1280e-6)
times = jnp.concatenate([jnp.zeros(1), jnp.geomspace(0.5, 500.0, NT - 1)])
depth = jnp.where(times > 0, 20e-6, 0.0)
scene = jc.Scene(grid, jc.Sphere(R), true, times, normal=jc.Displacement(depth))
start = time.perf_counter()
clean = np.asarray(jc.solve(scene).normal_force)
print(f"{N}^2 x {NT} steps: one solve {time.perf_counter() - start:.1f} s "
      "(with compile)")
# Sanity check against Lee & Radok for an indentation held from t_1 = 0.5 s:
# F(t) / F(t_1) = G(t - t_1) / G(0) (the piecewise-constant time scheme on these
# log-spaced steps lags by up to ~1 %).
ratio = clean[1:] / clean[1]
lee_radok = (np.asarray(true.relaxation(times[1:] - times[1]))
             / float(true.relaxation(0.0)))
np.testing.assert_allclose(ratio, lee_radok, rtol=2e-2)

rng = np.random.default_rng(2024)
rms = float(np.sqrt(np.mean(clean**2)))
noise = 0.003
measured = clean + noise * rms * rng.standard_normal(clean.shape)
data = jc.IndentationData(times, force=measured, depth=depth)

# %% [markdown]
# ## 3. The fit
#
# The scene template gives the grid, the indenter and the control mode; its material
# is only a placeholder (the initial guess comes from the data: apparent elastic
# moduli early and late, relaxation times log-spaced inside the data's time range).
# The loss is the mean squared residual relative to the RMS force. These synthetic
# data are a true step (the approach jumps between two samples), computed with the
# piecewise-constant scheme: the fit uses the same scheme (`fit_prony`'s default,
# `"linear"`, joins samples by ramps, which is right for sampled measurements).

# %%
template = jc.Scene(grid, jc.Sphere(R), jc.Elastic(1e9, 0.38), times,
                    normal=jc.Displacement(depth))
start = time.perf_counter()
constant = jc.FitOptions(solve_options={"scheme": "constant"})
fit = jc.fit_prony(data, template, 2, options=constant)
elapsed = time.perf_counter() - start
print(f"fit: {elapsed:.1f} s (with compile), optimiser {fit.optimiser} "
      f"({fit.lm_steps} LM / {fit.adam_steps} Adam + {fit.lbfgs_steps} L-BFGS steps); "
      f"{fit.message}")
print("initial:", describe(fit.initial))
print("fitted: ", describe(fit.material))
print("true:   ", describe(true))
err = params(fit.material) / params(true) - 1
std = np.concatenate([[fit.std["g_inf"]], fit.std["g"], fit.std["tau"]])
assert fit.solves_converged and np.all(np.isfinite(std))
print("relative error:", np.array2string(err, precision=3), " GN std (log):",
      np.array2string(std, precision=3))
# The individual parameters of a 2-term series trade off against each other (few
# samples, noise); the material FUNCTION is what the data determine (next section).

fig, ax = plt.subplots(1, 2, figsize=(10, 3.8))
ax[0].semilogy(fit.loss_history, ".-")
ax[0].axhline(noise**2, color="k", ls="--", lw=0.8, label="noise$^2$ (relative)")
ax[0].set(xlabel="start, end of each optimiser run", ylabel="loss",
          title="loss history")
ax[0].legend()
ax[1].semilogx(times[1:], measured[1:], ".", ms=4, label="measured (0.3 % noise)")
ax[1].semilogx(times[1:], fit.curve[1:], "-", label="fitted model")
ax[1].semilogx(times[1:], clean[1:], "k--", lw=0.8, label="noiseless")
ax[1].set(xlabel="t [s]", ylabel="force [N]", title="relaxation test")
ax[1].legend()
fig.tight_layout()
show(fig, "fit")

# %% [markdown]
# ## 4. Fitted against true material functions
#
# The relaxation modulus `G(t)` and the creep compliance `J(t)` (exact creep series of
# each Prony series), over and beyond the data's time range.

# %%
t_plot = np.geomspace(0.05, 5000.0, 200)
fig, ax = plt.subplots(1, 2, figsize=(10, 3.8))
for m, style, label in ((true, "k-", "true (PMMA)"), (fit.material, "C1--", "fitted"),
                        (fit.initial, "C2:", "initial guess")):
    ax[0].semilogx(t_plot, np.asarray(m.relaxation(t_plot)) / 1e6, style, label=label)
    ax[1].semilogx(t_plot, np.asarray(m.creep(t_plot)) * 1e9, style, label=label)
for a in ax:
    a.axvspan(float(times[1]), float(times[-1]), color="0.92", zorder=0)
ax[0].set(xlabel="t [s]", ylabel="G(t) [MPa]", title="relaxation modulus")
ax[1].set(xlabel="t [s]", ylabel="J(t) [1/GPa]", title="creep compliance")
ax[0].legend()
fig.tight_layout()
show(fig, "material_functions")
in_range = (t_plot >= float(times[1])) & (t_plot <= float(times[-1]))
g_err = np.max(np.abs(np.asarray(fit.material.relaxation(t_plot[in_range]))
                      / np.asarray(true.relaxation(t_plot[in_range])) - 1))
print(f"max relative error of G(t) over the data's range: {g_err:.2e}")
assert g_err < 10 * noise  # the function is far better determined than its parameters

# %% [markdown]
# ## 5. Sensitivities and the noise level
#
# `fit.std` is the Gauss-Newton (linearised least-squares) standard deviation of each
# log-parameter, i.e. roughly its relative standard deviation, from the residual's
# noise level. The slow relaxation time is the least determined: the data stop at
# 500 s, about 4 tau_2. The same compiled program serves every fit below.

# %%
rows = []
for level in NOISE_LEVELS:
    noisy = clean + level * rms * rng.standard_normal(clean.shape)
    f = jc.fit_prony(jc.IndentationData(times, force=noisy, depth=depth), template, 2,
                     noise_std=level * rms if level > 0 else None, options=constant)
    e = params(f.material) / params(true) - 1
    s = np.concatenate([[f.std["g_inf"]], f.std["g"], f.std["tau"]])
    rows.append((level, e, s))
print("noise/rms |" + "".join(f" {n:>16s}" for n in NAMES) + "   (|error| / GN std)")
for level, e, s in rows:
    print(f"{level:9.3f} |" + "".join(f" {abs(a):7.1e}/{b:7.1e}" for a, b in zip(e, s)))
assert np.all(np.abs(rows[0][1]) < 1e-2)  # noiseless: every parameter within 1 %

fig, ax = plt.subplots(1, 2, figsize=(10, 3.8))
x = np.arange(len(NAMES))
ax[0].bar(x - 0.2, std, 0.4, label="GN std (log)")
ax[0].bar(x + 0.2, np.abs(err), 0.4, label="|relative error|")
ax[0].set(xticks=x, xticklabels=NAMES, yscale="log", title="0.3 % noise")
ax[0].legend()
levels = np.array([r[0] for r in rows if r[0] > 0])
for i, name in enumerate(NAMES):
    ax[1].loglog(levels, [abs(r[1][i]) for r in rows if r[0] > 0], "o-", label=name)
ax[1].set(xlabel="noise / rms(F)", ylabel="|relative error|", title="error vs noise")
ax[1].legend()
fig.tight_layout()
show(fig, "sensitivity")
plt.close("all")
