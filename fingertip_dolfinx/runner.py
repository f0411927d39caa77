"""One run of a scene: build the mesh and the problem, step it, write everything as it goes.

Per accepted step: a row of history.csv, a checkpoint (one .npz per rank) from which
`--resume` continues, and with `output.fields = "every-step"` the fields for ParaView (VTX,
every `field_every` steps). At output times: the fields for ParaView, the pulp-surface
deflection, the depth profiles, the fields as arrays (`fields_t<t>s.npz`, 2D and 3D: what
`Result.fields` and `Result.to_pyvista` read) and, in 2D, their pictures.
At the end (or at a failure, or an interruption): summary.json and the figures. `run`
returns a `Result` (result.py) that holds all of it as arrays. With `output.receptors`, every
step also adds the receptor sites' rows to receptors.csv, and the end (or a failure, or an
interruption) writes every afferent's spike train (spikes.csv, afferents.csv, rates.npz) and
the population picture (population.png).

A resume is checked against the scene record kept with the checkpoint (`check_resume`).
SIGINT (Ctrl-C) and SIGTERM stop a run at the next step boundary, all ranks at the same one
(within a step, after the Newton iteration under way: the step is then not taken): its files
are closed, summary.json says `"status": "interrupted"`, and `RunInterrupted` (a
KeyboardInterrupt) is raised; the previous signal handlers are back in place when a run returns.
"""

from __future__ import annotations

import dataclasses
import json
import signal
import sys
import threading
import time
import warnings
from pathlib import Path
from typing import Self

import numpy as np
from mpi4py import MPI

from .afferents.receptors import (
    ReceptorRecorder,
    load_receptors,
    surface_sites,
    write_spike_files,
)
from .errors import ConvergenceError, InputError, RunInterrupted, SolveInterrupted, on_root
from .geometry.fingertip3d import Fingertip3D
from .geometry.mesh import build_mesh, write_xdmf
from .geometry.mesh3d import build_mesh3d
from .outputs import (
    DEPTH_COLUMNS,
    DEPTH_COLUMNS_3D,
    FRICTION_SURFACE_COLUMNS,
    FRICTION_SURFACE_COLUMNS_3D,
    HISTORY_COLUMNS,
    HISTORY_COLUMNS_3D,
    LINE_FORCE_COLUMNS,
    STICK_SLIP_COLUMNS,
    STICK_SLIP_COLUMNS_3D,
    SURFACE_COLUMNS,
    SURFACE_COLUMNS_3D,
    Checkpoint,
    CsvLog,
    FieldWriters,
    check_resume,
    clear_earlier_run,
    prepare_directory,
    read_csv,
    run_summary,
    save_npz,
    whole_files,
    write_json,
)
from .plotting.figures import (
    plot_depth_profiles,
    plot_force_history,
    plot_friction,
    plot_friction_3d,
    plot_line_force,
    plot_population,
    plot_surface_profiles,
)
from .plotting.pictures import field_pictures
from .post import DerivedFields, FieldArrays, Profiles, Profiles3D
from .problem import AREA_KEYS, FingertipProblem
from .result import Result
from .scene import Scene, scene_record
from .stepping.stepper import TimeStepper


class NoContactWarning(UserWarning):
    """A run whose indenters never pressed on the skin (zero force throughout)."""


def run(scene: Scene, out: str | Path, *, resume: bool = False, progress: bool = True,
        comm: MPI.Comm | None = None) -> Result:
    """Run `scene`, writing into `out` as it goes, and return its results as arrays.

    A failed step (after all cuts) raises `ConvergenceError` once everything up to the last
    good step is written (summary.json says `"status": "failed"` and why). SIGINT or SIGTERM
    stops the run at the next step boundary and raises `RunInterrupted` (a KeyboardInterrupt)
    once everything is written (`"status": "interrupted"`); `resume=True` continues it.
    """
    run_scene(scene, out, resume=resume, progress=progress, comm=comm)
    return Result(Path(out))


