"""One run of a scene: build, step, and record everything as it happens.

Per accepted step: a row of history.csv, the fields for ParaView (VTX, every `field_every`
steps and at output times) and a checkpoint (one .npz per rank) from which `--resume`
continues. At output times: the pulp-surface deflection and the depth profiles. At the end
(or at a failure): summary.json and the figures.
"""

from __future__ import annotations

import platform
import time
from pathlib import Path

import numpy as np
from dolfinx import fem, io
from mpi4py import MPI

from . import __version__
from .errors import InputError
from .figures import (
    plot_depth_profiles,
    plot_field,
    plot_force_history,
    plot_surface_profiles,
)
from .forms import FingertipProblem, Tissues
from .materials import strain_energy_density
from .mesh import build_mesh, write_xdmf
from .post import (
    DEPTH_COLUMNS,
    HISTORY_COLUMNS,
    SURFACE_COLUMNS,
    CsvLog,
    DerivedFields,
    PointSampler,
    depth_curve,
    read_csv,
    write_json,
)
from .solver import TimeStepper


class Recorder:
    def __init__(self, scene, out: Path, comm: MPI.Comm, *, resume: bool, progress: bool):
        self.scene, self.out, self.comm, self.progress = scene, out, comm, progress
        if comm.rank == 0:
            out.mkdir(parents=True, exist_ok=True)
            (out / "checkpoint").mkdir(exist_ok=True)
        comm.barrier()
        self.fm = build_mesh(scene.section, comm)
        if not resume:
            write_xdmf(self.fm, out / "mesh.xdmf")
        self.problem = FingertipProblem(self.fm, scene.indenters, scene.history, Tissues(),
                                        scene.model)
        self.start_time, self.start_dt, self.steps_before = 0.0, None, 0
        self.previous = None  # (time, unknowns) one step back: the predictor's second point
        self._last_state = (0.0, [f.x.array.copy() for f in self.problem.unknowns])
        if resume:
            self._load_checkpoint()
        self.stepper = TimeStepper(self.problem, self._step_options(), scene.petsc_options)
        self.dofs = sum(f.function_space.dofmap.index_map.size_global
                        * f.function_space.dofmap.index_map_bs for f in self.problem.unknowns)
        after = self.start_time if resume else None
        self.history = CsvLog(out / "history.csv", HISTORY_COLUMNS, comm, resume_after=after)
        self.surface = CsvLog(out / "surface_profile.csv", SURFACE_COLUMNS, comm, after)
        self.depth = CsvLog(out / "depth_profiles.csv", DEPTH_COLUMNS, comm, after)
        self._setup_sampling()
        self._setup_fields(resume)
        self.step_count = self.steps_before
        self._bar = None

    # --- set-up ----------------------------------------------------------------------------
    def _step_options(self):
        import dataclasses

        if self.start_dt is None:
            return self.scene.steps
        steps = self.scene.steps
        return dataclasses.replace(steps, dt_initial=min(max(self.start_dt, steps.dt_min), steps.dt_max))

    def _setup_sampling(self):
        p, scene = self.problem, self.scene
        tags = self.fm.names
        energies = {
            tags["skin"]: strain_energy_density(p.tissues.skin, p.F),
            tags["subcutaneous"]: strain_energy_density(p.tissues.subcutaneous.solid, p.F),
            tags["bone"]: strain_energy_density(p.tissues.bone, p.F),
            tags["nail"]: strain_energy_density(p.tissues.nail, p.F),
        }
        self.derived = DerivedFields(p.u, self.fm.cell_tags, energies)
        self.curves = []
        for d in scene.depths:
            x0, points = depth_curve(scene.section.outer, d, scene.profile_half_width,
                                     scene.profile_points)
            sub = PointSampler(p.submesh, points) if p.p is not None else None
            self.curves.append((d, x0, PointSampler(p.mesh, points), sub))

    def _setup_fields(self, resume: bool):
        p = self.problem
        suffix = f"-from-{self.start_time:g}s" if resume else ""
        V1 = fem.functionspace(p.mesh, ("Lagrange", 1, (2,)))
        self.u1 = fem.Function(V1, name="displacement")
        engine = "BP4"
        self.writers = [
            io.VTXWriter(self.comm, self.out / f"displacement{suffix}.bp", [p.u], engine=engine),
            io.VTXWriter(self.comm, self.out / f"log_strain{suffix}.bp", [self.derived.log_strain],
                         engine=engine),
            io.VTXWriter(self.comm, self.out / f"strain_energy_density{suffix}.bp",
                         [self.derived.sed], engine=engine),
        ]
        if p.p is not None:
            self.writers.append(io.VTXWriter(self.comm, self.out / f"pore_pressure{suffix}.bp",
                                             [p.p], engine=engine))

    # --- running ---------------------------------------------------------------------------
    def run(self):
        scene = self.scene
        end = scene.history.end_time
        if self.start_time >= end - 1e-12:
            return
        from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

        columns = (TextColumn("{task.description}"), BarColumn(), TextColumn("t = {task.completed:.3g} / {task.total:g} s"),
                   TimeElapsedColumn(), TextColumn("{task.fields[status]}"))
        show = self.progress and self.comm.rank == 0
        with Progress(*columns, disable=not show, transient=False) as bar:
            self._bar = (bar, bar.add_task(scene.name, total=end, completed=self.start_time,
                                           status=""))
            self.stepper.run(scene.history, end, start_time=self.start_time,
                             breakpoints=scene.output_times, on_step=self.on_step,
                             previous=self.previous)

    def on_step(self, report):
        self.step_count += 1
        d = report.diagnostics
        row = {"time_s": report.time, "indenter_displacement_mm": report.load,
               "force_N_per_mm": d["force_N_per_mm"], "newton_iterations": report.newton_iterations,
               "dt_s": report.dt, "reaction_N_per_mm": d["reaction_N_per_mm"],
               "max_penetration_mm": d["max_penetration_mm"], "min_J": d["min_J"],
               "cuts": report.cuts, "wall_time_s": report.wall_time_s}
        self.history.write([row])
        at_output = any(abs(report.time - t) < 1e-9 for t in self.scene.output_times)
        if at_output or self.step_count % self.scene.field_every == 0:
            self._write_fields(report.time)
        if at_output:
            self._write_profiles(report.time)
        self._save_checkpoint(report)
        self._last_state = (report.time, [f.x.array.copy() for f in self.problem.unknowns])
        if self._bar is not None:
            bar, task = self._bar
            bar.update(task, completed=report.time, status=(
                f"F = {d['force_N_per_mm']:.4g} N/mm, {report.newton_iterations} its, "
                f"Δt = {report.dt:.3g} s, pen. {1e3 * d['max_penetration_mm']:.2g} µm"))

    def _write_fields(self, t: float):
        # The problem's state is the converged one of this step (history already advanced).
        self.derived.update()
        for writer in self.writers:
            writer.write(t)

    def _write_profiles(self, t: float):
        p = self.problem
        X, x = p._pulp_nodes()
        uy = x[:, 1] - X[:, 1]
        keep = np.abs(X[:, 0]) <= self.scene.profile_half_width
        gathered = self.comm.gather((X[keep, 0], uy[keep]), root=0)
        self.derived.update()
        rows_depth = []
        for d, x0, sampler, sub in self.curves:
            u = sampler(p.u)
            e = sampler(self.derived.log_strain)
            pe = sampler(self.derived.principal)
            w = sampler(self.derived.sed)
            pp = sub(p.p) if sub is not None else None
            if self.comm.rank == 0:
                for i, xs in enumerate(x0):
                    rows_depth.append({
                        "x_mm": xs, "depth_mm": d, "time_s": t, "u1_mm": u[i, 0], "u2_mm": u[i, 1],
                        "e11": e[i, 0], "e22": e[i, 3], "e12": e[i, 1], "e_max": pe[i, 0],
                        "e_min": pe[i, 1], "sed_MPa": w[i, 0],
                        "p_MPa": pp[i, 0] if pp is not None else np.nan})
        if self.comm.rank == 0:
            xs = np.concatenate([g[0] for g in gathered])
            ys = np.concatenate([g[1] for g in gathered])
            xs, unique = np.unique(np.round(xs, 12), return_index=True)
            self.surface.write([{"x_mm": a, "time_s": t, "deflection_mm": b}
                                for a, b in zip(xs, ys[unique])])
            self.depth.write(rows_depth)
        self._plot_fields(t)

    def _plot_fields(self, t: float):
        """u2 and p on the deformed section near the load (cf. the paper's Fig. 4)."""
        p = self.problem
        self.u1.interpolate(p.u)
        window = ((-self.scene.profile_half_width, self.scene.profile_half_width),
                  (-p.fmesh.mesh.geometry.x[:, 1].max() - 0.5, 0.0))
        disp = _node_values(self.u1)
        pictures = [("u2", p.mesh, _node_values(self.u1)[:, 1], disp,
                     "vertical displacement u2 (mm)")]
        if p.p is not None:
            pictures.append(("p", p.submesh, _node_values(p.p)[:, 0], disp[p.submesh_nodes],
                             "pore pressure (MPa)"))
        for name, msh, values, node_disp, label in pictures:
            corners, values = _triangles(msh, values, node_disp)
            gathered = self.comm.gather((corners, values), root=0)
            if self.comm.rank == 0:
                plot_field(np.concatenate([g[0] for g in gathered]),
                           np.concatenate([g[1] for g in gathered]),
                           self.out / f"field_{name}_t{t:g}s.png", label,
                           title=f"{self.scene.name}: {name} at t = {t:g} s", window=window)

    # --- checkpoints ---------------------------------------------------------------------------
    def _state_arrays(self) -> dict[str, np.ndarray]:
        p = self.problem
        arrays = {"u": p.u.x.array, "u_n": p.u_n.x.array}
        if p.p is not None:
            arrays["p"] = p.p.x.array
        if p.qlv is not None:
            for i, h in enumerate(p.qlv.h):
                arrays[f"qlv_h{i}"] = h.x.array
            arrays["qlv_S_e_n"] = p.qlv.S_e_n.x.array
        return arrays

    def _save_checkpoint(self, report):
        path = self.out / "checkpoint" / f"rank{self.comm.rank}.npz"
        tmp = path.with_name(path.stem + ".tmp.npz")
        previous_time, previous = self._last_state
        np.savez(tmp, time=report.time, dt=report.next_dt, steps=self.step_count,
                 ranks=self.comm.size, previous_time=previous_time, **self._state_arrays(),
                 **{f"previous_{i}": a for i, a in enumerate(previous)})
        tmp.replace(path)

    def _load_checkpoint(self):
        path = self.out / "checkpoint" / f"rank{self.comm.rank}.npz"
        if not path.exists():
            raise InputError(f"--resume {self.out}", "there is no checkpoint to resume from "
                             f"({path}).", "run without --resume to start afresh.")
        data = np.load(path)
        if int(data["ranks"]) != self.comm.size:
            raise InputError(f"--resume {self.out}", f"the run was made on {int(data['ranks'])} "
                             f"ranks, this one has {self.comm.size}.",
                             f"resume with mpiexec -n {int(data['ranks'])}.")
        p = self.problem
        for name, array in self._state_arrays().items():
            if name not in data or data[name].shape != array.shape:
                raise InputError(f"--resume {self.out}", f"the checkpoint does not fit this "
                                 f"scene's model ({name}).", "resume with the same scene and "
                                 "options, or start afresh.")
            array[:] = data[name]
        for f in p.unknowns:
            f.x.scatter_forward()
        p.mark_accepted()
        self.start_time = float(data["time"])
        self.start_dt = float(data["dt"])
        self.steps_before = int(data["steps"])
        self.previous = (float(data["previous_time"]),
                         [data[f"previous_{i}"] for i in range(len(p.unknowns))])
        self._last_state = (self.start_time, [f.x.array.copy() for f in p.unknowns])
        p.set_time(self.start_time)

    # --- the end -----------------------------------------------------------------------------
    def finish(self, converged: bool, failure: str | None, wall: float) -> dict:
        for log in (self.history, self.surface, self.depth):
            log.close()
        for writer in self.writers:
            writer.close()
        self.stepper.close()
        self.comm.barrier()
        summary = None
        if self.comm.rank == 0:
            summary = self._summary(converged, failure, wall)
            self._figures()
        summary = self.comm.bcast(summary, root=0)
        write_json(self.out / "summary.json", summary, self.comm)
        return summary

    def _summary(self, converged, failure, wall) -> dict:
        import dolfinx

        from .scene import scene_record

        h = read_csv(self.out / "history.csv")
        times = h.get("time_s", np.zeros(0))
        force = h.get("force_N_per_mm", np.zeros(0))
        forces_at = {f"{t:g}": (float(np.interp(t, times, force)) if len(times) and t <= times[-1]
                                + 1e-9 else None) for t in self.scene.output_times}
        r = self.fm.report
        return {
            "scene": self.scene.name,
            "scene_data": scene_record(self.scene),
            "model": {k: v for k, v in vars(self.scene.model).items() if k != "extra"},
            "versions": {"fingertip_dolfinx": __version__, "dolfinx": dolfinx.__version__,
                         "python": platform.python_version()},
            "mpi_ranks": self.comm.size,
            "mesh": {"cells": r.num_cells, "cell_type": r.cell_type, "min_edge_mm": r.min_edge,
                     "max_edge_mm": r.max_edge, "min_quality": r.min_quality},
            "dofs": self.dofs,
            "time_steps": int(len(times)),
            "newton_iterations": int(np.nansum(h.get("newton_iterations", [0]))),
            "wall_time_s": wall,
            "converged": converged,
            "failure": failure,
            "end_time_s": float(times[-1]) if len(times) else 0.0,
            "peak_force_N_per_mm": float(np.max(force)) if len(force) else None,
            "max_penetration_mm": float(np.max(h["max_penetration_mm"])) if len(times) else None,
            "force_at_output_times_N_per_mm": forces_at,
            "written": time.strftime("%Y-%m-%dT%H:%M:%S"),
        }

    def _figures(self):
        name = self.scene.name
        h = read_csv(self.out / "history.csv")
        if h:
            plot_force_history(h, self.out / "force_history.png", title=name)
        s = read_csv(self.out / "surface_profile.csv")
        if s:
            plot_surface_profiles(s, self.out / "surface_profile.png", title=name)
        d = read_csv(self.out / "depth_profiles.csv")
        if d:
            for t in np.unique(d["time_s"]):
                plot_depth_profiles(d, self.out / f"depth_profiles_t{t:g}s.png", t, title=name)


def _triangles(msh, node_values: np.ndarray, node_disp: np.ndarray):
    """Deformed corners (n, 3, 2) and corner values (n, 3) of the owned cells of `msh`."""
    n = msh.topology.index_map(2).size_local
    cells = msh.geometry.dofmaps[0][:n]
    if cells.shape[1] == 4:  # quadrilaterals: two triangles each (DOLFINx's vertex order)
        cells = np.concatenate([cells[:, [0, 1, 3]], cells[:, [0, 3, 2]]])
    corners = msh.geometry.x[:, :2][cells] + node_disp[cells]
    return corners, node_values[cells]


def _node_values(f: fem.Function) -> np.ndarray:
    """A P1 function's values at its mesh's geometry nodes, shape (nodes, block size)."""
    msh, V = f.function_space.mesh, f.function_space
    bs = V.dofmap.index_map_bs
    values = np.zeros((msh.geometry.x.shape[0], bs))
    values[msh.geometry.dofmaps[0].ravel()] = f.x.array.reshape(-1, bs)[V.dofmap.list.ravel()]
    return values
