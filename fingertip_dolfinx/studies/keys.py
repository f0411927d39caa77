"""The key outputs of a scene run, by which runs are compared (accuracy and fidelity studies).

From a run directory: peak force; force at the last output time (100 s for the line load);
surface deflection 1, 2 and 3 mm from the load axis at the last output time (both sides
averaged); peak max principal log strain and peak SED at depth 0.75 mm at the first output time.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..outputs import read_csv

KEYS = ("peak_force", "final_force", "deflection_1mm", "deflection_2mm", "deflection_3mm",
        "peak_e_max_0.75mm", "peak_sed_0.75mm")


def key_outputs(run: Path, depth_mm: float = 0.75) -> dict[str, float]:
    run = Path(run)
    h = read_csv(run / "history.csv")
    s = read_csv(run / "surface_profile.csv")
    d = read_csv(run / "depth_profiles.csv")
    summary = json.loads((run / "summary.json").read_text())
    out = {"peak_force": float(np.max(h["force_N_per_mm"])),
           "final_force": float(h["force_N_per_mm"][-1])}
    last = np.max(s["time_s"])
    rows = np.isclose(s["time_s"], last)
    x, w = s["x_mm"][rows], s["deflection_mm"][rows]
    order = np.argsort(x)
    for r in (1, 2, 3):
        out[f"deflection_{r}mm"] = float(0.5 * (np.interp(r, x[order], w[order])
                                                + np.interp(-r, x[order], w[order])))
    first = np.min(d["time_s"])
    rows = np.isclose(d["time_s"], first) & np.isclose(d["depth_mm"], depth_mm)
    if not rows.any():
        rows = np.isclose(d["time_s"], first) & np.isclose(d["depth_mm"], np.min(d["depth_mm"]))
    out["peak_e_max_0.75mm"] = float(np.nanmax(d["e_max"][rows]))
    out["peak_sed_0.75mm"] = float(np.nanmax(d["sed_MPa"][rows]))
    out["wall_time_s"] = float(summary["wall_time_s"])
    out["dofs"] = int(summary["dofs"])
    return out


def relative_errors(values: dict, reference: dict) -> dict[str, float]:
    return {k: abs(values[k] - reference[k]) / max(abs(reference[k]), 1e-300) for k in KEYS}
