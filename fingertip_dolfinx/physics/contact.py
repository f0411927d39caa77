"""Frictionless Nitsche contact of the body's surface with rigid indenters, at finite strain.

Total Lagrangian: integrals over the reference surface (the `ds` passed in), gap and normal at
the current position x = X + u. With t = P N the nominal traction and, per indenter, g = φ(x) the
signed distance, n = ∇φ(x) its normal (pointing from the indenter into the body) and
t_n = t·n the normal traction (> 0 in compression), the contact conditions

    g ≥ 0,   t_n ≥ 0,   t_n g = 0,   tangential traction 0

are equivalent, for any γ > 0, to t_n = [t_n − γ g]_+ (Chouly & Hild, SINUM 51, 2013). Nitsche's
method puts the right-hand side, the contact pressure p = [t_n − γ g]_+, into the weak form:

    R(u; v) = ∫ P:∇v dx − ∫ p (n·v) ds + θ/γ ∫ (p − t_n) δt_n[v] ds,   γ = γ0 M / h,

with δt_n[v] the derivative of t_n along v. θ = 0 (default) drops the consistency term: only
the pressure term remains, and it was the variant that converged robustly in probe runs (θ = 1,
symmetric, diverged; θ = −1, skew, inverted elements). M is a stiffness scale: the P-wave
modulus λ + 2μ, not E, since nearly incompressible tissue is stiffer to a normal push than E
says. The method is consistent, so the solution does not depend on γ0 as a penalty's would;
γ0 ~ 10 is enough, γ0 ≥ 100 made Newton chatter on the active set.

Several indenters act as one obstacle, their union: each surface point takes the gap and normal
of the nearest indenter. Its force counts towards that indenter.

Dynamics (a model with inertia) needs a conservative contact force, one that is the gradient of
a potential, so that the semi-discrete system keeps an energy. The penalty force −∫ γ[−g]_+ n·v
is the derivative of ½ ∫ γ [−g]_+² ds, and Nitsche's with θ = 1 of
∫ ([t_n − γ g]_+² − t_n²)/(2γ) ds (Chouly, Hild & Renard, ESAIM: M2AN 49, 2015, 481–502: only
the symmetric variant conserves an augmented energy). Nitsche's with θ = 0 is not: its tangent
has the part −H(t_n − γg) δt_n[δu] (n·v) without its transpose, a follower-like force that can
feed the stiff modes of the contact's edges (flutter): on the coarse fingertip at 250 Hz an
unresolved oscillation of the contact zone grew until Newton failed with θ = 0, and decayed
with the penalty (the runs: docs/benchmarks/measurements.md). It is the space discretisation,
not the integrator: only enough numerical dissipation (ρ∞, or a longer Δt) hides it.
`NitscheContact.conservative` says which laws are safe; the time stepper warns about the others,
and friction with inertia refuses them (friction.check_dynamic_contact).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import basix
import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from ..errors import InputError
from ..geometry.indenters import Indenter

#: The surface elements under an indenter's tip must not be longer than this many tip radii:
#: a tip narrower than the spacing of the surface quadrature points slips between them and
#: pierces the body (measured on the line-load wedge, r = 25 µm: with surface elements of 0.1 mm
#: the tip was 14 µm inside at 0.39 mm of indentation and Newton stalled; 0.02 mm elements kept
#: the tip outside to < 1 µm up to 1 mm).
TIP_RESOLUTION = 2.0
#: A tip deeper than this fraction of the indentation (or 1 µm) inside the body is reported.
TIP_PENETRATION_TOLERANCE = 0.01


#: "nitsche": p = [t_n − γ g]_+, consistent, γ only needs to exceed the stress's stiffness.
#: "penalty": p = [−γ g]_+, always a positive stiffness but a penetration p/γ; the choice for a
#: sharp tip, where Nitsche's traction estimate t_n is poor and its derivative, a negative
#: stiffness, made Newton's matrix nearly singular (line load, hold phase).
CONTACT_METHODS = ("nitsche", "penalty")


class NonConservativeContactWarning(UserWarning):
    """A dynamic run with a contact force that derives from no potential (Nitsche, θ ≠ 1)."""


class TipResolutionWarning(UserWarning):
    """The mesh is too coarse at an indenter's tip: the tip can pierce the surface."""


