"""The files of a run: CSV tables written row by row, the summary, checkpoints, field arrays.

Everything is written as the run goes (rank 0 writes the tables; every rank its checkpoint),
so an interrupted run loses nothing and `--resume` continues from the last checkpoint. The
figures are drawn elsewhere (`figures.py`, `fieldplots.py`) from these files.
"""

from __future__ import annotations

import csv
import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI

from .errors import InputError

#: The columns of the result files (stable names: other tools read them).
HISTORY_COLUMNS = ("time_s", "indenter_displacement_mm", "force_N_per_mm", "newton_iterations",
                   "dt_s", "reaction_N_per_mm", "max_penetration_mm", "min_J", "cuts",
                   "wall_time_s", "krylov_iterations")
SURFACE_COLUMNS = ("x_mm", "time_s", "deflection_mm")
#: A 3D run's: forces in N (a half model's are its own half: summary.json's `mirror_factor`
#: gives the whole finger's), profiles across and along the finger, f(z) per unit length.
HISTORY_COLUMNS_3D = tuple({"force_N_per_mm": "force_N", "reaction_N_per_mm": "reaction_N"}
                           .get(c, c) for c in HISTORY_COLUMNS)
SURFACE_COLUMNS_3D = ("x_mm", "z_mm", "time_s", "deflection_mm")  # surface_across/along.csv
DEPTH_COLUMNS_3D = ("x_mm", "z_mm", "depth_mm", "time_s", "u1_mm", "u2_mm", "u3_mm", "e11",
                    "e22", "e33", "e12", "e_max", "e_min", "sed_MPa", "p_MPa")
LINE_FORCE_COLUMNS = ("z_mm", "time_s", "force_per_length_N_per_mm")
DEPTH_COLUMNS = ("x_mm", "depth_mm", "time_s", "u1_mm", "u2_mm", "e11", "e22", "e12", "e_max",
                 "e_min", "sed_MPa", "p_MPa")




def prepare_directory(out: Path, comm: MPI.Comm) -> Path:
    """Create the output directory (and its `checkpoint/`) or say why it cannot be."""
    out = Path(out)
    problem = None
    if comm.rank == 0:
        try:
            (out / "checkpoint").mkdir(parents=True, exist_ok=True)
            if not os.access(out, os.W_OK):
                problem = "is not writable"
        except OSError as error:
            problem = f"cannot be created ({error.strerror})"
    problem = comm.bcast(problem, root=0)
    if problem:
        raise InputError(f"--out {out}", f"the output directory {problem}.",
                         "choose a directory you can write to.")
    return out


class CsvLog:
    """A CSV file written row by row on rank 0 (flushed, so a crash loses nothing)."""

    def __init__(self, path: Path, columns: Sequence[str], comm: MPI.Comm, resume_after=None):
        self.comm, self.columns, self.path = comm, tuple(columns), path
        self._file = None
        if comm.rank != 0:
            return
        rows = []
        if resume_after is not None and path.exists():
            # Keep the rows up to the checkpoint; later ones are recomputed.
            with path.open() as f:
                rows = [r for r in csv.DictReader(f) if float(r["time_s"]) <= resume_after + 1e-12]
        self._file = path.open("w", newline="")
        self._writer = csv.DictWriter(self._file, fieldnames=self.columns)
        self._writer.writeheader()
        for r in rows:
            self._writer.writerow(r)
        self._file.flush()

    def write(self, rows: Sequence[dict]) -> None:
        if self._file is None:
            return
        for row in rows:
            self._writer.writerow({k: _fmt(row.get(k)) for k in self.columns})
        self._file.flush()

    def close(self) -> None:
        if self._file is not None:
            self._file.close()


def _fmt(value):
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    if isinstance(value, float | np.floating):
        return f"{value:.12g}"
    return value


def read_csv(path: Path) -> dict[str, np.ndarray]:
    """Columns of a result CSV as float arrays (empty cells become NaN)."""
    with Path(path).open() as f:
        rows = list(csv.DictReader(f))
    if not rows:
        return {}
    return {k: np.array([float(r[k]) if r[k] != "" else np.nan for r in rows]) for k in rows[0]}


def write_json(path: Path, data: dict, comm: MPI.Comm) -> None:
    if comm.rank == 0:
        tmp = path.with_suffix(".json.tmp")
        tmp.write_text(json.dumps(data, indent=2, default=_jsonable) + "\n")
        tmp.replace(path)  # atomic: readers never see half a file


