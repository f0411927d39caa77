"""Inexact Newton on the iterative route: the residual's norm split by region, per iteration.

The iterative route's Eisenstat–Walker forcing term η bounds each linear solve's residual
relative to the Newton residual's norm. On the fingertip with elastic bone and nail, that norm
may be the stiff regions' rows' (moduli 10³–10⁴ above the pulp's): a solve stopped at η would
then leave the soft tissue's part, where contact forms, inaccurate. This prints, per Newton
iteration of a 3D scene's run: the residual's norm over all rows and over the stiff (bone,
nail: every dof of their cells), soft (the other displacement dofs) and pressure rows, the
Krylov iterations and the linear tolerance η of that iteration's solve. Then the run's Newton
and Krylov iterations, CPU seconds and peak memory per rank, and the force.

    mpiexec -n 2 python benchmarks/newton_forcing.py --set section.mesh.min_size=0.8 \\
        --set section.mesh.max_size=2.4 --set section.mesh.bone_size=5
    ... --set solver.snes_ksp_ew=false            # exact solves (ksp_rtol 1e-10)

The scene is the 3D line load's first step (0.025 mm in 0.025 s) unless --set says otherwise.
"""

import resource
import time

import numpy as np
from mpi4py import MPI
from timing import scene_and_out, scene_parser

import fingertip_dolfinx  # noqa: F401  (sets up the DOLFINx wheel)
from fingertip_dolfinx.runner import run_scene
from fingertip_dolfinx.stepping.stepper import TimeStepper

FIRST_STEP = ["solver.linear=iterative", "protocol.depth=0.025", "protocol.ramp_time=0.025",
              "protocol.end_time=0.025", "output.times=[0.025]", "steps.dt_initial=0.025",
              "output.pictures=false"]


def region_masks(stepper: TimeStepper) -> dict[str, np.ndarray]:
    """Boolean masks over a rank's owned rows of the block residual (its owned u dofs, then
    its owned p dofs): stiff (a dof of a bone or nail cell), soft (the other u dofs), p."""
    V = stepper.problem.unknowns[0].function_space
    bs, n = V.dofmap.index_map_bs, V.dofmap.index_map.size_local * V.dofmap.index_map_bs
    marks = np.zeros(V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts)
    marks[np.unique(V.dofmap.list[stepper.linear.stiff])] = 1.0
    stiff = np.repeat(marks, bs)[:n] > 0  # a partition-boundary dof of a ghost cell: soft here
    rows = sum(f.function_space.dofmap.index_map.size_local * f.function_space.dofmap.index_map_bs
               for f in stepper.problem.unknowns)
    masks = {k: np.zeros(rows, bool) for k in ("stiff", "soft", "p")}
    masks["stiff"][:n], masks["soft"][:n] = stiff, ~stiff
    masks["p"][n:] = True
    return masks


def monitor(stepper: TimeStepper, comm) -> None:
    """Print, per Newton iteration, the residual norm by region and the last linear solve."""
    masks, seen = region_masks(stepper), [0]
    snes = stepper.snes

    def show(snes, its, fnorm):
        f = snes.getFunction()[0].getArray(readonly=True)
        parts = {k: np.sqrt(comm.allreduce(float(np.sum(f[m] ** 2)), op=MPI.SUM))
                 for k, m in masks.items()}
        krylov = snes.getLinearSolveIterations()  # of this solve (this step's Newton)
        seen[0] = 0 if its == 0 else seen[0]
        eta = snes.getKSP().getTolerances()[0]
        if comm.rank == 0:
            print(f"  Newton {its:2d}: |R| {fnorm:9.3e}  stiff {parts['stiff']:9.3e}  soft "
                  f"{parts['soft']:9.3e}  p {parts['p']:9.3e}  | Krylov {krylov - seen[0]:3d}"
                  f"  eta {eta:8.2e}", flush=True)
        seen[0] = krylov

    snes.setMonitor(show)


def main():
    parser = scene_parser(__doc__, "line-load-3d", out=False)
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    scene, out = scene_and_out(args, comm, [*FIRST_STEP, *args.overrides])
    init = TimeStepper.__init__

    def init_and_watch(self, *a, **k):
        init(self, *a, **k)
        monitor(self, comm)

    TimeStepper.__init__ = init_and_watch
    started, cpu = time.perf_counter(), time.process_time()
    summary = run_scene(scene, out, progress=False)
    cpu = comm.gather(time.process_time() - cpu, root=0)
    rss = comm.gather(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, root=0)
    if comm.rank == 0:
        its, krylov = summary["newton_iterations"], summary["krylov_iterations"]
        print(f"{summary['dofs']} dofs, {comm.size} rank(s): {summary['time_steps']} steps, "
              f"Newton {its}, Krylov {krylov} ({krylov / max(its, 1):.1f} per Newton); "
              f"wall {time.perf_counter() - started:.0f} s, CPU per rank "
              f"{', '.join(f'{c:.0f}' for c in cpu)} s, peak memory per rank "
              f"{', '.join(f'{r:.0f}' for r in rss)} MiB; force {summary['peak_force_N']:.10e} N"
              f" ({summary['status']})")


if __name__ == "__main__":
    main()
