"""Post-processing: derived fields and point sampling that is exact in parallel.

Derived fields (logarithmic strain, principal log strains, strain energy density) are
interpolated into discontinuous P1 spaces by expressions compiled once; curves are sampled
with `determine_point_ownership`, which gives every point to exactly one rank, so serial and
parallel runs write the same rows.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
import ufl
from dolfinx import fem, geometry
from dolfinx import mesh as dmesh

from .outputs import FRICTION_SURFACE_COLUMNS, FRICTION_SURFACE_COLUMNS_3D
from .physics.admissibility import reference_vertices
from .physics.friction import contact_state
from .physics.kinematics import hencky_strain, principal_log_strains


class PointSampler:
    """Evaluates functions of one mesh at fixed points; results gathered on rank 0.

    `points` (n, gdim) must be the same on every rank. Points outside the mesh give NaN.
    """

    def __init__(self, msh: dmesh.Mesh, points: np.ndarray, padding: float = 1e-10):
        self.comm = msh.comm
        self.n = len(points)
        mine = np.zeros((self.n if self.comm.rank == 0 else 0, 3))
        if self.comm.rank == 0:
            mine[:, :np.shape(points)[1]] = points
        data = geometry.determine_point_ownership(msh, mine, padding)
        self._points = np.asarray(data.dest_points).reshape(-1, 3)
        self._cells = np.asarray(data.dest_cells, dtype=np.int32)
        # A point outside every cell is still handed to the closest one (on a submesh: the
        # pore pressure "at" points in the skin): keep only the points in (or on) their cell.
        self._inside = np.ones(len(self._cells), dtype=bool)
        if len(self._cells):
            d2 = geometry.squared_distance(msh, msh.topology.dim, self._cells, self._points)
            self._inside = d2 <= max(padding, 1e-12) ** 2
        # On rank 0: which rank evaluates each point (-1: outside the mesh). A rank receives
        # its points in the order rank 0 sent them.
        self._owner = np.asarray(data.src_owner) if self.comm.rank == 0 else None

    def __call__(self, f: fem.Function) -> np.ndarray | None:
        """Values (n, value size) on rank 0, None on the other ranks."""
        size = f.function_space.dofmap.index_map_bs
        shape = f.function_space.value_shape
        size = int(np.prod(shape)) if shape else 1
        values = (f.eval(self._points, self._cells).reshape(-1, size) if len(self._cells)
                  else np.zeros((0, size)))
        values[~self._inside] = np.nan
        gathered = self.comm.gather(values, root=0)
        if self.comm.rank != 0:
            return None
        out = np.full((self.n, size), np.nan)
        for rank, vals in enumerate(gathered):
            out[np.flatnonzero(self._owner == rank)] = vals
        return out


class DerivedFields:
    """Log strain, principal log strains (max, min) and strain energy density as DG1 functions.

    `energies` maps a cell-tag value to the UFL strain energy density of that region.
    Plane strain: ½ ln b and the in-plane principal values in UFL (kinematics). 3D: b = F Fᵀ is
    interpolated (exact at the DG1 nodes) and decomposed there by numpy's symmetric eigensolver,
    which is exact at repeated eigenvalues too (a UFL spectral projector is 0/0 there).
    """

    def __init__(self, u: fem.Function, cell_tags: dmesh.MeshTags, energies: dict[int, object]):
        msh = u.function_space.mesh
        d = len(u)
        F = ufl.Identity(d) + ufl.grad(u)
        tensor = fem.functionspace(msh, ("Discontinuous Lagrange", 1, (d, d)))
        vector = fem.functionspace(msh, ("Discontinuous Lagrange", 1, (2,)))
        scalar = fem.functionspace(msh, ("Discontinuous Lagrange", 1))
        self.log_strain = fem.Function(tensor, name="log_strain")
        self.principal = fem.Function(vector, name="principal_log_strain")
        self.sed = fem.Function(scalar, name="strain_energy_density")
        self._sed_by_region = []
        points = tensor.element.interpolation_points
        if d == 2:
            self._b = None
            self._plan = [
                (self.log_strain, fem.Expression(hencky_strain(F), points)),
                (self.principal, fem.Expression(ufl.as_vector(principal_log_strains(F)),
                                                vector.element.interpolation_points)),
            ]
        else:
            self._b = fem.Function(tensor)
            self._plan = [(self._b, fem.Expression(F * F.T, points))]
        for tag, energy in energies.items():
            cells = cell_tags.find(tag)
            self._sed_by_region.append(
                (cells, fem.Expression(energy, scalar.element.interpolation_points))
            )

    def update(self) -> None:
        for f, expr in self._plan:
            f.interpolate(expr)
        if self._b is not None:
            c, n = np.linalg.eigh(self._b.x.array.reshape(-1, 3, 3))  # ascending c
            e = 0.5 * np.log(c)
            self.log_strain.x.array[:] = np.einsum("kia,ka,kja->kij", n, e, n).ravel()
            self.principal.x.array.reshape(-1, 2)[:] = e[:, ::-1][:, [0, 2]]
        for cells, expr in self._sed_by_region:
            self.sed.interpolate(expr, cells0=cells)
        for f in (self.log_strain, self.principal, self.sed):
            f.x.scatter_forward()


class QuadratureProjection:
    """Square (gdim × gdim) tensor expressions, one per set of cells, evaluated at the quadrature
    points of
    degree `quadrature_degree` (where a QLV history lives) and projected onto a DG1 tensor
    function cell by cell (least squares with the rule's weights: the local L2 projection on
    affine cells). `update()` re-evaluates them."""

    def __init__(self, msh, plan: list[tuple[np.ndarray, ufl.core.expr.Expr]],
                 quadrature_degree: int, name: str):
        import basix

        self.mesh = msh
        d = msh.geometry.dim
        space = fem.functionspace(msh, ("Discontinuous Lagrange", 1, (d, d)))
        self.stress = fem.Function(space, name=name)
        points, weights = basix.make_quadrature(msh.basix_cell(), quadrature_degree)
        p1 = basix.create_element(basix.ElementFamily.P, msh.basix_cell(), 1,
                                  discontinuous=True)
        phi = p1.tabulate(0, points)[0, :, :, 0]  # (points, dofs), the dofs in DG1's order
        wphi = weights[:, None] * phi
        self._fit = np.linalg.solve(phi.T @ wphi, wphi.T)  # (dofs, points)
        self._plan = [(cells, fem.Expression(expr, points)) for cells, expr in plan]

    def update(self) -> None:
        size = self.mesh.geometry.dim**2
        values = self.stress.x.array.reshape(-1, size)
        dofmap = self.stress.function_space.dofmap.list
        n = self._fit.shape[1]
        for cells, expr in self._plan:
            if len(cells):
                at_points = expr.eval(self.mesh, cells).reshape(len(cells), n, size)
                values[dofmap[cells]] = np.einsum("dq,cqk->cdk", self._fit, at_points)
        self.stress.x.scatter_forward()


class CauchyStress(QuadratureProjection):
    """The Cauchy stress σ = P Fᵀ / J of each region's own law as a DG1 tensor (MPa), at an
    accepted state (after `problem.accept()`: where a run's `on_step` is).

    `laws` maps a cell-tag value to that region's law (model.py; `.stress` is P). A law with a
    history (the skin's QLV) is evaluated with its stored internal variables, P = F (g∞ S_e +
    Σ g_i h_i): its own `.stress` would advance them once more. σ is evaluated at the quadrature
    points of the stress integral (`quadrature_degree`, where the QLV history lives) and
    projected onto P1 cell by cell (`QuadratureProjection`). The pore pressure is not part of
    any law: the total stress of the subcutaneous tissue is σ − p I.
    """

    def __init__(self, u: fem.Function, cell_tags: dmesh.MeshTags, laws: dict[int, object],
                 quadrature_degree: int):
        F = ufl.Identity(len(u)) + ufl.grad(u)
        plan = [(cell_tags.find(tag), accepted_stress(law, F) * F.T / ufl.det(F))
                for tag, law in laws.items()]
        super().__init__(u.function_space.mesh, plan, quadrature_degree, "cauchy_stress")


def accepted_stress(law, F) -> ufl.core.expr.Expr:
    """P of a region's law at its accepted state: `law.stress`, or for a QLV law F (g∞ S_e +
    Σ g_i h_i) with the internal variables as stored by the last `accept()`."""
    qlv = getattr(law, "history", None)
    if qlv is None:
        return law.stress
    prony = qlv.prony
    return F * (prony.g_inf * qlv.S_e + sum(g * h for g, h in zip(prony.g, qlv.h)))


def depth_curve(outer, depth: float, half_width: float, n: int,
                x: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Points at `depth` below the palmar outer ellipse, along its inward normals.

    Returns (x of the surface points the normals start from, the points (n, 2)). The surface
    points are n evenly spaced in |x| <= half_width, or those at the abscissae `x` if given.
    """
    x = np.linspace(-half_width, half_width, n) if x is None else np.asarray(x, dtype=float)
    return x, outer.below_palmar(x, depth)


