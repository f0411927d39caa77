"""Benchmark: a 3D fingertip scene (the 3D line load by default) at one mesh size and solver.

Prints dofs, steps, Newton iterations, Krylov iterations (GMRES orthogonalisations of the
iterative route; 0 with MUMPS), time per step, the stepping and total wall time, and the peak
resident memory per rank (max over ranks) and in all. Run it for two sizes and 1-2 ranks:

    .venv/bin/python benchmarks/fingertip_3d.py --min-size 0.4
    .venv/bin/python benchmarks/fingertip_3d.py --min-size 0.4 --linear iterative --set model.rigid_bone=true
    .venv/bin/mpiexec -n 2 .venv/bin/python benchmarks/fingertip_3d.py --min-size 0.4
"""

import argparse
import resource
import tempfile
import time
from pathlib import Path

from mpi4py import MPI
from petsc4py import PETSc

import fingertip_dolfinx  # noqa: F401  (sets up the DOLFINx wheel)
from fingertip_dolfinx.runner import run_scene
from fingertip_dolfinx.scene import load_scene


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawTextHelpFormatter)
    parser.add_argument("--scene", default="line-load-3d")
    parser.add_argument("--min-size", type=float, default=None, help="mm, under the load")
    parser.add_argument("--linear", choices=("direct", "iterative"), default="direct")
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    parser.add_argument("--out", type=Path, default=None, help="keep the results here")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    overrides = [f"solver.linear={args.linear}", *args.overrides]
    if args.min_size is not None:
        overrides.append(f"section.mesh.min_size={args.min_size}")
    scene = load_scene(args.scene, overrides)
    out = args.out or Path(comm.bcast(tempfile.mkdtemp() if comm.rank == 0 else None))

    PETSc.Log.begin()
    started = time.perf_counter()
    summary = run_scene(scene, out, progress=False)
    wall = time.perf_counter() - started
    krylov = int(PETSc.Log.Event("KSPGMRESOrthog").getPerfInfo().get("count", 0))
    rss = comm.gather(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, root=0)
    if comm.rank != 0:
        return
    steps, its = summary["time_steps"], summary["newton_iterations"]
    print(f"scene {scene.name}: min_size {scene.section.section.mesh.min_size} mm, "
          f"{summary['mesh']['cells']} cells, {summary['dofs']} dofs, {comm.size} rank(s), "
          f"linear solver {args.linear}")
    print(f"steps {steps}, Newton iterations {its} ({its / max(steps, 1):.2f} per step), "
          f"Krylov iterations {krylov} ({krylov / max(its, 1):.1f} per Newton iteration)")
    print(f"stepping {summary['wall_time_s']:.1f} s ({summary['wall_time_s'] / max(steps, 1):.2f}"
          f" s per step); total wall {wall:.1f} s (meshing and form compilation included)")
    print(f"peak memory: {max(rss):.0f} MiB per rank (max), {sum(rss):.0f} MiB in all")
    print(f"peak force {summary['peak_force_N']:.4g} N (x{summary['mirror_factor']} for the "
          f"whole finger); results in {out}")


if __name__ == "__main__":
    main()
