"""Benchmark: a 3D fingertip scene (the 3D line load by default) at one mesh size and solver.

Prints dofs, steps, Newton iterations, Krylov iterations (of the iterative route; 0 with
MUMPS; history.csv has them per step, so a run stopped early still tells them), time per
step, the stepping and total wall time, the peak resident memory of each rank (VmHWM)
and in all, the CPU seconds per rank and the load average (on a shared machine the wall time
measures the neighbours too; under MPI the CPU time includes the ranks' busy waiting), and
the assembly's share, and the set-up's parts (meshing, form compilation, the solver).
Run it for two sizes and 1-2 ranks:

    .venv/bin/python benchmarks/fingertip_3d.py --min-size 0.4
    .venv/bin/python benchmarks/fingertip_3d.py --min-size 0.4 --linear iterative \\
        --set model.rigid_bone=true
    .venv/bin/mpiexec -n 2 .venv/bin/python benchmarks/fingertip_3d.py --min-size 0.4

`--assembly N` only builds the scene and times N Jacobian and residual assemblies, and the contact
terms alone, at a smooth deformed state
(strains of a few per cent), wall and CPU seconds: the cost of one Newton iteration's Jacobian,
e.g. for `--set model.quadrature_degree=2` against 4.
"""

import os
import resource
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI
from timing import scene_and_out, scene_parser, tally

import fingertip_dolfinx  # noqa: F401  (sets up the DOLFINx wheel)
from fingertip_dolfinx.errors import RunInterrupted
from fingertip_dolfinx.runner import Run, run_scene
from fingertip_dolfinx.stepping.stepper import TimeStepper


def main():
    parser = scene_parser(__doc__, "line-load-3d")
    parser.add_argument("--min-size", type=float, default=None, help="mm, under the load")
    parser.add_argument("--linear", choices=("direct", "iterative"), default="direct")
    parser.add_argument("--assembly", type=int, default=0, metavar="N",
                        help="only time N Jacobian assemblies")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    overrides = [f"solver.linear={args.linear}", *args.overrides]
    if args.min_size is not None:
        overrides.append(f"section.mesh.min_size={args.min_size}")
    scene, out = scene_and_out(args, comm, overrides)

    if args.assembly:
        return time_assembly(scene, out, args.assembly)
    import dolfinx.fem.petsc  # after the package, which sets up the DOLFINx wheel
    from petsc4py import PETSc

    PETSc.Log.begin()  # the linear solver's events: solve, preconditioner set-up, LU
    tallies = {"jacobian": tally(dolfinx.fem.petsc, "assemble_jacobian"),
               "residual": tally(dolfinx.fem.petsc, "assemble_residual"),
               "set-up (mesh, forms, solver)": tally(Run, "__init__"),
               "of which meshing (gmsh, distribution, mesh.xdmf)": tally(Run, "_mesh"),
               "of which form compilation (FFCx, or the cache)": tally(dolfinx.jit, "ffcx_jit"),
               "of which the solver (forms, vectors, matrices)": tally(TimeStepper, "__init__"),
               "output per step (history, fields, checkpoint)": tally(Run, "on_step"),
               "summary and figures": tally(Run, "finish")}
    announce_set_up(tallies, comm)
    load = os.getloadavg()
    started, cpu = time.perf_counter(), time.process_time()
    try:
        summary = run_scene(scene, out, progress=False)
    except RunInterrupted as stop:  # SIGINT/SIGTERM: the figures of the steps done
        summary = stop.summary
    wall = time.perf_counter() - started
    cpu = comm.gather(time.process_time() - cpu, root=0)
    rss = comm.gather(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, root=0)
    if comm.rank == 0:
        report(scene, summary, args.linear, tallies, (wall, cpu, rss, load), out, PETSc)


