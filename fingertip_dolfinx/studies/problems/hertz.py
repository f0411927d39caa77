"""Hertz: a rigid cylinder pressed into a linear-elastic half block with Nitsche contact, and the
plane-strain Hertz half-width and peak pressure; `HertzSphere`, the 3D case, a rigid sphere on a
quarter block (two symmetry planes), Hertz's contact radius and peak pressure (forces in N);
`contact_edge`, the contact half-width from the trial pressure."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI

from ...geometry.indenters import Cylinder, Sphere
from ...physics import materials as mat
from ...physics.contact import NitscheContact, Obstacle
from .wiring import support_reaction


@dataclass(frozen=True)
class Hertz:
    """A rigid cylinder of radius R pressed by `depth` into the bottom face of a linear-elastic
    block [0, L]², half model (symmetry at x = 0, top fixed), small strain, Nitsche contact.

    With a ≪ R and a ≪ L the block is a half-space and plane-strain Hertz theory applies
    (Johnson, Contact Mechanics, §4.3 / eq. 4.43): for a force P per unit length (N/mm),
    E* = E/(1 − ν²), a = sqrt(4 P R/(π E*)), p0 = 2 P/(π a) = E* a/(2R). The default load is
    small, a/R = 0.02: strains ~ a/(2R) = 1 %, so finite-kinematics effects (the gap and normal
    at x = X + u, forces per reference area) stay well below the errors measured.
    """

    E: float = 1.0  # MPa
    nu: float = 0.3
    R: float = 1.0  # mm
    L: float = 4.0  # mm
    a_target: float = 0.02  # mm: the contact half-width aimed at
    depth: float = 0.0012  # mm: the indentation that gives about a_target on this block
    BOTTOM: ClassVar[int] = 1  # facet tags
    TOP: ClassVar[int] = 2
    SYMMETRY: ClassVar[int] = 3

    @property
    def modulus(self) -> float:
        """λ + 2μ (MPa): the M of Nitsche's γ = γ0 M/h."""
        return mat.p_wave_modulus(self.E, self.nu)

    def theory(self, force: float) -> tuple[float, float]:
        """Hertz half-width a (mm) and peak pressure p0 (MPa) for the whole cylinder's force."""
        a = math.sqrt(4 * force * self.R * (1 - self.nu**2) / (math.pi * self.E))
        return a, 2 * force / (math.pi * a)

    def stress(self, u):
        """σ(ε(u)) = λ tr(ε) I + 2μ ε: the first Piola–Kirchhoff stress of the small-strain
        limit."""
        mu = self.E / (2 * (1 + self.nu))
        lmbda = self.E * self.nu / ((1 + self.nu) * (1 - 2 * self.nu))
        eps = ufl.sym(ufl.grad(u))
        return lmbda * ufl.tr(eps) * ufl.Identity(2) + 2 * mu * eps

    def mesh(self, h_contact: float, comm=MPI.COMM_SELF):
        """The half block (gmsh on rank 0), graded from h_contact within 2 a_target of the
        first touch (the origin) to L/8 beyond L/2; returns (mesh, facet tags)."""
        import gmsh
        from dolfinx.io.gmsh import model_to_mesh

        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        if comm.rank == 0:
            self._gmsh_block(gmsh)
            self._gmsh_grading(gmsh, h_contact)
            gmsh.model.mesh.generate(2)
        data = model_to_mesh(gmsh.model, comm, 0, gdim=2)
        gmsh.finalize()
        return data.mesh, data.facet_tags

    def _gmsh_block(self, gmsh) -> None:
        """The square with its bottom, top and symmetry edges tagged."""
        L = self.L
        gmsh.model.add("block")
        occ = gmsh.model.occ
        occ.addRectangle(0, 0, 0, L, L)
        occ.synchronize()
        for curve in gmsh.model.getEntities(1):
            x, y, _ = occ.getCenterOfMass(*curve)
            tag = (self.BOTTOM if y < 1e-9 else self.TOP if y > L - 1e-9
                   else self.SYMMETRY if x < 1e-9 else 0)
            if tag:
                gmsh.model.addPhysicalGroup(1, [curve[1]], tag)
        gmsh.model.addPhysicalGroup(2, [1], 1)

    def _gmsh_grading(self, gmsh, h_contact: float) -> None:
        field = gmsh.model.mesh.field
        origin = gmsh.model.occ.addPoint(0, 0, 0)
        gmsh.model.occ.synchronize()
        field.add("Distance", 1)
        field.setNumbers(1, "PointsList", [origin])
        field.add("Threshold", 2)
        for name, value in [("InField", 1), ("SizeMin", h_contact), ("SizeMax", self.L / 8),
                            ("DistMin", 2 * self.a_target), ("DistMax", self.L / 2)]:
            field.setNumber(2, name, value)
        field.setAsBackgroundMesh(2)
        for option in ("MeshSizeExtendFromBoundary", "MeshSizeFromPoints", "MeshSizeFromCurvature"):
            gmsh.option.setNumber(f"Mesh.{option}", 0)

    def block(self, domain, facet_tags, *, theta: int = 0, gamma0: float = 10.0,
              modulus=None, method: str = "nitsche") -> HertzBlock:
        """The P2 displacement, the cylinder (touching at y = 0), the contact terms (`method`,
        contact.CONTACT_METHODS) with γ = γ0 modulus/h (modulus: `self.modulus` unless given,
        e.g. a Constant to sweep γ0 without recompiling), the residual and the supports."""
        V, u, P, obstacle, contact, residual = _contact_on_block(
            self, domain, facet_tags, Cylinder(radius=self.R), theta, gamma0, modulus, method)
        fdim = domain.topology.dim - 1
        top = fem.locate_dofs_topological(V, fdim, facet_tags.find(self.TOP))
        side = fem.locate_dofs_topological(V.sub(0), fdim, facet_tags.find(self.SYMMETRY))
        bcs = [fem.dirichletbc(np.zeros(2), top, V), fem.dirichletbc(0.0, side, V.sub(0))]
        return HertzBlock(u, P, obstacle, contact, residual, bcs, facet_tags)