def sample_curves(curves, problem, derived: DerivedFields):
    """Per depth curve (depth, x0, sampler, pressure sampler): the sampled u, log strain,
    principal log strains, SED and pore pressure (None without one), yielded on rank 0 only
    (every rank samples: the samplers are collective)."""
    derived.update()
    for d, x0, sampler, sub in curves:
        u, e = sampler(problem.u), sampler(derived.log_strain)
        pe, w = sampler(derived.principal), sampler(derived.sed)
        pp = sub(problem.p) if sub is not None else None
        if problem.mesh.comm.rank == 0:
            yield d, x0, u, e, pe, w, pp


class Profiles:
    """The pulp surface's deflection and the depth profiles of one run, at output times.

    `problem` is the run's FingertipProblem, `derived` its DerivedFields, `outer` the section's
    outer ellipse, `outputs` the scene's Outputs. Rows are returned on rank 0 (empty elsewhere).
    """

    def __init__(self, problem, derived: DerivedFields, outer, outputs):
        self.problem, self.derived, self.outputs = problem, derived, outputs
        self.comm = problem.mesh.comm
        self.curves = []
        for d in outputs.depths:
            x0, points = depth_curve(outer, d, outputs.profile_half_width, outputs.profile_points)
            sub = PointSampler(problem.submesh, points) if problem.p is not None else None
            self.curves.append((d, x0, PointSampler(problem.mesh, points), sub))

    def surface_rows(self, t: float) -> list[dict]:
        """Vertical displacement of the pulp nodes (the nail centre is held: deflection)."""
        X, x = self.problem.pulp_nodes()
        keep = np.abs(X[:, 0]) <= self.outputs.profile_half_width
        gathered = self.comm.gather((X[keep, 0], (x - X)[keep, 1]), root=0)
        # collective: every rank samples the friction's fields
        friction = None if self.problem.friction is None else self.stick_slip_rows(t)
        if self.comm.rank != 0:
            return []
        xs = np.concatenate([g[0] for g in gathered])
        ys = np.concatenate([g[1] for g in gathered])
        xs, unique = np.unique(np.round(xs, 12), return_index=True)
        rows = [{"x_mm": a, "time_s": t, "deflection_mm": b} for a, b in zip(xs, ys[unique])]
        return rows if friction is None else self._with_friction(rows, friction)

    @staticmethod
    def _with_friction(rows: list[dict], friction: list[dict]) -> list[dict]:
        """The surface rows with the friction columns (`stick_slip_rows`) of the same node."""
        xs = np.array([r["x_mm"] for r in friction])
        keys = FRICTION_SURFACE_COLUMNS
        # the same nodes, their x from the dof table and from the facet points: the nearest
        nearest = [int(np.argmin(np.abs(xs - r["x_mm"]))) for r in rows]
        return [r | {k: friction[i][k] for k in keys} for r, i in zip(rows, nearest)]

    @cached_property
    def _friction_sampler(self):
        contact, friction = self.problem.contact, self.problem.friction
        parts = ufl.as_vector([contact.pressure, friction.tangential_traction,
                               friction.stick_margin])
        # 3 points per facet: its ends and middle, the P2 displacement's nodes on it
        return contact.surface_sampler(parts, points_per_facet=3)

    def stick_slip_rows(self, t: float) -> list[dict]:
        """With friction: the pressure, tangential traction, stick margin and contact state at
        the pulp nodes with |x| <= profile_half_width (rank 0). Each value is a facet's at
        its middle; a node at the ends of two facets gets the mean of theirs (at a facet's
        ends the Nitsche traction estimate comes from one cell's stress and is noisy: on
        the coarse shear mesh it shows every other node sticking in gross slip). The state
        is that of the row's margin, so the two always agree."""
        X, values = self._friction_sampler()
        # (facets, 3 points, 3 values); a rank without contact facets has empty, flat arrays
        values = np.asarray(values).reshape(-1, 3, 3)
        # the middle's values for all three points of each facet
        x, values = X[:, 0], np.repeat(values[:, 1], 3, axis=0)
        gathered = self.comm.gather((x, values), root=0)
        if self.comm.rank != 0:
            return []
        x = np.concatenate([g[0] for g in gathered])
        v = np.concatenate([g[1] for g in gathered])
        keep = np.abs(x) <= self.outputs.profile_half_width + 1e-12
        xs, inverse, counts = np.unique(np.round(x[keep], 12), return_inverse=True,
                                        return_counts=True)
        mean = np.column_stack([np.bincount(inverse, w) for w in v[keep].T]) / counts[:, None]
        states = contact_state(mean[:, 0], mean[:, 2])
        return [{"x_mm": a, "time_s": t, "pressure_MPa": p, "tangential_traction_MPa": q,
                 "stick_margin_MPa": m, "contact_state": int(s)}
                for a, (p, q, m), s in zip(xs, mean, states)]

    def depth_rows(self, t: float) -> list[dict]:
        """Displacement, log strains, SED and pore pressure along each depth curve."""
        rows = []
        for d, x0, u, e, pe, w, pp in sample_curves(self.curves, self.problem, self.derived):
            for i, xs in enumerate(x0):
                rows.append({
                    "x_mm": xs, "depth_mm": d, "time_s": t, "u1_mm": u[i, 0], "u2_mm": u[i, 1],
                    "e11": e[i, 0], "e22": e[i, 3], "e12": e[i, 1], "e_max": pe[i, 0],
                    "e_min": pe[i, 1], "sed_MPa": w[i, 0],
                    "p_MPa": pp[i, 0] if pp is not None else np.nan})
        return rows


