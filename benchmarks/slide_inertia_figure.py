"""The `slide` scene with inertia against the quasi-static one: normal force, tangential force
and the friction's dissipated energy against the bar's travel, from the runs' history.csv.

    PYTHONPATH=. python benchmarks/slide_inertia_figure.py OUT.png QS_DIR DYN_DIR \
        [QS_DIR2 DYN_DIR2]

Pairs of runs (quasi-static, with inertia): the first pair (solid) with the penalty contact
(γ0 = 10), a second pair (dashed) with the scene's Nitsche contact (θ = 0).
"""

from __future__ import annotations

import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def history(folder: str) -> dict[str, np.ndarray]:
    with open(f"{folder}/history.csv") as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def main(out: str, *folders: str) -> None:
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6), constrained_layout=True)
    styles, laws = ("-", "--"), ("penalty γ0 = 10", "Nitsche θ = 0")
    for pair, style, law in zip(zip(folders[::2], folders[1::2]), styles, laws):
        for folder, colour, name in zip(pair, ("C0", "C3"), ("quasi-static", "with inertia")):
            h = history(folder)
            slide = h["time_s"] > 0.1 + 1e-12
            x = np.concatenate([[0.0], h["tangential_displacement_mm"][slide]])
            pick = np.concatenate([[np.flatnonzero(~slide)[-1]], np.flatnonzero(slide)])
            label = f"{name}, {law}"
            axes[0].plot(x, 1e3 * h["force_N_per_mm"][pick], style, color=colour, label=label)
            axes[1].plot(x, 1e3 * h["tangential_force_N_per_mm"][pick], style, color=colour)
            dissipated = np.cumsum(np.where(slide, h["dissipated_N_mm_per_mm"], 0.0))[pick]
            axes[2].plot(x, 1e6 * dissipated, style, color=colour)
    for ax, title in zip(axes, ("normal force Fn (mN/mm)", "tangential force Ft (mN/mm)",
                                "friction's dissipated energy (µN mm/mm)")):
        ax.set_xlabel("bar's travel (mm)")
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle("slide, 80 mm/s, μ = 0.5: quasi-static and with inertia", fontsize=11)
    fig.savefig(out, dpi=110)


if __name__ == "__main__":
    main(*sys.argv[1:])
