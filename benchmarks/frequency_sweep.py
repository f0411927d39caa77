"""Benchmark: the frequency route on the `vibrotactile` scene's own mesh (target: the 40-frequency
sweep in < 60 s on one core).

Prints the dofs, the time for the pressed state (the pre-indentation's quasi-static steps),
the assembly, the time per frequency (one MUMPS LU of the real block form, 2 × dofs), the
sweep's total, the resonances it resolves (and the bands it does not) and |Z| with its
phase at 10, 100 and 250 Hz (the lead's comparison points with the time-domain route).

    .venv/bin/python benchmarks/frequency_sweep.py [--frequencies 1:1000:40] [--state held]
                                                   [--set key=value ...]
"""

import math
import time

import numpy as np
from mpi4py import MPI
from timing import scene_and_out, scene_parser

import fingertip_dolfinx  # noqa: F401  (sets up the DOLFINx wheel)
from fingertip_dolfinx.frequency_response import pressing_of, run_frequency_response
from fingertip_dolfinx.geometry.mesh import build_mesh
from fingertip_dolfinx.harmonic import HarmonicSolver, linearise, press
from fingertip_dolfinx.problem import FingertipProblem


def main():
    parser = scene_parser(__doc__, "vibrotactile")
    parser.add_argument("--frequencies", default="1:1000:40")
    parser.add_argument("--state", default="held", choices=("held", "relaxed"))
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    scene, out = scene_and_out(args, comm)
    started = time.perf_counter()
    s = run_frequency_response(scene, out, frequencies=args.frequencies, state=args.state,
                               progress=False, comm=comm)
    wall = time.perf_counter() - started
    n = len(s["harmonic"]["frequencies_Hz"])
    if comm.rank == 0:
        print(f"scene {scene.name} ({args.state}), {comm.size} rank(s): {s['dofs']} dofs "
              f"({2 * s['dofs']} real unknowns per frequency)")
        print(f"pressed state: {s['pressed_state']['wall_time_s']:.2f} s "
              f"({s['pressed_state']['steps']} steps, force {s['pressed_state']['force']:.4g} "
              "N/mm)")
        print(f"assembly of K, M, B, K_v: {s['assembly_s']:.2f} s")
        print(f"sweep: {n} frequencies in {s['solve_s_total']:.2f} s "
              f"({s['solve_s_mean']:.3f} s per frequency; sampling and files included in the "
              f"total wall time {wall:.1f} s)")
        for kind, values in s["resonances_Hz"].items():
            print(f"resonances resolved ({kind}): {', '.join(f'{f:.4g}' for f in values)} Hz")
        if s["resonance_warning"]:
            print(s["resonance_warning"])
    _probe(scene, args.state, comm)


def _probe(scene, state, comm) -> None:
    """|Z| and its phase at 10, 100 and 250 Hz (a second pressed state: the sweep's own
    solver is closed)."""
    problem = FingertipProblem(build_mesh(scene.section, comm), scene.indenters, scene.history,
                               scene.materials, scene.model)
    press(problem, pressing_of(scene), state, scene.steps, scene.petsc_options)
    solver = HarmonicSolver(linearise(problem))
    for f in (10.0, 100.0, 250.0):
        r = solver.solve(f)
        if comm.rank == 0:
            print(f"{f:5g} Hz: K = {r.stiffness.real:.4g} {r.stiffness.imag:+.4g}i N/mm per mm; "
                  f"|Z| = {abs(r.impedance):.4g} N·s/mm per mm, phase "
                  f"{math.degrees(np.angle(r.impedance)):.2f}°")
    solver.close()


if __name__ == "__main__":
    main()
