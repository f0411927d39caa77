"""The key outputs of a scene run: one definition for the parameter sweeps, the accuracy and
fidelity studies, `run --tol` (adaptivity) and `run --fidelity auto`.

Each key output (`KeyOutput`) is a quantity in a unit, read at a place (a surface point, the
peak along a depth curve) at a time (the end of the run, or the largest value over the run),
and its column name says all four (docs/guide/key-outputs.md): ``{quantity}_{unit}_at_x{X}mm_
{when}`` (a surface point), ``{quantity}_{unit}_peak_at_depth{D}mm_{when}`` (a depth curve's
peak), ``{quantity}_{unit}_max_over_run`` or ``{quantity}_{unit}_at_t_end`` (no place), with
when = max_over_run | t_end and no unit for a dimensionless quantity:

- force_N_per_mm_max_over_run: the indenter force (history.csv), the largest over every step;
- force_N_per_mm_at_t_end: the same at the run's end time (history.csv's last row);
- deflection_mm_at_x{1,2,3}mm_t_end: the surface deflection at x = ±1, 2, 3 mm (both sides
  averaged) at the end time (surface_profile.csv);
- e_max_peak_at_depth0.75mm_max_over_run, sed_MPa_peak_at_depth0.75mm_max_over_run: the max
  principal log strain (dimensionless) and the strain energy density, the largest along the
  0.75 mm depth curve and over the output times (depth_profiles.csv).

"max over the run" is the largest value the run wrote: every time step for the force
(history.csv), the output times for the depth curves (depth_profiles.csv holds those only, so a
peak between two output times is not seen: add output times to resolve it). The time each
value was read at is recorded beside it (`{column}_t_s`). A run that lacks what a key needs
(the depth not in `output.depths`, the end time not among `output.times`, a 3D run) raises
`InputError`: no other depth or time is ever substituted.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputError
from .outputs import read_csv

#: The depth (mm below the undeformed outer surface) of the key outputs' depth curve.
KEY_DEPTH = 0.75
#: Surface points (|x|, mm) of the deflections.
DEFLECTION_POINTS = (1.0, 2.0, 3.0)
MAX_OVER_RUN = "max over the run"
END_OF_RUN = "end of the run"


@dataclass(frozen=True)
class KeyOutput:
    """One key output: `quantity` (a column of the run's CSV), its `unit`, where it is read
    (`x_mm`: the surface at x = ±x_mm averaged; `depth_mm`: the peak along that depth curve;
    neither: the force), `time` (END_OF_RUN or MAX_OVER_RUN) and the file it comes from."""

    quantity: str
    unit: str
    time: str
    source: str
    x_mm: float | None = None
    depth_mm: float | None = None

    @property
    def name(self) -> str:
        """Quantity and unit: the column of the run's CSV file it is read from."""
        return self.quantity + ("" if self.unit == "1" else "_" + self.unit.replace("/", "_per_"))

    @property
    def column(self) -> str:
        """The name in every table: quantity, unit, place and time (module docstring)."""
        name = self.name
        when = "max_over_run" if self.time == MAX_OVER_RUN else "t_end"
        if self.x_mm is not None:
            return f"{name}_at_x{self.x_mm:g}mm_{when}"
        if self.depth_mm is not None:
            return f"{name}_peak_at_depth{self.depth_mm:g}mm_{when}"
        return f"{name}_{when}" if self.time == MAX_OVER_RUN else f"{name}_at_{when}"

    @property
    def label(self) -> str:
        """Two lines for a plot: quantity (unit), then place and time."""
        name = {"sed": "SED"}.get(self.quantity, self.quantity)
        unit = "" if self.unit == "1" else f" ({self.unit})"
        where = (f"x = ±{self.x_mm:g} mm, " if self.x_mm is not None else
                 f"peak at {self.depth_mm:g} mm depth, " if self.depth_mm is not None else "")
        return f"{name}{unit}\n{where}{'max over run' if self.time == MAX_OVER_RUN else 't_end'}"

    def record(self) -> dict:
        """The definition as plain data (for summary.json)."""
        return {"quantity": self.quantity, "unit": self.unit, "x_mm": self.x_mm,
                "depth_mm": self.depth_mm, "time": self.time, "source": self.source,
                "time_column": f"{self.column}_t_s"}

    @property
    def short(self) -> str:
        """A table header: 'F max', 'F end', 'w 1 mm', 'e_max max', 'SED max'."""
        name = {"force": "F", "deflection": "w", "sed": "SED"}.get(self.quantity, self.quantity)
        where = f" {self.x_mm:g} mm" if self.x_mm is not None else ""
        when = " max" if self.time == MAX_OVER_RUN else (" end" if not where else "")
        return name + where + when


KEY_OUTPUTS = (
    KeyOutput("force", "N/mm", MAX_OVER_RUN, "history.csv"),
    KeyOutput("force", "N/mm", END_OF_RUN, "history.csv"),
    *(KeyOutput("deflection", "mm", END_OF_RUN, "surface_profile.csv", x_mm=r)
      for r in DEFLECTION_POINTS),
    KeyOutput("e_max", "1", MAX_OVER_RUN, "depth_profiles.csv", depth_mm=KEY_DEPTH),
    KeyOutput("sed", "MPa", MAX_OVER_RUN, "depth_profiles.csv", depth_mm=KEY_DEPTH),
)
#: The column names, in order: what the studies' tables and dicts are keyed by.
KEYS = tuple(k.column for k in KEY_OUTPUTS)
BY_COLUMN = {k.column: k for k in KEY_OUTPUTS}
#: What `key_outputs` adds beside each key: the time (s) its value was read at.
TIME_COLUMNS = tuple(f"{c}_t_s" for c in KEYS)


def check_scene(scene, where: str) -> None:
    """Before running: the scene writes what every key output reads (the key depth among
    output.depths, the end time among output.times, a plane-strain section), else InputError."""
    if hasattr(scene.section, "cylinder_length"):
        raise InputError(where, f"{scene.name} is a 3D scene: the key outputs (forces in N/mm, "
                         "the section's surface and depth curves) are defined for plane-strain "
                         "runs.", "use a 2D scene.")
    if not np.isclose(scene.depths, KEY_DEPTH).any():
        raise InputError(where, f"the key outputs read the depth curve at {KEY_DEPTH:g} mm, but "
                         f"output.depths = {list(scene.depths)}.",
                         f"add {KEY_DEPTH:g}: --set 'output.depths="
                         f"{_listed({*scene.depths, KEY_DEPTH})}'.")
    end = scene.history.end_time
    if not np.isclose(scene.output_times, end).any():
        raise InputError(where, f"the key deflections are read at the end of the run "
                         f"(t = {end:g} s), but output.times = {list(scene.output_times)}.",
                         f"add {end:g}: --set 'output.times="
                         f"{_listed({*scene.output_times, end})}'.")


def _listed(values) -> str:
    """Sorted numbers as a TOML list: [0.75, 1.2], [1, 5]."""
    return "[" + ", ".join(f"{v:g}" for v in sorted(float(v) for v in values)) + "]"


def key_outputs(run: Path) -> dict[str, float]:
    """Every key output of the finished run in `run` by column, the time each was read at
    (`{column}_t_s`), and the run's wall_time_s and dofs. InputError when the run lacks what
    a key needs (module docstring)."""
    run = Path(run)
    summary = _summary(run)
    end = float(summary["end_time_s"])
    tables = {name: _table(run, name) for name in ("history.csv", "surface_profile.csv",
                                                  "depth_profiles.csv")}
    out = {}
    for key in KEY_OUTPUTS:
        value, t = read_key(key, tables[key.source], end, f"{run / key.source}")
        out[key.column], out[f"{key.column}_t_s"] = value, t
    out["wall_time_s"] = float(summary["wall_time_s"])
    out["dofs"] = int(summary["dofs"])
    return out


def read_key(key: KeyOutput, table: dict, end: float, where: str) -> tuple[float, float]:
    """(value, time read at) of `key` from its file's table; `end`: the run's end time."""
    if key.name not in table:
        raise InputError(where, f"has no column {key.name!r} (a 3D run?): the key outputs are "
                         "defined for plane-strain runs.", "use a 2D scene.")
    t, v = np.asarray(table["time_s"], dtype=float), np.asarray(table[key.name], dtype=float)
    rows = np.ones(len(t), dtype=bool)
    if key.depth_mm is not None:
        rows = np.isclose(table["depth_mm"], key.depth_mm)
        if not rows.any():
            written = sorted({float(d) for d in table["depth_mm"]})
            raise InputError(where, f"no depth curve at {key.depth_mm:g} mm (written: "
                             f"{', '.join(f'{d:g}' for d in written)} mm): {key.column} "
                             "cannot be read.", f"run with {key.depth_mm:g} among output.depths.")
    if key.time == END_OF_RUN:
        rows &= np.isclose(t, end, rtol=1e-9, atol=1e-9)
        if not rows.any():
            written = sorted({float(x) for x in t})
            raise InputError(where, f"nothing written at the end of the run, t = {end:g} s "
                             f"(written: {', '.join(f'{x:g}' for x in written)} s): "
                             f"{key.column} cannot be read.",
                             f"run with {end:g} among output.times.")
    if key.x_mm is not None:
        x, w = np.asarray(table["x_mm"])[rows], v[rows]
        order = np.argsort(x)
        value = 0.5 * (np.interp(key.x_mm, x[order], w[order])
                       + np.interp(-key.x_mm, x[order], w[order]))
        return float(value), end
    if key.time == END_OF_RUN:
        return float(v[rows][-1]), end
    t, v = t[rows], v[rows]
    if not np.isfinite(v).any():
        return math.nan, math.nan
    i = int(np.nanargmax(v))
    return float(v[i]), float(t[i])


def _summary(run: Path) -> dict:
    path = run / "summary.json"
    if not path.is_file():
        raise InputError(str(run), "holds no finished run (no summary.json): no key outputs.",
                         "run the scene into it first.")
    summary = json.loads(path.read_text())
    if summary.get("converged") is False:
        raise InputError(str(path), f"the run stopped at t = {summary.get('end_time_s')} s "
                         "without reaching its end: its key outputs do not exist.",
                         "rerun it (see its 'failure').")
    return summary


def _table(run: Path, name: str) -> dict:
    if not (run / name).is_file():
        raise InputError(str(run), f"has no {name}: the key outputs cannot be read.",
                         "give the directory of a finished 2D run.")
    return read_csv(run / name)


def relative_errors(values: dict, reference: dict, where: str = "reference") -> dict[str, float]:
    """|value - reference| / |reference| per key output; InputError if the reference lacks
    one (a record written before the key outputs were named by quantity, unit and time)."""
    missing = [k for k in KEYS if k not in reference]
    if missing:
        raise InputError(where, f"has no key output {missing[0]!r} (its keys: "
                         f"{', '.join(list(reference)[:3])}, ...).",
                         "score against a record written by this version (rerun the study).")
    return {k: abs(values[k] - reference[k]) / max(abs(reference[k]), 1e-300) for k in KEYS}
