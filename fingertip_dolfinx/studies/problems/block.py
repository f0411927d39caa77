"""The confined block: a Steppable block on rollers loaded on its top (a traction strip or a
displacement), biphasic (consolidation, creep, undrained strip load), viscoelastic (a relaxing
strip) or hyperelastic (or, `small_strain`, exactly linear); with a `density`, dynamic
(inertia.py: free vibration, a harmonically driven layer); in 3D a column of tetrahedra. The
unconfined block between frictionless platens. Closed forms: the confined modulus, the drained
confined stress, the QLV stress of a ramp-hold (`prony_ramp_integral`)."""

from __future__ import annotations

from functools import cached_property

import numpy as np
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI

from ...physics import materials as mat
from ...physics.admissibility import Admissibility, Compaction
from ...physics.inertia import Inertia
from ...physics.kinematics import deformation_gradient
from ...physics.poroelasticity import biphasic_residuals
from ...physics.viscoelasticity import QuasiLinearViscoelasticity
from ...state import SteppableState
from .wiring import QUADRATURE_DEGREE, graded

#: M = K0 + 4μ0/3 (MPa): the small-strain stiffness of a laterally confined column (the
#: P-wave or aggregate modulus). With a permeability k, c = k M (mm²/s) is the consolidation
#: coefficient and H²/c the drainage time of a layer H.
confined_modulus = mat.small_strain_p_wave_modulus


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


def _small_strain_stress(solid: mat.LinearElastic, u) -> ufl.core.expr.Expr:
    """σ = λ tr(ε) I + 2μ ε, ε = sym Grad u: exactly linear in u (the dynamics' exact checks)."""
    eps = ufl.sym(ufl.grad(u))
    return solid.lmbda * ufl.tr(eps) * ufl.Identity(len(u)) + 2 * solid.mu * eps


