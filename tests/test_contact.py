"""Nitsche contact against plane-strain Hertz: a rigid cylinder pressed into an elastic block.

Half model (x ≥ 0, symmetry at x = 0) of a block [0, L] × [0, L], fixed on top, its bottom face
pushed up by a cylinder of radius R. Linear elastic material (small strain), so the only
nonlinearity is the contact itself, and with a ≪ R and a ≪ L the theory of a rigid cylinder on a
half-space applies: E* = E/(1 − ν²), a = sqrt(4 P R/(π E*)), p0 = 2 P/(π a) = E* a/(2 R).
"""

import math
from functools import cache

import gmsh
import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx.fem.petsc import NonlinearProblem
from dolfinx.io.gmsh import model_to_mesh
from mpi4py import MPI

from fingertip_dolfinx.contact import NitscheContact, Obstacle, p_wave_modulus
from fingertip_dolfinx.errors import InputError
from fingertip_dolfinx.indenters import Bar, Cylinder
from fingertip_dolfinx.solver import DEFAULT_PETSC_OPTIONS

E, NU, R, L = 1.0, 0.3, 1.0, 4.0  # MPa, -, mm, mm
E_STAR = E / (1 - NU**2)
# Small load: a/R = 0.02 keeps strains ~ a/(2R) = 1 %, so finite-kinematics effects (the gap
# and normal at x = X + u, forces per reference area) stay well below the errors tested.
A_TARGET = 0.02  # mm: contact half-width aimed at
DEPTH = 0.0012  # mm: indentation that gives about A_TARGET on this block
BOTTOM, TOP, SYMMETRY = 1, 2, 3  # facet tags


def block_mesh(h_contact: float, comm):
    """The half block, graded from h_contact within 2 a of the first touch to L/8 far away."""
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    if comm.rank == 0:
        gmsh.model.add("block")
        occ = gmsh.model.occ
        occ.addRectangle(0, 0, 0, L, L)
        occ.synchronize()
        for curve in gmsh.model.getEntities(1):
            x, y, _ = occ.getCenterOfMass(*curve)
            tag = BOTTOM if y < 1e-9 else TOP if y > L - 1e-9 else SYMMETRY if x < 1e-9 else 0
            if tag:
                gmsh.model.addPhysicalGroup(1, [curve[1]], tag)
        gmsh.model.addPhysicalGroup(2, [1], 1)
        field = gmsh.model.mesh.field
        origin = occ.addPoint(0, 0, 0)
        occ.synchronize()
        field.add("Distance", 1)
        field.setNumbers(1, "PointsList", [origin])
        field.add("Threshold", 2)
        for name, value in [("InField", 1), ("SizeMin", h_contact), ("SizeMax", L / 8),
                            ("DistMin", 2 * A_TARGET), ("DistMax", L / 2)]:
            field.setNumber(2, name, value)
        field.setAsBackgroundMesh(2)
        for option in ("MeshSizeExtendFromBoundary", "MeshSizeFromPoints", "MeshSizeFromCurvature"):
            gmsh.option.setNumber(f"Mesh.{option}", 0)
        gmsh.model.mesh.generate(2)
    data = model_to_mesh(gmsh.model, comm, 0, gdim=2)
    gmsh.finalize()
    return data.mesh, data.facet_tags


def linear_elastic(u):
    """σ(ε(u)), the first Piola–Kirchhoff stress of the small-strain limit."""
    mu, lmbda = E / (2 * (1 + NU)), E * NU / ((1 + NU) * (1 - 2 * NU))
    eps = ufl.sym(ufl.grad(u))
    return lmbda * ufl.tr(eps) * ufl.Identity(2) + 2 * mu * eps


def newton(F, u, bcs, prefix: str, rtol: float = 1e-12) -> NonlinearProblem:
    """The solver's own SNES set-up, with a tolerance fit for 1e-8 force balances."""
    options = {**DEFAULT_PETSC_OPTIONS, "snes_rtol": rtol, "snes_atol": 1e-3 * rtol}
    return NonlinearProblem(F, u, bcs=bcs, petsc_options_prefix=prefix, petsc_options=options)


