# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
#       format_version: '1.3'
#   kernelspec:
#     display_name: Python 3 (ipykernel)
#     language: python
#     name: python3
# ---

# %% [markdown]
# # A custom indenter and a sinusoidal protocol
#
# Scene files are one way to describe an experiment; this demo builds one in Python from its
# parts, without any file: a rigid cylinder of radius 2 mm (not one of the built-in
# indenters), pressed into the pulp by a sinusoidal displacement that starts from rest. The
# skin is viscoelastic, so loading and unloading follow different paths: the force against the
# indentation is a hysteresis loop, and its area is the energy the skin dissipates per cycle.
# A second run with an elastic skin is the control: its loop should close.
#
# Run it:
#
# ```bash
# python demos/demo_custom_indenter.py           # 1pt-scene mesh, two cycles of 40 steps (~3 min)
# python demos/demo_custom_indenter.py --coarse  # coarse mesh, one cycle, ~17 steps (~30 CPU s)
# ```
#
# (`FINGERTIP_DEMO_COARSE=1` does the same as `--coarse`; the outputs go to
# `$FINGERTIP_DEMO_OUT`, by default `results/demos/custom_indenter`.)
#
# ## Indenters are shapes with a signed distance
#
# An indenter is a rigid body described by its exact signed distance $\varphi(\mathbf x)$
# (positive outside) and the outward normal $\mathbf n = \nabla\varphi$; contact is enforced on
# the skin surface at its current position $\mathbf x = \mathbf X + \mathbf u$ (Nitsche's method:
# no penetration, $\varphi \ge 0$, and a compressive normal traction where $\varphi = 0$). For a
# cylinder of radius $R$ whose highest point is at $(x_c, y_{tip})$,
#
# $$
# \varphi(\mathbf x) = \big|\mathbf x - (x_c,\; y_{tip} - R)\big| - R .
# $$
#
# `ft.Cylinder(radius=2.0)`, `ft.Bar(width=...)`, `ft.Plate()` and
# `ft.Wedge(tip_radius=..., base=..., height=...)` (a round tip dilated from a cone: the base
# and height set the flank angle) are such shapes; the scene moves them together in $+y$.
#
# ## A protocol that starts from rest
#
# `ft.Sinusoid(amplitude=A, frequency=f, end_time=T, offset=A, phase_deg=-90)` prescribes the
# indentation after first touch
#
# $$
# d(t) = A + A\sin(2\pi f t - \tfrac{\pi}{2}) = A\,\big(1 - \cos 2\pi f t\big),
# $$
#
# which starts at $d = 0$ with zero velocity, reaches $2A$ at half a period and returns to
# touch at each full period. The time stepper lands on every peak and every zero crossing.
#
# ## How much should the loop open?
#
# The skin is quasi-linear viscoelastic: its stress is the hereditary integral of the
# elastic one with the relaxation function $g(t) = g_\infty + \sum_i g_i e^{-t/\tau_i}$. For a
# linear material under a harmonic strain of angular frequency $\omega = 2\pi f$ that gives the
# storage and loss factors
#
# $$
# g'(\omega) = g_\infty + \sum_i g_i\frac{\omega^2\tau_i^2}{1 + \omega^2\tau_i^2}, \qquad
# g''(\omega) = \sum_i g_i\frac{\omega\tau_i}{1 + \omega^2\tau_i^2}, \qquad
# \tan\delta = \frac{g''}{g'} ,
# $$
#
# and each term dissipates most near $\omega\tau_i = 1$. The paper's skin has
# $\tau = 2.1$ s and $9.4$ s, so it damps most at $f \approx 0.02$–$0.08$ Hz: this demo uses
# $f = 0.1$ Hz. A linear spring loaded by $d = A(1 - \cos\omega t)$ in steady state would lose
# $\pi\tan\delta/2$ of the work put in while loading; the finger loses less, because only the
# skin is viscoelastic and the first cycle from rest is not yet steady.
#
# The subcutaneous tissue keeps the paper's permeability: over 10 s it is undrained (see
# `demo_permeability_sweep.py`) and dissipates nothing.

