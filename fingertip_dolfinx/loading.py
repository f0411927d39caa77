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
from .force_control import NormalForce, normal_force_from_dict
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
    """Indentation d(t) through the points (times[i], values[i]), constant after the last point.

    Parameters
    ----------
    times : tuple of float
        Increasing times (s), the first 0.
    values : tuple of float
        Indentation (mm after first touch) at each time.
    end_time : float or None, optional
        The protocol's end (s); None: the last point's time.
    """

    times: tuple[float, ...]  # s, from 0, increasing
    values: tuple[float, ...]  # mm of indentation after first touch, one per time
    end_time: float | None = None  # s (default: the last time)

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
    """The paper's protocol: ramp to `depth` over `ramp_time`, then hold until `end_time`.

    Parameters
    ----------
    depth : float
        The indentation reached (mm after first touch), positive.
    ramp_time : float
        Duration of the linear ramp (s).
    end_time : float
        End of the hold (s), at least `ramp_time`.
    """

    depth: float  # mm of indentation after first touch
    ramp_time: float  # s
    end_time: float  # s, >= ramp_time
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
    """Indentation d(t) = offset + amplitude·sin(2π f t + phase) for 0 <= t <= end_time.

    ``phase_deg = -90`` with ``offset = amplitude`` starts from rest: d = A(1 − cos 2πft).

    Parameters
    ----------
    amplitude : float
        Amplitude (mm).
    frequency : float
        Frequency f (Hz).
    end_time : float
        The protocol's end (s).
    offset : float, optional
        Mean indentation (mm).
    phase_deg : float, optional
        Phase at t = 0 (degrees).
    """

    amplitude: float  # mm
    frequency: float  # Hz
    end_time: float  # s
    offset: float = 0.0  # mm
    phase_deg: float = 0.0  # degrees

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