def reaction_y(P, V, dofs) -> float:
    """The supports' y-reaction: the elastic residual tested with w = 1 on the fixed y-dofs."""
    w = fem.Function(V)
    w.x.array[dofs] = 1.0
    form = fem.form(ufl.inner(P, ufl.grad(w)) * ufl.dx)
    return V.mesh.comm.allreduce(fem.assemble_scalar(form))


@cache
def hertz(
    h_contact: float, steps: int = 3, theta: int = 0, gamma0: float = 10.0, rtol: float = 1e-12
) -> dict:
    """Indent the block by DEPTH in `steps` steps; what the tests compare with theory."""
    comm = MPI.COMM_WORLD
    domain, facet_tags = block_mesh(h_contact, comm)
    V = fem.functionspace(domain, ("Lagrange", 2, (2,)))
    u, v = fem.Function(V), ufl.TestFunction(V)
    P = linear_elastic(u)

    obstacle = Obstacle.at(domain, Cylinder(radius=R), y_tip=0.0)
    ds = ufl.Measure("ds", domain, subdomain_data=facet_tags)
    contact = NitscheContact(
        u, P, ds(BOTTOM), [obstacle], modulus=p_wave_modulus(E, NU), theta=theta, gamma0=gamma0
    )
    F = ufl.inner(P, ufl.grad(v)) * ufl.dx + contact.residual(v)

    fdim = domain.topology.dim - 1
    top = fem.locate_dofs_topological(V, fdim, facet_tags.find(TOP))
    side = fem.locate_dofs_topological(V.sub(0), fdim, facet_tags.find(SYMMETRY))
    bcs = [fem.dirichletbc(np.zeros(2), top, V), fem.dirichletbc(0.0, side, V.sub(0))]
    problem = newton(F, u, bcs, f"hertz_{h_contact}_{steps}_{theta}_{gamma0}_{rtol}_", rtol)
    iterations = []
    for k in range(1, steps + 1):
        obstacle.y_tip.value = DEPTH * k / steps
        problem.solve()
        assert problem.solver.getConvergedReason() > 0, f"step {k} did not converge"
        iterations.append(problem.solver.getIterationNumber())

    reaction = reaction_y(P, V, fem.locate_dofs_topological(V.sub(1), fdim, facet_tags.find(TOP)))

    # Pressure profile along the surface, gathered and sorted by x.
    X, p = contact.sample(contact.pressure, points_per_facet=11)
    _, s = contact.sample(contact.trial_pressure, points_per_facet=11)
    X, p, s = (np.concatenate(comm.allgather(a)) for a in (X, p, s))
    order = np.argsort(X[:, 0], kind="stable")
    x, p, s = X[order, 0], p[order], s[order]
    # The contact edge: first sign change of t_n − γ g, linearly interpolated.
    k = np.flatnonzero(s <= 0)[0]
    edge = x[k - 1] + (x[k] - x[k - 1]) * s[k - 1] / (s[k - 1] - s[k])
    return {
        "force": 2 * contact.forces()[0],  # whole cylinder: twice the half model's
        "reaction": 2 * reaction,
        "a": edge,
        "p0": p.max(),
        "iterations": iterations,
        "penetration": contact.max_penetration(),
        "cells": domain.topology.index_map(2).size_global,
    }


def theory(force: float) -> tuple[float, float]:
    """Half-width and peak pressure of a rigid cylinder on an elastic half-space."""
    a = math.sqrt(4 * force * R / (math.pi * E_STAR))
    return a, 2 * force / (math.pi * a)


def relative_errors(run: dict) -> tuple[float, float]:
    a, p0 = theory(run["force"])
    assert 0.5 * A_TARGET < a < 2 * A_TARGET, "the load is not the small one intended"
    return abs(run["a"] / a - 1), abs(run["p0"] / p0 - 1)


def test_hertz_half_width_and_peak_pressure_converge_to_theory():
    (ea_coarse, ep_coarse), (ea_fine, ep_fine) = (
        relative_errors(hertz(A_TARGET / n)) for n in (2.5, 10)
    )
    assert ea_fine < 0.05 and ep_fine < 0.05, (ea_fine, ep_fine)
    assert ea_fine < ea_coarse and ep_fine < ep_coarse, (ea_coarse, ep_coarse, ea_fine, ep_fine)