@dataclass(frozen=True)
class Obstacle:
    """An indenter in the scene: the loading moves it by setting `y_tip.value`, and, if it has
    them, its tangential displacement along x by `x_tip.value` and (3D) along z by
    `z_tip.value` (mm; None: it never moves along that axis, and the contact forms are exactly
    those of a fixed centre_x, centre_z)."""

    indenter: Indenter
    y_tip: fem.Constant
    x_tip: fem.Constant | None = None
    z_tip: fem.Constant | None = None

    @classmethod
    def at(cls, domain: dmesh.Mesh, indenter: Indenter, y_tip: float = 0.0,
           x_tip: float | None = None, z_tip: float | None = None) -> Obstacle:
        x, z = (None if v is None else fem.Constant(domain, float(v)) for v in (x_tip, z_tip))
        return cls(indenter, fem.Constant(domain, float(y_tip)), x, z)

    def _shifts(self, d: int) -> dict:
        """Axis -> the Constant moving the indenter along it (x: 0, z: 2), those it has."""
        return {k: c for k, c in ((0, self.x_tip), (2, self.z_tip)) if c is not None and k < d}

    def offset(self, d: int, value=lambda c: c) -> list:
        """The indenter's tangential displacement as d components (Constants, or what
        `value` makes of them; 0.0 along an axis it never moves along). A move along z
        carries it along `indenter.z_direction()` (a tilted grating: along its own plane)."""
        shifts = self._shifts(d)
        offset = [value(shifts[k]) if k in shifts else 0.0 for k in range(d)]
        direction = self.indenter.z_direction()
        if 2 in shifts and direction is not None:
            offset[1:] = [value(shifts[2]) * direction[k] for k in (1, 2)]
        return offset

    def relative(self, x):
        """The point x (UFL vector) in the indenter's frame: shifted back by its tangential
        displacement (`offset`)."""
        if not self._shifts(x.ufl_shape[0]):
            return x
        return x - ufl.as_vector(self.offset(x.ufl_shape[0]))

    def relative_np(self, x: np.ndarray) -> np.ndarray:
        """`relative` for points (m, d) in numpy."""
        if not self._shifts(x.shape[1]):
            return x
        return x - np.array(self.offset(x.shape[1], lambda c: float(c.value)))


def is_conservative(method: str, theta: int) -> bool:
    """Whether the contact law's force is the gradient of a potential (penalty, or Nitsche with
    θ = 1): then it cannot pump energy into a dynamic run (module docstring)."""
    return method == "penalty" or theta == 1


