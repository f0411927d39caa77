"""The two routes to the vibrating fingertip agree: the time-domain run (inertia, generalised-α)
fitted at its steady state equals the small-signal frequency response about the same held
state (held to the middle of the fitting window: the slow QLV terms relax on). At 10 Hz with
the fast-relaxation skin, a quiet start (press and hold in 10 ms steps, so the ramp's kink
leaves no ringing of the 49 Hz mode) and a 1 µm drive (linear: the second-order response is
~A/depth = 1e-3 of the first), the issue's 2 % holds; measured 0.16 % in modulus and 0.09° in
phase, 0.28 % between two fitting windows. The integrator's period error, (ωΔt)²/12 ~ 0.2 % of
the frequency at 40 steps a period, matters only where K is steep: 100 and 250 Hz need a fade-in
over tens of periods and two step sizes, minutes each: benchmarks/two_routes.py (README)."""

import math
import sys
from pathlib import Path

import pytest
from mpi4py import MPI

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from two_routes import compare  # noqa: E402

# Two long runs of a vibration, compared: run with `make test-slow`.
pytestmark = pytest.mark.slow


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="serial: one run per rank would clash")
def test_time_run_settles_on_the_frequency_response_at_10_hz():
    r = compare(10.0, amplitude=1e-3, cycles=4, periods=2, materials="fast-relaxation")
    assert r["rel"] < 0.02, r
    assert abs(r["phase_diff_deg"]) < math.degrees(0.02), r
