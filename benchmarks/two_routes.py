"""The two routes to the vibrating fingertip, side by side: the time-domain run (inertia,
generalised-α) against the small-signal frequency response about the same held state.

For a drive d(t) = d0 + A sin(ωt) after the hold, the time run's force is fitted over its last
`--periods` periods (studies.signals.steady_state, with a trend for the ongoing relaxation) and
divided by A; the frequency route gives K(ω) = δf/δd about the state at the end of the hold.
They must agree where the time run has reached its steady state (its start-up transients
decayed) and A is small enough for the response to be linear. The fast-relaxation materials
(milliseconds Prony terms in the skin) supply the damping; the paper's set has almost none at
these frequencies (loss ~ g_i/(ωτ_i) < 1e-3 above 10 Hz) and never settles (README).

    PYTHONPATH=. python benchmarks/two_routes.py [--frequencies 10 100 250] [--cycles 10]
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time

import numpy as np

from fingertip_dolfinx.frequency_response import small_signal_response
from fingertip_dolfinx.result import Result
from fingertip_dolfinx.runner import run_scene
from fingertip_dolfinx.scene import load_scene
from fingertip_dolfinx.studies.signals import steady_state

COARSE = ["section.mesh.min_size=0.2", "section.mesh.max_size=1.0", "section.mesh.bone_size=2.0"]


def scene_at(frequency: float, amplitude: float, cycles: float, materials: str):
    return load_scene("vibrotactile", [
        *COARSE, f"materials.set={materials}", f"protocol.amplitudes=[{amplitude}]",
        f"protocol.frequencies=[{frequency}]", f"protocol.cycles={cycles}",
        "output.pictures=false", "output.receptors=false", "output.times=[2.0]"])


def compare(frequency: float, amplitude: float, cycles: float, periods: float,
            materials: str) -> dict:
    scene = scene_at(frequency, amplitude, cycles, materials)
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as out:
        run_scene(scene, out, progress=False)
        history = Result(out).history
    time_s = time.perf_counter() - started
    t, force = history["time_s"], history["force_N_per_mm"]
    on = t >= scene.history.onset - 1e-12
    fitted = steady_state(t[on] - scene.history.onset, force[on], frequency, periods,
                          trend=True) / amplitude
    # the fit's Z multiplies e^{iωt}; the drive is A sin ωt = Re(−iA e^{iωt}): K = Z/(−i)
    K_time = fitted / (-1j)
    _, (response,) = small_signal_response(scene, [frequency], state="held")
    K_freq = response.stiffness
    return {"f": frequency, "K_time": K_time, "K_freq": K_freq,
            "rel": abs(K_time - K_freq) / abs(K_freq),
            "phase_diff_deg": math.degrees(np.angle(K_time / K_freq)),
            "steps": len(t), "time_s": time_s}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frequencies", type=float, nargs="+", default=[10.0, 100.0, 250.0])
    parser.add_argument("--amplitude", type=float, default=1e-3, help="mm (default 1 µm)")
    parser.add_argument("--cycles", type=float, default=10)
    parser.add_argument("--periods", type=float, default=3)
    parser.add_argument("--materials", default="fast-relaxation")
    a = parser.parse_args()
    print(f"{'f (Hz)':>7} {'K time (N/mm per mm)':>28} {'K frequency':>28} {'|ΔK|/|K|':>9} "
          f"{'Δphase':>8} {'steps':>6} {'wall':>7}")
    for f in a.frequencies:
        r = compare(f, a.amplitude, a.cycles, a.periods, a.materials)
        print(f"{r['f']:7.1f} {r['K_time']:28.5g} {r['K_freq']:28.5g} {r['rel']:9.2%} "
              f"{r['phase_diff_deg']:7.2f}° {r['steps']:6d} {r['time_s']:6.0f}s", flush=True)


if __name__ == "__main__":
    main()
