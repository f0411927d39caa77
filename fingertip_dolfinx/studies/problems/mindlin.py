"""Cattaneo–Mindlin: a rigid cylinder pressed into a linear-elastic block with Coulomb friction,
then dragged along the surface, and the closed-form stick zone and tangential traction;
`stick_halfwidth`, the stick zone's half-width from the stick margin."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem, mesh

from ...errors import InputError
from ...geometry.indenters import Cylinder
from ...physics.contact import NitscheContact, Obstacle
from ...physics.friction import CoulombFriction, contact_state
from .hertz import Hertz


@dataclass(frozen=True)
class CattaneoMindlin(Hertz):
    """A rigid cylinder of radius R pressed by `depth` into the bottom face of a linear-elastic
    block [−L, L] × [0, L] (the whole block: a tangential load breaks the mirror symmetry), top
    fixed, small strain, Nitsche contact with Coulomb friction μ; then moved along x.

    Cattaneo (1938), Mindlin (1949); plane strain, Johnson, Contact Mechanics, §7.1: under a
    normal force P (N/mm) and a tangential force Q < μP applied monotonically from 0, the
    contact of half-width a (Hertz) sticks on |x| < c with c = a sqrt(1 − Q/(μP)) and slips
    outside, the tangential traction being q(x) = μ p0 sqrt(1 − x²/a²) − μ p0 (c/a)
    sqrt(1 − x²/c²) (the second term on |x| < c only); Q = μP: gross slip, c = 0.

    The closed form neglects the tangential traction's effect on the pressure (Goodman's
    approximation), exact when the two bodies' second Dundurs constant β vanishes; for a rigid
    indenter β = (1 − 2ν)/(2(1 − ν)), so ν defaults to 0.49 (β = 0.0196), nearly incompressible
    (the P2 displacement does not lock at this ν, but its stress, hence Nitsche's pressure, is
    poor). `mixed`: Taylor–Hood P2/P1 (u, p) with σ = 2G ε − p I and tr ε + p/λ = 0, stable
    up to ν = 1/2, where β = 0 and the closed form is exact (`CattaneoMindlin.exact()`).
    """

    nu: float = 0.49
    mu: float = 0.5  # the friction coefficient
    mixed: bool = False  # Taylor–Hood (u, p) instead of the displacement alone

    def __post_init__(self):
        check_poisson("CattaneoMindlin.nu", self.nu, self.mixed)

    @classmethod
    def exact(cls, **fields) -> CattaneoMindlin:
        """The block on which the closed form is exact in the limit of a fine mesh: the two
        approximations it rests on besides the half-space (a/L = 0.005) made exact or small.

        - Goodman's (no coupling of pressure and tangential traction): exact at ν = 1/2,
          β = 0 (Johnson §7.1); Taylor–Hood P2/P1, since the displacement alone has no stress
          there.
        - Hertz's small slopes: the half-space's tangential load is the friction's alone. The
          pressure acts along the cylinder's normal, so it has an x-share p n_x ≈ p x/R, an
          antisymmetric tangential load of order (a/R) p0 that the closed form leaves out (on
          R = 1 mm it tilts q across the stick zone by ~±0.03 μ p0). R = 10 mm makes
          a/R = 0.002, pressed 0.12 µm for the same a ≈ 0.0205 mm (P ∝ a²/R: the depth and
          the shifts for a given Q/(μP) scale as 1/R).
        """
        return cls(**{"nu": 0.5, "mixed": True, "R": 10.0, "depth": 1.2e-4, **fields})

    @property
    def modulus(self) -> float:
        """M of Nitsche's γ = γ0 M/h (MPa): the P-wave modulus λ + 2G of the displacement
        element; mixed, E* = E/(1 − ν²), the plane-strain modulus that sets a half-space's
        normal stiffness (finite at ν = 1/2, where λ + 2G is not; the pressure unknown carries
        the volumetric stiffness)."""
        return half_space_modulus(self.E, self.nu) if self.mixed else super().modulus

    @property
    def shear_modulus(self) -> float:
        """G = E/(2(1 + ν)) (MPa): the scale of the tangential stiffness of the surface, and
        of the friction's γ_t = γ0 G/h (`CoulombFriction.gamma_ratio` = G/M)."""
        return self.E / (2 * (1 + self.nu))

    def stick_theory(self, force: float, tangential: float) -> float:
        """Cattaneo–Mindlin's stick half-width c (mm) under P = `force`, Q = `tangential`."""
        a, _ = self.theory(force)
        ratio = abs(tangential) / (self.mu * force)
        return a * math.sqrt(max(1.0 - ratio, 0.0))

    def traction_theory(self, x, force: float, tangential: float) -> np.ndarray:
        """q(x) (MPa), Cattaneo–Mindlin's tangential traction at x from the contact's centre."""
        a, p0 = self.theory(force)
        c = self.stick_theory(force, tangential)
        x = np.asarray(x, dtype=float)
        q = self.mu * p0 * np.sqrt(np.clip(1 - (x / a) ** 2, 0, None))
        inner = np.sqrt(np.clip(1 - (x / c) ** 2, 0, None)) if c > 0 else 0.0 * x
        return np.sign(tangential) * (q - self.mu * p0 * (c / a) * inner)

    def _gmsh_block(self, gmsh) -> None:
        """The rectangle [−L, L] × [0, L] with its bottom and top edges tagged."""
        L = self.L
        gmsh.model.add("block")
        occ = gmsh.model.occ
        occ.addRectangle(-L, 0, 0, 2 * L, L)
        occ.synchronize()
        for curve in gmsh.model.getEntities(1):
            _, y, _ = occ.getCenterOfMass(*curve)
            tag = self.BOTTOM if y < 1e-9 else self.TOP if y > L - 1e-9 else 0
            if tag:
                gmsh.model.addPhysicalGroup(1, [curve[1]], tag)
        gmsh.model.addPhysicalGroup(2, [1], 1)

    def block(self, domain, facet_tags, *, gamma0: float = 10.0,
              method: str = "nitsche", gamma_ratio: float = 1.0) -> MindlinBlock:
        """The P2 displacement (with `mixed`, and the P1 pressure), the cylinder (touching at
        the origin, movable in x and y), the contact and friction terms, the residual and the
        clamped top."""
        u, p, P, v, residuals = elasticity(self, domain)
        V = u.function_space
        obstacle = Obstacle.at(domain, Cylinder(radius=self.R), y_tip=0.0, x_tip=0.0)
        ds = ufl.Measure("ds", domain, subdomain_data=facet_tags)
        contact = NitscheContact(u, P, ds(self.BOTTOM), [obstacle], modulus=self.modulus,
                                 gamma0=gamma0, method=method)
        friction = CoulombFriction(contact, self.mu, gamma_ratio=gamma_ratio)
        residuals[0] = residuals[0] + contact.residual(v) + friction.residual(v)
        top = fem.locate_dofs_topological(V, 1, facet_tags.find(self.TOP))
        bcs = [fem.dirichletbc(np.zeros(2), top, V)]
        residual = residuals if p is not None else residuals[0]
        return MindlinBlock(u, P, obstacle, contact, friction, residual, bcs, facet_tags, p)


