"""Errors a user can act on: each message names the input at fault and the fix."""


class FingertipError(Exception):
    """Base class of every error this package raises on purpose."""


class InputError(FingertipError, ValueError):
    """A value in a data file or on the command line is impossible or non-physical."""

    def __init__(self, where: str, problem: str, fix: str | None = None):
        self.where, self.problem, self.fix = where, problem, fix
        message = f"{where}: {problem}"
        if fix:
            message += f" Fix: {fix}"
        super().__init__(message)


class ConvergenceError(FingertipError, RuntimeError):
    """A time step could not be solved even after repeated step cuts."""


class CompactionError(ConvergenceError):
    """The porous solid would be compressed to (or below) its solid volume fraction.

    A physical limit, not a numerical failure: the load is too fast or too large for the
    permeability, and smaller time steps cannot help. A `ConvergenceError`, so that a run
    that ends on it saves its results up to the last good step like any failed run."""


class MaterialInstabilityError(FingertipError, RuntimeError):
    """A hyperelastic state left the region where the Drucker condition holds."""


class RunInterrupted(KeyboardInterrupt):
    """A run stopped by SIGINT (Ctrl-C) or SIGTERM at a step boundary, after writing its files
    and summary.json (`"status": "interrupted"`); `--resume` continues it.

    A KeyboardInterrupt, so that Python code keeps Ctrl-C's meaning (it is not caught by
    `except Exception`); `time` is the last time reached (s), `signal` the signal's name,
    `summary` the summary written."""

    def __init__(self, time: float, signal: str, summary: dict):
        self.time, self.signal, self.summary = time, signal, summary
        super().__init__(f"interrupted by {signal} at t = {time:.6g} s")
