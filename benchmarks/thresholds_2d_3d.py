"""The most sensitive afferent's thresholds of two frequency-route runs side by side (the
section's `vibrotactile` and the 3D `vibrotactile-3d`): per class the lowest I1 (1:1) and I0
(absolute) over the sites at each frequency, as a table (best frequency and threshold; the
value at chosen frequencies) and one figure (I1 per class, solid 2D, open 3D).

    PYTHONPATH=. python benchmarks/thresholds_2d_3d.py OUT.png LABEL=DIR LABEL=DIR
        [--at 10 30 100 250 1000]

Each DIR holds a thresholds.csv (`class, frequency_Hz, I0_um, I1_um` among its columns).
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from fingertip_dolfinx.plotting.figures import plain_log_ticks

CLASSES = ("SA1", "RA", "PC")
COLOURS = {"SA1": "tab:blue", "RA": "tab:green", "PC": "tab:red"}


def best(directory: Path) -> dict[str, dict[str, np.ndarray]]:
    """{class: {"f", "I0", "I1"}}: the lowest finite threshold over the sites per frequency
    (inf where no site has one)."""
    with (directory / "thresholds.csv").open() as f:
        rows = list(csv.DictReader(f))
    out = {}
    for cls in CLASSES:
        mine = [r for r in rows if r["class"] == cls]
        freqs = np.unique([float(r["frequency_Hz"]) for r in mine])
        entry = {"f": freqs}
        for key in ("I0", "I1"):
            values = np.full(len(freqs), np.inf)
            for r in mine:
                v = float(r[f"{key}_um"]) if r[f"{key}_um"] else np.nan
                k = np.searchsorted(freqs, float(r["frequency_Hz"]))
                if np.isfinite(v) and v < values[k]:
                    values[k] = v
            entry[key] = values
        out[cls] = entry
    return out


def table(runs: dict, at: list[float]) -> str:
    head = ["run", "class", "lowest I1 (µm) at (Hz)", *(f"I1 at {f:g} Hz" for f in at)]
    lines = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    for label, data in runs.items():
        for cls in CLASSES:
            d = data[cls]
            k = int(np.argmin(d["I1"]))
            near = [d["I1"][int(np.argmin(np.abs(np.log(d["f"] / f))))] for f in at]
            lines.append(f"| {label} | {cls} | {d['I1'][k]:.3g} at {d['f'][k]:.3g} | "
                         + " | ".join(f"{v:.3g}" for v in near) + " |")
    return "\n".join(lines)


def figure(runs: dict, path: Path) -> None:
    fig = Figure(figsize=(6.8, 5.0))
    ax = fig.subplots()
    for (label, data), fill in zip(runs.items(), ("full", "none")):
        for cls in CLASSES:
            d = data[cls]
            keep = np.isfinite(d["I1"])
            ax.loglog(d["f"][keep], d["I1"][keep], "o-" if fill == "full" else "s--",
                      color=COLOURS[cls], mfc=COLOURS[cls] if fill == "full" else "none",
                      ms=4, lw=0.8, label=f"{cls}, {label}")
    ax.set_xlabel("vibration frequency (Hz)")
    ax.set_ylabel("most sensitive afferent's I1, 1:1 (µm)")
    ax.set_title("1:1 thresholds: plane-strain section against the 3D finger", fontsize=10)
    plain_log_ticks(ax, "x")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("runs", nargs="+")
    parser.add_argument("--at", type=float, nargs="*", default=[10.0, 30.0, 100.0, 250.0])
    args = parser.parse_args()
    runs = {label: best(Path(d)) for label, d in (r.split("=", 1) for r in args.runs)}
    print(table(runs, args.at))
    figure(runs, args.out)


if __name__ == "__main__":
    main()
