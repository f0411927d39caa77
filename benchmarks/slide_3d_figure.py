"""The `slide-3d` scene against the probe's travel (docs/benchmarks/friction.md): the
stick/slip map along the finger (x = 0, the probe's path), the forces (the total tangential
force, the friction's and the pressure's shares of it, μ times the pressure's normal force)
and the receptor sites' compressive stress along the path; and the table of the benchmark.

Run: `fingertip run slide-3d --out DIR`, then `python benchmarks/slide_3d_figure.py DIR OUT.png`.
"""

import sys
from pathlib import Path

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from fingertip_dolfinx.outputs import read_csv  # noqa: E402
from fingertip_dolfinx.plotting.figures import STATE_COLOURS, stick_slip_grid  # noqa: E402
from fingertip_dolfinx.result import Result  # noqa: E402

TRAVEL = "tangential_z_displacement_mm"


def slide_steps(h: dict) -> np.ndarray:
    """The steps of the slide and the last one of the press before it."""
    first = int(np.argmax(h[TRAVEL] > 0))
    return np.arange(max(first - 1, 0), len(h[TRAVEL]))


def stick_slip_map(ax, run: Path, h: dict, steps: np.ndarray) -> None:
    s = read_csv(run / "stick_slip.csv")
    travel = h[TRAVEL][steps]
    _, z_edges, state = stick_slip_grid(s, "z_mm", h["time_s"][steps])
    c_edges = np.concatenate([[travel[0] - 0.05], 0.5 * (travel[1:] + travel[:-1]),
                              [travel[-1]]])
    ax.pcolormesh(c_edges, z_edges, state, cmap=matplotlib.colors.ListedColormap(STATE_COLOURS),
                  vmin=-0.5, vmax=2.5)
    ax.plot(travel, 8.0 + travel, "k--", lw=0.8, label="probe's centre")
    ax.set_ylim(5.5, 12.5)
    ax.set_ylabel("skin point z (mm,\nreference; x = 0)")
    ax.legend(handles=[Patch(color=c, label=n) for c, n in
                       zip(STATE_COLOURS, ("free", "slip", "stick"))], loc="upper left",
              fontsize=8)


def forces(ax, h: dict, steps: np.ndarray, mu: float) -> None:
    c = h[TRAVEL][steps]
    fz, fn = (1e3 * h[k][steps] for k in ("tangential_z_force_N", "force_N"))
    pz, pn = (1e3 * h[k][steps] for k in ("pressure_tangential_z_force_N",
                                          "pressure_normal_force_N"))
    ax.plot(c, fn, "k-", label="normal force $F_n$")
    ax.plot(c, fz, "o-", ms=3, color=STATE_COLOURS[1], label="tangential force $F_z$")
    ax.plot(c, fz - pz, "-", color="tab:green", label="its friction share $F_z - F_{p,z}$")
    ax.plot(c, pz, "-", color="tab:purple", label="its pressure share $F_{p,z}$ (ploughing)")
    ax.plot(c, mu * pn, "--", color="0.4", label=rf"$\mu F_{{p,y}}$ ($\mu$ = {mu:g})")
    ax.set_ylabel("force (mN, half model)")
    ax.legend(fontsize=7, loc="upper left", ncol=2)
    ax.set_ylim(min(0.0, 1.1 * pz.min()), 1.35 * fn.max())
    ax.grid(alpha=0.3)


def path_sites(r: dict, cls: str = "RA", half_width: float = 1.0) -> list[int]:
    """The sites of class `cls` within `half_width` of the path (|x| < it, 6.5 < z < 10.5 mm)."""
    rows = r["class"] == cls
    first = rows & (r["time_s"] == r["time_s"][rows][0])
    keep = first & (np.abs(r["x_mm"]) < half_width) & (r["z_mm"] > 6.5) & (r["z_mm"] < 10.5)
    return sorted(r["index"][keep], key=lambda i: r["z_mm"][first & (r["index"] == i)][0])


