"""Benchmark: wall time of a scene (the paper's line load by default) and where it goes.

Prints dofs, steps, Newton iterations per step, the counts of residual and Jacobian
assemblies, LU factorisations and Krylov iterations, seconds per operation (PETSc's own log
events), the stepping time, and its ratio to the lower bound for an implicit scheme on the
same mesh: one Jacobian assembly plus one factorisation and solve per time step (each at its
cost measured in the same run). "Solving" is the stepping minus the results written after
each step (profiles, fields, and at the output times the field pictures: ~5 s of pyvista
rendering, not the solver's).

Why the ratio stays near 6 on the line load (measured, 2026-11-23; counts from PETSc's log):
- Newton iterations: the ramp's 18 steps take 4-14 iterations each (128 of the 164), in a
  slow, line-searched phase while surface points enter the penalty contact zone; the hold's
  15 take 2-3 (one to move, one that reaches snes_atol). The bound assumes 1 per step.
- A kept LU as preconditioner of GMRES on the fresh Jacobian (snes_lag_preconditioner 5 and
  20, persisting across steps) needed 8.4 and 16 Krylov iterations per solve: in 2D a MUMPS
  triangular solve costs 1/9 of a factorisation, so 36 (or 9) factorisations instead of 179
  saved nothing (stepping +2 % and +16 %). A kept Jacobian (chord steps) pays only in the
  quadratic phase: steps.jacobian_reuse = 0.02 (the scene's) -17 factorisations; looser
  thresholds lengthen the ramp (solver.JacobianReuse).
- Line searches: basic (full steps) 37 steps, 3 cuts, 180 factorisations; l2 160
  factorisations but 3.3 residuals per iteration: no gain over bt. MUMPS with METIS
  ordering: the same cost per factorisation.
- Quadrature degree 2 (3 points instead of 6; 2k - 2 for P2 keeps the optimal rate) makes a
  Jacobian ~35 % cheaper but the force moves by 2e-4 (1.1794e-3 against 1.1796e-3 N/mm:
  not the same 4 digits) and Newton takes 206 factorisations: kept at 4.
    .venv/bin/python benchmarks/line_load.py [--scene line-load] [--set key=value ...]
    .venv/bin/mpiexec -n 2 .venv/bin/python benchmarks/line_load.py
"""

import argparse
import tempfile
import time
from pathlib import Path

from mpi4py import MPI
from petsc4py import PETSc

import fingertip_dolfinx  # noqa: F401  (sets up the DOLFINx wheel)
from fingertip_dolfinx.outputs import read_csv
from fingertip_dolfinx.runner import Run
from fingertip_dolfinx.scene import load_scene

EVENTS = {"residual": "SNESFunctionEval", "jacobian": "SNESJacobianEval",
          "factorisation": "MatLUFactorNum", "solve": "KSPSolve", "triangular": "MatSolve"}


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    parser.add_argument("--scene", default="line-load")
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    parser.add_argument("--out", type=Path, default=None, help="keep the results here")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    scene = load_scene(args.scene, args.overrides)
    out = args.out or Path(comm.bcast(tempfile.mkdtemp() if comm.rank == 0 else None))

    PETSc.Log.begin()
    started = time.perf_counter()
    job = Run(scene, out, comm, resume=False, progress=False)
    writing = _timed(job, "on_step")  # the results written after each step, pictures too
    stepping = time.perf_counter()
    job.run()
    stepping = time.perf_counter() - stepping
    krylov = job.stepper.linear_iterations
    reuse = job.stepper.reuse  # None, or the counts of Jacobians assembled and kept
    summary = job.finish(True, None, time.perf_counter() - started)
    wall = time.perf_counter() - started
    solving = stepping - writing[0]
    perf = {k: PETSc.Log.Event(name).getPerfInfo() for k, name in EVENTS.items()}
    if comm.rank != 0:
        return
    h = read_csv(out / "history.csv")
    steps, its = summary["time_steps"], summary["newton_iterations"]
    t = {k: p.get("time", 0.0) for k, p in perf.items()}  # rank 0's share
    n = {k: int(p.get("count", 0)) for k, p in perf.items()}
    if reuse is not None:  # SNESJacobianEval counts the calls, kept Jacobians included
        n["jacobian"] = reuse.assembled
    per_jac = t["jacobian"] / max(n["jacobian"], 1)
    per_factor = t["factorisation"] / max(n["factorisation"], 1)
    per_solve = t["triangular"] / max(n["triangular"], 1)  # one pair of triangular solves
    bound = steps * (per_jac + per_factor + per_solve)
    direct = krylov == n["solve"]  # preonly: one "iteration" (a triangular solve) per solve
    print(f"scene {scene.name}: {summary['dofs']} dofs, {summary['mesh']['cells']} cells, "
          f"{comm.size} rank(s)")
    print(f"steps {steps}, Newton iterations {its} ({its / max(steps, 1):.2f} per step), "
          f"step cuts {int(h['cuts'].sum())}")
    print(f"per Newton iteration: residual {t['residual'] / max(n['residual'], 1):.4f} s "
          f"(x{n['residual'] / max(its, 1):.1f}), Jacobian {per_jac:.4f} s, "
          f"LU factorisation {per_factor:.4f} s, triangular solve {per_solve:.4f} s")
    print(f"totals: residual {t['residual']:.2f} s, Jacobian {t['jacobian']:.2f} s, "
          f"factorisation {t['factorisation']:.2f} s, linear solves {t['solve']:.2f} s "
          f"(of which triangular solves {t['triangular']:.2f} s)")
    print(f"counts: residuals {n['residual']}, Jacobians {n['jacobian']}, LU factorisations "
          f"{n['factorisation']}, linear solves {n['solve']}, Krylov iterations "
          f"{'- (direct)' if direct else krylov}"
          + ("" if reuse is None else f"; Jacobians kept {reuse.reused} (reuse threshold "
                                      f"{reuse.threshold:g})"))
    print(f"wall time {wall:.1f} s: stepping {stepping:.1f} s = solving {solving:.1f} s + "
          f"writing results {writing[0]:.1f} s (profiles, fields, pictures); the rest is "
          "meshing, form compilation and the summary's figures")
    print(f"lower bound (one Jacobian + LU + solve per step) {bound:.2f} s; ratio: solving "
          f"{solving / bound:.2f}, stepping {stepping / bound:.2f}")
    forces = summary["force_at_output_times_N_per_mm"]
    print("force at output times: " + ", ".join(f"{k} s {v:.6g} N/mm" for k, v in forces.items()))
    print(f"peak force {summary['peak_force_N_per_mm']:.6g} N/mm; max penetration "
          f"{1e3 * summary['max_penetration_mm']:.3g} µm; results in {out}")


def _timed(obj, name: str) -> list[float]:
    """Wrap the method `name` of `obj` to add its wall time to the returned one-item list."""
    total, method = [0.0], getattr(obj, name)

    def timed(*args, **kwargs):
        started = time.perf_counter()
        try:
            return method(*args, **kwargs)
        finally:
            total[0] += time.perf_counter() - started

    setattr(obj, name, timed)
    return total


if __name__ == "__main__":
    main()
