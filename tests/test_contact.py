"""Nitsche contact against plane-strain Hertz: a rigid cylinder pressed into an elastic block.

The problem is `studies.problems.Hertz` (shared with the stability study): half model (x ≥ 0,
symmetry at x = 0) of a block [0, L] × [0, L], fixed on top, its bottom face pushed up by a
cylinder of radius R. Linear elastic material (small strain), so the only nonlinearity is the
contact itself, and with a ≪ R and a ≪ L the theory of a rigid cylinder on a half-space applies:
E* = E/(1 − ν²), a = sqrt(4 P R/(π E*)), p0 = 2 P/(π a) = E* a/(2 R).
"""

from functools import cache

import numpy as np
import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI

from fingertip_dolfinx.errors import InputError
from fingertip_dolfinx.geometry.indenters import Bar, Cylinder
from fingertip_dolfinx.physics.contact import NitscheContact, Obstacle
from fingertip_dolfinx.studies.problems import (
    Hertz,
    contact_edge,
    newton_problem,
    support_reaction,
)

HERTZ = Hertz()  # E = 1 MPa, ν = 0.3, R = 1 mm, L = 4 mm, a ≈ 0.02 mm at the depth 0.0012 mm
A_TARGET, DEPTH = HERTZ.a_target, HERTZ.depth


@cache
def hertz(
    h_contact: float, steps: int = 3, theta: int = 0, gamma0: float = 10.0, rtol: float = 1e-12
) -> dict:
    """Indent the block by DEPTH in `steps` steps; what the tests compare with theory."""
    domain, facet_tags = HERTZ.mesh(h_contact, MPI.COMM_WORLD)
    block = HERTZ.block(domain, facet_tags, theta=theta, gamma0=gamma0)
    # the solver's own SNES set-up, with a tolerance fit for 1e-8 force balances
    problem = newton_problem(block.residual, block.u, block.bcs,
                             f"hertz_{h_contact}_{steps}_{theta}_{gamma0}_{rtol}_",
                             snes_rtol=rtol, snes_atol=1e-3 * rtol)
    iterations = []
    for k in range(1, steps + 1):
        block.obstacle.y_tip.value = DEPTH * k / steps
        problem.solve()
        assert problem.solver.getConvergedReason() > 0, f"step {k} did not converge"
        iterations.append(problem.solver.getIterationNumber())
    x, p, s = block.profile()
    return {
        "force": block.force(),
        "reaction": block.reaction(),
        "a": contact_edge(x, s),
        "p0": p.max(),
        "iterations": iterations,
        "penetration": block.contact.max_penetration(),
        "cells": domain.topology.index_map(2).size_global,
    }


def relative_errors(run: dict) -> tuple[float, float]:
    a, p0 = HERTZ.theory(run["force"])
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
    P = HERTZ.stress(u)
    bars = [Obstacle.at(domain, Bar(width=1.0, centre_x=x0), y_tip=0.02) for x0 in (-0.75, 0.75)]
    contact = NitscheContact(u, P, ufl.ds, bars, modulus=HERTZ.modulus)
    top = locate_entities_boundary(domain, 1, lambda x: np.isclose(x[1], 1.0))
    dofs = fem.locate_dofs_topological(V, 1, top)
    problem = newton_problem(
        ufl.inner(P, ufl.grad(v)) * ufl.dx + contact.residual(v), u,
        [fem.dirichletbc(np.zeros(2), dofs, V)], "two_bars_", snes_rtol=1e-12, snes_atol=1e-15,
    )
    problem.solve()
    assert problem.solver.getConvergedReason() > 0

    left, right = contact.forces()
    assert left > 0 and left == pytest.approx(right, rel=1e-6)
    support = support_reaction(P, V, fem.locate_dofs_topological(V.sub(1), 1, top))
    assert support == pytest.approx(-(left + right), rel=1e-8)