# %%
import os
import sys
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

import fingertip_dolfinx as ft

COARSE = os.environ.get("FINGERTIP_DEMO_COARSE", "") not in ("", "0") or "--coarse" in sys.argv
OUT = Path(os.environ.get("FINGERTIP_DEMO_OUT", "results/demos/custom_indenter"))
BACKEND = matplotlib.get_backend()  # fingertip_dolfinx switches to Agg for its own figures

# %% [markdown]
# ## The scene, from parts
#
# The section is the built-in `male-index` with its mesh options overridden (the full run uses
# those of the `1pt` scene: 0.1 mm elements under the pulp), the materials default to the
# paper's set (`ft.load_materials("wu2004")`).

# %%
A, FREQ = 0.25, 0.1  # mm, Hz: indentation from 0 to 0.5 mm and back, every 10 s
if COARSE:
    mesh = {"min_size": 0.2, "max_size": 1.0, "bone_size": 2.0}
    cycles, steps = 1, ft.StepOptions(dt_initial=0.5, dt_max=1.0)
else:
    mesh = {"min_size": 0.1, "max_size": 0.8, "bone_size": 1.5, "refine_half_width": 3.0,
            "refine_depth": 1.5}
    cycles, steps = 2, ft.StepOptions(dt_initial=0.1, dt_max=0.25)
T_END = cycles / FREQ

section = ft.load_section("male-index", {"mesh": mesh})
cylinder = ft.Cylinder(radius=2.0)
history = ft.Sinusoid(amplitude=A, frequency=FREQ, end_time=T_END, offset=A, phase_deg=-90)
peaks = [(k + 0.5) / FREQ for k in range(cycles)]  # the deepest points, 2A
outputs = ft.Outputs(times=(*peaks, T_END), depths=(0.75,), profile_points=121)


def scene(viscoelastic: bool) -> ft.Scene:
    return ft.Scene(
        section=section, indenters=[cylinder], history=history,
        model=ft.ModelOptions(skin_viscoelastic=viscoelastic),
        steps=steps,
        petsc_options={"snes_atol": 1e-9},  # N/mm: 1e-6 of the force, as in line-load.toml
        outputs=outputs,
        name=f"cylinder R = 2 mm, {'viscoelastic' if viscoelastic else 'elastic'} skin",
    )


print(cylinder, history, sep="\n")
print(f"d(t) at t = 0, T/4, T/2, T: {[round(history(t), 6) for t in (0, 2.5, 5, 10)]} mm")
print(f"breakpoints in the first cycle: {[t for t in history.breakpoints if t <= 1 / FREQ]}")

# %% [markdown]
# The expected damping, from the skin's own Prony series:

# %%
prony = ft.load_materials("wu2004").skin_prony
g, tau = np.array(prony.g), np.array(prony.tau)


def tan_delta(f: float) -> float:
    wt = 2 * np.pi * f * tau
    return float(np.sum(g * wt / (1 + wt**2)) / (prony.g_inf + np.sum(g * wt**2 / (1 + wt**2))))


for f in (0.02, FREQ, 1.0, 100.0):
    print(f"  f = {f:6g} Hz: tan(delta) = {tan_delta(f):.3g}")
print(f"linear estimate of the loss per cycle at {FREQ} Hz: pi tan(delta)/2 = "
      f"{np.pi * tan_delta(FREQ) / 2:.3f} of the loading work")

# %% [markdown]
# ## The runs

# %%
runs = {}
for viscoelastic in (True, False):
    key = "viscoelastic" if viscoelastic else "elastic"
    runs[key] = ft.run(scene(viscoelastic), OUT / key, progress=not COARSE)
    s = runs[key].summary
    print(f"{key:>12}: {s['dofs']} unknowns, {s['time_steps']} steps, "
          f"{s['newton_iterations']} Newton iterations, {s['wall_time_s']:.1f} s, "
          f"converged {s['converged']}")