@dataclass(frozen=True)
class HertzBlock:
    """A built Hertz half model: solve `residual` = 0 for `u` with `bcs`, moving the cylinder
    by `obstacle.y_tip.value`; the measures are those of the whole cylinder (twice the half)."""

    u: fem.Function
    P: ufl.core.expr.Expr
    obstacle: Obstacle
    contact: NitscheContact
    residual: ufl.Form
    bcs: list
    facet_tags: mesh.MeshTags

    def force(self) -> float:
        """The cylinder's push on the block (N/mm)."""
        return 2 * float(self.contact.forces()[0])

    def reaction(self) -> float:
        """The fixed top's y-reaction (N/mm): −force at discrete equilibrium."""
        V = self.u.function_space
        fdim = V.mesh.topology.dim - 1
        top = self.facet_tags.find(Hertz.TOP)
        return 2 * support_reaction(self.P, V, fem.locate_dofs_topological(V.sub(1), fdim, top))

    def profile(self, points_per_facet: int = 11) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Along the contact face, gathered from every rank and sorted by x: x (mm), the
        Nitsche pressure [t_n − γ g]_+ and the trial pressure t_n − γ g (MPa)."""
        contact, comm = self.contact, self.u.function_space.mesh.comm
        X, p = contact.sample(contact.pressure, points_per_facet=points_per_facet)
        _, s = contact.sample(contact.trial_pressure, points_per_facet=points_per_facet)
        X, p, s = (np.concatenate(comm.allgather(a)) for a in (X, p, s))
        order = np.argsort(X[:, 0], kind="stable")
        return X[order, 0], p[order], s[order]


@dataclass(frozen=True)
class HertzSphere(Hertz):
    """A rigid sphere of radius R pressed by `depth` into the face y = 0 of a linear-elastic
    block [0, L]³: a quarter model (symmetry u_x = 0 at x = 0 and u_z = 0 at z = 0, the top
    y = L fixed), small strain, Nitsche contact; the sphere touches at the origin.

    Hertz (Johnson, Contact Mechanics, §4.2, eqs. 4.22–4.23): for the whole sphere's force P
    (N), E* = E/(1 − ν²), a = (3PR/(4E*))^(1/3), p0 = 3P/(2πa²), and the depth δ = a²/R. The
    default a/R = 0.05 keeps the strains ~ a/R small; L = 20a: the finite block adds to the
    depth a near-rigid shift (~ P/(E* L)) but, to first order, leaves the pressure under the
    sphere, hence a(P) and p0(P), unchanged (measured: a and p0 move by < 0.5 % from L = 20a
    to 40a, see benchmarks/hertz_sphere.py).
    """

    a_target: float = 0.05  # mm
    depth: float = 0.0025  # mm: a_target²/R
    L: float = 1.0  # mm
    SYMMETRY_Z: ClassVar[int] = 4

    def theory(self, force: float) -> tuple[float, float]:
        """Hertz contact radius a (mm) and peak pressure p0 (MPa) for the whole sphere's force."""
        a = (3 * force * self.R * (1 - self.nu**2) / (4 * self.E)) ** (1 / 3)
        return a, 3 * force / (2 * math.pi * a**2)

    def stress(self, u):
        mu = self.E / (2 * (1 + self.nu))
        lmbda = self.E * self.nu / ((1 + self.nu) * (1 - 2 * self.nu))
        eps = ufl.sym(ufl.grad(u))
        return lmbda * ufl.tr(eps) * ufl.Identity(3) + 2 * mu * eps

    def mesh(self, h_contact: float, comm=MPI.COMM_SELF):
        """The quarter block (gmsh tetrahedra on rank 0), graded from h_contact within
        2 a_target of the origin to L/4 beyond L/2; returns (mesh, facet tags)."""
        import gmsh
        from dolfinx.io.gmsh import model_to_mesh

        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        if comm.rank == 0:
            self._gmsh_box(gmsh)
            self._gmsh_grading(gmsh, h_contact)
            gmsh.option.setNumber("Mesh.MeshSizeMax", self.L / 4)
            gmsh.model.mesh.generate(3)
        data = model_to_mesh(gmsh.model, comm, 0, gdim=3)
        gmsh.finalize()
        return data.mesh, data.facet_tags

    def _gmsh_box(self, gmsh) -> None:
        L = self.L
        gmsh.model.add("quarter block")
        occ = gmsh.model.occ
        occ.addBox(0, 0, 0, L, L, L)
        occ.synchronize()
        for face in gmsh.model.getEntities(2):
            x, y, z = occ.getCenterOfMass(*face)
            tag = (self.BOTTOM if y < 1e-9 else self.TOP if y > L - 1e-9
                   else self.SYMMETRY if x < 1e-9 else self.SYMMETRY_Z if z < 1e-9 else 0)
            if tag:
                gmsh.model.addPhysicalGroup(2, [face[1]], tag)
        gmsh.model.addPhysicalGroup(3, [1], 1)

    def block(self, domain, facet_tags, *, theta: int = 0, gamma0: float = 10.0,
              modulus=None) -> HertzSphereBlock:
        """The P2 displacement, the sphere (touching at the origin), the contact terms, the
        residual and the supports (top clamped, the two symmetry planes on rollers)."""
        V, u, P, obstacle, contact, residual = _contact_on_block(
            self, domain, facet_tags, Sphere(radius=self.R), theta, gamma0, modulus)
        fdim = domain.topology.dim - 1
        top = fem.locate_dofs_topological(V, fdim, facet_tags.find(self.TOP))
        bcs = [fem.dirichletbc(np.zeros(3), top, V)]
        for tag, k in ((self.SYMMETRY, 0), (self.SYMMETRY_Z, 2)):
            dofs = fem.locate_dofs_topological(V.sub(k), fdim, facet_tags.find(tag))
            bcs.append(fem.dirichletbc(0.0, dofs, V.sub(k)))
        return HertzSphereBlock(u, P, obstacle, contact, residual, bcs, facet_tags)


