"""Mindlin's sphere: a rigid sphere pressed into a linear-elastic block with Coulomb friction,
then dragged along the surface, and the closed-form stick radius and tangential traction;
`drag_sphere`, the press and drag with the stick zone measured along and across the drag."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from ...geometry.indenters import Sphere
from ...physics.contact import NitscheContact, Obstacle
from ...physics.friction import CoulombFriction
from .hertz import HertzSphere
from .mindlin import (
    MindlinBlock,
    check_poisson,
    elasticity,
    half_space_modulus,
    press_and_drag,
    stick_halfwidth,
)


@dataclass(frozen=True)
class MindlinSphere(HertzSphere):
    """A rigid sphere of radius R pressed by `depth` into the face y = 0 of a linear-elastic
    block [−L, L] × [0, L] × [0, L], then moved along x: a half model (the drag along x keeps
    the mirror symmetry about the plane z = 0, u_z = 0 there; it breaks the one about x = 0),
    the top y = L fixed, small strain, Nitsche contact with Coulomb friction μ.

    Mindlin (1949); Johnson, Contact Mechanics (1985), §7.2: under a normal force P (N) and a
    tangential force Q < μP along x applied monotonically from 0, the Hertz contact of radius a
    sticks on r < c, c = a (1 − Q/(μP))^(1/3), and slips on c < r < a, the traction being
    parallel to x, q(r) = (3μP/(2πa³)) (sqrt(a² − r²) − sqrt(c² − r²)) (the second root on
    r < c only; 3μP/(2πa³) = μ p0/a); Q = μP: gross slip, c = 0.

    Two approximations make it closed-form (docs/benchmarks/friction.md, "3D: a sphere"): the
    tangential traction does not change the pressure (exact when the Dundurs constant
    β = (1 − 2ν)/(2(1 − ν)) of a rigid indenter vanishes, ν = 1/2), and the traction in the slip
    annulus is parallel to x (exact for ν = 0: for ν > 0 the surface's slip has a component
    across x of relative size ~ν/(2 − ν)). The stick zone's conditions (u_x uniform, u_z = 0
    on r < c) hold exactly for any ν. No ν makes both exact for a rigid sphere; ν = 0.45 keeps
    β small (0.091, β/μ = 0.18: pressing with friction locks in a radial shear of order β p,
    Spence 1975) without the nearly incompressible P2 stress of ν = 0.49. At ν = 0.3 (β = 0.29)
    the press locked in a radial traction of 0.5 μ p0 and the stick zone across the drag came
    out 0.2 a smaller than Mindlin's (measured, a/1.5).
    """

    nu: float = 0.45
    mu: float = 0.5  # the friction coefficient
    mixed: bool = False  # Taylor–Hood (u, p) instead of the displacement alone

    def __post_init__(self):
        check_poisson("MindlinSphere.nu", self.nu, self.mixed)

    @classmethod
    def exact(cls, **fields) -> MindlinSphere:
        """The block with the closed form's coupling and slope errors removed, as
        `CattaneoMindlin.exact()`: ν = 1/2 (β = 0: no coupling of pressure and tangential
        traction, nothing locked in by the press), Taylor–Hood P2/P1; R = 10 mm pressed
        0.25 µm, for the same a ≈ 0.05 mm with a/R = 0.005 (the pressure's x-share p x/R,
        a load the half-space solution leaves out, 10 times smaller; P ∝ a³/R: the depth and
        the shifts for a given Q/(μP) scale as 1/R). Left: the traction parallel to x, exact
        only at ν = 0 (the class docstring)."""
        return cls(**{"nu": 0.5, "mixed": True, "R": 10.0, "depth": 2.5e-4, **fields})

    @property
    def modulus(self) -> float:
        """M of Nitsche's γ = γ0 M/h (MPa): λ + 2G for the displacement element, E* (finite at
        ν = 1/2) for the mixed one."""
        return half_space_modulus(self.E, self.nu) if self.mixed else super().modulus

    @property
    def shear_modulus(self) -> float:
        """G = E/(2(1 + ν)) (MPa): sets the friction's γ_t = γ0 G/h."""
        return self.E / (2 * (1 + self.nu))

    def stick_theory(self, force: float, tangential: float) -> float:
        """Mindlin's stick radius c (mm) under P = `force`, Q = `tangential` (N)."""
        a, _ = self.theory(force)
        return a * max(1.0 - abs(tangential) / (self.mu * force), 0.0) ** (1 / 3)

    def traction_theory(self, r, force: float, tangential: float) -> np.ndarray:
        """q_x(r) (MPa), Mindlin's tangential traction at the distance r from the centre."""
        a, p0 = self.theory(force)
        c = self.stick_theory(force, tangential)
        r = np.asarray(r, dtype=float)
        q = np.sqrt(np.clip(a**2 - r**2, 0, None)) - np.sqrt(np.clip(c**2 - r**2, 0, None))
        return np.sign(tangential) * self.mu * p0 / a * q

    def _gmsh_box(self, gmsh) -> None:
        """Two boxes x < 0 and x > 0, fused conformally: the line x = 0 of the contact face is
        a mesh edge, so the stick zone can be sampled across the drag there."""
        L = self.L
        gmsh.model.add("half block")
        occ = gmsh.model.occ
        occ.fragment([(3, occ.addBox(-L, 0, 0, L, L, L))], [(3, occ.addBox(0, 0, 0, L, L, L))])
        occ.synchronize()
        tags = {self.BOTTOM: [], self.TOP: [], self.SYMMETRY_Z: []}
        for face in gmsh.model.getEntities(2):
            _, y, z = occ.getCenterOfMass(*face)
            tag = (self.BOTTOM if y < 1e-9 else self.TOP if y > L - 1e-9
                   else self.SYMMETRY_Z if z < 1e-9 else 0)
            if tag:
                tags[tag].append(face[1])
        for tag, faces in tags.items():
            gmsh.model.addPhysicalGroup(2, faces, tag)
        gmsh.model.addPhysicalGroup(3, [v[1] for v in gmsh.model.getEntities(3)], 1)

    def block(self, domain, facet_tags, *, gamma0: float = 10.0) -> SphereBlock:
        """The P2 displacement (with `mixed`, and the P1 pressure), the sphere (touching at the
        origin, movable in x and y), the contact and friction (γ_t = γ0 G/h) terms, the
        residual, the clamped top and the symmetry plane z = 0 on rollers."""
        u, p, P, v, residuals = elasticity(self, domain)
        V = u.function_space
        obstacle = Obstacle.at(domain, Sphere(radius=self.R), y_tip=0.0, x_tip=0.0)
        ds = ufl.Measure("ds", domain, subdomain_data=facet_tags)
        contact = NitscheContact(u, P, ds(self.BOTTOM), [obstacle], modulus=self.modulus,
                                 gamma0=gamma0)
        friction = CoulombFriction(contact, self.mu, gamma_ratio=self.shear_modulus / self.modulus)
        residuals[0] = residuals[0] + contact.residual(v) + friction.residual(v)
        fdim = domain.topology.dim - 1
        top = fem.locate_dofs_topological(V, fdim, facet_tags.find(self.TOP))
        side = fem.locate_dofs_topological(V.sub(2), fdim, facet_tags.find(self.SYMMETRY_Z))
        bcs = [fem.dirichletbc(np.zeros(3), top, V), fem.dirichletbc(0.0, side, V.sub(2))]
        residual = residuals if p is not None else residuals[0]
        return SphereBlock(u, P, obstacle, contact, friction, residual, bcs, facet_tags, p)


