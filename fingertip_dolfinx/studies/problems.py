"""Verification problems with exact answers, shared by the tests and the stability study.

Each problem builds its mesh, forms and boundary conditions from the package's own pieces
(poroelasticity, viscoelasticity, contact, the time stepper's SNES set-up) and knows its exact
solution, so that a test and a study of the same problem measure the same thing. Units: mm, N,
s, MPa; plane strain, so forces are per unit thickness (N/mm).

- `ConfinedBlock`: a block on rollers loaded on its top (a traction strip or a displacement):
  biphasic (consolidation, creep, undrained strip load), viscoelastic (a relaxing strip) or
  hyperelastic (or, `small_strain`, exactly linear); with a `density`, dynamic (inertia.py:
  free vibration, a harmonically driven layer). A `Steppable` for `solver.TimeStepper`.
- `Terzaghi`: the drained-top consolidation column and its exact pore pressure and settlement,
  after any time t (Terzaghi's series) and after one backward-Euler step.
- `Hertz` and `HertzBlock`: a rigid cylinder pressed into a linear-elastic half block with
  Nitsche contact, and the plane-strain Hertz half-width and peak pressure. `HertzSphere`: the
  3D case, a rigid sphere on a quarter block (two symmetry planes), Hertz's contact radius and
  peak pressure (forces in N).
- `layered_block`: a synthetic 3D `FingertipMesh`, the four tissues as horizontal slabs of a
  half block with the fingertip's tags (pulp below, nail centre strip on top, symmetry and
  proximal-cut planes): the 3D problem's wiring without the fingertip geometry.
- `VibratingLayer`: a viscoelastic hyperfoam layer on a rigid base, laterally confined, its
  top shaken harmonically: the standing wave of uniaxial strain in closed form, the exact check
  of the frequency-domain route (`harmonic`: G*(ω), the mass, the real block form).
- Closed forms: `confined_modulus`, `confined_drained_stress`, `prony_ramp_integral`; for
  dynamics the harmonically driven layer (`driven_layer`, `driven_layer_force`; the
  complex modulus is `harmonic.complex_modulus`).
- Wiring: `newton_problem` (a NonlinearProblem with the solver's SNES set-up),
  `support_reaction`, `contact_edge`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import ClassVar, NamedTuple

import numpy as np
import ufl
from dolfinx import fem, mesh
from dolfinx.fem.petsc import NonlinearProblem
from mpi4py import MPI

from .. import materials as mat
from ..admissibility import Admissibility, Compaction
from ..contact import NitscheContact, Obstacle
from ..harmonic import Linearisation, ViscousPart, complex_modulus, qlv_tangent
from ..indenters import Cylinder, Sphere
from ..inertia import Inertia
from ..kinematics import deformation_gradient
from ..loading import RampHold
from ..mesh import CELL_TAGS, FACET_TAGS_3D, FingertipMesh
from ..poroelasticity import biphasic_residuals
from ..solver import DEFAULT_PETSC_OPTIONS, StepOptions, TimeStepper
from ..state import SteppableState
from ..viscoelasticity import QuasiLinearViscoelasticity

#: Quadrature degree of the block's volume terms: the hyperfoam stress is not polynomial.
QUADRATURE_DEGREE = 4


# ---- closed forms ----------------------------------------------------------------------------


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


class PlatenState(NamedTuple):
    """A homogeneous plane-strain state under platens: stretches across (x) and along (y) the
    platens' travel, J = λx λy, the pore pressure p (MPa) and the total nominal stress P22
    (MPa: the platen force per unit reference width, negative in compression)."""

    stretch_x: float
    stretch_y: float
    J: float
    pressure: float
    P22: float


def confined_drained_state(solid, lam: float) -> PlatenState:
    """The drained end of confined compression to the stretch λ (`confined_drained_stress`):
    F = diag(1, λ), p = 0, P22 = τ2/λ."""
    return PlatenState(1.0, lam, lam, 0.0, float(confined_drained_stress(solid, lam)[1]))


def unconfined_undrained_state(solid, lam: float) -> PlatenState:
    r"""The undrained state of plane-strain unconfined compression between frictionless
    platens at the platen stretch λy = `lam`: the core of a specimen loaded faster than it
    drains.

    Frictionless platens moved uniformly leave every field independent of y (u_y = (λy − 1) y
    exactly), so the problem is one-dimensional in x: σ_xy = 0 and equilibrium ∂σ_xx/∂x = 0
    with a traction-free edge give σ_xx = 0 everywhere. The mixture's Cauchy stress is
    σ = τ(F)/J − p I, τ_a = Σ_i (2μ_i/α_i)(λ_a^α_i − J^(−α_i β_i)) the hyperfoam's principal
    Kirchhoff stresses (λ3 = 1, plane strain). Where no fluid has left, J = λx λy = 1, so

        λx = 1/λy,   p = τ1 = Σ_i (2μ_i/α_i)(λy^(−α_i) − 1)        (σ_xx = τ1 − p = 0),
        P22 = J σ_yy / λy = (τ2 − τ1)/λy,   τ2 = Σ_i (2μ_i/α_i)(λy^α_i − 1).

    At J = 1 the volume term is 1 for every β_i: the undrained response does not depend on ν.
    Displacement control makes it exact until the drainage front sqrt(c t) (c = k M) reaches
    the point: no Mandel–Cryer rise (that needs a prescribed force).
    """
    stretches = np.array([1.0 / lam, lam, 1.0])
    tau = solid.principal_kirchhoff(stretches)
    return PlatenState(1.0 / lam, lam, 1.0, float(tau[0]), float((tau[1] - tau[0]) / lam))


def unconfined_drained_state(solid, lam: float) -> PlatenState:
    r"""The drained end (p = 0) of plane-strain unconfined compression between frictionless
    platens at the platen stretch λy = `lam`.

    As in `unconfined_undrained_state` σ_xx = 0 everywhere; with p = 0 the solid alone is
    free across: τ1(λx, λy, 1) = Σ_i (2μ_i/α_i)(λx^α_i − (λx λy)^(−α_i β_i)) = 0. For λy < 1
    τ1 < 0 at λx = 1 (the volume term pushes out; λ0 ln λy at small strain) and τ1 > 0 at
    λx = 1/λy (J = 1), so Brent's method finds λx between them (to round-off). ν = 0 (every
    β_i = 0): τ1 = Σ (2μ_i/α_i)(λx^α_i − 1) vanishes at λx = 1: no lateral expansion at all,
    the foam's signature. Then J = λx λy and P22 = J σ_yy/λy = τ2/λy.
    """
    from scipy.optimize import brentq

    def tau_x(lx: float) -> float:
        return float(solid.principal_kirchhoff(np.array([lx, lam, 1.0]))[0])

    low, high = sorted((1.0, 1.0 / lam))
    if tau_x(low) == 0.0:
        lx = low
    elif tau_x(high) == 0.0:
        lx = high
    else:
        lx = brentq(tau_x, low, high, xtol=1e-15, rtol=4 * np.finfo(float).eps)
    tau = solid.principal_kirchhoff(np.array([lx, lam, 1.0]))
    return PlatenState(lx, lam, lx * lam, 0.0, float(tau[1] / lam))


def prony_ramp_integral(prony, t: float, T: float = 1.0) -> float:
    """∫_0^min(t,T) g(t − s) ds (s), g(t) = g∞ + Σ g_i exp(−t/τ_i) the relaxation function.

    The QLV stress is the hereditary integral S(t) = ∫ g(t − s) dS_e(s); for S_e ramped linearly
    to S_e(T) over [0, T] and then held, S(t) = S_e(T)/T times this integral, exactly.
    """
    t1 = min(t, T)
    return prony.g_inf * t1 + sum(g * tau * (np.exp(-(t - t1) / tau) - np.exp(-t / tau))
                                  for g, tau in zip(prony.g, prony.tau))


def driven_layer(y, H: float, omega: float, density: float, modulus: complex) -> np.ndarray:
    r"""u(y)/U of a uniform layer 0 ≤ y ≤ H held at y = 0 and displaced U e^{iωt} at y = H,
    laterally confined (a one-dimensional P-wave), in the steady state:

        M* u'' + ρ ω² u = 0,  u(0) = 0, u(H) = U  ⇒  u(y) = U sin(k y)/sin(k H),

    k = ω sqrt(ρ/M*), M* the complex confined modulus (M0 G*(ω) for a QLV solid). Complex:
    the amplitude and phase relative to the drive (either root k: the ratio is even in k)."""
    k = omega * np.sqrt(density / complex(modulus))
    return np.sin(k * np.asarray(y, dtype=float)) / np.sin(k * H)


def driven_layer_force(H: float, omega: float, density: float, modulus: complex) -> complex:
    """The top traction σ_yy(H)/U = M* k cos(kH)/sin(kH) (MPa/mm) of `driven_layer`: the force
    per unit width that holds the driven top, per unit drive amplitude."""
    k = omega * np.sqrt(density / complex(modulus))
    return complex(modulus) * k * np.cos(k * H) / np.sin(k * H)


# ---- wiring ----------------------------------------------------------------------------------


def graded(s: np.ndarray, ratio: float) -> np.ndarray:
    """s ∈ [0, 1] mapped so that equal cells in s shrink geometrically towards s = 1, the
    first `ratio` times the last (1: unchanged): 1 − (e^(g(1 − s)) − 1)/(e^g − 1), g = ln ratio.
    A drained boundary's layer, ~sqrt(c t) thick at first, needs the small cells."""
    if ratio == 1.0:
        return s
    g = math.log(ratio)
    return 1.0 - np.expm1(g * (1.0 - s)) / math.expm1(g)


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


