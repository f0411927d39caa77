"""Coulomb friction (physics/friction.py) in 3D against Mindlin's sphere: a rigid sphere pressed
into a large elastic block, then dragged along it (`studies.problems.MindlinSphere`).

Closed form (Mindlin 1949; Johnson §7.2): under P and a monotonic tangential load Q < μP the
Hertz contact of radius a sticks on r < c = a (1 − Q/(μP))^(1/3); Q = μP is gross slip.
"""

from functools import cache

import numpy as np
import pytest
from mpi4py import MPI

from fingertip_dolfinx.errors import InputError
from fingertip_dolfinx.studies.problems import MindlinSphere, drag_sphere, stick_radii

SPHERE = MindlinSphere()  # E = 1 MPa, ν = 0.45, μ = 0.5, R = 1 mm, a ≈ 0.05 mm
#: Sphere shifts (mm): partial stick at Q/μP ≈ 0.6, then gross slip (Mindlin's full-slip
#: distance μδ(2 − ν)/(2(1 − ν)) = 1.8 µm, the block adding a little), and a step of steady
#: sliding (the first gross-slip step's slip still carries the surface's transverse elastic
#: change: Q/(μP) = 0.998 after it, 0.9996 after the next on the a/1.5 block).
SHIFTS = (9e-4, 2.4e-3, 3.2e-3)


@cache
def dragged(problem: MindlinSphere, n: float, shifts: tuple, press_steps: int = 1):
    """The press and the drag through `shifts` on a mesh of a/n at the contact."""
    prefix = f"drag3d_{problem.L}_{n}_{press_steps}_".replace(".", "_")
    return tuple(drag_sphere(problem, problem.a_target / n, shifts, press_steps=press_steps,
                             prefix=prefix, comm=MPI.COMM_WORLD))


def test_a_dragged_sphere_obeys_coulomb_sticks_partly_then_slips_at_mu_times_the_load():
    rows = dragged(SPHERE, 1.5, SHIFTS)
    for r in rows:
        # |f| <= μp at every point the projection is evaluated: to rounding
        assert r["coulomb_excess"] <= 1e-12, r
        assert abs(r["Q"]) <= SPHERE.mu * abs(r["P"]) * (1 + 1e-9), r
    partial, gross = rows[1], rows[-1]
    assert 0.3 < partial["ratio"] < 0.9, partial
    # The stick zone's edge is an active-set edge on P2 elements of a/1.5, located to within a
    # quarter element, 0.17 a (as Hertz's contact edge is), on top of Mindlin's own error at
    # ν = 0.45 (the slip annulus's traction is not parallel to x: an angle ~ν/(2 − ν) = 0.29,
    # ~θ²/2 = 0.04 a; docs/benchmarks/friction.md): 0.25 a along and across the drag.
    for key in ("c_along", "c_across"):
        assert 0 < partial[key] < partial["a"], partial
        assert abs(partial[key] - partial["c_theory"]) < 0.25 * partial["a"], partial
    # Gross slip: |f| = μp everywhere in contact, tangent to the sphere; Q/(μP) differs from
    # 1 by the tilt of the sphere's surface over the contact, of order (a/R)² = 2.5e-3.
    assert gross["c_along"] == gross["c_across"] == 0.0, gross
    assert gross["ratio"] == pytest.approx(1.0, abs=(SPHERE.a_target / SPHERE.R) ** 2), gross


def test_mindlin_traction_carries_the_tangential_force_and_mu_p_where_it_slips():
    # 2π ∫ q r dr = μP (1 − c³/a³) = Q: the two hemispheres are consistent with c(Q).
    P, Q = 2e-4, 0.6 * SPHERE.mu * 2e-4
    a, p0 = SPHERE.theory(P)
    r = np.linspace(0.0, a, 400001)
    q = SPHERE.traction_theory(r, P, Q)
    assert np.trapezoid(2 * np.pi * r * q, r) == pytest.approx(Q, rel=1e-5)
    c = SPHERE.stick_theory(P, Q)
    assert c == pytest.approx(a * 0.4 ** (1 / 3))
    outside = r > c
    p = p0 * np.sqrt(np.clip(1 - (r / a) ** 2, 0, None))
    assert np.allclose(q[outside], SPHERE.mu * p[outside], atol=1e-12)
    assert np.all(q[~outside] < SPHERE.mu * p[~outside])