@pytest.mark.mpi
def test_contact_force_equals_support_reaction_and_penetration_is_small():
    run = hertz(A_TARGET / 2.5)
    # Exact discrete equilibrium: the two are the residual tested with complementary parts of
    # the translation e_y, whose total is zero at convergence.
    assert run["force"] > 0
    assert run["reaction"] == pytest.approx(-run["force"], rel=1e-8)
    assert run["penetration"] < 1e-3 * DEPTH


def test_theta_zero_converges_in_few_newton_iterations_per_step():
    # Semismooth Newton: most iterations move the contact edge (measured 9, 8, 8 here, the last
    # one or two quadratic); the count grows slowly with the number of facets in contact.
    run = hertz(A_TARGET / 10, steps=3, theta=0, gamma0=10.0, rtol=1e-9)
    assert max(run["iterations"]) <= 10, run["iterations"]


@pytest.mark.parametrize("theta", [-1, 1])
def test_symmetric_and_skew_variants_agree_with_theta_zero(theta):
    # All three are consistent: on a small-strain problem they reach the same discrete answer
    # up to the method's own error, far inside the Hertz tolerance.
    reference, run = hertz(A_TARGET / 2.5), hertz(A_TARGET / 2.5, theta=theta)
    assert run["force"] == pytest.approx(reference["force"], rel=1e-3)
    assert run["reaction"] == pytest.approx(-run["force"], rel=1e-8)


def test_two_bars_share_the_load_symmetrically_and_balance_the_support():
    # A block [-2, 2] x [0, 1] (mirror-symmetric mesh) on two bars at x = ±0.75: each surface
    # point belongs to the nearest bar, and the two forces add up to the reaction of the top.
    from dolfinx.mesh import DiagonalType, create_rectangle, locate_entities_boundary

    comm = MPI.COMM_WORLD
    domain = create_rectangle(
        comm, [[-2.0, 0.0], [2.0, 1.0]], [32, 8], diagonal=DiagonalType.crossed
    )
    V = fem.functionspace(domain, ("Lagrange", 2, (2,)))
    u, v = fem.Function(V), ufl.TestFunction(V)
    P = linear_elastic(u)
    bars = [Obstacle.at(domain, Bar(width=1.0, centre_x=x0), y_tip=0.02) for x0 in (-0.75, 0.75)]
    contact = NitscheContact(u, P, ufl.ds, bars, modulus=p_wave_modulus(E, NU))
    top = locate_entities_boundary(domain, 1, lambda x: np.isclose(x[1], 1.0))
    dofs = fem.locate_dofs_topological(V, 1, top)
    problem = newton(
        ufl.inner(P, ufl.grad(v)) * ufl.dx + contact.residual(v), u,
        [fem.dirichletbc(np.zeros(2), dofs, V)], "two_bars_",
    )
    problem.solve()
    assert problem.solver.getConvergedReason() > 0

    left, right = contact.forces()
    assert left > 0 and left == pytest.approx(right, rel=1e-6)
    support = reaction_y(P, V, fem.locate_dofs_topological(V.sub(1), 1, top))
    assert support == pytest.approx(-(left + right), rel=1e-8)


def test_bad_nitsche_parameters_are_refused():
    from dolfinx.mesh import create_unit_square

    domain = create_unit_square(MPI.COMM_WORLD, 2, 2)
    u = fem.Function(fem.functionspace(domain, ("Lagrange", 1, (2,))))
    P, obstacle = linear_elastic(u), Obstacle.at(domain, Cylinder(radius=1.0))
    with pytest.raises(InputError, match="theta"):
        NitscheContact(u, P, ufl.ds, [obstacle], modulus=1.0, theta=0.5)
    with pytest.raises(InputError, match="gamma0"):
        NitscheContact(u, P, ufl.ds, [obstacle], modulus=1.0, gamma0=0.0)
    with pytest.raises(InputError, match="no indenter"):
        NitscheContact(u, P, ufl.ds, [], modulus=1.0)
