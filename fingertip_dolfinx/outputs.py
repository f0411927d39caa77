"""The files of a run: CSV tables written row by row, the summary, checkpoints, field arrays.

Everything is written as the run goes (rank 0 writes the tables; every rank its checkpoint),
so an interrupted run loses nothing and `--resume` continues from the last checkpoint. Every
file is written whole or not at all (`whole`: a temporary name, then a rename), so a crash or a
kill never leaves half a file; CSV rows are appended and flushed one by one. The checkpoint
keeps the scene's record (`checkpoint/scene.json`), and `check_resume` says what a resumed
scene may not change. The figures are drawn elsewhere (`figures.py`, `fieldplots.py`).
"""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI

from .errors import InputError, on_root
from .loading import history_from_dict

#: The columns of the result files (stable names: other tools read them).
HISTORY_COLUMNS = ("time_s", "indenter_displacement_mm", "force_N_per_mm", "newton_iterations",
                   "dt_s", "reaction_N_per_mm", "max_penetration_mm", "min_J", "cuts",
                   "wall_time_s", "krylov_iterations")
SURFACE_COLUMNS = ("x_mm", "time_s", "deflection_mm")
#: With friction (2D): the columns surface_profile.csv gains and stick_slip.csv (every step)
#: has: the contact pressure, the tangential traction along the surface (+x under the
#: indenter), the stick margin μp − |q| and the contact state (`CONTACT_STATES`).
FRICTION_SURFACE_COLUMNS = ("pressure_MPa", "tangential_traction_MPa", "stick_margin_MPa",
                            "contact_state")
STICK_SLIP_COLUMNS = ("x_mm", "time_s") + FRICTION_SURFACE_COLUMNS
#: contact_state's codes: out of contact (p = 0), slipping (p > 0, margin <= 0), sticking
#: (margin > 0, which needs p > 0).
CONTACT_STATES = {0: "free", 1: "slip", 2: "stick"}
#: A 3D run's: forces in N (a half model's are its own half: summary.json's `mirror_factor`
#: gives the whole finger's), profiles across and along the finger, f(z) per unit length.
HISTORY_COLUMNS_3D = tuple({"force_N_per_mm": "force_N", "reaction_N_per_mm": "reaction_N"}
                           .get(c, c) for c in HISTORY_COLUMNS)
SURFACE_COLUMNS_3D = ("x_mm", "z_mm", "time_s", "deflection_mm")  # surface_across/along.csv
#: With friction (3D): the columns surface_across/along.csv gain and stick_slip.csv (every
#: step, along the finger on the line x = x_c of surface_along.csv) has: the contact pressure,
#: the tangential traction's x, y and z parts (on the body, MPa nominal; tangent to the
#: indenter), the stick margin μp − |q| and the contact state (`CONTACT_STATES`).
FRICTION_SURFACE_COLUMNS_3D = ("pressure_MPa", "tangential_traction_x_MPa",
                               "tangential_traction_y_MPa", "tangential_traction_z_MPa",
                               "stick_margin_MPa", "contact_state")
STICK_SLIP_COLUMNS_3D = ("x_mm", "z_mm", "time_s") + FRICTION_SURFACE_COLUMNS_3D
DEPTH_COLUMNS_3D = ("x_mm", "z_mm", "depth_mm", "time_s", "u1_mm", "u2_mm", "u3_mm", "e11",
                    "e22", "e33", "e12", "e_max", "e_min", "sed_MPa", "p_MPa")
LINE_FORCE_COLUMNS = ("z_mm", "time_s", "force_per_length_N_per_mm")
DEPTH_COLUMNS = ("x_mm", "depth_mm", "time_s", "u1_mm", "u2_mm", "e11", "e22", "e12", "e_max",
                 "e_min", "sed_MPa", "p_MPa")


@contextmanager
def whole(path: Path) -> Iterator[Path]:
    """A temporary name beside `path` (same folder, same suffix, so writers that go by the
    suffix still work) to write the file to; it becomes `path` by one rename once written, so
    a reader, a resumed run or a crash never meets half a file. Nothing is renamed where
    nothing was written (the ranks that do not write); on an error the half file is removed."""
    path = Path(path)
    tmp = path.with_name(f"{path.stem}.tmp{path.suffix}")
    try:
        yield tmp
        if tmp.exists():
            os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


