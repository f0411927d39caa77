r"""The coupled fingertip problem on the tagged mesh: unknowns, residuals, supports and loads.

Unknowns: the displacement u on the whole section (Lagrange degree k, vector) and, when the
subcutaneous tissue has a pore law (biphasic or undrained), the pore pressure p on the
subcutaneous region only (degree k − 1 on a submesh: Taylor–Hood where it matters, no pressure
unknowns in skin, bone or nail). One backward-Euler step solves

    Σ_r ∫_r P_r : Grad v dX − ∫_sub p J F⁻ᵀ : Grad v dX − ∫_pulp p_c n·v dS = 0     for all v,
    ∫_sub (J − J_n) q + Δt J k(J) C⁻¹ Grad p · Grad q dX                  = 0     for all q,

with P_r the first Piola–Kirchhoff stress of region r's law (model.py: P_skin = F S, S the QLV
history of the hyperfoam stress; P_sub the drained hyperfoam stress of the solid; bone and nail
St Venant–Kirchhoff; rigid regions 0) and p_c the Nitsche contact pressure of the rigid
indenters on the pulp (contact.py). Undrained, the mass balance is ∫_sub (J − J_n) q dX = 0.
A BDF2 step (stepping.StepOptions.scheme) replaces the biphasic J − J_n by a₀ J + a₁ J_n +
a₂ J_{n−1} (`rate_weights`, `u_nm1`); every other part is quasi-static or keeps its own exact
recursion (the skin's QLV history).
Every boundary not in contact is traction-free; the subcutaneous boundary is impermeable (zero
flux is the natural condition).

The residual is assembled from named parts: `_region_stresses`, `_pressure`, `_contact`, and
the `_support`:

Support: the `nail_centre` patch (a short arc at the top of the nail, centred on the point the
paper fixes; in 3D a strip along the nail's top) is clamped in every component. A single fixed
point would leave the rigid rotation about
it free; clamping the short patch of the 170 MPa nail removes it and exerts no force of its
own: at equilibrium its reaction equals the indenter force, and for a load on the symmetry
line its moment is zero. If a region is rigid (bone, nail), its nodes are clamped instead and
hold the body. The reaction is the residual tested with e_y on all clamped dofs.
3D meshes may carry two more supports, rollers that exert no y-force: `proximal_cut` (the
plane z = 0 where the model is cut from the rest of the finger, which continues beyond it):
u_z = 0; `symmetry` (the mid-sagittal plane x = 0 of a half model): u_x = 0. A half model's
forces and reaction are half the whole finger's (`mirror_factor` = 2 gives the whole).

Units: forces in N/mm in plane strain (per unit length of finger), in N in 3D; the diagnostics
name them accordingly (`force_keys`).

Inertia (`ModelOptions.inertia`, a dynamic run): the momentum balance gains `_inertia`,
Σ_r ∫_r ρ_r [(1 − α_m) a_{n+1} + α_m a_n]·v dX with a_{n+1} from Newmark's update
(inertia.py: the Wood–Bossak–Zienkiewicz method, which the time stepper's "generalized-alpha"
scheme drives); every other part is unchanged and stays at t_{n+1}. Off, the forms are the
quasi-static ones term for term.

The admissibility checks of a converged state (inverted elements, compaction) are in
admissibility.py.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from functools import cached_property

import numpy as np
import ufl
from dolfinx import fem, jit
from dolfinx import mesh as dmesh
from mpi4py import MPI

from .errors import InputError
from .force_control import DepthControl
from .geometry.indenters import Indenter
from .geometry.mesh import FingertipMesh
from .loading import History, check_tangential_path
from .model import ModelOptions, State, compose_laws
from .physics.admissibility import Admissibility, Compaction, from_holder
from .physics.contact import (
    TIP_PENETRATION_TOLERANCE,
    NitscheContact,
    Obstacle,
    TipResolutionWarning,
    check_tip_resolution,
)
from .physics.friction import CoulombFriction, check_dynamic_contact, friction_coefficients
from .physics.inertia import Inertia
from .physics.kinematics import deformation_gradient
from .physics.tissues import REGIONS, WU2004, Tissues
from .state import SteppableState

#: Points per surface facet at which the deformed pulp is sampled to find a tip's depth.
TIP_SAMPLES = 9
#: The tags a fingertip mesh must carry.
REQUIRED_TAGS = (*REGIONS, "pulp_surface", "nail_centre")
DEFAULT_OPTIONS = ModelOptions()
#: How long (s) a process waits for a form another process is compiling: FFCx's default, 10 s,
#: is far shorter than a compile on a busy machine (a 3D Newton form takes minutes). Runs side
#: by side under MPI (`runner.run_side_by_side`: the 3D acuity study, sweeps) compile the same
#: forms at once on a cold cache; with 10 s one rank gave up on the shared reaction form and waited
#: in a collective until the other rank's runs ended. The container's setting too.
JIT_WAIT = 1800
#: See `FingertipProblem.jit_options`.
JIT_OPTIONS_3D = {"cffi_extra_compile_args": ["-O1", "-g0"], "timeout": JIT_WAIT}


def expands_stress(gdim: int, options: ModelOptions) -> bool:
    """Whether the hyperfoam's stress is expanded about a copy of the state (materials.
    second_piola_kirchhoff): equal in value and first derivative, and its Jacobian kernel far
    shorter (docs/benchmarks/solvers-3d.md, "The Jacobian's assembly"). 3D only (2D's forms
    stay as they were, bit for bit), and not with Nitsche's θ ≠ 0, whose residual holds the
    stress's derivative: its Jacobian needs the second, which the expansion does not keep."""
    nitsche_derivative = options.contact == "nitsche" and options.contact_theta != 0
    return gdim == 3 and not nitsche_derivative


