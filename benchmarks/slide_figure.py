"""The `slide` scene against the bar's travel (docs/benchmarks/friction.md): the stick/slip map
of the pulp surface, the forces (the total tangential force, the friction's and the pressure's
shares of it, μ times the pressure's normal force) and the receptor rows' compressive stress.

Run: `fingertip run slide --out DIR`, then `python benchmarks/slide_figure.py DIR OUT.png`.
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


def slide_steps(h: dict) -> np.ndarray:
    """The steps of the slide and the last one of the press before it."""
    moving = h["tangential_displacement_mm"] > 0
    first = int(np.argmax(moving))
    return np.arange(max(first - 1, 0), len(moving))


def stick_slip_map(ax, run: Path, h: dict, steps: np.ndarray) -> None:
    s = read_csv(run / "stick_slip.csv")
    travel = h["tangential_displacement_mm"][steps]
    _, x_edges, state = stick_slip_grid(s, "x_mm", h["time_s"][steps])
    c_edges = np.concatenate([[travel[0] - 0.01], 0.5 * (travel[1:] + travel[:-1]),
                              [travel[-1]]])
    ax.pcolormesh(c_edges, x_edges, state, cmap=matplotlib.colors.ListedColormap(STATE_COLOURS),
                  vmin=-0.5, vmax=2.5)
    ax.set_ylim(-2.5, 1.5)
    ax.set_ylabel("skin point x\n(mm, reference)")
    ax.legend(handles=[Patch(color=c, label=n) for c, n in
                       zip(STATE_COLOURS, ("free", "slip", "stick"))], loc="upper left",
              fontsize=8)


def forces(ax, h: dict, steps: np.ndarray, mu: float) -> None:
    c = h["tangential_displacement_mm"][steps]
    ft, fn = (1e3 * h[k][steps] for k in ("tangential_force_N_per_mm", "force_N_per_mm"))
    px = 1e3 * h["pressure_tangential_force_N_per_mm"][steps]
    ax.plot(c, fn, "k-", label="normal force $F_n$")
    ax.plot(c, ft, "o-", ms=3, color=STATE_COLOURS[1], label="tangential force $F_t$")
    ax.plot(c, ft - px, "-", color="tab:green", label="its friction share $F_t - F_{p,x}$")
    ax.plot(c, px, "-", color="tab:purple", label="its pressure share $F_{p,x}$ (ploughing)")
    ax.plot(c, mu * (fn + mu * px), "--", color="0.4",
            label=rf"$\mu (F_n + \mu F_{{p,x}})$, = $\mu F_{{p,y}}$ in gross slip ($\mu$ = {mu:g})")
    ax.set_ylabel("force (mN/mm)")
    ax.legend(fontsize=7, loc="upper left", ncol=2)
    ax.set_ylim(0, 1.3 * fn.max())
    ax.grid(alpha=0.3)


def receptors(ax, run: Path, h: dict, steps: np.ndarray) -> None:
    """−σ22 at the RA sites (0.5 mm deep) the bar passes over, against the travel."""
    r = Result(run).receptors()
    travel = dict(zip(np.round(h["time_s"], 12), h["tangential_displacement_mm"]))
    ra = r["class"] == "RA"
    sites = [i for i in np.unique(r["index"][ra])
             if abs(r["x_mm"][ra & (r["index"] == i)][0]) < 1.6]
    start = h["time_s"][steps[0]] - 1e-12
    for i in sites:
        rows = ra & (r["index"] == i) & (r["time_s"] >= start)
        c = [travel[t] for t in np.round(r["time_s"][rows], 12)]
        ax.plot(c, -1e3 * r["sigma22_MPa"][rows], label=f"x = {r['x_mm'][rows][0]:.2f} mm")
    ax.set_ylabel("RA site −σ22 (kPa)\n(0.5 mm deep)")
    ax.set_xlabel("bar's travel along x (mm), from x = −1 mm")
    ax.legend(fontsize=7, loc="upper left", ncol=2)
    ax.grid(alpha=0.3)


def main(run: Path, out: Path, mu: float = 0.5) -> None:
    h = read_csv(run / "history.csv")
    steps = slide_steps(h)
    fig, axes = plt.subplots(3, 1, figsize=(6.4, 8.0), sharex=True, constrained_layout=True,
                             height_ratios=(2, 3, 3))
    stick_slip_map(axes[0], run, h, steps)
    axes[0].set_title(f"slide: 1 mm bar pressed 0.5 mm, slid at 80 mm/s; μ = {mu:g}")
    forces(axes[1], h, steps, mu)
    receptors(axes[2], run, h, steps)
    fig.savefig(out, dpi=120)


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]))
