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

Step sizes (`StepOptions.control`; the policies are controllers.py's objects):

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

Under "iterations" a step starts from the linear extrapolation of the last two accepted states,
but not across a breakpoint or an output time; with `tangent_start` the first step after a kink
starts from the tangent predictor (`TangentPredictor`: the accepted state's linearisation, with
friction the sticking skin moved with the indenter) and output times are extrapolated across.

In both, steps land exactly on every breakpoint of the load and output time, and a step is cut
when it fails (divergence, NaN, inverted elements); after `max_cuts` cuts in a row the run
stops with a message that says when, where and why (diagnosis.py). Compaction of a porous
tissue (J within the margin of its solid fraction φ0, at a quadrature point or a node) is a
physical limit, not a numerical one: the run stops at once with a `CompactionError` (also when
Newton's residual turns non-finite twice in a step at an iterate whose pores closed, and the
accepted states, extrapolated, reach the limit within the step; otherwise that iterate overshot
and the step is cut). Times in the messages carry the digits that tell t and t + Δt apart.
Forms are compiled once: time, step size, loads and multistep weights are `fem.Constant`s the
problem updates in place.

`TimeStepper.run` tells the story of a step: begin it (its size limited by the load's period),
settle it (attempts that move the loads, predict, solve and, under error control, estimate,
until one is accepted: a rejected attempt is redone shorter, a failed one cut), accept it
(report it), ask the step-size policy for the next, and advance.
"""

from __future__ import annotations

import math
import time as wallclock
import warnings
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import dolfinx.fem.petsc
import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import FingertipError, SolveInterrupted
from ..loading import step_times
from ..physics.contact import NonConservativeContactWarning
from .controllers import (
    BACKWARD_EULER,
    Outcome,
    PeriodLimit,
    bdf2_weights,
    controller,
    lagrange,
    milne_factor,
)
from .diagnosis import (
    compacted,
    compaction_error,
    crosses,
    cuts_error,
    dynamic_friction_note,
    error_stall_error,
    newton_failure,
)
from .linear import (
    DIRECT_OPTIONS,
    LinearSolver,
    flexible_gmres,
    kept_factor_options,
    use_kept_factors,
)
from .options import (
    DEFAULT_PETSC_OPTIONS,
    SECOND_ORDER_RATE,
    StepOptions,
    StepReport,
    check_factor_reuse,
    check_petsc_options,
)
from .residual import UnliftedResidual


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


class TimeStepper:
    """Drives a `Steppable` problem along a load history with adaptive implicit steps.

    Parameters
    ----------
    problem : Steppable
        The problem to advance (`FingertipProblem`, or a verification problem).
    options : StepOptions, optional
        The step control (default: `StepOptions()`).
    petsc_options : dict, optional
        PETSc options added to the Newton and linear solvers' defaults.
    prefix : str, optional
        The PETSc options prefix of this stepper's SNES.
    linear : str, optional
        The linear solver inside Newton: "direct" (MUMPS) or "iterative".
    """

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
        #: The linear solver inside Newton (linear.py): "direct" (MUMPS) or "iterative".
        self.linear = LinearSolver(linear, problem)
        opts, limit = self._solver_options(petsc_options, linear)
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
        #: Krylov iterations of all solves so far (1 per Newton step with the direct solver;
        #: tangent_reuse's GMRES iterations too).
        self.linear_iterations, self._last_linear = 0, 0
        #: The residual without DOLFINx's Dirichlet lifting where it adds zero (residual.py).
        self.residual = UnliftedResidual(self.snes)
        self._watch_residual()
        self._set_dynamics()
        #: Called after every Newton iteration on every rank together (a collective callable,
        #: e.g. the runner's signal check): True ends the solve there, puts back the accepted
        #: state and raises SolveInterrupted. None: never asked.
        self.stop_asked: Callable[[], bool] | None = None
        self._interrupted = False
        self.snes.setMonitor(self._check_stop)
        #: Jacobian (and factorisation) reuse within a step (StepOptions.jacobian_reuse).
        reuse = self.options.jacobian_reuse
        self.reuse = JacobianReuse(self.snes, reuse) if reuse > 0 else None
        #: The LU factorisation kept as GMRES's preconditioner (StepOptions.factor_reuse, or
        #: hold_factor_reuse: in held steps only).
        self.factor = None if limit == 0 else FactorReuse(
            self.snes, limit, held_only=self.options.factor_reuse == 0)
        #: Whether a step may start from the Jacobian the last one ended with (`_carries`), and
        #: whether the solver holds the last step's LU factors for the predictor (`_predict`).
        self._kept = self._factored = False
        #: The predictor where no extrapolation starts a step (StepOptions.tangent_start).
        self.tangent = TangentPredictor(self.snes, self.nonlinear) \
            if self.options.tangent_start else None
        #: Force control's predictor between the solves of a step (`_solve_to_force`).
        self.depth_tangent = None if getattr(problem, "force_control", None) is None else \
            self.tangent or TangentPredictor(self.snes, self.nonlinear)
        _check_force_control(problem, self.options)

    def _solver_options(self, petsc_options: dict | None, linear: str) -> tuple[dict, int]:
        """The SNES's PETSc options (Newton's defaults, the linear route's, a kept
        factorisation's, the caller's) and the Krylov limit of the kept factors (0: none).
        factor_reuse keeps the factors in every step (GMRES from the options), hold_factor_reuse
        in held steps only (FactorReuse switches the direct route's KSP for them); the
        iterative route has no factors: there hold_factor_reuse changes nothing."""
        newton = {k: v for k, v in DEFAULT_PETSC_OPTIONS.items() if k not in DIRECT_OPTIONS}
        held = self.options.hold_factor_reuse if linear == "direct" else 0
        limit = self.options.factor_reuse or held
        kept = kept_factor_options(limit) if self.options.factor_reuse > 0 else {}
        opts = {**newton, **self.linear.options, **kept,
                **check_petsc_options(petsc_options or {}, "petsc_options")}
        check_factor_reuse(limit, linear, opts, "steps.factor_reuse" if kept else
                           "steps.hold_factor_reuse")
        return opts, limit

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
        for tangent in (self.tangent, self.depth_tangent):  # one object where both exist
            if tangent is not None:
                tangent.close()  # closing twice is nothing
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

    def _check_stop(self, snes, its: int, fnorm: float) -> None:
        """SNES's monitor: end the solve after this iteration if a stop was asked (the
        reason, a divergence, only ends it: `solve_once` reads `_interrupted`)."""
        if its > 0 and self.stop_asked is not None and self.stop_asked():
            self._interrupted = True
            snes.setConvergedReason(PETSc.SNES.ConvergedReason.DIVERGED_FUNCTION_DOMAIN)

    def solve_once(self, keep: bool = False) -> tuple[int, int]:
        """One Newton solve from the current state; returns (converged reason, iterations).
        `keep`: start from the Jacobian kept from the last solve (JacobianReuse.start)."""
        self._evaluations, self._closed = 0, None
        if self.reuse is not None:
            self.reuse.start(keep)
        if self.factor is not None:  # after a failed solve, from a fresh factorisation
            self.factor.start(fresh=self.snes.getConvergedReason() < 0)
        with np.errstate(all="ignore"):
            self.nonlinear.solve()
        if self._interrupted:
            self._interrupted = False
            raise SolveInterrupted(math.nan)  # the step's time: `run` puts its state back
        self._last_linear = self.snes.getLinearSolveIterations()
        self.linear_iterations += self._last_linear
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
        self._control = controller(self.options)  # the options may change between runs
        line = _Timeline.start(self.problem, history, end_time, start_time, breakpoints,
                               previous)
        self._peaks = [_max_abs(f) for f in self.problem.unknowns]
        limit = PeriodLimit(history, self.options.steps_per_period)
        dt, reports = self.options.dt_initial, []
        self._kept = self._factored = False  # a run starts with a fresh Jacobian
        while not line.finished():
            step = self._begin(line, limit(line.t, dt))
            try:
                self._settle(line, step)  # predict, solve, estimate; reject or cut until taken
            except SolveInterrupted:
                self._put_back(step)
                raise SolveInterrupted(step.t) from None
            report, state = self._accept(line, step, number=len(reports) + 1)
            self._factored = self.options.tangent_reuse and self.linear.linear == "direct"
            held = _held(history, step.t, step.t_new) and not _force_control(self.problem,
                                                                             step.t_new)
            dt = report.next_dt = self._control.next_dt(step.outcome(held))
            self._kept = self._carries(step, held)
            if self._control.estimates_error:
                self._peaks = [max(a, _max_abs(f))
                               for a, f in zip(self._peaks, self.problem.unknowns)]
            line.advance(state, step.middle)
            reports.append(report)
            if on_step is not None:
                on_step(report)
            if not math.isfinite(dt) or dt <= 0:
                raise FingertipError(f"time step became {dt} at t = {line.t}")
        return reports

    # --- one step: its attempts, until one is accepted -----------------------------------------
    def _put_back(self, step: _Step) -> None:
        """The accepted state at the step's start, as if the step had never begun (a doubled
        step's half may have advanced the history: its saved state has it all)."""
        if step.saved is not None:
            _restore(self.problem, step.saved)
        else:
            self.problem.restore()
        self.problem.set_time(step.t)

    def _begin(self, line: _Timeline, dt: float) -> _Step:
        """A step from `line.t` of (at most) `dt`; under error control the first step after a
        kink saves the whole state, for its step doubling."""
        restart = self._control.estimates_error and len(line.since) == 1
        return _Step(t=line.t, dt=dt, started=wallclock.perf_counter(),
                     linear_before=self.linear_iterations,
                     saved=_save(self.problem) if restart else None)

    def _settle(self, line: _Timeline, step: _Step) -> None:
        """Attempt the step until an attempt is accepted: a converged, admissible state, under
        error control also within the tolerance. A rejected attempt is redone shorter, a failed
        one cut; both raise when the step can shrink no further."""
        while True:
            self._attempt(line, step)
            if step.reason > 0 and not step.why:
                if not self._control.estimates_error or self._estimate(line, step) <= 1:
                    return
                self._reject(line, step)
            else:
                self._fail(line, step)

    def _attempt(self, line: _Timeline, step: _Step) -> None:
        """Move the loads to the attempt's end, predict the unknowns there and solve."""
        problem, opts, predicted = self.problem, self.options, 0
        step.t_new = line.lands(step.t, step.dt)
        step.t_first = step.t_new if step.t_first is None else step.t_first
        problem.dt.value = step.t_new - step.t
        control = _force_control(problem, step.t_new)
        if control is not None:
            control.begin(step.t_new)  # the predicted depth, before the loads move there
        problem.set_time(step.t_new)
        step.plan = self._prepare(line.since, line.own, step.t_new)
        if self._control.estimates_error:
            if opts.extrapolate and step.plan.predictor is not None:
                _assign(problem.unknowns, step.plan.predictor)
        elif opts.extrapolate and len(line.states) == 2 and not _is_mark(
                step.t, line.marks if self.tangent is None else line.kinks):
            _extrapolate(problem.unknowns, line.states, step.t_new)
        elif self.tangent is not None and len(line.states) == 2:  # its solve: an iteration
            self._predict(step)
            predicted = 1
        step.reason, step.iterations = self._solve(line, step, control, predicted)
        step.iterations += predicted
        step.why = (problem.inadmissible() or "").rstrip(".") if step.reason > 0 else ""
        if control is not None and step.reason > 0 and not step.why and not control.reached:
            step.why = control.shortfall()  # a force off its tolerance: the step is cut

    def _solve(self, line: _Timeline, step: _Step, control, predicted: int) -> tuple[int, int]:
        """The attempt's Newton solves (SNES reason, iterations): under force control to the
        force; a held step, unpredicted and uncut, after an easy held one from the Jacobian
        kept (jacobian_carry); else one solve. With hold_factor_reuse, a held step's Newton
        solves run on the kept LU factors (FactorReuse.hold), every other solve on its own."""
        held = control is None and _held(line.history, step.t, step.t_new)
        if self.factor is not None:
            self.factor.hold(held)
        try:
            if control is not None:
                return self._solve_to_force(control, step.t_new)
            if self._kept and not predicted and step.cuts == step.rejected == 0 and held:
                return self._solve_from_kept()
            return self.solve_once()
        finally:
            if self.factor is not None:
                self.factor.hold(False)  # the predictor and other solves factorise as before

    def _predict(self, step: _Step) -> None:
        """The tangent predictor of the attempt, with the accepted state's Jacobian: solved by
        GMRES on the factors the last accepted step ended with (StepOptions.tangent_reuse) on
        a first attempt, else factorised (a cut attempt's solver holds a failed one's)."""
        kept = self._factored and step.cuts == step.rejected == 0
        self._factored = False  # this attempt's solve replaces them
        if self.reuse is not None:
            self.reuse.start()  # a fresh Jacobian: the accepted state's, not a kept one
        self.linear_iterations += self.tangent.predict(self.problem, step.t, step.t_new,
                                                       kept=kept)

    def _carries(self, step: _Step, held: bool) -> bool:
        """Whether the step after the accepted `step` may start from the Jacobian it ended
        with (StepOptions.jacobian_carry): `step` was taken under a held load, uncut, in at
        most `jacobian_carry` Newton iterations; the next step must be held too (`_attempt`)."""
        most = self.options.jacobian_carry
        return (self.reuse is not None and most > 0 and held and step.cuts == 0
                and step.iterations <= most)

    def _solve_from_kept(self) -> tuple[int, int]:
        """Solve a held step from the Jacobian the last step ended with; if Newton fails with
        it, solve again from the same start with a fresh Jacobian, as a step without the
        option would (the failed solve's iterations are counted: they were spent). The kept
        Jacobian is reassembled as soon as an iteration cuts the residual by less than the
        reuse threshold (JacobianReuse)."""
        start = [f.x.array.copy() for f in self.problem.unknowns]
        reason, iterations = self.solve_once(keep=True)
        if reason > 0:
            return reason, iterations
        _assign(self.problem.unknowns, start)
        reason, more = self.solve_once()
        return reason, iterations + more

    def _solve_to_force(self, control, t_new: float) -> tuple[int, int]:
        """Under force control (force_control.py): solve the step at the trial depth, each
        solve from the last one's state, until the indenters' normal force is within its
        tolerance, a solve fails, its state is inadmissible, or `control.max_solves` solves are
        spent (`control.reached` says which). Returns the last SNES reason and the Newton
        iterations of all the solves."""
        problem, iterations = self.problem, 0
        for _ in range(control.max_solves):
            reason, its = self.solve_once()
            iterations += its
            if reason <= 0 or problem.inadmissible():
                break
            d = control.d_trial
            if control.record(problem.normal_force()):
                break
            # to the next trial depth along the tangent (an iteration's cost: counted as one)
            d_next = control.d_trial

            def move(s, d=d, d_next=d_next):
                control.d_trial = d + s * (d_next - d)
                problem.set_time(t_new)

            if self.reuse is not None:
                self.reuse.start()  # the Jacobian of the solved state, not a kept one
            self.depth_tangent.predict_along(problem, move)
            iterations += 1
        return reason, iterations

    def _estimate(self, line: _Timeline, step: _Step) -> float:
        """The converged attempt's error over the tolerance: by step doubling after a kink (the
        halves are kept if they pass), else by Milne's device."""
        if step.saved is not None:
            step.error, step.middle, more = self._double(step.t, step.t_new, step.saved,
                                                         line.since[-1][1])
            step.iterations += more
        else:
            step.error, step.middle = self._norm(step.plan), None
        return step.error

    def _reject(self, line: _Timeline, step: _Step) -> None:
        """Redo an attempt whose error is over the tolerance with a shorter step."""
        self.problem.restore()
        step.rejected += 1
        step.extra_iterations += step.iterations
        step.dt = self._control.reject(step.error, step.plan.order, step.t, step.t_new,
                                       lambda dt: line.lands(step.t, dt))
        if step.dt < self.options.dt_min:
            self.problem.set_time(step.t)
            raise error_stall_error(step.t, step.t_new, step.error, self.options.dt_min)

    def _fail(self, line: _Timeline, step: _Step) -> None:
        """A failed attempt: stop on compaction, else cut the step (and stop after too many
        cuts, or below dt_min)."""
        problem = self.problem
        found = self._compaction(line, step)
        problem.restore()
        if found is not None:
            problem.set_time(step.t)
            raise compaction_error(problem, found, step.t, step.t_new, iterate=step.reason <= 0)
        step.cuts += 1
        step.cut_linear += self._last_linear  # uncounted, like the attempt's Newton iterations
        step.dt = self._control.cut(step.t_new - step.t)
        if step.cuts > self.options.max_cuts or step.dt < self.options.dt_min:
            problem.set_time(step.t)
            control = _force_control(problem, step.t_new)
            # under force control the depths are the ones found (the accepted state's) and the
            # last one tried, not the protocol's
            loads = (line.history(step.t), line.history(step.t_new)) if control is None else \
                (control.depth_at(step.t), control.tried)
            raise cuts_error(step.t, step.t_new, loads, step.cuts, step.why,
                             step.closed_iterates, dynamic_friction_note(problem),
                             found=control is not None)

    def _compaction(self, line: _Timeline, step: _Step):
        """The compaction a failed attempt reached (admissibility.Compacted), or None; for a
        Newton failure, also why it failed (`step.why`).

        A converged but inadmissible state has reached the limit if it is compacted. A Newton
        failure has if the residual turned non-finite at an iterate whose pores closed (J ≤ φ0
        at a quadrature point) for the second time in the step, with the accepted states heading
        there within it: once may be an overshoot. Iterates of large ramp steps of the
        undrained line load closed pores at J = 0.39 while every accepted state had J = 1:
        Newton's overshoot, cut."""
        problem = self.problem
        if step.reason > 0:
            return compacted(problem)
        hotspot = getattr(problem, "residual_hotspot", None)
        where = None if hotspot is None else hotspot(self.snes.getFunction()[0])
        step.why = newton_failure(step.reason, where)
        closed = self._closed  # this attempt's closed iterate; an earlier one may have closed
        step.closed_iterates += closed is not None
        if closed is not None and step.closed_iterates > 1 and self._heading_for(
                line.states, step.t_first, closed.limit):
            return self._closed
        return None

    def _accept(self, line: _Timeline, step: _Step, number: int
                ) -> tuple[StepReport, tuple[float, list[np.ndarray]]]:
        """Take the attempt's state as the new history; its report and the state (time,
        unknowns' arrays)."""
        problem = self.problem
        # Diagnostics first: accepting advances the history, after which the stress forms
        # describe the start of the next step, not the state just solved.
        diagnostics = problem.diagnostics()
        problem.accept()
        state = (step.t_new, [f.x.array.copy() for f in problem.unknowns])
        report = StepReport(
            step=number,
            time=step.t_new,
            dt=step.t_new - step.t,
            load=line.history(step.t_new),
            newton_iterations=step.iterations + step.extra_iterations,
            cuts=step.cuts,
            wall_time_s=wallclock.perf_counter() - step.started,
            linear_iterations=self.linear_iterations - step.linear_before - step.cut_linear,
            diagnostics=diagnostics,
            error=step.error,
            rejected=step.rejected,
        )
        return report, state

    def _heading_for(self, states: deque, t_reach: float, limit: float) -> bool:
        """Whether the accepted states head for J = `limit` by `t_reach`: the lowest J of the
        last two accepted states (`states`: (time, unknowns' arrays)), extrapolated linearly."""
        if len(states) < 2:
            return False  # the first step: nothing accepted is heading anywhere yet
        unknowns = self.problem.unknowns
        keep = [f.x.array.copy() for f in unknowns]
        lows = []
        for _, arrays in states:
            _assign(unknowns, arrays)
            found = compacted(self.problem, math.inf)  # the lowest J, wherever it is
            lows.append(math.inf if found is None else found.J)
        _assign(unknowns, keep)
        (t0, _), (t1, _) = states
        return crosses(t0, lows[0], t1, lows[1], t_reach, limit)

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
        return _Plan(order=order, predictor=lagrange(points, t_new),
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


class JacobianReuse:
    """Keep the assembled Jacobian, and with it the LU factorisation, while Newton contracts.

    A Newton iteration costs a residual, a Jacobian assembly, an LU factorisation and a solve;
    one with the previous Jacobian (a chord iteration) costs a residual and a pair of
    triangular solves (PETSc refactorises only a matrix whose values changed). Within a solve,
    the Jacobian is kept at an iterate whose residual norm is at most `threshold` times the
    previous iterate's (Newton is in its quadratic phase: the chord step from there is almost
    as good), else reassembled; every solve starts with a fresh one, except a held step's
    after an easy held step with StepOptions.jacobian_carry (TimeStepper._carries), which
    starts from the kept one. Newton's tolerances are unchanged: only the path to them differs.

    A threshold too loose keeps Jacobians in the slow, contact-driven phase of a ramp's steps,
    which then take more iterations and are cut; the line-load scene uses 0.02, well clear of
    that edge (docs/benchmarks/measurements.md, "Jacobian reuse").
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

    def start(self, keep: bool = False) -> None:
        """A new solve (a step, or its retry) starts from a fresh Jacobian; with `keep`, from
        the one kept (the last assembled, if any), whose first iteration is judged by the
        threshold like any kept Jacobian's."""
        self._valid, self._norm = self._valid and keep, None


class FactorReuse:
    """Keep the LU factorisation of an older Jacobian as the preconditioner of GMRES, which
    solves every Newton iteration's system with the Jacobian assembled fresh.

    An iteration then costs an assembly, a residual and k GMRES iterations (a pair of
    triangular solves and a mat-vec each) instead of a factorisation. k grows as the Jacobian
    moves away from the factored one (the contact set grows, the tissues stiffen, Δt changes
    the Darcy term): after a solve of more than `limit` iterations the next Jacobian is
    factorised; a solve that has not converged after 2 × `limit` (GMRES's cap,
    linear.kept_factor_options) is finished at once by factorising the Jacobian being solved
    and solving with the new factors, which are kept from then on. Every Newton iteration
    gets an exact solve (to GMRES's 1e-10, or LU's own), so Newton's iterates, and its
    answers, are the direct route's. A Newton solve after a failed one starts with a fresh
    factorisation (`start`). `limit` should be below the factorisation's cost in iterations
    (3D line load, 2 ranks: 4.2 s against ~0.12 s, ~35).

    The hooks are the KSP's pre- and post-solve (KSPSetPreSolve, KSPSetPostSolve). The first
    runs after SNES has set the reuse flag from its own preconditioner lag, before the PC is
    set up: PCSetUp keeps the factors while `PCSetReusePreconditioner` is set, whatever the
    operator's values (the mat-vecs use the operator as assembled). The second runs at the end
    of KSPSolve, before SNES reads the outcome. The factors are solver state, never saved: a
    resumed run starts with fresh ones.

    `held_only` (StepOptions.hold_factor_reuse): the KSP is the direct route's (preonly LU,
    every matrix factorised) except during a held step's Newton solves, for which `hold`
    switches it to flexible GMRES on the kept factors and back (`linear.use_kept_factors`).
    """

    def __init__(self, snes: PETSc.SNES, limit: int, held_only: bool = False):
        if not limit >= 1:
            raise ValueError(f"the Krylov limit must be >= 1, got {limit}")
        self.limit = limit
        #: StepOptions.hold_factor_reuse: the factors are kept for Newton's solves in held
        #: steps only (`hold`); every other solve is the direct route's own (preonly LU).
        self.held_only, self._active = held_only, not held_only
        #: Factorisations done; solves finished by a new one after `limit` iterations.
        self.factorisations = self.fallbacks = 0
        #: Solves preconditioned by the factors of an older matrix than the one solved.
        self.kept = 0
        self._fresh, self._state, self._last = True, None, 0
        self._ksp = ksp = snes.getKSP()
        self._pc = ksp.getPC()
        ksp.setPreSolve(self._presolve)
        ksp.setPostSolve(self._postsolve)

    def hold(self, held: bool) -> None:
        """With `held_only`: the coming solves are a held step's Newton solves (True: FGMRES
        on the kept factors, `linear.use_kept_factors`) or not (False: preonly LU, each matrix
        factorised). Without it, nothing: the factors serve every solve."""
        if self.held_only and held != self._active:
            self._active = held
            use_kept_factors(self._ksp, self.limit, held)

    def _presolve(self, ksp: PETSc.KSP, b: PETSc.Vec, x: PETSc.Vec) -> None:
        renew = self._fresh or self._last > self.limit or not self._active
        self._pc.setReusePreconditioner(not renew)
        if renew:
            self._factored(ksp)
        elif ksp.getOperators()[1].stateGet() != self._state:
            self.kept += 1
        self._fresh = False

    def _factored(self, ksp: PETSc.KSP) -> None:
        """Count a factorisation of the operator as it is now (PCSetUp refactorises only a
        matrix whose values changed since its last set-up)."""
        state = ksp.getOperators()[1].stateGet()
        if state != self._state:
            self.factorisations += 1
            self._state = state

    def _postsolve(self, ksp: PETSc.KSP, b: PETSc.Vec, x: PETSc.Vec) -> None:
        """A solve that stopped short of the tolerance (not one that met a NaN: SNES fails
        that step) is redone directly with the factors of the matrix being solved."""
        reason, self._last = ksp.getConvergedReason(), ksp.getIterationNumber()
        if reason >= 0 or reason == PETSc.KSP.ConvergedReason.DIVERGED_NANORINF:
            return
        self._pc.setReusePreconditioner(False)
        self._pc.setUp()
        self._factored(ksp)
        self.fallbacks += 1
        if self._pc.getFailedReason() != 0:
            return  # the factorisation failed: so does the solve, and SNES's step
        self._pc.apply(b, x)
        ksp.setConvergedReason(PETSc.KSP.ConvergedReason.CONVERGED_ITS)
        self._last = 0  # the new factors are the solved matrix's

    def start(self, fresh: bool = False) -> None:
        """A Newton solve starts; with `fresh`, from a new factorisation."""
        self._fresh = self._fresh or fresh


class TangentPredictor:
    """The tangent (Euler) predictor: u_n − J_n⁻¹ [R(u_n; t) + ∂R/∂t (t_new − t)], the first
    Newton iterate of a step linearised at the accepted state u_n under its own loads (J_n,
    and ∂R/∂t by a difference over a sliver `EPS` × Δt of the load path).

    Started from u_n with the loads moved to t_new, Newton linearises where the loads jumped:
    a plate moved along the skin by Δx makes the friction's trial traction γ_τ Δx, far outside
    Coulomb's cone, so every contact point enters the first iteration on the slip branch with
    its traction clipped to μp: the residual no longer tells how far the skin must follow the
    plate, and Newton moves it by ~(μp − |f|)/γ_τ per iteration. Taken at the accepted state,
    where the sliver of the load path keeps every point on its branch (stick stays stick,
    contact stays contact), the linearisation moves the sticking skin with the plate.
    """

    #: The sliver of the step over which ∂R/∂t is differenced: small enough that no point
    #: leaves its branch, large enough that the difference is far above round-off.
    EPS = 1e-6
    #: `kept` (StepOptions.tangent_reuse): GMRES's relative residual and its iteration cap.
    #: The factors are of a Newton iterate near the accepted state, yet applied alone they
    #: are no solve: at the contact zone's edge (gaps inside the law's 0.1 µm smoothing band)
    #: a point the accepted state holds in contact may be free at that iterate, and the
    #: factors' solve drives it 10-100 times too far (2D line load: predictors 4-100 times
    #: the exact one, steps cut to 0.1 ms). GMRES corrects those few points in a few
    #: iterations. It must solve tightly: the error it leaves lies in the soft tissue's
    #: compliant modes, where a small residual is a large displacement (2D line load: to 1e-3
    #: relative, 146 steps and 37 cuts against 26 and none; to 1e-6 and 1e-10 the exact
    #: predictor's steps, iterations and forces, in 6 and 9 GMRES iterations per predictor).
    #: A solve not converged within the cap, about a factorisation's cost in 3D (an iteration
    #: 0.14 s, a factorisation 2.5-4 s on the 3D line load, 2 ranks), is redone by
    #: factorising.
    KEPT_RTOL, KEPT_MAX_IT = 1e-8, 20

    def __init__(self, snes: PETSc.SNES, nonlinear):
        self.snes, self.x = snes, nonlinear.x
        self.r0, self.r1, self.dx = (self.x.duplicate() for _ in range(3))
        self._gmres: PETSc.KSP | None = None
        #: Predictors solved on kept factors, and those redone by factorising.
        self.kept = self.refactored = 0

    def close(self) -> None:
        """Destroy the kept-factor GMRES, on every rank together (TimeStepper.close)."""
        if self._gmres is not None:
            self._gmres.destroy()
            self._gmres = None

    def predict(self, problem, t: float, t_new: float, kept: bool = False) -> int:
        """Set the unknowns to the tangent predictor of the step t → t_new (the loads end at
        t_new, the problem's dt is the step's). `kept`: solve by GMRES on the LU factors the
        solver holds (StepOptions.tangent_reuse). Returns GMRES's iterations (0 without)."""
        return self.predict_along(problem, lambda s: problem.set_time(
            t_new if s == 1.0 else t + s * (t_new - t)), kept)  # t_new itself, to the digit

    def predict_along(self, problem, move: Callable[[float], None],
                      kept: bool = False) -> int:
        """The same for any change of the loads: `move(s)` sets them a fraction s of the way
        (0 where the unknowns are, 1 where they go; they end at 1). Force control moves the
        depth so between two solves of a step: from the last solve's state with the
        indenters moved by more than its penetration (~0.2 µm on the coarse shear scene),
        Newton starts with the contact lost or overlapping, and was measured to fail (15
        iterations for a move of 0.15 µm)."""
        snes, x = self.snes, self.x
        dolfinx.fem.petsc.assign(problem.unknowns, x)
        J, P, _ = snes.getJacobian()
        move(0.0)
        snes.computeFunction(x, self.r0)
        snes.computeJacobian(x, J, P)
        move(self.EPS)
        snes.computeFunction(x, self.r1)
        move(1.0)
        self.r1.axpby(1.0 - 1.0 / self.EPS, 1.0 / self.EPS, self.r0)  # r0 + (r1 − r0)/EPS
        iterations, solved = self._solve_kept(J, self.r1, self.dx) if kept else (0, False)
        if not solved:
            ksp = snes.getKSP()
            ksp.setOperators(J, P)
            ksp.solve(self.r1, self.dx)
        x.axpy(-1.0, self.dx)
        x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        dolfinx.fem.petsc.assign(x, problem.unknowns)
        for f in problem.unknowns:
            f.x.scatter_forward()
        return iterations

    def _solve_kept(self, J: PETSc.Mat, b: PETSc.Vec, dx: PETSc.Vec) -> tuple[int, bool]:
        """dx ≈ J⁻¹ b by GMRES (KEPT_RTOL), right-preconditioned by the factors the Newton
        solver's LU holds: its iterations, and whether it converged."""
        pc = self.snes.getKSP().getPC()
        if self._gmres is None:
            self._gmres = _kept_factor_gmres(J.getComm(), pc, self.KEPT_RTOL, self.KEPT_MAX_IT)
        self._gmres.setOperators(J, J)
        pc.setReusePreconditioner(True)  # its PCApply must not refactorise the new J
        try:
            self._gmres.solve(b, dx)
        finally:
            pc.setReusePreconditioner(False)  # SNES sets it again from its own lag
        solved = self._gmres.getConvergedReason() > 0
        self.kept += solved
        self.refactored += not solved
        return self._gmres.getIterationNumber(), solved


@dataclass
class _Timeline:
    """Where a run is: the times its steps land on (`marks`: the load's breakpoints, the
    output times, the end), the load's kinks (where the multistep history restarts; output
    times are no kinks), and the accepted states behind `t`."""

    history: Callable[[float], float]
    end_time: float
    marks: list[float]
    kinks: list[float]
    t: float
    #: The last two accepted states (time, unknowns' arrays), for the predictor.
    states: deque
    #: The accepted states since the last kink (at most 3), for BDF2 and the error estimate.
    since: deque
    #: Steps since the last kink taken in this run, whose u_{n−1} the problem holds.
    own: int = 0

    @classmethod
    def start(cls, problem, history, end_time: float, start_time: float,
              breakpoints: Sequence[float], previous) -> _Timeline:
        marks = sorted({*getattr(history, "breakpoints", ()), *breakpoints, end_time})
        kinks = sorted({*getattr(history, "breakpoints", ()), start_time})
        states = deque([(start_time, [f.x.array.copy() for f in problem.unknowns])], maxlen=2)
        if previous is not None:
            states.appendleft(previous)
        since = deque(states if previous is not None and not _is_mark(start_time, kinks) else
                      [states[-1]], maxlen=3)
        return cls(history, end_time, marks, kinks, start_time, states, since)

    def finished(self) -> bool:
        return not self.t < self.end_time - 1e-12 * max(1.0, self.end_time)

    def lands(self, t: float, dt: float) -> float:
        """Where a step of at most dt from t ends: on the first mark it reaches, or on one a
        sliver beyond it (loading.step_times)."""
        return step_times(self.marks, t, dt, self.end_time)

    def advance(self, state: tuple[float, list[np.ndarray]], middle: tuple | None) -> None:
        """Move to the accepted `state` (and the `middle` of a doubled step before it)."""
        self.t = state[0]
        self.states.append(state)
        if middle is not None:
            self.since.append(middle)
        self.since.append(state)
        self.own += 1
        if _is_mark(self.t, self.kinks):
            self.since, self.own = deque([state], maxlen=3), 0


@dataclass
class _Plan:
    """How a step's error is estimated: its order, the predictor and Milne's factor (none for
    a step that has no smooth history: the first, or the first after a kink)."""

    order: int
    predictor: list[np.ndarray] | None = None
    factor: float = 1.0


@dataclass
class _Step:
    """A step from `t` while its attempts run: the size of the next attempt (`dt`), the last
    attempt (`t_new`, its SNES `reason` and Newton `iterations`, why it failed), and the tally
    the report gives."""

    t: float
    dt: float
    started: float  # wall clock
    linear_before: int  # the stepper's Krylov iterations before the step
    saved: dict | None = None  # error control after a kink: the state at t, for step doubling
    t_new: float = math.nan
    t_first: float | None = None  # the end of the first attempt
    plan: _Plan | None = None
    reason: int = 0
    iterations: int = 0
    why: str = ""
    error: float = math.nan  # error control: the last estimate over the tolerance
    middle: tuple | None = None  # the midpoint state of an accepted doubled step
    extra_iterations: int = 0  # Newton iterations of rejected attempts (reported)
    cuts: int = 0
    rejected: int = 0
    cut_linear: int = 0  # Krylov iterations of failed attempts (not reported)
    closed_iterates: int = 0  # failed attempts whose iterate closed the pores

    def outcome(self, held: bool = False) -> Outcome:
        """The accepted step, as the step-size policy sees it (`held`: under a held load)."""
        return Outcome(taken=self.t_new - self.t, planned=self.dt, iterations=self.iterations,
                       cuts=self.cuts, error=self.error, order=self.plan.order,
                       doubled=self.middle is not None, held=held)


def _check_force_control(problem, options: StepOptions) -> None:
    """Force control finds the depth per step: no error control's doubled steps with it."""
    if getattr(problem, "force_control", None) is not None and options.control == "error":
        raise FingertipError("force control finds the depth per step, which error control's "
                             "doubled steps would not. Fix: steps.control = \"iterations\" "
                             "(the default).")


def _held(history, t: float, t_new: float) -> bool:
    """Whether the load is the same at t, halfway and at t_new: the indenters' displacement
    `history(t)` and, on a tangential path, their displacement along the skin."""
    along = getattr(history, "displacement_at", None)
    loads = [np.hstack([history(s), *(along(s) if along else ())])
             for s in (t, 0.5 * (t + t_new), t_new)]
    return all(np.array_equal(loads[0], x) for x in loads[1:])


def _force_control(problem, t_new: float):
    """The problem's force control (force_control.DepthControl) if it holds the force in the
    step to t_new, else None."""
    control = getattr(problem, "force_control", None)
    return control if control is not None and control.active(t_new) else None


def _is_mark(t: float, marks: Sequence[float]) -> bool:
    return any(abs(t - m) <= 1e-12 * max(1.0, abs(m)) for m in marks)


def _extrapolate(unknowns: list[fem.Function], states: deque, t_new: float) -> None:
    """Set the unknowns to the linear extrapolation through the last two accepted states."""
    (t0, old), (t1, last) = states
    c = (t_new - t1) / (t1 - t0)
    for f, a, b in zip(unknowns, old, last):
        f.x.array[:] = b + c * (b - a)


class _Factors:
    """A python PC that applies another PC as it is set up (here the Newton solver's LU)."""

    def __init__(self, pc: PETSc.PC):
        self.pc = pc

    def apply(self, _pc: PETSc.PC, x: PETSc.Vec, y: PETSc.Vec) -> None:
        self.pc.apply(x, y)


def _kept_factor_gmres(comm, pc: PETSc.PC, rtol: float, max_it: int) -> PETSc.KSP:
    """Flexible GMRES (no options prefix: the scene's PETSc options do not reach it)
    preconditioned on the right by `pc`'s current factors, so that it measures the true
    residual. Flexible: it builds the solution from the preconditioned vectors it keeps, where
    GMRES applies the factors once more at the end (a pair of triangular solves per predictor;
    the same iterates in exact arithmetic)."""
    ksp = PETSc.KSP().create(comm)
    flexible_gmres(ksp, rtol, 0.0, max_it)
    shell = ksp.getPC()
    shell.setType(PETSc.PC.Type.PYTHON)
    shell.setPythonContext(_Factors(pc))
    return ksp


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


def _finite(vector: PETSc.Vec) -> bool:
    """Every entry of a (parallel) PETSc vector finite, on every rank."""
    local = bool(np.all(np.isfinite(vector.getArray(readonly=True))))
    return vector.getComm().tompi4py().allreduce(local, op=MPI.LAND)