class Profiles3D:
    """A 3D run's profiles at output times, in the cross-section z = `z_c` and along the line
    x = `x_c` of the pulp: the surface's vertical deflection across and along the finger,
    the depth profiles (the 2D section's depth curves, placed in the plane z = z_c: the
    cylindrical part's cross-section is the 2D outer ellipse) and the indenters' y-force per
    unit length of finger, f(z) (N/mm: what a plane-strain section would carry).

    Surface points lie on the exact outer surface, outside the faceted mesh by up to the chord
    sag h²/8R (h the section's max_size, R the smallest radius of curvature): they are
    evaluated in the nearest cell within 1.5 times that distance. Rows are returned on rank 0
    (empty elsewhere).
    """

    def __init__(self, problem, derived: DerivedFields, tip, outputs, z_c: float, x_c: float):
        self.problem, self.derived, self.outputs = problem, derived, outputs
        self.comm = problem.mesh.comm
        self.z_c, self.x_c = z_c, x_c
        w, n = outputs.profile_half_width, outputs.profile_points
        x = np.linspace(-w, w, n)
        if "symmetry" in problem.tags:
            x = x[x >= 0.0]  # the half model's side
        z = np.linspace(0.0, tip.total_length, n)
        a, b = tip.outer_semi_axes(z)
        z = z[a > abs(x_c) + 1e-9]
        self.across = self._surface(tip, x, np.full_like(x, z_c))
        self.along = self._surface(tip, np.full_like(z, x_c), z)
        # a sample point lies over a contact facet within the chord sag (as `_surface`)
        self.reach = 1.5 * tip.section.mesh.max_size**2 / (8 * tip.outer.min_curvature_radius)
        self.curves = []
        for d in outputs.depths:
            x0, points = depth_curve(tip.outer, d, w, n, x)
            points = np.column_stack([points, np.full(len(points), z_c)])
            sub = PointSampler(problem.submesh, points) if problem.p is not None else None
            self.curves.append((d, x0, PointSampler(problem.mesh, points), sub))
        self.edges = np.arange(0.0, tip.total_length + 0.5, 0.5)

    def _surface(self, tip, x, z):
        a, b = tip.outer_semi_axes(z)
        y = tip.outer.cy - b * np.sqrt(np.clip(1 - (x / a) ** 2, 0.0, None))
        points = np.column_stack([x, y, z])
        sag = tip.section.mesh.max_size**2 / (8 * tip.outer.min_curvature_radius)
        return points, PointSampler(self.problem.mesh, points, 1.5 * sag)

    def surface_rows(self, t: float, direction: str) -> list[dict]:
        """u_y on the pulp surface "across" (z = z_c) or "along" (x = x_c) the finger; with
        friction, and the friction's columns (`friction_rows`) at the same points."""
        points, sampler = self.across if direction == "across" else self.along
        u = sampler(self.problem.u)
        friction = None if self.problem.friction is None else self.friction_rows(t, direction)
        if self.comm.rank != 0:
            return []
        rows = [{"x_mm": X[0], "z_mm": X[2], "time_s": t, "deflection_mm": ui[1]}
                for X, ui in zip(points, u)]
        return rows if friction is None else [r | f for r, f in zip(rows, friction)]

    @cached_property
    def _friction(self) -> SurfaceFriction:
        return SurfaceFriction(self.problem.contact, self.problem.friction)

    def friction_rows(self, t: float, direction: str = "along") -> list[dict]:
        """With friction (collective; rows on rank 0): the friction's columns
        (FRICTION_SURFACE_COLUMNS_3D, `SurfaceFriction`) at the surface points "along"
        (x = x_c) or "across" (z = z_c) the finger."""
        points = (self.across if direction == "across" else self.along)[0]
        values = self._friction.at(points, self.reach)
        if self.comm.rank != 0:
            return []
        return [{"x_mm": X[0], "z_mm": X[2], "time_s": t}
                | dict(zip(FRICTION_SURFACE_COLUMNS_3D, (*row[:5], int(row[5]))))
                for X, row in zip(points, values)]

    def depth_rows(self, t: float) -> list[dict]:
        """Displacement, log strains, SED and pore pressure along each depth curve."""
        rows = []
        for d, x0, u, e, pe, w, pp in sample_curves(self.curves, self.problem, self.derived):
            for i, xs in enumerate(x0):
                rows.append({
                    "x_mm": xs, "z_mm": self.z_c, "depth_mm": d, "time_s": t,
                    "u1_mm": u[i, 0], "u2_mm": u[i, 1], "u3_mm": u[i, 2], "e11": e[i, 0],
                    "e22": e[i, 4], "e33": e[i, 8], "e12": e[i, 1], "e_max": pe[i, 0],
                    "e_min": pe[i, 1], "sed_MPa": w[i, 0],
                    "p_MPa": pp[i, 0] if pp is not None else np.nan})
        return rows

    def line_force_rows(self, t: float) -> list[dict]:
        """f(z), the indenters' y-force per unit length of finger on 0.5 mm slabs (N/mm)."""
        f = self.problem.contact.line_force(2, self.edges) * self.problem.mirror_factor
        if self.comm.rank != 0:
            return []
        mid = 0.5 * (self.edges[:-1] + self.edges[1:])
        return [{"z_mm": z, "time_s": t, "force_per_length_N_per_mm": v} for z, v in zip(mid, f)]


