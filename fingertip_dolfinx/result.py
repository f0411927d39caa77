"""The results of a run as arrays: what `run_scene` returns and `load_result(DIR)` reads back.

A `Result` reads the run's own files (summary.json, history.csv, surface_profile.csv,
depth_profiles.csv, fields_t<t>s.npz), so a finished, failed or resumed run, or one made on
another machine, is read the same way; nothing needs CSV parsing by hand.
"""

from __future__ import annotations

import csv
import json
from functools import cached_property
from pathlib import Path

import numpy as np

from .errors import InputError
from .outputs import read_csv


class Result:
    """A run's results in `out`.

    - `summary`: summary.json as a dict (scene, materials, model, mesh, dofs, steps, ...);
    - `history`: per accepted step, columns as arrays (`time_s`, `force_N_per_mm`, ...);
    - `surface`, `depth`: the profiles at the output times, columns as arrays;
    - `fields(t)`: the fields at output time t as arrays (see `post.FieldArrays`);
    - `receptors()`: the receptor sites' samples per step (receptors.csv), if the run wrote them;
    - shortcuts `time`, `force`, `surface_profile(t)`, `depth_profile(quantity, depth, t)`.
    """

    def __init__(self, out: str | Path):
        self.out = Path(out)
        if not (self.out / "history.csv").exists():
            raise InputError(str(self.out), "holds no run (no history.csv).",
                             "give the --out directory of a run.")

    def __repr__(self) -> str:
        s = self.summary
        return (f"Result({str(self.out)!r}: {s.get('scene')}, {s.get('time_steps')} steps, "
                f"peak force {s.get('peak_force_N_per_mm')} N/mm, converged {s.get('converged')})")

    @cached_property
    def summary(self) -> dict:
        return json.loads((self.out / "summary.json").read_text())

    @cached_property
    def history(self) -> dict[str, np.ndarray]:
        return read_csv(self.out / "history.csv")

    @cached_property
    def surface(self) -> dict[str, np.ndarray]:
        return _read_if_there(self.out / "surface_profile.csv")

    @cached_property
    def depth(self) -> dict[str, np.ndarray]:
        return _read_if_there(self.out / "depth_profiles.csv")

    @property
    def time(self) -> np.ndarray:
        return self.history["time_s"]

    @property
    def force(self) -> np.ndarray:
        """Indenter force per unit thickness (N/mm) at every accepted step."""
        return self.history["force_N_per_mm"]

    @property
    def output_times(self) -> list[float]:
        return sorted(float(t) for t in np.unique(self.depth.get("time_s", [])))

    def surface_profile(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(x, deflection) of the pulp surface at output time t (mm)."""
        rows = np.isclose(self.surface["time_s"], t)
        return self.surface["x_mm"][rows], self.surface["deflection_mm"][rows]

    def depth_profile(self, quantity: str, depth: float, t: float) -> tuple[np.ndarray, ...]:
        """(x, values) of a depth_profiles.csv column (`e11`, `sed_MPa`, ...) along the curve
        `depth` mm below the surface at output time t."""
        if quantity not in self.depth:
            raise InputError(f"quantity {quantity!r}", "is not a column of depth_profiles.csv.",
                             f"use one of {', '.join(self.depth)}.")
        at_depth = np.isclose(self.depth["depth_mm"], depth)
        if not at_depth.any():
            written = sorted(float(d) for d in np.unique(self.depth["depth_mm"]))
            raise InputError(f"depth {depth} mm", "was not written by this run.",
                             f"use a written depth, {written} mm (or run again with "
                             f"output.depths = [{depth}]).")
        rows = at_depth & np.isclose(self.depth["time_s"], t)
        if not rows.any():
            raise InputError(f"t = {t} s", "was not an output time of this run.",
                             f"use an output time, {self.output_times} s.")
        return self.depth["x_mm"][rows], self.depth[quantity][rows]

    def receptors(self) -> dict[str, np.ndarray]:
        """receptors.csv (a run with `output.receptors`) as columns: `time_s`, `class`
        (strings), `index` (integers), `x_mm`, `depth_mm`, `sed_MPa`, `e_min`, `sigma22_MPa`,
        `p_MPa`; one row per receptor per accepted step. Rates and spikes:
        `receptors.afferent_responses(result)`."""
        path = self.out / "receptors.csv"
        if not path.exists():
            raise InputError(str(self.out), "holds no receptors.csv.",
                             'run the scene with output.receptors = "default" (or a set).')
        return _read_table(path, text=("class",), integer=("index",))

    def fields(self, t: float) -> dict[str, np.ndarray]:
        """The fields at output time t, cell by cell (X, u, region, sed, log_strain, ...)."""
        path = self.out / f"fields_t{t:g}s.npz"
        if not path.exists():
            raise InputError(f"fields at t = {t:g} s", f"were not written ({path}).",
                             f"output times of this run: {self.output_times}.")
        with np.load(path) as data:
            return {k: data[k] for k in data.files}


def load_result(out: str | Path) -> Result:
    """The results of the run written into `out`."""
    return Result(out)


def _read_if_there(path: Path) -> dict[str, np.ndarray]:
    return read_csv(path) if path.exists() else {}


def _read_table(path: Path, text=(), integer=()) -> dict[str, np.ndarray]:
    """A CSV file's columns: those in `text` as strings, in `integer` as integers, the others
    as floats (empty cells NaN)."""
    with path.open() as f:
        rows = list(csv.DictReader(f))
    if not rows:
        return {}

    def column(k):
        values = [r[k] for r in rows]
        if k in text:
            return np.array(values)
        if k in integer:
            return np.array([int(v) for v in values])
        return np.array([float(v) if v != "" else np.nan for v in values])

    return {k: column(k) for k in rows[0]}