def test_stick_radii_read_the_margin_along_z_0_and_across_on_x_0():
    # an elliptic stick zone x²/0.4² + z²/0.2² < 1 sampled on the two lines and off them
    s = np.linspace(-1.0, 1.0, 21)
    along = np.column_stack([s, 0 * s, 0 * s])
    across = np.column_stack([0 * s[10:], 0 * s[10:], s[10:]])
    off = np.array([[0.3, 0.0, 0.1], [0.05, 0.0, 0.5]])
    X = np.vstack([along, across, off])
    margin = 1 - (X[:, 0] / 0.4) ** 2 - (X[:, 2] / 0.2) ** 2
    c_along, c_across = stick_radii(X, margin)
    # linear interpolation of a quadratic between points 0.1 apart
    assert c_along == pytest.approx(0.4, abs=0.01)
    assert c_across == pytest.approx(0.2, abs=0.01)


def stick_errors(rows) -> np.ndarray:
    """|c − c_theory|/a along and across the drag, at the partial-stick steps."""
    return np.array([abs(r[k] - r["c_theory"]) / r["a"] for r in rows if 0.1 < r["ratio"] < 0.95
                     for k in ("c_along", "c_across")])


@pytest.mark.slow
def test_the_stick_radius_converges_to_mindlins_with_the_mesh():
    coarse, fine = (stick_errors(dragged(SPHERE, n, SHIFTS)) for n in (1.5, 2.0))
    assert len(coarse) == len(fine) == 2, (coarse, fine)
    # measured 0.10 a at a/1.5, 0.03 a at a/2; the floor is Mindlin's own error at ν = 0.45,
    # estimated at a few % of a (the class docstring, docs/benchmarks/friction.md)
    assert fine.max() < coarse.max() and fine.max() < 0.05, (coarse, fine)


#: The block on which only Mindlin's traction-parallel-to-x approximation is left: ν = 1/2
#: (β = 0), Taylor–Hood, R = 10 mm (a/R = 0.005), a ≈ 0.05 mm as SPHERE's.
EXACT = MindlinSphere.exact()


def test_an_incompressible_sphere_block_needs_the_mixed_element():
    with pytest.raises(InputError, match="mixed"):
        MindlinSphere(nu=0.5)  # the displacement element's λ is infinite
    assert EXACT.nu == 0.5 and EXACT.mixed and EXACT.modulus == pytest.approx(4 / 3)
    # the same contact radius as SPHERE's: a = sqrt(R δ)
    assert (EXACT.R * EXACT.depth) ** 0.5 == pytest.approx(SPHERE.a_target)


def test_the_face_integrals_carry_mindlins_and_hertzs_resultants():
    domain, tags = EXACT.mesh(EXACT.a_target / 1.5, MPI.COMM_WORLD)
    built = EXACT.block(domain, tags)  # not pressed: u = 0, no pressure, no friction
    P = 4 * EXACT.E * EXACT.a_target**3 / (3 * EXACT.R * (1 - EXACT.nu**2))  # a = a_target
    a, p0 = EXACT.theory(P)
    for ratio in (0.2, 0.6, 0.9):
        Q = ratio * EXACT.mu * P
        n_q, d_q, n_p, d_p, n_z = built.face_integrals(a, EXACT.stick_theory(P, Q), p0, 0.0, 1.0)
        # the half face carries half of each resultant, 2π∫ q r dr = Q and 2π∫ p r dr = P, to
        # the face quadrature's error at the square-root edges (r = a; for q also r = c) on
        # facets of 0.67 a: measured 0.9-1.2 % for q, 0.16 % for p
        assert d_q == pytest.approx(Q / 2, rel=0.02) and d_p == pytest.approx(P / 2, rel=5e-3)
        # nothing pressed: the distances are the closed forms' whole size
        assert n_q == pytest.approx(d_q) and n_p == pytest.approx(d_p) and n_z == 0.0


#: The benchmark's partial-stick shifts scaled by 1/R (at the same a, Q ∝ P ∝ 1/R):
#: Q/(μP) ≈ 0.2, 0.4, 0.58, 0.74 on the incompressible block.
EXACT_SHIFTS = tuple(s * EXACT.depth / SPHERE.depth for s in (3e-4, 6e-4, 9e-4, 1.2e-3))


@pytest.mark.slow
def test_the_tangential_traction_converges_on_the_incompressible_sphere_block():
    coarse, fine = ([r for r in dragged(EXACT, n, EXACT_SHIFTS) if r["shift"] > 0]
                    for n in (1.5, 2.0))
    for c, f in zip(coarse, fine):
        assert 0.1 < f["ratio"] < 0.9, f
        # from a/1.5 to a/2 the traction's L1 distance (an integral over the contact face)
        # fell 1.7-2.0 times at every Q, a rate of 1.9-2.4 in h (benchmarks page, measured
        # to a/4); a rate of 1.5, 1.54 times, is the least this asserts
        assert f["q_error"] < c["q_error"] / (2.0 / 1.5) ** 1.5, (c, f)
