"""Implicit time stepping with PETSc SNES: adaptive steps, cuts on failure, clear errors.

Every step solves the full nonlinear system R(u_{n+1}; u_n, Δt) = 0 (backward Euler in the
history terms) with Newton's method. The step grows while Newton converges easily and is cut
when it fails (divergence, NaN, inverted elements); after `max_cuts` cuts in a row the run
stops with a message that says when, where and why. Compaction of a porous tissue (J within
the margin of its solid fraction φ0, at a quadrature point or a node) is a physical limit, not
a numerical one: the run stops at once with a `CompactionError` (also when Newton's residual
turns non-finite twice in a step at an iterate whose pores closed). Times in the messages carry
the digits that tell t and t + Δt apart. Forms are compiled once: time, step size and loads are
`fem.Constant`s that the problem updates in place.
"""

from __future__ import annotations

import math
import time as wallclock
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Protocol

import dolfinx.fem.petsc
import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from .errors import CompactionError, ConvergenceError, FingertipError
from .loading import step_times

#: Newton with a backtracking line search and a direct solve (MUMPS): robust for contact and
#: for the saddle-point structure of the undrained tissue. Users override any of these.
DEFAULT_PETSC_OPTIONS = {
    "snes_type": "newtonls",
    "snes_linesearch_type": "bt",
    "snes_rtol": 1e-9,
    "snes_atol": 1e-10,  # N/mm: the bone (17 GPa) puts round-off near 1e-12
    "snes_stol": 0.0,
    "snes_max_it": 15,  # a failing attempt should fail fast: the step is cut and retried
    "ksp_type": "preonly",
    "pc_type": "lu",
    "pc_factor_mat_solver_type": "mumps",
}

_SNES_REASONS = {
    getattr(PETSc.SNES.ConvergedReason, name): name
    for name in dir(PETSc.SNES.ConvergedReason)
    if not name.startswith("_") and isinstance(getattr(PETSc.SNES.ConvergedReason, name), int)
}


class Steppable(Protocol):
    """What the time stepper needs from a problem (problem.FingertipProblem is one)."""

    residuals: list  # UFL forms, one per unknown
    unknowns: list[fem.Function]
    bcs: list[fem.DirichletBC]
    entity_maps: list | None
    dt: fem.Constant

    def set_time(self, t: float) -> None:
        """Move the loads (indenter positions, boundary values) to time t."""

    def accept(self) -> None:
        """Take the converged state as the new history (u_n, internal variables)."""

    def restore(self) -> None:
        """Return the unknowns to the last accepted state (after a failed attempt)."""

    def inadmissible(self) -> str | None:
        """Why the converged state cannot be accepted (inverted elements, ...), or None."""

    # Optional: `compacted(margin=None, nodes=True)`, the porous tissue's lowest J if within
    # `margin` of its solid fraction (admissibility.Compacted: `message(when)`), else None. The
    # stepper stops on it with a CompactionError; `residual_hotspot(residual)`, where the
    # residual of a failed attempt is largest.

    def diagnostics(self) -> dict[str, float]:
        """Per-step quantities of the converged state, before `accept`: force, min J, ..."""


@dataclass
class StepOptions:
    """Adaptive time-step control (times in s)."""

    dt_initial: float = 0.1
    dt_min: float = 1e-5
    dt_max: float = 10.0
    growth: float = 1.5  # factor after an easy step
    cut: float = 0.5  # factor after a failed attempt
    max_cuts: int = 8  # failed attempts in a row before giving up
    easy_iterations: int = 6  # a step with at most this many Newton iterations is easy
    #: Start Newton from the linear extrapolation of the last two states (not across a kink
    #: of the load history): in a ramp this removes most of the iterations.
    extrapolate: bool = True

    def __post_init__(self):
        if not 0 < self.dt_min <= self.dt_initial <= self.dt_max:
            raise ValueError("need 0 < dt_min <= dt_initial <= dt_max")
        if not (self.growth >= 1 and 0 < self.cut < 1 and self.max_cuts >= 0):
            raise ValueError("need growth >= 1, 0 < cut < 1, max_cuts >= 0")


@dataclass
class StepReport:
    step: int
    time: float
    dt: float
    load: float
    newton_iterations: int
    cuts: int
    wall_time_s: float
    diagnostics: dict[str, float] = field(default_factory=dict)
    next_dt: float = math.nan  # the step size planned next (a checkpoint stores it)

    def row(self) -> dict[str, float]:
        row = asdict(self)
        row.update(row.pop("diagnostics"))
        return row