class SurfaceFriction:
    """A 3D contact's friction at given points of the surface: the pressure, the tangential
    traction's x, y and z parts, the stick margin and the contact state (the columns
    FRICTION_SURFACE_COLUMNS_3D). A point takes the values of the contact facet it lies on
    or over (within `reach`: `facets_under`), those at the facet's centroid (as the 2D rows
    are the facets' middles': `Profiles.stick_slip_rows`); a point over none (off the contact
    surface) has NaN values and the state free (no indenter can touch it there). The values
    are the last accepted step's (`CoulombFriction.accepted`): measure after `mark_accepted`."""

    def __init__(self, contact, friction):
        self.comm = contact.u.function_space.mesh.comm
        traction, margin = friction.accepted  # measured after the step is accepted
        parts = ufl.as_vector([contact.pressure, *(traction[i] for i in range(3)), margin])
        self._sampler = contact.surface_sampler(parts, points=np.array([[1.0, 1.0]]) / 3.0)
        self._corners = facet_corners(contact.u.function_space.mesh, contact._facet_entities)

    def at(self, points: np.ndarray, reach: float) -> np.ndarray | None:
        """(n, 6) on rank 0 (None elsewhere): the values at the reference `points` (n, 3),
        the state (`contact_state`) last. Collective."""
        values = np.asarray(self._sampler()[1]).reshape(-1, 5)
        which, distance = facets_under(points, self._corners, reach)
        picked = np.full((len(points), 5), np.nan)
        picked[which >= 0] = values[which[which >= 0]]
        gathered = self.comm.gather((distance, picked), root=0)
        if self.comm.rank != 0:
            return None
        d = np.array([g[0] for g in gathered])  # (ranks, points): the nearest rank's facet
        v = np.array([g[1] for g in gathered])[np.argmin(d, axis=0), np.arange(len(points))]
        return np.column_stack([v, contact_state(v[:, 0], v[:, 4])])