class NitscheContact:
    """The contact terms of the surface `ds` (e.g. `ds(PULP_SURFACE)`) against `obstacles`.

    `P` is the first Piola–Kirchhoff stress as a UFL expression of `u` (a displacement Function
    of its own, not a subfunction); `modulus` is M in γ = γ0 M / h (a number or UFL, per cell);
    `h` defaults to the cell diameter; the surface quadrature degree to 2 k + 2 for
    displacements of degree k. Forms are built once; moving an obstacle only changes its
    `y_tip` Constant.
    """

    def __init__(
        self,
        u: fem.Function,
        P: ufl.core.expr.Expr,
        ds: ufl.Measure,
        obstacles: Sequence[Obstacle],
        *,
        modulus,
        theta: int = 0,
        gamma0: float = 10.0,
        h=None,
        quadrature_degree: int | None = None,
        method: str = "nitsche",
        smoothing: float = 0.0,
    ):
        _check_options(method, theta, gamma0, smoothing, obstacles)
        domain = u.function_space.mesh
        # A fixed rule: UFL's estimate for these non-polynomial terms is huge and differs
        # between the residual and its derivative, which makes the Jacobian inexact.
        degree = quadrature_degree or 2 * u.function_space.ufl_element().embedded_superdegree + 2
        self.u, self.ds, self.theta, self.method = u, ds(degree=degree), theta, method
        self.quadrature_degree = degree
        self.obstacles = tuple(obstacles)
        h = ufl.CellDiameter(domain) if h is None else h
        self.gamma = gamma0 * modulus / h
        x = ufl.SpatialCoordinate(domain) + u
        t = P * ufl.FacetNormal(domain)
        #: The nominal traction P N on the surface: friction's tangential estimate (friction.py).
        self.traction = t
        gaps, self._normals, self._tn = [], [], []
        for obstacle in self.obstacles:
            g, n = obstacle.indenter.signed_distance(obstacle.relative(x), obstacle.y_tip)
            gaps.append(g)
            self._normals.append(n)
            # The penalty method is Nitsche's without the traction estimate (t_n = 0, θ = 0).
            self._tn.append(ufl.dot(t, n) if method == "nitsche" else 0.0)
        self._pressures = [
            self.gamma * _ramp(tn / self.gamma - g, smoothing) for tn, g in zip(self._tn, gaps)
        ]
        self._nearest = _nearest_indicators(gaps)
        #: t_n − γ g, the pressure before clipping: > 0 exactly where contact is active, so its
        #: zero level is the edge of the contact zone.
        self.trial_pressure = sum(
            c * (tn - self.gamma * g) for c, tn, g in zip(self._nearest, self._tn, gaps)
        )
        #: The Nitsche contact pressure [t_n − γ g]_+ on the surface (MPa, > 0 in compression).
        self.pressure = sum(c * p for c, p in zip(self._nearest, self._pressures))

    @property
    def conservative(self) -> bool:
        """Whether the contact force is the gradient of a potential (`is_conservative`)."""
        return is_conservative(self.method, self.theta)

    def _term(self, i: int, v) -> ufl.Form:
        """Indenter i's share of the residual, tested with v (an Argument or a Function)."""
        p, n, tn = self._pressures[i], self._normals[i], self._tn[i]
        integrand = -p * ufl.dot(n, v)
        if self.theta and self.method == "nitsche":
            integrand += self.theta / self.gamma * (p - tn) * ufl.derivative(tn, self.u, v)
        return self._nearest[i] * integrand * self.ds

    def residual(self, v) -> ufl.Form:
        """The contact contribution to the residual: add it to ∫ P:∇v dx."""
        return sum(self._term(i, v) for i in range(len(self.obstacles)))

    @cached_property
    def _force_forms(self) -> list[fem.Form]:
        # The residual tested with the rigid translation e_y: the interior term ∫ P:∇e_y dx
        # vanishes, so at a converged state this force balances the supports' reactions to
        # solver precision, for every θ (for θ = 0 it is ∫ p n_y ds).
        V = self.u.function_space
        e_y = fem.Function(V)
        e_y.x.array.reshape(-1, V.dofmap.index_map_bs)[:, 1] = 1.0
        return [fem.form(-self._term(i, e_y)) for i in range(len(self.obstacles))]

    @cached_property
    def _slab_force_form(self) -> tuple[fem.Form, fem.Constant]:
        # The force on one slab a <= X_k < b of the surface: the force form's e_y times the
        # slab's indicator (the residual is linear in the test function). One form for every
        # slab: the bounds are Constants, so moving the slab never recompiles.
        domain = self.u.function_space.mesh
        X = ufl.SpatialCoordinate(domain)
        bounds = fem.Constant(domain, np.zeros(3))  # (axis as a number, a, b)
        along = sum(ufl.conditional(ufl.eq(bounds[0], k), X[k], 0.0)
                    for k in range(domain.geometry.dim))
        inside = ufl.conditional(ufl.And(ufl.ge(along, bounds[1]), ufl.lt(along, bounds[2])),
                                 1.0, 0.0)
        e_y = ufl.as_vector([inside if k == 1 else 0.0 for k in range(domain.geometry.dim)])
        total = -sum(self._term(i, e_y) for i in range(len(self.obstacles)))
        return fem.form(total), bounds

    def line_force(self, axis: int, edges) -> np.ndarray:
        """The y-force of all indenters per unit length along the reference coordinate `axis`
        (N/mm in 3D): the force on each slab edges[k] <= X_axis < edges[k+1], divided by its
        width. On a z-slab of a 3D finger it is what a plane-strain section carries."""
        form, bounds = self._slab_force_form
        comm = self.u.function_space.mesh.comm
        edges = np.asarray(edges, dtype=float)
        local = []
        for a, b in zip(edges[:-1], edges[1:]):
            bounds.value[:] = (axis, a, b)
            local.append(fem.assemble_scalar(form))
        return comm.allreduce(np.array(local, dtype=float), op=MPI.SUM) / np.diff(edges)

    def forces(self) -> np.ndarray:
        """The y-force each indenter exerts on the body (N/mm in plane strain, N in 3D; > 0
        pushes +y)."""
        comm = self.u.function_space.mesh.comm
        local = [fem.assemble_scalar(f) for f in self._force_forms]
        return np.array(comm.allreduce(np.array(local, dtype=float), op=MPI.SUM))

    @cached_property
    def facets(self) -> np.ndarray:
        """The (local) facets of the contact surface, from the tags and id of `ds`."""
        domain = self.u.function_space.mesh
        fdim = domain.topology.dim - 1
        domain.topology.create_connectivity(fdim, fdim + 1)
        sid, tags = self.ds.subdomain_id(), self.ds.subdomain_data()
        if sid == "everywhere" or tags is None:
            return dmesh.exterior_facet_indices(domain.topology)
        ids = sid if isinstance(sid, tuple) else (sid,)
        return np.unique(np.concatenate([tags.find(i) for i in ids]))

    def max_penetration(self) -> float:
        """Deepest that a displacement node of the surface lies inside any indenter (mm)."""
        V, u = self.u.function_space, self.u
        fdim = V.mesh.topology.dim - 1
        nodes = fem.locate_dofs_topological(V, fdim, self.facets)
        nodes = nodes[nodes < V.dofmap.index_map.size_local]  # owned: each node counted once
        bs = V.dofmap.index_map_bs  # = gdim
        x = V.tabulate_dof_coordinates()[nodes, :bs] + u.x.array.reshape(-1, bs)[nodes]
        depth = max(
            (float(np.max(-o.indenter.signed_distance_np(o.relative_np(x), o.y_tip.value)[0],
                          initial=0.0))
             for o in self.obstacles),
        )
        return V.mesh.comm.allreduce(depth, op=MPI.MAX)

    def active_set(self) -> np.ndarray:
        """Which of this rank's surface quadrature points are in contact, t_n − γ g > 0: one
        bool per point of the facet rule the contact integrates with (basix's default rule of
        `quadrature_degree`, FFCx's), facet after facet in the order of `facets`.

        The order is fixed, so comparing two iterates shows how many points entered or left
        the contact zone (benchmarks/line_load.py --newton prints it per Newton iteration).
        With smoothing the pressure is never exactly 0: this counts the penetrating points.
        """
        return self._trial_at_quadrature() > 0

    @cached_property
    def _trial_at_quadrature(self):
        domain = self.u.function_space.mesh
        fdim = domain.topology.dim - 1
        facet = domain.topology.entity_types[fdim][0]  # interval (2D) or triangle (3D)
        points, _ = basix.make_quadrature(basix.CellType[facet.name], self.quadrature_degree)
        compiled = fem.Expression(self.trial_pressure, points)
        entities = self._facet_entities

        return lambda: compiled.eval(domain, entities).ravel()

    @cached_property
    def _facet_entities(self) -> np.ndarray:
        """(cell, local facet) pairs of this rank's contact facets."""
        domain = self.u.function_space.mesh
        tdim = domain.topology.dim
        domain.topology.create_connectivity(tdim, tdim - 1)
        return fem.compute_integration_domains(
            fem.IntegralType.exterior_facet, domain.topology, self.facets).reshape(-1, 2)

    def surface_sampler(self, expr, points_per_facet: int = 5, points=None):
        """A function returning (X, values) of the vector or scalar UFL `expr` at points on
        this rank's owned surface facets: X (m, gdim) reference coordinates, values (m, ...).
        The points are those of a P(points_per_facet − 1) lattice on each facet (its ends in
        2D; in 3D the lattice of the triangle), or the facet's reference `points` if given.
        The expression is compiled once, here."""
        domain = self.u.function_space.mesh
        tdim = domain.topology.dim
        entities = self._facet_entities
        X = ufl.SpatialCoordinate(domain)
        gdim = domain.geometry.dim
        shape = expr.ufl_shape
        parts = [*(X[i] for i in range(gdim)),
                 *([expr[i] for i in range(shape[0])] if shape else [expr])]
        if points is None:
            points = _facet_points(tdim, points_per_facet)
        compiled = fem.Expression(ufl.as_vector(parts), np.asarray(points, dtype=float))

        def evaluate() -> tuple[np.ndarray, np.ndarray]:
            values = compiled.eval(domain, entities).reshape(-1, len(parts))
            return values[:, :gdim], values[:, gdim:] if shape else values[:, gdim]

        return evaluate

    def sample(self, expr, points_per_facet: int = 5) -> tuple[np.ndarray, np.ndarray]:
        """`expr` (e.g. `self.pressure`) at points on this rank's owned surface facets.

        Returns the reference coordinates X (m, gdim) of the points and the values (m,); the
        points of different ranks do not overlap. Facet ends are included (shared points appear
        once per facet, each with its own cell's value: the field may jump there).
        """
        return self.surface_sampler(expr, points_per_facet)()


