"""Verification problems with exact answers, shared by the tests and the stability study.

Each problem builds its mesh, forms and boundary conditions from the package's own pieces
(poroelasticity, viscoelasticity, contact, the time stepper's SNES set-up) and knows its exact
solution, so that a test and a study of the same problem measure the same thing. Units: mm, N,
s, MPa; plane strain, so forces are per unit thickness (N/mm).

- `ConfinedBlock`: a block on rollers loaded on its top (a traction strip or a displacement):
  biphasic (consolidation, creep, undrained strip load), viscoelastic (a relaxing strip) or
  hyperelastic. A `Steppable` for `solver.TimeStepper`.
- `Terzaghi`: the drained-top consolidation column and its exact pore pressure and settlement,
  after any time t (Terzaghi's series) and after one backward-Euler step.
- `Hertz` and `HertzBlock`: a rigid cylinder pressed into a linear-elastic half block with
  Nitsche contact, and the plane-strain Hertz half-width and peak pressure.
- Closed forms: `confined_modulus`, `confined_drained_stress`, `prony_ramp_integral`.
- Wiring: `newton_problem` (a NonlinearProblem with the solver's SNES set-up),
  `support_reaction`, `contact_edge`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import ClassVar

import numpy as np
import ufl
from dolfinx import fem, mesh
from dolfinx.fem.petsc import NonlinearProblem
from mpi4py import MPI

from .. import materials as mat
from ..contact import NitscheContact, Obstacle, p_wave_modulus
from ..errors import CompactionError
from ..indenters import Cylinder
from ..kinematics import deformation_gradient
from ..poroelasticity import biphasic_residuals
from ..solver import DEFAULT_PETSC_OPTIONS
from ..viscoelasticity import QuasiLinearViscoelasticity

#: Quadrature degree of the block's volume terms: the hyperfoam stress is not polynomial.
QUADRATURE_DEGREE = 4


# ---- closed forms ----------------------------------------------------------------------------


def confined_modulus(solid) -> float:
    """M = K0 + 4μ0/3 (MPa): the small-strain stiffness of a laterally confined column (the
    P-wave or aggregate modulus). With a permeability k, c = k M (mm²/s) is the consolidation
    coefficient and H²/c the drainage time of a layer H."""
    return solid.K0 + 4 * solid.mu0 / 3


def confined_drained_stress(solid, lam: float) -> np.ndarray:
    """Nominal stresses (P11, P22) (MPa) of the drained solid at F = diag(1, λ), λ3 = 1.

    A laterally confined column compressed to the stretch λ and fully drained (p = 0) carries
    the load by its solid alone: P_aa = τ_a / λ_a with the principal Kirchhoff stresses τ of
    the hyperfoam (`Hyperfoam.principal_kirchhoff`, the closed form from W).
    """
    stretches = np.array([1.0, lam, 1.0])
    tau = solid.principal_kirchhoff(stretches)
    return tau[:2] / stretches[:2]


def prony_ramp_integral(prony, t: float, T: float = 1.0) -> float:
    """∫_0^min(t,T) g(t − s) ds (s), g(t) = g∞ + Σ g_i exp(−t/τ_i) the relaxation function.

    The QLV stress is the hereditary integral S(t) = ∫ g(t − s) dS_e(s); for S_e ramped linearly
    to S_e(T) over [0, T] and then held, S(t) = S_e(T)/T times this integral, exactly.
    """
    t1 = min(t, T)
    return prony.g_inf * t1 + sum(g * tau * (np.exp(-(t - t1) / tau) - np.exp(-t / tau))
                                  for g, tau in zip(prony.g, prony.tau))


# ---- wiring ----------------------------------------------------------------------------------


def newton_problem(F, u, bcs, prefix: str, **options) -> NonlinearProblem:
    """A NonlinearProblem with the time stepper's SNES set-up (`solver.DEFAULT_PETSC_OPTIONS`:
    Newton with line search, direct LU) and `options` on top, e.g. snes_rtol=1e-12.
    `prefix` must be unique per problem (PETSc options are global)."""
    return NonlinearProblem(F, u, bcs=bcs, petsc_options_prefix=prefix,
                            petsc_options={**DEFAULT_PETSC_OPTIONS, **options})


def support_reaction(P, V, dofs) -> float:
    """The y-reaction of the supports holding `dofs` (N/mm): the elastic residual ∫ P:∇w dx
    tested with w = 1 on those y-dofs, summed over the ranks."""
    w = fem.Function(V)
    w.x.array[dofs] = 1.0
    form = fem.form(ufl.inner(P, ufl.grad(w)) * ufl.dx)
    return V.mesh.comm.allreduce(fem.assemble_scalar(form))


# ---- the confined block (column) ---------------------------------------------------------------


class ConfinedBlock:
    """A Steppable block [0, W] × [0, H] (mm) on rollers: u_x = 0 on the sides, u_y = 0 at the
    bottom, so that a load over the whole top gives the one-dimensional confined state.

    Top: a compressive traction `load(t)` (MPa) on x < load_width (a strip footing; the whole
    top by default), or with `top_displacement` a prescribed downward displacement `load(t)`
    (mm) of the whole top. Material: a biphasic `tissue` (pore pressure p in P1, its residuals
    from `poroelasticity`; the top drained, p = 0, if `drained_top`, every other boundary
    impermeable), else the hyperelastic `solid`; `prony` makes the solid's stress quasi-linear
    viscoelastic. Displacement degree `degree_u`: 2 with the P1 pressure is Taylor–Hood, 1 the
    equal-order pair that fails the inf-sup condition. The tissue's mass balance takes the time
    stepper's multistep weights (`rate_weights`, `u_nm1`: backward Euler or BDF2), as the
    fingertip's does.
    """

    def __init__(self, nx, ny, load, *, tissue=None, solid=None, prony=None, degree_u=2,
                 width=1.0, H=1.0, load_width=None, drained_top=False, top_displacement=False,
                 diagonal="right", comm=MPI.COMM_SELF):
        self.msh = mesh.create_rectangle(comm, [[0.0, 0.0], [width, H]], [nx, ny],
                                         diagonal=getattr(mesh.DiagonalType, diagonal))
        self.W, self.H, self.load, self.tissue = width, H, load, tissue
        self.load_width = width if load_width is None else load_width
        self.top_displacement = top_displacement
        V = fem.functionspace(self.msh, ("Lagrange", degree_u, (2,)))
        self.u, self.u_n, self.u_nm1 = fem.Function(V), fem.Function(V), fem.Function(V)
        self.rate_weights = fem.Constant(self.msh, np.array([1.0, -1.0, 0.0]))
        self.p = None if tissue is None else fem.Function(
            fem.functionspace(self.msh, ("Lagrange", 1)))
        self.unknowns = [self.u] + ([] if self.p is None else [self.p])
        self.dt = fem.Constant(self.msh, 1.0)
        self.value = fem.Constant(self.msh, 0.0)  # the top load now (MPa, or mm downwards)
        self.ds = self._top_measure()
        F = deformation_gradient(self.u)
        S = mat.second_piola_kirchhoff(solid or tissue.solid, F)
        self.qlv = None if prony is None else QuasiLinearViscoelasticity(
            S, prony, self.msh, QUADRATURE_DEGREE, self.dt)
        self.residuals = self._residuals(F * (S if self.qlv is None else self.qlv.stress()))
        self.bcs = self._bcs(drained_top)
        self.entity_maps = None
        self._last = [f.x.array.copy() for f in self.unknowns]
        # J at each cell's centroid and vertices: with P2 displacements J varies over a cell,
        # and its extremes (inversion, compaction) are usually at the corners
        points = np.array([[1 / 3, 1 / 3], [0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
        self._J = fem.Expression(ufl.det(F), points)
        self._settle = fem.form(-self.u[1] * self.ds(1))

    def _top_facets(self) -> np.ndarray:
        return mesh.locate_entities_boundary(self.msh, 1, lambda x: np.isclose(x[1], self.H))

    def _top_measure(self) -> ufl.Measure:
        """ds with the loaded part of the top (facet midpoints at x < load_width) tagged 1."""
        top = self._top_facets()
        loaded = top[mesh.compute_midpoints(self.msh, 1, top)[:, 0] < self.load_width + 1e-12]
        tags = mesh.meshtags(self.msh, 1, loaded, np.full(len(loaded), 1, dtype=np.int32))
        return ufl.Measure("ds", domain=self.msh, subdomain_data=tags)

    def _residuals(self, P_e) -> list[ufl.Form]:
        """Momentum balance ∫ P:∇v dX (P = P_e − p J F⁻ᵀ for a tissue) with the top traction
        unless the top is displaced, and for a tissue Δt × the fluid mass balance."""
        v = ufl.TestFunction(self.u.function_space)
        dx = ufl.dx(metadata={"quadrature_degree": QUADRATURE_DEGREE})
        if self.tissue is None:
            residuals = [ufl.inner(P_e, ufl.grad(v)) * dx]
        else:
            q = ufl.TestFunction(self.p.function_space)
            residuals = list(biphasic_residuals(self.u, self.p, self.u_n, v, q, self.dt,
                                                self.tissue, dx, P_e, self.u_nm1,
                                                self.rate_weights))
        if not self.top_displacement:
            residuals[0] += self.value * v[1] * self.ds(1)
        return residuals

    def _bcs(self, drained_top: bool) -> list[fem.DirichletBC]:
        """The rollers, the prescribed top u_y if the top is displaced, p = 0 if drained."""
        msh, W = self.msh, self.W
        sides = mesh.locate_entities_boundary(
            msh, 1, lambda x: np.isclose(x[0], 0.0) | np.isclose(x[0], W))
        bottom = mesh.locate_entities_boundary(msh, 1, lambda x: np.isclose(x[1], 0.0))
        Vx, Vy = self.u.function_space.sub(0), self.u.function_space.sub(1)
        bcs = [fem.dirichletbc(0.0, fem.locate_dofs_topological(Vx, 1, sides), Vx),
               fem.dirichletbc(0.0, fem.locate_dofs_topological(Vy, 1, bottom), Vy)]
        if self.top_displacement:
            bcs.append(fem.dirichletbc(self.value, self._top_y_dofs, Vy))
        if drained_top:
            Q = self.p.function_space
            bcs.append(fem.dirichletbc(0.0, fem.locate_dofs_topological(Q, 1, self._top_facets()),
                                       Q))
        return bcs

    @cached_property
    def _top_y_dofs(self) -> np.ndarray:
        """The top's y-dofs (indices into u's array)."""
        return fem.locate_dofs_topological(self.u.function_space.sub(1), 1, self._top_facets())

    # Steppable --------------------------------------------------------------------------------
    def set_time(self, t):
        self.value.value = -self.load(t) if self.top_displacement else self.load(t)

    def accept(self):
        if self.qlv is not None:
            self.qlv.advance()
        self.u_nm1.x.array[:] = self.u_n.x.array
        self.u_n.x.array[:] = self.u.x.array
        self._last = [f.x.array.copy() for f in self.unknowns]

    def mark_accepted(self):
        self._last = [f.x.array.copy() for f in self.unknowns]

    def state_arrays(self) -> dict[str, np.ndarray]:
        """The live arrays that define the state (the time stepper's error control saves and
        restores them around a trial step)."""
        arrays = {"u": self.u.x.array, "u_n": self.u_n.x.array, "u_nm1": self.u_nm1.x.array}
        if self.p is not None:
            arrays["p"] = self.p.x.array
        if self.qlv is not None:
            arrays |= {f"qlv_{i}": f.x.array for i, f in enumerate([*self.qlv.h, self.qlv.S_e_n])}
        return arrays

    def restore(self):
        for f, saved in zip(self.unknowns, self._last):
            f.x.array[:] = saved

    def inadmissible(self) -> str | None:
        """Inverted cells, or a tissue within 0.02 of compaction (J = φ0)."""
        J_min, where = self.min_jacobian()
        if not np.isfinite(J_min) or J_min <= 0:
            return f"inverted elements (J = {J_min:.3g})"
        if self.tissue is None:
            return None
        try:  # the same margin as problem.FingertipProblem
            mat.check_compaction(J_min, f"block cell near ({where[0]:.3f}, {where[1]:.3f}) mm",
                                 self.tissue.phi0, margin=0.02)
        except CompactionError as e:
            return str(e)
        return None

    def diagnostics(self) -> dict[str, float]:
        out = {"settlement": self.settlement(), "J_min": self.min_jacobian()[0],
               "max_J_change_lower_half": self.max_J_change(below=self.H / 2)}
        if self.top_displacement:
            out["reaction"] = self.reaction()
        return out

    # outputs ----------------------------------------------------------------------------------
    def settlement(self) -> float:
        """Mean downward displacement of the loaded part of the top (mm)."""
        return self.msh.comm.allreduce(fem.assemble_scalar(self._settle)) / self.load_width

    @cached_property
    def _reaction_form(self) -> fem.Form:
        V = self.u.function_space
        w = fem.Function(V)
        w.x.array[self._top_y_dofs] = 1.0
        return fem.form(ufl.replace(self.residuals[0], {ufl.TestFunction(V): w}))

    def reaction(self) -> float:
        """The momentum residual tested with w = 1 on the top's y-dofs (N/mm): at a converged
        state, the force holding a displaced top in place."""
        return self.msh.comm.allreduce(fem.assemble_scalar(self._reaction_form))

    def _jacobians(self) -> tuple[np.ndarray, np.ndarray]:
        """J at the owned cells' centroids and vertices (a row per cell), the cells' centres."""
        n = self.msh.topology.index_map(2).size_local
        cells = np.arange(n, dtype=np.int32)
        centres = self.msh.geometry.x[self.msh.geometry.dofmaps[0][cells]].mean(axis=1)
        return self._J.eval(self.msh, cells).reshape(n, -1), centres

    def min_jacobian(self) -> tuple[float, np.ndarray]:
        """The smallest J over every rank, and the centre of a cell reaching it (mm)."""
        J, centres = self._jacobians()
        with np.errstate(invalid="ignore"):
            worst = int(np.nanargmin(J.min(axis=1))) if np.isfinite(J).any() else 0
        J_min, *where = self.msh.comm.allreduce((float(np.min(J)), *centres[worst]), op=MPI.MIN)
        return J_min, np.array(where)

    def max_J_change(self, below: float) -> float:
        """max |J − 1| at the centroids of the cells whose centre lies below y = `below`
        (every rank): the volume change away from a drained top's boundary layer."""
        J, centres = self._jacobians()
        local = float(np.max(np.abs(J[centres[:, 1] < below, 0] - 1), initial=0.0))
        return self.msh.comm.allreduce(local, op=MPI.MAX)

    def pressure_nodes(self) -> tuple[np.ndarray, np.ndarray]:
        """(x, y) of the pressure nodes (mm) and p there (MPa), gathered from every rank."""
        Q, comm = self.p.function_space, self.msh.comm
        n = Q.dofmap.index_map.size_local
        X = np.concatenate(comm.allgather(Q.tabulate_dof_coordinates()[:n, :2]))
        return X, np.concatenate(comm.allgather(self.p.x.array[:n]))

    def pressure_at(self, y: np.ndarray) -> np.ndarray:
        """p along the left edge x = 0 at heights y (P1: exact between its nodes)."""
        X, p = self.pressure_nodes()
        left = np.isclose(X[:, 0], 0.0)
        order = np.argsort(X[left, 1])
        return np.interp(y, X[left, 1][order], p[left][order])