def announce_set_up(tallies: dict, comm) -> None:
    """Print the set-up's parts as soon as the run is set up (before its first step), so that
    a large run stopped in its first step still tells them."""
    init = Run.__init__  # already tallied

    def init_then_print(self, *args, **kwargs):
        init(self, *args, **kwargs)
        rss = comm.gather(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, root=0)
        if comm.rank == 0:
            print(f"set up: {self.dofs} dofs; " + ", ".join(
                f"{name} {t.wall:.1f} / {t.cpu:.1f} s" for name, t in tallies.items()
                if "set-up" in name or "of which" in name) + "; peak memory per rank "
                + ", ".join(f"{r:.0f}" for r in rss) + " MiB", flush=True)

    Run.__init__ = init_then_print


def report(scene, summary: dict, linear: str, tallies: dict, measured: tuple, out: Path,
           PETSc) -> None:
    """Print the run's figures (rank 0): sizes, iterations, times, phases, memory, force."""
    wall, cpu, rss, load = measured
    size = len(cpu)
    steps, its = summary["time_steps"], summary["newton_iterations"]
    krylov = summary["krylov_iterations"] if linear == "iterative" else 0
    print(f"scene {scene.name}: min_size {scene.section.section.mesh.min_size} mm, "
          f"{summary['mesh']['cells']} cells, {summary['dofs']} dofs, {size} rank(s), "
          f"linear solver {linear}")
    print(f"steps {steps}, Newton iterations {its} ({its / max(steps, 1):.2f} per step), "
          f"Krylov iterations {krylov} ({krylov / max(its, 1):.1f} per Newton iteration)")
    print(f"stepping {summary['wall_time_s']:.1f} s ({summary['wall_time_s'] / max(steps, 1):.2f}"
          f" s per step); total wall {wall:.1f} s (meshing and form compilation included)")
    print(f"CPU time per rank {', '.join(f'{c:.0f}' for c in cpu)} s (meshing and compilation "
          f"included); load average {load[0]:.2f} at the start, {os.getloadavg()[0]:.2f} at the "
          f"end (the machine is shared)")
    (jw, jc), (rw, rc) = tallies["jacobian"].per_call(), tallies["residual"].per_call()
    print(f"assembly on rank 0 (wall / CPU s per call): Jacobian {tallies['jacobian'].calls} x "
          f"{jw:.2f} / {jc:.2f}, residual {tallies['residual'].calls} x {rw:.3f} / {rc:.3f}; "
          f"quadrature degree {scene.model.quadrature_degree}")
    print(f"linear solver on rank 0 (wall s in all / calls): {solver_events(PETSc)}")
    phases = {k: t for k, t in tallies.items() if k not in ("jacobian", "residual")}
    print("phases on rank 0 (wall / CPU s in all, calls): " + ", ".join(
        f"{name} {t.wall:.1f} / {t.cpu:.1f} ({t.calls})" for name, t in phases.items()))
    print(f"peak memory (VmHWM) per rank: {', '.join(f'{r:.0f}' for r in rss)} MiB; "
          f"{sum(rss):.0f} MiB in all, {sum(rss) * 1024 / summary['dofs']:.1f} KiB per dof")
    print(f"peak force {summary['peak_force_N']:.4g} N (x{summary['mirror_factor']} for the "
          f"whole finger); results in {out}")


def solver_events(PETSc) -> str:
    """PETSc's wall seconds and calls of the linear solves (KSPSolve, which includes the
    preconditioner's set-up, PCSetUp, of which GAMG's, PCSetUp_GAMG+) and of LU factorisations
    (MUMPS, or the stiff block's: the analysis and ordering MatLUFactorSym, the numerical
    factorisation MatLUFactorNum, the triangular solves MatSolve)."""
    parts = []
    for name in ("SNESSolve", "KSPSolve", "PCSetUp", "PCSetUp_GAMG+", "MatLUFactorSym",
                 "MatLUFactorNum", "MatSolve"):
        info = PETSc.Log.Event(name).getPerfInfo()
        parts.append(f"{name} {info.get('time', 0.0):.1f} s / {info.get('count', 0)}")
    return ", ".join(parts)