# ---- the canonical biphasic benchmarks: a platen ramp, then hold ---------------------------------


@dataclass(frozen=True)
class PlatenRelaxation:
    """A Holmes–Mow tissue (the paper's κ and M, permeability `k0` at J = 1, the hyperfoam
    `solid`) compressed by a platen to `strain` (of the height) in a linear ramp, then held:
    stress relaxation. Times scale with the consolidation time t_c = L²/(k0 M), M = K0 + 4μ0/3
    the confined modulus and L the drainage length: the ramp lasts `ramp` t_c, the run `end`
    t_c. Subclasses fix the geometry (`ConfinedRelaxation`, `UnconfinedRelaxation`), their
    block and their exact limits.
    """

    solid: mat.Hyperfoam = mat.SUBCUTANEOUS
    k0: float = 1.0  # mm⁴/(N·s)
    strain: float = 0.1
    ramp: float = 0.002
    end: float = 12.0
    length: float = 1.0  # mm: the drainage length L
    height: float = 1.0  # mm: the height the platen compresses

    @property
    def tissue(self) -> mat.Biphasic:
        hm = mat.HOLMES_MOW_SUBCUTANEOUS
        return mat.Biphasic(self.solid, mat.HolmesMow(k0=self.k0, phi0=hm.phi0,
                                                      kappa=hm.kappa, M=hm.M))

    @property
    def consolidation_time(self) -> float:
        """t_c = L²/(k0 M) (s)."""
        return self.length**2 / (self.k0 * confined_modulus(self.solid))

    @property
    def history(self) -> RampHold:
        """The platen's travel (mm) against time (s)."""
        tc = self.consolidation_time
        return RampHold(self.strain * self.height, self.ramp * tc, self.end * tc)

    @property
    def stretch(self) -> float:
        return 1.0 - self.strain

    def slowest_rate(self) -> float:
        """λ1 = (π/2)² c/L² (1/s): the decay rate of the slowest consolidation mode near the
        drained end (one drained side, L the drainage length), c the end state's
        consolidation coefficient (`consolidation_coefficient`)."""
        return (math.pi / 2) ** 2 * self.consolidation_coefficient() / self.length**2

    def end_tolerance(self, excess: float, steps: np.ndarray) -> float:
        """A bound on |F/F_drained − 1| at the end of a run: the drained end state is
        homogeneous (u linear, p = 0), so P2/P1 holds it exactly and the mesh adds nothing;
        what is left is the slowest consolidation mode, at most the relative excess force
        `excess` at the ramp's end, decayed by backward Euler's Π (1 + λ1 Δt_i)⁻¹ over the
        hold's `steps` (slower than e^(−λ1 t)); twice that, for the modes' nonlinear mixing."""
        decay = float(np.prod(1.0 / (1.0 + self.slowest_rate() * np.asarray(steps))))
        return 2.0 * abs(excess) * decay


