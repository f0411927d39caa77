"""Benchmark: wall time of a scene (the paper's line load by default) and where it goes.

Prints dofs, steps, Newton iterations per step, seconds per Newton iteration split into
residual assembly, Jacobian assembly and the linear solve (PETSc's own log events), the total
wall time, and the ratio of the wall time to its lower bound for an implicit scheme on the
same mesh: one Jacobian assembly plus one factorisation and solve per time step.

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
from fingertip_dolfinx.runner import run_scene
from fingertip_dolfinx.scene import load_scene

EVENTS = {"residual": "SNESFunctionEval", "jacobian": "SNESJacobianEval",
          "factorisation": "MatLUFactorNum", "solve": "KSPSolve"}


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
    summary = run_scene(scene, out, progress=False)
    wall = time.perf_counter() - started
    perf = {k: PETSc.Log.Event(name).getPerfInfo() for k, name in EVENTS.items()}
    if comm.rank != 0:
        return
    h = read_csv(out / "history.csv")
    steps, its = summary["time_steps"], summary["newton_iterations"]
    t = {k: p.get("time", 0.0) for k, p in perf.items()}  # rank 0's share
    n = {k: int(p.get("count", 0)) for k, p in perf.items()}
    per_jac = t["jacobian"] / max(n["jacobian"], 1)
    per_factor = t["factorisation"] / max(n["factorisation"], 1)
    per_solve = t["solve"] / max(n["solve"], 1)
    bound = steps * (per_jac + per_factor + per_solve)
    print(f"scene {scene.name}: {summary['dofs']} dofs, {summary['mesh']['cells']} cells, "
          f"{comm.size} rank(s)")
    print(f"steps {steps}, Newton iterations {its} ({its / max(steps, 1):.2f} per step), "
          f"step cuts {int(h['cuts'].sum())}")
    print(f"per Newton iteration: residual {t['residual'] / max(n['residual'], 1):.4f} s "
          f"(x{n['residual'] / max(its, 1):.1f}), Jacobian {per_jac:.4f} s, "
          f"LU factorisation {per_factor:.4f} s, solve {per_solve:.4f} s")
    print(f"totals: residual {t['residual']:.2f} s, Jacobian {t['jacobian']:.2f} s, "
          f"factorisation {t['factorisation']:.2f} s, triangular solves {t['solve']:.2f} s")
    print(f"wall time {wall:.1f} s (stepping alone {summary['wall_time_s']:.1f} s; the rest is "
          "meshing and form compilation); "
          f"lower bound (one Jacobian + LU + solve per step) {bound:.1f} s; ratio {wall / bound:.1f}")
    print(f"peak force {summary['peak_force_N_per_mm']:.4g} N/mm; max penetration "
          f"{1e3 * summary['max_penetration_mm']:.3g} µm; results in {out}")


if __name__ == "__main__":
    main()
