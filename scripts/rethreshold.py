"""Redo a frequency-route thresholds.csv (and its figure) for a receptor set's classes from the
file's own H and s0 per site and frequency, without the mechanics: used when a class's input
scale changes (data/receptors/calibrated.toml) and the mechanics do not.

    PYTHONPATH=. python scripts/rethreshold.py CSV PNG TITLE [SET] [CLASS ...]

CSV is rewritten in place: the rows of the named classes (default: every class of SET,
default "calibrated") get the thresholds of SET's model of their class; the other rows, the
columns, the sites and H are kept. PNG is drawn as the frequency route draws thresholds.png
(`vibrotactile.plot_threshold_curves`, the most sensitive site per class; no resolution note).
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path

import numpy as np

from fingertip_dolfinx.afferents import vibrotactile as vt
from fingertip_dolfinx.afferents.receptors import load_receptors

PER_UM = 1e-3  # mm per µm: the file's H is per µm, its thresholds in µm


def _value(text: str) -> float:
    return float(text) if text else np.nan  # empty: NaN (the pressed value alone fires)


def class_thresholds(rows: list[dict], cls, recompute: bool) -> vt.VibrationThresholds:
    """The class's thresholds on the file's (f, site) grid: recomputed, or as the file has."""
    mine = [r for r in rows if r["class"] == cls.name]
    f = np.unique([float(r["frequency_Hz"]) for r in mine])
    sites = np.unique([int(r["index"]) for r in mine])
    at = [(np.searchsorted(f, float(r["frequency_Hz"])), np.searchsorted(sites, int(r["index"])))
          for r in mine]
    h, i0, i1, s0 = np.zeros((len(f), len(sites))), *np.zeros((2, len(f), len(sites))), \
        np.zeros(len(sites))
    for (j, k), r in zip(at, mine):
        h[j, k], s0[k] = float(r["H_abs_per_um"]) / PER_UM, float(r["s0"])
        i0[j, k], i1[j, k] = _value(r["I0_um"]) * PER_UM, _value(r["I1_um"]) * PER_UM
    if recompute:
        th = vt.vibration_thresholds(cls, f, h, s0)
        for (j, k), r in zip(at, mine):
            r["I0_um"], r["I1_um"] = (_cell(th.absolute[j, k] / PER_UM),
                                      _cell(th.entrainment[j, k] / PER_UM))
        return th
    return vt.VibrationThresholds(cls.name, cls.unit, f, i0, i1, i0 * h, i1 * h)


def _cell(v: float) -> str:
    return "" if np.isnan(v) else f"{v:.12g}"  # as the route's CsvLog writes them


def main(argv: list[str]) -> None:
    path, png, title = Path(argv[0]), Path(argv[1]), argv[2]
    population = load_receptors(argv[3] if len(argv) > 3 else "calibrated")
    names = argv[4:] or [c.name for c in population.classes]
    with path.open() as fh:
        rows = list(csv.DictReader(fh))
        columns = list(rows[0])
    present = {r["class"] for r in rows}
    curves = [class_thresholds(rows, c, c.name in names) for c in population.classes
              if c.name in present]
    with path.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)
    vt.plot_threshold_curves(curves, png, title=title)
    print(f"written: {path}, {png}")


if __name__ == "__main__":
    main(sys.argv[1:])