@dataclass(frozen=True)
class ConfinedRelaxation(PlatenRelaxation):
    """Confined compression (the column of `ConfinedBlock`, `length` = its height, drained on
    top, 0.1 mm wide) by a displacement ramp, then held.

    Exact limits: at the end, drained, the homogeneous state F = diag(1, λ) with p = 0 and the
    force −P22 W of `confined_drained_state`. At the start, undrained: a confined piece of
    tissue that keeps its volume cannot deform, so below the drainage front (~sqrt(c t) under
    the drained top) J = 1 and the solid is unstressed: the fluid carries the whole load,
    p(bottom) = F/W. The layer above the front takes the whole travel; the linear solution
    for a displacement ramp u = V t into a drained half-space puts its top strain at
    2 V sqrt(t/(π c)), i.e. 2ε/sqrt(π τ0) at the ramp's end (τ0 = t0/t_c): a fast ramp
    compacts the top (issue 11). The defaults balance the two: τ0 = 0.002 keeps the lower
    half undrained to e^(−1/(16 τ0)) ≈ 3e-14 and a 1 % strain puts the top strain near 0.25.
    """

    strain: float = 0.01
    width: float = 0.1

    def block(self, n: int, grading: float = 1.0, comm=MPI.COMM_SELF) -> ConfinedBlock:
        return ConfinedBlock(1, n, self.history, tissue=self.tissue, width=self.width,
                             H=self.length, drained_top=True, top_displacement=True,
                             grading=grading, comm=comm)

    def drained(self) -> PlatenState:
        return confined_drained_state(self.solid, self.stretch)

    def consolidation_coefficient(self) -> float:
        """c = k(λ) P22'(λ)/λ (mm²/s) at the drained end: with J = λ and the total P22 =
        P_s(λ) − p uniform, the mass balance ∂λ/∂t = ∂/∂Y((k/λ) ∂p/∂Y) is a diffusion of λ
        with this coefficient (P_s' by central differences of the closed form)."""
        lam, h = self.stretch, 1e-6

        def P(x):
            return confined_drained_state(self.solid, x).P22

        slope = (P(lam + h) - P(lam - h)) / (2 * h)
        return float(self.tissue.permeability.permeability_np(lam)) * slope / lam

    def drained_force(self) -> float:
        """The platen force at the drained end (N/mm, compressive positive)."""
        return -self.drained().P22 * self.width


