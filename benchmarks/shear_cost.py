"""Where a scene's Newton iterations go: every step with its size, its Newton iterations (the
count history.csv reports), its cuts and the iterations of every attempt, the cut ones included
(a SNES monitor), stepped as `fingertip run` steps it (the output times are breakpoints) but
writing nothing. docs/benchmarks/friction.md, "The cost of the shear scene".

Run (serially, from the repository root; ~15-30 s for the coarse shear scene):
    PYTHONPATH=$PWD python benchmarks/shear_cost.py [SCENE] [KEY=VALUE ...]
SCENE a built-in scene or a TOML file (default: shear); KEY=VALUE scene overrides as `--set`
takes them, e.g. steps.tangent_start=false solver.snes_linesearch_type='"bt"'.
"""

import sys

from mpi4py import MPI

from fingertip_dolfinx.geometry.mesh import build_mesh
from fingertip_dolfinx.problem import FingertipProblem
from fingertip_dolfinx.scene import load_scene
from fingertip_dolfinx.stepping import TimeStepper


def main(source: str, overrides: list[str]) -> None:
    scene = load_scene(source, overrides)
    problem = FingertipProblem(build_mesh(scene.section, MPI.COMM_WORLD), scene.indenters,
                               scene.history, scene.materials, scene.model,
                               friction=[i.friction for i in scene.indenters])
    stepper = TimeStepper(problem, scene.steps, scene.petsc_options, linear=scene.linear)
    every = [0, 0]  # all iterations so far, and at the last report

    def count(snes, its, norm):
        every[0] += its > 0

    def report(r):
        d = r.diagnostics
        ratio = abs(d.get("tangential_force_N_per_mm", 0.0)) / abs(d["force_N_per_mm"])
        print(f"t = {r.time:9.6f} s  dt = {r.dt:9.6f} s  Newton {r.newton_iterations:2d}  "
              f"cuts {r.cuts}  every attempt {every[0] - every[1]:3d}  |Ft|/|Fn| = {ratio:.4f}",
              flush=True)
        every[1] = every[0]

    stepper.snes.setMonitor(count)
    try:
        reports = stepper.run(scene.history, scene.history.end_time,
                              breakpoints=scene.output_times, on_step=report)
    finally:
        stepper.close()
    print(f"{len(reports)} steps, {sum(r.newton_iterations for r in reports)} Newton iterations, "
          f"{every[0]} in every attempt, {sum(r.cuts for r in reports)} cuts")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "shear", sys.argv[2:])
