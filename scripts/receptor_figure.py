"""The README's receptor figure: SA1 rates along the pulp at the end of the one-point ramp
(the SED-proportional model and the integrate-and-fire neuron), and the transduction stage's
threshold against frequency for each class.

    python scripts/receptor_figure.py [--run results/receptors-1pt] [--out docs/results/receptors]

runs the one-point scene on the coarse mesh (0.2 mm under the pulp; about 10 s) with
`output.receptors = "default"` into RUN, draws OUT/receptors_1pt.png, writes the SA1 numbers
it draws to OUT/sa1_rates_1pt.csv and prints them.
"""

import argparse
from pathlib import Path

import numpy as np

import fingertip_dolfinx as ft
from fingertip_dolfinx.afferents.receptors import (
    afferent_responses,
    load_receptors,
    threshold_amplitude,
)

COARSE = ["section.mesh.min_size=0.2", "section.mesh.max_size=1.0",
          "section.mesh.bone_size=2.0", 'output.receptors="default"', "output.pictures=false"]
COLOURS = {"SA1": "#32a028", "RA": "#1e78b4", "PC": "#ff7f00"}  # TouchSim's class colours


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--run", type=Path, default=Path("results/receptors-1pt"))
    parser.add_argument("--out", type=Path, default=Path("docs/results/receptors"))
    args = parser.parse_args()
    result = ft.run(ft.load_scene("1pt", COARSE), args.run, progress=False)
    population = load_receptors()
    r = afferent_responses(result, population)

    from matplotlib.figure import Figure

    fig = Figure(figsize=(11.5, 4.2), layout="constrained")
    left, right = fig.subplots(1, 2)
    sa1 = r.of("SA1")
    order = np.argsort(r.x[sa1])
    x = r.x[sa1][order]
    sed_rate = r.sed_rate[-1, sa1][order]
    lif_rate = r.rate[-1, sa1][order]
    left.plot(x, sed_rate, "o-", color=COLOURS["SA1"], label="r = k SED (k = 1e6 /s/MPa)")
    left.plot(x, lif_rate, "s--", color="k", label="integrate-and-fire, last step")
    left.axvspan(-0.5, 0.5, color="0.9", zorder=0, label="bar (1 mm)")
    left.set(xlabel="x of the site (mm)", ylabel="SA1 rate (spikes/s)",
             title=f"SA1 at 0.75 mm, 1-mm bar pressed 1 mm (t = {r.time[-1]:g} s)")
    left.legend(frameon=False, fontsize=8)
    print("SA1 x (mm):", np.round(x, 3))
    print("SA1 SED (MPa):", r.stimulus[-1, sa1][order])
    print("SA1 rate k SED (1/s):", np.round(sed_rate, 2))
    print("SA1 LIF rate in the last step (1/s):", np.round(lif_rate, 2))
    print("mean LIF rate over the ramp (1/s):",
          {c: np.round(r.mean_rate[r.of(c)], 1).tolist() for c in ("SA1", "RA", "PC")})

    frequencies = np.geomspace(0.5, 1000.0, 23)
    for c in population.classes:
        th = np.array([threshold_amplitude(c.lif, f, samples_per_cycle=100)
                       for f in frequencies])
        right.loglog(frequencies, th, "o-", ms=3, color=COLOURS[c.name],
                     label=f"{c.name}: {'SED' if c.quantity == 'sed' else '−σ22'} "
                           f"at {c.depth:g} mm")
        print(c.name, "threshold amplitude (MPa):", [float(f"{a:.3g}") for a in th])
    right.set(xlabel="frequency (Hz)", ylabel="threshold amplitude at the site (MPa)",
              title="transduction stage alone, s = A sin(2πft), ≥ 0.25 s")
    right.legend(frameon=False, fontsize=8)
    args.out.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out / "receptors_1pt.png", dpi=120)
    np.savetxt(args.out / "sa1_rates_1pt.csv",
               np.column_stack([x, r.stimulus[-1, sa1][order], sed_rate, lif_rate]),
               delimiter=",", header="x_mm,sed_MPa,rate_k_sed_per_s,rate_lif_last_step_per_s",
               comments="", fmt="%.6g")
    print("wrote", args.out / "receptors_1pt.png")


if __name__ == "__main__":
    main()
