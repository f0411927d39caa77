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

3. The frequency route's threshold search on a run (--route RUN: the --out directory of
   `fingertip run vibrotactile --frequencies ...`): the search of every class of the run's
   receptor set (the calibrated Saal et al. fits) redone from the run's thresholds.csv (its
   H and s0 per site and frequency), timed per class (wall and CPU time), and checked against
   the thresholds the run wrote (largest relative difference; 0 when the search is unchanged).

Run: .venv/bin/python benchmarks/vibrotactile_thresholds.py [DIR]
     .venv/bin/python benchmarks/vibrotactile_thresholds.py --route RUN
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


def route_speed(run: Path) -> None:
    """Time the threshold search of a frequency-route run's classes on its own H and s0."""
    import json

    from fingertip_dolfinx.afferents.receptors import receptors_from_dict
    from fingertip_dolfinx.result import FrequencyResult

    result = FrequencyResult(run)
    population = receptors_from_dict(json.loads((run / "receptors.json").read_text()))
    table, total = result.thresholds, 0.0
    for cls in population.classes:
        rows = table["class"] == cls.name
        f, sites = np.unique(table["frequency_Hz"][rows]), np.unique(table["index"][rows])
        at = (np.searchsorted(f, table["frequency_Hz"][rows]),
              np.searchsorted(sites, table["index"][rows]))
        h, i0, i1 = (np.zeros((len(f), len(sites))) for _ in range(3))
        h[at], i0[at], i1[at] = (table[k][rows] for k in ("H_abs_per_um", "I0_um", "I1_um"))
        s0 = np.zeros(len(sites))
        s0[at[1]] = table["s0"][rows]
        wall, cpu = time.perf_counter(), time.process_time()
        th = vt.vibration_thresholds(cls, f, h * 1e3, s0)  # per µm -> per mm
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        total += wall
        diff = max(_relative_difference(th.absolute * 1e3, i0),
                   _relative_difference(th.entrainment * 1e3, i1))
        print(f"  {cls.name}: {len(f)} frequencies x {len(sites)} sites: {wall:.1f} s wall, "
              f"{cpu:.1f} s CPU; largest relative difference from the run's thresholds {diff:.1e}")
    print(f"  all classes: {total:.1f} s wall")


def _relative_difference(a, b) -> float:
    """max |a/b - 1| over entries finite in both; inf if NaN or inf differ in place."""
    if not np.array_equal(np.isfinite(a), np.isfinite(b)):
        return float("inf")
    ok = np.isfinite(a)
    return float(np.max(np.abs(a[ok] / b[ok] - 1), initial=0.0))


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
    if len(sys.argv) > 2 and sys.argv[1] == "--route":
        route_speed(Path(sys.argv[2]))
    else:
        main(Path(sys.argv[1] if len(sys.argv) > 1 else "vibrotactile-benchmark"))