def _contact_on_block(hertz, domain, facet_tags, indenter, theta: int, gamma0: float, modulus,
                      method: str = "nitsche"):
    """The Hertz blocks' common part (2D and 3D): P2 displacement, `hertz.stress`, the
    indenter touching at y = 0 on the BOTTOM facets, the Nitsche terms and the residual."""
    V = fem.functionspace(domain, ("Lagrange", 2, (domain.geometry.dim,)))
    u, v = fem.Function(V), ufl.TestFunction(V)
    P = hertz.stress(u)
    obstacle = Obstacle.at(domain, indenter, y_tip=0.0)
    ds = ufl.Measure("ds", domain, subdomain_data=facet_tags)
    contact = NitscheContact(u, P, ds(hertz.BOTTOM), [obstacle],
                             modulus=hertz.modulus if modulus is None else modulus,
                             theta=theta, gamma0=gamma0, method=method)
    residual = ufl.inner(P, ufl.grad(v)) * ufl.dx + contact.residual(v)
    return V, u, P, obstacle, contact, residual


@dataclass(frozen=True)
class HertzSphereBlock(HertzBlock):
    """A built quarter model of `HertzSphere`; forces are the whole sphere's (4 × the quarter)."""

    def force(self) -> float:
        """The sphere's push on the block (N)."""
        return 4 * float(self.contact.forces()[0])

    def reaction(self) -> float:
        """The fixed top's y-reaction (N): −force at discrete equilibrium."""
        V = self.u.function_space
        top = self.facet_tags.find(Hertz.TOP)
        dofs = fem.locate_dofs_topological(V.sub(1), V.mesh.topology.dim - 1, top)
        return 4 * support_reaction(self.P, V, dofs)

    def profile(self, points_per_facet: int = 7) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Along the radius on the contact face: the points of the facets on the symmetry line
        z = 0 (and, the same by symmetry, on x = 0), gathered and sorted by their distance r
        from the origin: r (mm), the Nitsche pressure and the trial pressure (MPa)."""
        contact, comm = self.contact, self.u.function_space.mesh.comm
        X, p = contact.sample(contact.pressure, points_per_facet=points_per_facet)
        _, s = contact.sample(contact.trial_pressure, points_per_facet=points_per_facet)
        on_line = (np.abs(X[:, 2]) < 1e-12) | (np.abs(X[:, 0]) < 1e-12)
        r = np.hypot(X[on_line, 0], X[on_line, 2])
        r, p, s = (np.concatenate(comm.allgather(a)) for a in (r, p[on_line], s[on_line]))
        order = np.argsort(r, kind="stable")
        return r[order], p[order], s[order]


def contact_edge(x: np.ndarray, trial: np.ndarray) -> float:
    """The contact half-width (mm): the first sign change of the trial pressure t_n − γ g
    along x (sorted), linearly interpolated; NaN without one."""
    k = np.flatnonzero(trial <= 0)
    if not len(k) or k[0] == 0:
        return math.nan
    i = k[0]
    return x[i - 1] + (x[i] - x[i - 1]) * trial[i - 1] / (trial[i - 1] - trial[i])