def facet_corners(msh: dmesh.Mesh, entities: np.ndarray) -> np.ndarray:
    """The reference corners (m, 3, gdim) of the triangles given as (cell, local facet) pairs
    (m, 2) of a tetrahedral mesh."""
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim, tdim - 1)
    c2f = msh.topology.connectivity(tdim, tdim - 1)
    facets = np.array([c2f.links(c)[f] for c, f in entities], dtype=np.int32)
    if not len(facets):
        return np.zeros((0, 3, msh.geometry.dim))
    nodes = dmesh.entities_to_geometry(msh, tdim - 1, facets)[:, :3]  # the vertices first
    return msh.geometry.x[nodes][..., :msh.geometry.dim]


def facets_under(points: np.ndarray, corners: np.ndarray,
                 reach: float) -> tuple[np.ndarray, np.ndarray]:
    """For each point (n, 3): the index of the triangle (of `corners`, (m, 3, 3)) nearest to
    it, and the distance, where that is at most `reach`; else -1 and inf. The distance is the
    point's to the nearest point of the triangle, found by clamping the barycentric
    coordinates of its projection on the triangle's plane (exact inside, and beside an edge;
    over a corner an upper bound)."""
    n = len(points)
    if not len(corners):
        return np.full(n, -1), np.full(n, np.inf)
    a, e1, e2 = corners[:, 0], corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    d = points[:, None, :] - a[None]  # (n, m, 3)
    g11, g12, g22 = (e1 * e1).sum(-1), (e1 * e2).sum(-1), (e2 * e2).sum(-1)
    b1, b2 = np.einsum("nmk,mk->nm", d, e1), np.einsum("nmk,mk->nm", d, e2)
    det = g11 * g22 - g12**2
    s = np.clip((g22 * b1 - g12 * b2) / det, 0.0, None)
    t = np.clip((g11 * b2 - g12 * b1) / det, 0.0, None)
    over = np.maximum(s + t, 1.0)  # beyond the third edge: back onto it
    s, t = s / over, t / over
    gap = d - s[..., None] * e1[None] - t[..., None] * e2[None]
    distance = np.linalg.norm(gap, axis=-1)
    which = np.argmin(distance, axis=1)
    best = distance[np.arange(n), which]
    far = best > reach
    return np.where(far, -1, which), np.where(far, np.inf, best)