def run_scene(scene: Scene, out: str | Path, *, resume: bool = False, progress: bool = True,
              comm: MPI.Comm | None = None) -> dict:
    """One time run of `scene` into `out`, returning its summary instead of a `Result`.

    Resuming a completed run of the same scene computes and writes nothing: it returns its
    summary.

    Parameters
    ----------
    scene : Scene
        The experiment.
    out : str or Path
        The output folder (created; an earlier run's files there are replaced).
    resume : bool, optional
        Continue the run found in `out` from its last checkpoint (the scene must match it).
    progress : bool, optional
        Show a progress bar on rank 0.
    comm : MPI.Comm, optional
        The communicator (default: COMM_WORLD).

    Returns
    -------
    dict
        summary.json's content (`"status"`: "complete", "failed" or "interrupted").
    """
    comm = comm or MPI.COMM_WORLD
    if resume:
        done = completed_summary(scene, Path(out), comm)
        if done is not None:
            return done
    started = time.perf_counter()
    failed, status = None, "completed"
    with Interrupts() as interrupts:
        job = Run(scene, Path(out), comm, resume=resume, progress=progress,
                  interrupts=interrupts)
        try:
            job.run()
        except ConvergenceError as error:  # CompactionError too: its type reaches the caller
            failed, status = error, "failed"
        except (_Stop, SolveInterrupted):  # at a step boundary, or within a step's solve
            status = "interrupted"
        why = (str(failed) if failed is not None else None if status == "completed" else
               f"interrupted by {interrupts.received} at t = {job.time:.6g} s")
        summary = job.finish(status == "completed", why, time.perf_counter() - started,
                             status=status)
    if failed is not None:
        raise failed
    if status == "interrupted":
        raise RunInterrupted(job.time, interrupts.received, summary)
    return summary


def completed_summary(scene: Scene, out: Path, comm: MPI.Comm) -> dict | None:
    """The summary of the run in `out` if resuming it with `scene` has nothing left to do (it
    completed, to the scene's end time); None if there is more to compute. A scene that would
    mix two experiments is refused (`check_resume`)."""
    record, t = Checkpoint(out, comm).stored()
    check_resume(record, scene_record(scene), t, out, scene.changes)
    path = out / "summary.json"
    if t < scene.history.end_time - 1e-12 or not path.exists():
        return None
    summary = json.loads(path.read_text())
    return summary if summary.get("status", "completed") == "completed" else None


class _Stop(Exception):
    """Raised after a step once every rank knows that a signal asked to stop."""


