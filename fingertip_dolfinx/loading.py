"""Prescribed histories: the indenter displacement as a function of time.

A history knows its own breakpoints (the end of a ramp, say) so that the time stepper can land
on them exactly: stepping across a kink in the load smears it and costs accuracy for nothing.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .errors import InputError


@dataclass(frozen=True)
class PiecewiseLinear:
    """d(t) through the points (times[i], values[i]), constant after the last point."""

    times: tuple[float, ...]
    values: tuple[float, ...]

    def __post_init__(self):
        t = np.asarray(self.times, dtype=float)
        if len(self.times) != len(self.values) or len(self.times) < 2:
            raise InputError(
                "protocol", "a piecewise-linear path needs at least two (time, value) points "
                f"of equal count, got {len(self.times)} times and {len(self.values)} values."
            )
        if t[0] != 0.0 or np.any(np.diff(t) <= 0):
            raise InputError(
                "protocol.times", f"times must start at 0 and increase strictly, got {self.times}."
            )

    def __call__(self, t: float) -> float:
        return float(np.interp(t, self.times, self.values))

    @property
    def breakpoints(self) -> tuple[float, ...]:
        return tuple(self.times)


@dataclass(frozen=True)
class RampHold:
    """The paper's protocol: ramp to `depth` over `ramp_time`, then hold until `end_time`."""

    depth: float
    ramp_time: float
    end_time: float
    _path: PiecewiseLinear = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        if not (self.ramp_time > 0 and self.end_time >= self.ramp_time):
            raise InputError(
                "protocol",
                f"need 0 < ramp_time <= end_time, got ramp_time={self.ramp_time}, "
                f"end_time={self.end_time}.",
            )
        times = (0.0, self.ramp_time) + ((self.end_time,) if self.end_time > self.ramp_time else ())
        values = (0.0, self.depth) + ((self.depth,) if self.end_time > self.ramp_time else ())
        object.__setattr__(self, "_path", PiecewiseLinear(times, values))

    def __call__(self, t: float) -> float:
        return self._path(t)

    @property
    def breakpoints(self) -> tuple[float, ...]:
        return self._path.breakpoints


@dataclass(frozen=True)
class Sinusoid:
    """d(t) = offset + amplitude·sin(2π f t) for 0 <= t <= end_time (vibrotactile stimuli)."""

    amplitude: float
    frequency: float
    end_time: float
    offset: float = 0.0

    def __post_init__(self):
        if self.frequency <= 0 or self.end_time <= 0:
            raise InputError(
                "protocol", f"frequency and end_time must be positive, got {self.frequency}, "
                f"{self.end_time}."
            )

    def __call__(self, t: float) -> float:
        return self.offset + self.amplitude * math.sin(2 * math.pi * self.frequency * t)

    @property
    def breakpoints(self) -> tuple[float, ...]:
        # Peaks and zero crossings: a step should not jump over a reversal of the load.
        quarter = 0.25 / self.frequency
        n = int(self.end_time / quarter)
        return tuple(sorted({0.0, *(quarter * i for i in range(n + 1)), self.end_time}))


History = PiecewiseLinear | RampHold | Sinusoid


def history_from_dict(data: dict, where: str = "protocol") -> History:
    """Build a history from a scene file's `[protocol]` table."""
    kinds = {"ramp-hold": RampHold, "piecewise-linear": PiecewiseLinear, "sinusoid": Sinusoid}
    data = dict(data)
    kind = data.pop("kind", "ramp-hold")
    if kind not in kinds:
        raise InputError(f"{where}.kind", f"unknown protocol {kind!r}.", f"use one of {sorted(kinds)}.")
    cls = kinds[kind]
    allowed = [f for f in cls.__dataclass_fields__ if not f.startswith("_")]
    unknown = sorted(set(data) - set(allowed))
    if unknown:
        raise InputError(where, f"unknown keys {unknown} for a {kind} protocol.", f"allowed: {allowed}.")
    if cls is PiecewiseLinear:
        data = {k: tuple(float(x) for x in v) for k, v in data.items()}
    try:
        return cls(**data)
    except TypeError as err:
        raise InputError(where, f"incomplete {kind} protocol ({err}).", f"give {allowed}.") from None


def step_times(breakpoints: Sequence[float], t: float, dt: float, end_time: float) -> float:
    """The next time after `t` for a step of at most `dt` that lands on every breakpoint."""
    target = min(t + dt, end_time)
    for b in breakpoints:
        if t + 1e-12 < b < target - 1e-12:
            return b
    # Avoid leaving a sliver of a step before a breakpoint: stretch to it if it is close.
    for b in (*breakpoints, end_time):
        if target < b <= target + 0.25 * dt:
            return b
    return target