def check_poisson(where: str, nu: float, mixed: bool) -> None:
    """Refuse a ν the element cannot take: λ is infinite at ν = 1/2, where the displacement
    element has no stress; the mixed one takes 1/λ = 0 (and needs λ > 0, ν > 0, for its
    p = −λ tr ε)."""
    if not (0.0 < nu <= 0.5 if mixed else -1.0 < nu < 0.5):
        raise InputError(where, f"ν = {nu!r} is outside "
                         f"{'(0, 0.5]' if mixed else '(−1, 0.5)'}.",
                         "use −1 < ν < 0.5, or mixed=True with 0 < ν <= 0.5 (0.5: "
                         "incompressible).")


def half_space_modulus(E: float, nu: float) -> float:
    """E* = E/(1 − ν²) (MPa), the modulus that sets a half-space's normal stiffness (Hertz's, in
    plane strain and for the sphere): the mixed blocks' M of Nitsche's γ = γ0 M/h, finite at
    ν = 1/2, where λ + 2G is not (the pressure unknown carries the volumetric stiffness)."""
    return E / (1 - nu**2)


def elasticity(problem, domain):
    """(u, p or None, the stress, the test function v, the volume residuals) of `problem`'s
    block (E, ν, `mixed`, `stress`, `shear_modulus`), in 2D or 3D: the P2 displacement alone,
    or mixed with the P1 pressure p = −λ tr ε (Taylor–Hood), σ = 2G ε − p I, whose residual
    −∫ (tr ε + p/λ) q dx keeps its (p, p) block at 1/λ = 0 (a Constant)."""
    dim = domain.geometry.dim
    V = fem.functionspace(domain, ("Lagrange", 2, (dim,)))
    u, v = fem.Function(V), ufl.TestFunction(V)
    if not problem.mixed:
        P = problem.stress(u)
        return u, None, P, v, [ufl.inner(P, ufl.grad(v)) * ufl.dx]
    p = fem.Function(fem.functionspace(domain, ("Lagrange", 1)), name="pressure")
    q = ufl.TestFunction(p.function_space)
    E, nu = problem.E, problem.nu
    inverse_lambda = fem.Constant(domain, (1 + nu) * (1 - 2 * nu) / (E * nu))
    eps = ufl.sym(ufl.grad(u))
    P = 2 * problem.shear_modulus * eps - p * ufl.Identity(dim)
    return u, p, P, v, [ufl.inner(P, ufl.grad(v)) * ufl.dx,
                        -(ufl.tr(eps) + inverse_lambda * p) * q * ufl.dx]