# ---- Terzaghi's consolidation column -------------------------------------------------------------


@dataclass(frozen=True)
class Terzaghi:
    """One-dimensional consolidation: a biphasic layer 0 ≤ y ≤ H under a sudden load σ0 on its
    top, drained there (p = 0), impermeable at the bottom, confined at the sides.

    The permeability is constant (Holmes–Mow with κ = M = 0) and set to k = c/M (M the confined
    modulus of `solid`), so the consolidation coefficient is c (mm²/s); the load is `strain` × M,
    which keeps the finite-strain code in its small-strain limit (linear Biot theory). Exact:
    p solves ∂p/∂t = c ∂²p/∂y², p(y, 0) = σ0, p(H, t) = 0, ∂p/∂y(0, t) = 0 (Terzaghi 1923;
    e.g. Verruijt, Theory and Problems of Poroelasticity, ch. 2), and the settlement is σ0 H/M
    times the degree of consolidation.
    """

    solid: mat.Hyperfoam = mat.SUBCUTANEOUS
    c: float = 1.0  # mm²/s: with H = 1 mm the time factor c t/H² is t
    H: float = 1.0  # mm
    strain: float = 1e-5

    @property
    def M(self) -> float:
        return confined_modulus(self.solid)

    @property
    def sigma0(self) -> float:
        """The load (MPa)."""
        return self.strain * self.M

    @property
    def tissue(self) -> mat.Biphasic:
        return mat.Biphasic(self.solid, mat.HolmesMow(k0=self.c / self.M, phi0=0.4, kappa=0.0,
                                                      M=0.0))

    def column(self, ny: int, *, degree_u: int = 2, comm=MPI.COMM_SELF) -> ConfinedBlock:
        """A column 0.1 mm wide (one cell across), ny cells high."""
        return ConfinedBlock(1, ny, lambda t: self.sigma0, tissue=self.tissue, degree_u=degree_u,
                             width=0.1, H=self.H, drained_top=True, comm=comm)

    def series(self, y, t: float, terms: int = 200) -> tuple[np.ndarray, float]:
        """p(y, t) (MPa) and the settlement at t (mm), from Terzaghi's Fourier series:
        p = Σ 2σ0/m_k sin(m_k (H − y)/H) exp(−m_k² T), m_k = (2k + 1)π/2, T = c t/H²."""
        m = np.arange(terms)
        Mm = np.pi * (2 * m + 1) / 2
        T = self.c * t / self.H**2
        Z = (self.H - np.asarray(y))[:, None] / self.H
        p = (2 * self.sigma0 / Mm * np.sin(Mm * Z) * np.exp(-(Mm**2) * T)).sum(axis=1)
        degree = 1 - (2 / Mm**2 * np.exp(-(Mm**2) * T)).sum()
        return p, self.sigma0 * self.H / self.M * degree

    def one_step_pressure(self, z, dt: float) -> np.ndarray:
        """Exact p (MPa) after one backward-Euler step Δt from rest, continuous in space:
        p − c Δt p'' = σ0, p(H) = 0, p'(0) = 0 ⇒ p = σ0 (1 − cosh(z/ℓ)/cosh(H/ℓ)), ℓ = sqrt(cΔt).
        Never above σ0 and monotone: any overshoot is the discretisation's."""
        ell = math.sqrt(self.c * dt)
        z = np.asarray(z, dtype=float)
        H = self.H
        ratio = np.exp((z - H) / ell) * (1 + np.exp(-2 * z / ell)) / (1 + np.exp(-2 * H / ell))
        return self.sigma0 * (1 - ratio)

    def one_step_settlement(self, dt: float) -> float:
        """The settlement (mm) after that step: ∫ (σ0 − p)/M dz = σ0 ℓ tanh(H/ℓ)/M."""
        ell = math.sqrt(self.c * dt)
        return self.sigma0 / self.M * ell * math.tanh(self.H / ell)