# %% [markdown]
# ## The loop
#
# The work done on the finger per unit length over the protocol is $\oint F\,\mathrm dd$
# (N·mm per mm of finger); over whole cycles that returns to $d = 0$ it is the energy
# dissipated. The loading work, $\int F\,\mathrm dd$ up to the first peak, sets the scale.
# Both are integrated with the trapezoidal rule over the time steps, which do not fall at the
# same indentations on loading and unloading: the elastic control's loop, which should be
# zero, measures that quadrature error.


# %%
def loop(result: ft.Result):
    d = np.r_[0.0, result.history["indenter_displacement_mm"]]
    F = np.r_[0.0, result.force]
    return d, F


def work(d, F) -> float:
    return float(np.sum(0.5 * (F[1:] + F[:-1]) * np.diff(d)))


numbers = {}
for key, result in runs.items():
    d, F = loop(result)
    first_peak = int(np.argmax(d >= 2 * A - 1e-12))
    w_in = work(d[: first_peak + 1], F[: first_peak + 1])
    w_loop = work(d, F)
    numbers[key] = (F.max(), w_in, w_loop)
    print(f"{key:>12}: peak force {F.max():.4e} N/mm; loading work {w_in:.3e} N mm/mm; "
          f"dissipated over {cycles} cycle(s) {w_loop:.3e} N mm/mm "
          f"({100 * w_loop / w_in:.2f} % of the loading work)")

# %% [markdown]
# ## The deformed pulp against the cylinder
#
# `result.fields(t)` holds the corners `X` of every cell and the displacement `u` there; the
# pulp surface's vertices lie on the outer ellipse $(x/a)^2 + ((y - c_y)/b)^2 = 1$, $y < c_y$,
# so their deformed positions $\mathbf X + \mathbf u$ trace the deformed surface. Where the
# skin touches the cylinder their signed distance $\varphi$ to it should be about zero. The
# first touch is at the bottom of the pulp, $(0, c_y - b)$, so the cylinder's top is at
# $y_{tip} = c_y - b + d(t)$.


# %%
outer = section.outer
t_peak = peaks[0]
y_tip = outer.cy - outer.b + history(t_peak)


def deformed_pulp(result: ft.Result, t: float):
    """(x, y) of the pulp surface's vertices at output time t, sorted by x."""
    f = result.fields(t)
    X, u = f["X"].reshape(-1, 2), f["u"].reshape(-1, 2)
    on = (np.abs((X[:, 0] / outer.a) ** 2 + ((X[:, 1] - outer.cy) / outer.b) ** 2 - 1) < 1e-9)
    on &= X[:, 1] < outer.cy
    points = np.unique(np.round(np.c_[X[on] + u[on]], 12), axis=0)
    return points[:, 0], points[:, 1]


for key, result in runs.items():
    x, y = deformed_pulp(result, t_peak)
    phi, _ = cylinder.signed_distance_np(np.c_[x, y], y_tip)
    touching = phi < 1e-3  # within 1 um of the cylinder
    print(f"{key:>12}: at t = {t_peak:g} s, {touching.sum()} surface vertices within 1 um of "
          f"the cylinder, |x| <= {np.abs(x[touching]).max():.2f} mm; largest penetration "
          f"{1e3 * max(0.0, -phi.min()):.2f} um")

# %% [markdown]
# ## Figure
#
# Left: the pulp surface at the first peak wraps the cylinder's tip. Middle: force and
# indentation against time; the viscoelastic skin has relaxed a little by the peak and carries
# less force while unloading. Right: force against indentation, the hysteresis loop.

# %%
plt.switch_backend(BACKEND)
fig, axes = plt.subplots(1, 3, figsize=(15, 4.4))
ax = axes[0]
for key, style in (("viscoelastic", "C0-"), ("elastic", "C1--")):
    ax.plot(*deformed_pulp(runs[key], t_peak), style, label=key)
