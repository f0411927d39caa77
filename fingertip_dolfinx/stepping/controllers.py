"""Step-size policies: how long the next step is, after an accepted, a rejected or a failed one.

Each policy is a small object over floats (no PETSc, no DOLFINx), in the spirit of FESTIM's
`Stepsize`: `next_dt(outcome)` after an accepted step, `cut(taken)` after a failed attempt
(divergence, NaN, inverted elements), and for error control `reject(...)` after an attempt
whose error estimate is over the tolerance. The stepper (stepper.py) applies them; what they
decide is what the module docstring there describes.

- `IterationControl` ("iterations", the default): the step grows ×`growth` while Newton
  converges easily (≤ `easy_iterations`), whatever the error, up to `dt_max`.
- `ErrorControl` ("error"): the next step is Δt·min(growth, max(ERROR_CUT_MIN,
  safety·err^(−1/(k+1)))) for an error estimate err (over the tolerance) of a step of order k;
  under BDF2 the ratio of two steps stays below `growth` < 1 + √2 (zero stability).
- `PeriodLimit`: a dynamic step resolves the load's period, Δt ≤ period/`steps_per_period`
  from the load's `onset` on.

And the closed forms the error estimate and the multistep rate use: `bdf2_weights` (variable-step
BDF2), `milne_factor` (the local error from corrector minus predictor), `lagrange` (the
polynomial predictor through the last accepted states).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .options import SECOND_ORDER_RATE, StepOptions

#: The smallest factor by which error control shrinks a step it rejects or follows.
ERROR_CUT_MIN = 0.2
#: (a₀, a₁, a₂) of backward Euler: Δt ẋ_{n+1} ≈ x_{n+1} − x_n.
BACKWARD_EULER = (1.0, -1.0, 0.0)


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


def lagrange(points: list, t_new: float) -> list[np.ndarray]:
    """The polynomial through the accepted states `points` (time, arrays), at t_new."""
    times = [tp for tp, _ in points]
    weights = [math.prod((t_new - tm) / (tj - tm) for m, tm in enumerate(times) if m != j)
               for j, tj in enumerate(times)]
    return [sum(w * arrays[i] for w, (_, arrays) in zip(weights, points))
            for i in range(len(points[0][1]))]


def error_factor(err: float, order: int, safety: float, largest: float) -> float:
    """The step-size factor safety·err^(−1/(k+1)), between ERROR_CUT_MIN and `largest`: the
    step whose error, ∝ Δt^(k+1), would be `safety` × the tolerance."""
    if err <= 0:
        return largest
    return min(largest, max(ERROR_CUT_MIN, safety * err ** (-1.0 / (order + 1))))


@dataclass(frozen=True)
class Outcome:
    """An accepted step as a step-size policy sees it."""

    taken: float  # s: its length
    planned: float  # s: the step the policy asked for (longer if a breakpoint cut it short)
    iterations: int  # Newton iterations of the accepted attempt
    cuts: int  # failed attempts before it
    error: float = math.nan  # error control: its error estimate over the tolerance
    order: int = 1  # error control: the order of that estimate
    doubled: bool = False  # error control: checked by step doubling (two halves of `taken`)
    held: bool = False  # the load was held over the step (StepOptions.hold_growth)


class IterationControl:
    """Steps by Newton's effort: ×`growth` after an easy step (at most `easy_iterations` Newton
    iterations and no cut; ×`hold_growth` if one is given and the load was held over the step),
    the same after a hard one, ×`cut` after a failed attempt."""

    estimates_error = False

    def __init__(self, options: StepOptions):
        self.options = options

    def next_dt(self, outcome: Outcome) -> float:
        opts = self.options
        if outcome.cuts == 0 and outcome.iterations <= opts.easy_iterations:
            growth = opts.hold_growth if outcome.held and opts.hold_growth else opts.growth
            return min(max(outcome.planned, outcome.taken) * growth, opts.dt_max)
        return min(outcome.taken, opts.dt_max)  # a hard step: cuts have already shrunk it

    def cut(self, taken: float) -> float:
        """The step to retry after a failed attempt of length `taken`."""
        return taken * self.options.cut


class ErrorControl(IterationControl):
    """Steps by their estimated local error (`rtol`, `atol`): the step after an accepted one
    aims at `safety` × the tolerance, grows at most ×`growth` (and under BDF2 keeps the step
    ratio below it), and is no longer than the last after a cut; a rejected step is redone
    shorter; a failed attempt is cut as under `IterationControl`."""

    estimates_error = True

    def next_dt(self, outcome: Outcome) -> float:
        opts, taken, err = self.options, outcome.taken, outcome.error
        if outcome.doubled:  # two halves of `taken`: one step Δt errs ~2 err (Δt/taken)² as much
            last = 0.5 * taken
            dt = min(taken / math.sqrt(2.0) * error_factor(err, 1, opts.safety, math.inf),
                     opts.growth * last)
        else:
            last = taken
            dt = taken * error_factor(err, outcome.order, opts.safety, opts.growth)
            if outcome.planned > taken * (1 + 1e-9) and dt >= taken:  # cut short by a mark
                dt = max(dt, outcome.planned)
        if opts.scheme in SECOND_ORDER_RATE:
            dt = min(dt, opts.growth * last)  # BDF2's step ratio stays below 1 + √2
        if outcome.cuts > 0:
            dt = min(dt, taken)
        return min(dt, opts.dt_max)

    def reject(self, err: float, order: int, t: float, t_new: float, lands) -> float:
        """The step to redo from t after the attempt to t_new erred `err` × the tolerance;
        `lands(dt)` is where a step dt from t ends (on a mark if one is near): a retry that
        would land on t_new again (stretched back to a mark) is made 3/4 as long instead."""
        dt = (t_new - t) * error_factor(err, order, self.options.safety, 1.0)
        if lands(dt) >= t_new:
            dt = 0.75 * (t_new - t)
        return dt


def controller(options: StepOptions) -> IterationControl:
    """The step-size policy `options.control` names."""
    return ErrorControl(options) if options.control == "error" else IterationControl(options)


class PeriodLimit:
    """dt ↦ min(dt, period/steps_per_period) from the history's `onset` on (0 if it has
    none), if it has a `period` (loading.Vibration); else dt unchanged."""

    def __init__(self, history, steps_per_period: int):
        period = getattr(history, "period", None)
        self.onset = getattr(history, "onset", 0.0)
        self.largest = math.inf if period is None else period / steps_per_period

    def __call__(self, t: float, dt: float) -> float:
        if self.largest == math.inf:
            return dt
        return min(dt, self.largest) if t >= self.onset - 1e-12 * max(1.0, self.onset) else dt