class Interrupts:
    """SIGINT and SIGTERM, while a run is in progress, only note that they came (`received`:
    the signal's name); the run checks after each step (`Run.on_step`). A KeyboardInterrupt in
    the middle of a PETSc solve or of a file being written would leave a traceback, PETSc's
    own errors and half files. The previous handlers are put back on exit. Outside the main
    thread (where Python cannot handle signals) it does nothing; a signal that is ignored
    (nohup, a background job) stays ignored.

    `arm()` installs the handlers again: gmsh resets SIGTERM to its default (the process
    ends at once) behind Python's back when it meshes, so the run re-arms after building."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self):
        self.received: str | None = None
        self._previous = {}

    def __enter__(self) -> Self:
        if threading.current_thread() is threading.main_thread():
            self._previous = {s: signal.signal(s, self._note) for s in self.SIGNALS
                              if signal.getsignal(s) is not signal.SIG_IGN}
        return self

    def arm(self) -> None:
        for s in self._previous:
            signal.signal(s, self._note)

    def _note(self, number, frame) -> None:
        self.received = self.received or signal.Signals(number).name

    def __exit__(self, *exc) -> None:
        for s, handler in self._previous.items():
            signal.signal(s, handler)


def run_side_by_side(jobs: list[tuple[Scene, Path]], progress: bool = True,
                     resume: bool = False) -> None:
    """Run several scenes, each into its own directory; under `mpiexec -n N` they run side by
    side, one group of ranks each (N groups at most). Every rank returns when all are done.
    With `resume`, a run whose directory holds a checkpoint continues from it (a completed
    one is kept as it is, one of another scene is refused: `check_resume`) and the others
    start afresh, so that a sweep stopped part-way picks up where it stopped."""
    world = MPI.COMM_WORLD
    groups = max(1, min(world.size, len(jobs)))
    colour = world.rank % groups
    comm = world.Split(colour, world.rank)
    try:
        for i, (scene, out) in enumerate(jobs):
            if i % groups == colour:
                _run_in_group(scene, out, progress and comm.rank == 0, comm, resume)
    finally:
        world.barrier()
        comm.Free()


def _run_in_group(scene: Scene, out: Path, progress: bool, comm: MPI.Comm,
                  resume: bool = False) -> None:
    """One side-by-side run (resumed if asked and it has a checkpoint); a failure is said at
    once (the group then waits for the others' runs to end before raising it), not only when
    every group is done. An interrupt is not: every rank was signalled, the command says it."""
    try:
        held = comm.bcast(any((Path(out) / "checkpoint").glob("rank*.npz"))
                          if comm.rank == 0 and resume else None, root=0)
        run_scene(scene, out, progress=progress, comm=comm, resume=bool(held))
    except KeyboardInterrupt:
        raise
    except BaseException as error:
        if comm.rank == 0:
            print(f"{scene.name} into {out} stopped: {type(error).__name__}: {error}; the "
                  "runs of the other ranks go on, then this error is raised.",
                  file=sys.stderr, flush=True)
        raise


class Run:
    """Build, step, resume: one scene run into the directory `out`."""

    def __init__(self, scene: Scene, out: Path, comm: MPI.Comm, *, resume: bool,
                 progress: bool, interrupts: Interrupts | None = None):
        self.scene, self.comm, self.progress = scene, comm, progress
        self.interrupts = interrupts
        self.three_d = isinstance(scene.section, Fingertip3D)
        receptors = load_receptors(scene.outputs.receptors) if scene.outputs.receptors else None
        self.out = prepare_directory(out, comm)
        self.checkpoint = Checkpoint(self.out, comm)
        record = self._own_checkpoint(resume)
        self.fm = self._mesh(resume)
        self.problem = FingertipProblem(self.fm, scene.indenters, scene.history,
                                        scene.materials, scene.model,
                                        friction=[i.friction for i in scene.indenters])
        check_reach(self.problem, scene)
        self.start_time, self.steps_before, self.previous = 0.0, 0, None
        steps = scene.steps
        if resume:
            steps = self._resume()
            self.checkpoint.remember(record)  # the resumed scene's: a later end, more times
        self.time = self.start_time
        self.stepper = TimeStepper(self.problem, steps, scene.petsc_options,
                                   linear=scene.linear)
        self.stepper.stop_asked = self._asked  # a step of a fine mesh may take an hour
        self.dofs = sum(f.function_space.dofmap.index_map.size_global
                        * f.function_space.dofmap.index_map_bs for f in self.problem.unknowns)
        after = self.start_time if resume else None
        self.derived = DerivedFields(self.problem.u, self.fm.cell_tags,
                                     self.problem.region_energies())
        self._open_logs(after)
        self.receptors = None if receptors is None else ReceptorRecorder(
            self.problem, self.derived, receptors, scene.section.outer, self.out, comm, after,
            surface_sites(receptors, self.fm, scene.section.half) if self.three_d else None)
        self.fields = FieldWriters(self.out, comm, self._vtx_fields(), resume_after=after)
        self._last_state = (self.start_time, [f.x.array.copy() for f in self.problem.unknowns])
        self.step_count = self.steps_before
        self._bar = None

    # --- set-up ----------------------------------------------------------------------------
    def _own_checkpoint(self, resume: bool) -> dict:
        """The scene's record. A resume is checked against the run's record before anything
        is built or written (the same experiment?); a fresh run's record replaces an earlier
        run's checkpoints (nothing to resume until its first step)."""
        record = scene_record(self.scene)
        if resume:
            stored, t = self.checkpoint.stored()
            check_resume(stored, record, t, self.out, self.scene.changes)
        else:
            clear_earlier_run(self.out, self.comm)
            self.checkpoint.start(record)
        return record

    def _mesh(self, resume: bool):
        """The mesh, written whole to mesh.xdmf (+ .h5) by a fresh run."""
        fm = (build_mesh3d if self.three_d else build_mesh)(self.scene.section, self.comm)
        if self.interrupts is not None:
            self.interrupts.arm()  # gmsh has reset SIGTERM to its default
        if not resume:
            with whole_files(self.out, "mesh", self.comm) as folder:
                write_xdmf(fm, folder / "mesh.xdmf")
        return fm

    def _open_logs(self, after) -> None:
        """The CSV files and their samplers: the section's profiles in 2D; in 3D, across and
        along the finger through the load, and the force per unit length f(z)."""
        scene, out, comm, p = self.scene, self.out, self.comm, self.problem
        self.arrays = FieldArrays(p, self.derived)  # fields_t<t>s.npz, for Result.to_pyvista
        if not self.three_d:
            self.history = CsvLog(out / "history.csv", HISTORY_COLUMNS + self._friction_columns
                                  + self._force_columns, comm, after)
            friction = p.friction is not None
            self.surfaces = {"": CsvLog(out / "surface_profile.csv", SURFACE_COLUMNS
                                        + (FRICTION_SURFACE_COLUMNS if friction else ()),
                                        comm, after)}
            self.stick_slip = CsvLog(out / "stick_slip.csv", STICK_SLIP_COLUMNS, comm,
                                     after) if friction else None
            self.depth = CsvLog(out / "depth_profiles.csv", DEPTH_COLUMNS, comm, after)
            self.line_force = None
            self.profiles = Profiles(p, self.derived, scene.section.outer, scene.outputs)
            return
        self.history = CsvLog(out / "history.csv", HISTORY_COLUMNS_3D + self._friction_columns
                              + self._force_columns, comm, after)
        friction = p.friction is not None
        self.surfaces = {d: CsvLog(out / f"surface_{d}.csv", SURFACE_COLUMNS_3D
                                   + (FRICTION_SURFACE_COLUMNS_3D if friction else ()),
                                   comm, after) for d in ("across", "along")}
        # every step, along the finger (the line of surface_along.csv): the stick/slip map
        self.stick_slip = CsvLog(out / "stick_slip.csv", STICK_SLIP_COLUMNS_3D, comm,
                                 after) if friction else None
        self.depth = CsvLog(out / "depth_profiles.csv", DEPTH_COLUMNS_3D, comm, after)
        self.line_force = CsvLog(out / "line_force.csv", LINE_FORCE_COLUMNS, comm, after)
        z_c, x_c = profile_position(scene)
        self.profiles = Profiles3D(p, self.derived, scene.section, scene.outputs, z_c, x_c)

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
        if self.interrupts is not None:
            self.interrupts.arm()  # after the mesh (gmsh) and the solvers are built
        with Progress(*columns, disable=not show, transient=False) as bar:
            self._bar = (bar, bar.add_task(scene.name, total=end, completed=self.start_time,
                                           status=""))
            self.stepper.run(scene.history, end, start_time=self.start_time,
                             breakpoints=scene.output_times, on_step=self.on_step,
                             previous=self.previous)

    @property
    def _friction_columns(self) -> tuple[str, ...]:
        """history.csv's tangential force and displacement, the pressure's share of the
        tangential force (ploughing) and the friction's dissipated energy over the step, with
        friction only (a frictionless run's file stays as it was). 3D: the contact and stick
        areas, and the pressure's share of the normal force (Coulomb's bound on the friction's
        share of the tangential force, μ times it, on a curved indenter)."""
        if self.problem.friction is None:
            return ()
        force = self.problem.force_keys[0]
        axes = ("x_", "z_") if self.three_d else ("",)  # 3D: along x and along z, each named
        return (*(column for a in axes for column in (
            f"tangential_{a}{force}", f"tangential_{a}displacement_mm",
            f"pressure_tangential_{a}{force}")), self.problem.dissipated_key,
            *((*AREA_KEYS, f"pressure_normal_{force}") if self.three_d else ()))

    @property
    def _force_columns(self) -> tuple[str, ...]:
        """Under force control: the target normal force (the model's share, as its force
        column) and the Newton solves the step's depth took (history.csv's depth is then the
        one found)."""
        return () if self.problem.force_control is None else (self.problem.target_key,
                                                              "force_solves")

    def on_step(self, report) -> None:
        """Write what the accepted step produced (its state is the converged one)."""
        self.step_count += 1
        d = report.diagnostics
        force, reaction = self.problem.force_keys
        column_force, column_reaction = self.history.columns[2], self.history.columns[5]
        self.history.write([{
            "time_s": report.time, "indenter_displacement_mm": d["indentation_mm"],
            column_force: d[force], "newton_iterations": report.newton_iterations,
            "dt_s": report.dt, column_reaction: d[reaction],
            "max_penetration_mm": d["max_penetration_mm"], "min_J": d["min_J"],
            "cuts": report.cuts, "wall_time_s": report.wall_time_s,
            "krylov_iterations": report.linear_iterations}
            | {k: d[k] for k in self._friction_columns + self._force_columns}])
        at_output = any(abs(report.time - t) < 1e-9 for t in self.scene.output_times)
        outputs = self.scene.outputs
        if at_output or (outputs.fields == "every-step"
                         and self.step_count % outputs.field_every == 0):
            self.derived.update()
            self.fields.write(report.time)
        if at_output:
            self._write_output_time(report.time)
        if self.receptors is not None:
            self.receptors.write(report.time)
        if self.stick_slip is not None:  # every step: the stick/slip map's time axis
            self.stick_slip.write(self.profiles.friction_rows(report.time) if self.three_d
                                  else self.profiles.stick_slip_rows(report.time))
        self._save_checkpoint(report)
        self.time = report.time
        self._show(report)
        self._stop_if_asked(report.time)

    def _stop_if_asked(self, t: float) -> None:
        """After a step, with everything written: stop if a signal came to any rank."""
        if self._asked() and t < self.scene.history.end_time - 1e-12:
            raise _Stop

    def _asked(self) -> bool:
        """Whether a signal came to any rank, on every rank together (after a step, and within
        a step after each Newton iteration: mpiexec may deliver it at different moments)."""
        if self.interrupts is None:
            return False
        self.interrupts.arm()
        if not self.comm.allreduce(self.interrupts.received is not None, op=MPI.LOR):
            return False
        if self.interrupts.received is None:  # another rank's signal
            self.interrupts.received = "a signal to another rank"
        return True

    def _write_output_time(self, t: float) -> None:
        for direction, log in self.surfaces.items():
            log.write(self.profiles.surface_rows(t, *([direction] if direction else [])))
        self.depth.write(self.profiles.depth_rows(t))
        if self.line_force is not None:
            self.line_force.write(self.profiles.line_force_rows(t))
        arrays = self.arrays()  # updates the derived fields
        if self.comm.rank == 0:
            save_npz(self.out / f"fields_t{t:g}s.npz", time=t, **arrays)
        if self.scene.outputs.pictures and not self.three_d:  # the pictures are the section's
            with whole_files(self.out, "pictures", self.comm) as folder:
                field_pictures(self.problem, self.derived, folder, t, self.scene.title)

    def _save_checkpoint(self, report) -> None:
        self.checkpoint.save(report.time, report.next_dt, self.step_count,
                             self.problem.state_arrays(), self._last_state)
        self._last_state = (report.time, [f.x.array.copy() for f in self.problem.unknowns])

    def _show(self, report) -> None:
        if self._bar is None:
            return
        bar, task = self._bar
        d = report.diagnostics
        force = self.problem.force_keys[0]
        unit = "N" if self.three_d else "N/mm"
        bar.update(task, completed=report.time, status=(
            f"F = {d[force]:.4g} {unit}, {report.newton_iterations} its, "
            f"Δt = {report.dt:.3g} s, pen. {1e3 * d['max_penetration_mm']:.2g} µm"))

    # --- the end ---------------------------------------------------------------------------
    def finish(self, converged: bool, failure: str | None, wall: float,
               status: str | None = None) -> dict:
        """Close every file, write summary.json and draw the figures; returns the summary.
        `status`: "completed", "failed" or "interrupted" (default: by `converged`)."""
        for log in (self.history, *self.surfaces.values(), self.depth, self.line_force,
                    self.receptors, self.stick_slip):
            if log is not None:
                log.close()
        self.fields.close()
        self.stepper.close()
        self.comm.barrier()
        summary = on_root(self.comm, lambda: self._summary_and_figures(converged, failure, wall,
                                                                       status))
        write_json(self.out / "summary.json", summary, self.comm)
        peak = summary.get("peak_force_N", summary.get("peak_force_N_per_mm"))
        if converged and peak is not None and not peak > 0:
            warnings.warn(f"{self.scene.name}: the indenters never pressed on the skin (peak "
                          f"force {peak:g}).", NoContactWarning,
                          stacklevel=2)
        return summary

    def _summary_and_figures(self, converged, failure, wall, status) -> dict:
        """On rank 0: the spike files, the summary's record and the figures."""
        afferents = None if self.receptors is None else write_spike_files(
            self.out, self.receptors.population, self.receptors.sites)
        summary = run_summary(self.out, scene_record(self.scene), self.fm.report, self.dofs,
                              self.comm.size, converged=converged, failure=failure,
                              wall=wall, output_times=self.scene.output_times,
                              mirror_factor=self.problem.mirror_factor, status=status)
        if self.scene.outputs.pictures:
            with whole_files(self.out, "figures", MPI.COMM_SELF) as folder:
                _figures(self.out, self.scene.title, folder, self.problem.mirror_factor == 2)
                if self.stick_slip is not None and not self.three_d:
                    _friction_figure(self.out, self.scene.title, folder,
                                     max(self.problem.friction_coefficients))
                if afferents is not None:
                    plot_population(afferents, self.scene.section.outer,
                                    folder / "population.png", self.scene.title)
                if self.three_d:
                    _figures_3d(self.out, self.scene.title, folder)
                    if self.problem.friction is not None:
                        h = read_csv(self.out / "history.csv")
                        s = read_csv(self.out / "stick_slip.csv")
                        plot_friction_3d(h, folder / "friction.png",
                                         max(self.problem.friction_coefficients),
                                         title=self.scene.title, stick_slip=s or None,
                                         half=self.problem.mirror_factor == 2)
        return summary


def check_reach(problem, scene: Scene) -> None:
    """Every indenter must touch the skin before the protocol's deepest indentation.

    The indenters move together; the first touch sets the zero of the indentation. An
    indenter placed off the pulp (or far beside a sharper one) may never reach the surface:
    that run would end with a force from the others only, or none, and say nothing.
    A half model's mirror image counts: the indenter at −x of a symmetric pair presses it.
    """
    X, _ = problem.pulp_nodes()
    points = np.concatenate(problem.mesh.comm.allgather(X))
    if problem.mirror_factor == 2:  # a half model: its mirror image presses the other side
        points = np.concatenate([points, points * [-1.0, 1.0, 1.0]])
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


def _figures_3d(out: Path, name: str, to: Path) -> None:
    """A 3D run's surface deflection across and along the finger and f(z) (rank 0; PNGs
    into `to`)."""
    for direction, along in (("across", "x"), ("along", "z")):
        s = read_csv(out / f"surface_{direction}.csv")
        if s:
            plot_surface_profiles(s, to / f"surface_{direction}.png",
                                  title=f"{name}: {direction} the finger", along=along)
    f = read_csv(out / "line_force.csv")
    if f:
        plot_line_force(f, to / "line_force.png", title=name)


def _friction_figure(out: Path, name: str, to: Path, mu: float) -> None:
    """With friction (2D): the stick/slip map over time and the tangential against the
    normal force, from stick_slip.csv and history.csv (rank 0; friction.png into `to`)."""
    s, h = read_csv(out / "stick_slip.csv"), read_csv(out / "history.csv")
    if s and h:
        plot_friction(s, h, to / "friction.png", mu, title=name)


def _figures(out: Path, name: str, to: Path, half: bool = False) -> None:
    """The curves of the run, from its own CSV files (rank 0; PNGs into `to`); `half`: a half
    model's forces."""
    h = read_csv(out / "history.csv")
    if h:
        plot_force_history(h, to / "force_history.png", title=name, half=half)
    s = read_csv(out / "surface_profile.csv") if (out / "surface_profile.csv").exists() else {}
    if s:
        plot_surface_profiles(s, to / "surface_profile.png", title=name)
    d = read_csv(out / "depth_profiles.csv")
    if d:
        for t in np.unique(d["time_s"]):
            plot_depth_profiles(d, to / f"depth_profiles_t{t:g}s.png", t, title=name)


def profile_position(scene: Scene) -> tuple[float, float]:
    """(z_c, x_c) of a 3D run's profiles: the cross-section z_c (`output.section_z`, else a
    sphere's or an across-prism's centre_z, else the middle of the cylindrical part) and the
    line x_c of the along-finger profile (the first indenter's centre_x; 0 for an x prism)."""
    first = scene.indenters[0]
    along_x = getattr(first, "axis", "z") == "x"
    placed = first.shape == "sphere" or along_x
    z_c = scene.outputs.section_z
    if z_c is None:
        z_c = first.centre_z if placed else 0.5 * scene.section.cylinder_length
    return z_c, 0.0 if along_x else first.centre_x
