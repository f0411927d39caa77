"""Prescribed histories (protocols): the indenter displacement as a function of time.

Every protocol kind meets `LoadHistory`: d(t) in mm of indentation after first touch, its
`end_time`, its `breakpoints` (the end of a ramp, say: the time stepper lands on them exactly,
since stepping across a kink in the load smears it and costs accuracy for nothing), and its
`deepest` indentation (a protocol that never presses, deepest <= 0, is refused by the scene).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, fields
from typing import Protocol, runtime_checkable

import numpy as np

from .errors import InputError
from .validation import check_keys


@runtime_checkable
class LoadHistory(Protocol):
    """What the time stepper and the run need from a protocol."""

    end_time: float

    def __call__(self, t: float) -> float:
        """Indentation (mm) at time t (s)."""

    @property
    def breakpoints(self) -> tuple[float, ...]:
        """Times (s) at which d(t) has a kink: steps land on them."""

    @property
    def deepest(self) -> float:
        """The largest indentation (mm) over the protocol."""


@dataclass(frozen=True)
class PiecewiseLinear:
    """d(t) through the points (times[i], values[i]), constant after the last point until
    `end_time` (default: the last point's time)."""

    times: tuple[float, ...]
    values: tuple[float, ...]
    end_time: float | None = None

    def __post_init__(self):
        object.__setattr__(self, "times", tuple(float(x) for x in self.times))
        object.__setattr__(self, "values", tuple(float(x) for x in self.values))
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
        end = self.times[-1] if self.end_time is None else float(self.end_time)
        if end < self.times[-1]:
            raise InputError("protocol.end_time", f"{end} s ends before the last point "
                             f"({self.times[-1]} s).", "drop the later points or run longer.")
        object.__setattr__(self, "end_time", end)

    def __call__(self, t: float) -> float:
        return float(np.interp(t, self.times, self.values))

    @property
    def breakpoints(self) -> tuple[float, ...]:
        return tuple(self.times)

    @property
    def deepest(self) -> float:
        return max(self.values)


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

    @property
    def deepest(self) -> float:
        return max(self.depth, 0.0)


@dataclass(frozen=True)
class Sinusoid:
    """d(t) = offset + amplitude·sin(2π f t + phase) for 0 <= t <= end_time (vibrotactile
    stimuli). `phase_deg = -90` with `offset = amplitude` starts from rest: d = A(1 − cos 2πft)."""

    amplitude: float
    frequency: float
    end_time: float
    offset: float = 0.0
    phase_deg: float = 0.0

    def __post_init__(self):
        if self.frequency <= 0 or self.end_time <= 0:
            raise InputError(
                "protocol", f"frequency and end_time must be positive, got {self.frequency}, "
                f"{self.end_time}."
            )

    def __call__(self, t: float) -> float:
        phase = math.radians(self.phase_deg)
        return self.offset + self.amplitude * math.sin(2 * math.pi * self.frequency * t + phase)

    @property
    def deepest(self) -> float:
        return self.offset + abs(self.amplitude)

    @property
    def breakpoints(self) -> tuple[float, ...]:
        # Peaks and zero crossings: a step should not jump over a reversal of the load.
        quarter = 0.25 / self.frequency
        shift = (-self.phase_deg / 360.0 / self.frequency) % quarter
        n = int((self.end_time - shift) / quarter)
        marks = (shift + quarter * i for i in range(n + 1))
        return tuple(sorted({0.0, *(m for m in marks if m <= self.end_time), self.end_time}))


#: Any of the built-in protocol kinds (each meets `LoadHistory`).
History = PiecewiseLinear | RampHold | Sinusoid


KINDS = {"ramp-hold": RampHold, "piecewise-linear": PiecewiseLinear, "sinusoid": Sinusoid}


def history_from_dict(data: dict, where: str = "protocol") -> LoadHistory:
    """Build a protocol from a scene file's `[protocol]` table (`kind` picks the class)."""
    data = dict(data)
    kind = data.pop("kind", "ramp-hold")
    if kind not in KINDS:
        raise InputError(f"{where}.kind", f"unknown protocol {kind!r}.",
                         f"use one of {', '.join(KINDS)}.")
    cls = KINDS[kind]
    allowed = [f.name for f in fields(cls) if f.init]
    required = [f.name for f in fields(cls) if f.init and f.default is dataclasses.MISSING]
    check_keys(f"{where} ({kind})", data, allowed, required)
    for key, value in data.items():
        if isinstance(value, list):
            data[key] = tuple(value)
        if isinstance(value, bool) or not isinstance(value, int | float | list | tuple):
            raise InputError(f"{where}.{key}", f"must be a number or a list of numbers, got "
                             f"{value!r}.", "write a number.")
    return cls(**data)


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
