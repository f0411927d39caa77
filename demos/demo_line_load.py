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
# # The line load, from Python
#
# A rigid steel wedge is pushed 1 mm into the pulp of a fingertip in 1 s and held there for
# 100 s: the *line load* of Wu et al., *A structural fingertip model for simulating of the
# biomechanics of tactile sensation*, Med. Eng. Phys. 26 (2004) 165–175 (their Figs 2–5).
# This demo runs that experiment through the Python API, `import fingertip_dolfinx as ft`,
# and reads the results back as arrays: the force on the wedge against time, the deflection
# of the pulp surface, and the strains and strain energy density under the load.
#
# Run it:
#
# ```bash
# python demos/demo_line_load.py            # the scene's own mesh, 100 s  (about 1 min)
# python demos/demo_line_load.py --coarse   # coarse mesh, 10 s: what CI runs (~16 CPU s)
# ```
#
# (`FINGERTIP_DEMO_COARSE=1` does the same as `--coarse`; the outputs go to
# `$FINGERTIP_DEMO_OUT`, by default `results/demos/line_load`.)
#
# ## The model
#
# The finger is a plane-strain cross-section: skin (0.8 mm), subcutaneous tissue, bone and
# nail. Units are mm, N, s and MPa throughout, so forces are per unit length of finger, N/mm.
# With the deformation gradient $\mathbf F = \mathbf I + \operatorname{Grad}\mathbf u$,
# $\mathbf C = \mathbf F^{\mathsf T}\mathbf F$, $J = \det\mathbf F$ and principal stretches
# $\lambda_a$ ($\lambda_3 = 1$ in plane strain), the skin and the solid of the subcutaneous
# tissue are compressible Ogden foams ("hyperfoam"):
#
# $$
# W(\mathbf C) = \sum_{i=1}^{3} \frac{2\mu_i}{\alpha_i^2}\Big[\lambda_1^{\alpha_i} +
# \lambda_2^{\alpha_i} + \lambda_3^{\alpha_i} - 3 + \frac{1}{\beta}\big(J^{-\alpha_i\beta}
# - 1\big)\Big], \qquad \beta = \frac{\nu}{1 - 2\nu},
# $$
#
# with the small-strain moduli $\mu_0 = \sum_i \mu_i$ and
# $K_0 = \sum_i 2\mu_i\,(\tfrac13 + \beta)$. The skin is quasi-linear viscoelastic: its second
# Piola–Kirchhoff stress is the hereditary integral of the elastic one,
#
# $$
# \mathbf S(t) = \int_0^t g(t - s)\,\frac{\mathrm d\mathbf S_e}{\mathrm ds}\,\mathrm ds,
# \qquad g(t) = 1 - \sum_i g_i\big(1 - e^{-t/\tau_i}\big),
# $$
#
# and this is what makes the force relax while the wedge is held. The subcutaneous tissue is
# biphasic: a hyperfoam solid saturated by an inviscid fluid at pore pressure $p$, with
# momentum and mass balance
#
# $$
# \operatorname{Div}\big(\mathbf P_s - p\,J\,\mathbf F^{-\mathsf T}\big) = \mathbf 0,
# \qquad
# \frac{\mathrm d}{\mathrm dt} J - \operatorname{Div}\big(J\,k(J)\,\mathbf C^{-1}
# \operatorname{Grad} p\big) = 0,
# $$
#
# and the Holmes–Mow permeability
#
# $$
# k(J) = k_0\left(\frac{J - \phi_0}{1 - \phi_0}\right)^{\kappa}
# \exp\!\Big(\frac{M}{2}\,\big(J^2 - 1\big)\Big).
# $$
#
# Bone and nail are St Venant–Kirchhoff solids; the nail's centre is held; the wedge is a
# rigid body whose exact signed distance enters a penalty contact term.
#
# ## Why the tissue is undrained
#
# Linearise the mass balance about the reference state: the pressure diffuses with the
# consolidation coefficient $c = H_A k_0$, where $H_A = K_0 + \tfrac43\mu_0$ is the
# aggregate (confined) modulus of the solid, so fluid moves a distance $L$ in the drainage time
#
# $$
# t_d \sim \frac{L^2}{H_A\,k_0}.
# $$
#
# With the paper's $k_0 = 10^{-3}$ mm⁴/(N·s) and $L$ of a few millimetres (the size of the
# loaded zone up to the thickness of the pulp), $t_d$ is of order $10^6$ s — days, against a
# 100 s protocol. Over the experiment the fluid cannot move: the tissue behaves as
# incompressible, and its pore pressure acts as the Lagrange multiplier of $J = 1$. The cell
# below computes $t_d$ from the scene's own parameters.

# %%
import os
import sys
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

import fingertip_dolfinx as ft
from fingertip_dolfinx.physics.materials import small_strain_p_wave_modulus

COARSE = os.environ.get("FINGERTIP_DEMO_COARSE", "") not in ("", "0") or "--coarse" in sys.argv
OUT = Path(os.environ.get("FINGERTIP_DEMO_OUT", "results/demos/line_load"))
# fingertip_dolfinx draws its own figures with the file-only Agg backend; remember ours so that
# the figure at the end shows inline in Jupyter.
BACKEND = matplotlib.get_backend()

# %% [markdown]
# ## The scene
#
# `ft.load_scene` reads the built-in scene file `line-load.toml` (shipped inside the package)
# and applies overrides, given as the scene file's own tables. The full run uses the scene as
# it is: 0.1 mm elements under the load, a disc of 20 µm elements around the 25 µm wedge tip
# (a tip narrower than the surface elements would slip between the contact quadrature points),
# the protocol to 100 s. The coarse run keeps the tip disc but coarsens everything else and
# stops at 10 s.

