"""A scene's `[harmonic]` table as data: the frequencies and the pressed state of the frequency
route (harmonic.py, frequency_response.py). Data only, with no PETSc or DOLFINx import, so that
a scene (scene.py) validates the table without loading the solvers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import InputError

#: The pressed states about which the response is linearised (harmonic.press).
STATES = ("relaxed", "held")


def parse_frequencies(spec, where: str = "harmonic.frequencies") -> tuple[float, ...]:
    """Frequencies (Hz) from "start:stop:count" (log-spaced, both ends included), a comma list
    "10,100,250", or a list of numbers."""
    fix = 'give "start:stop:count" (log-spaced, e.g. "1:1000:40"), "10,100,250" or a list.'
    try:
        if isinstance(spec, str) and ":" in spec:
            start, stop, count = spec.split(":")
            start, stop, n = float(start), float(stop), int(count)
            if not (0 < start < stop and n >= 2):
                raise InputError(where, f"{spec!r}: need 0 < start < stop and count >= 2.", fix)
            values = np.geomspace(start, stop, n)
        elif isinstance(spec, str):
            values = [float(x) for x in spec.split(",") if x.strip()]
        elif isinstance(spec, int | float):
            values = [float(spec)]
        else:
            values = [float(x) for x in spec]
    except InputError:
        raise  # (a ValueError too): its own message, not "cannot read"
    except (TypeError, ValueError):
        raise InputError(where, f"cannot read {spec!r}.", fix) from None
    values = tuple(float(f) for f in values)
    if not values or not all(f > 0 and math.isfinite(f) for f in values):
        raise InputError(where, f"{spec!r} gives {values}: frequencies are positive (Hz).", fix)
    return values


@dataclass(frozen=True)
class HarmonicOptions:
    """A scene's `[harmonic]` table: the frequencies (a `parse_frequencies` spec; empty: the
    protocol's own) and the pressed state ("held": the protocol's pre-indentation, ramp and
    hold, as a time-domain run would vibrate from; "relaxed": the long-term equilibrium)."""

    #: Hz: a list, or "start:stop:count" (log-spaced); empty: the protocol's own.
    frequencies: tuple[float, ...] | str = ()
    #: The pressed state: "held" or "relaxed".
    state: str = "held"

    def __post_init__(self):
        spec = self.frequencies
        if not (isinstance(spec, tuple | list) and len(spec) == 0):
            object.__setattr__(self, "frequencies", parse_frequencies(spec))
        else:
            object.__setattr__(self, "frequencies", ())
        if self.state not in STATES:
            raise InputError("harmonic.state", f"unknown pressed state {self.state!r}.",
                             f"use one of {STATES}.")
