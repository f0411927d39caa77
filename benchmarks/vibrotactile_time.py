"""Benchmark: the vibrotactile scene in the time domain (inertia, generalised-α).

Runs the `vibrotactile` scene (1 mm bar, 1 mm press in 1 s, hold, then 50 µm at 250 Hz for 10
periods) and prints the dofs, the steps and Newton iterations before and after the vibration's
onset, the wall time per step and in total, and the steady-state force at the drive frequency:
the complex amplitude Z_F of the indenter force fitted over the last `--periods` periods
(`studies.signals.steady_state`, with a trend for the skin's ongoing QLV relaxation), its
modulus, the dynamic stiffness |Z_F|/A and the phase of the force relative to the drive
displacement (positive: the force leads, as a damped system's does).

    .venv/bin/python benchmarks/vibrotactile_time.py [--set key=value ...] [--periods 3]
    .venv/bin/mpiexec -n 2 .venv/bin/python benchmarks/vibrotactile_time.py

Outputs that cost time per step and do not enter the numbers (fields for ParaView, pictures)
are off unless `--set output.fields=every-step --set output.field_every=1` etc. asks for them.
"""

import cmath
import math
import time

import numpy as np
from mpi4py import MPI
from timing import scene_and_out, scene_parser

import fingertip_dolfinx  # noqa: F401  (sets up the DOLFINx wheel)
from fingertip_dolfinx.outputs import read_csv
from fingertip_dolfinx.runner import run_scene
from fingertip_dolfinx.studies.signals import steady_state

QUIET = ["output.field_every=100000", "output.pictures=false"]


def main():
    parser = scene_parser(__doc__, "vibrotactile")
    parser.add_argument("--periods", type=float, default=3.0, help="periods fitted (the last)")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    scene, out = scene_and_out(args, comm, QUIET + args.overrides)
    history = scene.history

    started = time.perf_counter()
    summary = run_scene(scene, out, progress=False)
    wall = time.perf_counter() - started
    if comm.rank != 0:
        return
    h = read_csv(out / "history.csv")
    report(scene, history, summary, h, wall, args.periods)


def report(scene, history, summary, h, wall: float, periods: float) -> None:
    t, its, step_wall = h["time_s"], h["newton_iterations"], h["wall_time_s"]
    after = t > history.onset + 1e-12
    print(f"scene {scene.name}: {summary['dofs']} dofs, {summary['mesh']['cells']} cells, "
          f"{MPI.COMM_WORLD.size} rank(s); scheme {scene.steps.scheme}, "
          f"rho_inf {scene.steps.rho_inf}, {scene.steps.steps_per_period} steps per period")
    for name, part in (("press + hold", ~after), ("vibration", after)):
        n = int(part.sum())
        print(f"{name}: {n} steps, {int(its[part].sum())} Newton iterations "
              f"({its[part].sum() / max(n, 1):.2f} per step), {step_wall[part].sum():.1f} s "
              f"({step_wall[part].sum() / max(n, 1):.3f} s per step), cuts "
              f"{int(h['cuts'][part].sum())}")
    print(f"total: {len(t)} steps, {int(its.sum())} Newton iterations, wall {wall:.1f} s "
          f"(stepping {step_wall.sum():.1f} s)")
    frequency = max(history.frequencies)
    amplitude = history.amplitudes[int(np.argmax(history.frequencies))]
    drive = -1j * amplitude  # d − depth = A sin ω(t − t_on) = Re(−iA e^{iω(t − t_on)})
    s = t[after] - history.onset
    for column in ("force_N_per_mm", "reaction_N_per_mm"):
        Z = steady_state(s, h[column][after], frequency, periods, trend=True)
        print(f"{column} at {frequency:g} Hz over the last {periods:g} periods: "
              f"|Z| = {abs(Z):.5g} N/mm, |Z|/A = {abs(Z) / amplitude:.5g} N/mm per mm, phase "
              f"relative to the displacement {math.degrees(cmath.phase(Z / drive)):+.2f} deg; "
              f"{stationarity(s, h[column][after], frequency, periods)}")
    mean = h["force_N_per_mm"][(t > history.onset - 1e-9) & (t < history.onset + 1e-9)]
    if len(mean):
        print(f"static force at the onset {mean[0]:.5g} N/mm")


def stationarity(t, signal, frequency: float, periods: float) -> str:
    """How far from a steady state the window is: |Z| over the last single period against the
    last `periods`, and the rms of what the fit leaves (transients, harmonics) over |Z|."""
    Z = steady_state(t, signal, frequency, periods, trend=True)
    last = steady_state(t, signal, frequency, 1.0, trend=True)
    window = t >= t[-1] - periods / frequency - 1e-9 / frequency
    w = 2 * math.pi * frequency
    rest = signal[window] - (Z * np.exp(1j * w * t[window])).real
    rest = rest - np.polyval(np.polyfit(t[window], rest, 1), t[window])
    return (f"|Z| over the last period / over {periods:g}: {abs(last) / abs(Z):.3f}, rms of "
            f"the rest / |Z|: {np.std(rest) / abs(Z):.3f}")


if __name__ == "__main__":
    main()