def _check_options(method: str, theta: int, gamma0: float, smoothing, obstacles) -> None:
    """The contact's options, each refused with its key and the fix."""
    if method not in CONTACT_METHODS:
        raise InputError("model.contact", f"unknown contact method {method!r}.",
                         f"use one of {CONTACT_METHODS}.")
    if theta not in (-1, 0, 1):
        raise InputError(
            "contact.theta", f"got {theta}.",
            "use 0 (default, robust), 1 (symmetric) or -1 (skew-symmetric).",
        )
    if not gamma0 > 0:
        raise InputError("contact.gamma0", f"must be positive, got {gamma0}.", "use ~10.")
    if not (isinstance(smoothing, int | float) and smoothing >= 0):
        raise InputError("model.contact_smoothing", f"must be >= 0 (mm), got {smoothing!r}.",
                         "use 0 (exact) or a gap width well below the penetration, ~1e-4.")
    if not obstacles:
        raise InputError("contact", "no indenter given.", "give at least one Obstacle.")


def _facet_points(tdim: int, n: int) -> np.ndarray:
    """Reference points on a facet: n evenly spaced on an edge (2D), or the triangle's
    lattice with n points per side (3D)."""
    s = np.linspace(0.0, 1.0, n)
    if tdim == 2:
        return s[:, None]
    return np.array([(a, b) for a in s for b in s if a + b <= 1.0 + 1e-12])