@dataclass(frozen=True)
class SphereBlock(MindlinBlock):
    """A built half model of `MindlinSphere`: solve `residual` = 0 for `unknowns` (u, or the
    mixed block's [u, p]) with `bcs`, moving the sphere by `obstacle.y_tip` and
    `obstacle.x_tip`; `friction.mark_accepted()` after each accepted step. Forces are the whole
    sphere's (twice the half's x and y components)."""

    def forces(self) -> tuple[float, float]:
        """(tangential Q along x, normal P along y) the sphere puts on the block (N)."""
        fx, fy, _ = self.friction.forces()[0]
        return 2 * float(fx), 2 * float(fy)

    def surface(self, points_per_facet: int = 5) -> dict[str, np.ndarray]:
        """At points on the contact face, gathered from every rank: the reference X (m, 3), the
        surface's displacement u (m, 3), the pressure p, the friction traction f (m, 3) (MPa)
        and the stick margin μp − |t_t − γ_t Δs_t| (> 0 sticks)."""
        contact, friction = self.contact, self.friction
        comm = self.u.function_space.mesh.comm
        fields = {"u": self.u, "p": contact.pressure, "f": friction.traction,
                  "margin": friction.stick_margin}
        out = {}
        for name, expr in fields.items():
            X, values = contact.sample(expr, points_per_facet=points_per_facet)
            out["X"], out[name] = (np.concatenate(comm.allgather(a)) for a in (X, values))
        return out

    @cached_property
    def _closed_form(self) -> tuple[list, list[fem.Form]]:
        """Constants (a, c, p0, x_tip, sign of Q) and the forms ∫|f_x − q_th| ds, ∫|q_th| ds,
        ∫|p − p_th| ds, ∫|p_th| ds, ∫|f_z| ds over the contact face, r about the sphere's axis
        at the surface's current position; q_th Mindlin's, p_th Hertz's."""
        domain = self.u.function_space.mesh
        a, c, p0, x_tip, sign = (fem.Constant(domain, 1.0) for _ in range(5))
        x = ufl.SpatialCoordinate(domain) + self.u
        r2 = (x[0] - x_tip) ** 2 + x[2] ** 2

        def root(b):
            return ufl.sqrt(ufl.max_value(b**2 - r2, 0.0))
        q_th = sign * self.friction.mu[0] * p0 / a * (root(a) - root(c))
        p_th = p0 / a * root(a)
        ds = self.contact.ds  # the quadrature that integrates the forces
        pairs = ((self.friction.traction[0], q_th), (self.contact.pressure, p_th))
        forms = [fem.form(abs(f) * ds) for value, th in pairs for f in (value - th, th)]
        return [a, c, p0, x_tip, sign], forms + [fem.form(abs(self.friction.traction[2]) * ds)]

    def face_integrals(self, a: float, c: float, p0: float, x_tip: float,
                       sign: float) -> np.ndarray:
        """Over the half model's contact face (N): ∫|f_x − q_th| ds, ∫|q_th| ds,
        ∫|p − p_th| ds, ∫|p_th| ds, ∫|f_z| ds, with Mindlin's q_th (stick radius c, the sign
        of Q) and Hertz's p_th (a, p0) about the sphere at x_tip."""
        constants, forms = self._closed_form
        for constant, value in zip(constants, (a, c, p0, x_tip, sign)):
            constant.value = value
        comm = self.u.function_space.mesh.comm
        return np.array([comm.allreduce(fem.assemble_scalar(f), op=MPI.SUM) for f in forms])

    def l1_distances(self, a: float, c: float, p0: float, x_tip: float,
                     sign: float) -> tuple[float, float, float]:
        """(∫|f_x − q_th| ds, ∫|p − p_th| ds / ∫|p_th| ds, ∫|f_z| ds), the first and last
        over ∫|q_th| ds (NaN if q_th = 0): integrals over the whole contact face
        (`face_integrals`; a traction outside the closed form's contact is error too)."""
        n_q, d_q, n_p, d_p, n_z = self.face_integrals(a, c, p0, x_tip, sign)
        q_scale = d_q if d_q > 0 else np.nan
        return float(n_q / q_scale), float(n_p / d_p), float(n_z / q_scale)


