r"""Is a state physical? The checks the time stepper makes before accepting a step.

Newton can converge to a state no tissue can reach:

- inverted elements: J = det F ≤ 0 (or not finite): the step is cut and retried;
- compaction: in the porous subcutaneous tissue, J ≤ φ0 + margin, φ0 the solid volume
  fraction: at J = φ0 every pore is closed and the permeability (Holmes–Mow: ∝ (J − φ0)^κ)
  and the mixture are undefined. The margin (0.02 by default) is the band in which the
  approach to that limit is recognised. Compaction is physical: the fluid cannot leave fast
  enough for the load, and no smaller step changes that; the time stepper stops at once
  (`stepping`, `errors.CompactionError`).

J is evaluated at the quadrature points of the volume integrals (where the residual sees it)
and at the cells' vertices (the nodes, where a P2 displacement's J is usually most extreme:
the quadrature points can stay above φ0 while a node is below it). The location reported is
that point's reference position, on every rank.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from ..errors import InputError


def from_holder(comm: MPI.Comm, holds: bool, value):
    """`value()` evaluated on the lowest rank where `holds` (e.g. it owns the extreme of a
    reduction) and broadcast to every rank."""
    owner = comm.allreduce(comm.rank if holds else comm.size, op=MPI.MIN)
    return comm.bcast(value() if comm.rank == owner else None, root=owner)


@dataclass(frozen=True)
class Compaction:
    """The porous region to guard: its cells, its solid volume fraction φ0, the margin, and
    the permeability k0 at J = 1 (mm⁴/(N·s); None without flow), which the message names."""

    cells: np.ndarray
    phi0: float
    margin: float
    k0: float | None = None

    def __post_init__(self):
        if not (self.margin >= 0 and self.phi0 + self.margin < 1):
            raise InputError(
                "model.compaction_margin", f"{self.margin} with phi0 = {self.phi0}: the band "
                "above the solid fraction in which compaction is recognised must be >= 0 (below "
                "0 a state whose pores are closed at the nodes would be accepted) and leave "
                "phi0 + margin < 1.", "use a margin in [0, 1 - phi0), e.g. 0.02.")


@dataclass(frozen=True)
class Lowest:
    """The smallest J over some cells: its value, its reference position x (mm) and whether it
    is at a node (a cell vertex) or at a quadrature point."""

    J: float
    x: np.ndarray
    at_node: bool

    @property
    def place(self) -> str:
        return f"{'a node' if self.at_node else 'a quadrature point'} near x = {self.where}"

    @property
    def where(self) -> str:
        """The reference position in mm to the micrometre (no negative zero); (x, y) in
        plane strain, (x, y, z) in 3D."""
        parts = ", ".join(f"{round(float(v), 3) + 0.0:.3f}" for v in self.x)
        return f"({parts}) mm"


@dataclass(frozen=True)
class Compacted:
    """A state whose porous tissue reached J ≤ `limit` (φ0 + margin): the lowest J, the
    guard, the limit."""

    lowest: Lowest
    guard: Compaction
    limit: float

    @property
    def J(self) -> float:
        return self.lowest.J

    @property
    def x(self) -> np.ndarray:
        return self.lowest.x

    def _relation(self) -> str:
        """How J stands to φ0: below it, or within the margin above it."""
        g = self.guard
        if self.J <= g.phi0:
            return f"at or below its solid volume fraction phi0 = {g.phi0:g}"
        return (f"within the margin {self.limit - g.phi0:g} of its solid volume fraction "
                f"phi0 = {g.phi0:g}")

    def _pores(self) -> str:
        return ("the pores are closed there" if self.J <= self.guard.phi0
                else "the pores are all but closed there")

    def describe(self) -> str:
        """What happened, where: for a message that adds when."""
        return (f"the tissue's volume ratio J reached {self.J:.4g} at {self.lowest.place}, "
                f"{self._relation()}: {self._pores()}")

    def message(self, when: str, iterate: bool = False, before: str = "") -> str:
        """The whole story for the user: compaction `when` (e.g. "at t = 36.5 s"), where, how
        far, what it means and what helps. `iterate`: found in a Newton iterate whose
        residual was not finite (the pores closed on the way), not in a converged state;
        `before`: a parenthesis on the approach (e.g. the last accepted J)."""
        g, low = self.guard, self.lowest
        k0 = ("this permeability" if g.k0 is None
              else f"this permeability (k0 = {g.k0:g} mm^4/(N s))")
        node = "a node" if low.at_node else "a quadrature point"
        iterate = " in the last Newton iterate, whose residual was not finite" if iterate else ""
        before = f" ({before})" if before else ""
        return (
            f"compaction {when} near x = {low.where}: the tissue's "
            f"volume ratio J reached {low.J:.4g} at {node}{iterate}, "
            f"{self._relation()}{before}: {self._pores()} and no more fluid can leave. "
            f"This is a physical limit: the load is too fast or too large for {k0}. Lower the "
            "loading rate or the depth, or raise k0; smaller time steps cannot help.")


class Admissibility:
    """The checks of a state of the deformation gradient `F` on `msh`."""

    def __init__(self, F, msh: dmesh.Mesh, quadrature_degree: int,
                 compaction: Compaction | None = None):
        self.mesh = msh
        self.compaction_guard = compaction
        quadrature = quadrature_points(msh, quadrature_degree)
        points = np.vstack([quadrature, reference_vertices(msh)])
        self._first_node = len(quadrature)  # points[_first_node:] are the vertices
        self._J = fem.Expression(ufl.det(F), points)
        self._X = fem.Expression(ufl.SpatialCoordinate(msh), points)
        imap = msh.topology.index_map(msh.topology.dim)
        self._owned_cells = np.arange(imap.size_local, dtype=np.int32)

    def lowest(self, cells: np.ndarray | None = None, nodes: bool = True) -> Lowest:
        """The smallest J at the quadrature points and (if `nodes`) the vertices of `cells`
        (owned cells by default; NaN counts as lowest), on every rank."""
        cells = self._owned_cells if cells is None else cells
        cells = cells[cells < len(self._owned_cells)]
        comm = self.mesh.comm
        if len(cells):
            values = self._J.eval(self.mesh, cells).reshape(len(cells), -1)
            if not nodes:
                values = values[:, :self._first_node]
            values = np.where(np.isnan(values), -np.inf, values)
            cell, point = np.unravel_index(np.argmin(values), values.shape)
            local = float(values[cell, point])
        else:
            local = np.inf
        J_min = comm.allreduce(local, op=MPI.MIN)

        def where():
            X = self._X.eval(self.mesh, cells[cell:cell + 1]).reshape(-1, self.mesh.geometry.dim)
            return X[point], bool(point >= self._first_node)

        if J_min == np.inf:  # no cells on any rank
            return Lowest(J_min, np.full(self.mesh.geometry.dim, np.nan), False)
        x, at_node = from_holder(comm, local == J_min, where)
        return Lowest(float("nan") if J_min == -np.inf else J_min, np.asarray(x), at_node)

    def min_jacobian(self, cells: np.ndarray | None = None) -> tuple[float, np.ndarray]:
        """Smallest J at the quadrature points and vertices of `cells` (owned cells by
        default), and where (reference position, mm)."""
        low = self.lowest(cells)
        return low.J, low.x

    def compacted(self, margin: float | None = None, nodes: bool = True) -> Compacted | None:
        """The porous tissue's lowest J (at the quadrature points, and at the nodes if
        `nodes`) if it is at or below φ0 + margin (the guard's margin unless given) and above
        0 (J ≤ 0 is an inverted element), else None."""
        guard = self.compaction_guard
        if guard is None:
            return None
        low = self.lowest(guard.cells, nodes)
        limit = guard.phi0 + (guard.margin if margin is None else margin)
        return Compacted(low, guard, limit) if 0 < low.J <= limit else None

    def violation(self) -> str | None:
        """Why the current state cannot be accepted, or None."""
        low = self.lowest()
        if not low.J > 0:
            return f"inverted elements (J = {low.J:.3g}) at {low.place}"
        found = self.compacted()
        return None if found is None else f"compaction: {found.describe()}"


def quadrature_points(msh: dmesh.Mesh, degree: int) -> np.ndarray:
    """The reference points of the degree-`degree` quadrature rule on the mesh's cell."""
    import basix

    cell = basix.CellType[msh.topology.cell_name()]
    points, _ = basix.make_quadrature(cell, degree)
    return points


def reference_vertices(msh: dmesh.Mesh) -> np.ndarray:
    """The vertices of the mesh's reference cell."""
    import basix

    return basix.geometry(basix.CellType[msh.topology.cell_name()])
