"""The 3D line load against the plane-strain one: how far is the 2D model from 3D?

Reads a 2D run and a 3D run of the same load (same section, materials, indenter and protocol)
and prints, at each output time: the force per unit length (2D: N/mm; 3D: f(z) at the
cross-section z_c, and the whole finger's force over its loaded length), the pulp's
deflection under the load and its width at half depth across the finger (and along it in 3D),
and the strains and SED at 0.75 mm under the load. Draws `compare_2d_3d.png`.

    fingertip run line-load --set indenters.0.tip_radius=0.5 --set "section.mesh.tips=[]" --out R2
    fingertip run line-load-3d --out R3
    .venv/bin/python benchmarks/compare_2d_3d.py R2 R3 [--out FIG_DIR]
"""

import argparse
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from fingertip_dolfinx.outputs import read_csv  # noqa: E402

QUANTITIES = ("e_max", "e_min", "e12", "sed_MPa")


def at(table: dict, t: float) -> dict:
    rows = np.isclose(table["time_s"], t)
    return {k: v[rows] for k, v in table.items()}


def half_width(x: np.ndarray, w: np.ndarray) -> float:
    """The distance from the load axis at which the deflection falls to half its peak, on the
    side x >= 0 (the half model's), interpolated linearly between the profile's points."""
    side = x >= 0
    order = np.argsort(x[side])
    x, w = x[side][order], w[side][order]
    half = 0.5 * np.nanmax(w)
    below = np.flatnonzero(w < half)
    if not len(below) or below[0] == 0:
        return float("nan")
    i = below[0]
    return float(x[i - 1] + (x[i] - x[i - 1]) * (w[i - 1] - half) / (w[i - 1] - w[i]))


def under_load(depth: dict, d: float, x0: float = 0.0) -> dict:
    rows = np.isclose(depth["depth_mm"], d)
    i = np.argmin(np.abs(depth["x_mm"][rows] - x0))
    return {q: depth[q][rows][i] for q in QUANTITIES}


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawTextHelpFormatter)
    parser.add_argument("run2d", type=Path)
    parser.add_argument("run3d", type=Path)
    parser.add_argument("--out", type=Path, default=None, help="figure directory (run3d)")
    args = parser.parse_args()
    s3 = json.loads((args.run3d / "summary.json").read_text())
    h2, h3 = read_csv(args.run2d / "history.csv"), read_csv(args.run3d / "history.csv")
    surf2 = read_csv(args.run2d / "surface_profile.csv")
    across, along = (read_csv(args.run3d / f"surface_{d}.csv") for d in ("across", "along"))
    d2, d3 = (read_csv(run / "depth_profiles.csv") for run in (args.run2d, args.run3d))
    line = read_csv(args.run3d / "line_force.csv")
    z_c = float(d3["z_mm"][0])  # the cross-section of the 3D profiles
    times = np.unique(line["time_s"])
    print(f"3D: {s3['dofs']} dofs, cross-section z_c = {z_c} mm")
    for t in times:
        f = at(line, t)
        # f on 0.5 mm slabs scatters by ~5 % where facets straddle slab edges (the slab's
        # indicator is taken at quadrature points): average over 2 mm either side.
        near = np.abs(f["z_mm"] - z_c) <= 2.0
        f_c = float(np.mean(f["force_per_length_N_per_mm"][near]))
        cut = f["z_mm"] <= 2.0
        f_0 = float(np.mean(f["force_per_length_N_per_mm"][cut]))
        F2 = np.interp(t, h2["time_s"], h2["force_N_per_mm"])
        F3 = s3["mirror_factor"] * np.interp(t, h3["time_s"], h3["force_N"])
        print(f"t = {t:g} s: force per unit length 2D {F2:.4e} N/mm, 3D f(z_c ± 2 mm) "
              f"{f_c:.4e} N/mm ({f_c / F2 - 1:+.1%}), f(0-2 mm) {f_0:.4e} N/mm "
              f"({f_0 / F2 - 1:+.1%}); 3D whole finger {F3:.4e} N = 2D x {F3 / F2:.2f} mm")
        a2, a3, l3 = at(surf2, t), at(across, t), at(along, t)
        print(f"  deflection under the load: 2D {np.nanmax(a2['deflection_mm']):.4f} mm, "
              f"3D {np.nanmax(a3['deflection_mm']):.4f} mm; half-width across: 2D "
              f"{half_width(a2['x_mm'], a2['deflection_mm']):.2f} mm, 3D "
              f"{half_width(a3['x_mm'], a3['deflection_mm']):.2f} mm; 3D along the finger: "
              f"deflection ≥ half its peak over z = {_span(l3):s}")
        q2, q3 = under_load(at(d2, t), 0.75), under_load(at(d3, t), 0.75)
        print("  at 0.75 mm under the load: " + ", ".join(
            f"{q} 2D {q2[q]:.4g} 3D {q3[q]:.4g}" for q in QUANTITIES))
    _figure(args.out or args.run3d, times, h2, surf2, across, along, line)


def _span(l3: dict) -> str:
    w = l3["deflection_mm"]
    keep = w >= 0.5 * np.nanmax(w)
    return f"{l3['z_mm'][keep].min():.1f}–{l3['z_mm'][keep].max():.1f} mm"


def _figure(out: Path, times, h2, surf2, across, along, line) -> None:
    fig, (ax_x, ax_z, ax_f) = plt.subplots(1, 3, figsize=(14, 4))
    for t in times:
        a2, a3, l3, f = at(surf2, t), at(across, t), at(along, t), at(line, t)
        o = np.argsort(a2["x_mm"])
        line2, = ax_x.plot(a2["x_mm"][o], a2["deflection_mm"][o], "--", label=f"2D, t = {t:g} s")
        ax_x.plot(a3["x_mm"], a3["deflection_mm"], "-", color=line2.get_color(),
                  label=f"3D, t = {t:g} s")
        ax_z.plot(l3["z_mm"], l3["deflection_mm"], color=line2.get_color(), label=f"t = {t:g} s")
        ax_f.step(f["z_mm"], f["force_per_length_N_per_mm"], where="mid",
                  color=line2.get_color(), label=f"3D f(z), t = {t:g} s")
        ax_f.axhline(np.interp(t, h2["time_s"], h2["force_N_per_mm"]), ls="--",
                     color=line2.get_color(), label=f"2D, t = {t:g} s")
    ax_x.set(xlabel="x (mm), across the finger", ylabel="pulp deflection (mm)",
             title="across the finger (3D at z_c)")
    ax_z.set(xlabel="z (mm), along the finger", ylabel="pulp deflection (mm)",
             title="along the finger (3D, x = 0)")
    ax_f.set(xlabel="z (mm), along the finger", ylabel="force per unit length (N/mm)",
             title="force per unit length")
    for ax in (ax_x, ax_z, ax_f):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    Path(out).mkdir(parents=True, exist_ok=True)
    fig.savefig(Path(out) / "compare_2d_3d.png", dpi=150)
    print(f"figure: {Path(out) / 'compare_2d_3d.png'}")


if __name__ == "__main__":
    main()
