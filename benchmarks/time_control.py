"""Benchmark: time steps chosen by Newton's effort (today) or by their error.

For two problems it prints, per step-size control: steps, Newton iterations, wall time (the
time stepping only) and the force error against a reference run with a much tighter tolerance:

- the confined ramp-and-hold of the Holmes–Mow tissue (a 1 mm column, 20 uniform P2/P1 cells,
  its drained top pushed down 0.01 mm over 100 s and held to 3000 s; studies.problems.
  ConfinedBlock). Errors: max |F − F_ref| over the run relative to the peak force, and the
  largest relative error in the hold;
- the 1pt scene held to 20 s (`protocol.end_time=20`; scene mesh). Errors: F at the end of the
  ramp (1 s) and at 20 s, and the largest relative error in the hold (F_ref interpolated).

Controls: today's (growth ×1.5 after easy steps; the confined run with the default
StepOptions, dt_max 10 s; the scene with its own dt_max 0.25 s), backward Euler + error control
(rtol 1e-3), BDF2 + error control (rtol 1e-3 and 1e-4); error control with dt_max the whole
run (and atol: 1e-12 on the column, where the tolerance is purely relative; the default 1e-6
mm/MPa on the scene). The confined problem adds fixed BDF2 steps of 1 s (what a hand-chosen
schedule costs);
its runs stop Newton at 1e-14 N/mm (the forces are ~1e-4 N/mm), the reference at 1e-15.

    .venv/bin/python benchmarks/time_control.py [--skip-scene]
"""

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

import fingertip_dolfinx  # noqa: F401  (sets up the DOLFINx wheel)
from fingertip_dolfinx.loading import RampHold
from fingertip_dolfinx.outputs import read_csv
from fingertip_dolfinx.physics import materials as mat
from fingertip_dolfinx.runner import run_scene
from fingertip_dolfinx.scene import load_scene
from fingertip_dolfinx.stepping import StepOptions, TimeStepper
from fingertip_dolfinx.studies.problems import ConfinedBlock

RAMP = RampHold(0.01, 100.0, 3000.0)
ERROR = {"control": "error", "dt_max": RAMP.end_time}
CONFINED = {
    "today (x1.5 to 10 s)": StepOptions(),
    "fixed BDF2, 1 s": StepOptions(scheme="bdf2", dt_initial=1.0, dt_max=1.0, growth=1.0),
    "BE + error, rtol 1e-3": StepOptions(rtol=1e-3, atol=1e-12, **ERROR),
    "BDF2 + error, rtol 1e-3": StepOptions(scheme="bdf2", rtol=1e-3, atol=1e-12, **ERROR),
    "BDF2 + error, rtol 1e-4": StepOptions(scheme="bdf2", rtol=1e-4, atol=1e-12, **ERROR),
}
CONFINED_REFERENCE = StepOptions(control="error", scheme="bdf2", rtol=1e-7, atol=1e-13,
                                 dt_initial=1e-3, dt_min=1e-9, dt_max=RAMP.end_time)
TIGHT_NEWTON = {"snes_rtol": 1e-11, "snes_atol": 1e-15, "snes_max_it": 30}
#: Forces here are ~1e-4 N/mm: the default snes_atol (1e-10 N/mm) would leave Newton errors
#: near 1e-6 of the solution, above what rtol = 1e-4 asks of the first steps from rest.
NEWTON = {"snes_atol": 1e-14}

SCENE_END = 20.0
SCENE = {
    "today (x1.5 to 0.25 s)": [],
    "BE + error, rtol 1e-3": ["steps.control=error", "steps.rtol=1e-3", "steps.dt_max=20"],
    "BDF2 + error, rtol 1e-3": ["steps.control=error", "steps.scheme=bdf2", "steps.rtol=1e-3",
                                "steps.dt_max=20"],
    "BDF2 + error, rtol 1e-4": ["steps.control=error", "steps.scheme=bdf2", "steps.rtol=1e-4",
                                "steps.dt_max=20"],
}
#: atol stays at its default (1e-6 mm, MPa): Newton's default residual tolerance (1e-10 N/mm;
#: 1e-12 fails on the bone's round-off) leaves errors near 1e-7 mm in the first steps.
SCENE_REFERENCE = ["steps.control=error", "steps.scheme=bdf2", "steps.rtol=1e-5",
                   "steps.dt_initial=0.01", "steps.dt_max=20"]