@dataclass(frozen=True)
class MindlinBlock:
    """A built Cattaneo–Mindlin block: solve `residual` = 0 for `unknowns` (u, or the mixed
    block's [u, p] and its residuals) with `bcs`, moving the cylinder by `obstacle.y_tip` and
    `obstacle.x_tip`; `friction.mark_accepted()` after each accepted step."""

    u: fem.Function
    P: ufl.core.expr.Expr
    obstacle: Obstacle
    contact: NitscheContact
    friction: CoulombFriction
    residual: ufl.Form
    bcs: list
    facet_tags: mesh.MeshTags
    p: fem.Function | None = None  # the mixed block's pressure

    @property
    def unknowns(self):
        """u, or [u, p] for the mixed block (the residual is then a list too)."""
        return self.u if self.p is None else [self.u, self.p]

    def forces(self) -> tuple[float, float]:
        """(tangential Q along x, normal P along y) the cylinder puts on the block (N/mm)."""
        fx, fy = self.friction.forces()[0]
        return float(fx), float(fy)

    def profile(self, points_per_facet: int = 11) -> dict[str, np.ndarray]:
        """Along the contact face, gathered from every rank and sorted by x: x (mm), the
        pressure p and the tangential traction's x-component q (MPa), the stick margin, the
        surface's displacement u_x (mm)."""
        contact, friction = self.contact, self.friction
        comm = self.u.function_space.mesh.comm
        fields = {"p": contact.pressure, "q": friction.traction[0],
                  "margin": friction.stick_margin, "u_x": self.u[0]}
        out = {}
        for name, expr in fields.items():
            X, values = contact.sample(expr, points_per_facet=points_per_facet)
            out["x"], out[name] = np.concatenate(comm.allgather(X[:, 0])), np.concatenate(
                comm.allgather(values))
        order = np.argsort(out["x"], kind="stable")
        return {k: a[order] for k, a in out.items()}


def stick_halfwidth(x: np.ndarray, margin: np.ndarray) -> float:
    """Half the width of the stick zone (mm): the span between the outermost zero crossings of
    the stick margin (x sorted; > 0 sticks), each linearly interpolated; 0 without a stick
    point."""
    inside = np.flatnonzero(margin > 0)
    if not len(inside):
        return 0.0
    ends = []
    for i, j in ((inside[0], inside[0] - 1), (inside[-1], inside[-1] + 1)):
        if j < 0 or j >= len(x):
            return math.nan
        ends.append(x[i] + (x[j] - x[i]) * margin[i] / (margin[i] - margin[j]))
    return 0.5 * (ends[1] - ends[0])


