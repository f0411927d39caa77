"""A tolerance asked of the outputs: the time error's share, controlled and verified.

Local error control bounds each step's error; the error of an output at the end is the sum of
what every step left, propagated, so it can be many times the tolerance (the confined ramp
and hold at rtol 1e-4 ended 6.5e-3 off in the core pressure, where the default atol, 1e-6
MPa, was 0.5 % of the pressure). So a tolerance asked of the outputs sets the local
tolerances (`tolerance_steps`) and is then checked against a run whose tolerances, rtol and
atol alike, are tighter (`verify_time`): the global error of the tighter run is estimated
from the difference, Richardson-style with the exponent of tolerance proportionality.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

from ..errors import ConvergenceError
from .options import StepOptions

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
