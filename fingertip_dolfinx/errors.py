"""Errors a user can act on: each message names the input at fault and the fix."""


class FingertipError(Exception):
    """Base class of every error this package raises on purpose.

    Catch it to handle any failure of an input or of a computation; an error that is not one
    of these is a bug.
    """


class InputError(FingertipError, ValueError):
    """A value in a data file or on the command line is impossible or non-physical.

    The message reads ``"{where}: {problem} Fix: {fix}"``; the command line prints it as one
    line and exits with status 2.

    Parameters
    ----------
    where : str
        Where the value came from and its key (``"--set protocol.depth=-1: protocol.depth"``,
        a file and a table, a Python override).
    problem : str
        What is wrong with the value.
    fix : str or None, optional
        What to do instead; None when the problem says it.
    """

    def __init__(self, where: str, problem: str, fix: str | None = None):
        self.where, self.problem, self.fix = where, problem, fix
        message = f"{where}: {problem}"
        if fix:
            message += f" Fix: {fix}"
        super().__init__(message)


class ConvergenceError(FingertipError, RuntimeError):
    """A time step could not be solved even after repeated step cuts.

    The run has saved its results up to the last good step, and summary.json says
    ``"status": "failed"`` and why. The message names the time, the load, the reason and the
    place where the residual is largest (the command line exits with status 1).
    """


class CompactionError(ConvergenceError):
    """The porous solid would be compressed to (or below) its solid volume fraction.

    A physical limit, not a numerical failure: the load is too fast or too large for the
    permeability, and smaller time steps cannot help. A `ConvergenceError`, so that a run
    that ends on it saves its results up to the last good step like any failed run.
    """


class MaterialInstabilityError(FingertipError, RuntimeError):
    """A hyperelastic state left the region where the Drucker condition holds."""


class RunInterrupted(KeyboardInterrupt):
    """A run stopped by SIGINT (Ctrl-C) or SIGTERM at a step boundary.

    Raised after the run has written its files and summary.json (``"status":
    "interrupted"``); ``resume=True`` (``--resume``) continues it. A KeyboardInterrupt, so that
    Python code keeps Ctrl-C's meaning (it is not caught by ``except Exception``).

    Parameters
    ----------
    time : float
        The last time reached (s).
    signal : str
        The signal's name.
    summary : dict
        The summary written (summary.json's content).
    """

    def __init__(self, time: float, signal: str, summary: dict):
        self.time, self.signal, self.summary = time, signal, summary
        super().__init__(f"interrupted by {signal} at t = {time:.6g} s")
