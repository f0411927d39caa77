"""Afferent threshold curves (vibrotactile.py): speed at the target size and the curves of
a stand-in mechanics, printed and drawn.

1. Speed: 40 frequencies (2-1000 Hz) × 20 sites × 3 classes of the default receptor set, both
   thresholds (I0, I1), H = 1 per mm at every site, s0 spread over 0-2e-6 MPa (the SA1 lanes
   then differ per site; RA and PC do not read s0). Prints the wall time per class.
2. Curves: a coarse 1pt quasi-static run (bar, 1 mm in 1 s) with the default receptor set;
   at the step nearest 0.5 mm, H = ds/dd by central differences of the sampled quantities
   over the neighbouring steps (real, frequency independent: the quasi-static tangent, which
   stands in for the harmonic mechanics and carries no inertia and no fast relaxation), s0 =
   the pressed value. Writes thresholds.csv and thresholds.png (with the verified published
   bands) to the output directory (argument, default ./vibrotactile-benchmark).

Run: .venv/bin/python benchmarks/vibrotactile_thresholds.py [DIR]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from fingertip_dolfinx.afferents import vibrotactile as vt
from fingertip_dolfinx.afferents.receptors import QUANTITIES, load_receptors

FREQUENCIES = np.geomspace(2.0, 1000.0, 40)
COARSE = ["section.mesh.min_size=0.2", "section.mesh.max_size=1.0", "section.mesh.bone_size=2.0",
          "output.pictures=false", 'output.receptors="default"', "steps.dt_max=0.05"]


def speed() -> None:
    population = load_receptors()
    h = np.ones((len(FREQUENCIES), 20))
    s0 = np.linspace(0.0, 2e-6, 20)
    total = 0.0
    for name in ("SA1", "RA", "PC"):
        start = time.perf_counter()
        vt.vibration_thresholds(population[name], FREQUENCIES, h, s0)
        elapsed = time.perf_counter() - start
        total += elapsed
        print(f"  {name}: 40 frequencies x 20 sites, I0 and I1: {elapsed:.1f} s")
    print(f"  all three classes: {total:.1f} s")


def stand_in_transfer(out: Path):
    from fingertip_dolfinx.runner import run
    from fingertip_dolfinx.scene import load_scene

    result = run(load_scene("1pt", COARSE), out / "1pt", progress=False)
    table = result.receptors()
    times = np.unique(table["time_s"])
    k = int(np.argmin(np.abs(times - 0.5)))  # d = t mm on the 1 s ramp to 1 mm
    population = load_receptors()
    transfer = {}
    for c in population.classes:
        column, sign, _ = QUANTITIES[c.quantity]
        s = [sign * table[column][(table["class"] == c.name) & (table["time_s"] == times[i])]
             for i in (k - 1, k, k + 1)]
        x = table["x_mm"][(table["class"] == c.name) & (table["time_s"] == times[k])]
        gain = (s[2] - s[0]) / (times[k + 1] - times[k - 1])
        transfer[c.name] = (x, np.tile(gain, (len(FREQUENCIES), 1)), s[1])
    return population, transfer, times[k]


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    print("speed:")
    speed()
    population, transfer, depth = stand_in_transfer(out)
    curves, rows = [], []
    for name, (x, h, s0) in transfer.items():
        start = time.perf_counter()
        th = vt.vibration_thresholds(population[name], FREQUENCIES, h, s0)
        curves.append(th)
        best0, best1 = th.best("absolute"), th.best("entrainment")
        i = int(np.argmin(best0))
        print(f"{name} ({len(x)} sites, {time.perf_counter() - start:.1f} s): best I0 "
              f"{best0[i] * 1e3:.3g} µm at {FREQUENCIES[i]:.0f} Hz; I1 at that frequency "
              f"{best1[i] * 1e3:.3g} µm")
        rows += [(name, f, a, b) for f, a, b in zip(FREQUENCIES, best0, best1)]
    with (out / "thresholds.csv").open("w") as f:
        f.write("class,frequency_Hz,absolute_mm,entrainment_mm\n")
        f.writelines(f"{r[0]},{r[1]:.6g},{r[2]:.6g},{r[3]:.6g}\n" for r in rows)
    vt.plot_threshold_curves(curves, out / "thresholds.png", title=(
        f"stand-in: quasi-static tangent at {depth:.2f} mm (no inertia, no fast relaxation)"))
    print(f"written: {out / 'thresholds.csv'}, {out / 'thresholds.png'}")


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "vibrotactile-benchmark"))