@dataclass(frozen=True)
class Vibration:
    """A vibrotactile stimulus: press, hold, then vibrate about the pressed depth.

        d(t) = depth · t/ramp_time                               0 <= t <= ramp_time
             = depth                                              ramp_time <= t <= t_on
             = depth + w(t − t_on) Σ_k A_k sin(2π f_k (t − t_on))  t_on <= t <= end_time

    with t_on = ramp_time + hold_time (the `pressing` part is a `RampHold` ending at t_on) and
    `cycles` periods of the slowest frequency after it. Without a fade (w = 1) the vibration
    starts at the pressed depth with the velocity Σ 2π f_k A_k: t_on is a kink of the load (a
    breakpoint), and the jump in velocity strikes every free mode of the fingertip.

    With a fade the amplitude rises over T_f = fade_in/min(f_k) along w(s) = x − sin(2πx)/(2π),
    x = s/T_f (1 after T_f): w, w' and w'' are continuous at both ends (C2), so the load has no
    kink, and w' is a Hann window, whose spectrum falls as 1/(Δf T_f)³ beyond its main lobe
    |Δf| < 2/T_f: a free mode of the fingertip at f_n ≠ f_k is struck with a relative strength of
    that order instead of O(1) (the two-routes comparison, benchmarks/two_routes.py, needs a
    steady state of a nearly undamped model).

    Parameters
    ----------
    depth : float
        The pressed indentation (mm after first touch).
    ramp_time : float
        Duration of the press (s).
    hold_time : float
        Duration of the hold before the vibration (s).
    amplitudes : tuple of float
        Amplitude A_k of each tone (mm).
    frequencies : tuple of float
        Frequency f_k of each tone (Hz), paired with `amplitudes` (one of each: a pure tone).
    cycles : float, optional
        Periods of the slowest frequency after t_on.
    fade_in : float, optional
        Periods of the slowest frequency, counted within `cycles`, over which the amplitude
        rises; 0: none.
    """

    depth: float  # mm: the pressed depth
    ramp_time: float  # s
    hold_time: float  # s, before the vibration starts
    amplitudes: tuple[float, ...]  # mm, one per frequency
    frequencies: tuple[float, ...]  # Hz
    cycles: float = 10.0  # periods of the slowest frequency
    fade_in: float = 0.0  # periods of the slowest frequency over which the amplitude rises

    def __post_init__(self):
        for name in ("amplitudes", "frequencies"):
            value = getattr(self, name)
            value = (value,) if isinstance(value, int | float) else value
            object.__setattr__(self, name, tuple(float(x) for x in value))
        if not (self.depth > 0 and self.ramp_time > 0 and self.hold_time >= 0):
            raise InputError("protocol", f"need depth > 0, ramp_time > 0, hold_time >= 0, got "
                             f"{self.depth}, {self.ramp_time}, {self.hold_time}.",
                             "press into the skin before vibrating.")
        if not self.frequencies or len(self.frequencies) != len(self.amplitudes):
            raise InputError("protocol.amplitudes/frequencies", f"{len(self.amplitudes)} "
                             f"amplitudes for {len(self.frequencies)} frequencies.",
                             "give one amplitude (mm) per frequency (Hz).")
        if min(self.frequencies) <= 0 or not self.cycles > 0:
            raise InputError("protocol.frequencies/cycles", f"frequencies {self.frequencies} "
                             f"and cycles {self.cycles} must be positive.", "use values > 0.")
        if sum(abs(a) for a in self.amplitudes) >= self.depth:
            raise InputError("protocol.amplitudes", f"Σ|A_k| = "
                             f"{sum(abs(a) for a in self.amplitudes):g} mm reaches the pressed "
                             f"depth {self.depth:g} mm: the probe would leave the skin.",
                             "use smaller amplitudes or press deeper.")
        if not 0 <= self.fade_in < self.cycles:
            raise InputError("protocol.fade_in", f"fade_in = {self.fade_in} periods for cycles "
                             f"= {self.cycles}: the fade must fit in the vibration.",
                             "use 0 <= fade_in < cycles (periods of the slowest frequency).")

    @property
    def onset(self) -> float:
        """t_on: when the vibration starts (s)."""
        return self.ramp_time + self.hold_time

    @property
    def end_time(self) -> float:
        return self.onset + self.cycles / min(self.frequencies)

    @property
    def pressing(self) -> RampHold:
        """The pre-indentation alone: ramp to `depth`, hold until the vibration's onset."""
        return RampHold(self.depth, self.ramp_time, self.onset)

    @property
    def period(self) -> float:
        """The shortest period (s): dynamic steps must resolve it."""
        return 1.0 / max(self.frequencies)

    @property
    def fade_end(self) -> float:
        """When the amplitude has risen to its full value (s): t_on + fade_in/min(f_k)."""
        return self.onset + self.fade_in / min(self.frequencies)

    def envelope(self, s: float) -> float:
        """w(s), s = t − t_on: the C2 rise x − sin(2πx)/(2π) over the fade, then 1."""
        x = s / (self.fade_end - self.onset) if self.fade_in > 0 else 1.0
        return 1.0 if x >= 1.0 else max(x, 0.0) - math.sin(2 * math.pi * x) / (2 * math.pi)

    def __call__(self, t: float) -> float:
        if t <= self.onset:
            return self.pressing(t)
        s = t - self.onset
        return self.depth + self.envelope(s) * sum(
            a * math.sin(2 * math.pi * f * s) for a, f in zip(self.amplitudes, self.frequencies))

    @property
    def breakpoints(self) -> tuple[float, ...]:
        marks = {0.0, self.ramp_time, self.onset, self.fade_end, self.end_time}
        if len(self.frequencies) == 1:  # a pure tone: its peaks and zero crossings
            quarter = 0.25 / self.frequencies[0]
            n = int(round((self.end_time - self.onset) / quarter))
            marks |= {self.onset + quarter * i for i in range(n + 1)}
        return tuple(sorted(m for m in marks if m <= self.end_time))

    @property
    def deepest(self) -> float:
        return self.depth + sum(abs(a) for a in self.amplitudes)


#: Any of the built-in protocol kinds (each meets `LoadHistory`).
History = PiecewiseLinear | RampHold | Sinusoid | Vibration