def time_assembly(scene, out: Path, repeats: int) -> None:
    """Wall and CPU seconds (min over `repeats`) at a smooth deformed state of one Jacobian
    assembly, one residual assembly (SNES's, and DOLFINx's with and without its Dirichlet
    lifting: stepping.residual; the state moves the nail's clamped strip, so SNES's is the
    lifted one here, and the unlifted one is timed, not used), and of the contact terms' own
    residual and Jacobian (compiled apart: in the Newton forms they are part of the
    displacement block)."""
    import ufl
    from dolfinx import fem

    comm = MPI.COMM_WORLD
    job = smooth_state(scene, out, comm)
    problem, nonlinear = job.problem, job.stepper.nonlinear
    snes = nonlinear.solver
    J, P, (jacobian, args, kargs) = snes.getJacobian()
    b, (residual, rargs, rkargs) = snes.getFunction()
    contact = problem.contact.residual(ufl.TestFunction(problem.V))
    R_c = fem.form(contact, jit_options=problem.jit_options)
    J_c = fem.form(ufl.derivative(contact, problem.u), jit_options=problem.jit_options)
    lifting = job.stepper.residual  # stepping.residual.UnliftedResidual
    reuse = job.stepper.reuse  # the scene's JacobianReuse would keep the first Jacobian

    def assemble_jacobian():
        if reuse is not None:
            reuse.start()
        jacobian(snes, nonlinear.x, J, P, *args, **(kargs or {}))

    calls = {"Jacobian": assemble_jacobian,
             "residual": lambda: residual(snes, nonlinear.x, b, *rargs, **(rkargs or {})),
             "residual, DOLFINx's (lifted)": lambda: lifting.assemble_lifted(snes, nonlinear.x,
                                                                             b),
             "residual without the lifting": lambda: lifting.assemble_unlifted(nonlinear.x, b),
             "contact residual": lambda: fem.petsc.assemble_vector(R_c).destroy(),
             "contact Jacobian": lambda: _assembled(fem.petsc.assemble_matrix(J_c))}
    times = {name: _min_time(call, repeats, comm) for name, call in calls.items()}
    if comm.rank == 0:
        print(f"assembly, quadrature degree {scene.model.quadrature_degree}, "
              f"{job.fm.mesh.topology.index_map(3).size_global} cells, {job.dofs} dofs, "
              f"{comm.size} rank(s), min over {repeats} calls (wall s, CPU s per rank): "
              + "; ".join(f"{name} {w:.4f}, {', '.join(f'{c:.4f}' for c in cpu)}"
                          for name, (w, cpu) in times.items())
              + f"; load average {os.getloadavg()[0]:.2f}")


def smooth_state(scene, out: Path, comm) -> Run:
    """The scene's run set up (not stepped) with its unknowns at a smooth deformed state of
    strains of a few per cent, where Jacobians and residuals are assembled and timed."""
    import dolfinx.fem.petsc  # after the package, which sets up the DOLFINx wheel

    job = Run(scene, out, comm, resume=False, progress=False)
    job.problem.u.interpolate(lambda x: np.array([0.02 * x[0],
                                                  -0.05 * x[1] + 0.03 * np.sin(x[2]),
                                                  0.01 * x[2]]))
    dolfinx.fem.petsc.assign(job.problem.unknowns, job.stepper.nonlinear.x)
    return job


def _assembled(A) -> None:
    A.assemble()
    A.destroy()


def _min_time(call, repeats: int, comm) -> tuple[float, list[float]]:
    """The least wall seconds (rank 0) and CPU seconds (each rank) of `repeats` calls."""
    walls, cpus = [], []
    for _ in range(repeats):
        comm.barrier()
        wall, cpu = time.perf_counter(), time.process_time()
        call()
        walls.append(time.perf_counter() - wall)
        cpus.append(time.process_time() - cpu)
    return min(walls), comm.gather(min(cpus), root=0)


if __name__ == "__main__":
    main()