@dataclass(frozen=True)
class UnconfinedRelaxation(PlatenRelaxation):
    """Plane-strain unconfined compression between frictionless impermeable platens with a
    drained free edge (`UnconfinedBlock`: `length` = the half-width W, `height` = the half
    height), by a displacement ramp, then held.

    Exact limits: at the end of a fast ramp the core (x < W/2) is undrained: p equals
    `unconfined_undrained_state`'s (the front sqrt(c t0) = sqrt(τ0) W leaves the centre
    undrained to e^(−1/(16 τ0))); at long times the force equals
    `unconfined_drained_state`'s −P22 W. The free edge is drained from the start, at the
    drained lateral stretch: J there is the drained J, no compaction however fast the ramp.
    """

    height: float = 0.25

    def block(self, n: int, grading: float = 1.0, comm=MPI.COMM_SELF) -> UnconfinedBlock:
        return UnconfinedBlock(n, 1, self.history, tissue=self.tissue, width=self.length,
                               H=self.height, grading=grading, comm=comm)

    def undrained(self) -> PlatenState:
        return unconfined_undrained_state(self.solid, self.stretch)

    def drained(self) -> PlatenState:
        return unconfined_drained_state(self.solid, self.stretch)

    def consolidation_coefficient(self) -> float:
        """c = k(J) P11'(λx)/J (mm²/s) at the drained end: with λy fixed, J = λx λy and the
        total P11 = P_s(λx) − p λy = 0, the mass balance λy ∂λx/∂t = ∂/∂X((J k/λx²) ∂p/∂X)
        is a diffusion of λx with this coefficient (P_s = τ1/λx, by central differences)."""
        end = self.drained()
        lx, ly, h = end.stretch_x, end.stretch_y, 1e-6

        def P(x):
            return float(self.solid.principal_kirchhoff(np.array([x, ly, 1.0]))[0]) / x

        slope = (P(lx + h) - P(lx - h)) / (2 * h)
        return float(self.tissue.permeability.permeability_np(end.J)) * slope / end.J

    def drained_force(self) -> float:
        """The platen force at the drained end (N/mm over the half-width, compressive > 0)."""
        return -self.drained().P22 * self.length


