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


class CompactionError(FingertipError, RuntimeError):
    """The porous solid would be compressed to (or below) its solid volume fraction."""


class MaterialInstabilityError(FingertipError, RuntimeError):
    """A hyperelastic state left the region where the Drucker condition holds."""