def wait_for_compiles_elsewhere(seconds: float = JIT_WAIT) -> None:
    """Make every form compiled from now on in this process wait up to `seconds` for another
    process compiling the same form (DOLFINx's default JIT option; a user's
    `dolfinx_jit_options.json` still takes precedence)."""
    value, doc = jit.DOLFINX_DEFAULT_JIT_OPTIONS["timeout"]
    jit.DOLFINX_DEFAULT_JIT_OPTIONS["timeout"] = (max(value, seconds), doc)


#: Under force control: the diagnostics' (and history.csv's) name of the target normal force
#: in plane strain (3D: `FingertipProblem.target_key`).
TARGET_KEY = "normal_force_target_N_per_mm"
#: With friction, 3D: the diagnostics' names of the contact area (p > 0) and the stick area.
AREA_KEYS = ("contact_area_mm2", "stick_area_mm2")


def _check_inputs(fmesh: FingertipMesh, indenters: Sequence[Indenter]) -> None:
    if not indenters:
        raise InputError("scene.indenters", "no indenter given.", "give at least one.")
    for name in REQUIRED_TAGS:
        if name not in fmesh.names:
            raise InputError("mesh", f"the tag {name!r} is missing.", "rebuild the mesh.")


def check_tangential(fmesh: FingertipMesh, history) -> None:
    """`loading.check_tangential_path` for this mesh (a half model has a `symmetry` plane)."""
    check_tangential_path(history, fmesh.mesh.geometry.dim, "symmetry" in fmesh.names)