@contextmanager
def whole_files(out: Path, name: str, comm: MPI.Comm) -> Iterator[Path]:
    """A temporary folder `out/<name>.tmp/` for writers that name their own files (several at
    once, as XDMF's .xdmf + .h5): once every rank is done, rank 0 moves each file into `out`
    (one rename each) and removes the folder."""
    tmp = Path(out) / f"{name}.tmp"
    if comm.rank == 0:
        tmp.mkdir(exist_ok=True)
    comm.barrier()
    try:
        yield tmp
        comm.barrier()
        if comm.rank == 0:
            for f in sorted(tmp.iterdir()):
                os.replace(f, Path(out) / f.name)
    finally:
        if comm.rank == 0:
            shutil.rmtree(tmp, ignore_errors=True)


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


#: What a run writes that a later run in the same folder might not overwrite: files named by
#: output time, the figures, the summary, the receptor table, the spike trains and the fields
#: of older versions.
RUN_OUTPUTS = ("summary.json", "fields_t*s.npz", "*_t*s.png", "force_history.png",
               "surface_profile.png", "surface_across.png", "surface_along.png",
               "line_force.png", "receptors.csv", "*-from-*s.bp", "spikes.csv",
               "afferents.csv", "rates.npz", "population.png", "stick_slip.csv",
               "friction.png")


def clear_earlier_run(out: Path, comm: MPI.Comm) -> None:
    """A fresh run into a folder that holds an earlier one: remove the earlier run's files
    that this run may not rewrite (a picture at a time it does not reach, its summary.json
    until this run writes its own), so that no file in the folder belongs to another run.
    Only the run's own file names go; anything else in the folder stays."""
    remove_outputs(out, RUN_OUTPUTS, comm)


def remove_outputs(out: Path, patterns, comm: MPI.Comm) -> None:
    """Remove the files and folders in `out` named by the glob `patterns` (on rank 0; every
    rank returns once they are gone): an earlier run's or sweep's own outputs, before a new
    one writes its own, so that none is left describing another experiment."""
    if comm.rank == 0:
        for pattern in patterns:
            for path in Path(out).glob(pattern):
                if path.is_dir():
                    shutil.rmtree(path, ignore_errors=True)
                else:
                    path.unlink(missing_ok=True)
    comm.barrier()


