# %% [markdown]
# # Parameter sweeps with `jax.vmap`
#
# One compiled program solves a whole batch of scenes: `jax.vmap` over a function that
# builds the scene from a traced parameter and calls `jc.solve`. Two sweeps, each
# checked against theory:
#
# 1. materials: Zener half-spaces with `mu_inf / mu_0` from 1.5 to 10 under a held
#    load: the creep of the approach against Lee & Radok;
# 2. friction: an elastic sphere under a fixed tangential force, Coulomb coefficient
#    from 0.1 to 0.6: the stick ratio against Cattaneo-Mindlin.
#
# `JAXCONTACT_NOTEBOOK_SIZE`: `ci` (tiny), `small` (default) or `paper`;
# `JAXCONTACT_NOTEBOOK_OUT=DIR` also saves the figures as PNG.

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
N = {"ci": 16, "small": 48, "paper": 128}[SIZE]
BATCH = {"ci": 3, "small": 8, "paper": 16}[SIZE]
# Figures are saved to JAXCONTACT_NOTEBOOK_OUT, by default out/notebooks (a notebook
# also shows them inline).
OUT = os.environ.get("JAXCONTACT_NOTEBOOK_OUT") or os.path.join("out", "notebooks")
print(f"figures -> {os.path.abspath(OUT)}")


def show(fig, name):
    os.makedirs(OUT, exist_ok=True)
    fig.savefig(os.path.join(OUT, f"parameter_sweep_{name}.png"), dpi=100)


# %% [markdown]
# ## 1. A batch of Zener materials
#
# The base scene is the paper's Table 2 preset; `jax.vmap` runs over `mu_0`, and the
# material is built INSIDE the vmapped function (its constructor checks traced values
# with `eqx.error_if`). For a step load W, Lee & Radok give `a(t)^3 = 3 R (1 - nu) J(t)
# W / 8` and `delta = a^2 / R`, so `delta(t) / delta(0) = (J(t) / J(0))^(2/3)`.

# %%
base = jc.presets.zener(ratio=4, n=N, steps={"ci": 13, "small": 31, "paper": 61}[SIZE])
mu_inf = float(base.material.mu_inf)
ratios = np.linspace(1.5, 10.0, BATCH)


def creep_curve(mu_0):
    material = jc.Zener(mu_inf, mu_0, 0.01, 0.3)
    scene = jc.Scene(
        base.grid,
        base.indenter,
        material,
        base.times,
        normal=base.normal,
        slip=base.slip,
    )
    sol = jc.solve(scene)
    return sol.approach, sol.converged


start = time.perf_counter()
approach, converged = jax.vmap(creep_curve)(jnp.asarray(mu_inf / ratios))
approach = np.asarray(approach)
print(
    f"{BATCH} materials x {base.times.shape[0]} steps on {N}x{N}: "
    f"{time.perf_counter() - start:.1f} s (compilation included); "
    f"all converged: {bool(np.all(converged))}"
)

t = np.asarray(base.times)
j_ratio = 1 + (ratios[:, None] - 1) * (1 - np.exp(-t[None, :] / 0.01))  # J(t) / J(0)
lee_radok = j_ratio ** (2 / 3)
err = np.max(np.abs(approach / approach[:, :1] / lee_radok - 1))
print(f"creep ratio delta(t)/delta(0) vs Lee-Radok: max relative difference {err:.1e}")
# Tractions piecewise constant in time (the paper's scheme): a first-order error in
# the time step, largest for the strongest creep (ratio 10; measured 6% with steps of
# 0.75 tau, so at least 4 steps per tau here).
assert err < 0.05

fig, ax = plt.subplots(figsize=(5.5, 3.8))
for k, ratio in enumerate(ratios):
    (line,) = ax.plot(t / 0.01, approach[k] / approach[k, 0], "o", ms=3)
    ax.plot(
        t / 0.01,
        lee_radok[k],
        "-",
        color=line.get_color(),
        lw=0.8,
        label=f"{ratio:.1f}",
    )
ax.set(
    xlabel="t / tau",
    ylabel="delta(t) / delta(0)",
    title="creep: points jaxcontact, lines Lee-Radok",
)
ax.legend(title="mu_inf / mu_0", fontsize=7)
show(fig, "materials")

# %% [markdown]
# ## 2. A batch of friction coefficients
#
# An elastic sphere (G = 1.93 MPa, nu = 0.3) under W = 0.15 N and a tangential force
# F_x = 0.04 N reached in 4 increments, uncoupled. Cattaneo-Mindlin: the stick disc has
# `c / a = (1 - F_x / (mu W))^(1/3)` while `F_x < mu W`; beyond, the sphere slides.

# %%
fx_max, w = 0.04, 0.15
times = jnp.linspace(0.0, 1.0, 5)
grid = jc.Grid((N, N), 4 * float(jc.presets.table2_hertz().contact_radius))
mus = np.linspace(0.1, 0.6, BATCH)


def stick_ratio(mu):
    scene = jc.Scene(
        grid,
        jc.Sphere(10e-3),
        jc.Elastic(1.93e6, 0.3),
        times,
        normal=jc.Force(w),
        x=jc.Force(jnp.linspace(0.0, fx_max, 5)),
        friction=mu,
        coupling="none",
    )
    sol = jc.solve(scene)
    return sol.stick_ratio[-1], sol.sliding[-1], sol.converged


start = time.perf_counter()
ratio, sliding, converged = (np.asarray(v) for v in jax.vmap(stick_ratio)(mus))
print(
    f"{BATCH} friction coefficients: {time.perf_counter() - start:.1f} s; "
    f"all converged: {bool(converged.all())}"
)
load = np.clip(fx_max / (mus * w), 0, 1)
theory = (1 - load) ** (2 / 3)
for mu_k, r, s, th in zip(mus, ratio, sliding, theory):
    print(
        f"mu = {mu_k:.3f}: stick ratio {r:.3f} (Cattaneo-Mindlin {th:.3f}), "
        f"sliding = {bool(s)}"
    )
# Gross sliding exactly where F_x >= mu W.
assert np.array_equal(sliding, fx_max >= mus * w)

fig, ax = plt.subplots(figsize=(5.5, 3.8))
mu_fine = np.linspace(0.1, 0.6, 200)
ax.plot(
    mu_fine,
    np.clip(1 - fx_max / (mu_fine * w), 0, 1) ** (2 / 3),
    "k-",
    label="Cattaneo-Mindlin",
)
ax.plot(mus, ratio, "o", label=f"jaxcontact {N}x{N}")
ax.set(
    xlabel="friction coefficient mu",
    ylabel="stick area / contact area",
    title=f"F_x = {fx_max} N, W = {w} N",
)
ax.legend()
show(fig, "friction")
