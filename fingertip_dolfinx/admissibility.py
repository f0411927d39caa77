r"""Is a converged state physical? The checks the time stepper makes before accepting a step.

Newton can converge to a state no tissue can reach; the step is then cut and retried:

- inverted elements: J = det F ≤ 0 (or not finite) at a quadrature point;
- compaction: in the porous subcutaneous tissue, J ≤ φ0 + margin, φ0 the solid volume
  fraction: at J = φ0 every pore is closed and the permeability (Holmes–Mow: ∝ (J − φ0)^κ)
  and the mixture are undefined. The margin (0.02 by default) keeps the state away from it.

J is evaluated at the quadrature points of the volume integrals, the points where the
residual sees it. The location reported is the centre of the cell holding the smallest J, on
every rank.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI


def from_holder(comm: MPI.Comm, holds: bool, value):
    """`value()` evaluated on the lowest rank where `holds` (e.g. it owns the extreme of a
    reduction) and broadcast to every rank."""
    owner = comm.allreduce(comm.rank if holds else comm.size, op=MPI.MIN)
    return comm.bcast(value() if comm.rank == owner else None, root=owner)


@dataclass(frozen=True)
class Compaction:
    """The porous region to guard: its cells, its solid volume fraction φ0, the margin."""

    cells: np.ndarray
    phi0: float
    margin: float


class Admissibility:
    """The checks of a converged state of the deformation gradient `F` on `msh`."""

    def __init__(self, F, msh: dmesh.Mesh, quadrature_degree: int,
                 compaction: Compaction | None = None):
        self.mesh = msh
        self.compaction = compaction
        self._J = fem.Expression(ufl.det(F), quadrature_points(msh, quadrature_degree))
        imap = msh.topology.index_map(msh.topology.dim)
        self._owned_cells = np.arange(imap.size_local, dtype=np.int32)

    def min_jacobian(self, cells: np.ndarray | None = None) -> tuple[float, np.ndarray]:
        """Smallest J at the quadrature points of `cells` (owned cells by default), and where."""
        cells = self._owned_cells if cells is None else cells
        cells = cells[cells < len(self._owned_cells)]
        comm = self.mesh.comm
        if len(cells):
            values = self._J.eval(self.mesh, cells).reshape(len(cells), -1)
            i = np.unravel_index(np.argmin(values), values.shape)
            local = (float(values[i]), cells[i[0]])
        else:
            local = (np.inf, -1)
        J_min = comm.allreduce(local[0], op=MPI.MIN)
        geometry = self.mesh.geometry
        return J_min, from_holder(
            comm, local[0] == J_min,
            lambda: geometry.x[geometry.dofmaps[0][local[1]], :2].mean(axis=0))

    def violation(self) -> str | None:
        """Why the current state cannot be accepted, or None."""
        J_min, where = self.min_jacobian()
        if not np.isfinite(J_min) or J_min <= 0:
            return (f"inverted elements (J = {J_min:.3g}) near x = ({where[0]:.3f}, "
                    f"{where[1]:.3f}) mm")
        c = self.compaction
        if c is not None:
            J_sub, where = self.min_jacobian(c.cells)
            if J_sub <= c.phi0 + c.margin:
                return (
                    f"compaction: the subcutaneous tissue reached J = {J_sub:.3g} (solid fraction "
                    f"phi0 = {c.phi0:g}) near x = ({where[0]:.3f}, {where[1]:.3f}) mm"
                )
        return None


def quadrature_points(msh: dmesh.Mesh, degree: int) -> np.ndarray:
    """The reference points of the degree-`degree` quadrature rule on the mesh's cell."""
    import basix

    cell = basix.CellType[msh.topology.cell_name()]
    points, _ = basix.make_quadrature(cell, degree)
    return points
