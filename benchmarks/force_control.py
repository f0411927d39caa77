"""Force control, measured (docs/benchmarks/friction.md, "Force control"): from a force-
controlled run's history.csv, the force delivered against its target at every step, Coulomb's
law integrated (the friction's tangential force against μ times the pressure's normal force),
the dissipated energy against μ F_p,y × the indenters' travel, and the cost per step; with a
second, depth-controlled run, a figure of both against the travel.

Run: `fingertip run slide-force --out DIR` (or a scene with `[protocol] normal_force`), then
`python benchmarks/force_control.py DIR MU [DEPTH_RUN OUT.png]`.

In gross slip in 2D the friction's force is μ (F_p,y, −F_p,x), F_p = ∫ p n ds the pressure's
(test_slide.py), so with Fn = F_p,y + F_f,y the pressure's normal force is Fn + μ F_p,x, and
D/(μ F_p,y Δc) = 1 − (the skin's pressure-weighted speed)/(the indenters'): 1 in steady
sliding, below 1 while the skin is carried along.
"""

import sys
from pathlib import Path

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from fingertip_dolfinx.outputs import read_csv  # noqa: E402


def measures(h: dict, mu: float) -> dict[str, np.ndarray]:
    """Per step: the force's relative miss, the friction law's residual, D/(μ F_p,y Δc)."""
    fn, ft, px = h["force_N_per_mm"], h["tangential_force_N_per_mm"], \
        h["pressure_tangential_force_N_per_mm"]
    target = h["normal_force_target_N_per_mm"]
    travel = h["tangential_displacement_mm"]
    step = np.diff(np.concatenate([[0.0], travel]))
    normal = fn + mu * px  # F_p,y in gross slip
    with np.errstate(invalid="ignore", divide="ignore"):
        return {"miss": np.abs(fn - target) / target, "coulomb": (ft - px) / (mu * normal) - 1,
                "dissipation": h["dissipated_N_mm_per_mm"] / (mu * normal * step),
                "travel": travel, "step": step}


def report(run: Path, mu: float) -> None:
    h = read_csv(run / "history.csv")
    m = measures(h, mu)
    on = ~np.isnan(h["normal_force_target_N_per_mm"])
    print(f"{run}: {len(on)} steps, {on.sum()} force controlled")
    print(f"  max |Fn − F*|/F* = {np.nanmax(m['miss'][on]):.3g}")
    for name, rows in (("press", on & (m["travel"] == 0)), ("slide", m["travel"] > 0)):
        its, solves = h["newton_iterations"][rows], h["force_solves"][rows]
        print(f"  {name}: {rows.sum()} steps, Newton {its.sum():.0f} (mean {its.mean():.2f}, "
              f"max {its.max():.0f}), solves mean {solves.mean():.2f} max {solves.max():.0f}, "
              f"cuts {h['cuts'][rows].sum():.0f}")
    print("  travel  depth  Fn  Ft/Fn  Fpx/Fn  (Ft−Fpx)/(μFpy)−1  D/(μFpyΔc)  its  solves")
    for i in np.flatnonzero(m["travel"] > 0):
        print(f"  {m['travel'][i]:.4f} {h['indenter_displacement_mm'][i]:.5f} "
              f"{h['force_N_per_mm'][i]:.6g} "
              f"{h['tangential_force_N_per_mm'][i] / h['force_N_per_mm'][i]:.4f} "
              f"{h['pressure_tangential_force_N_per_mm'][i] / h['force_N_per_mm'][i]:.4f} "
              f"{m['coulomb'][i]:+.2e} {m['dissipation'][i]:.5f} "
              f"{h['newton_iterations'][i]:.0f} {h['force_solves'][i]:.0f}")


def figure(run: Path, depth_run: Path, out: Path) -> None:
    """Fn, the depth and D/(μ F_p,y Δc) against the travel, force- and depth-controlled."""
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    for path, label, style in ((depth_run, "depth held (slide)", "--"),
                               (run, "force held (slide-force)", "-")):
        h = read_csv(path / "history.csv")
        m = measures(h | {"normal_force_target_N_per_mm": np.ones_like(h["time_s"])}, 0.5)
        s = m["travel"] > 0
        axes[0].plot(m["travel"][s], 1e3 * h["force_N_per_mm"][s], style, label=label)
        axes[1].plot(m["travel"][s], h["indenter_displacement_mm"][s], style, label=label)
        axes[2].plot(m["travel"][s], m["dissipation"][s], style, marker=".", label=label)
    axes[0].set_ylabel("normal force Fn (mN/mm)")
    axes[1].set_ylabel("depth (mm after first touch)")
    axes[2].set_ylabel("D / (μ F_p,y Δc)")
    axes[2].axhline(1.0, color="grey", lw=0.8)
    for ax in axes:
        ax.set_xlabel("the bar's travel (mm)")
        ax.grid(alpha=0.3)
    axes[0].legend()
    fig.suptitle("The bar slid 2 mm across the pulp: depth held against normal force held")
    fig.tight_layout()
    fig.savefig(out, dpi=120)


if __name__ == "__main__":
    report(Path(sys.argv[1]), float(sys.argv[2]))
    if len(sys.argv) > 4:
        figure(Path(sys.argv[1]), Path(sys.argv[3]), Path(sys.argv[4]))