class FieldArrays:
    """The state's fields as plain arrays, cell by cell, gathered on rank 0.

    `__call__()` returns (rank 0; None elsewhere): each owned cell's corners in the reference
    configuration `X` (cells, corners, gdim), the displacement there `u`, the cell's region tag
    `region`, and the derived fields at the corners (discontinuous P1, so exact): `sed` (MPa),
    `log_strain` (cells, corners, gdim²: e11, e12, e21, e22 in 2D), `principal` (e_max, e_min);
    with a
    pore pressure, the subcutaneous submesh's corners `X_p`, their displacement `u_p` and `p`.
    """

    def __init__(self, problem, derived: DerivedFields):
        self.problem, self.derived = problem, derived
        msh = problem.mesh
        self.gdim = msh.geometry.dim
        self.u1 = fem.Function(fem.functionspace(msh, ("Lagrange", 1, (self.gdim,))))
        self.nodes = _owned_cell_nodes(msh)
        self.region = _cell_regions(problem.fmesh.cell_tags, len(self.nodes))
        if problem.p is not None:
            self.sub_nodes = _owned_cell_nodes(problem.submesh)

    def __call__(self) -> dict[str, np.ndarray] | None:
        p, msh = self.problem, self.problem.mesh
        self.derived.update()
        self.u1.interpolate(p.u)  # exact at the vertices, where the corners are
        disp = node_values(self.u1)
        cells = np.arange(len(self.nodes), dtype=np.int32)
        local = {"X": msh.geometry.x[self.nodes][..., :self.gdim], "u": disp[self.nodes],
                 "region": self.region,
                 **{name: _dg_corner_values(f, cells) for name, f in (
                     ("sed", self.derived.sed), ("log_strain", self.derived.log_strain),
                     ("principal", self.derived.principal))}}
        if p.p is not None:
            sub = self.sub_nodes
            local["X_p"] = p.submesh.geometry.x[sub][..., :self.gdim]
            local["u_p"] = disp[p.submesh_nodes][sub]
            local["p"] = node_values(p.p)[sub][..., 0]
        gathered = msh.comm.gather(local, root=0)
        if msh.comm.rank != 0:
            return None
        return {k: np.concatenate([g[k] for g in gathered]) for k in local}


