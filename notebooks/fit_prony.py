# slow (~30-60 s at ci size, kept out of the default run for the CI time budget; test_fit.py covers the same path)
# %% [markdown]
# # Fitting a Prony series to an indentation test
#
# A rigid sphere is pressed 20 um into a PMMA half-space and held; the force relaxes.
# From the force-time curve we recover the material's relaxation modulus
# `G(t) = g_inf + sum_i g_i exp(-t / tau_i)` by running the full contact model
# (`jc.solve`) inside the loss and differentiating through it (exact implicit
# gradients of every contact step).
#
# The story:
#
# 1. the "true" material: PMMA from the paper (Eq. 27/28, true shear moduli);
# 2. a synthetic experiment: `jc.solve` gives the force, we add measurement noise;
# 3. the fit: `jc.fit_prony` (Adam, then L-BFGS), its loss history;
# 4. fitted against true relaxation and creep curves;
# 5. sensitivities: the Gauss-Newton standard deviations against the actual errors,
#    and how the error grows with the noise level.
#
# `JAXCONTACT_NOTEBOOK_SIZE`: `ci` (tiny), `small` (default) or `paper` (64 x 64 x 40,
# the target size); `JAXCONTACT_NOTEBOOK_OUT=DIR` saves the figures as PNG.

# %%
import os
import time

import jax


jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import jaxcontact as jc  # noqa: E402


SIZE = os.environ.get("JAXCONTACT_NOTEBOOK_SIZE", "small")
if SIZE not in ("ci", "small", "paper"):
    raise ValueError(f"JAXCONTACT_NOTEBOOK_SIZE must be ci, small or paper, got {SIZE!r}")
N = {"ci": 16, "small": 32, "paper": 64}[SIZE]
NT = {"ci": 16, "small": 24, "paper": 40}[SIZE]
NOISE_LEVELS = {"ci": (0.0, 0.01), "small": (0.0, 0.003, 0.01, 0.03),
                "paper": (0.0, 0.001, 0.003, 0.01, 0.03)}[SIZE]
OUT = os.environ.get("JAXCONTACT_NOTEBOOK_OUT")


def show(fig, name):
    if OUT:
        os.makedirs(OUT, exist_ok=True)
        fig.savefig(os.path.join(OUT, f"fit_prony_{name}.png"), dpi=100)


# %% [markdown]
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
print(f"{N}^2 x {NT} steps: one solve {time.perf_counter() - start:.1f} s (with compile)")
# Sanity check against Lee & Radok for an indentation held from t_1 = 0.5 s:
# F(t) / F(t_1) = G(t - t_1) / G(0) (the piecewise-constant time scheme on these
# log-spaced steps lags by up to ~1 %).
ratio = clean[1:] / clean[1]
lee_radok = np.asarray(true.relaxation(times[1:] - times[1])) / float(true.relaxation(0.0))
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
# The loss is the mean squared residual relative to the RMS force.

# %%
template = jc.Scene(grid, jc.Sphere(R), jc.Elastic(1e9, 0.38), times,
                    normal=jc.Displacement(depth))
start = time.perf_counter()
fit = jc.fit_prony(data, template, 2)
elapsed = time.perf_counter() - start
print(f"fit: {elapsed:.1f} s (with compile), {fit.adam_steps} Adam + {fit.lbfgs_steps} "
      f"L-BFGS steps, {fit.evaluations} model evaluations; {fit.message}")
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
ax[0].axvline(fit.adam_steps, color="grey", ls=":", label="Adam | L-BFGS")
ax[0].axhline(noise**2, color="k", ls="--", lw=0.8, label="noise$^2$ (relative)")
ax[0].set(xlabel="iteration", ylabel="loss", title="loss history")
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
                     noise_std=level * rms if level > 0 else None)
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