class ConfinedBlock(SteppableState):
    """A Steppable block [0, W] × [0, H] (mm) on rollers: u_x = 0 on the sides, u_y = 0 at the
    bottom, so that a load over the whole top gives the one-dimensional confined state.

    Top: a compressive traction `load(t)` (MPa) on x < load_width (a strip footing; the whole
    top by default), or with `top_displacement` a prescribed downward displacement `load(t)`
    (mm) of the whole top. Material: a biphasic `tissue` (pore pressure p in P1, its residuals
    from `poroelasticity`; the top drained, p = 0, if `drained_top`, every other boundary
    impermeable), else the hyperelastic `solid`; `prony` makes the solid's stress quasi-linear
    viscoelastic. Displacement degree `degree_u`: 2 with the P1 pressure is Taylor–Hood, 1 the
    equal-order pair that fails the inf-sup condition. A tissue is guarded against compaction
    as the fingertip's is (`admissibility`): J ≤ φ0 + `compaction_margin` at a quadrature point
    or a node stops the time stepper with a `CompactionError`. The tissue's mass balance takes
    the time stepper's multistep weights (`rate_weights`, `u_nm1`: backward Euler or BDF2), as
    the fingertip's does.

    `gdim = 3`: the column [0, W] × [0, H] × [0, W] of tetrahedra (nx × ny × nx boxes), rollers
    also on z = 0 and z = W: the same one-dimensional state, whose C = diag(1, λ², 1) has a
    double eigenvalue. Forces are then in N, the settlement the mean over the loaded area.
    """

    #: The axis along which `grading` shrinks the cells (towards its far end: the drained top).
    GRADED_AXIS = 1

    def __init__(self, nx, ny, load, *, tissue=None, solid=None, prony=None, degree_u=2,
                 width=1.0, H=1.0, load_width=None, drained_top=False, top_displacement=False,
                 diagonal="right", compaction_margin=0.02, grading=1.0, density=None,
                 small_strain=False, gdim=2, comm=MPI.COMM_SELF):
        if gdim == 3:
            self.msh = mesh.create_box(comm, [[0.0, 0.0, 0.0], [width, H, width]], [nx, ny, nx],
                                       mesh.CellType.tetrahedron)
        else:
            self.msh = mesh.create_rectangle(comm, [[0.0, 0.0], [width, H]], [nx, ny],
                                             diagonal=getattr(mesh.DiagonalType, diagonal))
        self.gdim = gdim
        self.fdim = gdim - 1
        if grading != 1.0:  # cells shrink geometrically towards the drained boundary
            axis, length = self.GRADED_AXIS, (width, H)[self.GRADED_AXIS]
            x = self.msh.geometry.x
            x[:, axis] = length * graded(x[:, axis] / length, grading)
        self.W, self.H, self.load, self.tissue = width, H, load, tissue
        self.load_width = width if load_width is None else load_width
        self.top_displacement = top_displacement
        V = fem.functionspace(self.msh, ("Lagrange", degree_u, (gdim,)))
        self.u, self.u_n, self.u_nm1 = fem.Function(V), fem.Function(V), fem.Function(V)
        self.rate_weights = fem.Constant(self.msh, np.array([1.0, -1.0, 0.0]))
        self.p = None if tissue is None else fem.Function(
            fem.functionspace(self.msh, ("Lagrange", 1)))
        self.unknowns = [self.u] + ([] if self.p is None else [self.p])
        self.dt = fem.Constant(self.msh, 1.0)
        self.value = fem.Constant(self.msh, 0.0)  # the top load now (MPa, or mm downwards)
        self.ds = self._top_measure()
        F = deformation_gradient(self.u)
        self.solid, self.small_strain = solid or tissue.solid, small_strain
        S = _small_strain_stress(solid, self.u) if small_strain else \
            mat.second_piola_kirchhoff(self.solid, F)
        self.qlv = None if prony is None else QuasiLinearViscoelasticity(
            S, prony, self.msh, QUADRATURE_DEGREE, self.dt)
        S_total = S if self.qlv is None else self.qlv.stress()
        self.inertia = None if density is None else Inertia(
            self.u, self.u_n, self.dt,
            [(density, ufl.dx(metadata={"quadrature_degree": QUADRATURE_DEGREE}))])
        self.residuals = self._residuals(S_total if small_strain else F * S_total)
        self.bcs = self._bcs(drained_top)
        self.entity_maps = None
        cells = np.arange(self.msh.topology.index_map(gdim).size_local, dtype=np.int32)
        self.admissibility = Admissibility(F, self.msh, QUADRATURE_DEGREE, None if tissue is None
                                           else Compaction(cells, tissue.phi0, compaction_margin,
                                                           tissue.permeability.k0))
        self.mark_accepted()
        centroid = np.full((1, gdim), 1 / (gdim + 1))
        self._J = fem.Expression(ufl.det(F), centroid)  # at the centroids
        self._settle = fem.form(-self.u[1] * self.ds(1))

    def _top_facets(self) -> np.ndarray:
        return mesh.locate_entities_boundary(self.msh, self.fdim,
                                             lambda x: np.isclose(x[1], self.H))

    def _top_measure(self) -> ufl.Measure:
        """ds with the loaded part of the top (facet midpoints at x < load_width) tagged 1."""
        top = self._top_facets()
        loaded = top[mesh.compute_midpoints(self.msh, self.fdim, top)[:, 0]
                     < self.load_width + 1e-12]
        tags = mesh.meshtags(self.msh, self.fdim, loaded, np.full(len(loaded), 1, dtype=np.int32))
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
        if self.inertia is not None:
            residuals[0] += self.inertia.residual(v)
        return residuals

    def _bcs(self, drained_top: bool) -> list[fem.DirichletBC]:
        """The rollers, the prescribed top u_y if the top is displaced, p = 0 if drained."""
        msh, W, fdim = self.msh, self.W, self.fdim
        bottom = mesh.locate_entities_boundary(msh, fdim, lambda x: np.isclose(x[1], 0.0))
        Vy = self.u.function_space.sub(1)
        bcs = [fem.dirichletbc(0.0, fem.locate_dofs_topological(Vy, fdim, bottom), Vy)]
        for k in (0, 2)[:self.gdim - 1]:  # the sides normal to x (and to z in 3D)
            sides = mesh.locate_entities_boundary(
                msh, fdim, lambda x, k=k: np.isclose(x[k], 0.0) | np.isclose(x[k], W))
            Vk = self.u.function_space.sub(k)
            bcs.append(fem.dirichletbc(0.0, fem.locate_dofs_topological(Vk, fdim, sides), Vk))
        if self.top_displacement:
            bcs.append(fem.dirichletbc(self.value, self._top_y_dofs, Vy))
        if drained_top:
            Q = self.p.function_space
            bcs.append(fem.dirichletbc(
                0.0, fem.locate_dofs_topological(Q, fdim, self._top_facets()), Q))
        return bcs

    @cached_property
    def _top_y_dofs(self) -> np.ndarray:
        """The top's y-dofs (indices into u's array)."""
        return fem.locate_dofs_topological(self.u.function_space.sub(1), self.fdim,
                                           self._top_facets())

    # Steppable --------------------------------------------------------------------------------
    def set_time(self, t):
        self.value.value = -self.load(t) if self.top_displacement else self.load(t)

    def histories(self) -> list:
        """The solid's QLV history, if it relaxes."""
        return [] if self.qlv is None else [self.qlv]

    def diagnostics(self) -> dict[str, float]:
        out = {"settlement": self.settlement(), "J_min": self.min_jacobian()[0],
               "max_J_change_lower_half": self.max_J_change(below=self.H / 2)}
        if self.top_displacement:
            out["reaction"] = self.reaction()
        if self.p is not None:
            out["core_pressure"] = self.core_pressure()
        return out

    # outputs ----------------------------------------------------------------------------------
    def strain_energy(self) -> float:
        """∫ W dX (N·mm/mm) of the elastic solid: ½ σ:ε at small strain, else W(C)."""
        if not hasattr(self, "_energy_form"):
            if self.small_strain:
                eps = ufl.sym(ufl.grad(self.u))
                W = 0.5 * ufl.inner(_small_strain_stress(self.solid, self.u), eps)
            else:
                W = mat.strain_energy_density(self.solid, deformation_gradient(self.u))
            self._energy_form = fem.form(W * ufl.dx(metadata={
                "quadrature_degree": QUADRATURE_DEGREE}))
        return self.msh.comm.allreduce(fem.assemble_scalar(self._energy_form))

    def settlement(self) -> float:
        """Mean downward displacement of the loaded part of the top (mm)."""
        area = self.load_width * (self.W if self.gdim == 3 else 1.0)
        return self.msh.comm.allreduce(fem.assemble_scalar(self._settle)) / area

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
        """J at the owned cells' centroids, and the cells' centres."""
        n = self.msh.topology.index_map(self.gdim).size_local
        cells = np.arange(n, dtype=np.int32)
        centres = self.msh.geometry.x[self.msh.geometry.dofmaps[0][cells]].mean(axis=1)
        return self._J.eval(self.msh, cells).reshape(n), centres

    def core_J_change(self) -> float:
        """max |J − 1| at the centroids of the lower half: the core, away from a drained top."""
        return self.max_J_change(below=self.H / 2)

    def max_J_change(self, below: float) -> float:
        """max |J − 1| at the centroids of the cells whose centre lies below y = `below`
        (every rank): the volume change away from a drained top's boundary layer."""
        J, centres = self._jacobians()
        local = float(np.max(np.abs(J[centres[:, 1] < below] - 1), initial=0.0))
        return self.msh.comm.allreduce(local, op=MPI.MAX)

    def pressure_nodes(self) -> tuple[np.ndarray, np.ndarray]:
        """(x, y) of the pressure nodes (mm) and p there (MPa), gathered from every rank."""
        Q, comm = self.p.function_space, self.msh.comm
        n = Q.dofmap.index_map.size_local
        X = np.concatenate(comm.allgather(Q.tabulate_dof_coordinates()[:n, :self.gdim]))
        return X, np.concatenate(comm.allgather(self.p.x.array[:n]))

    def pressure_at(self, y: np.ndarray) -> np.ndarray:
        """p along the left edge x = 0 (and z = 0) at heights y (P1: exact between its nodes)."""
        X, p = self.pressure_nodes()
        left = np.isclose(X[:, 0], 0.0) & (np.isclose(X[:, 2], 0.0) if self.gdim == 3 else True)
        order = np.argsort(X[left, 1])
        return np.interp(y, X[left, 1][order], p[left][order])

    def core_pressure(self) -> float:
        """p (MPa) at the bottom, y = 0: the point farthest from a drained top."""
        return float(self.pressure_at(np.array([0.0]))[0])


