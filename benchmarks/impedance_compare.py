"""Driving-point impedance of several frequency-route runs side by side (README, vibrotactile):
one Bode figure, and per run the first resonances and K, |Z|, phase Z at chosen frequencies.

Each DIR is the output of `fingertip run vibrotactile --frequencies ... --out DIR` (its
frequency_response.csv and summary.json); LABEL names it in the figure and the table.

    PYTHONPATH=. python benchmarks/impedance_compare.py OUT.png LABEL=DIR [LABEL=DIR ...]
        [--at 10 100 250]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from fingertip_dolfinx.frequency_response import magnitude_key, resonances
from fingertip_dolfinx.outputs import read_csv


def load(directory: Path) -> dict:
    table = read_csv(directory / "frequency_response.csv")
    order = np.argsort(table["frequency_Hz"])
    rows = [{k: float(table[k][i]) for k in table} for i in order]
    summary = json.loads((directory / "summary.json").read_text())
    return {"rows": rows, "dofs": summary["dofs"], "resonances": resonances(rows),
            "force": summary["pressed_state"]["force"]}


def table_lines(label: str, run: dict, at) -> list[str]:
    f = np.array([r["frequency_Hz"] for r in run["rows"]])
    # the first zero of K, then the first pole above it (a broad maximum of |K| below the
    # first zero, the fast Prony terms' stiffening overtaken by inertia, is no resonance)
    zeros = run["resonances"]["force_driven"]
    poles = [f for f in run["resonances"]["probe_held"] if not zeros or f > zeros[0]]
    head = (f"| {label} | {f'{zeros[0]:.4g}' if zeros else '-'} | "
            f"{f'{poles[0]:.4g}' if poles else '-'} |")
    cells = []
    for target in at:
        i = int(np.argmin(np.abs(f - target)))
        if abs(f[i] - target) > 1e-6 * target:
            cells.append("-")
            continue
        r = run["rows"][i]
        cells.append(f"{r['K_real']:.3e} {r['K_imag']:+.1e} i; {r[magnitude_key(r, 'Z')]:.3e}, "
                     f"{r['Z_phase_deg']:+.1f}°")
    return [head + " " + " | ".join(cells) + " |"]


def plot(runs: dict, path: Path) -> None:
    fig = Figure(figsize=(6.4, 6.0))
    top, bottom = fig.subplots(2, 1, sharex=True)
    for label, run in runs.items():
        f = [r["frequency_Hz"] for r in run["rows"]]
        top.loglog(f, [r[magnitude_key(r, "Z")] for r in run["rows"]], "-", lw=1, label=label)
        bottom.semilogx(f, [r["Z_phase_deg"] for r in run["rows"]], "-", lw=1)
    top.set_ylabel("|Z| (N·s/mm per mm)")
    top.set_title("driving-point impedance of the 1 mm bar (held state)", fontsize=9)
    top.legend(fontsize=7)
    bottom.set_ylabel("phase of Z (°)")
    bottom.set_xlabel("frequency (Hz)")
    for ax in (top, bottom):
        ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=130)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("figure")
    parser.add_argument("runs", nargs="+", metavar="LABEL=DIR")
    parser.add_argument("--at", type=float, nargs="+", default=[10.0, 100.0, 250.0])
    a = parser.parse_args()
    runs = {}
    for item in a.runs:
        label, directory = item.split("=", 1)
        runs[label] = load(Path(directory))
    plot(runs, Path(a.figure))
    print("| run | first force-driven resonance (Hz) | first probe-held resonance (Hz) | "
          + " | ".join(f"K (N/mm per mm); \\|Z\\| (N·s/mm per mm), phase Z at {f:g} Hz"
                       for f in a.at) + " |")
    print("|" + " --- |" * (3 + len(a.at)))
    for label, run in runs.items():
        print("\n".join(table_lines(label, run, a.at)))
    for label, run in runs.items():
        print(f"{label}: {run['dofs']} dofs, pressed force {run['force']:.4g} N/mm, "
              f"resonances {run['resonances']}")


if __name__ == "__main__":
    main()