def _owned_cell_nodes(msh: dmesh.Mesh) -> np.ndarray:
    """Geometry nodes of the owned cells' corners (cells, corners)."""
    tdim = msh.topology.dim
    n = msh.topology.index_map(tdim).size_local
    corners = len(reference_vertices(msh))
    return msh.geometry.dofmaps[0][:n, :corners]


def _dg_corner_values(f: fem.Function, cells: np.ndarray) -> np.ndarray:
    """A discontinuous P1 function's values at the corners of `cells` (cells, corners, size):
    its dofs are the corner values, in the cell's vertex order."""
    bs = f.function_space.dofmap.index_map_bs
    dofs = f.function_space.dofmap.list[cells]
    return f.x.array.reshape(-1, bs)[dofs]


def node_values(f: fem.Function) -> np.ndarray:
    """A P1 function's values at its mesh's geometry nodes, shape (nodes, block size)."""
    msh, V = f.function_space.mesh, f.function_space
    bs = V.dofmap.index_map_bs
    values = np.zeros((msh.geometry.x.shape[0], bs))
    corners = V.dofmap.list.shape[1]
    values[msh.geometry.dofmaps[0][:, :corners].ravel()] = (
        f.x.array.reshape(-1, bs)[V.dofmap.list.ravel()])
    return values


def _cell_regions(cell_tags: dmesh.MeshTags, n: int) -> np.ndarray:
    regions = np.zeros(n, dtype=np.int32)
    owned = cell_tags.indices < n
    regions[cell_tags.indices[owned]] = cell_tags.values[owned]
    return regions
