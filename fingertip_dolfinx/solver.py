"""Implicit time stepping with PETSc SNES: adaptive steps, cuts on failure, clear errors.

Every step solves the full nonlinear system R(u_{n+1}; u_n, Δt) = 0 with Newton's method.
The model's one time derivative, dJ/dt in the biphasic mass balance, is integrated by
backward Euler (first order, the default) or variable-step BDF2 (second order;
`StepOptions.scheme`): the problem's `rate_weights` (a₀, a₁, a₂) make Δt·dJ/dt ≈ a₀ J_{n+1}
+ a₁ J_n + a₂ J_{n−1}. BDF2's first step, and the first after every kink of the load, are
backward Euler. The skin's QLV history keeps its own recursion (exact for a stress linear over
the step: second order for a smooth one); elasticity and contact are quasi-static.

Dynamics (a problem with `inertia`, model option `inertia`): the scheme "generalized-alpha"
integrates the inertia by the Wood–Bossak–Zienkiewicz method (generalised-α with α_f = 0,
inertia.py; second order, numerical dissipation `rho_inf` ∈ [0, 1], 1 the trapezoidal rule)
and the biphasic mass balance by BDF2 as above; with α_f = 0 the internal forces, QLV,
pore pressure and contact stay at t_{n+1}. A dynamic step must resolve the load's shortest
period: when the history has a `period` (loading.Vibration), Δt ≤ period/`steps_per_period`
from its `onset` on (before it, in the quasi-static press and hold, the steps grow as usual:
the inertia is on but negligible there, ρ d̈ ~ 0 on a ramp, and ρ∞ < 1 damps the start-up
transients of the Newmark velocity at the ramp's kink by ρ∞ per large step).

Step sizes (`StepOptions.control`):

- "iterations" (the default): the step grows ×`growth` while Newton converges easily
  (≤ `easy_iterations`), whatever the error, up to `dt_max`.
- "error": each step's local time-integration error is estimated and kept below the
  tolerance: for every unknown field f, max |e_f| ≤ atol + rtol·(the largest |f| reached so
  far). e is Milne's estimate K/(K − K_p)·(x − x_pred) from the difference between the
  corrector x and the polynomial predictor x_pred through the last states (linear for
  backward Euler, quadratic for BDF2; K, K_p their error constants at the actual step
  ratios). The first step, and the first after a kink of the load, where no smooth history
  exists, is checked by step doubling (one step against two half steps; the halves are
  kept). A step whose error exceeds the tolerance (err > 1) is redone; the next step is
  Δt·min(growth, max(0.2, safety·err^(−1/(k+1)))), k the order.

In both, steps land exactly on every breakpoint of the load and output time, and a step is cut
when it fails (divergence, NaN, inverted elements); after `max_cuts` cuts in a row the run
stops with a message that says when, where and why. Compaction of a porous tissue (J within
the margin of its solid fraction φ0, at a quadrature point or a node) is a physical limit, not
a numerical one: the run stops at once with a `CompactionError` (also when Newton's residual
turns non-finite twice in a step at an iterate whose pores closed, and the accepted states,
extrapolated, reach the limit within the step; otherwise that iterate overshot and the step
is cut). Times in the messages carry
the digits that tell t and t + Δt apart. Forms are compiled once: time, step size, loads and
multistep weights are `fem.Constant`s the problem updates in place.
"""

from __future__ import annotations

import dataclasses
import math
import time as wallclock
import warnings
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Protocol

import dolfinx.fem.petsc
import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from .contact import NonConservativeContactWarning
from .errors import CompactionError, ConvergenceError, FingertipError
from .linear_solvers import DIRECT_OPTIONS, LinearSolver
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

CONTROLS = ("iterations", "error")
SCHEMES = ("backward-euler", "bdf2", "generalized-alpha")
#: Schemes whose biphasic rate is BDF2 (generalised-α keeps the mass balance second order).
SECOND_ORDER_RATE = ("bdf2", "generalized-alpha")
#: Variable-step BDF2 is zero-stable for step ratios ω = Δt_n/Δt_{n−1} < 1 + √2.
BDF2_GROWTH_LIMIT = 1 + math.sqrt(2)
#: The smallest factor by which error control shrinks a step it rejects or follows.
ERROR_CUT_MIN = 0.2
BACKWARD_EULER = (1.0, -1.0, 0.0)

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

    # Optional. `rate_weights`: a fem.Constant (a₀, a₁, a₂) that the residual uses as
    # Δt·dJ/dt ≈ a₀ J_{n+1} + a₁ J_n + a₂ J_{n−1} (J_{n−1} from the state before u_n, which
    # `accept` keeps); the stepper sets it every step (a problem without a rate has none).
    # `state_arrays()` (live arrays of the whole state, history included) and
    # `mark_accepted()`: error control saves and restores the state around a doubled step.


