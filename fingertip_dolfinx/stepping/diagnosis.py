"""Why a step failed, said so that a user can act on it: the messages of a stopped run.

A failed attempt (Newton diverged, a NaN, an inverted element) is cut and retried; after
`max_cuts` cuts in a row the run stops with a `ConvergenceError` that says when (with the
digits that tell t and t + Δt apart: `distinct`), under which load, why (the SNES converged
reason by name, `SNES_REASONS`; where the residual is largest) and what to change.

Compaction of a porous tissue (J within the margin of its solid fraction φ0) is a physical
limit, not a numerical one: the run stops at once with a `CompactionError`, which says how J
approached the limit over the step (`approach`). A Newton iterate that closed the pores while
the accepted states were not heading there (`crosses`: their lowest J, extrapolated linearly,
does not reach the limit within the step) is Newton's overshoot, not compaction: the step is
cut, and the final message says so (`overshoot_note`).
"""

from __future__ import annotations

import math

from petsc4py import PETSc

from ..errors import CompactionError, ConvergenceError

#: SNES converged reason (an int; negative: diverged) -> its PETSc name.
SNES_REASONS = {
    getattr(PETSc.SNES.ConvergedReason, name): name
    for name in dir(PETSc.SNES.ConvergedReason)
    if not name.startswith("_") and isinstance(getattr(PETSc.SNES.ConvergedReason, name), int)
}


def distinct(a: float, b: float, digits: int = 6) -> tuple[str, str]:
    """a and b printed with enough significant digits (at least `digits`) to tell them apart:
    t = 36.4231 s and t + 1e-5 s print as 36.4231 and 36.42311."""
    scale, gap = max(abs(a), abs(b)), abs(b - a)
    if gap > 0 and scale > 0:
        digits = max(digits, min(17, math.ceil(math.log10(scale / gap)) + 2))
    return f"{a:.{digits}g}", f"{b:.{digits}g}"


def crosses(t0: float, J0: float, t1: float, J1: float, t_reach: float, limit: float) -> bool:
    """Whether J, falling from J0 at t0 to J1 at t1 and extrapolated linearly, reaches `limit`
    by `t_reach`. A J that does not fall (an undrained tissue stays at J = 1) never does."""
    if not (t1 > t0 and J1 < J0):
        return False
    return J1 + (J1 - J0) / (t1 - t0) * (t_reach - t1) <= limit


def compacted(problem, margin: float | None = None, nodes: bool = True):
    """The problem's compaction finding (admissibility.Compacted: the lowest J if within
    `margin` of the solid fraction) if it has the check (`compacted`), else None."""
    check = getattr(problem, "compacted", None)
    return None if check is None else check(margin, nodes)


def approach(problem, found, t: float, t_new: float, nodes: bool) -> str:
    """How J approached the limit over the failed step to t_new, where it was `found`: the
    lowest J of the last accepted state (the problem's current one, at the same kind of points)
    and, by linear interpolation, when it crossed the limit."""
    accepted = compacted(problem, math.inf, nodes)  # the lowest J, wherever it is
    if accepted is None:
        return ""
    J0, J1, limit = accepted.J, found.J, found.limit
    text = f"the lowest J was {J0:.4g} at t = {distinct(t, t_new)[0]} s"
    if J0 > limit > J1:
        crossing = t + (t_new - t) * (J0 - limit) / (J0 - J1)
        text += f" and crossed {limit:g} near t = {distinct(crossing, t_new)[0]} s"
    return text


def overshoot_note(closed_iterates: int) -> str:
    """What the failure message adds when Newton's iterates closed pores that the accepted
    states were not heading for."""
    if not closed_iterates:
        return ""
    return (f"; in {closed_iterates} attempt(s) a Newton iterate closed the pores (J <= phi0) "
            "although the accepted states were not heading there: an overshoot of Newton's, "
            "not compaction (smaller or more gradual steps help)")


