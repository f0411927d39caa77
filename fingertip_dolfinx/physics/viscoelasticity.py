"""Quasi-linear viscoelasticity (Prony series) on the second Piola–Kirchhoff stress.

    S(t) = g∞ S_e(t) + Σ_i g_i h_i(t),   h_i(t) = ∫_0^t exp(−(t − s)/τ_i) dS_e(s),

which is the paper's σ0 + ∫ ġ σ0 with g(t) = g∞ + Σ g_i exp(−t/τ_i), applied to S (objective:
rigid rotations leave S and so the history untouched). Over a step with S_e linear in time,

    h_i^{n+1} = a_i h_i^n + b_i (S_e^{n+1} − S_e^n),   a_i = exp(−Δt/τ_i),
    b_i = (1 − a_i) τ_i / Δt,

is exact. The h_i and S_e^n live at the quadrature points of the stress integral (a
`basix.ufl.quadrature_element` space): forms using `stress()` must integrate with
`dx(metadata=qlv.metadata)` so the points coincide.
"""

from __future__ import annotations

import basix.ufl
import numpy as np
import ufl
from dolfinx import fem

from ..errors import InputError
from .materials import Prony


class QuasiLinearViscoelasticity:
    """History of S at quadrature points for one elastic stress expression.

    S_e: UFL elastic PK2 stress of the *current* state (e.g. second_piola_kirchhoff(SKIN, F)).
    dt: the time step as a `fem.Constant` owned by the solver; forms read it, so changing the
    step never recompiles. cells: the cells whose history is updated (e.g. the skin); the
    stress is meaningful only where it is integrated.

    Only `advance()` changes the history, after a step has converged: a rejected (cut) step
    needs no restore, just re-solve with a smaller dt. name: the prefix of the internal
    variables' names ({name}_h{i}, {name}_S_e_n: their checkpoint names, one per region).
    """

    def __init__(self, S_e, prony: Prony, mesh, quadrature_degree: int, dt,
                 cells: np.ndarray | None = None, name: str = "qlv"):
        if not isinstance(prony, Prony):
            raise InputError("viscoelasticity", f"expected a Prony series, got {prony!r}.")
        if int(quadrature_degree) < 0:
            raise InputError("viscoelasticity", f"quadrature degree {quadrature_degree} < 0.")
        self.prony = prony
        self.mesh = mesh
        self.degree = int(quadrature_degree)
        self.dt = dt if isinstance(dt, fem.Constant) else fem.Constant(mesh, float(dt))
        self.metadata = {"quadrature_degree": self.degree}

        shape = S_e.ufl_shape
        element = basix.ufl.quadrature_element(mesh.basix_cell(), value_shape=shape,
                                               degree=self.degree)
        self.space = fem.functionspace(mesh, element)
        self.h = [fem.Function(self.space, name=f"{name}_h{i}") for i in range(len(prony.g))]
        self.S_e_n = fem.Function(self.space, name=f"{name}_S_e_n")

        self.S_e = S_e
        self.h_new = []
        for h, tau in zip(self.h, prony.tau):
            a = ufl.exp(-self.dt / tau)
            b = (1.0 - a) * tau / self.dt
            self.h_new.append(a * h + b * (S_e - self.S_e_n))
        self._stress = prony.g_inf * S_e + sum(g * hn for g, hn in zip(prony.g, self.h_new))

        # One compiled expression for the whole update: [h_1^{n+1}, ..., h_m^{n+1}, S_e^{n+1}].
        stacked = ufl.as_tensor([*self.h_new, S_e])
        points = self.space.element.interpolation_points
        self._update = fem.Expression(stacked, points)

        tdim = mesh.topology.dim
        if cells is None:  # owned and ghost cells: ghosts stay consistent without a scatter
            imap = mesh.topology.index_map(tdim)
            cells = np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32)
        self.cells = np.asarray(cells, dtype=np.int32)
        bs = self.space.dofmap.bs
        dofs = self.space.dofmap.list[self.cells]  # (cells, points): quadrature points in order
        self._index = (dofs[..., None] * bs + np.arange(bs)).reshape(len(self.cells), -1)

    def stress(self) -> ufl.core.expr.Expr:
        """Total PK2 stress at t_{n+1} as UFL (depends on the unknowns through S_e)."""
        return self._stress

    def advance(self) -> None:
        """Store h_i^{n+1} and S_e^{n+1} after a converged step (evaluates the compiled kernel)."""
        if len(self.cells) == 0:
            return
        values = self._update.eval(self.mesh, self.cells)
        n = len(self.h)
        values = values.reshape(len(self.cells), -1, n + 1, self.space.dofmap.bs)
        for k, f in enumerate([*self.h, self.S_e_n]):
            f.x.array[self._index] = values[:, :, k, :].reshape(len(self.cells), -1)

    def arrays(self) -> dict[str, np.ndarray]:
        """The live arrays of the internal variables, by checkpoint name ({name}_h{i},
        {name}_S_e_n)."""
        return {f.name: f.x.array for f in (*self.h, self.S_e_n)}

    def reset(self) -> None:
        """Forget the history (undeformed, stress-free start)."""
        for f in [*self.h, self.S_e_n]:
            f.x.array[:] = 0.0
