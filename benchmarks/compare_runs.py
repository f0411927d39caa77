"""The largest relative differences of one run's outputs from a reference run's (the 0.1 % rule).

For two runs of the same scene (e.g. the direct and the iterative linear solver), prints for
each output time: the force (summary.json), and for each column of line_force.csv (f(z)),
surface_across.csv and surface_along.csv (the deflections; 2D: surface_profile.csv) and
depth_profiles.csv (displacements, strains, SED, pore pressure), max |run − reference| over
the points, relative to the reference's largest |value| at that time; then the largest of all.
The runs' steps may differ: only the outputs at the output times are compared. 2D and 3D runs
both: the tables a run has, located by the columns it has.

    python benchmarks/compare_runs.py REFERENCE_DIR RUN_DIR
"""

import csv
import json
import sys
from pathlib import Path

import numpy as np

#: The output tables and the columns that locate a point (with time_s).
TABLES = {"line_force.csv": ["z_mm"], "surface_across.csv": ["x_mm", "z_mm"],
          "surface_along.csv": ["x_mm", "z_mm"], "surface_profile.csv": ["x_mm"],
          "depth_profiles.csv": ["x_mm", "z_mm", "depth_mm"]}


def read(path: Path) -> dict[str, np.ndarray]:
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) if r[k] != "" else np.nan for r in rows]) for k in rows[0]}


def forces(summary: dict) -> dict[str, float]:
    """The force at each output time: N in 3D, N/mm in plane strain."""
    key = next(k for k in summary if k.startswith("force_at_output_times_"))
    return summary[key]


def differences(ref: Path, run: Path) -> dict[str, float]:
    out = {}
    f0, f1 = (forces(json.loads((r / "summary.json").read_text())) for r in (ref, run))
    for t in f0:
        out[f"force t={t}"] = abs(f1[t] - f0[t]) / abs(f0[t])
    for name, columns in TABLES.items():
        if not (ref / name).exists():
            continue
        a, b = read(ref / name), read(run / name)
        where = [k for k in columns if k in a]
        for k in [*where, "time_s"]:
            if not np.allclose(a[k], b[k]):
                raise SystemExit(f"{name}: the points differ ({k})")
        for t in sorted(set(a["time_s"])):
            m = a["time_s"] == t
            for c in (c for c in a if c not in [*where, "time_s"]):
                if not np.all(np.isnan(a[c][m])):
                    out[f"{name[:-4]}:{c} t={t:g}"] = (np.nanmax(np.abs(b[c][m] - a[c][m]))
                                                      / np.nanmax(np.abs(a[c][m])))
    return out


if __name__ == "__main__":
    diffs = differences(Path(sys.argv[1]), Path(sys.argv[2]))
    for key, value in sorted(diffs.items(), key=lambda kv: kv[1]):
        print(f"{value:10.2e}  {key}")
    worst = max(diffs, key=diffs.get)
    print(f"largest: {diffs[worst]:.2e} ({worst})")