class TimeStepper:
    """Drives a `Steppable` problem along a load history with adaptive backward-Euler steps."""

    def __init__(
        self,
        problem: Steppable,
        options: StepOptions | None = None,
        petsc_options: dict | None = None,
        prefix: str = "fingertip_",
    ):
        self.problem = problem
        self.options = options or StepOptions()
        opts = {**DEFAULT_PETSC_OPTIONS, **(petsc_options or {})}
        # One NonlinearProblem for the whole run: its forms are compiled here, once.
        self.nonlinear = dolfinx.fem.petsc.NonlinearProblem(
            problem.residuals,
            problem.unknowns,
            bcs=problem.bcs,
            entity_maps=problem.entity_maps,
            kind="mpi",
            petsc_options_prefix=prefix,
            petsc_options=opts,
        )
        self.snes = self.nonlinear.solver
        self._watch_residual()

    def close(self) -> None:
        """Destroy the solver's PETSc objects now, on every rank together.

        Their destruction is collective (MUMPS broadcasts as it frees its factors). Left to
        Python's garbage collector, it happens at different moments on different ranks (rank 0
        alone draws the figures, which triggers a collection) and `mpiexec` runs hang at exit.
        """
        nonlinear = self.nonlinear
        for obj in (nonlinear.solver, nonlinear.A, nonlinear.P_mat, nonlinear.b, nonlinear.x):
            if obj is not None:
                obj.destroy()

    def _watch_residual(self) -> None:
        """Wrap the residual so that, where it turns non-finite at a Newton iterate (not at the
        initial guess, the predictor), the problem's compaction finding there is kept: while
        the residual is assembled the unknowns hold that iterate; after a failed solve they
        hold SNES's last accepted iterate instead."""
        self._evaluations, self._closed = 0, None
        check = getattr(self.problem, "compacted", None)
        if check is None:
            return
        vector, (function, args, kargs) = self.snes.getFunction()

        def residual(snes, x, f):
            function(snes, x, f, *args, **kargs)
            self._evaluations += 1
            if self._evaluations > 1 and self._closed is None and not _finite(f):
                self._closed = check(0.0, False)  # J ≤ φ0 at a quadrature point?

        self.snes.setFunction(residual, vector)

    def solve_once(self) -> tuple[int, int]:
        """One Newton solve from the current state; returns (converged reason, iterations)."""
        self._evaluations, self._closed = 0, None
        with np.errstate(all="ignore"):
            self.nonlinear.solve()
        return self.snes.getConvergedReason(), self.snes.getIterationNumber()

    def run(
        self,
        history: Callable[[float], float],
        end_time: float,
        *,
        start_time: float = 0.0,
        breakpoints: Sequence[float] = (),
        on_step: Callable[[StepReport], None] | None = None,
        previous: tuple[float, list[np.ndarray]] | None = None,
    ) -> list[StepReport]:
        """Step from `start_time` to `end_time`, landing exactly on every breakpoint.

        `history(t)` is the load reported per step (e.g. indenter displacement); the problem's
        own `set_time` applies it. `on_step` is called after every accepted step, so results
        are written as they come and survive a later failure. `previous` is the accepted state
        (time, unknowns' arrays) one step before `start_time`, for the predictor on a restart.
        """
        opts, problem = self.options, self.problem
        marks = sorted({*getattr(history, "breakpoints", ()), *breakpoints, end_time})
        t, dt, step = start_time, opts.dt_initial, 0
        reports: list[StepReport] = []
        # The last two accepted states (time, unknowns), for the predictor.
        states = deque([(t, [f.x.array.copy() for f in problem.unknowns])], maxlen=2)
        if previous is not None:
            states.appendleft(previous)
        while t < end_time - 1e-12 * max(1.0, end_time):
            started = wallclock.perf_counter()
            cuts, why, closed_iterates = 0, "", 0
            while True:
                t_new = step_times(marks, t, dt, end_time)
                problem.dt.value = t_new - t
                problem.set_time(t_new)
                if opts.extrapolate and len(states) == 2 and not _is_mark(t, marks):
                    _extrapolate(problem.unknowns, states, t_new)
                reason, iterations = self.solve_once()
                compacted = None
                if reason > 0:
                    why = (problem.inadmissible() or "").rstrip(".")
                    if not why:
                        break
                    compacted = _compacted(problem)  # a solution: the limit is reached
                else:
                    why = f"Newton did not converge ({_SNES_REASONS.get(reason, reason)})"
                    hotspot = getattr(problem, "residual_hotspot", None)
                    if hotspot is not None:
                        where = hotspot(self.snes.getFunction()[0])
                        if where is not None:
                            why += (f"; the residual is largest near x = ({where[0]:.3f}, "
                                    f"{where[1]:.3f}) mm")
                    # Did the residual turn non-finite at an iterate whose pores closed (J ≤ φ0
                    # at a quadrature point)? Once may be an overshoot; again after a cut, it
                    # is the limit.
                    closed_iterates += self._closed is not None
                    compacted = self._closed if closed_iterates > 1 else None
                problem.restore()
                if compacted is not None:
                    problem.set_time(t)
                    a, b = _distinct(t, t_new)
                    raise CompactionError(
                        compacted.message(f"at t = {b} s (the step from t = {a} s, Δt = "
                                          f"{t_new - t:.3g} s)", iterate=reason <= 0,
                                          before=_approach(problem, compacted, t, t_new,
                                                           nodes=reason > 0))
                        + f" Results up to t = {a} s are saved.")
                cuts += 1
                dt = (t_new - t) * opts.cut
                if cuts > opts.max_cuts or dt < opts.dt_min:
                    problem.set_time(t)
                    a, b = _distinct(t, t_new)
                    load_a, load_b = _distinct(history(t), history(t_new))
                    raise ConvergenceError(
                        f"the step from t = {a} s to t = {b} s (load {load_a} -> {load_b}) "
                        f"failed {cuts} times, the last with Δt = {t_new - t:.3g} s: {why}. "
                        f"Results up to t = {a} s are saved. Fix: lower the load or its rate, "
                        "refine the mesh where it fails, or allow smaller steps (dt_min, "
                        "max_cuts)."
                    )
            # Diagnostics first: accepting advances the history, after which the stress forms
            # describe the start of the next step, not the state just solved.
            diagnostics = problem.diagnostics()
            problem.accept()
            states.append((t_new, [f.x.array.copy() for f in problem.unknowns]))
            step += 1
            report = StepReport(
                step=step,
                time=t_new,
                dt=t_new - t,
                load=history(t_new),
                newton_iterations=iterations,
                cuts=cuts,
                wall_time_s=wallclock.perf_counter() - started,
                diagnostics=diagnostics,
            )
            # Grow after easy steps, keep the size after hard ones (cuts already shrank it).
            taken = t_new - t
            t = t_new
            if cuts == 0 and iterations <= opts.easy_iterations:
                dt = min(max(dt, taken) * opts.growth, opts.dt_max)
            else:
                dt = min(taken, opts.dt_max)
            report.next_dt = dt
            reports.append(report)
            if on_step is not None:
                on_step(report)
            if not math.isfinite(dt) or dt <= 0:
                raise FingertipError(f"time step became {dt} at t = {t}")
        return reports


