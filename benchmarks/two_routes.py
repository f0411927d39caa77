"""The two routes to the vibrating fingertip, side by side: the time-domain run (inertia,
generalised-α) against the small-signal frequency response about the same held state.

For a drive d(t) = d0 + w(t) A sin(ωt) after the hold (w the protocol's `fade_in` envelope,
1 without), the time run's force is fitted over its last `--periods` periods
(studies.signals.steady_state, with a trend for the ongoing relaxation) and divided by A; the
frequency route gives K(ω) = δf/δd about a held state. They must agree
where the time run has reached its steady state (its start-up transients decayed) and A is
small enough for the response to be linear. The reference is K about the state held until
the middle of the fitting window (`reference_stiffness`: the slow QLV drift goes on).

The fast-relaxation materials (milliseconds Prony terms) damp the skin only; the subcutaneous
tissue (undrained, no viscosity of its own) keeps the fingertip's free modes ringing for
hundreds of periods. Switching the sinusoid on (w = 1) strikes them with O(1) of the drive;
`--fade-in N` lets the amplitude rise over N periods (loading.Vibration), which strikes a mode
at f_n with about (|f_n − f| N/f)^-3 of it. The residual transient is estimated by the same
fit over the `--periods` periods before the last ones: `drift` = |K_last − K_before|/|K_freq|
(a settled run has drift → 0; a free mode beating with the drive shows as drift).

The contact is the scene's penalty (γ0 = 100): a force with a potential. Nitsche's θ = 0 has
none, and at 250 Hz steps of 67 and 50 µs (60 and 80 a period) let an oscillation near the
steps' Nyquist frequency grow at the contact's edges (contact.py); the penalty runs them.

    PYTHONPATH=. python benchmarks/two_routes.py [--frequencies 10 100 250] [--cycles 10]
        [--fade-in 0] [--periods 3]
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
#: The press and hold in steps of at most 10 ms: the ramp's kink (a velocity jump of 1 mm/s)
#: strikes the fingertip's free modes (49, 79.5 Hz ... on this mesh, ~3 µm for the first,
#: more than the 1 µm drive), and nothing in the model damps them; the integrator (ρ∞ = 0.8)
#: does, by a factor of about ρ∞ per step of ωΔt >> 1: 200 steps of 10 ms take them to
#: nothing, 6 steps of up to 0.25 s (the scene's) do not.
QUIET_START = ["steps.dt_max=0.01", "steps.dt_initial=0.01"]


def scene_at(frequency: float, amplitude: float, cycles: float, materials: str,
             fade_in: float = 0.0, extra=()):
    return load_scene("vibrotactile", [
        *COARSE, f"materials.set={materials}", f"protocol.amplitudes=[{amplitude}]",
        f"protocol.frequencies=[{frequency}]", f"protocol.cycles={cycles}",
        f"protocol.fade_in={fade_in}", "output.pictures=false", "output.receptors=false",
        "output.times=[2.0]", *QUIET_START, *extra])


def fitted_stiffness(t, force, frequency: float, amplitude: float, periods: float,
                     end: float | None = None) -> complex:
    """K from the force over the `periods` periods ending at `end` (default: the last ones).
    The fit's Z multiplies e^{iωt}; the drive is A sin ωt = Re(−iA e^{iωt}): K = Z/(−iA)."""
    keep = t <= (t[-1] if end is None else end) + 1e-9 / frequency
    return steady_state(t[keep], force[keep], frequency, periods, trend=True) / (-1j * amplitude)


def reference_stiffness(scene, frequency: float, middle: float, args) -> complex:
    """K(ω) of the frequency route about the state held until the middle of the time run's
    fitting window (`middle` s after the onset). The skin's slow QLV terms (2.1 s, 9.4 s) go on
    relaxing under the vibration; the fit sees the tangent of its window, not of the onset:
    at 100 Hz, where K is a small difference of stiffness and inertia, K about the onset
    (hold 1 s) and about 0.425 s later differ by 3.6 % (−7.72e-5 against −9.11e-5 N/mm per
    mm in Re K; coarse mesh, fast-relaxation set)."""
    hold = scene.history.hold_time + middle
    *same, extra = args
    held = scene_at(*same, [*extra, f"protocol.hold_time={float(hold)!r}"])
    _, (response,) = small_signal_response(held, [frequency], state="held")
    return response.stiffness