def surface_mesh_size_at(ds_facets: np.ndarray, domain: dmesh.Mesh, x0: float) -> float:
    """Length of the palmar surface facet (of `ds_facets`, local) nearest to x = x0 (mm)."""
    fdim = domain.topology.dim - 1
    best = (np.inf, np.nan)
    if len(ds_facets):
        nodes = dmesh.entities_to_geometry(domain, fdim, ds_facets)
        pts = domain.geometry.x[nodes][:, :, :2]  # (facets, nodes, 2)
        ends = pts[:, :2]  # the two vertices come first
        mid = ends.mean(axis=1)
        palmar = mid[:, 1] < 0
        if palmar.any():
            dist = np.where(palmar, np.abs(mid[:, 0] - x0), np.inf)
            i = int(np.argmin(dist))
            best = (float(dist[i]), float(np.linalg.norm(ends[i, 1] - ends[i, 0])))
    everyone = domain.comm.allgather(best)
    return min(everyone)[1]


def check_tip_resolution(contact: NitscheContact) -> list[float]:
    """Surface element size under each indenter's tip; warns if it exceeds TIP_RESOLUTION
    tip radii (the tip could slip between quadrature points). Returns the sizes (mm).

    Plane strain only, where sharp tips (the wedge's 25 µm) are meshed for: in 3D the sizes
    are NaN and nothing is checked (the penetration of the surface nodes is still reported)."""
    domain = contact.u.function_space.mesh
    if domain.geometry.dim == 3:
        return [math.nan] * len(contact.obstacles)
    sizes = []
    for o in contact.obstacles:
        h = surface_mesh_size_at(contact.facets, domain, o.indenter.centre_x)
        r = o.indenter.tip_curvature_radius()
        sizes.append(h)
        if h > TIP_RESOLUTION * r:
            warnings.warn(
                f"the {o.indenter.shape} tip (radius {r:g} mm at x = {o.indenter.centre_x:g} mm) "
                f"meets surface elements of {h:.3g} mm, more than {TIP_RESOLUTION:g} tip radii: "
                "the tip can slip between the contact quadrature points and pierce the body "
                f"(the reported max_penetration will show it). Fix: refine around the tip: "
                f"section.mesh.tips = [{o.indenter.centre_x:g}] with tip_size <= "
                f"{TIP_RESOLUTION * r:.3g} mm.",
                TipResolutionWarning, stacklevel=3,
            )
    return sizes


def _ramp(x, width: float):
    """[x]_+, or for width δ > 0 its smooth version (x + sqrt(x² + δ²))/2 (within δ/2 of it).

    On a round tip the boundary of the contact zone sweeps over the surface quadrature points;
    with the exact kink Newton can cycle between active sets there (seen on the line load as
    a residual stalling near 1e-9 N/mm). A C∞ ramp of gap width δ removes the cycling.
    """
    if width == 0:
        return ufl.max_value(x, 0.0)
    return 0.5 * (x + ufl.sqrt(x * x + width * width))


def _nearest_indicators(gaps: list) -> list:
    """χ_i = 1 where indenter i is the nearest (ties to the lower index), else 0."""
    indicators = []
    for i, gi in enumerate(gaps):
        chi = 1.0
        for j, gj in enumerate(gaps):
            if j != i:
                closer = ufl.lt(gi, gj) if j < i else ufl.le(gi, gj)
                chi = chi * ufl.conditional(closer, 1.0, 0.0)
        indicators.append(chi)
    return indicators
