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


def test_fade_in_rises_smoothly_to_the_full_tone():
    """w = x − sin(2πx)/2π: the load, its velocity and its acceleration are continuous at the
    onset and at the fade's end (C2), and the tone is the unfaded one after the fade."""
    faded = Vibration(1.0, 1.0, 1.0, (0.05,), (100.0,), cycles=6, fade_in=4)
    plain = Vibration(1.0, 1.0, 1.0, (0.05,), (100.0,), cycles=6)
    assert faded.fade_end == pytest.approx(2.04) and faded.fade_end in faded.breakpoints
    for t in (2.045, 2.0537, 2.06):
        assert faded(t) == pytest.approx(plain(t), rel=1e-15)
    h = 1e-6  # one-sided differences of d: jumps in d' or d'' would show at O(1)/O(1/h)
    for t0 in (faded.onset, faded.fade_end):
        left = [faded(t0 - k * h) for k in (0, 1, 2)]
        right = [faded(t0 + k * h) for k in (0, 1, 2)]
        assert (right[1] - right[0]) / h == pytest.approx((left[0] - left[1]) / h, abs=1e-3)
        acc_r = (right[2] - 2 * right[1] + right[0]) / h**2
        acc_l = (left[0] - 2 * left[1] + left[2]) / h**2
        assert abs(acc_r - acc_l) < 0.05 * (2 * math.pi * 100) ** 2 * 0.05
    # unfaded: the onset velocity jumps to 2π f A
    assert (plain(2.0 + h) - plain(2.0)) / h == pytest.approx(2 * math.pi * 100 * 0.05, rel=1e-3)
    with pytest.raises(InputError, match="fade must fit"):
        Vibration(1.0, 1.0, 0.0, (0.05,), (100.0,), cycles=4, fade_in=4)