# ---- Hertz: a rigid cylinder on an elastic half block ---------------------------------------


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
        return p_wave_modulus(self.E, self.nu)

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
              modulus=None) -> HertzBlock:
        """The P2 displacement, the cylinder (touching at y = 0), the contact terms with
        γ = γ0 modulus/h (modulus: `self.modulus` unless given, e.g. a Constant to sweep γ0
        without recompiling), the residual and the supports."""
        V = fem.functionspace(domain, ("Lagrange", 2, (2,)))
        u, v = fem.Function(V), ufl.TestFunction(V)
        P = self.stress(u)
        obstacle = Obstacle.at(domain, Cylinder(radius=self.R), y_tip=0.0)
        ds = ufl.Measure("ds", domain, subdomain_data=facet_tags)
        contact = NitscheContact(u, P, ds(self.BOTTOM), [obstacle],
                                 modulus=self.modulus if modulus is None else modulus,
                                 theta=theta, gamma0=gamma0)
        residual = ufl.inner(P, ufl.grad(v)) * ufl.dx + contact.residual(v)
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


def contact_edge(x: np.ndarray, trial: np.ndarray) -> float:
    """The contact half-width (mm): the first sign change of the trial pressure t_n − γ g
    along x (sorted), linearly interpolated; NaN without one."""
    k = np.flatnonzero(trial <= 0)
    if not len(k) or k[0] == 0:
        return math.nan
    i = k[0]
    return x[i - 1] + (x[i] - x[i - 1]) * trial[i - 1] / (trial[i - 1] - trial[i])
