"""One run of a scene: build the mesh and the problem, step it, write everything as it goes.

Per accepted step: a row of history.csv, the fields for ParaView (VTX, every `field_every`
steps and at output times) and a checkpoint (one .npz per rank) from which `--resume`
continues. At output times: the pulp-surface deflection, the depth profiles, the fields as
arrays (`fields_t<t>s.npz`) and their pictures. At the end (or at a failure): summary.json and
the figures. `run_scene` returns a `Result` (result.py) that holds all of it as arrays.
With `output.receptors`, every step also adds the receptor sites' rows to receptors.csv.
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from pathlib import Path

import numpy as np
from mpi4py import MPI

from .errors import ConvergenceError, InputError
from .figures import plot_depth_profiles, plot_force_history, plot_surface_profiles
from .mesh import build_mesh, write_xdmf
from .outputs import (
    DEPTH_COLUMNS,
    HISTORY_COLUMNS,
    SURFACE_COLUMNS,
    Checkpoint,
    CsvLog,
    FieldWriters,
    prepare_directory,
    read_csv,
    run_summary,
    write_json,
)
from .pictures import field_pictures
from .post import DerivedFields, FieldArrays, Profiles
from .problem import FingertipProblem
from .receptors import ReceptorRecorder, load_receptors
from .result import Result
from .scene import Scene, scene_record
from .solver import TimeStepper


class NoContactWarning(UserWarning):
    """A run whose indenters never pressed on the skin (zero force throughout)."""


def run(scene: Scene, out: str | Path, *, resume: bool = False, progress: bool = True,
        comm: MPI.Comm | None = None) -> Result:
    """Run `scene`, writing into `out` as it goes, and return its results as arrays.

    A failed step (after all cuts) raises `ConvergenceError` once everything up to the last
    good step is written (summary.json says `"converged": false` and why).
    """
    run_scene(scene, out, resume=resume, progress=progress, comm=comm)
    return Result(Path(out))


def run_scene(scene: Scene, out: str | Path, *, resume: bool = False, progress: bool = True,
              comm: MPI.Comm | None = None) -> dict:
    """`run`, returning the summary (summary.json's content) instead of a Result."""
    comm = comm or MPI.COMM_WORLD
    job = Run(scene, Path(out), comm, resume=resume, progress=progress)
    started = time.perf_counter()
    failed = None
    try:
        job.run()
    except ConvergenceError as error:  # CompactionError too: its type reaches the caller
        failed = error
    summary = job.finish(failed is None, None if failed is None else str(failed),
                         time.perf_counter() - started)
    if failed is not None:
        raise failed
    return summary


def run_side_by_side(jobs: list[tuple[Scene, Path]], progress: bool = True) -> None:
    """Run several scenes, each into its own directory; under `mpiexec -n N` they run side by
    side, one group of ranks each (N groups at most). Every rank returns when all are done."""
    world = MPI.COMM_WORLD
    groups = max(1, min(world.size, len(jobs)))
    colour = world.rank % groups
    comm = world.Split(colour, world.rank)
    try:
        for i, (scene, out) in enumerate(jobs):
            if i % groups == colour:
                run_scene(scene, out, progress=progress and comm.rank == 0, comm=comm)
    finally:
        world.barrier()
        comm.Free()


class Run:
    """Build, step, resume: one scene run into the directory `out`."""

    def __init__(self, scene: Scene, out: Path, comm: MPI.Comm, *, resume: bool,
                 progress: bool):
        self.scene, self.comm, self.progress = scene, comm, progress
        receptors = load_receptors(scene.outputs.receptors) if scene.outputs.receptors else None
        self.out = prepare_directory(out, comm)
        self.fm = build_mesh(scene.section, comm)
        if not resume:
            write_xdmf(self.fm, self.out / "mesh.xdmf")
        self.problem = FingertipProblem(self.fm, scene.indenters, scene.history,
                                        scene.materials, scene.model)
        check_reach(self.problem, scene)
        self.checkpoint = Checkpoint(self.out, comm)
        self.start_time, self.steps_before, self.previous = 0.0, 0, None
        steps = scene.steps
        if resume:
            steps = self._resume()
        self.stepper = TimeStepper(self.problem, steps, scene.petsc_options,
                                   linear=scene.linear)
        self.dofs = sum(f.function_space.dofmap.index_map.size_global
                        * f.function_space.dofmap.index_map_bs for f in self.problem.unknowns)
        after = self.start_time if resume else None
        self.history = CsvLog(self.out / "history.csv", HISTORY_COLUMNS, comm, after)
        self.surface = CsvLog(self.out / "surface_profile.csv", SURFACE_COLUMNS, comm, after)
        self.depth = CsvLog(self.out / "depth_profiles.csv", DEPTH_COLUMNS, comm, after)
        self.derived = DerivedFields(self.problem.u, self.fm.cell_tags,
                                     self.problem.region_energies())
        self.profiles = Profiles(self.problem, self.derived, scene.section.outer, scene.outputs)
        self.arrays = FieldArrays(self.problem, self.derived)
        self.receptors = None if receptors is None else ReceptorRecorder(
            self.problem, self.derived, receptors, scene.section.outer, self.out, comm, after)
        self.fields = FieldWriters(self.out, comm, self._vtx_fields(),
                                   suffix=f"-from-{self.start_time:g}s" if resume else "")
        self._last_state = (self.start_time, [f.x.array.copy() for f in self.problem.unknowns])
        self.step_count = self.steps_before
        self._bar = None

    # --- set-up ----------------------------------------------------------------------------
    def _resume(self):
        """Load the checkpoint; returns the step options that continue with its step size."""
        p = self.problem
        state = self.checkpoint.load(p.state_arrays(), len(p.unknowns))
        for f in p.unknowns:
            f.x.scatter_forward()
        p.mark_accepted()
        p.set_time(state.time)
        self.start_time, self.steps_before, self.previous = state.time, state.steps, state.previous
        steps = self.scene.steps
        return dataclasses.replace(steps, dt_initial=min(max(state.dt, steps.dt_min),
                                                         steps.dt_max))

    def _vtx_fields(self) -> dict:
        p = self.problem
        fields = {"displacement": p.u, "log_strain": self.derived.log_strain,
                  "strain_energy_density": self.derived.sed}
        if p.p is not None:
            fields["pore_pressure"] = p.p
        return fields

    # --- stepping --------------------------------------------------------------------------
    def run(self) -> None:
        scene = self.scene
        end = scene.history.end_time
        if self.start_time >= end - 1e-12:
            return
        from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

        columns = (TextColumn("{task.description}"), BarColumn(),
                   TextColumn("t = {task.completed:.3g} / {task.total:g} s"),
                   TimeElapsedColumn(), TextColumn("{task.fields[status]}"))
        show = self.progress and self.comm.rank == 0
        with Progress(*columns, disable=not show, transient=False) as bar:
            self._bar = (bar, bar.add_task(scene.name, total=end, completed=self.start_time,
                                           status=""))
            self.stepper.run(scene.history, end, start_time=self.start_time,
                             breakpoints=scene.output_times, on_step=self.on_step,
                             previous=self.previous)

    def on_step(self, report) -> None:
        """Write what the accepted step produced (its state is the converged one)."""
        self.step_count += 1
        d = report.diagnostics
        self.history.write([{
            "time_s": report.time, "indenter_displacement_mm": report.load,
            "force_N_per_mm": d["force_N_per_mm"], "newton_iterations": report.newton_iterations,
            "dt_s": report.dt, "reaction_N_per_mm": d["reaction_N_per_mm"],
            "max_penetration_mm": d["max_penetration_mm"], "min_J": d["min_J"],
            "cuts": report.cuts, "wall_time_s": report.wall_time_s}])
        at_output = any(abs(report.time - t) < 1e-9 for t in self.scene.output_times)
        if at_output or self.step_count % self.scene.field_every == 0:
            self.derived.update()
            self.fields.write(report.time)
        if at_output:
            self._write_output_time(report.time)
        if self.receptors is not None:
            self.receptors.write(report.time)
        self._save_checkpoint(report)
        self._show(report)

    def _write_output_time(self, t: float) -> None:
        self.surface.write(self.profiles.surface_rows(t))
        self.depth.write(self.profiles.depth_rows(t))
        arrays = self.arrays()  # updates the derived fields
        if self.comm.rank == 0:
            np.savez_compressed(self.out / f"fields_t{t:g}s.npz", time=t, **arrays)
        if self.scene.outputs.pictures:
            field_pictures(self.problem, self.derived, self.out, t, self.scene.name)

    def _save_checkpoint(self, report) -> None:
        self.checkpoint.save(report.time, report.next_dt, self.step_count,
                             self.problem.state_arrays(), self._last_state)
        self._last_state = (report.time, [f.x.array.copy() for f in self.problem.unknowns])

    def _show(self, report) -> None:
        if self._bar is None:
            return
        bar, task = self._bar
        d = report.diagnostics
        bar.update(task, completed=report.time, status=(
            f"F = {d['force_N_per_mm']:.4g} N/mm, {report.newton_iterations} its, "
            f"Δt = {report.dt:.3g} s, pen. {1e3 * d['max_penetration_mm']:.2g} µm"))

    # --- the end ---------------------------------------------------------------------------
    def finish(self, converged: bool, failure: str | None, wall: float) -> dict:
        """Close every file, write summary.json and draw the figures; returns the summary."""
        for log in (self.history, self.surface, self.depth, self.receptors):
            if log is not None:
                log.close()
        self.fields.close()
        self.stepper.close()
        self.comm.barrier()
        summary = None
        if self.comm.rank == 0:
            summary = run_summary(self.out, scene_record(self.scene), self.fm.report, self.dofs,
                                  self.comm.size, converged=converged, failure=failure,
                                  wall=wall, output_times=self.scene.output_times)
            if self.scene.outputs.pictures:
                _figures(self.out, self.scene.name)
        summary = self.comm.bcast(summary, root=0)
        write_json(self.out / "summary.json", summary, self.comm)
        if converged and summary["peak_force_N_per_mm"] is not None and not (
                summary["peak_force_N_per_mm"] > 0):
            warnings.warn(f"{self.scene.name}: the indenters never pressed on the skin (peak "
                          f"force {summary['peak_force_N_per_mm']:g} N/mm).", NoContactWarning,
                          stacklevel=2)
        return summary


def check_reach(problem, scene: Scene) -> None:
    """Every indenter must touch the skin before the protocol's deepest indentation.

    The indenters move together; the first touch sets the zero of the indentation. An
    indenter placed off the pulp (or far beside a sharper one) may never reach the surface:
    that run would end with a force from the others only, or none, and say nothing.
    """
    X, _ = problem.pulp_nodes()
    points = np.concatenate(problem.mesh.comm.allgather(X))
    y_deepest = problem.y_touch + scene.history.deepest
    for i, indenter in enumerate(scene.indenters):
        clearance = float(np.min(indenter.signed_distance_np(points, y_deepest)[0]))
        if clearance > 0:
            raise InputError(
                f"{scene.name}: indenters[{i}] ({indenter.shape} at x = {indenter.centre_x:g} mm)",
                f"never reaches the skin: at the deepest indentation ({scene.history.deepest:g} "
                f"mm) it is still {clearance:.3g} mm away from the pulp surface.",
                "move it under the pulp (|x| well inside the section's half-width "
                f"{scene.section.outer.a:g} mm) or indent deeper.")


def _figures(out: Path, name: str) -> None:
    """The curves of the run, from its own CSV files (rank 0)."""
    h = read_csv(out / "history.csv")
    if h:
        plot_force_history(h, out / "force_history.png", title=name)
    s = read_csv(out / "surface_profile.csv")
    if s:
        plot_surface_profiles(s, out / "surface_profile.png", title=name)
    d = read_csv(out / "depth_profiles.csv")
    if d:
        for t in np.unique(d["time_s"]):
            plot_depth_profiles(d, out / f"depth_profiles_t{t:g}s.png", t, title=name)