def drag(problem: CattaneoMindlin, h_contact: float, shifts, *, press_steps: int = 2,
         prefix: str = "mindlin_", comm=None, **snes) -> list[dict]:
    """Press the cylinder by `problem.depth` (in `press_steps`), then move it along x through
    `shifts` (mm, increasing), one accepted step each; per step (press and drag): the shift,
    the forces P and Q (N/mm), Hertz's a from P, the measured stick half-width c and
    Cattaneo–Mindlin's, the Newton iterations, the contact face's points x, stick margins
    and states (`contact_state`), the energy the friction dissipated over the step. Raises
    if a step does not converge."""
    from mpi4py import MPI

    from .wiring import newton_problem

    domain, tags = problem.mesh(h_contact, comm or MPI.COMM_WORLD)
    built = problem.block(domain, tags, gamma_ratio=problem.shear_modulus / problem.modulus)
    newton = newton_problem(built.residual, built.unknowns, built.bcs, prefix,
                            **{"snes_rtol": 1e-10, "snes_atol": 1e-13, "snes_max_it": 80,
                               **snes})
    return press_and_drag(built, newton, problem.depth, press_steps, shifts,
                          lambda x_tip, its: _drag_row(problem, built, x_tip, its))


def press_and_drag(built, newton, depth: float, press_steps: int, shifts, row) -> list[dict]:
    """Press `built`'s indenter to `depth` in `press_steps` equal steps, then move it along x
    through `shifts` (mm) at that depth, one Newton solve each; `row(x_tip, iterations)` after
    each converged step, before the friction's slip is accepted (the rows measure the step's
    slip and dissipation). Raises if a step does not converge."""
    path = [(0.0, depth * k / press_steps) for k in range(1, press_steps + 1)]
    path += [(float(s), depth) for s in shifts]
    rows = []
    for x_tip, y_tip in path:
        built.obstacle.x_tip.value, built.obstacle.y_tip.value = x_tip, y_tip
        newton.solve()
        if newton.solver.getConvergedReason() <= 0:
            raise RuntimeError(f"Newton failed at x_tip = {x_tip:g} mm, y_tip = {y_tip:g} mm")
        rows.append(row(x_tip, newton.solver.getIterationNumber()))
        built.friction.mark_accepted()  # after measuring: the slip is the step's
    return rows


def _drag_row(problem: CattaneoMindlin, built: MindlinBlock, x_tip: float, its: int) -> dict:
    Q, P = built.forces()
    profile = built.profile()
    a, p0 = problem.theory(P)
    # q(x) about the contact's centre, the cylinder's axis, at the points' current positions;
    # the L1 distance (q and its closed form have square-root edges, where a shift of the
    # edge by δ costs ~sqrt(δ/a) in a root-mean-square but only ~(δ/a)^1.5 in L1)
    x = profile["x"] + profile["u_x"] - x_tip
    q_theory = problem.traction_theory(x, P, Q)
    p_theory = p0 * np.sqrt(np.clip(1 - (x / a) ** 2, 0, None))
    return {"shift": x_tip, "P": P, "Q": Q, "ratio": Q / (problem.mu * P), "a": a,
            "c": stick_halfwidth(profile["x"], profile["margin"]),
            "c_theory": problem.stick_theory(P, Q), "newton_iterations": its,
            "q_error": l1_distance(x, profile["q"], q_theory),
            "p_error": l1_distance(x, profile["p"], p_theory),
            "x": profile["x"], "margin": profile["margin"], "x_axis": x,
            "q": profile["q"], "p": profile["p"],
            "state": contact_state(profile["p"], profile["margin"]),
            "dissipated": built.friction.dissipated(),
            "cells": built.u.function_space.mesh.topology.index_map(2).size_global}


def l1_distance(x: np.ndarray, values: np.ndarray, theory: np.ndarray) -> float:
    """∫ |values − theory| dx / ∫ |theory| dx over the sampled face (x sorted, a facet's end
    points once per facet): the trapezoidal rule on the sample points, so that unequal
    facets weigh by their length, and the whole face counted (a traction outside the
    closed form's contact is error too)."""
    return float(np.trapezoid(np.abs(values - theory), x) / np.trapezoid(np.abs(theory), x))