@dataclass(frozen=True)
class TangentialPath:
    """An indenter path in two parts: the indentation d(t) of `normal` (any protocol) and the
    tangential displacement s(t) of the indenters along `direction` (mm), the piecewise-linear
    `tangential`, constant after its last point. `direction` = (d_x, d_z), the in-plane
    direction (x across the finger, z along it; only its direction counts, it is made a unit
    vector): (1, 0), the default, is +x, the only direction of a 2D section. Press then shear:
    `normal` a ramp-hold, `tangential` 0 until the ramp's end, then a ramp. It meets
    `LoadHistory` (d(t), the end and depth of `normal`, the breakpoints of both), so every
    existing protocol and its use stay as they are; `tangential_at(t)` is s(t),
    `displacement_at(t)` its (x, z) components. With `normal_force` (force_control.py) the
    indenters' normal force follows that target from its first time on, their depth found
    per step; `normal` presses before it and gives the first guess of the depth after it.
    """

    normal: LoadHistory
    tangential: PiecewiseLinear
    direction: tuple[float, float] = (1.0, 0.0)  # (x, z), made a unit vector
    normal_force: NormalForce | None = None  # the target normal force (N/mm; 3D: N), or None

    def __post_init__(self):
        if not isinstance(self.tangential, PiecewiseLinear):
            raise InputError("protocol.tangential", f"got {self.tangential!r}.",
                             "give a PiecewiseLinear path of (time, x) points.")
        if self.tangential.times[-1] > self.normal.end_time + 1e-12:
            raise InputError(
                "protocol.tangential.times", f"the tangential path runs to "
                f"{self.tangential.times[-1]:g} s, after the protocol's end "
                f"({self.normal.end_time:g} s).", "end it by the protocol's end_time.")
        object.__setattr__(self, "direction", unit_direction(self.direction))
        force = self.normal_force
        if force is not None and not force.start < self.normal.end_time:
            raise InputError("protocol.normal_force.times", f"force control would start at "
                             f"{force.start:g} s, not before the protocol's end "
                             f"({self.normal.end_time:g} s).", "start it earlier.")

    @property
    def end_time(self) -> float:
        return self.normal.end_time

    def __call__(self, t: float) -> float:
        return self.normal(t)

    def tangential_at(self, t: float) -> float:
        """The indenters' tangential displacement s(t) along `direction` (mm)."""
        return self.tangential(t)

    def displacement_at(self, t: float) -> tuple[float, float]:
        """The indenters' tangential displacement's (x, z) components at t (mm)."""
        s = self.tangential(t)
        return s * self.direction[0], s * self.direction[1]

    @property
    def breakpoints(self) -> tuple[float, ...]:
        force = () if self.normal_force is None else (
            t for t in self.normal_force.times if t <= self.end_time)
        return tuple(sorted(set(self.normal.breakpoints) | set(self.tangential.breakpoints)
                            | set(force)))

    @property
    def deepest(self) -> float:
        return self.normal.deepest


def unit_direction(direction, where: str = "protocol.tangential.direction") -> tuple:
    """(d_x, d_z) as a unit vector; two finite numbers, not both 0 (InputError otherwise)."""
    values = tuple(direction) if isinstance(direction, list | tuple) else (direction,)
    if len(values) != 2 or not all(isinstance(x, int | float) and not isinstance(x, bool)
                                   and math.isfinite(x) for x in values):
        raise InputError(where, f"got {direction!r}.", "give two numbers [d_x, d_z]: the "
                         "direction across (x) and along (z) the finger, e.g. [0, 1].")
    norm = math.hypot(*values)
    if norm == 0:
        raise InputError(where, "the direction [0, 0] has none.",
                         "give [1, 0] (across the finger, +x) or [0, 1] (along it, +z).")
    return values[0] / norm, values[1] / norm


def check_tangential_path(history, gdim: int, half: bool) -> None:
    """A path along z needs a 3D finger; a path with a part along x needs the whole width of
    the finger: a half model (the 3D `symmetry` plane x = 0 on rollers, u_x = 0) mirrors the
    drag and would silently resist it. A drag along z keeps the mirror symmetry: a half model
    is exact for it (with its indenters on the plane x = 0, as a half model needs anyway)."""
    if not hasattr(history, "tangential_at"):
        return
    d_x, d_z = getattr(history, "direction", (1.0, 0.0))
    if d_z != 0 and gdim == 2:
        raise InputError("protocol.tangential.direction", f"{list(history.direction)} has a "
                         "part along z, but the section is 2D (plane strain, no z).",
                         "drag along x in 2D (direction = [1, 0], the default; [-1, 0] drags "
                         "towards -x), or use a 3D section.")
    if d_x != 0 and half:
        raise InputError("protocol.tangential", "the mesh is a half model, mirror-symmetric "
                         "about x = 0: a drag with a part along x breaks that symmetry.",
                         "drag along the finger (direction = [0, 1]), or use a 2D section "
                         "or a whole 3D finger (section.half = false).")