x = np.linspace(-3, 3, 301)
ax.plot(x, outer.cy - outer.b * np.sqrt(1 - (x / outer.a) ** 2), "k:", lw=1, label="undeformed")
xc = np.linspace(-cylinder.radius, cylinder.radius, 301)
ax.fill_between(xc, y_tip - cylinder.radius + np.sqrt(cylinder.radius**2 - xc**2),
                y_tip - cylinder.radius - 0.5, color="grey", alpha=0.4, label="cylinder")
ax.set(xlim=(-2.5, 2.5), ylim=(y_tip - 1.2, y_tip + 0.7), aspect="equal", xlabel="x (mm)",
       ylabel="y (mm)", title=f"pulp surface at t = {t_peak:g} s (d = {history(t_peak):g} mm)")
ax.legend(fontsize=7, loc="lower left")
ax = axes[1]
for key, style in (("viscoelastic", "C0o-"), ("elastic", "C1s--")):
    ax.plot(np.r_[0, runs[key].time], np.r_[0, runs[key].force] * 1e3, style, ms=3, label=key)
ax.set(xlabel="time (s)", ylabel="force (mN/mm)", title="force and indentation")
ax.legend(loc="upper left", fontsize=8)
ax_d = ax.twinx()
t = np.linspace(0, T_END, 400)
ax_d.plot(t, [history(s) for s in t], "k:", lw=1)
ax_d.set_ylabel("indentation d (mm), dotted")
ax = axes[2]
for key, style in (("viscoelastic", "C0o-"), ("elastic", "C1s--")):
    d, F = loop(runs[key])
    ax.plot(d, F * 1e3, style, ms=3,
            label=f"{key}: loop {100 * numbers[key][2] / numbers[key][1]:.1f} % of loading work")
ax.set(xlabel="indentation d (mm)", ylabel="force (mN/mm)",
       title=f"hysteresis, f = {FREQ:g} Hz, {cycles} cycle(s)")
ax.legend(fontsize=8, loc="upper left")
for a in axes:
    a.grid(alpha=0.3)
fig.tight_layout()
figure = OUT / "custom_indenter.png"
fig.savefig(figure, dpi=120)
print(f"figure: {figure}")

# %% [markdown]
# What the skin's memory leaves behind: while unloading, the viscoelastic skin recovers more
# slowly than the cylinder withdraws, so the force reaches zero before the indentation does
# (the skin lets go of the cylinder); at the end of the protocol, with the cylinder back at
# first touch, the surface is still pressed in. The elastic skin follows the cylinder back.

# %%
for key, result in runs.items():
    d, F = loop(result)
    last_peak = int(np.flatnonzero(np.isclose(d, 2 * A))[-1])
    zero = last_peak + np.flatnonzero(F[last_peak:] <= 0.0)
    if len(zero) and d[zero[0]] > 0:
        print(f"{key:>12}: unloading, the skin lets go of the cylinder between d = "
              f"{d[zero[0] - 1]:.3f} and {d[zero[0]]:.3f} mm")
    else:
        print(f"{key:>12}: unloading, in contact until d = 0")
    x, w = result.surface_profile(T_END)
    print(f"{key:>12}: deflection under the cylinder at t = {T_END:g} s: "
          f"{1e3 * np.interp(0.0, np.sort(x), w[np.argsort(x)]):.1f} um; force "
          f"{result.force[-1]:.2e} N/mm")
ve, el = numbers["viscoelastic"], numbers["elastic"]
print(f"the viscoelastic loop dissipates {100 * ve[2] / ve[1]:.2f} % of the loading work, the "
      f"elastic control {100 * el[2] / el[1]:.3f} %; linear estimate for the skin alone "
      f"{100 * np.pi * tan_delta(FREQ) / 2:.1f} %")