@dataclass
class RelaxationRun:
    """One run's histories (one entry per accepted step, after t = 0): time (s), platen force
    (N/mm, compressive positive), core pressure (MPa), max |J − 1| in the core, min J; and its
    cost: steps, Newton iterations, step cuts, wall time of the stepping (s)."""

    time: np.ndarray
    force: np.ndarray
    core_pressure: np.ndarray
    core_J_change: np.ndarray
    J_min: np.ndarray
    steps: int
    newton_iterations: int
    cuts: int
    wall_time_s: float

    def at(self, t: float) -> int:
        """The index of the step that ended at t (the stepper lands on breakpoints)."""
        i = int(np.argmin(np.abs(self.time - t)))
        if not abs(self.time[i] - t) <= 1e-9 * max(1.0, abs(t)):
            raise ValueError(f"no step ended at t = {t} s")
        return i


def run_relaxation(problem: PlatenRelaxation, block: ConfinedBlock, options: StepOptions,
                   petsc_options: dict | None = None, sample_times=(), prefix: str = "relax_"
                   ) -> RelaxationRun:
    """Step `block` along `problem`'s history with `options`, landing on `sample_times` (and
    the ramp's end); returns the histories and the cost."""
    import time as wallclock

    history = problem.history
    stepper = TimeStepper(block, options, petsc_options, prefix=prefix)
    rows = []

    def record(report):
        d = report.diagnostics
        rows.append((report.time, -d["reaction"], d["core_pressure"], block.core_J_change(),
                     d["J_min"], report.newton_iterations, report.cuts))

    started = wallclock.perf_counter()
    try:
        stepper.run(history, history.end_time, breakpoints=sorted(sample_times),
                    on_step=record)
    finally:
        wall = wallclock.perf_counter() - started
        stepper.close()
    a = np.array(rows)
    return RelaxationRun(a[:, 0], a[:, 1], a[:, 2], a[:, 3], a[:, 4], len(rows),
                         int(a[:, 5].sum()), int(a[:, 6].sum()), wall)


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
              modulus=None) -> HertzBlock:
        """The P2 displacement, the cylinder (touching at y = 0), the contact terms with
        γ = γ0 modulus/h (modulus: `self.modulus` unless given, e.g. a Constant to sweep γ0
        without recompiling), the residual and the supports."""
        V, u, P, obstacle, contact, residual = _contact_on_block(
            self, domain, facet_tags, Cylinder(radius=self.R), theta, gamma0, modulus)
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