def dynamic_friction_note(problem) -> str:
    """What the failure message adds for a problem with inertia and friction: a velocity jump
    of an indenter's tangential path (the `slide` scene's onset) gives the nodes that stick in
    the first step after it the velocity of Newmark's update, (γ/β) Δu/Δt, up to twice the
    indenter's whatever Δt (measured: 140 mm/s under a bar at 80 mm/s), so the next step
    starts with the skin overtaking the indenter; with the penalty at γ0 = 100 Newton did not
    converge down to Δt = 20 µs, at γ0 = 10 it did, and at γ0 = 100 with ρ∞ = 0 (which takes
    the highest modes' velocity out in one step; docs/benchmarks/friction.md)."""
    if getattr(problem, "inertia", None) is None or getattr(problem, "friction", None) is None:
        return ""
    return (" With friction and inertia, a jump of an indenter's tangential velocity (a kink "
            "of the path) sends the skin that sticks in the step after it at up to twice the "
            "indenter's speed: use model.contact_gamma0 = 10 (the default; γ0 = 100 failed "
            "there), steps.rho_inf = 0 (damps that overshoot within a step), or a tangential "
            "path whose speed rises over several steps.")


def newton_failure(reason: int, where: tuple[float, ...] | None = None) -> str:
    """Why an attempt failed: SNES's converged reason by name, and `where` (mm) the residual
    is largest if known."""
    why = f"Newton did not converge ({SNES_REASONS.get(reason, reason)})"
    if where is not None:
        why += f"; the residual is largest near x = ({where[0]:.3f}, {where[1]:.3f}) mm"
    return why


def compaction_error(problem, found, t: float, t_new: float, iterate: bool) -> CompactionError:
    """The stop on compaction `found` in the step from t to t_new (at a Newton `iterate` or at
    a converged state); the problem holds the last accepted state, at t."""
    a, b = distinct(t, t_new)
    before = approach(problem, found, t, t_new, nodes=not iterate)
    return CompactionError(
        found.message(f"at t = {b} s (the step from t = {a} s, Δt = {t_new - t:.3g} s)",
                      iterate=iterate, before=before)
        + f" Results up to t = {a} s are saved.")


def cuts_error(t: float, t_new: float, loads: tuple[float, float], cuts: int, why: str,
               closed_iterates: int, note: str = "", found: bool = False) -> ConvergenceError:
    """The stop after `cuts` failed attempts in a row from t, the last to t_new; `loads` the
    load at t and at t_new, or (`found`, under force control) the depth accepted at t and the
    last one tried for t_new; `note` is added to the fix (`dynamic_friction_note`)."""
    a, b = distinct(t, t_new)
    load_a, load_b = distinct(*loads)
    loads = f"depth {load_a} -> {load_b} mm, as found by force control" if found else \
        f"load {load_a} -> {load_b}"
    return ConvergenceError(
        f"the step from t = {a} s to t = {b} s ({loads}) "
        f"failed {'once' if cuts == 1 else f'{cuts} times'}, the last with Δt = "
        f"{t_new - t:.3g} s: {why}"
        f"{overshoot_note(closed_iterates)}. "
        f"Results up to t = {a} s are saved. Fix: lower the load or its rate, "
        f"refine the mesh where it fails, or allow smaller steps (dt_min, max_cuts).{note}")


def error_stall_error(t: float, t_new: float, err: float, dt_min: float) -> ConvergenceError:
    """The stop of error control when the step from t, last tried to t_new, errs `err` × the
    tolerance and a smaller one would be below `dt_min`."""
    return ConvergenceError(
        f"the step from t = {t:.6g} s keeps a time-integration error "
        f"{err:.3g} times the tolerance at Δt = {t_new - t:.3g} s, and "
        f"a smaller step would be below dt_min = {dt_min:g} s. "
        f"Results up to t = {t:.6g} s are saved. Fix: loosen steps.rtol "
        "and steps.atol, or lower steps.dt_min; an error that does not "
        "shrink with the step is Newton's own: tighten the solver's "
        "snes_atol and snes_rtol.")
