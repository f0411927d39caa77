"""The `shear` scene's tangential force Ft and Coulomb's bound μFn against the plate's drag,
from a run's history.csv (docs/benchmarks/friction.md).

Run: `fingertip run shear --out DIR`, then `python benchmarks/shear_figure.py DIR OUT.png`.
"""

import csv
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main(run: Path, out: Path, mu: float = 0.5) -> None:
    rows = list(csv.DictReader(open(run / "history.csv")))
    pressed = min(float(r["time_s"]) for r in rows if float(r["tangential_displacement_mm"]) > 0)
    rows = [r for r in rows if float(r["time_s"]) >= pressed - 1e-9]  # the drag, from its start
    x = [float(r["tangential_displacement_mm"]) for r in rows]
    ft = [float(r["tangential_force_N_per_mm"]) * 1e3 for r in rows]
    fn = [float(r["force_N_per_mm"]) * 1e3 for r in rows]
    fig, ax = plt.subplots(figsize=(6.0, 3.6), constrained_layout=True)
    ax.plot(x, ft, "o-", ms=3, label="tangential force $F_t$")
    ax.plot(x, [mu * f for f in fn], "--", label=r"Coulomb's bound $\mu F_n$")
    ax.set_xlabel("plate's drag along x (mm)")
    ax.set_ylabel("force (mN/mm)")
    ax.set_title(f"shear: plate pressed 0.5 mm, then dragged; μ = {mu:g}")
    ax.set_ylim(0, 1.15 * max(mu * f for f in fn))
    ax.legend(loc="lower right")
    fig.savefig(out, dpi=120)


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]))