def _contact_on_block(hertz, domain, facet_tags, indenter, theta: int, gamma0: float, modulus):
    """The Hertz blocks' common part (2D and 3D): P2 displacement, `hertz.stress`, the
    indenter touching at y = 0 on the BOTTOM facets, the Nitsche terms and the residual."""
    V = fem.functionspace(domain, ("Lagrange", 2, (domain.geometry.dim,)))
    u, v = fem.Function(V), ufl.TestFunction(V)
    P = hertz.stress(u)
    obstacle = Obstacle.at(domain, indenter, y_tip=0.0)
    ds = ufl.Measure("ds", domain, subdomain_data=facet_tags)
    contact = NitscheContact(u, P, ds(hertz.BOTTOM), [obstacle],
                             modulus=hertz.modulus if modulus is None else modulus,
                             theta=theta, gamma0=gamma0)
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


# ---- a layered 3D block with the fingertip's tags ---------------------------------------------

#: Slab tops (mm) of the layered block from its bottom y = −3: skin 0.5 mm, subcutaneous 3 mm,
#: bone 0.5 mm, nail 0.5 mm (round numbers of the section's proportions, not its geometry).
LAYERS = (("skin", -2.5), ("subcutaneous", 0.5), ("bone", 1.0), ("nail", 1.5))


def layered_block(comm=MPI.COMM_SELF, *, half_width: float = 3.0, length: float = 6.0,
                  cells_per_mm: float = 2.0, centre_half_width: float = 1.0) -> FingertipMesh:
    """The half block [0, half_width] × [−3, 1.5] × [0, length] (mm) of tetrahedra, its cells
    tagged as the slabs of `LAYERS` and its facets as the fingertip's: pulp_surface (y = −3,
    where indenters act), nail_centre (the top's strip x < centre_half_width), symmetry
    (x = 0), proximal_cut (z = 0), outer_surface (the rest). 2 cells per mm put every slab
    boundary on a cell layer."""
    y0, y1 = -3.0, LAYERS[-1][1]
    n = [max(1, round(d * cells_per_mm)) for d in (half_width, y1 - y0, length)]
    msh = mesh.create_box(comm, [[0.0, y0, 0.0], [half_width, y1, length]], n,
                          mesh.CellType.tetrahedron)
    tdim = msh.topology.dim
    cells = np.arange(msh.topology.index_map(tdim).size_local
                      + msh.topology.index_map(tdim).num_ghosts, dtype=np.int32)
    y = mesh.compute_midpoints(msh, tdim, cells)[:, 1]
    tops = np.array([top for _, top in LAYERS])
    regions = np.array([CELL_TAGS[name] for name, _ in LAYERS])[np.searchsorted(tops, y)]
    cell_tags = mesh.meshtags(msh, tdim, cells, regions.astype(np.int32))
    facet_tags = mesh.meshtags(msh, tdim - 1, *_block_facets(msh, y0, y1, centre_half_width))
    names = {**CELL_TAGS, **{k: FACET_TAGS_3D[k] for k in (
        "pulp_surface", "outer_surface", "nail_centre", "symmetry", "proximal_cut")}}
    return FingertipMesh(msh, cell_tags, facet_tags, names)


def _block_facets(msh, y0: float, y1: float, centre_half_width: float):
    """(sorted exterior facets, their tags) of `layered_block`."""
    fdim = msh.topology.dim - 1
    msh.topology.create_connectivity(fdim, fdim + 1)
    facets = mesh.exterior_facet_indices(msh.topology)
    x = mesh.compute_midpoints(msh, fdim, facets)
    tags = np.full(len(facets), FACET_TAGS_3D["outer_surface"], dtype=np.int32)
    for name, on in (("symmetry", np.isclose(x[:, 0], 0.0)),
                     ("proximal_cut", np.isclose(x[:, 2], 0.0)),
                     ("pulp_surface", np.isclose(x[:, 1], y0)),
                     ("nail_centre", np.isclose(x[:, 1], y1) & (x[:, 0] < centre_half_width))):
        tags[on] = FACET_TAGS_3D[name]
    return facets.astype(np.int32), tags


# ---- the vibrating layer (frequency domain) ----------------------------------------------------