KINDS = {"ramp-hold": RampHold, "piecewise-linear": PiecewiseLinear, "sinusoid": Sinusoid,
         "vibration": Vibration}


def history_from_dict(data: dict, where: str = "protocol") -> LoadHistory:
    """Build a protocol from a scene file's `[protocol]` table (`kind` picks the class)."""
    if not isinstance(data, dict):
        raise InputError(where, f"must be a table, got {data!r}.",
                         'write [protocol] with its kind and times, e.g. {kind = "ramp-hold", '
                         "depth = 1.0, ramp_time = 1.0, end_time = 1.0}.")
    data = dict(data)
    tangential = data.pop("tangential", None)
    force = data.pop("normal_force", None)
    if force is not None and tangential is None:
        raise InputError(f"{where}.normal_force", "force control comes with a tangential path "
                         "(the normal force held while the indenters move).",
                         "add tangential = {times = [0.0, T], values = [0.0, 0.0]} to hold "
                         "the force without moving along the surface.")
    if tangential is not None:  # the normal protocol, and the indenters' tangential path
        force = None if force is None else normal_force_from_dict(force, f"{where}.normal_force")
        return TangentialPath(history_from_dict(data, where),
                              *_tangential(tangential, f"{where}.tangential"), force)
    kind = data.pop("kind", "ramp-hold")
    if kind not in KINDS:
        raise InputError(f"{where}.kind", f"unknown protocol {kind!r}.",
                         f"use one of {', '.join(KINDS)}.")
    cls = KINDS[kind]
    allowed = [f.name for f in fields(cls) if f.init]
    required = [f.name for f in fields(cls) if f.init and f.default is dataclasses.MISSING]
    check_keys(f"{where} ({kind})", data, allowed, required)
    lists = {f.name for f in fields(cls) if str(f.type).startswith("tuple")}
    for key, value in data.items():
        data[key] = _numbers(f"{where}.{key}", value, key in lists)
    return cls(**data)


def _numbers(where: str, value, listed: bool):
    """A protocol's value: a finite number, or for a key that takes a list (`listed`: times,
    values, amplitudes, frequencies) a list of them (as a tuple; a number is a list of one).
    An infinite depth or end time, or a NaN, would pass every comparison the protocols make."""
    items = value if isinstance(value, list | tuple) else None
    if items is not None and not listed:
        raise InputError(where, f"must be one number, got the list {value!r}.",
                         "write a single number.")
    for x in [value] if items is None else items:
        if isinstance(x, bool) or not isinstance(x, int | float):
            raise InputError(where, f"must be a number{' or a list of numbers' * listed}, got "
                             f"{value!r}.", "write a number.")
        if not math.isfinite(x):
            raise InputError(where, f"must be finite, got {value!r}.",
                             "write a finite number (mm, s or Hz).")
    return value if items is None else tuple(items)


def _tangential(data, where: str) -> tuple[PiecewiseLinear, tuple[float, float]]:
    """`[protocol.tangential]`: times (s) and values (mm along the direction) of a
    piecewise-linear path, and its optional `direction` [d_x, d_z] (default [1, 0]: +x)."""
    check_keys(where, data, ["times", "values", "direction"], ["times", "values"])
    for key, value in data.items():
        if not isinstance(value, list | tuple):
            raise InputError(f"{where}.{key}", f"must be a list of numbers, got {value!r}.")
        _numbers(f"{where}.{key}", value, True)
    direction = unit_direction(data.get("direction", (1.0, 0.0)), f"{where}.direction")
    return PiecewiseLinear(tuple(data["times"]), tuple(data["values"])), direction


def step_times(breakpoints: Sequence[float], t: float, dt: float, end_time: float) -> float:
    """The next time after `t` for a step of at most `dt` that lands on every breakpoint."""
    target = min(t + dt, end_time)
    for b in breakpoints:  # the first breakpoint reached, also one the step ends on exactly
        if t + 1e-12 < b <= target + 1e-12:  # (else the stretch below would step over it)
            return b
    # Avoid leaving a sliver of a step before a breakpoint: stretch to it if it is close.
    for b in (*breakpoints, end_time):
        if target < b <= target + 0.25 * dt:
            return b
    return target
