"""TouchSim's ramp-and-hold indentations on the finite-element finger: the calibrated afferents'
rates in the ramp and hold phases next to TouchSim's own (docs/benchmarks/afferents.md).

TouchSim's stimulus (`stim_ramp`, 0.5 mm pin): a linear ramp to the depth in 50 ms, a hold,
and a ramp off over the last 50 ms of 1 s. Its responses (all 17 fits under the pin, noise off)
are in tests/data/touchsim_reference.json (scripts/touchsim_reference.py). The package's side:
the 1 mm bar (round tip of radius 0.5 mm, the plane-strain stand-in for the pin) pressed into
the coarse section of the damped-fingerpad materials (the set the calibration used) on the
same ramp, held to 0.95 s, quasi-static (TouchSim's mechanics has no inertia either); the
compressive stress at the site under the bar of each class, fed to every fit of the class with
the calibrated input scale (`data/receptors/calibrated.toml`). Rates: spikes in the ramp
(0-50 ms) and in the hold (50-950 ms) per second, the mean over the class's fits.

    PYTHONPATH=. python benchmarks/touchsim_ramps.py [OUT]   # OUT default ./touchsim-ramps

Each depth is one run (~1-2 min on the coarse mesh); a run already in OUT is reused.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from fingertip_dolfinx.afferents.receptors import QUANTITIES, load_receptors
from fingertip_dolfinx.afferents.transduction import site_inputs, spike_times

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "tests" / "data" / "touchsim_reference.json"
DEPTHS = (1.0, 0.25)  # mm: TouchSim's ramps under its 0.5 mm pin in the reference
RAMP, HOLD_END = 0.05, 0.95  # s: TouchSim's ramp_len; the hold's end before its ramp off
SCENE = """name = "touchsim-ramp"
description = "1 mm bar: TouchSim's ramp, {depth:g} mm in 50 ms, held"
[section]
file = "male-index"
[section.mesh]
min_size = 0.2
max_size = 1.0
bone_size = 2.0
refine_half_width = 3.0
refine_depth = 1.5
[materials]
set = "damped-fingerpad"
[[indenters]]
file = "bar"
centre_x = 0.0
[protocol]
kind = "ramp-hold"
depth = {depth:g}
ramp_time = 0.05
end_time = 0.95
[model]
displacement_degree = 2
subcutaneous = "biphasic"
skin_viscoelastic = true
[steps]
dt_initial = 0.005
dt_max = 0.05
[output]
times = [0.95]
depths = [0.75]
profile_half_width = 6.0
pictures = false
receptors = "calibrated"
"""


def run_ramp(depth: float, out: Path) -> Path:
    """The finite-element run of the ramp to `depth` (reused if `out` holds it)."""
    from fingertip_dolfinx.runner import run
    from fingertip_dolfinx.scene import load_scene

    if not (out / "receptors.csv").exists():
        out.mkdir(parents=True, exist_ok=True)
        (out / "scene.toml").write_text(SCENE.format(depth=depth))
        run(load_scene(out / "scene.toml"), out, progress=False)
    return out


def phase_rates(trains) -> np.ndarray:
    """(ramp, hold) rates (spikes/s) per spike train."""
    return np.array([[np.sum(t <= RAMP) / RAMP,
                      np.sum((t > RAMP) & (t <= HOLD_END)) / (HOLD_END - RAMP)] for t in trains])


def site_history(run: Path, cls):
    """(t, s): the class's quantity (compression positive) at its site under the bar, from
    rest (t = 0, s = 0) through the run's steps."""
    from fingertip_dolfinx.result import Result

    table = Result(run).receptors()
    column, sign, _ = QUANTITIES[cls.quantity]
    rows = (table["class"] == cls.name) & (table["x_mm"] == 0.0)
    return (np.concatenate([[0.0], table["time_s"][rows]]),
            np.concatenate([[0.0], sign * table[column][rows]]))


def hold_mean(t, s) -> float:
    """The mean of s over the hold (RAMP to HOLD_END; the steps' values joined linearly)."""
    grid = np.linspace(RAMP, HOLD_END, 9001)
    return float(np.mean(np.interp(grid, t, s)))


def package_rates(run: Path, cls):
    """(ramp, hold) rates of every fit of `cls` at the site under the bar, and the stress
    there at the end of the ramp (MPa)."""
    t, s = site_history(run, cls)
    aff = cls.saal.afferents(cls.name)
    grid = np.arange(int(round(HOLD_END * aff.fs)) + 1) / aff.fs
    static, dynamic = site_inputs(np.interp(grid, t, s), aff.fs, cls.saal.input_scale,
                                  cls.saal.kappa(cls.name))
    trains = spike_times(aff, np.tile(static, (len(aff), 1)), np.tile(dynamic, (len(aff), 1)))
    return phase_rates(trains), float(np.interp(RAMP, t, s))


def touchsim_rates(depth: float, cls: str):
    """(ramp, hold) rates of TouchSim's fits of `cls` on its ramp, and its c_s (MPa/mm)."""
    ref = json.loads(REFERENCE.read_text())
    rec = next(r for r in ref["stimuli"] if r["label"] == f"ramp {depth:g} mm, 0.5 mm pin")
    trains = [(np.asarray(r["spike_samples"]) + 1) / rec["fs"] for r in rec["responses"]
              if r["class"] == cls]
    return phase_rates(trains), rec["input"][cls]["c_s"]


def compare(out: Path) -> list[dict]:
    population = load_receptors("calibrated")
    rows = []
    for depth in DEPTHS:
        run = run_ramp(depth, out / f"ramp-{depth:g}mm")
        for cls in population.classes:
            ours, stress = package_rates(run, cls)
            theirs, c_s = touchsim_rates(depth, cls.name)
            for k, phase in enumerate(("ramp 0-50 ms", "hold 50-950 ms")):
                rows.append({"depth": depth, "phase": phase, "class": cls.name,
                             "touchsim": theirs[:, k].mean(), "package": ours[:, k].mean(),
                             "input_ratio": cls.saal.input_scale * stress / (c_s * depth)})
    return rows


def main(out: Path) -> None:
    rows = compare(out)
    print("| stimulus (0.5 mm pin; 1 mm bar) | class | TouchSim (spikes/s) | this package "
          "(spikes/s) | ratio | input ratio at 50 ms |")
    print("| --- | --- | --- | --- | --- | --- |")
    for r in rows:
        ratio = r["package"] / r["touchsim"] if r["touchsim"] > 0 else float("nan")
        print(f"| ramp {r['depth']:g} mm, {r['phase']} | {r['class']} | {r['touchsim']:.3g} | "
              f"{r['package']:.3g} | {ratio:.2g} | {r['input_ratio']:.2f} |")


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "touchsim-ramps"))