class FingertipProblem(SteppableState):
    """Forms, unknowns, supports and loads of the fingertip under rigid indenters.

    The indenters move together as one rigid holder along the protocol. Implements the
    `stepping.Steppable` protocol: `TimeStepper` advances it in time;
    its state bookkeeping (accept, restore, the state arrays, admissibility) is
    `state.SteppableState`.

    Parameters
    ----------
    fmesh : FingertipMesh
        The tagged mesh (`build_mesh`, `build_mesh3d`).
    indenters : sequence of Indenter
        The rigid indenters.
    history : LoadHistory or callable
        The indentation d(t) (mm after first touch) as a function of time (s).
    tissues : Tissues, optional
        The materials of the four regions.
    options : ModelOptions, optional
        The modelling and discretisation choices.
    friction : float or sequence of float, optional
        Coulomb's μ, one for all indenters or one each (0, the default: frictionless, the
        forms exactly those without friction). A `loading.TangentialPath` history moves the
        indenters along x as well.
    """

    def __init__(
        self,
        fmesh: FingertipMesh,
        indenters: Sequence[Indenter],
        history: History,
        tissues: Tissues = WU2004,
        options: ModelOptions = DEFAULT_OPTIONS,
        friction=0.0,
    ):
        _check_inputs(fmesh, indenters)
        check_tangential(fmesh, history)
        wait_for_compiles_elsewhere()
        #: μ per indenter (0: frictionless, the default; physics/friction.py).
        self.friction_coefficients = friction_coefficients(friction, len(indenters))
        check_dynamic_contact(options.contact, options.contact_theta, options.inertia,
                              self.friction_coefficients)
        self.fmesh, self.history, self.tissues, self.options = fmesh, history, tissues, options
        self.indenters = list(indenters)
        self.mesh = msh = fmesh.mesh
        self.tags = fmesh.names
        self.dt = fem.Constant(msh, 1.0)
        self.dx = ufl.Measure("dx", domain=msh, subdomain_data=fmesh.cell_tags,
                              metadata={"quadrature_degree": options.quadrature_degree})
        self.ds = ufl.Measure("ds", domain=msh, subdomain_data=fmesh.facet_tags)
        self.gdim = msh.geometry.dim
        #: Compiler flags of the Newton forms (stepping.TimeStepper passes them on): None, the
        #: defaults, in 2D. The 3D hyperfoam's Jacobian (three principal stretches with their
        #: series branches, per region) is a long C function (13 500 lines since its stress is
        #: expanded in invariants, 74 000 before): gcc compiles it faster at -O1 than at -O2,
        #: and -O2's code is no faster (times: docs/benchmarks/measurements.md).
        self.jit_options = JIT_OPTIONS_3D if self.gdim == 3 else None
        self._unknowns_u()
        cells = {r: fmesh.cell_tags.find(self.tags[r]) for r in REGIONS}
        self.laws = compose_laws(tissues, options, State(
            self.u, self.F, self.dt, options.quadrature_degree, cells,
            None if self.u_state is None else deformation_gradient(self.u_state)))
        self._residual(cells["subcutaneous"])
        self.admissibility = self._admissibility(cells["subcutaneous"])
        self.time = 0.0
        #: Force control (force_control.py): the depth found per step, or None.
        target = getattr(history, "normal_force", None)
        self.force_control = None if target is None else DepthControl(
            target, history, self.normal_force, lambda: self.time, self.mirror_factor,
            "N" if self.gdim == 3 else "N/mm")
        self.mark_accepted()

    def _unknowns_u(self) -> None:
        """The displacement, its two earlier accepted values and F."""
        self.V = fem.functionspace(self.mesh, ("Lagrange", self.options.displacement_degree,
                                               (self.gdim,)))
        self.u = fem.Function(self.V, name="displacement")
        self.u_n = fem.Function(self.V, name="displacement_n")
        #: u at t_{n−1} and the weights (a₀, a₁, a₂) of J_{n+1}, J_n, J_{n−1} in Δt·dJ/dt of
        #: the biphasic mass balance: backward Euler (1, −1, 0) until the time stepper sets
        #: BDF2's (stepping.bdf2_weights). A Constant: switching schemes never recompiles.
        self.u_nm1 = fem.Function(self.V, name="displacement_nm1")
        self.rate_weights = fem.Constant(self.mesh, np.array([1.0, -1.0, 0.0]))
        self.F = deformation_gradient(self.u)
        #: 3D: u's values under another name (the same vector), which ufl.derivative does not
        #: differentiate: the hyperfoam's stress is expanded about it (`expands_stress`).
        self.u_state = fem.Function(self.V, x=self.u.x, name="displacement_state") \
            if expands_stress(self.gdim, self.options) else None

    def _residual(self, sub_cells: np.ndarray) -> None:
        """The residuals from their named parts, the unknowns, the supports and the reaction."""
        v = ufl.TestFunction(self.V)
        R_u = self._region_stresses(v)
        coupling, residuals_p = self._pressure(v, sub_cells)
        #: The pore pressure's term in the momentum balance (None without a pore law).
        self.pressure_coupling = coupling
        if coupling is not None:
            R_u += coupling
        R_u += self._contact(v)
        self.inertia = None
        if self.options.inertia:  # no new term at all in a quasi-static run
            R_u += self._inertia(v)
        self.residuals = [R_u, *residuals_p]
        self.unknowns = [self.u] + ([self.p] if self.p is not None else [])
        self.bcs, self._reaction_form = self._support(R_u, v)

    def _admissibility(self, sub_cells: np.ndarray) -> Admissibility:
        """The checks of a state: J > 0 everywhere, and with a pore law, J above compaction."""
        pore = self.laws.pore
        material = getattr(pore, "material", None)  # the biphasic law's (no flow: None)
        compaction = (None if pore is None else Compaction(
            sub_cells, pore.phi0, self.options.compaction_margin,
            None if material is None else material.permeability.k0))
        return Admissibility(self.F, self.mesh, self.options.quadrature_degree, compaction)

    # --- the parts of the residual --------------------------------------------------------------
    def _region_stresses(self, v) -> ufl.Form:
        """Σ_r ∫_r P_r : Grad v dX over the four regions (a rigid region's P is 0)."""
        return sum(ufl.inner(law.stress, ufl.grad(v)) * self.dx(self.tags[name])
                   for name, law in self.laws.regions.items())

    def _pressure(self, v, sub_cells: np.ndarray) -> tuple[ufl.Form | None, list]:
        """The pore pressure p on the subcutaneous submesh, if the tissue has a pore law:
        its term −∫_sub p J F⁻ᵀ : Grad v dX in the momentum balance and its own residual."""
        self.p, self.entity_maps = None, None
        pore = self.laws.pore
        if pore is None:
            return None, []
        msh = self.mesh
        submesh, entity_map, _, self.submesh_nodes = dmesh.create_submesh(
            msh, msh.topology.dim, sub_cells)
        self.submesh = submesh
        Q = fem.functionspace(submesh, ("Lagrange", self.options.displacement_degree - 1))
        self.p = fem.Function(Q, name="pore_pressure")
        self.entity_maps = [entity_map]
        dx_sub = self.dx(self.tags["subcutaneous"])
        F = self.F
        coupling = -(ufl.inner(self.p * ufl.det(F) * ufl.inv(F).T, ufl.grad(v)) * dx_sub)
        q = ufl.TestFunction(Q)
        return coupling, [pore.residual(self.u, self.p, self.u_n, q, self.dt, dx_sub,
                                        self.u_nm1, self.rate_weights)]

    def _contact(self, v) -> ufl.Form:
        """The rigid indenters on the pulp: −∫_pulp p_c n·v dS (contact.NitscheContact), with
        the pulp law's instantaneous elastic stress as the traction estimate."""
        X_pulp, _ = self.pulp_nodes()
        self.y_touch = first_touch(np.concatenate(self.mesh.comm.allgather(X_pulp)),
                                    self.indenters)
        # x_tip (and in 3D z_tip) Constants only for a path with a tangential part: else the
        # forms stay as they were
        x_tip = 0.0 if hasattr(self.history, "tangential_at") else None
        z_tip = x_tip if self.gdim == 3 else None
        self.obstacles = [Obstacle.at(self.mesh, ind, self.y_touch, x_tip, z_tip)
                          for ind in self.indenters]
        pulp, o = self.laws.regions["skin"], self.options
        self.contact = NitscheContact(
            self.u, pulp.elastic_stress, self.ds(self.tags["pulp_surface"]), self.obstacles,
            modulus=pulp.p_wave_modulus, theta=o.contact_theta, gamma0=o.contact_gamma0,
            method=o.contact, smoothing=o.contact_smoothing,
        )
        #: Surface element size (mm) under each indenter's tip; warns if it cannot hold it.
        self.tip_mesh_sizes = check_tip_resolution(self.contact)
        self._tip_warned = False
        self.friction = None
        if any(mu > 0 for mu in self.friction_coefficients):
            self.friction = CoulombFriction(self.contact, self.friction_coefficients)
            return self.contact.residual(v) + self.friction.residual(v)
        return self.contact.residual(v)

    def _inertia(self, v) -> ufl.Form:
        """Σ_r ∫_r ρ_r [(1 − α_m) a_{n+1} + α_m a_n]·v dX over the deformable regions
        (inertia.Inertia; ρ_r from `Tissues.densities()`, the reference densities: ρ dX is the
        mass, conserved). Rigid regions are clamped and carry none. The biphasic tissue is
        one u–p mixture whose fluid moves with the solid: the fluid's acceleration relative to
        the solid (w = n_f(v_f − v_s)) is neglected, so its inertia is the mixture's ρ a,
        consistent with a relative flux ~ k Grad p that is tiny at these permeabilities."""
        densities = self.tissues.densities("materials")
        rigid = set(self.laws.rigid_regions())
        self.inertia = Inertia(self.u, self.u_n, self.dt, [
            (densities[r], self.dx(self.tags[r])) for r in REGIONS if r not in rigid])
        return self.inertia.residual(v)

    def _support(self, R_u: ufl.Form, v) -> tuple[list, fem.Form]:
        """Clamp the rigid regions' nodes or, if none is rigid, the nail-centre patch; the 3D
        rollers (`_rollers`); and the reaction form: R_u tested with e_y on the clamped dofs
        only (the rollers carry no y-force)."""
        msh, V = self.mesh, self.V
        tdim = msh.topology.dim
        msh.topology.create_connectivity(tdim - 1, tdim)
        rigid = self.laws.rigid_regions()
        if rigid:
            cells = np.concatenate([self.fmesh.cell_tags.find(self.tags[r]) for r in rigid])
            clamp_dofs = fem.locate_dofs_topological(V, tdim, cells)
        else:
            facets = self.fmesh.facet_tags.find(self.tags["nail_centre"])
            clamp_dofs = fem.locate_dofs_topological(V, tdim - 1, facets)
        self.clamped_dofs = clamp_dofs
        w = fem.Function(V)
        w.x.array.reshape(-1, self.gdim)[clamp_dofs, 1] = 1.0
        reaction = fem.form(ufl.replace(R_u, {v: w}), entity_maps=self.entity_maps)
        bcs = [fem.dirichletbc(np.zeros(self.gdim), clamp_dofs, V), *self._rollers()]
        return bcs, reaction

    def _rollers(self) -> list:
        """u_z = 0 on `proximal_cut`, u_x = 0 on `symmetry`, where the mesh has those tags."""
        bcs, fdim = [], self.mesh.topology.dim - 1
        for name, component in (("proximal_cut", 2), ("symmetry", 0)):
            if name in self.tags and component < self.gdim:
                sub = self.V.sub(component)
                dofs = fem.locate_dofs_topological(
                    sub, fdim, self.fmesh.facet_tags.find(self.tags[name]))
                bcs.append(fem.dirichletbc(0.0, dofs, sub))
        return bcs

    def stiff_cells(self) -> np.ndarray:
        """The cells of the elastic stiff regions, bone and nail (17 GPa and 170 MPa against the
        soft tissues' 10-100 kPa; a rigid one is clamped instead): the iterative linear solver
        treats their block apart (stepping/linear.py). Local cell indices."""
        rigid = self.laws.rigid_regions()
        return np.concatenate([np.zeros(0, np.int32), *(
            self.fmesh.cell_tags.find(self.tags[r]) for r in ("bone", "nail") if r not in rigid)])

    @property
    def mirror_factor(self) -> int:
        """2 for a half model (a `symmetry` plane): its forces times 2 are the whole finger's."""
        return 2 if "symmetry" in self.tags else 1

    @property
    def force_keys(self) -> tuple[str, str]:
        """The diagnostics' names of the indenter force and the reaction: per unit length in
        plane strain (N/mm), a force in 3D (N)."""
        if self.gdim == 3:
            return "force_N", "reaction_N"
        return "force_N_per_mm", "reaction_N_per_mm"

    @property
    def target_key(self) -> str:
        """Under force control, the diagnostics' name of the target normal force, in the force
        column's unit and on its footing (the model's own: a half model's is half the whole
        finger's target)."""
        return TARGET_KEY if self.gdim == 2 else "normal_force_target_N"

    # --- what the recorder needs ---------------------------------------------------------------
    @property
    def qlv(self):
        """The skin's QLV history (viscoelasticity.QuasiLinearViscoelasticity), or None."""
        return self.laws.regions["skin"].history

    @property
    def keeps_u_nm1(self) -> bool:
        """u_{n−1} is state if the pore law has a rate (biphasic, for BDF2)."""
        return getattr(self.laws.pore, "has_rate", False)

    def histories(self) -> list:
        """The QLV histories of the regions' laws (a law shared by regions counts once), and
        the friction's last accepted state (its slip increments start there)."""
        laws = [law.history for law in self.laws.with_history()]
        # force control first: it measures the accepted step's force, which the friction's
        # advance (its slip since the last accepted state) would change
        force = [] if self.force_control is None else [self.force_control]
        return force + laws + ([] if self.friction is None else [self.friction])

    def history_arrays(self) -> dict[str, np.ndarray]:
        """qlv_h{i}, qlv_S_e_n if the skin is viscoelastic, qlv_subcutaneous_h{i},
        qlv_subcutaneous_S_e_n if the subcutaneous solid is (`model.Laws.history_arrays`);
        with friction, its friction_u_prev and friction_previous_{i} (and with the penalty
        contact its friction_elastic_slip)."""
        arrays = self.laws.history_arrays()
        if self.force_control is not None:  # the accepted depths: a resume predicts from them
            arrays |= self.force_control.arrays()
        return arrays if self.friction is None else arrays | self.friction.arrays()

    def region_energies(self) -> dict[int, ufl.core.expr.Expr]:
        """Cell-tag value -> that region's own strain energy density (MPa; rigid regions 0)."""
        return {self.tags[name]: law.energy for name, law in self.laws.regions.items()}

    def pulp_nodes(self) -> tuple[np.ndarray, np.ndarray]:
        """Reference and current positions of this rank's owned displacement nodes on the pulp."""
        V = self.V
        fdim = self.mesh.topology.dim - 1
        facets = self.fmesh.facet_tags.find(self.tags["pulp_surface"])
        nodes = fem.locate_dofs_topological(V, fdim, facets)
        nodes = nodes[nodes < V.dofmap.index_map.size_local]
        X = V.tabulate_dof_coordinates()[nodes, :self.gdim]
        return X, X + self.u.x.array.reshape(-1, self.gdim)[nodes]


    # --- the Steppable protocol ---------------------------------------------------------------
    def indentation(self, t: float) -> float:
        """The depth (mm after first touch) at t: the protocol's, or under force control the
        depth found for the step."""
        if self.force_control is not None:
            return self.force_control.depth_at(t)
        return float(self.history(t))

    def normal_force(self) -> float:
        """The indenters' y-force on the body (N/mm; history.csv's force column): the
        contact's, with friction the friction's y-share too (what the holder feels)."""
        if self.friction is None:
            return float(np.sum(self.contact.forces()))
        return float(self.friction.forces().sum(axis=0)[1])

    def set_time(self, t: float) -> None:
        for obstacle in self.obstacles:
            obstacle.y_tip.value = self.y_touch + self.indentation(t)
            if obstacle.x_tip is not None:
                obstacle.x_tip.value = self.tangential_displacement(t)
            if obstacle.z_tip is not None:
                obstacle.z_tip.value = self.tangential_displacements(t)[1]
        self.time = t

    def tangential_displacement(self, t: float) -> float:
        """The indenters' displacement along x at time t (mm; 0 without a tangential path)."""
        return self.tangential_displacements(t)[0]

    def tangential_displacements(self, t: float) -> tuple[float, float]:
        """The indenters' displacement along x and z at time t (mm; 0 without a tangential
        path)."""
        if not hasattr(self.history, "tangential_at"):
            return 0.0, 0.0
        # a path along x (2D) is x(t) itself, as before the direction existed
        if getattr(self.history, "direction", (1.0, 0.0)) == (1.0, 0.0):
            return float(self.history.tangential_at(t)), 0.0
        return tuple(float(c) for c in self.history.displacement_at(t))

    def residual_hotspot(self, residual) -> np.ndarray | None:
        """Reference position (mm) of the displacement node with the largest residual force in
        `residual` (the solver's last residual vector: per rank, the owned u entries first),
        or None if the residual is not finite anywhere to compare."""
        n, d = self.V.dofmap.index_map.size_local, self.gdim
        r = residual.getArray(readonly=True)[: d * n].reshape(-1, d)
        norms = np.linalg.norm(np.nan_to_num(r, nan=np.inf), axis=1)
        local = float(norms.max()) if len(norms) else -1.0
        comm = self.mesh.comm
        largest = comm.allreduce(local, op=MPI.MAX)
        if not largest > 0:
            return None
        return from_holder(comm, local == largest,
                           lambda: self.V.tabulate_dof_coordinates()[int(np.argmax(norms)), :d])

    def support_reaction(self) -> float:
        """The y-force (N/mm; N in 3D) the body passes to the clamped dofs (> 0 pushes +y).

        The residual at the clamped dofs is the force the clamp exerts on the body; the load
        on the support is its opposite. At equilibrium it equals the indenters' force.
        """
        local = fem.assemble_scalar(self._reaction_form)
        return -self.mesh.comm.allreduce(local, op=MPI.SUM)

    def diagnostics(self) -> dict[str, float]:
        forces = self.contact.forces()
        J_min, _ = self.min_jacobian()
        force, reaction = self.force_keys
        out = {
            "indentation_mm": self.indentation(self.time),
            force: float(np.sum(forces)),
            reaction: self.support_reaction(),
            "max_penetration_mm": self.max_penetration(),
            "min_J": J_min,
        }
        control = self.force_control
        if control is not None:  # the target (the model's share) and the solves it took
            active = control.active(self.time)
            share = control.target(self.time) / self.mirror_factor
            out |= {self.target_key: share if active else math.nan,
                    "force_solves": len(control.samples) if active else 1}
        return out if self.friction is None else out | self._friction_diagnostics()

    def _friction_diagnostics(self) -> dict[str, float]:
        """With friction: the indenters' y-force with the friction's share (what balances the
        support), the tangential force along x and the indenters' displacement along x (3D:
        along x and along z, `tangential_x_force_N`, `tangential_z_displacement_mm`, ...); the
        pressure's share of the forces (`pressure_tangential_...`, `pressure_normal_...`; the
        rest is the friction traction's) and the energy the friction dissipated over the step
        (`dissipated_N_mm_per_mm`, 3D `dissipated_N_mm`; measured before the step is accepted);
        3D: the contact and stick areas (`AREA_KEYS`)."""
        f = self.friction.forces().sum(axis=0)
        p = self.friction.pressure_forces().sum(axis=0)
        force = self.force_keys[0]
        out = {force: float(f[1]), f"pressure_normal_{force}": float(p[1]),
               self.dissipated_key: self.friction.dissipated()}
        axes = ("x", "z") if self.gdim == 3 else ("",)  # 3D: both tangential axes, named
        for name, k, s in zip(axes, (0, 2), self.tangential_displacements(self.time)):
            axis = f"{name}_" if name else ""
            out |= {f"tangential_{axis}{force}": float(f[k]),
                    f"tangential_{axis}displacement_mm": s,
                    f"pressure_tangential_{axis}{force}": float(p[k])}
        if self.gdim == 3:  # the stick and contact areas over the whole surface
            out |= dict(zip(AREA_KEYS, self.friction.areas()))
        return out

    @property
    def dissipated_key(self) -> str:
        """The diagnostics' name of the friction's dissipated energy over a step: per unit
        length in plane strain (N mm/mm), N mm in 3D."""
        return "dissipated_N_mm" if self.gdim == 3 else "dissipated_N_mm_per_mm"

    # --- penetration ----------------------------------------------------------------------------
    def max_penetration(self) -> float:
        """Deepest overlap of body and indenters: surface nodes inside an indenter, and the
        indenter tip inside the body (a sharp tip can slip between the nodes)."""
        nodes = self.contact.max_penetration()
        return max(nodes, self.tip_penetration(nodes))

    def tip_penetration(self, nodes: float | None = None) -> float:
        """How far each indenter's tip lies above the deformed pulp surface (0 if below).

        Near the tip the deformed pulp is a graph y = s(x); the tip pierces the body when its
        height exceeds s at its x. s is sampled from the displacement field itself at
        `TIP_SAMPLES` points per surface facet (not interpolated between nodes, whose chords
        cut into a round indenter by h²/8r and would be mistaken for penetration).
        Plane strain only (sharp tips are a 2D concern): 0 in 3D, where the surface nodes'
        penetration (`contact.max_penetration`) is the measure.
        """
        if self.gdim == 3:
            return 0.0
        x = self._deformed_pulp()
        depth = 0.0
        if self.mesh.comm.rank == 0 and len(x):
            order = np.argsort(x[:, 0])
            xs, ys = x[order, 0], x[order, 1]
            for o in self.obstacles:
                shift = 0.0 if o.x_tip is None else float(o.x_tip.value)  # moved along x
                for cx in (x0 + shift for x0 in o.indenter.tip_xs()):  # no tip in a gap
                    if xs[0] <= cx <= xs[-1]:
                        depth = max(depth, float(o.y_tip.value - np.interp(cx, xs, ys)))
        depth = max(self.mesh.comm.bcast(depth, root=0), 0.0)
        nodes = self.contact.max_penetration() if nodes is None else nodes
        self._warn_if_tip_slips(depth, nodes)
        return depth

    def _warn_if_tip_slips(self, depth: float, nodes: float) -> None:
        """Warn (once per run) when the tip is deeper in the body than the surface nodes are
        in the indenters. Any contact law lets the nodes overlap a little (penalty: p/γ;
        Nitsche: as far as t_n − γg needs), and a tip on the surface lies that deep too
        (a round bar of the 1pt scene: 0.39 µm of tip for 0.38 µm of nodes at t = 0.05 s on
        a 0.4 mm mesh): that is the law's, not the mesh's. A tip deeper than the nodes by
        more than the tolerance sits between them: the elements are too long for it."""
        excess = depth - nodes
        tolerance = max(TIP_PENETRATION_TOLERANCE * abs(self.indentation(self.time)), 1e-3)
        if excess > tolerance and not self._tip_warned:
            self._tip_warned = True  # once per run
            tips = ", ".join(f"{o.indenter.centre_x:g}" for o in self.obstacles)
            warnings.warn(
                f"at t = {self.time:.4g} s the indenter tip is {depth * 1e3:.3g} µm inside the "
                f"body, {excess * 1e3:.3g} µm deeper than the surface nodes (tolerance "
                f"{tolerance * 1e3:.3g} µm): it slips between surface elements "
                f"{max(self.tip_mesh_sizes):.3g} mm long. Fix: refine the mesh under the tip: "
                f"section.mesh.tips = [{tips}], tip_size below the tip radius.",
                TipResolutionWarning, stacklevel=3,
            )

    @cached_property
    def _surface_position(self):
        return self.contact.surface_sampler(ufl.SpatialCoordinate(self.mesh) + self.u,
                                            TIP_SAMPLES)

    def _deformed_pulp(self) -> np.ndarray:
        """Current positions of points of the palmar pulp surface (TIP_SAMPLES per facet),
        gathered on rank 0 (empty elsewhere)."""
        X, x = self._surface_position()
        x = x[X[:, 1] < 0]
        gathered = self.mesh.comm.gather(x, root=0)
        if self.mesh.comm.rank != 0:
            return np.zeros((0, 2))
        return np.concatenate(gathered)


def first_touch(points: np.ndarray, indenters: Sequence[Indenter]) -> float:
    """The common tip height at which the first indenter touches the surface `points`.

    min over the points of φ(y_tip) decreases with y_tip; bisection finds its zero.
    """
    if len(points) == 0:
        raise InputError("mesh", "the pulp surface has no nodes.", "rebuild the mesh.")

    def clearance(y_tip: float) -> float:
        return min(float(np.min(ind.signed_distance_np(points, y_tip)[0])) for ind in indenters)

    low = float(points[:, 1].min()) - 50.0  # far below: clear of the body
    high = float(points[:, 1].max())
    if clearance(low) <= 0:
        raise InputError("scene.indenters", "an indenter overlaps the fingertip even far below it.")
    for _ in range(80):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if clearance(mid) > 0 else (low, mid)
    return low
