"""One timing helper for the benchmarks: wall and CPU seconds and calls of a wrapped function.

PETSc's log events (`PETSc.Log.Event(name).getPerfInfo()`) count the solver's own operations
but time them in wall seconds only; on a shared machine the wall time includes the other
processes' turns, so the benchmarks print this process's CPU seconds next to it.
"""

import time
from dataclasses import dataclass


@dataclass
class Tally:
    """Totals over the calls of one wrapped function."""

    wall: float = 0.0
    cpu: float = 0.0
    calls: int = 0

    def per_call(self) -> tuple[float, float]:
        """(wall, CPU) seconds per call (0 without calls)."""
        n = max(self.calls, 1)
        return self.wall / n, self.cpu / n


def tally(owner, name: str) -> Tally:
    """Replace the attribute `name` of `owner` (a module, class or object) by a wrapper that
    adds each call's wall and CPU seconds to the returned Tally. Wrap a module's function
    before anything looks it up (DOLFINx's NonlinearProblem keeps the assemblers it finds)."""
    totals, function = Tally(), getattr(owner, name)

    def timed(*args, **kwargs):
        wall, cpu = time.perf_counter(), time.process_time()
        try:
            return function(*args, **kwargs)
        finally:
            totals.wall += time.perf_counter() - wall
            totals.cpu += time.process_time() - cpu
            totals.calls += 1

    setattr(owner, name, timed)
    return totals