def _jsonable(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {value!r}")


@dataclass
class CheckpointState:
    """What a checkpoint restores: the time, the planned step, the steps done, and the
    accepted state one step back (time, arrays) for the predictor."""

    time: float
    dt: float
    steps: int
    previous: tuple[float, list[np.ndarray]]


class Checkpoint:
    """One .npz per rank in `out/checkpoint/`, replaced atomically after every step."""

    def __init__(self, out: Path, comm: MPI.Comm):
        self.out, self.comm = Path(out), comm
        self.path = self.out / "checkpoint" / f"rank{comm.rank}.npz"

    def save(self, time: float, dt: float, steps: int, state: dict[str, np.ndarray],
             previous: tuple[float, list[np.ndarray]]) -> None:
        tmp = self.path.with_name(self.path.stem + ".tmp.npz")
        previous_time, arrays = previous
        np.savez(tmp, time=time, dt=dt, steps=steps, ranks=self.comm.size,
                 previous_time=previous_time, **state,
                 **{f"previous_{i}": a for i, a in enumerate(arrays)})
        tmp.replace(self.path)

    def load(self, state: dict[str, np.ndarray], n_unknowns: int) -> CheckpointState:
        """Fill the arrays of `state` in place; a checkpoint of another run is refused."""
        where = f"--resume {self.out}"
        if not self.path.exists():
            raise InputError(where, f"there is no checkpoint to resume from ({self.path}).",
                             "run without --resume to start afresh.")
        data = np.load(self.path)
        if int(data["ranks"]) != self.comm.size:
            raise InputError(where, f"the run was made on {int(data['ranks'])} ranks, this one "
                             f"has {self.comm.size}.", f"resume with mpiexec -n {int(data['ranks'])}.")
        for name, array in state.items():
            if name not in data or data[name].shape != array.shape:
                raise InputError(where, f"the checkpoint does not fit this scene's model ({name}).",
                                 "resume with the same scene and options, or start afresh.")
            array[:] = data[name]
        previous = (float(data["previous_time"]),
                    [data[f"previous_{i}"] for i in range(n_unknowns)])
        return CheckpointState(float(data["time"]), float(data["dt"]), int(data["steps"]),
                               previous)


class FieldWriters:
    """Fields over time for ParaView: one VTX (ADIOS2) file per field, `<name><suffix>.bp`,
    which keeps P2 displacements exact (XDMF would need P1)."""

    def __init__(self, out: Path, comm: MPI.Comm, fields: dict, suffix: str = ""):
        from dolfinx import io

        self.writers = [io.VTXWriter(comm, Path(out) / f"{name}{suffix}.bp", [f], engine="BP4")
                        for name, f in fields.items()]

    def write(self, t: float) -> None:
        for writer in self.writers:
            writer.write(t)

    def close(self) -> None:
        for writer in self.writers:
            writer.close()


def run_summary(out: Path, record: dict, mesh_report, dofs: int, ranks: int, *, converged: bool,
                failure: str | None, wall: float, output_times, mirror_factor: int = 1) -> dict:
    """summary.json's content, from the run's own history.csv and the scene's record.
    3D runs' forces are in N; a half model's are its half (`mirror_factor` 2: the whole's)."""
    import platform
    import time

    import dolfinx

    from . import __version__

    h = read_csv(Path(out) / "history.csv")
    times = h.get("time_s", np.zeros(0))
    unit = "N" if "force_N" in h else "N_per_mm"  # 3D: N; plane strain: N/mm
    force = h.get(f"force_{unit}", np.zeros(0))
    forces_at = {f"{t:g}": (float(np.interp(t, times, force))
                            if len(times) and t <= times[-1] + 1e-9 else None)
                 for t in output_times}
    r = mesh_report
    return {
        "scene": record["name"],
        "scene_data": record,
        "materials": record["materials"],
        "model": record["model"],
        "versions": {"fingertip_dolfinx": __version__, "dolfinx": dolfinx.__version__,
                     "python": platform.python_version()},
        "mpi_ranks": ranks,
        "mesh": {"cells": r.num_cells, "cell_type": r.cell_type, "min_edge_mm": r.min_edge,
                 "max_edge_mm": r.max_edge, "min_quality": r.min_quality},
        "dofs": dofs,
        "time_steps": len(times),
        "newton_iterations": int(np.nansum(h.get("newton_iterations", [0]))),
        # Krylov iterations (= Newton iterations with the direct solver; 0 in older runs).
        "krylov_iterations": int(np.nansum(h.get("krylov_iterations", [0]))),
        "wall_time_s": wall,
        "converged": converged,
        "failure": failure,
        "end_time_s": float(times[-1]) if len(times) else 0.0,
        f"peak_force_{unit}": float(np.max(force)) if len(force) else None,
        "max_penetration_mm": float(np.max(h["max_penetration_mm"])) if len(times) else None,
        f"force_at_output_times_{unit}": forces_at,
        **({"mirror_factor": mirror_factor} if unit == "N" else {}),
        "written": time.strftime("%Y-%m-%dT%H:%M:%S"),
    }