def _compacted(problem, margin: float | None = None, nodes: bool = True):
    """The problem's compaction finding (admissibility.Compacted) if it has the check."""
    check = getattr(problem, "compacted", None)
    return None if check is None else check(margin, nodes)


def _approach(problem, compacted, t: float, t_new: float, nodes: bool) -> str:
    """How J approached the limit over the failed step: the lowest J of the last accepted
    state (now restored; at the same kind of points) and, by linear interpolation, when it
    crossed the limit."""
    accepted = _compacted(problem, math.inf, nodes)  # the lowest J, wherever it is
    if accepted is None:
        return ""
    J0, J1, limit = accepted.J, compacted.J, compacted.limit
    text = f"the lowest J was {J0:.4g} at t = {_distinct(t, t_new)[0]} s"
    if J0 > limit > J1:
        crossing = t + (t_new - t) * (J0 - limit) / (J0 - J1)
        text += f" and crossed {limit:g} near t = {_distinct(crossing, t_new)[0]} s"
    return text


def _finite(vector: PETSc.Vec) -> bool:
    """Every entry of a (parallel) PETSc vector finite, on every rank."""
    local = bool(np.all(np.isfinite(vector.getArray(readonly=True))))
    return vector.getComm().tompi4py().allreduce(local, op=MPI.LAND)


def _distinct(a: float, b: float, digits: int = 6) -> tuple[str, str]:
    """a and b printed with enough significant digits (at least `digits`) to tell them apart:
    t = 36.4231 s and t + 1e-5 s print as 36.4231 and 36.42311."""
    scale, gap = max(abs(a), abs(b)), abs(b - a)
    if gap > 0 and scale > 0:
        digits = max(digits, min(17, math.ceil(math.log10(scale / gap)) + 2))
    return f"{a:.{digits}g}", f"{b:.{digits}g}"


def _is_mark(t: float, marks: Sequence[float]) -> bool:
    return any(abs(t - m) <= 1e-12 * max(1.0, abs(m)) for m in marks)


def _extrapolate(unknowns: list[fem.Function], states: deque, t_new: float) -> None:
    """Set the unknowns to the linear extrapolation through the last two accepted states."""
    (t0, old), (t1, last) = states
    c = (t_new - t1) / (t1 - t0)
    for f, a, b in zip(unknowns, old, last):
        f.x.array[:] = b + c * (b - a)