class CsvLog:
    """A CSV file written row by row on rank 0 (flushed, so a crash loses nothing). The header
    and, on a resume, the rows kept are written whole (`whole`); rows are then appended."""

    def __init__(self, path: Path, columns: Sequence[str], comm: MPI.Comm, resume_after=None):
        self.comm, self.columns, self.path = comm, tuple(columns), path
        self._file = None
        if comm.rank != 0:
            return
        rows = []
        if resume_after is not None and path.exists():
            # Keep the whole rows up to the checkpoint; later ones are recomputed.
            with path.open() as f:
                rows = [r for r in csv.DictReader(f) if None not in r.values()
                        and float(r["time_s"]) <= resume_after + 1e-12]
        with whole(path) as tmp, tmp.open("w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=self.columns)
            writer.writeheader()
            writer.writerows(rows)
        self._file = path.open("a", newline="")
        self._writer = csv.DictWriter(self._file, fieldnames=self.columns)

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
    """`data` as JSON into `path`, written whole by rank 0; every rank of `comm` calls it and
    returns once the file is there, or raises if rank 0 could not write it (`on_root`)."""
    def write() -> None:
        with whole(path) as tmp:
            tmp.write_text(json.dumps(data, indent=2, default=_jsonable) + "\n")

    on_root(comm, write)


def save_npz(path: Path, **arrays) -> None:
    """Arrays into a compressed .npz, written whole (the caller's rank only)."""
    with whole(path) as tmp, tmp.open("wb") as f:
        np.savez_compressed(f, **arrays)


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
    """One .npz per rank in `out/checkpoint/`, replaced atomically after every step, and the
    scene's record `scene.json` beside them, written when the run starts: a resume is
    checked against it (`check_resume`), so the files never mix two experiments.

    Each rank replaces its own file, so a kill without a clean stop (a second Ctrl-C, SIGKILL
    after a batch system's grace time) can land when some ranks hold step n + 1 and others
    step n; resuming from such files would mix two states (measured: the ranks then wait on
    each other for ever). Each rank therefore keeps its step before as `rank<r>.previous.npz`,
    and a resume continues from the latest step that every rank holds (`common_time`)."""

    def __init__(self, out: Path, comm: MPI.Comm):
        self.out, self.comm = Path(out), comm
        self.folder = self.out / "checkpoint"
        self.path = self.folder / f"rank{comm.rank}.npz"
        self.previous = self.folder / f"rank{comm.rank}.previous.npz"

    def start(self, record: dict) -> None:
        """A fresh run: the checkpoints of an earlier run in this folder go, the record of
        this one is written (a kill before the first step leaves nothing to resume)."""
        if self.comm.rank == 0:
            for old in self.folder.glob("rank*.npz"):
                old.unlink()
            shutil.rmtree(self.folder / "fields", ignore_errors=True)
        self.remember(record)

    def remember(self, record: dict) -> None:
        """The record the checkpoints belong to (after a resume: the resumed scene's)."""
        write_json(self.folder / "scene.json", record, self.comm)
        self.comm.barrier()

    def stored(self) -> tuple[dict, float]:
        """(the record of the run in `out`, the time of the latest checkpoint that every rank
        holds); every rank."""
        where = f"--resume {self.out}"
        held = self.comm.allgather(list(self._held().values()))
        t, found = common_time(held), None
        if self.comm.rank == 0:
            record, state = self.folder / "scene.json", self.folder / "rank0.npz"
            if not any(held):
                found = state
            elif not record.exists():
                found = record
            else:
                found = json.loads(record.read_text())
        found = self.comm.bcast(found, root=0)
        if isinstance(found, Path):
            older = " (a run older than the record kept)" if found.name == "scene.json" else ""
            raise InputError(where, f"there is no checkpoint to resume from ({found} is "
                             f"missing{older}).", "run without --resume to start afresh.")
        ranks = sum(1 for times in held if times)
        if t is None and ranks < self.comm.size:
            raise InputError(where, f"only {ranks} of the {self.comm.size} ranks have a "
                             f"checkpoint in {self.folder}.",
                             f"resume with mpiexec -n {ranks} (the ranks the run was made on).")
        if t is None:
            raise InputError(where, f"the ranks' checkpoints in {self.folder} hold no step in "
                             "common (a kill while they were written).",
                             "run without --resume to start afresh.")
        return found, t

    def _held(self) -> dict[Path, float]:
        """This rank's checkpoint files and their times (the last step's, the one before)."""
        held = {}
        for path in (self.path, self.previous):
            if path.exists():
                with np.load(path) as data:
                    held[path] = float(data["time"])
        return held

    def save(self, time: float, dt: float, steps: int, state: dict[str, np.ndarray],
             previous: tuple[float, list[np.ndarray]]) -> None:
        previous_time, arrays = previous
        with whole(self.path) as tmp:
            with tmp.open("wb") as f:
                np.savez(f, time=time, dt=dt, steps=steps, ranks=self.comm.size,
                         previous_time=previous_time, **state,
                         **{f"previous_{i}": a for i, a in enumerate(arrays)})
            if self.path.exists():  # kept until this step's file is whole on every rank
                os.replace(self.path, self.previous)

    def load(self, state: dict[str, np.ndarray], n_unknowns: int) -> CheckpointState:
        """Fill the arrays of `state` in place; a checkpoint of another run is refused."""
        where = f"--resume {self.out}"
        held = self._held()
        t = common_time(self.comm.allgather(list(held.values())))
        path = next((p for p, s in held.items() if t is not None and abs(s - t) <= 1e-12), None)
        if path is None:
            raise InputError(where, f"there is no checkpoint to resume from ({self.path}).",
                             "run without --resume to start afresh.")
        with np.load(path) as data:  # closed after reading, on every path
            if int(data["ranks"]) != self.comm.size:
                raise InputError(where, f"the run was made on {int(data['ranks'])} ranks, this "
                                 f"one has {self.comm.size}.",
                                 f"resume with mpiexec -n {int(data['ranks'])}.")
            for name, array in state.items():
                if name not in data or data[name].shape != array.shape:
                    raise InputError(where, "the checkpoint does not fit this scene's model "
                                     f"({name}).",
                                     "resume with the same scene and options, or start afresh.")
                array[:] = data[name]
            previous = (float(data["previous_time"]),
                        [data[f"previous_{i}"] for i in range(n_unknowns)])
            return CheckpointState(float(data["time"]), float(data["dt"]), int(data["steps"]),
                                   previous)


def common_time(held: list[list[float]]) -> float | None:
    """The latest checkpoint time that every rank holds (`held`: each rank's times), or None."""
    shared = [t for t in held[0] if all(any(abs(t - s) <= 1e-12 for s in times)
                                        for times in held[1:])]
    return max(shared, default=None)


#: Keys a resumed scene may change freely: what is drawn and how often fields are written,
#: never what is computed. The protocol and the output times follow `check_resume`'s rules.
FREE_ON_RESUME = ("description", "output.pictures", "output.fields", "output.field_every")


def check_resume(old: dict, new: dict, t: float, out: Path, changes=()) -> None:
    """Refuse to continue the run in `out`, checkpointed at `t` with the scene record `old`,
    with a scene (record `new`) that would mix two experiments: every key must be the same but
    FREE_ON_RESUME, the protocol where it leaves the load d(t) on [0, t] and its kinks before t
    as they were (a later end time, more cycles, points after t), and the output times after t
    (the ones up to t are written: they must stay)."""
    old, new = (json.loads(json.dumps(r, default=_jsonable)) for r in (old, new))
    for key, a, b in _differences(old, new):
        if key in FREE_ON_RESUME or (key.startswith("protocol.")
                                     and _same_load(old["protocol"], new["protocol"], t)):
            continue
        fix = f"start a new --out, or resume without --set {key}=... (or with {key} = {a!r})"
        if not any(key == k or key.startswith(f"{k}.") for k in _override_keys(changes)):
            fix = (f"start a new --out, or put {key} = {a!r} back where this scene takes it "
                   "from (the scene file, or the materials, section or indenter file it "
                   "names), as the run had it")
        if key == "output.times":
            written = [x for x in a if x <= t + 1e-12]
            asked = [x for x in b if x <= t + 1e-12]
            if written == asked:
                continue
            fix = (f"keep the output times up to {t:g} s as they were, {written} (the run is "
                   f"past them: {sorted(set(asked) - set(written)) or 'none'} cannot be "
                   f"written now, {sorted(set(written) - set(asked)) or 'none'} are written "
                   f"already); times after {t:g} s may be added or dropped. Or start a new "
                   "--out")
        raise InputError(f"--resume {out}: {key}", f"the run there was computed to t = {t:g} s "
                         f"with {key} = {_shown(a)}; this scene has {_shown(b)}. Resuming would "
                         f"mix two experiments (the record: {out}/checkpoint/scene.json).", fix)


def _override_keys(changes) -> list[str]:
    """The keys the overrides (`Scene.changes`: `--set`, `--config`, Python) set."""
    return [str(text).partition("=")[0].strip() for text in changes]


def _shown(value) -> str:
    return "(absent)" if value is _ABSENT else json.dumps(value)


_ABSENT = object()


def _differences(old: dict, new: dict) -> list[tuple[str, object, object]]:
    """(key path, old value, new value) of every leaf that differs; lists of numbers are
    leaves, lists of tables (indenters) are entered by index."""
    a, b = _leaves(old), _leaves(new)
    return [(k, a.get(k, _ABSENT), b.get(k, _ABSENT)) for k in dict.fromkeys([*a, *b])
            if a.get(k, _ABSENT) != b.get(k, _ABSENT)]


def _leaves(node, prefix: str = "") -> dict:
    if isinstance(node, dict):
        items = node.items()
    elif isinstance(node, list) and any(isinstance(v, dict | list) for v in node):
        items = enumerate(node)
    else:
        return {prefix.rstrip("."): node}
    out = {}
    for key, value in items:
        out |= _leaves(value, f"{prefix}{key}.")
    return out


def _same_load(old: dict, new: dict, t: float) -> bool:
    """Do two protocols (records) prescribe the same d(s) for s <= t, with the same kinks
    before t (where the steps landed), and the same force control (its start and tolerance,
    and its target for s <= t)? Then what was computed up to t is what the new one would
    compute."""
    a, b = (history_from_dict(dict(p)) for p in (old, new))
    kinks = [[m for m in h.breakpoints if m < t - 1e-12] for h in (a, b)]
    if len(kinks[0]) != len(kinks[1]) or not np.allclose(*kinks, rtol=0, atol=1e-12):
        return False
    if _force_control(a) != _force_control(b):
        return False
    s = np.union1d(np.linspace(0.0, t, 1001), [*kinks[0], t])
    same = True
    # the indentation, the path along x and z, and the target force (0 without one)
    for path in (lambda h, x: h(x), _tangential_at, _force_at):
        da, db = (np.array([path(h, x) for x in s]) for h in (a, b))
        same = same and bool(np.allclose(da, db, rtol=1e-12, atol=1e-15))
    return same


def _force_control(history) -> tuple[float, float] | None:
    """A force-controlled protocol's (start, rtol); None without force control."""
    force = getattr(history, "normal_force", None)
    return None if force is None else (force.start, force.rtol)


def _force_at(history, t: float) -> float:
    """The target normal force at t (N/mm; 0 without force control)."""
    force = getattr(history, "normal_force", None)
    return 0.0 if force is None else force(t)


def _tangential_at(history, t: float) -> tuple[float, float]:
    """The indenters' tangential displacement (x, z) at t (mm; 0 for a protocol without one)."""
    return history.displacement_at(t) if hasattr(history, "displacement_at") else (0.0, 0.0)


class FieldWriters:
    """Fields over time for ParaView: one VTX (ADIOS2) file per field, `<name>.bp`, which keeps
    P2 displacements exact (XDMF would need P1).

    DOLFINx's VTX writer cannot append to a series, so each time written is also kept in the
    checkpoint (`checkpoint/fields/rank<r>_<k>.npz`: the functions' own arrays on this rank).
    A resumed run (`resume_after`: the checkpoint's time) writes the series again from them up
    to its checkpoint and continues it: one time line per field, as if never interrupted."""

    def __init__(self, out: Path, comm: MPI.Comm, fields: dict, resume_after: float | None = None):
        from dolfinx import io

        self.fields, self.rank = fields, comm.rank
        self.store = Path(out) / "checkpoint" / "fields"
        self.store.mkdir(parents=True, exist_ok=True)
        kept = self._kept(resume_after)
        self.writers = [io.VTXWriter(comm, Path(out) / f"{name}.bp", [f], engine="BP4")
                        for name, f in fields.items()]
        self.count = 0
        self._replay(kept)

    def _kept(self, resume_after: float | None) -> list[Path]:
        """This rank's stored times up to the checkpoint (none for a fresh run); the later
        ones (written after the last checkpoint) are removed: they are computed again."""
        kept = []
        for path in sorted(self.store.glob(f"rank{self.rank}_*.npz")):
            if resume_after is not None:
                with np.load(path) as data:
                    if float(data["time"]) <= resume_after + 1e-12:
                        kept.append(path)
                        continue
            path.unlink()
        return kept

    def _replay(self, kept: list[Path]) -> None:
        """Write the stored times again, then put the functions' arrays back."""
        now = {name: f.x.array.copy() for name, f in self.fields.items()}
        for path in kept:
            with np.load(path) as data:
                for name, f in self.fields.items():
                    f.x.array[:] = data[name]
                for writer in self.writers:
                    writer.write(float(data["time"]))
            self.count += 1
        for name, f in self.fields.items():
            f.x.array[:] = now[name]

    def write(self, t: float) -> None:
        for writer in self.writers:
            writer.write(t)
        path = self.store / f"rank{self.rank}_{self.count:06d}.npz"
        with whole(path) as tmp, tmp.open("wb") as f:
            np.savez(f, time=t, **{name: g.x.array for name, g in self.fields.items()})
        self.count += 1

    def close(self) -> None:
        for writer in self.writers:
            writer.close()


def run_summary(out: Path, record: dict, mesh_report, dofs: int, ranks: int, *, converged: bool,
                failure: str | None, wall: float, output_times, mirror_factor: int = 1,
                status: str | None = None) -> dict:
    """summary.json's content, from the run's own history.csv and the scene's record.
    3D runs' forces are in N; a half model's are its half (`mirror_factor` 2: the whole's).
    `status`: "completed", "failed" (a step could not be solved) or "interrupted" (SIGINT or
    SIGTERM: stopped at a step boundary, `end_time_s` is the last time reached); `converged`
    is true for a completed run only."""
    import platform
    import time

    import dolfinx

    from .datafiles import package_version

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
        "versions": {"fingertip_dolfinx": package_version(), "dolfinx": dolfinx.__version__,
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
        "status": status or ("completed" if converged else "failed"),
        "converged": converged,
        "failure": failure,
        "end_time_s": float(times[-1]) if len(times) else 0.0,
        f"peak_force_{unit}": float(np.max(force)) if len(force) else None,
        "max_penetration_mm": float(np.max(h["max_penetration_mm"])) if len(times) else None,
        f"force_at_output_times_{unit}": forces_at,
        **({"mirror_factor": mirror_factor} if unit == "N" else {}),
        "written": time.strftime("%Y-%m-%dT%H:%M:%S"),
    }