def stick_radii(X: np.ndarray, margin: np.ndarray, x0: float = 0.0) -> tuple[float, float]:
    """The stick zone's half-widths (mm) along the drag (on the line z = 0) and across it (on
    the line x = x0, mirrored about z = 0), from the stick margin's zero crossings
    (`stick_halfwidth`); the lines are mesh edges, so the points are exactly on them."""
    along = np.abs(X[:, 2]) < 1e-12
    order = np.argsort(X[along, 0], kind="stable")
    c_along = stick_halfwidth(X[along, 0][order], margin[along][order])
    across = np.abs(X[:, 0] - x0) < 1e-12
    z = np.concatenate([-X[across, 2], X[across, 2]])
    m = np.concatenate([margin[across], margin[across]])
    order = np.argsort(z, kind="stable")
    return c_along, stick_halfwidth(z[order], m[order])


def drag_sphere(problem: MindlinSphere, h_contact: float, shifts, *, press_steps: int = 2,
                prefix: str = "mindlin_sphere_", comm=None, **snes) -> list[dict]:
    """Press the sphere by `problem.depth` (in `press_steps`), then move it along x through
    `shifts` (mm, increasing), one accepted step each; per step (press and drag): the shift,
    the forces P and Q (N), Hertz's a from P, the stick radii along and across the drag and
    Mindlin's c, the tangential traction's distance from Mindlin's, the largest |f| − μp, the
    Newton iterations. Raises if a step does not converge."""
    from .wiring import newton_problem

    domain, tags = problem.mesh(h_contact, comm or MPI.COMM_WORLD)
    built = problem.block(domain, tags)
    newton = newton_problem(built.residual, built.unknowns, built.bcs, prefix,
                            **{"snes_rtol": 1e-10, "snes_atol": 1e-13, "snes_max_it": 80,
                               **snes})
    return press_and_drag(built, newton, problem.depth, press_steps, shifts,
                          lambda x_tip, its: _sphere_row(problem, built, x_tip, its))


def _sphere_row(problem: MindlinSphere, built: SphereBlock, x_tip: float, its: int) -> dict:
    Q, P = built.forces()
    s = built.surface()
    a, p0 = problem.theory(P)
    c = problem.stick_theory(P, Q)
    c_along, c_across = stick_radii(s["X"], s["margin"], x0=0.0)
    q_error, p_error, q_z = built.l1_distances(a, c, p0, x_tip, np.sign(Q))
    # the points' current positions about the sphere's axis (x_tip, ·, 0)
    x = s["X"] + s["u"] - np.array([x_tip, 0.0, 0.0])
    inside = np.hypot(x[:, 0], x[:, 2]) < a
    excess = np.linalg.norm(s["f"], axis=1) - problem.mu * s["p"]
    return {"shift": x_tip, "P": P, "Q": Q, "ratio": Q / (problem.mu * P), "a": a,
            "c_along": c_along, "c_across": c_across, "c_theory": c,
            "newton_iterations": its, "q_error": q_error, "p_error": p_error,
            "q_z_error": q_z,
            "q_across": float(np.max(np.abs(s["f"][inside, 2]), initial=0.0)
                              / (problem.mu * p0)),
            "coulomb_excess": float(excess.max() / (problem.mu * p0)),
            "cells": built.u.function_space.mesh.topology.index_map(3).size_global}
