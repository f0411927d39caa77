r"""The coupled fingertip problem on the tagged mesh: unknowns, residuals, supports and loads.

Unknowns: the displacement u on the whole section (Lagrange degree k, vector) and, when the
subcutaneous tissue is biphasic, the pore pressure p on the subcutaneous region only (degree
k − 1 on a submesh: Taylor–Hood where it matters, no pressure unknowns in skin, bone or nail).
One backward-Euler step solves

    Σ_r ∫_r P_r : Grad v dX − ∫_sub p J F⁻ᵀ : Grad v dX − ∫_pulp p_c n·v dS = 0     for all v,
    ∫_sub (J − J_n) q + Δt J k(J) C⁻¹ Grad p · Grad q dX                  = 0     for all q,

with P_skin = F S, S the QLV history of the hyperfoam stress; P_sub the drained hyperfoam
stress of the solid; bone and nail St Venant–Kirchhoff; p_c the Nitsche contact pressure of
the rigid indenters on the pulp. Every boundary not in contact is traction-free; the
subcutaneous boundary is impermeable (zero flux is the natural condition).

Support: the `nail_centre` patch (a short arc at the top of the nail, centred on the point the
paper fixes) is clamped in x and y. A single fixed point would leave the rigid rotation about
it free; clamping the short patch of the 170 MPa nail removes it and exerts no force of its
own: at equilibrium its reaction equals the indenter force, and for a load on the symmetry
line its moment is zero.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from .contact import (
    TIP_PENETRATION_TOLERANCE,
    NitscheContact,
    Obstacle,
    TipResolutionWarning,
    check_tip_resolution,
    p_wave_modulus,
)
from .errors import InputError
from .indenters import Indenter
from .kinematics import deformation_gradient
from .loading import History
from .materials import (
    first_piola_kirchhoff,
    second_piola_kirchhoff,
)
from .mesh import FingertipMesh
from .poroelasticity import mass_residual
from .tissues import WU2004, Tissues
from .viscoelasticity import QuasiLinearViscoelasticity

SUBCUTANEOUS_MODELS = ("biphasic", "undrained", "drained")
#: Points per surface facet at which the deformed pulp is sampled to find a tip's depth.
TIP_SAMPLES = 9
TISSUE_MODELS = ("layered", "continuum")


@dataclass(frozen=True)
class ModelOptions:
    """Discretisation and modelling choices of one run."""

    displacement_degree: int = 2
    #: Quadrature degree of the volume integrals (and of the QLV internal variables).
    quadrature_degree: int = 4
    #: Skin history (QLV). False: the skin responds with its instantaneous elasticity.
    skin_viscoelastic: bool = True
    #: "layered": the four regions with their own laws. "continuum": one homogeneous
    #: small-strain linear-elastic section (continuum_E, continuum_nu), the cheapest model.
    tissue: str = "layered"
    continuum_E: float = 2 * 0.579e-3 * 1.4  # MPa: the subcutaneous tissue's small-strain E
    continuum_nu: float = 0.4
    #: "biphasic": pore pressure unknown (Taylor–Hood). "undrained": no flow at all, the
    #: tissue is incompressible (J = 1; p its Lagrange multiplier). "drained": the solid alone
    #: (p = 0), the long-time limit.
    subcutaneous: str = "biphasic"
    #: Bone and nail rigid and held (their nodes clamped) instead of elastic and held at the
    #: nail centre.
    rigid_bone: bool = False
    #: "nitsche" (consistent) or "penalty" (robust at sharp tips): see contact.CONTACT_METHODS.
    contact: str = "nitsche"
    contact_theta: int = 0
    #: Gap width (mm) over which the contact pressure's kink is smoothed (0: exact).
    contact_smoothing: float = 0.0
    contact_gamma0: float = 10.0
    #: A converged state whose subcutaneous J falls below φ0 + margin is rejected.
    compaction_margin: float = 0.02
    extra: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.displacement_degree not in (1, 2, 3):
            raise InputError(
                "model.displacement_degree", f"got {self.displacement_degree}.", "use 1, 2 or 3."
            )
        if self.subcutaneous not in SUBCUTANEOUS_MODELS:
            raise InputError(
                "model.subcutaneous", f"unknown model {self.subcutaneous!r}.",
                f"use one of {SUBCUTANEOUS_MODELS}.",
            )
        if self.tissue not in TISSUE_MODELS:
            raise InputError("model.tissue", f"unknown model {self.tissue!r}.",
                             f"use one of {TISSUE_MODELS}.")
        if not (self.continuum_E > 0 and -1 < self.continuum_nu < 0.5):
            raise InputError("model.continuum_E/continuum_nu",
                             f"E = {self.continuum_E}, nu = {self.continuum_nu} is not a stable "
                             "elastic material.", "use E > 0 and -1 < nu < 0.5.")
        if (self.tissue == "layered" and self.subcutaneous != "drained"
                and self.displacement_degree < 2):
            raise InputError(
                "model.displacement_degree",
                f"the {self.subcutaneous} tissue needs Taylor–Hood elements (displacement degree "
                ">= 2): equal-order u/p fails the inf-sup condition in the (nearly) undrained "
                "regime.",
                "use displacement_degree = 2.",
            )


class FingertipProblem:
    """Forms, unknowns, supports and loads of the fingertip under rigid indenters.

    `indenters` move together as one rigid holder along `history` (indentation depth, mm,
    measured from first touch). Implements the `solver.Steppable` protocol.
    """

    def __init__(
        self,
        fmesh: FingertipMesh,
        indenters: Sequence[Indenter],
        history: History,
        tissues: Tissues = WU2004,
        options: ModelOptions = ModelOptions(),
    ):
        if not indenters:
            raise InputError("scene.indenters", "no indenter given.", "give at least one.")
        self.fmesh, self.history, self.tissues, self.options = fmesh, history, tissues, options
        msh = fmesh.mesh
        self.mesh = msh
        tags = fmesh.names
        for name in ("skin", "subcutaneous", "bone", "nail", "pulp_surface", "nail_centre"):
            if name not in tags:
                raise InputError("mesh", f"the tag {name!r} is missing.", "rebuild the mesh.")
        tdim = msh.topology.dim
        qd = options.quadrature_degree
        self.dt = fem.Constant(msh, 1.0)
        dx = ufl.Measure(
            "dx", domain=msh, subdomain_data=fmesh.cell_tags, metadata={"quadrature_degree": qd}
        )
        ds = ufl.Measure("ds", domain=msh, subdomain_data=fmesh.facet_tags)
        self.dx = dx

        # --- displacement ----------------------------------------------------------------
        V = fem.functionspace(msh, ("Lagrange", options.displacement_degree, (2,)))
        self.V = V
        self.u = fem.Function(V, name="displacement")
        self.u_n = fem.Function(V, name="displacement_n")
        v = ufl.TestFunction(V)
        F = deformation_gradient(self.u)
        self.F = F

        # --- constitutive responses per region -------------------------------------------
        self.qlv = None
        if options.tissue == "continuum":
            sigma = _small_strain_stress(self.u, options.continuum_E, options.continuum_nu)
            self.P = dict.fromkeys(("skin", "subcutaneous", "bone", "nail"), sigma)
            P_contact = sigma
        else:
            S_skin = second_piola_kirchhoff(tissues.skin, F)
            # The QLV history lives at cell quadrature points and cannot be evaluated on
            # facets, so Nitsche's traction estimate uses the skin's instantaneous stress
            # F S_e. This only shifts the consistency term: at convergence the gap in contact
            # is (t_n(S_e) − t_n(S))/γ, a fraction (strain/γ0) of h; the penetration is reported.
            P_contact = F * S_skin
            if options.skin_viscoelastic and tissues.skin_prony is not None:
                skin_cells = fmesh.cell_tags.find(tags["skin"])
                self.qlv = QuasiLinearViscoelasticity(
                    S_skin, tissues.skin_prony, msh, qd, self.dt, cells=skin_cells
                )
                S_skin = self.qlv.stress()
            self.P = {
                "skin": F * S_skin,
                "subcutaneous": first_piola_kirchhoff(tissues.subcutaneous.solid, F),
                "bone": first_piola_kirchhoff(tissues.bone, F),
                "nail": first_piola_kirchhoff(tissues.nail, F),
            }
        R_u = sum(ufl.inner(P, ufl.grad(v)) * dx(tags[name]) for name, P in self.P.items())

        # --- pore pressure on the subcutaneous submesh -------------------------------------
        self.p = None
        self.entity_maps = None
        residuals_p = []
        sub_cells = fmesh.cell_tags.find(tags["subcutaneous"])
        self._sub_cells = sub_cells
        if options.subcutaneous != "drained" and options.tissue == "layered":
            submesh, entity_map, _, self.submesh_nodes = dmesh.create_submesh(msh, tdim, sub_cells)
            self.submesh = submesh
            Q = fem.functionspace(submesh, ("Lagrange", options.displacement_degree - 1))
            self.p = fem.Function(Q, name="pore_pressure")
            q = ufl.TestFunction(Q)
            J = ufl.det(F)
            R_u -= ufl.inner(self.p * J * ufl.inv(F).T, ufl.grad(v)) * dx(tags["subcutaneous"])
            if options.subcutaneous == "biphasic":
                residuals_p.append(mass_residual(self.u, self.p, self.u_n, q, self.dt,
                                                 tissues.subcutaneous, dx(tags["subcutaneous"])))
            else:  # undrained: no flow, the volume of every piece of tissue is kept
                residuals_p.append((J - ufl.det(deformation_gradient(self.u_n))) * q
                                   * dx(tags["subcutaneous"]))
            self.entity_maps = [entity_map]

        # --- contact ------------------------------------------------------------------------
        X_pulp, _ = self._pulp_nodes()
        self.y_touch = _first_touch(np.concatenate(msh.comm.allgather(X_pulp)), indenters)
        self.obstacles = [Obstacle.at(msh, ind, self.y_touch) for ind in indenters]
        skin = tissues.skin
        modulus = p_wave_modulus(2 * skin.mu0 * (1 + skin.nu), skin.nu)
        if options.tissue == "continuum":
            modulus = p_wave_modulus(options.continuum_E, options.continuum_nu)
        self.contact = NitscheContact(
            self.u, P_contact, ds(tags["pulp_surface"]), self.obstacles,
            modulus=modulus, theta=options.contact_theta, gamma0=options.contact_gamma0,
            method=options.contact, smoothing=options.contact_smoothing,
        )
        #: Surface element size (mm) under each indenter's tip; warns if it cannot hold it.
        self.tip_mesh_sizes = check_tip_resolution(self.contact)
        self._tip_warned = False
        R_u += self.contact.residual(v)
        self.residuals = [R_u, *residuals_p]
        self.unknowns = [self.u] + ([self.p] if self.p is not None else [])

        # --- support: clamp the nail-centre patch (or the whole rigid bone and nail) ----------
        fdim = tdim - 1
        msh.topology.create_connectivity(fdim, tdim)
        if options.rigid_bone and options.tissue == "layered":
            rigid = np.concatenate([fmesh.cell_tags.find(tags[n]) for n in ("bone", "nail")])
            clamp_dofs = fem.locate_dofs_topological(V, tdim, rigid)
        else:
            clamp_facets = fmesh.facet_tags.find(tags["nail_centre"])
            clamp_dofs = fem.locate_dofs_topological(V, fdim, clamp_facets)
        self.bcs = [fem.dirichletbc(np.zeros(2), clamp_dofs, V)]

        # The support's y-reaction: the residual tested with e_y on the clamped dofs only.
        self._w = fem.Function(V)
        self._w.x.array.reshape(-1, 2)[clamp_dofs, 1] = 1.0
        self._reaction_form = fem.form(
            ufl.replace(R_u, {v: self._w}), entity_maps=self.entity_maps
        )

        # J at the quadrature points, to reject inverted or over-compacted states.
        self._J_expr = fem.Expression(
            ufl.det(F), _quadrature_points(msh, qd)
        )
        imap = msh.topology.index_map(tdim)
        self._owned_cells = np.arange(imap.size_local, dtype=np.int32)
        self._last = [f.x.array.copy() for f in self.unknowns]
        self.time = 0.0

    # --- the Steppable protocol ---------------------------------------------------------------
    def indentation(self, t: float) -> float:
        return float(self.history(t))

    def set_time(self, t: float) -> None:
        for obstacle in self.obstacles:
            obstacle.y_tip.value = self.y_touch + self.indentation(t)
        self.time = t

    def accept(self) -> None:
        if self.qlv is not None:
            self.qlv.advance()
        self.u_n.x.array[:] = self.u.x.array
        self._last = [f.x.array.copy() for f in self.unknowns]

    def mark_accepted(self) -> None:
        """Take the current unknowns as the last accepted state (after loading a checkpoint)."""
        self._last = [f.x.array.copy() for f in self.unknowns]

    def restore(self) -> None:
        for f, saved in zip(self.unknowns, self._last):
            f.x.array[:] = saved

    def min_jacobian(self, cells: np.ndarray | None = None) -> tuple[float, np.ndarray]:
        """Smallest J at the quadrature points of `cells` (owned cells by default), and where."""
        cells = self._owned_cells if cells is None else cells
        cells = cells[cells < len(self._owned_cells)]
        comm = self.mesh.comm
        if len(cells):
            values = self._J_expr.eval(self.mesh, cells).reshape(len(cells), -1)
            i = np.unravel_index(np.argmin(values), values.shape)
            local = (float(values[i]), cells[i[0]])
        else:
            local = (np.inf, -1)
        J_min = comm.allreduce(local[0], op=MPI.MIN)
        geometry = self.mesh.geometry
        return J_min, _from_holder(
            comm, local[0] == J_min,
            lambda: geometry.x[geometry.dofmaps[0][local[1]], :2].mean(axis=0))

    def inadmissible(self) -> str | None:
        J_min, where = self.min_jacobian()
        if not np.isfinite(J_min) or J_min <= 0:
            return f"inverted elements (J = {J_min:.3g}) near x = ({where[0]:.3f}, {where[1]:.3f}) mm"
        if self.p is not None:
            phi0 = self.tissues.subcutaneous.phi0
            J_sub, where = self.min_jacobian(self._sub_cells)
            if J_sub <= phi0 + self.options.compaction_margin:
                return (
                    f"compaction: the subcutaneous tissue reached J = {J_sub:.3g} (solid fraction "
                    f"phi0 = {phi0:g}) near x = ({where[0]:.3f}, {where[1]:.3f}) mm"
                )
        return None

    def residual_hotspot(self, residual) -> np.ndarray | None:
        """Reference position (mm) of the displacement node with the largest residual force in
        `residual` (the solver's last residual vector: per rank, the owned u entries first),
        or None if the residual is not finite anywhere to compare."""
        n = self.V.dofmap.index_map.size_local
        r = residual.getArray(readonly=True)[: 2 * n].reshape(-1, 2)
        norms = np.linalg.norm(np.nan_to_num(r, nan=np.inf), axis=1)
        local = float(norms.max()) if len(norms) else -1.0
        comm = self.mesh.comm
        largest = comm.allreduce(local, op=MPI.MAX)
        if not largest > 0:
            return None
        return _from_holder(comm, local == largest,
                            lambda: self.V.tabulate_dof_coordinates()[int(np.argmax(norms)), :2])

    def support_reaction(self) -> float:
        """The y-force (N/mm) the body passes to the clamped nail patch (> 0 pushes it +y).

        The residual at the clamped dofs is the force the clamp exerts on the body; the load
        on the support is its opposite. At equilibrium it equals the indenters' force.
        """
        local = fem.assemble_scalar(self._reaction_form)
        return -self.mesh.comm.allreduce(local, op=MPI.SUM)

    def diagnostics(self) -> dict[str, float]:
        forces = self.contact.forces()
        J_min, _ = self.min_jacobian()
        return {
            "indentation_mm": self.indentation(self.time),
            "force_N_per_mm": float(np.sum(forces)),
            "reaction_N_per_mm": self.support_reaction(),
            "max_penetration_mm": self.max_penetration(),
            "min_J": J_min,
        }

    def max_penetration(self) -> float:
        """Deepest overlap of body and indenters: surface nodes inside an indenter, and the
        indenter tip inside the body (a sharp tip can slip between the nodes)."""
        return max(self.contact.max_penetration(), self.tip_penetration())

    def tip_penetration(self) -> float:
        """How far each indenter's tip lies above the deformed pulp surface (0 if below).

        Near the tip the deformed pulp is a graph y = s(x); the tip pierces the body when its
        height exceeds s at its x. s is sampled from the displacement field itself at
        `TIP_SAMPLES` points per surface facet (not interpolated between nodes, whose chords
        cut into a round indenter by h²/8r and would be mistaken for penetration).
        """
        x = self._deformed_pulp()
        depth = 0.0
        if self.mesh.comm.rank == 0 and len(x):
            order = np.argsort(x[:, 0])
            xs, ys = x[order, 0], x[order, 1]
            for o in self.obstacles:
                cx = o.indenter.centre_x
                if xs[0] <= cx <= xs[-1]:
                    depth = max(depth, float(o.y_tip.value - np.interp(cx, xs, ys)))
        depth = max(self.mesh.comm.bcast(depth, root=0), 0.0)
        tolerance = max(TIP_PENETRATION_TOLERANCE * abs(self.indentation(self.time)), 1e-3)
        if depth > tolerance and not self._tip_warned:
            self._tip_warned = True  # once per run
            warnings.warn(
                f"at t = {self.time:.4g} s the indenter tip is {depth * 1e3:.3g} µm inside the "
                f"body (tolerance {tolerance * 1e3:.3g} µm): the surface elements under the tip "
                f"are {max(self.tip_mesh_sizes):.3g} mm long. Fix: refine the mesh under the tip "
                "(section.mesh.tips = [x of the tip], tip_size below the tip radius).",
                TipResolutionWarning, stacklevel=2,
            )
        return depth

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

    def state_arrays(self) -> dict[str, np.ndarray]:
        """The arrays that define the state (for a checkpoint)."""
        arrays = {"u": self.u.x.array, "u_n": self.u_n.x.array}
        if self.p is not None:
            arrays["p"] = self.p.x.array
        if self.qlv is not None:
            for i, h in enumerate(self.qlv.h):
                arrays[f"qlv_h{i}"] = h.x.array
            arrays["qlv_S_e_n"] = self.qlv.S_e_n.x.array
        return arrays

    def region_energies(self) -> dict:
        """Cell tag -> strain energy density of that region (for the SED output)."""
        from .materials import strain_energy_density

        t, tags = self.tissues, self.fmesh.names
        return {tags["skin"]: strain_energy_density(t.skin, self.F),
                tags["subcutaneous"]: strain_energy_density(t.subcutaneous.solid, self.F),
                tags["bone"]: strain_energy_density(t.bone, self.F),
                tags["nail"]: strain_energy_density(t.nail, self.F)}

    def pulp_nodes(self) -> tuple[np.ndarray, np.ndarray]:
        return self._pulp_nodes()

    def _pulp_nodes(self) -> tuple[np.ndarray, np.ndarray]:
        """Reference and current positions of this rank's owned displacement nodes on the pulp."""
        V = self.V
        fdim = self.mesh.topology.dim - 1
        facets = self.fmesh.facet_tags.find(self.fmesh.names["pulp_surface"])
        nodes = fem.locate_dofs_topological(V, fdim, facets)
        nodes = nodes[nodes < V.dofmap.index_map.size_local]
        X = V.tabulate_dof_coordinates()[nodes, :2]
        return X, X + self.u.x.array.reshape(-1, 2)[nodes]


def _from_holder(comm: MPI.Comm, holds: bool, value):
    """`value()` evaluated on the lowest rank where `holds` (e.g. it owns the extreme of a
    reduction) and broadcast to every rank."""
    owner = comm.allreduce(comm.rank if holds else comm.size, op=MPI.MIN)
    return comm.bcast(value() if comm.rank == owner else None, root=owner)


def _small_strain_stress(u, E: float, nu: float):
    """σ = λ tr(ε) I + 2μ ε, ε = sym grad u: the linear-elastic continuum model."""
    mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    eps = ufl.sym(ufl.grad(u))
    return lmbda * ufl.tr(eps) * ufl.Identity(2) + 2 * mu * eps


def _quadrature_points(msh: dmesh.Mesh, degree: int) -> np.ndarray:
    import basix

    cell = basix.CellType[msh.topology.cell_name()]
    points, _ = basix.make_quadrature(cell, degree)
    return points


def _first_touch(points: np.ndarray, indenters: Sequence[Indenter]) -> float:
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