def confined(options: StepOptions, prefix: str, petsc=None) -> dict:
    column = ConfinedBlock(1, 20, RAMP, tissue=mat.SUBCUTANEOUS_BIPHASIC, width=0.1,
                           drained_top=True, top_displacement=True)
    stepper = TimeStepper(column, options, petsc, prefix=prefix)
    started = time.perf_counter()
    reports = stepper.run(RAMP, RAMP.end_time)
    wall = time.perf_counter() - started
    stepper.close()
    return {"t": np.array([0.0] + [r.time for r in reports]),
            "F": np.array([0.0] + [r.diagnostics["reaction"] for r in reports]),
            "steps": len(reports), "newton": sum(r.newton_iterations for r in reports),
            "wall": wall}


def scene_run(overrides: list[str], out: Path) -> dict:
    scene = load_scene("1pt", [f"protocol.end_time={SCENE_END:g}", *overrides])
    summary = run_scene(scene, out, progress=False)
    h = read_csv(out / "history.csv")
    return {"t": np.concatenate([[0.0], h["time_s"]]),
            "F": np.concatenate([[0.0], h["force_N_per_mm"]]),
            "steps": summary["time_steps"], "newton": summary["newton_iterations"],
            "wall": summary["wall_time_s"]}


def at(run: dict, t: float) -> float:
    i = int(np.argmin(np.abs(run["t"] - t)))
    assert abs(run["t"][i] - t) < 1e-9, (t, run["t"][i])
    return run["F"][i]


def hold_error(run: dict, ref: dict, start: float) -> float:
    hold = run["t"] >= start
    exact = np.interp(run["t"][hold], ref["t"], ref["F"])
    return float(np.max(np.abs(run["F"][hold] / exact - 1)))


def table(title: str, header: list[str], rows: list[list[str]]) -> None:
    print(f"\n{title}\n")
    print("| " + " | ".join(header) + " |")
    print("| --- | " + " | ".join("---:" for _ in header[1:]) + " |")
    for row in rows:
        print("| " + " | ".join(row) + " |")


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawTextHelpFormatter)
    parser.add_argument("--skip-scene", action="store_true", help="the confined column only")
    args = parser.parse_args()

    ref = confined(CONFINED_REFERENCE, "reference_", TIGHT_NEWTON)
    peak = np.max(np.abs(ref["F"]))
    rows = []
    for i, (name, options) in enumerate(CONFINED.items()):
        run = confined(options, f"confined{i}_", NEWTON)
        exact = np.interp(run["t"], ref["t"], ref["F"])
        rows.append([name, str(run["steps"]), str(run["newton"]), f"{run['wall']:.2f}",
                     f"{np.max(np.abs(run['F'] - exact)) / peak:.1e}",
                     f"{hold_error(run, ref, RAMP.ramp_time):.1e}"])
    table(f"Confined ramp-and-hold (reference: BDF2, rtol 1e-7, {ref['steps']} steps)",
          ["control", "steps", "Newton", "wall (s)", "max error / peak F", "max error in hold"],
          rows)
    if args.skip_scene:
        return

    with tempfile.TemporaryDirectory() as tmp:
        ref = scene_run(SCENE_REFERENCE, Path(tmp) / "reference")
        rows = []
        for i, (name, overrides) in enumerate(SCENE.items()):
            run = scene_run(overrides, Path(tmp) / f"run{i}")
            rows.append([name, str(run["steps"]), str(run["newton"]), f"{run['wall']:.1f}",
                         f"{at(run, 1.0) / at(ref, 1.0) - 1:+.1e}",
                         f"{at(run, SCENE_END) / at(ref, SCENE_END) - 1:+.1e}",
                         f"{hold_error(run, ref, 1.0):.1e}"])
    table(f"1pt scene held to {SCENE_END:g} s (reference: BDF2, rtol 1e-5, {ref['steps']} steps, "
          f"{ref['newton']} Newton iterations, {ref['wall']:.0f} s)",
          ["control", "steps", "Newton", "wall (s)", "F(1 s)", f"F({SCENE_END:g} s)",
           "max error in hold"], rows)


if __name__ == "__main__":
    main()
