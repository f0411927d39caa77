"""Checks of input values, one copy each: every data table is read through these, so every
mistake gets the same kind of message, naming the key and the fix."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping

from .errors import InputError


def check_keys(where: str, data: Mapping, allowed: Iterable[str], required: Iterable[str] = (),
               what: str = "key") -> None:
    """Unknown keys and missing required keys of a table are errors that list the valid ones."""
    if not isinstance(data, Mapping):
        raise InputError(where, f"must be a table, got {type(data).__name__} {data!r}.",
                         "write it as a TOML table ([name] or {key = value}).")
    allowed = list(allowed)
    unknown = sorted(set(data) - set(allowed))
    if unknown:
        table = where.rsplit(": ", 1)[-1]
        raise InputError(f"{where}.{', '.join(unknown)}", f"unknown {what}(s).",
                         f"{table} takes: {', '.join(allowed)} (check the spelling).")
    missing = [k for k in required if k not in data]
    if missing:
        raise InputError(where, f"missing {what}(s) {', '.join(missing)}.",
                         f"give {', '.join(missing)}.")


def number(where: str, value) -> float:
    """A finite real number (a TOML boolean is not one, although Python's bool is an int)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(where, f"must be a number, got {value!r}.", "write a number.")
    if not math.isfinite(value):
        raise InputError(where, f"must be finite, got {value!r}.", "write a finite number.")
    return float(value)


def numbers(where: str, value, unit: str) -> tuple[float, ...]:
    """A list of finite numbers in `unit` (a single number or a string is not one)."""
    if not isinstance(value, list | tuple):
        raise InputError(where, f"must be a list of numbers ({unit}), got {value!r}.",
                         f"write a list, e.g. {where.rsplit(': ', 1)[-1]} = [1.0].")
    return tuple(number(where, x) for x in value)


def positive(where: str, value, unit: str = "") -> float:
    x = number(where, value)
    if not x > 0:
        raise InputError(where, f"must be positive, got {x}{f' {unit}' if unit else ''}.",
                         "use a value > 0.")
    return x


def count(where: str, value, what: str, example: str) -> int:
    """A whole number >= 0 of `what` (a TOML boolean is not one); `example` shows the fix."""
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise InputError(where, f"must be a whole number of {what} >= 0, got {value!r}.",
                         f"write e.g. {example} (0: off).")
    return value