class UnconfinedBlock(ConfinedBlock):
    """Plane-strain unconfined compression of a biphasic block between frictionless,
    impermeable platens, drained at its free edge (a Mandel-type problem, under a prescribed
    platen displacement): the quarter [0, W] × [0, H] (mm) of a specimen 2W wide and 2H high.

    x = 0 and y = 0 are symmetry lines (rollers: u_x = 0, resp. u_y = 0; the bottom is also the
    mid-plane between the platens); the top is the platen, displaced uniformly downwards by
    `load(t)` (mm) with u_x free (frictionless); x = W is free and drained (p = 0); the platens
    and the symmetry lines are impermeable (zero flux, the natural condition). Every field is
    independent of y (see `unconfined_undrained_state`): one row of cells is exact in y.
    `grading` shrinks the cells towards the drained edge. The core is x < W/2 (centre x = 0).
    """

    GRADED_AXIS = 0

    def __init__(self, nx, ny, load, *, tissue, degree_u=2, width=1.0, H=1.0,
                 compaction_margin=0.02, grading=1.0, comm=MPI.COMM_SELF):
        super().__init__(nx, ny, load, tissue=tissue, degree_u=degree_u, width=width, H=H,
                         top_displacement=True, compaction_margin=compaction_margin,
                         grading=grading, comm=comm)

    def _bcs(self, drained_top: bool) -> list[fem.DirichletBC]:
        """Symmetry at x = 0 and y = 0, the platen's u_y at the top, p = 0 at the free edge."""
        msh, W = self.msh, self.W
        centre = mesh.locate_entities_boundary(msh, 1, lambda x: np.isclose(x[0], 0.0))
        bottom = mesh.locate_entities_boundary(msh, 1, lambda x: np.isclose(x[1], 0.0))
        edge = mesh.locate_entities_boundary(msh, 1, lambda x: np.isclose(x[0], W))
        Vx, Vy = self.u.function_space.sub(0), self.u.function_space.sub(1)
        Q = self.p.function_space
        return [fem.dirichletbc(0.0, fem.locate_dofs_topological(Vx, 1, centre), Vx),
                fem.dirichletbc(0.0, fem.locate_dofs_topological(Vy, 1, bottom), Vy),
                fem.dirichletbc(self.value, self._top_y_dofs, Vy),
                fem.dirichletbc(0.0, fem.locate_dofs_topological(Q, 1, edge), Q)]

    def core_pressure(self) -> float:
        """p (MPa) at the centre x = 0 (mean over its nodes; p does not depend on y)."""
        X, p = self.pressure_nodes()
        return float(np.mean(p[np.isclose(X[:, 0], 0.0)]))

    def core_J_change(self) -> float:
        """max |J − 1| at the centroids of the cells with x < W/2: the undrained core."""
        J, centres = self._jacobians()
        local = float(np.max(np.abs(J[centres[:, 0] < self.W / 2] - 1), initial=0.0))
        return self.msh.comm.allreduce(local, op=MPI.MAX)

    def diagnostics(self) -> dict[str, float]:
        return {"settlement": self.settlement(), "J_min": self.min_jacobian()[0],
                "reaction": self.reaction(), "core_pressure": self.core_pressure(),
                "core_J_change": self.core_J_change()}
