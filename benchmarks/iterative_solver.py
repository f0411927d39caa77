"""Direct (MUMPS) against iterative (FGMRES + Schur field split + GAMG) inside Newton.

The 1pt fingertip (biphasic subcutaneous tissue: unknowns u and p) pressed two steps of 0.05 s
along its ramp (0.1 mm), at element sizes h (min_size; max_size 5h, bone_size 10h). Prints per
run: dofs, Newton iterations, Krylov iterations per Newton step, wall time per step, the force
and max |Δu| against the direct solution (to solver tolerance: the last Newton correction).
Run it serially and under `mpiexec -n 2` for the rank comparison:

    python benchmarks/iterative_solver.py                       # h = 0.4 and 0.1 (4x finer)
    python benchmarks/iterative_solver.py --sizes 0.4 0.2 0.1 --bone elastic
    python benchmarks/iterative_solver.py --bone elastic --set solver.snes_ksp_ew=false
    mpiexec -n 2 python benchmarks/iterative_solver.py --sizes 0.4
"""

import argparse
import re
import time

import numpy as np
from mpi4py import MPI

import fingertip_dolfinx  # noqa: F401  (sets up the DOLFINx wheel)
from fingertip_dolfinx.errors import ConvergenceError
from fingertip_dolfinx.geometry.mesh import build_mesh
from fingertip_dolfinx.problem import FingertipProblem
from fingertip_dolfinx.scene import load_scene
from fingertip_dolfinx.stepping import StepOptions, TimeStepper

STEPS = StepOptions(dt_initial=0.05, dt_min=0.05, dt_max=0.05, max_cuts=0)


def run(h: float, linear: str, bone: str, comm, overrides=()) -> dict:
    scene = load_scene("1pt", [f"section.mesh.min_size={h}", f"section.mesh.max_size={5 * h}",
                               f"section.mesh.bone_size={10 * h}",
                               f"model.rigid_bone={'true' if bone == 'rigid' else 'false'}",
                               *overrides])
    problem = FingertipProblem(build_mesh(scene.section, comm), scene.indenters, scene.history,
                               scene.materials, scene.model)
    stepper = TimeStepper(problem, STEPS, scene.petsc_options, linear=linear,
                          prefix=f"bench_{linear}_")
    dofs = sum(f.function_space.dofmap.index_map.size_global * f.function_space.dofmap.index_map_bs
               for f in problem.unknowns)
    row = {"h": h, "linear": linear, "bone": bone, "dofs": dofs, "ranks": comm.size}
    started = time.perf_counter()
    try:
        reports = stepper.run(scene.history, 0.1)
    except ConvergenceError as error:
        reason = re.search(r"\((\w+)\)", str(error))  # SNES's reason, e.g. DIVERGED_MAX_IT
        row["failed"] = reason.group(1) if reason else str(error)[:60]
        stepper.close()
        return row
    newton = sum(r.newton_iterations for r in reports)
    row |= {"newton": newton, "krylov_per_newton": stepper.linear_iterations / newton,
            "s_per_step": (time.perf_counter() - started) / len(reports),
            "force": reports[-1].diagnostics["force_N_per_mm"],
            "u_max": comm.allreduce(float(np.abs(problem.u.x.array).max()), op=MPI.MAX),
            "last_update": stepper.snes.getSolutionUpdate().norm(3)}
    stepper.close()
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", type=float, nargs="+", default=[0.4, 0.1])
    parser.add_argument("--bone", choices=("rigid", "elastic"), default="rigid")
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        help="a scene override, e.g. solver.snes_ksp_ew=false (exact linear "
                             "solves to ksp_rtol 1e-10)")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    say = print if comm.rank == 0 else (lambda *a, **k: None)
    say(f"{'ranks':>5} {'h mm':>5} {'bone':>7} {'solver':>9} {'dofs':>7} {'Newton':>6} "
        f"{'Krylov/N':>8} {'s/step':>7} {'force N/mm':>16} {'max|u| mm':>12} {'last du':>8}")
    for h in args.sizes:
        for linear in ("direct", "iterative"):
            r = run(h, linear, args.bone, comm, args.overrides)
            if "failed" in r:
                say(f"{r['ranks']:>5} {h:>5} {args.bone:>7} {linear:>9} {r['dofs']:>7} "
                    f"failed: {r['failed']}")
                continue
            say(f"{r['ranks']:>5} {h:>5} {args.bone:>7} {linear:>9} {r['dofs']:>7} "
                f"{r['newton']:>6} {r['krylov_per_newton']:>8.1f} {r['s_per_step']:>7.2f} "
                f"{r['force']:>16.10e} {r['u_max']:>12.8e} {r['last_update']:>8.1e}")


if __name__ == "__main__":
    main()