def test_bad_nitsche_parameters_are_refused():
    from dolfinx.mesh import create_unit_square

    domain = create_unit_square(MPI.COMM_WORLD, 2, 2)
    u = fem.Function(fem.functionspace(domain, ("Lagrange", 1, (2,))))
    P, obstacle = HERTZ.stress(u), Obstacle.at(domain, Cylinder(radius=1.0))
    with pytest.raises(InputError, match="theta"):
        NitscheContact(u, P, ufl.ds, [obstacle], modulus=1.0, theta=0.5)
    with pytest.raises(InputError, match="gamma0"):
        NitscheContact(u, P, ufl.ds, [obstacle], modulus=1.0, gamma0=0.0)
    with pytest.raises(InputError, match="no indenter"):
        NitscheContact(u, P, ufl.ds, [], modulus=1.0)


@pytest.mark.parametrize("method, theta, conservative", [
    ("penalty", 0, True), ("nitsche", 1, True), ("nitsche", 0, False), ("nitsche", -1, False)])
def test_only_conservative_contact_laws_have_a_symmetric_tangent(method, theta, conservative):
    # A contact force that is the gradient of a potential (penalty: ½∫γ[−g]_+², Nitsche θ = 1:
    # ∫([t_n − γg]_+² − t_n²)/2γ) has a symmetric tangent, the potential's Hessian; Nitsche's
    # θ = 0 lacks the transpose of −H δt_n[δu] (n·v) and can pump energy into a dynamic run
    # (contact.py). A bar's round tip pressed 0.02 mm into a block under a smooth, non-trivial
    # deformation (the curvature of the tip and the stress both enter the tangent): symmetric
    # to round-off (1e-10 of the norm) exactly where `conservative` says so.
    from dolfinx.fem.petsc import assemble_matrix
    from dolfinx.mesh import create_rectangle

    domain = create_rectangle(MPI.COMM_WORLD, [[-1.0, 0.0], [1.0, 1.0]], [16, 8])
    V = fem.functionspace(domain, ("Lagrange", 2, (2,)))
    u, v, du = fem.Function(V), ufl.TestFunction(V), ufl.TrialFunction(V)
    u.interpolate(lambda x: np.vstack([0.01 * x[0] * (1 - x[1]), 0.005 * x[0] ** 2 - 0.003 * x[1]]))
    bar = Obstacle.at(domain, Bar(width=1.0, centre_x=0.1), y_tip=0.02)
    contact = NitscheContact(u, HERTZ.stress(u), ufl.ds, [bar], modulus=HERTZ.modulus,
                             method=method, theta=theta)
    K = assemble_matrix(fem.form(ufl.derivative(contact.residual(v), u, du)))
    K.assemble()
    asymmetry = K.copy()
    asymmetry.transpose()  # in place: Kᵀ
    asymmetry.aypx(-1.0, K)  # K − Kᵀ
    ratio = asymmetry.norm() / K.norm()
    assert contact.conservative == conservative
    assert K.norm() > 0  # the tip is in contact
    assert (ratio < 1e-10) == conservative, ratio


def test_active_set_is_the_quadrature_points_inside_the_indenter():
    # With u = 0 the penalty law is active exactly where the reference surface lies inside the
    # indenter, g < 0. A round-tipped bar pressed 0.02 mm into the bottom of a block: the count
    # of active points must equal the points the NumPy distance puts inside, at the same
    # points (the contact's facet rule: 4 Gauss points per facet for P2, degree 6), and the
    # rule must hold every surface facet's points.
    from dolfinx.mesh import create_rectangle

    domain = create_rectangle(MPI.COMM_WORLD, [[-1.0, 0.0], [1.0, 1.0]], [16, 8])
    u = fem.Function(fem.functionspace(domain, ("Lagrange", 2, (2,))))
    bar = Obstacle.at(domain, Bar(width=1.0, centre_x=0.1), y_tip=0.02)
    contact = NitscheContact(u, HERTZ.stress(u), ufl.ds, [bar], modulus=HERTZ.modulus,
                             method="penalty")
    active = contact.active_set()
    assert active.size == 4 * len(contact.facets)
    entities = contact._facet_entities  # (cell, local facet) pairs, in the same order
    points = fem.Expression(ufl.SpatialCoordinate(domain), np.array(
        [[0.0694318442029737], [0.3300094782075719], [0.6699905217924281],
         [0.9305681557970263]]))
    x = points.eval(domain, entities).reshape(-1, 2)
    inside = bar.indenter.signed_distance_np(x, 0.02)[0] < 0
    assert 0 < active.sum() < active.size
    assert np.array_equal(active, inside)