class VibratingLayer:
    """A QLV hyperfoam layer [0, W] × [0, H] on a rigid base (u = 0 at y = 0), on rollers
    (u_x = 0 on the sides: uniaxial strain), its top loaded by a uniform harmonic traction;
    linearised at rest (C = I) for `harmonic.HarmonicSolver`.

    Exact: ρ (iω)² u = M* u'' with M*(ω) = M0 G*(ω), M0 = K0 + 4μ0/3 the hyperfoam's confined
    modulus at C = I (`confined_modulus`) and G* the Prony complex modulus; u(0) = 0 gives
    u(y) = U sin(k y)/sin(k H), k = ω sqrt(ρ/M*), and the traction the top needs per unit top
    displacement is the dynamic stiffness M* k cot(k H) (MPa/mm). The layer is driven by a unit
    traction and its output is the mean top displacement, so the computed stiffness is
    1/output (the same operator as a displacement drive; a traction drive keeps the drive a
    right-hand side, as the fingertip's is).
    """

    def __init__(self, solid, prony, density: float, *, H: float = 5.0, width: float = 0.25,
                 cells: int = 40, degree: int = 2, comm=MPI.COMM_SELF):
        self.solid, self.prony, self.rho, self.H, self.W = solid, prony, density, H, width
        self.msh = mesh.create_rectangle(comm, [[0.0, 0.0], [width, H]], [1, cells])
        V = fem.functionspace(self.msh, ("Lagrange", degree, (2,)))
        self.V, self.u = V, fem.Function(V)
        self.qlv = QuasiLinearViscoelasticity(
            mat.second_piola_kirchhoff(solid, deformation_gradient(self.u)), prony, self.msh,
            QUADRATURE_DEGREE, 1.0)

    def _bcs(self) -> list:
        V, fdim = self.V, 1
        base = mesh.locate_entities_boundary(self.msh, fdim, lambda x: np.isclose(x[1], 0.0))
        sides = mesh.locate_entities_boundary(
            self.msh, fdim, lambda x: np.isclose(x[0], 0.0) | np.isclose(x[0], self.W))
        side_dofs = fem.locate_dofs_topological(V.sub(0), fdim, sides)
        return [fem.dirichletbc(np.zeros(2), fem.locate_dofs_topological(V, fdim, base), V),
                fem.dirichletbc(0.0, side_dofs, V.sub(0))]

    def linearisation(self) -> Linearisation:
        u, V = self.u, self.V
        v, du = ufl.TestFunction(V), ufl.TrialFunction(V)
        dx = ufl.dx(metadata=self.qlv.metadata)
        geometric, material = qlv_tangent(self.qlv, deformation_gradient(u), u, du, v, dx)
        top = mesh.locate_entities_boundary(self.msh, 1, lambda x: np.isclose(x[1], self.H))
        tags = mesh.meshtags(self.msh, 1, top, np.ones_like(top))
        ds = ufl.Measure("ds", domain=self.msh, subdomain_data=tags)(1)
        return Linearisation(
            unknowns=[u], K=[[geometric]], M=[[self.rho * ufl.inner(du, v) * dx]], B=[[None]],
            viscous=[ViscousPart([[material]], self.prony)], drive=[v[1] * ds],
            force=[v[1] / self.W * ds], bcs=self._bcs())

    def modulus(self, frequency: float) -> complex:
        """M*(ω) = M0 G*(ω), the complex confined modulus (MPa)."""
        omega = 2 * math.pi * frequency
        return confined_modulus(self.solid) * complex_modulus(self.prony, omega)

    def exact_stiffness(self, frequency: float) -> complex:
        """M* k cot(k H): the top traction per unit top displacement (MPa/mm)."""
        return driven_layer_force(self.H, 2 * math.pi * frequency, self.rho,
                                  self.modulus(frequency))

    def exact_profile(self, y: np.ndarray, frequency: float) -> np.ndarray:
        """u_y(y) per unit top displacement: sin(k y)/sin(k H)."""
        return driven_layer(y, self.H, 2 * math.pi * frequency, self.rho, self.modulus(frequency))