# %%
if COARSE:
    overrides = {
        "section": {"mesh": {"min_size": 0.2, "max_size": 1.0, "bone_size": 2.0}},
        "protocol": {"end_time": 10.0},
        "output": {"times": [1.0, 10.0], "depths": [0.75], "profile_points": 121},
    }
else:
    overrides = {}
scene = ft.load_scene("line-load", overrides)
wedge = scene.indenters[0]
T_END = scene.history.end_time
print(f"{scene.name}: {scene.description}")
print(f"  wedge: tip radius {wedge.tip_radius} mm, flank half-angle "
      f"{np.degrees(wedge.half_angle):.1f} deg")
print(f"  protocol: {scene.history.depth} mm in {scene.history.ramp_time} s, held to {T_END} s")
print(f"  mesh: min_size {scene.section.mesh.min_size} mm, tip disc {scene.section.mesh.tip_size}"
      f" mm; output times {scene.output_times} s")

# %% [markdown]
# The drainage time from the materials of the scene (`scene.materials` is the paper's set,
# `wu2004.toml`):

# %%
sub = scene.materials.subcutaneous
H_A = small_strain_p_wave_modulus(sub.solid)  # K0 + 4 mu0/3, MPa
k0 = sub.permeability.k0  # mm^4/(N s)
for L in (1.0, 2.0, 6.0):
    print(f"  L = {L:3.1f} mm: t_d = L^2/(H_A k0) = {L**2 / (H_A * k0):.1e} s")
print(f"H_A = {H_A:.3e} MPa, k0 = {k0:g} mm^4/(N s): undrained over the {T_END:g} s protocol")

# %% [markdown]
# ## The run
#
# `ft.run` builds the mesh and the problem, steps through the protocol with adaptive backward
# Euler steps (landing exactly on the end of the ramp and on the output times), writes
# everything into the output directory as it goes (`history.csv`, profiles, ParaView fields,
# `summary.json`, figures) and returns a `ft.Result` that reads those files back as arrays.

# %%
result = ft.run(scene, OUT / "run", progress=not COARSE)
print(result)
s = result.summary
print(f"{s['dofs']} unknowns, {s['time_steps']} steps, {s['newton_iterations']} Newton "
      f"iterations, {s['wall_time_s']:.1f} s; converged: {s['converged']}")

# %% [markdown]
# ## Results
#
# The force rises over the ramp and then relaxes at constant indentation: in the hold nothing
# moves but the skin's internal variables (the fluid in the subcutaneous tissue stays put,
# see above). The surface deflection is that of the paper's Fig. 2; the strains and the strain
# energy density 0.75 mm under the surface are the quantities the paper relates to the
# mechanoreceptors (Fig. 5).

# %%
t, F = result.time, result.force
F_peak = float(np.interp(1.0, t, F))
F_end = float(F[-1])
x1, w1 = result.surface_profile(1.0)
x2, w2 = result.surface_profile(T_END)
xs, sed = result.depth_profile("sed_MPa", depth=0.75, t=1.0)
_, e22 = result.depth_profile("e22", depth=0.75, t=1.0)
order = np.argsort(xs)

plt.switch_backend(BACKEND)
fig, axes = plt.subplots(1, 3, figsize=(14, 4.2))
ax = axes[0]
ax.plot(np.r_[0, t], np.r_[0, F] * 1e3, "o-", ms=3)
ax.set(xlabel="time (s)", ylabel="force (mN/mm)", title="force on the wedge")
ax.set_xscale("symlog", linthresh=1.0)
ax = axes[1]
for x, w, label in ((x1, w1, "t = 1 s"), (x2, w2, f"t = {T_END:g} s")):
    i = np.argsort(x)
    ax.plot(x[i], w[i], label=label)
ax.set(xlabel="x (mm)", ylabel="deflection (mm)", title="pulp surface (cf. Fig. 2)")
ax.legend()
ax = axes[2]
ax.plot(xs[order], e22[order], label=r"$e_{22}$ (log strain)")
ax.set(xlabel="x (mm)", ylabel="strain", title="0.75 mm deep, t = 1 s (cf. Fig. 5)",
       xlim=(-3, 3))
ax2 = ax.twinx()
ax2.plot(xs[order], sed[order] * 1e3, "C3", label="SED")
ax2.set_ylabel("strain energy density (kPa)", color="C3")
ax.legend(loc="center left")
for a in axes:
    a.grid(alpha=0.3)
fig.suptitle(f"line load{' (coarse)' if COARSE else ''}")
fig.tight_layout()
figure = OUT / "line_load.png"
fig.savefig(figure, dpi=120)
print(f"figure: {figure}")

# %% [markdown]
# A few numbers: the peak force, how much of it relaxes during the hold, the deflection under
# the wedge, and the peaks at 0.75 mm depth.

# %%
print(f"peak force {F_peak:.4g} N/mm at 1 s; {F_end:.4g} N/mm at {T_END:g} s "
      f"({100 * (1 - F_end / F_peak):.1f} % relaxed)")
print(f"deflection under the wedge: {np.interp(0.0, x1[np.argsort(x1)], w1[np.argsort(x1)]):.3f}"
      f" mm at 1 s; 3 mm beside it: {np.interp(3.0, x1[np.argsort(x1)], w1[np.argsort(x1)]):.3f}"
      " mm")
print(f"0.75 mm deep at 1 s: peak SED {np.nanmax(sed):.3e} MPa, most compressive e22 "
      f"{np.nanmin(e22):.3f}")
print(f"the wedge stayed within {1e3 * s['max_penetration_mm']:.2f} um of the skin surface")
