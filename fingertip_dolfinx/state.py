"""The state bookkeeping of a problem the time stepper drives (`solver.Steppable`).

A state is the unknowns (u, and p with a pore law), u at the last two accepted times (u_n, and
u_{n−1} for a multistep rate), the inertia's v_n, a_n and the QLV internal variables. The time
stepper accepts a converged step (the histories advance, then u_n and u_{n−1} shift), restores
the unknowns after a failed attempt, saves and restores the whole state around error control's
doubled step (`state_arrays`, `mark_accepted`), and asks whether a converged state is physical
(`admissibility`). The fingertip (`problem.FingertipProblem`) and the verification problems
(`studies.problems`) keep their state alike: they share this one implementation.
"""

from __future__ import annotations

import numpy as np


class SteppableState:
    """Accept, restore, the live state arrays and the admissibility questions of a problem.

    The problem sets `u`, `u_n`, `u_nm1`, `p` (None without a pore law), `unknowns` (u first),
    `inertia` (an `inertia.Inertia` or None) and `admissibility` (an
    `admissibility.Admissibility`), then calls `mark_accepted()`. It names the internal
    variables to advance (`histories`) and their arrays (`history_arrays`), and whether u_{n−1}
    belongs to the state (`keeps_u_nm1`: a rate that BDF2 reads).
    """

    #: Whether u_{n−1} is part of the state (the default: the problem has a rate).
    keeps_u_nm1 = True

    def histories(self) -> list:
        """The internal variables that advance when a step is accepted (QLV histories)."""
        return []

    def history_arrays(self) -> dict[str, np.ndarray]:
        """The internal variables' live arrays by their checkpoint names."""
        arrays = {}
        for history in self.histories():
            arrays |= history.arrays()
        return arrays

    def accept(self) -> None:
        """Take the converged state as the new history (internal variables, u_n, u_{n−1})."""
        for history in self.histories():
            history.advance()
        if self.inertia is not None:  # Newmark's update needs u_n of the step: first
            self.inertia.advance()
        self.u_nm1.x.array[:] = self.u_n.x.array
        self.u_n.x.array[:] = self.u.x.array
        self.mark_accepted()

    def mark_accepted(self) -> None:
        """Take the current unknowns as the last accepted state (after loading a checkpoint)."""
        self._last = [f.x.array.copy() for f in self.unknowns]

    def restore(self) -> None:
        """Return the unknowns to the last accepted state (after a failed attempt)."""
        for f, saved in zip(self.unknowns, self._last):
            f.x.array[:] = saved

    def state_arrays(self) -> dict[str, np.ndarray]:
        """The arrays that define the state, by their checkpoint names: u, u_n, p (if any),
        u_nm1 (if `keeps_u_nm1`), v_n and a_n (with inertia), qlv_h{i} and qlv_S_e_n (with a
        QLV history). They are the live arrays: writing into them sets the state (then
        scatter_forward the unknowns, mark_accepted)."""
        arrays = {"u": self.u.x.array, "u_n": self.u_n.x.array}
        if self.p is not None:
            arrays["p"] = self.p.x.array
        if self.keeps_u_nm1:
            arrays["u_nm1"] = self.u_nm1.x.array
        if self.inertia is not None:
            arrays |= self.inertia.arrays()
        return arrays | self.history_arrays()

    def min_jacobian(self, cells: np.ndarray | None = None) -> tuple[float, np.ndarray]:
        """Smallest J at the quadrature points and vertices of `cells` (owned cells by
        default), on every rank, and where (reference position, mm)."""
        return self.admissibility.min_jacobian(cells)

    def inadmissible(self) -> str | None:
        """Why the converged state cannot be accepted (inverted elements, compaction), or
        None."""
        return self.admissibility.violation()

    def compacted(self, margin: float | None = None, nodes: bool = True):
        """The porous tissue's lowest J if within `margin` (the guard's by default) of its
        solid fraction (admissibility.Compacted), else None: the solver stops on it."""
        return self.admissibility.compacted(margin, nodes)
