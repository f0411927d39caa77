"""Protocols: every kind meets `LoadHistory`; the vibration protocol presses, holds and then
vibrates about the pressed depth, continuously, with its kinks as breakpoints."""

import math

import numpy as np
import pytest

from fingertip_dolfinx.errors import InputError
from fingertip_dolfinx.loading import (
    KINDS,
    LoadHistory,
    PiecewiseLinear,
    RampHold,
    Sinusoid,
    Vibration,
    history_from_dict,
)

TONE = Vibration(depth=1.0, ramp_time=1.0, hold_time=2.0, amplitudes=(0.05,),
                 frequencies=(250.0,), cycles=10)


@pytest.mark.parametrize("history", [
    RampHold(1.0, 1.0, 5.0), PiecewiseLinear((0, 1), (0, 1), end_time=3), Sinusoid(0.1, 5, 1),
    TONE])
def test_every_kind_meets_the_protocol(history):
    assert isinstance(history, LoadHistory)
    assert history.breakpoints[0] == 0.0 and history.breakpoints[-1] <= history.end_time
    assert history.deepest == pytest.approx(max(history(t) for t in
                                                np.linspace(0, history.end_time, 20001)),
                                            rel=1e-6)


def test_vibration_presses_holds_then_vibrates_about_the_pressed_depth():
    t_on = 3.0
    assert TONE.onset == t_on and TONE.end_time == pytest.approx(t_on + 10 / 250)
    assert TONE(0.5) == 0.5 and TONE(2.0) == 1.0 and TONE(t_on) == 1.0  # continuous at t_on
    quarter = t_on + 0.25 / 250
    assert TONE(quarter) == pytest.approx(1.05, rel=1e-12)  # the first peak
    assert min(abs(b - quarter) for b in TONE.breakpoints) < 1e-12 and t_on in TONE.breakpoints
    assert TONE.pressing == RampHold(1.0, 1.0, t_on)
    assert TONE.period == pytest.approx(4e-3)
    # a sum of tones: the slowest sets the length, the fastest the period
    two = Vibration(1.0, 1.0, 0.0, (0.02, 0.01), (10.0, 100.0), cycles=2)
    assert two.end_time == pytest.approx(1.2) and two.period == pytest.approx(0.01)
    s = 0.0123
    assert two(1.0 + s) == pytest.approx(
        1.0 + 0.02 * math.sin(2 * math.pi * 10 * s) + 0.01 * math.sin(2 * math.pi * 100 * s))


def test_vibration_from_a_scene_table_and_its_errors():
    data = {"kind": "vibration", "depth": 1.0, "ramp_time": 1.0, "hold_time": 0.5,
            "amplitudes": [0.05], "frequencies": [100]}
    assert history_from_dict(data) == Vibration(1.0, 1.0, 0.5, (0.05,), (100.0,))
    assert "vibration" in KINDS
    with pytest.raises(InputError, match="probe would leave the skin"):
        Vibration(0.04, 1.0, 0.0, (0.05,), (100.0,))
    with pytest.raises(InputError, match="one amplitude"):
        Vibration(1.0, 1.0, 0.0, (0.05, 0.01), (100.0,))
    with pytest.raises(InputError, match="must be positive"):
        Vibration(1.0, 1.0, 0.0, (0.05,), (-5.0,))