def compare(frequency: float, amplitude: float, cycles: float, periods: float,
            materials: str, fade_in: float = 0.0, extra=()) -> dict:
    scene = scene_at(frequency, amplitude, cycles, materials, fade_in, extra)
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as out:
        run_scene(scene, out, progress=False)
        history = Result(out).history
    time_s = time.perf_counter() - started
    t, force = history["time_s"], history["force_N_per_mm"]
    on = t >= scene.history.onset - 1e-12
    t, force = t[on] - scene.history.onset, force[on]
    K_time = fitted_stiffness(t, force, frequency, amplitude, periods)
    K_before = fitted_stiffness(t, force, frequency, amplitude, periods,
                                end=t[-1] - periods / frequency)
    K_freq = reference_stiffness(scene, frequency, t[-1] - periods / (2 * frequency),
                                 (frequency, amplitude, cycles, materials, fade_in, extra))
    return {"f": frequency, "K_time": K_time, "K_freq": K_freq,
            "rel": abs(K_time - K_freq) / abs(K_freq),
            "phase_diff_deg": math.degrees(np.angle(K_time / K_freq)),
            "drift": abs(K_time - K_before) / abs(K_freq),
            "steps": len(t), "time_s": time_s, "t": t, "force": force}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frequencies", type=float, nargs="+", default=[10.0, 100.0, 250.0])
    parser.add_argument("--amplitude", type=float, default=1e-3, help="mm (default 1 µm)")
    parser.add_argument("--cycles", type=float, default=10)
    parser.add_argument("--periods", type=float, default=3)
    parser.add_argument("--materials", default="fast-relaxation")
    parser.add_argument("--fade-in", type=float, default=0.0,
                        help="periods over which the amplitude rises (loading.Vibration)")
    parser.add_argument("--set", dest="extra", action="append", default=[],
                        help="more scene overrides, e.g. steps.steps_per_period=80")
    parser.add_argument("--save", default=None, help="directory for the force histories (npz)")
    parser.add_argument("--steps-per-period", type=int, nargs="+", default=[40],
                        help="one run each; two or more: Richardson extrapolation in Δt")
    a = parser.parse_args()
    print(f"{'f (Hz)':>7} {'steps/T':>7} {'K time (N/mm per mm)':>28} {'K frequency':>28} "
          f"{'|ΔK|/|K|':>9} {'Δphase':>8} {'drift':>7} {'steps':>6} {'wall':>7}")
    for f in a.frequencies:
        runs = []
        for n in a.steps_per_period:
            r = compare(f, a.amplitude, a.cycles, a.periods, a.materials, a.fade_in,
                        [*a.extra, f"steps.steps_per_period={n}"])
            runs.append(r)
            print(f"{r['f']:7.1f} {n:7d} {r['K_time']:28.5g} {r['K_freq']:28.5g} "
                  f"{r['rel']:9.2%} {r['phase_diff_deg']:7.2f}° {r['drift']:7.2%} "
                  f"{r['steps']:6d} {r['time_s']:6.0f}s", flush=True)
            if a.save:
                np.savez(f"{a.save}/two_routes_{f:g}Hz_fade{a.fade_in:g}_{n}.npz", t=r["t"],
                         force=r["force"], K_freq=r["K_freq"], amplitude=a.amplitude)
        if len(runs) >= 2:
            print(richardson(runs[-2:], a.steps_per_period[-2:]), flush=True)


def richardson(runs: list[dict], steps: list[int]) -> str:
    """The time runs' K extrapolated to Δt → 0 from two step sizes, assuming the integrator's
    second order (tests/test_dynamics.py): K0 = K2 + (K2 − K1)/(r² − 1), r = n2/n1. The
    generalised-α error at 40 steps a period is mostly a shift of the frequency the discrete
    system answers at (≈ (ωΔt)²/12 = 0.2 %), large where K(ω) is steep against its size."""
    k1, k2 = runs[0]["K_time"], runs[1]["K_time"]
    ratio = steps[1] / steps[0]
    k0 = k2 + (k2 - k1) / (ratio**2 - 1)
    kf = runs[1]["K_freq"]
    return (f"{runs[1]['f']:7.1f} {'Δt→0':>7} {k0:28.5g} {kf:28.5g} "
            f"{abs(k0 - kf) / abs(kf):9.2%} {np.degrees(np.angle(k0 / kf)):7.2f}°  "
            f"(Richardson from {steps[0]} and {steps[1]} steps a period)")


if __name__ == "__main__":
    main()
