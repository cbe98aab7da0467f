# %% [markdown]
# # jaxcontact quickstart
#
# A rigid sphere on a (visco)elastic half-space, three ways: elastic Hertz contact,
# viscoelastic creep under a held load (against Lee & Radok), and partial slip under a
# tangential load (against Cattaneo-Mindlin). Each result is checked against its
# analytic reference.
#
# This is a jupytext "percent" script: run it with `python notebooks/quickstart.py`, or
# open it as a notebook (`pip install ".[notebooks]"`, then `jupytext --to notebook`).
# `JAXCONTACT_NOTEBOOK_SIZE` picks the size: `ci` (tiny, seconds), `small` (default),
# `paper` (256 x 256). `JAXCONTACT_NOTEBOOK_OUT=DIR` also saves the figures as PNG.

# %%
import os

import jax


jax.config.update("jax_enable_x64", True)  # validation-grade float64

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import jaxcontact as jc  # noqa: E402


SIZE = os.environ.get("JAXCONTACT_NOTEBOOK_SIZE", "small")
N = {"ci": 16, "small": 64, "paper": 256}[SIZE]
# Figures are saved to JAXCONTACT_NOTEBOOK_OUT, by default out/notebooks (a notebook
# also shows them inline).
OUT = os.environ.get("JAXCONTACT_NOTEBOOK_OUT") or os.path.join("out", "notebooks")
print(f"figures -> {os.path.abspath(OUT)}")


def show(fig, name):
    """Save the figure to OUT (a notebook also shows it)."""
    os.makedirs(OUT, exist_ok=True)
    fig.savefig(os.path.join(OUT, f"quickstart_{name}.png"), dpi=100)


# %% [markdown]
# ## 1. Hertz: one elastic load step
#
# `jc.presets.hertz` is a `jc.Scene`: a 10 mm sphere pressed with 0.15 N into an
# elastic half-space with TRUE shear modulus G = 1.93 MPa and nu = 0.3. Frictionless
# and axisymmetric, it is solved on rings (`sol.method == "rings"`: milliseconds, second
# order), the ring pressures mapped onto the grid's cells; `jc.solve(scene,
# solver=jc.Rounds())` solves it on the grid.

# %%
scene = jc.presets.hertz(n=N)
sol = jc.solve(scene)
hertz = jc.Hertz(
    scene.indenter.radius, 0.15, scene.material.shear_modulus, scene.material.poisson
)
a0, p0 = float(hertz.contact_radius), float(hertz.peak_pressure)
print(f"converged: {bool(sol.converged[0])}")
print(f"peak pressure {float(sol.pressure[0].max()):.5g} Pa, Hertz {p0:.5g} Pa")
print(
    f"approach      {float(sol.approach[0]):.5g} m,  "
    f"Hertz {float(hertz.approach):.5g} m"
)
assert abs(float(sol.approach[0]) / float(hertz.approach) - 1) < 0.03

x = np.asarray(scene.grid.x)
fig, ax = plt.subplots(figsize=(5, 3.5))
r = np.linspace(-1.5, 1.5, 301)
ax.plot(r, np.sqrt(np.clip(1 - r**2, 0, None)), "k-", label="Hertz")
ax.plot(
    x / a0,
    np.asarray(sol.pressure[0, :, N // 2]) / p0,
    "o",
    ms=3,
    label=f"jaxcontact ({sol.method}), {N}x{N} cells",
)
ax.set(xlabel="x / a0", ylabel="p / p0", title="Hertz contact")
ax.legend()
show(fig, "hertz")

# %% [markdown]
# ## 2. Viscoelastic creep under a held load
#
# The Zener material of the paper's Table 2 (`mu_inf / mu_0 = 4`): the approach grows
# as the material creeps. Lee & Radok: `delta(t) = a(t)^2 / R` with
# `a(t)^3 = 3 R (1 - nu) / 8 J(t) W` for a step load.

# %%
steps = {"ci": 7, "small": 31, "paper": 61}[SIZE]
scene = jc.presets.zener(ratio=4, n=N, steps=steps)
sol = jc.solve(scene)
ref = jc.LeeRadok(
    scene.indenter.radius,
    scene.material.poisson,
    scene.material,
    lambda t: 0.15 * (t >= 0),
)
t = np.asarray(scene.times)
delta_ref = np.array([float(ref.approach(tk)) for tk in t])
err = np.max(np.abs(np.asarray(sol.approach) / delta_ref - 1))
print(
    f"all steps converged: {bool(np.all(sol.converged))}; "
    f"approach vs Lee-Radok: max relative difference {err:.2e}"
)
assert err < 0.03

fig, ax = plt.subplots(figsize=(5, 3.5))
ax.plot(t / 0.01, delta_ref * 1e6, "k-", label="Lee & Radok")
ax.plot(t / 0.01, np.asarray(sol.approach) * 1e6, "o", ms=4, label="jaxcontact")
ax.set(xlabel="t / tau", ylabel="approach [um]", title="Zener creep, W = 0.15 N")
ax.legend()
show(fig, "creep")

# %% [markdown]
# ## 3. Partial slip: Cattaneo-Mindlin
#
# An elastic sphere under W = 0.15 N, then a tangential force F_x = 0.5 mu W in 4
# increments (uncoupled: `coupling="none"`). The stick zone is a disc of radius
# `c = a (1 - F_x / (mu W))^(1/3)`, so the stick ratio (area) is `(c / a)^2`.

# %%
mu, w = 0.3, 0.15
times = np.linspace(0.0, 1.0, 5)
scene = jc.Scene(
    jc.presets.hertz(n=N).grid,
    jc.Sphere(10e-3),
    jc.Elastic(1.93e6, 0.3),
    times,
    normal=jc.Force(w),
    x=jc.Force(np.linspace(0.0, 0.5 * mu * w, 5)),
    friction=mu,
    coupling="none",
)
sol = jc.solve(scene)
fx = np.asarray(sol.tangential_force[:, 0])
theory = (1 - fx / (mu * w)) ** (2 / 3)
print("F_x / (mu W):       ", np.round(fx / (mu * w), 3))
print("stick ratio:        ", np.round(np.asarray(sol.stick_ratio), 3))
print(
    "Cattaneo-Mindlin:   ", np.round(theory, 3), f"(grid {N}x{N}: cells blur the edge)"
)

fig, axes = plt.subplots(1, 2, figsize=(9, 3.5))
axes[0].imshow(
    (np.asarray(sol.contact[-1], int) + np.asarray(sol.stick[-1], int)).T,
    origin="lower",
    cmap="Greys",
    extent=[x[0] / a0, x[-1] / a0] * 2,
)
axes[0].set(title="stick (dark) / slip (grey)", xlabel="x / a0", ylabel="y / a0")
axes[1].plot(x / a0, np.asarray(sol.shear[-1, 0, :, N // 2]) / p0, ".-", label="q_x")
axes[1].plot(
    x / a0, mu * np.asarray(sol.pressure[-1, :, N // 2]) / p0, "k--", label="mu p"
)
axes[1].set(xlabel="x / a0", ylabel="traction / p0")
axes[1].legend()
show(fig, "partial_slip")
