"""Force control: the indenters' normal force held at a target, their depth found per step.

A finger exploring a surface holds its normal force, not its depth: slid at a constant depth
over the curved pulp, the bar of the `slide` scene presses harder as it goes (its force grew
by 29 % over 2 mm) and never slides steadily. `[protocol] normal_force = {times, values}` (a
`NormalForce`) makes the indenters' y-force Fn (history.csv's `force_N_per_mm`, per unit
length in plane strain; pressure and friction together: what the holder feels) follow the
piecewise-linear target F*(t) from `times[0]` on; before it the protocol's depth d(t) presses.
The indenters' depth is then an unknown of each step (`DepthControl`), its value the one
history.csv's `indenter_displacement_mm` reports.

The method: an outer iteration on the depth, each evaluation a full Newton solve of the step
at that depth (the stepper's own, unchanged), started from the last solve's state moved to
the new depth along its tangent (`stepping.stepper.TangentPredictor.predict_along`: from the
state itself, with the indenter moved by more than the contact's penetration, Newton started
with the contact lost and failed).

- Why not a global unknown: the constraint Fn(u, d) = F* as an extra scalar unknown with d
  needs a one-dof ("real") space in the Newton system. DOLFINx 0.11 has none (scifem adds
  one); a bordered system would be assembled and factorised by hand around SNES, with the
  contact's and the friction's Jacobians, and the error control, tangent predictor and
  Jacobian reuse taught about it. The outer iteration leaves all of them as they are, and a
  solve from a nearby depth costs few Newton iterations.
- The first depth is predicted (`predict`): from the last two accepted depths extrapolated
  linearly in time (in steady sliding under a constant force the depth drifts slowly and
  smoothly; on a force ramp it follows the ramp), except after a kink of the target, where
  the last accepted depth is corrected by (F* − Fn)/k, k = dFn/dd the last measured
  stiffness (or, with none yet, the protocol's own depth d(t) is the guess).
- Then, at a fixed time Fn grows with d (a deeper indenter presses harder): before F* is
  bracketed, a step (F* − Fn)/k by the stiffness k (the secant through the last two samples
  in contact, the last step's, or k ≈ 1.5 Fn/d for a first sample: Fn ∝ d^1.5, a Hertz-like
  estimate that only sizes the first correction), at most halving or doubling the depth;
  once a sample lies on each side of F*, false position between the innermost two with the
  Illinois modification (Dowell & Jarratt, BIT 11, 1971: an end kept twice in a row has its
  residual halved), which stays inside the bracket, cannot stall at one end on a convex or
  kinked Fn(d) (the contact reaching a stiffer layer), and converges superlinearly (order
  ~1.44) where Fn(d) is smooth.

Tolerance: the step is accepted when |Fn − F*| <= rtol·F* (`NormalForce.rtol`, default 1e-3).
Each Fn is exact to Newton's residual tolerance (snes_atol, 1e-10 N/mm by default), far below
any rtol·F* of interest. A step that has not reached the tolerance after `MAX_SOLVES` solves
fails with a message saying how far it got; the stepper cuts it and, after `max_cuts` cuts,
stops the run with that message (a tolerance asked is a tolerance delivered, or a stop).

In 3D (N, not N/mm) the target is the whole finger's normal force: a half model (section
`half = true`, the mid-sagittal plane x = 0 on rollers) carries half of it, so its solved
force is doubled (`DepthControl`'s `mirror`, the problem's `mirror_factor`) before it is
compared with the target. history.csv keeps every force on one footing, the model's own:
its `normal_force_target_N` (3D; `normal_force_target_N_per_mm` in 2D) is the target divided
by the mirror factor, the value its `force_N` is held to (`problem.target_key`). The depth
moves every indenter along y, in 2D and 3D alike.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .errors import FingertipError, InputError
from .validation import check_keys

#: Newton solves per step before a step that misses the force tolerance fails (and is cut).
MAX_SOLVES = 8


@dataclass(frozen=True)
class NormalForce:
    """The target normal force F*(t) (N/mm in plane strain; N in 3D, the whole finger's) through
    (times[i], values[i]),
    constant after the last point, held from `times[0]` on to the tolerance `rtol` (relative).

    Every value is > 0 (a force of 0 or less has no depth: the indenter would leave the skin),
    except a first value at t = 0, the untouched start of a press under force control.
    """

    times: tuple[float, ...]  # s, increasing, >= 0
    values: tuple[float, ...]  # N/mm (2D), N (3D, whole finger): the indenters' total y-force
    rtol: float = 1e-3  # |Fn − F*| <= rtol F* at every step from times[0] on

    def __post_init__(self):
        where = "protocol.normal_force"
        object.__setattr__(self, "times", tuple(float(x) for x in self.times))
        object.__setattr__(self, "values", tuple(float(x) for x in self.values))
        t = np.asarray(self.times)
        if len(self.times) != len(self.values) or len(self.times) < 1:
            raise InputError(where, f"{len(self.times)} times for {len(self.values)} values.",
                             "give one force (N/mm in 2D, N in 3D) per time (s).")
        if t[0] < 0 or np.any(np.diff(t) <= 0) or not np.all(np.isfinite(t)):
            raise InputError(f"{where}.times", f"times must be >= 0 and increase strictly, got "
                             f"{self.times}.", "list the times in order, from 0 or later.")
        later = self.values[1:] if self.times[0] == 0 else self.values
        if not all(math.isfinite(v) and v > 0 for v in later) or not self.values[0] >= 0:
            raise InputError(f"{where}.values", f"got {self.values}: a normal force <= 0 "
                             "has no depth (the indenters would leave the skin).",
                             "give forces > 0 (N/mm in 2D, N in 3D: the indenters' push on the "
                             "finger); only a first value at t = 0 may be 0.")
        if not (isinstance(self.rtol, int | float) and 0 < self.rtol < 1):
            raise InputError(f"{where}.rtol", f"got {self.rtol!r}.",
                             "give a relative tolerance in (0, 1), e.g. 1e-3.")

    @property
    def start(self) -> float:
        """When force control takes over from the protocol's depth (s)."""
        return self.times[0]

    def __call__(self, t: float) -> float:
        return float(np.interp(t, self.times, self.values))

    def active(self, t: float) -> bool:
        """Whether a step ending at t is force controlled (it ends after `start`)."""
        return t > self.start + 1e-12 * max(1.0, self.start)


def normal_force_from_dict(data, where: str = "protocol.normal_force") -> NormalForce:
    """`[protocol] normal_force = {times, values, rtol}` as a `NormalForce`."""
    if not isinstance(data, dict):
        raise InputError(where, f"got {data!r}.", "give a table {times = [...], values = "
                         "[...]} of the target force (N/mm in 2D, N in 3D) at those times (s).")
    check_keys(where, data, ["times", "values", "rtol"], ["times", "values"])
    for key in ("times", "values"):
        value = data[key]
        if not isinstance(value, list | tuple) or not all(
                isinstance(x, int | float) and not isinstance(x, bool) for x in value):
            raise InputError(f"{where}.{key}", f"must be a list of numbers, got {value!r}.")
    return NormalForce(tuple(data["times"]), tuple(data["values"]), data.get("rtol", 1e-3))


#: The entries of `DepthControl.state` (a live array: the checkpoint saves and restores it).
T_PREV, D_PREV, T_LAST, D_LAST, F_LAST, STIFFNESS, IN_WINDOW = range(7)


class DepthControl:
    """The depth of a force-controlled run, step by step (module docstring): the accepted
    depths (`state`, a live array the checkpoint keeps), the trial depth of the step being
    solved with its samples (d, Fn), and the next depth to try.

    The stepper calls `begin(t_new)` before it moves the loads to t_new, then after each
    converged solve `record(Fn)`, which says whether Fn is within the tolerance and otherwise
    sets the next trial depth. `advance()` (a history of the problem's, the first to advance)
    takes the accepted step's depth and force.

    Parameters
    ----------
    target : NormalForce
        The target force and its tolerance.
    depth : callable
        The protocol's depth d(t) (mm): the depth before `target.start`, the first guess after.
    measure : callable
        Fn (N/mm) of the problem's current state.
    clock : callable
        The problem's time (s).
    mirror : int
        The whole finger's force over the model's (2 for a half model): `measure` and the
        forces passed to `record` are the model's, the target and `samples` the whole's.
    unit : str
        The forces' unit in messages ("N/mm" in plane strain, "N" in 3D).
    """

    #: Newton solves per step before the step counts as failed (the stepper reads it).
    max_solves = MAX_SOLVES

    def __init__(self, target: NormalForce, depth: Callable[[float], float],
                 measure: Callable[[], float], clock: Callable[[], float], mirror: int = 1,
                 unit: str = "N/mm"):
        self.target, self._depth, self._clock = target, depth, clock
        self._measure = lambda: mirror * measure()
        self.mirror, self.unit = mirror, unit
        self.state = np.array([math.nan, math.nan, 0.0, float(depth(0.0)), 0.0, math.nan, 0.0])
        self.t_trial, self.d_trial = math.nan, math.nan
        self.samples: list[tuple[float, float]] = []

    def active(self, t: float) -> bool:
        return self.target.active(t)

    def depth_at(self, t: float) -> float:
        """The depth (mm) at t: the protocol's before force control; after it, linear over the
        step from the last accepted depth to the trial (so the loads at the accepted time are
        the accepted ones, and the tangent predictor's sliver of the step moves the depth too)."""
        if not self.active(t):
            return float(self._depth(t))
        t0, d0 = self.state[T_LAST], self.state[D_LAST]
        if not (t > t0 and self.t_trial > t0):
            return float(d0)
        return float(d0 + min((t - t0) / (self.t_trial - t0), 1.0) * (self.d_trial - d0))

    def begin(self, t_new: float) -> None:
        """A force-controlled attempt to t_new: its first depth is the prediction."""
        self.t_trial, self.samples = t_new, []
        self.d_trial = self.predict(t_new)

    def predict(self, t_new: float) -> float:
        """The first depth of the step to t_new (module docstring)."""
        s = self.state
        kink = any(abs(s[T_LAST] - b) <= 1e-12 * max(1.0, b) for b in self.target.times)
        if s[IN_WINDOW] >= 1 and not kink and s[T_LAST] > s[T_PREV]:
            rate = (s[D_LAST] - s[D_PREV]) / (s[T_LAST] - s[T_PREV])
            return float(s[D_LAST] + rate * (t_new - s[T_LAST]))
        if s[STIFFNESS] > 0 and s[F_LAST] > 0:
            return float(s[D_LAST] + (self.target(t_new) - s[F_LAST]) / s[STIFFNESS])
        return max(float(self._depth(t_new)), float(s[D_LAST]))

    @property
    def reached(self) -> bool:
        """Whether the last solve's force is within the tolerance of the trial's target."""
        if not self.samples:
            return False
        target = self.target(self.t_trial)
        return abs(self.samples[-1][1] - target) <= self.target.rtol * target

    def record(self, force: float) -> bool:
        """Take the solved trial's Fn (the model's: a half model's is doubled): True if within
        the tolerance; else set the next trial depth and return False."""
        self.samples.append((self.d_trial, self.mirror * float(force)))
        if self.reached:
            return True
        self.d_trial = self._next(self.target(self.t_trial))
        return False

    def _next(self, target: float) -> float:
        """The next depth: Illinois false position once the root is bracketed, else a step by
        the stiffness, at most halving or doubling the depth."""
        below = [(d, f - target) for d, f in self.samples if f < target]
        above = [(d, f - target) for d, f in self.samples if f > target]
        self._learn_stiffness()
        if below and above:
            (lo, r_lo), (hi, r_hi) = max(below), min(above)
            # Illinois: an end kept m times in a row has its residual halved m − 1 times, so
            # that a convex or kinked Fn cannot stall false position at one end
            sides = [f < target for _, f in self.samples]
            kept = next((i for i, s in enumerate(reversed(sides)) if s != sides[-1]), len(sides))
            if sides[-1]:
                r_hi *= 0.5 ** (kept - 1)
            else:
                r_lo *= 0.5 ** (kept - 1)
            return float(lo - r_lo * (hi - lo) / (r_hi - r_lo))
        d, f = self.samples[-1]
        k = self.state[STIFFNESS]
        if not k > 0 and f > 0 and d > 0:
            k = 1.5 * f / d  # Fn ∝ d^1.5: sizes the first correction only
        guess = d + (target - f) / k if k > 0 and f > 0 else 2 * d  # no force at all: deeper
        return float(min(max(guess, 0.5 * d), 2 * d) if d > 0 else max(guess, 0.01))

    def _learn_stiffness(self) -> None:
        """dFn/dd at this time from the last two samples in contact (for the next step's
        prediction after a kink of the target, and for steps before a bracket)."""
        if len(self.samples) >= 2:
            (d0, f0), (d, f) = self.samples[-2:]
            if d != d0 and f0 > 0 and f > 0 and (f - f0) / (d - d0) > 0:
                self.state[STIFFNESS] = (f - f0) / (d - d0)

    def shortfall(self) -> str:
        """Why the step's force missed the tolerance (the stepper's failure message)."""
        target, u = self.target(self.t_trial), self.unit
        d, f = self.samples[-1]
        whole = " (the whole finger's)" if self.mirror != 1 else ""
        return (f"the normal force{whole} was {f:.6g} {u} at depth {d:.6g} mm after "
                f"{len(self.samples)} solves, {abs(f - target) / target:.2g} from the target "
                f"{target:.6g} {u}, over "
                f"the tolerance protocol.normal_force.rtol = {self.target.rtol:g} (loosen it, or "
                "tighten Newton's snes_atol and snes_rtol if the force is noisy at that level)")

    @property
    def tried(self) -> float:
        """The depth (mm) of the step's last solve (its trial depth before any solve)."""
        return self.samples[-1][0] if self.samples else float(self.d_trial)

    def advance(self) -> None:
        """The accepted step, at the problem's time: its depth and Fn become the last accepted
        (before the other histories advance: the friction's force depends on the slip since
        the last accepted state)."""
        t, s = self._clock(), self.state
        active = self.active(t)
        if active and not (abs(t - self.t_trial) <= 1e-12 * max(1.0, t) and self.samples):
            raise FingertipError(f"force control: the step to t = {t:g} s was not solved for "
                                 "its depth; a force-controlled problem needs the TimeStepper's "
                                 "step loop (stepping.TimeStepper.run).")
        d = self.d_trial if active else float(self._depth(t))
        f = self.samples[-1][1] if active else float(self._measure())
        if not active and d != s[D_LAST] and (f - s[F_LAST]) / (d - s[D_LAST]) > 0:
            s[STIFFNESS] = (f - s[F_LAST]) / (d - s[D_LAST])  # the press's dFn/dd
        s[T_PREV], s[D_PREV] = s[T_LAST], s[D_LAST]
        s[T_LAST], s[D_LAST], s[F_LAST] = t, d, f
        s[IN_WINDOW] = s[IN_WINDOW] + 1 if active else 0

    def arrays(self) -> dict[str, np.ndarray]:
        """The live state by checkpoint name (a resumed run predicts from it)."""
        return {"force_control": self.state}