@dataclass
class StepOptions:
    """Adaptive time-step control (times in s)."""

    dt_initial: float = 0.1  # s: the first step
    dt_min: float = 1e-5  # s: a step cut below this stops the run
    dt_max: float = 10.0  # s: the largest step
    growth: float = 1.5  # factor after an easy step
    cut: float = 0.5  # factor after a failed attempt
    max_cuts: int = 8  # failed attempts in a row before giving up
    easy_iterations: int = 6  # a step with at most this many Newton iterations is easy
    #: Start Newton from the linear extrapolation of the last two states (not across a kink
    #: of the load history): in a ramp this removes most of the iterations. Measured on the
    #: line load: without it, 81 steps of ~2 ms (7 iterations each) reached only 0.22 mm of
    #: the 1 mm ramp; a quadratic extrapolation through three states overshoots the growing
    #: contact zone: 41 steps, 209 iterations against the linear one's 33 and 164.
    extrapolate: bool = True
    #: Keep the Jacobian, and so its LU factorisation, for the next Newton iteration of a step
    #: when the last one cut the residual norm by at least this factor (0: never keep it; a
    #: chord step is then nearly as good as Newton's: the iterate is in the quadratic phase).
    #: Measured on the line load (benchmarks/line_load.py): see JacobianReuse.
    jacobian_reuse: float = 0.0
    #: "iterations": grow by `growth` after easy steps. "error": steps chosen by their
    #: estimated local time-integration error (rtol, atol); `growth` is then the largest
    #: factor from one step to the next.
    control: str = "iterations"
    #: "backward-euler" (first order) or "bdf2" (variable-step BDF2, second order) for the
    #: biphasic mass balance; "generalized-alpha" for dynamics (a model with inertia): the
    #: Wood–Bossak–Zienkiewicz method for the inertia (inertia.py), BDF2 for the mass balance.
    scheme: str = "backward-euler"
    #: "generalized-alpha" (dynamics): the spectral radius ρ∞ ∈ [0, 1] at Δt → ∞ of the
    #: Wood–Bossak–Zienkiewicz method (1: trapezoidal rule, no numerical dissipation; 0.8
    #: damps the unresolved mesh modes that contact and kinks of the load excite while
    #: keeping the resolved ones: a relative period error and damping ~(ωΔt)²).
    rho_inf: float = 0.8
    #: Steps per shortest period of a periodic load (a history with `period`, after its
    #: `onset`): the largest step there is period/steps_per_period.
    steps_per_period: int = 40
    #: Error control: per unknown field, max |local error| <= atol + rtol * (largest |value|
    #: the field has reached). atol in the unknowns' units, mm (displacement) and MPa
    #: (pressure): the floor that keeps the first steps from rest, where every field is still
    #: tiny, from asking more than Newton's own accuracy (its residual tolerance, snes_atol).
    rtol: float = 1e-3
    atol: float = 1e-6  # error control: the absolute floor (mm, MPa), see rtol
    safety: float = 0.9  # the next step aims at safety × the tolerance

    def __post_init__(self):
        if not 0 < self.dt_min <= self.dt_initial <= self.dt_max:
            raise ValueError("need 0 < dt_min <= dt_initial <= dt_max")
        if not (self.growth >= 1 and 0 < self.cut < 1 and self.max_cuts >= 0):
            raise ValueError("need growth >= 1, 0 < cut < 1, max_cuts >= 0")
        if self.control not in CONTROLS:
            raise ValueError(f"control must be one of {CONTROLS}, got {self.control!r}")
        if self.scheme not in SCHEMES:
            raise ValueError(f"scheme must be one of {SCHEMES}, got {self.scheme!r}")
        if not (self.rtol >= 0 and self.atol >= 0 and self.rtol + self.atol > 0
                and 0 < self.safety <= 1):
            raise ValueError("need rtol >= 0, atol >= 0, rtol + atol > 0, 0 < safety <= 1")
        if not 0.0 <= self.jacobian_reuse < 1.0:
            raise ValueError(f"need 0 <= jacobian_reuse < 1, got {self.jacobian_reuse}")
        if not 0.0 <= self.rho_inf <= 1.0:
            raise ValueError(f"need 0 <= rho_inf <= 1, got {self.rho_inf}")
        if isinstance(self.steps_per_period, bool) or not (
                isinstance(self.steps_per_period, int) and self.steps_per_period >= 4):
            raise ValueError(f"steps_per_period must be an integer >= 4 (a step per quarter "
                             f"period at least), got {self.steps_per_period!r}")
        if self.scheme == "generalized-alpha" and self.control == "error":
            raise ValueError("control = 'error' has no error estimate for the generalized-alpha "
                             "scheme: use control = 'iterations' (steps_per_period sets the "
                             "accuracy)")
        if self.scheme in SECOND_ORDER_RATE and not self.growth < BDF2_GROWTH_LIMIT:
            raise ValueError(f"BDF2 is unstable for step ratios above 1 + √2: need growth < "
                             f"{BDF2_GROWTH_LIMIT:.4f}, got {self.growth}")