def receptors(ax, run: Path, h: dict, steps: np.ndarray, cls: str = "RA") -> None:
    """−σ22 at the sites of class `cls` near the probe's path, against the travel."""
    r = Result(run).receptors()
    travel = dict(zip(np.round(h["time_s"], 12), h[TRAVEL]))
    start = h["time_s"][steps[0]] - 1e-12
    colours = plt.cm.viridis(np.linspace(0, 0.9, max(len(path_sites(r, cls)), 1)))
    for colour, i in zip(colours, path_sites(r, cls)):
        rows = (r["class"] == cls) & (r["index"] == i) & (r["time_s"] >= start)
        c = [travel[t] for t in np.round(r["time_s"][rows], 12)]
        ax.plot(c, -1e3 * r["sigma22_MPa"][rows], color=colour,
                label=f"z = {r['z_mm'][rows][0]:.1f}, |x| = {abs(r['x_mm'][rows][0]):.1f}")
    depth = r["depth_mm"][r["class"] == cls][0]
    ax.set_ylabel(f"{cls} site −σ22 (kPa)\n({depth:g} mm deep)")
    ax.set_xlabel("probe's travel along z (mm), from z = 8 mm")
    ax.legend(fontsize=6, loc="upper left", ncol=3)
    ax.grid(alpha=0.3)


def table(run: Path, h: dict, steps: np.ndarray, mu: float) -> None:
    """The benchmark's table: per step of the slide, the forces' ratios and the areas."""
    s = read_csv(run / "stick_slip.csv")
    print("| travel (mm) | Fn (mN) | Fz/(μFn) | F_p,z/Fn | (Fz − F_p,z)/(μ F_p,y) | "
          "(Fx − F_p,x)/(μ F_p,y) | contact, stick (mm²) | max over the path of \\|f\\|/(μp) − 1 "
          "| D/(μ F_p,y Δz) | its |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    previous = 0.0
    for k in steps:
        rows = np.isclose(s["time_s"], h["time_s"][k], rtol=0, atol=1e-12) & (
            s["pressure_MPa"] > 0)
        f = np.sqrt(sum(s[f"tangential_traction_{a}_MPa"][rows] ** 2 for a in "xyz"))
        excess = np.max(f / (mu * s["pressure_MPa"][rows]) - 1) if np.any(rows) else np.nan
        friction = h["tangential_z_force_N"][k] - h["pressure_tangential_z_force_N"][k]
        across = h["tangential_x_force_N"][k] - h["pressure_tangential_x_force_N"][k]
        pn = h["pressure_normal_force_N"][k]
        dz = h[TRAVEL][k] - previous
        previous = h[TRAVEL][k]
        dissipation = h["dissipated_N_mm"][k] / (mu * pn * dz) if dz > 0 else np.nan
        print(f"| {h[TRAVEL][k]:.3g} | {1e3 * h['force_N'][k]:.4g} | "
              f"{h['tangential_z_force_N'][k] / (mu * h['force_N'][k]):.3f} | "
              f"{h['pressure_tangential_z_force_N'][k] / h['force_N'][k]:.3f} | "
              f"{friction / (mu * pn):.4f} | {across / (mu * pn):.3f} | "
              f"{h['contact_area_mm2'][k]:.2f}, "
              f"{h['stick_area_mm2'][k]:.2f} | {excess:.1e} | {dissipation:.3f} | "
              f"{h['newton_iterations'][k]} |")


def main(run: Path, out: Path, mu: float = 0.5) -> None:
    h = read_csv(run / "history.csv")
    steps = slide_steps(h)
    table(run, h, np.arange(len(h["time_s"])), mu)
    fig, axes = plt.subplots(3, 1, figsize=(6.4, 8.8), sharex=True, constrained_layout=True,
                             height_ratios=(3, 3, 3))
    stick_slip_map(axes[0], run, h, steps)
    axes[0].set_title(f"slide-3d: probe (R = 2 mm) pressed 0.5 mm, slid at 80 mm/s; μ = {mu:g}",
                      fontsize=10)
    forces(axes[1], h, steps, mu)
    receptors(axes[2], run, h, steps)
    fig.savefig(out, dpi=120)


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]))