@dataclass
class StepReport:
    step: int
    time: float
    dt: float
    load: float
    newton_iterations: int
    cuts: int
    wall_time_s: float
    #: Krylov iterations of the Newton iterations counted in `newton_iterations` (one per
    #: Newton iteration with the direct solver; attempts that were cut count in neither).
    linear_iterations: int = 0
    diagnostics: dict[str, float] = field(default_factory=dict)
    next_dt: float = math.nan  # the step size planned next (a checkpoint stores it)
    #: Error control: the accepted step's error estimate over the tolerance (<= 1), and the
    #: attempts redone because it was above.
    error: float = math.nan
    rejected: int = 0

    def row(self) -> dict[str, float]:
        row = asdict(self)
        row.update(row.pop("diagnostics"))
        return row


class TimeStepper:
    """Drives a `Steppable` problem along a load history with adaptive implicit steps."""

    def __init__(
        self,
        problem: Steppable,
        options: StepOptions | None = None,
        petsc_options: dict | None = None,
        prefix: str = "fingertip_",
        linear: str = "direct",
    ):
        self.problem = problem
        self.options = options or StepOptions()
        #: The linear solver inside Newton (linear_solvers.py): "direct" (MUMPS) or "iterative".
        self.linear = LinearSolver(linear, problem)
        newton = {k: v for k, v in DEFAULT_PETSC_OPTIONS.items() if k not in DIRECT_OPTIONS}
        opts = {**newton, **self.linear.options, **(petsc_options or {})}
        # One NonlinearProblem for the whole run: its forms are compiled here, once.
        self.nonlinear = dolfinx.fem.petsc.NonlinearProblem(
            problem.residuals,
            problem.unknowns,
            bcs=problem.bcs,
            entity_maps=problem.entity_maps,
            kind="mpi",
            petsc_options_prefix=prefix,
            petsc_options=opts,
            jit_options=getattr(problem, "jit_options", None),
        )
        self.snes = self.nonlinear.solver
        self.linear.attach(self.nonlinear, prefix, opts)
        #: Krylov iterations of all solves so far (1 per Newton step with the direct solver).
        self.linear_iterations, self._last_linear = 0, 0
        self._watch_residual()
        self._set_dynamics()
        #: Jacobian (and factorisation) reuse within a step (StepOptions.jacobian_reuse).
        reuse = self.options.jacobian_reuse
        self.reuse = JacobianReuse(self.snes, reuse) if reuse > 0 else None

    def _set_dynamics(self) -> None:
        """Give a problem with inertia the scheme's ρ∞; refuse a quasi-static scheme for it."""
        inertia = getattr(self.problem, "inertia", None)
        if inertia is None:
            return
        if self.options.scheme != "generalized-alpha":
            raise FingertipError(
                f"the model has inertia but steps.scheme is {self.options.scheme!r}, which "
                "integrates no acceleration. Fix: steps.scheme = \"generalized-alpha\" (or "
                "model.inertia = false for a quasi-static run).")
        inertia.set_dissipation(self.options.rho_inf)
        contact = getattr(self.problem, "contact", None)
        if contact is not None and not contact.conservative:
            warnings.warn(
                f"a dynamic run with {contact.method} contact (theta = {contact.theta}), whose "
                "force derives from no potential: it can feed the contact zone's fast modes "
                "(on the coarse fingertip at 250 Hz an oscillation near the steps' Nyquist "
                "frequency grew until Newton failed at steps of 50 µs; generalised-α's "
                "dissipation hides it at larger steps). Fix: model.contact = \"penalty\" with "
                "model.contact_gamma0 = 100 (conservative; penetration ~ pressure/γ), see "
                "contact.py.",
                NonConservativeContactWarning, stacklevel=3)

    def close(self) -> None:
        """Destroy the solver's PETSc objects now, on every rank together.

        Their destruction is collective (MUMPS broadcasts as it frees its factors). Left to
        Python's garbage collector, it happens at different moments on different ranks (rank 0
        alone draws the figures, which triggers a collection) and `mpiexec` runs hang at exit.
        """
        nonlinear = self.nonlinear
        self.linear.release()
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
        if self.reuse is not None:
            self.reuse.start()
        with np.errstate(all="ignore"):
            self.nonlinear.solve()
        self._last_linear = self.snes.getLinearSolveIterations()
        self.linear_iterations += self._last_linear
        return self.snes.getConvergedReason(), self.snes.getIterationNumber()

    # Accept/reject, cuts, compaction diagnosis and the step-size update in one loop: it is to
    # become a stepping package with step-size policies as objects (noqa until then).
    def run(  # noqa: C901
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
        # Where the load has a kink, the multistep history restarts (output times are no kinks).
        kinks = sorted({*getattr(history, "breakpoints", ()), start_time})
        error_control = opts.control == "error"
        t, dt, step = start_time, opts.dt_initial, 0
        reports: list[StepReport] = []
        # The last two accepted states (time, unknowns), for the predictor.
        states = deque([(t, [f.x.array.copy() for f in problem.unknowns])], maxlen=2)
        if previous is not None:
            states.appendleft(previous)
        # The accepted states since the last kink (at most 3), for BDF2 and the error estimate;
        # `own`: steps since then taken here, whose u_{n−1} the problem holds.
        since = deque(states if previous is not None and not _is_mark(t, kinks) else
                      [states[-1]], maxlen=3)
        own = 0
        self._peaks = [_max_abs(f) for f in problem.unknowns]
        resolve = _period_limit(history, opts.steps_per_period)
        while t < end_time - 1e-12 * max(1.0, end_time):
            started, linear_before = wallclock.perf_counter(), self.linear_iterations
            dt = resolve(t, dt)
            cuts, why, closed_iterates = 0, "", 0
            rejected, extra_iterations, cut_linear = 0, 0, 0
            restart = error_control and len(since) == 1
            saved = _save(problem) if restart else None
            t_first = None  # the end of this step's first attempt
            while True:
                t_new = step_times(marks, t, dt, end_time)
                t_first = t_new if t_first is None else t_first
                problem.dt.value = t_new - t
                problem.set_time(t_new)
                plan = self._prepare(since, own, t_new)
                if error_control:
                    if opts.extrapolate and plan.predictor is not None:
                        _assign(problem.unknowns, plan.predictor)
                elif opts.extrapolate and len(states) == 2 and not _is_mark(t, marks):
                    _extrapolate(problem.unknowns, states, t_new)
                reason, iterations = self.solve_once()
                compacted = None
                if reason > 0:
                    why = (problem.inadmissible() or "").rstrip(".")
                    if not why:
                        if not error_control:
                            break
                        if restart:
                            err, middle, more = self._double(t, t_new, saved, since[-1][1])
                            iterations += more
                        else:
                            err, middle = self._norm(plan), None
                        if err <= 1:
                            break
                        problem.restore()
                        rejected += 1
                        extra_iterations += iterations
                        dt = (t_new - t) * _factor(err, plan.order, opts.safety, 1.0)
                        if step_times(marks, t, dt, end_time) >= t_new:  # stretched back
                            dt = 0.75 * (t_new - t)
                        if dt < opts.dt_min:
                            problem.set_time(t)
                            raise ConvergenceError(
                                f"the step from t = {t:.6g} s keeps a time-integration error "
                                f"{err:.3g} times the tolerance at Δt = {t_new - t:.3g} s, and "
                                f"a smaller step would be below dt_min = {opts.dt_min:g} s. "
                                f"Results up to t = {t:.6g} s are saved. Fix: loosen steps.rtol "
                                "and steps.atol, or lower steps.dt_min; an error that does not "
                                "shrink with the step is Newton's own: tighten the solver's "
                                "snes_atol and snes_rtol."
                            )
                        continue
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
                    # at a quadrature point)? Once may be an overshoot; again after a cut, and
                    # with the accepted states heading there within the step, it is the limit.
                    # Iterates of large ramp steps of the undrained line load closed pores at
                    # J = 0.39 while every accepted state had J = 1: Newton's overshoot, cut.
                    closed_iterates += self._closed is not None
                    if closed_iterates > 1 and _heading_for(problem, states, t_first,
                                                            self._closed.limit):
                        compacted = self._closed
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
                cut_linear += self._last_linear  # uncounted, like the attempt's Newton its
                dt = (t_new - t) * opts.cut
                if cuts > opts.max_cuts or dt < opts.dt_min:
                    problem.set_time(t)
                    a, b = _distinct(t, t_new)
                    load_a, load_b = _distinct(history(t), history(t_new))
                    raise ConvergenceError(
                        f"the step from t = {a} s to t = {b} s (load {load_a} -> {load_b}) "
                        f"failed {cuts} times, the last with Δt = {t_new - t:.3g} s: {why}"
                        f"{_overshoot_note(closed_iterates)}. "
                        f"Results up to t = {a} s are saved. Fix: lower the load or its rate, "
                        "refine the mesh where it fails, or allow smaller steps (dt_min, "
                        "max_cuts)."
                    )
            # Diagnostics first: accepting advances the history, after which the stress forms
            # describe the start of the next step, not the state just solved.
            diagnostics = problem.diagnostics()
            problem.accept()
            new_state = (t_new, [f.x.array.copy() for f in problem.unknowns])
            states.append(new_state)
            step += 1
            report = StepReport(
                step=step,
                time=t_new,
                dt=t_new - t,
                load=history(t_new),
                newton_iterations=iterations + extra_iterations,
                cuts=cuts,
                wall_time_s=wallclock.perf_counter() - started,
                linear_iterations=self.linear_iterations - linear_before - cut_linear,
                diagnostics=diagnostics,
                error=err if error_control else math.nan,
                rejected=rejected,
            )
            taken, planned = t_new - t, dt
            t = t_new
            if error_control:
                dt = self._next_dt(err, plan.order, taken, planned, middle is not None,
                                   cuts > 0)
                self._peaks = [max(a, _max_abs(f)) for a, f in zip(self._peaks, problem.unknowns)]
            # Grow after easy steps, keep the size after hard ones (cuts already shrank it).
            elif cuts == 0 and iterations <= opts.easy_iterations:
                dt = min(max(dt, taken) * opts.growth, opts.dt_max)
            else:
                dt = min(taken, opts.dt_max)
            if error_control and middle is not None:
                since.append(middle)
            since.append(new_state)
            own += 1
            if _is_mark(t, kinks):
                since, own = deque([new_state], maxlen=3), 0
            report.next_dt = dt
            reports.append(report)
            if on_step is not None:
                on_step(report)
            if not math.isfinite(dt) or dt <= 0:
                raise FingertipError(f"time step became {dt} at t = {t}")
        return reports

    # --- the integrator and the error control --------------------------------------------------
    def _prepare(self, since: deque, own: int, t_new: float) -> _Plan:
        """Set the multistep weights of the step to `t_new` (BDF2 once the problem holds a
        u_{n−1} since the last kink, else backward Euler) and, under error control, plan its
        error estimate: the predictor through the last states and Milne's factor."""
        opts, problem = self.options, self.problem
        times = [s[0] for s in since]
        dts = [t_new - times[-1], *np.diff(times)[::-1]]  # Δt_n, Δt_{n−1}, ...
        needed = 3 if opts.control == "error" else 2
        bdf2 = opts.scheme in SECOND_ORDER_RATE and own >= 1 and len(since) >= needed
        weights = getattr(problem, "rate_weights", None)
        if weights is not None:
            weights.value[:] = bdf2_weights(dts[0] / dts[1]) if bdf2 else BACKWARD_EULER
        if opts.control != "error" or len(since) == 1:
            return _Plan(order=1)
        order = 2 if bdf2 else 1
        points = list(since)[-(order + 1):]
        return _Plan(order=order, predictor=_lagrange(points, t_new),
                     factor=milne_factor(order, dts[: order + 1]))

    def _error_of(self, differences: list[np.ndarray], factor: float = 1.0) -> float:
        """max over the unknown fields f of max|factor·d_f| / (atol + rtol·(largest |f|)),
        over every rank (owned dofs)."""
        opts, worst = self.options, 0.0
        for f, d, peak in zip(self.problem.unknowns, differences, self._peaks):
            owned = _owned(f)
            local = float(np.max(np.abs(d[:owned]), initial=0.0))
            scale = max(peak, _max_abs(f))
            comm = f.function_space.mesh.comm
            e = comm.allreduce(local, op=MPI.MAX) * abs(factor) / (opts.atol + opts.rtol * scale)
            worst = max(worst, e if math.isfinite(e) else math.inf)
        return worst

    def _norm(self, plan: _Plan) -> float:
        """The error of the converged step: Milne's factor × (corrector − predictor)."""
        differences = [f.x.array - x for f, x in zip(self.problem.unknowns, plan.predictor)]
        return self._error_of(differences, plan.factor)

    def _double(self, t: float, t_new: float, saved: dict, start: list[np.ndarray]
                ) -> tuple[float, tuple | None, int]:
        """Step doubling for a step without a smooth history (the first, or the first after a
        kink): the unknowns hold one backward-Euler step t → t_new; redo it as two half steps
        from the state `saved` at t and compare. Returns the error of the halves (which are
        kept: the state at t_new, the history advanced over the first half), the state at the
        midpoint, and the Newton iterations. A failed or rejected pair restores `saved`."""
        problem = self.problem
        full = [f.x.array.copy() for f in problem.unknowns]
        _restore(problem, saved)
        t_mid = 0.5 * (t + t_new)
        problem.dt.value = t_new - t_mid
        middle, iterations = None, 0
        for target, guess in ((t_mid, [0.5 * (a + b) for a, b in zip(start, full)]),
                              (t_new, full)):
            problem.set_time(target)
            if self.options.extrapolate:
                _assign(problem.unknowns, guess)
            reason, its = self.solve_once()
            iterations += its
            if reason <= 0 or problem.inadmissible():
                _restore(problem, saved)
                return math.inf, None, iterations
            if middle is None:
                middle = (t_mid, [f.x.array.copy() for f in problem.unknowns])
                problem.accept()
        err = self._error_of([f.x.array - x for f, x in zip(problem.unknowns, full)])
        if err > 1:
            _restore(problem, saved)
            return err, None, iterations
        return err, middle, iterations

    def _next_dt(self, err: float, order: int, taken: float, planned: float, doubled: bool,
                 hard: bool) -> float:
        """The step after an accepted one under error control."""
        opts = self.options
        if doubled:  # two halves of `taken`: one step Δt errs about 2 err (Δt/taken)² as much
            last = 0.5 * taken
            dt = min(taken / math.sqrt(2.0) * _factor(err, 1, opts.safety, math.inf),
                     opts.growth * last)
        else:
            last = taken
            dt = taken * _factor(err, order, opts.safety, opts.growth)
            if planned > taken * (1 + 1e-9) and dt >= taken:  # cut short by a breakpoint
                dt = max(dt, planned)
        if opts.scheme in SECOND_ORDER_RATE:
            dt = min(dt, opts.growth * last)  # BDF2's step ratio stays below 1 + √2
        if hard:
            dt = min(dt, taken)
        return min(dt, opts.dt_max)


class JacobianReuse:
    """Keep the assembled Jacobian, and with it the LU factorisation, while Newton contracts.

    A Newton iteration costs a residual, a Jacobian assembly, an LU factorisation and a solve;
    one with the previous Jacobian (a chord iteration) costs a residual and a pair of
    triangular solves (PETSc refactorises only a matrix whose values changed). Within a solve,
    the Jacobian is kept at an iterate whose residual norm is at most `threshold` times the
    previous iterate's (Newton is in its quadratic phase: the chord step from there is almost
    as good), else reassembled; every solve starts with a fresh one. Newton's tolerances are
    unchanged: only the path to them differs.

    Measured on the line load (benchmarks/line_load.py, 33 steps, 179 factorisations with full
    Newton, 164 once the first step no longer fails): threshold 0.02 saves 17 factorisations
    for 5 more (chord) iterations, 0.05 saves 25 for 12 more, forces and SED equal to 1e-7;
    0.1 keeps Jacobians in the slow, contact-driven phase of the ramp's steps, which then take
    more iterations, grow less and are cut (43 steps, 168 factorisations, more time). Keeping
    the Jacobian across steps as well was worse still (0.25: 54 steps and 227 factorisations;
    0.5: 75 steps). The line-load scene uses 0.02, well clear of that edge.
    """

    def __init__(self, snes: PETSc.SNES, threshold: float):
        if not 0 < threshold < 1:
            raise ValueError(f"the reuse threshold must be in (0, 1), got {threshold}")
        self.threshold = threshold
        self.assembled = self.reused = 0
        self._valid, self._norm = False, None
        J, P, (assemble, args, kargs) = snes.getJacobian()

        def jacobian(snes, x, J_, P_):
            norm = snes.getFunctionNorm()
            if self._valid and (self._norm is None or norm <= self.threshold * self._norm):
                self.reused += 1
            else:
                assemble(snes, x, J_, P_, *args, **(kargs or {}))
                self.assembled += 1
                self._valid = True
            self._norm = norm

        snes.setJacobian(jacobian, J, P)

    def start(self) -> None:
        """A new solve (a step, or its retry) starts from a fresh Jacobian."""
        self._valid, self._norm = False, None


def _period_limit(history, steps_per_period: int) -> Callable[[float, float], float]:
    """dt ↦ min(dt, period/steps_per_period) from the history's `onset` on (0 if it has
    none), if it has a `period`; else dt unchanged."""
    period = getattr(history, "period", None)
    if period is None:
        return lambda t, dt: dt
    onset, largest = getattr(history, "onset", 0.0), period / steps_per_period
    return lambda t, dt: min(dt, largest) if t >= onset - 1e-12 * max(1.0, onset) else dt


def _is_mark(t: float, marks: Sequence[float]) -> bool:
    return any(abs(t - m) <= 1e-12 * max(1.0, abs(m)) for m in marks)


def _extrapolate(unknowns: list[fem.Function], states: deque, t_new: float) -> None:
    """Set the unknowns to the linear extrapolation through the last two accepted states."""
    (t0, old), (t1, last) = states
    c = (t_new - t1) / (t1 - t0)
    for f, a, b in zip(unknowns, old, last):
        f.x.array[:] = b + c * (b - a)


def _lagrange(points: list, t_new: float) -> list[np.ndarray]:
    """The polynomial through the accepted states `points` (time, arrays), at t_new."""
    times = [tp for tp, _ in points]
    weights = [math.prod((t_new - tm) / (tj - tm) for m, tm in enumerate(times) if m != j)
               for j, tj in enumerate(times)]
    return [sum(w * arrays[i] for w, (_, arrays) in zip(weights, points))
            for i in range(len(points[0][1]))]


def bdf2_weights(omega: float) -> tuple[float, float, float]:
    """(a₀, a₁, a₂) of variable-step BDF2: Δt_n ẋ_{n+1} ≈ a₀ x_{n+1} + a₁ x_n + a₂ x_{n−1},
    ω = Δt_n/Δt_{n−1}; (3/2, −2, 1/2) at ω = 1. Exact for quadratics."""
    return ((1 + 2 * omega) / (1 + omega), -(1 + omega), omega**2 / (1 + omega))


def milne_factor(order: int, dts) -> float:
    """K/(K − K_p): the local error of a step from its corrector minus predictor (Milne).

    `dts` = (Δt_n, Δt_{n−1}[, Δt_{n−2}]). Order 1: backward Euler, K = 1/2 (error ≈ K Δt² ẍ),
    against the linear extrapolation through the last two states, K_p = −(1 + r₁)/2 with
    r₁ = Δt_{n−1}/Δt_n: 1/(2 + r₁) (1/3 at equal steps). Order 2: BDF2,
    K = (a₁ + a₂ s³)/(6 a₀) with s = 1 + r₁ (error ≈ K Δt³ x⃛), against the quadratic
    extrapolation through the last three, K_p = −(1 + r₁)(1 + r₁ + r₂)/6: 2/11 at equal steps.
    """
    r = [d / dts[0] for d in dts[1:]]
    if order == 1:
        return 1.0 / (2.0 + r[0])
    a0, a1, a2 = bdf2_weights(1.0 / r[0])
    K = (a1 + a2 * (1 + r[0]) ** 3) / (6 * a0)
    K_p = -(1 + r[0]) * (1 + r[0] + r[1]) / 6
    return K / (K - K_p)


def _factor(err: float, order: int, safety: float, largest: float) -> float:
    """The step-size factor safety·err^(−1/(k+1)), between ERROR_CUT_MIN and `largest`."""
    if err <= 0:
        return largest
    return min(largest, max(ERROR_CUT_MIN, safety * err ** (-1.0 / (order + 1))))


def _owned(f: fem.Function) -> int:
    index_map = f.function_space.dofmap.index_map
    return index_map.size_local * f.function_space.dofmap.index_map_bs


def _max_abs(f: fem.Function) -> float:
    """max |f| over its owned dofs on every rank."""
    local = float(np.max(np.abs(f.x.array[: _owned(f)]), initial=0.0))
    return f.function_space.mesh.comm.allreduce(local, op=MPI.MAX)


def _assign(unknowns: list[fem.Function], arrays: list[np.ndarray]) -> None:
    for f, a in zip(unknowns, arrays):
        f.x.array[:] = a


def _save(problem) -> dict[str, np.ndarray]:
    """A copy of the whole state (history included): error control's doubled steps need it."""
    arrays = getattr(problem, "state_arrays", None)
    if arrays is None:
        raise FingertipError("error control needs the problem's state_arrays() and "
                             "mark_accepted() to redo a step: use control = 'iterations'")
    return {name: a.copy() for name, a in arrays().items()}


def _restore(problem, saved: dict[str, np.ndarray]) -> None:
    for name, a in problem.state_arrays().items():
        a[:] = saved[name]
    problem.mark_accepted()


@dataclass
class _Plan:
    """How a step's error is estimated: its order, the predictor and Milne's factor (none for
    a step that has no smooth history: the first, or the first after a kink)."""

    order: int
    predictor: list[np.ndarray] | None = None
    factor: float = 1.0


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


def _heading_for(problem, states, t_reach: float, limit: float) -> bool:
    """Whether the accepted states head for J = `limit` by `t_reach`: the lowest J of the
    last two accepted states (`states`: (time, unknowns' arrays)), extrapolated linearly."""
    if len(states) < 2:
        return False  # the first step: nothing accepted is heading anywhere yet
    keep = [f.x.array.copy() for f in problem.unknowns]
    lows = []
    for _, arrays in states:
        _assign(problem.unknowns, arrays)
        found = _compacted(problem, math.inf)  # the lowest J, wherever it is
        lows.append(math.inf if found is None else found.J)
    _assign(problem.unknowns, keep)
    (t0, _), (t1, _) = states
    return crosses(t0, lows[0], t1, lows[1], t_reach, limit)


def crosses(t0: float, J0: float, t1: float, J1: float, t_reach: float, limit: float) -> bool:
    """Whether J, falling from J0 at t0 to J1 at t1 and extrapolated linearly, reaches `limit`
    by `t_reach`. A J that does not fall (an undrained tissue stays at J = 1) never does."""
    if not (t1 > t0 and J1 < J0):
        return False
    return J1 + (J1 - J0) / (t1 - t0) * (t_reach - t1) <= limit


def _overshoot_note(closed_iterates: int) -> str:
    """What the failure message adds when Newton's iterates closed pores that the accepted
    states were not heading for."""
    if not closed_iterates:
        return ""
    return (f"; in {closed_iterates} attempt(s) a Newton iterate closed the pores (J <= phi0) "
            "although the accepted states were not heading there: an overshoot of Newton's, "
            "not compaction (smaller or more gradual steps help)")


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


# --- a tolerance asked of the outputs: the time error's share, controlled and verified ----------
#
# Local error control bounds each step's error; the error of an output at the end is the sum of
# what every step left, propagated, so it can be many times the tolerance (the confined ramp
# and hold at rtol 1e-4 ended 6.5e-3 off in the core pressure, where the default atol, 1e-6
# MPa, was 0.5 % of the pressure). So a tolerance asked of the outputs sets the local
# tolerances (`tolerance_steps`) and is then checked against a run whose tolerances, rtol and
# atol alike, are tighter (`verify_time`): the global error of the tighter run is estimated
# from the difference, Richardson-style with the exponent of tolerance proportionality.

#: The share of an asked relative tolerance that goes to the time error; the mesh gets the rest
#: (the two add). Time is the cheap one: BDF2's steps grow as tol^(-1/3), a 2D P2 mesh's
#: unknowns as tol^(-1).
TIME_SHARE = 0.25
#: The first run's rtol per unit of the time budget (see `tolerance_steps`).
RTOL_PER_BUDGET = 0.1
#: atol = rtol × this (mm for displacements, MPa for pressures): the floor for the first steps
#: from rest scales with the tolerance, so tightening the tolerance tightens every field.
ATOL_PER_RTOL = 1e-3
#: How much tighter the verification run is than the one it checks (rtol and atol divided).
TIGHTEN = 4.0
#: Global error ∝ tolerance^a. A step's local error ~ Δt^(k+1) ~ tol and the global ~ Δt^k give
#: a = k/(k + 1): 2/3 for BDF2, but 1/2 for the backward-Euler steps that restart it at every
#: kink of the load, and those dominate right after a ramp. Measured on the confined ramp and
#: hold (benchmarks/biphasic_confined.py --asked): the errors halve per 4x tighter tolerance.
#: The smaller exponent gives the larger, safer estimate.
TOLERANCE_EXPONENT = 0.5
#: Roache's factor of safety on a two-run estimate with an assumed exponent.
TIME_SAFETY = 1.25


def tolerance_steps(budget: float, base: StepOptions) -> StepOptions:
    """The step options for a relative time-error budget on the outputs: `base` with error
    control, BDF2, rtol = RTOL_PER_BUDGET × budget and atol = ATOL_PER_RTOL × rtol (every
    other option, dt_initial, dt_max, dt_min, growth, kept). Steps land on the kinks of the
    load and restart there by step doubling (backward Euler), as every error-controlled run's."""
    if not 0 < budget < 1:
        raise ValueError(f"a time-error budget is a relative error in (0, 1), got {budget}")
    rtol = RTOL_PER_BUDGET * budget
    return tightened(dataclasses.replace(base, control="error", scheme="bdf2",
                                         growth=min(base.growth, 1.5)), 1.0, rtol)


def tightened(options: StepOptions, factor: float, rtol: float | None = None) -> StepOptions:
    """`options` with rtol (or `rtol`) and atol = ATOL_PER_RTOL × rtol divided by `factor`."""
    rtol = (options.rtol if rtol is None else rtol) / factor
    return dataclasses.replace(options, rtol=rtol, atol=ATOL_PER_RTOL * rtol)


def time_estimates(coarse: dict[str, float], fine: dict[str, float], factor: float,
                   scales: dict[str, float] | None = None) -> dict[str, float]:
    """The estimated global time error of each output of the finer run, relative to its scale
    (|fine value| unless `scales` gives one): TIME_SAFETY |fine − coarse| / (factor^a − 1),
    the two runs' tolerances `factor` apart, a = TOLERANCE_EXPONENT."""
    denominator = factor**TOLERANCE_EXPONENT - 1.0
    out = {}
    for key, value in fine.items():
        scale = abs(value) if scales is None else scales[key]
        difference = abs(value - coarse[key])
        out[key] = TIME_SAFETY * difference / denominator / scale if scale > 0 else (
            0.0 if difference == 0 else math.inf)
    return out


def verify_time(run: Callable[[StepOptions, int], dict[str, float]], options: StepOptions,
                budget: float, *, scales: Callable[[dict], dict] | None = None,
                max_runs: int = 4) -> dict:
    """Run with `options`, then tighter, until the estimated global time error of every output
    is within `budget` (relative), or `max_runs` runs.

    `run(options, i)` makes run i and returns its outputs {name: value}; `scales(values)` the
    scale each output's error is relative to (default |value|). Run 1 is TIGHTEN times tighter
    than run 0; a later one tightens the last by (E/(budget/2))^(1/a) (between 2 and 16), E its
    largest estimate. Returns the last run's `values`, its `estimates`, `converged`, and per
    run its rtol, atol and largest estimate (`runs`). The last run is the answer: the earlier
    ones only measure its error.

    A tighter run that fails (a `ConvergenceError`: e.g. a tolerance below what Newton's own
    accuracy can tell) ends the check unconverged, its message in its entry (`failed`); the
    answer is then the last run that finished, with the last estimate (inf after run 0)."""
    values = run(options, 0)
    runs = [{"rtol": options.rtol, "atol": options.atol, "largest_estimate": None}]
    estimates, worst, factor, answer = {k: math.inf for k in values}, math.inf, TIGHTEN, options
    while True:
        tighter = tightened(answer, factor)
        try:
            fresh = run(tighter, len(runs))
        except ConvergenceError as error:
            runs.append({"rtol": tighter.rtol, "atol": tighter.atol, "largest_estimate": None,
                         "failed": str(error)})
            return {"values": values, "estimates": estimates, "converged": False,
                    "budget": budget, "options": answer, "runs": runs}
        estimates = time_estimates(values, fresh, factor,
                                   None if scales is None else scales(fresh))
        values, answer, worst = fresh, tighter, max(estimates.values(), default=0.0)
        runs.append({"rtol": answer.rtol, "atol": answer.atol, "largest_estimate": worst})
        if worst <= budget or len(runs) >= max_runs:
            break
        factor = min(16.0, max(2.0, (worst / (0.5 * budget)) ** (1 / TOLERANCE_EXPONENT)))
    return {"values": values, "estimates": estimates, "converged": worst <= budget,
            "budget": budget, "options": answer, "runs": runs}
