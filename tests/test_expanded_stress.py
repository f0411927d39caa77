"""The 3D hyperfoam's stress expanded about a copy of the state (materials._expanded_stress,
what the 3D problem assembles) against the direct S = 2 ∂W/∂C: the same stress and the same
derivative in u, to round-off, at every branch of the eigenvalue sum (C ∝ I, near it, a
double eigenvalue, distinct eigenvalues).

The derivative is compared along directions w (ufl.derivative(P, u, w)): the Jacobian's
action, point by point, without compiling the direct form's whole Jacobian (minutes)."""

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI

from fingertip_dolfinx.physics import materials as mat
from fingertip_dolfinx.physics.kinematics import deformation_gradient, invariants_3d
from fingertip_dolfinx.problem import JIT_OPTIONS_3D

#: The round-off allowed, relative to the larger of the largest value and the law's μ0 (near
#: C = I the stress is a small difference of the stretch and volume terms' O(μ0) parts, whose
#: rounding is O(eps μ0) in either form). The two forms differ in the order of operations
#: (tr Dᵏ by Cayley–Hamilton, d/(2p³) for det(D/p)/2): measured ≤ 8e-14 at these states; a
#: wrong or missing term of the tangent would be O(1).
RTOL = 1e-12

STATES = {
    "identity": lambda x: 0.0 * x,
    "near isotropic": lambda x: 1e-4 * np.array([x[0] * x[1], -x[1] + x[2] ** 2, x[2] * x[0]]),
    "uniaxial (double eigenvalue)": lambda x: np.array([-0.2 * x[0], 0 * x[1], 0 * x[2]]),
    "general": lambda x: np.array([0.1 * x[0] + 0.05 * x[1] ** 2, -0.15 * x[1] + 0.08 * x[2] * x[0],
                                   0.06 * x[2] + 0.04 * x[0] * x[1]]),
}


@pytest.fixture(scope="module")
def space():
    msh = mesh.create_box(MPI.COMM_WORLD, [[0, 0, 0], [1, 1, 1]], [2, 1, 1],
                          mesh.CellType.tetrahedron)
    return fem.functionspace(msh, ("Lagrange", 2, (3,)))


def _points(msh):
    import basix

    points, _ = basix.make_quadrature(basix.CellType.tetrahedron, 2)
    cells = np.arange(msh.topology.index_map(3).size_local, dtype=np.int32)
    return points, cells


def _values(expr, V):
    points, cells = _points(V.mesh)
    return fem.Expression(expr, points, jit_options=JIT_OPTIONS_3D).eval(V.mesh, cells)


@pytest.mark.parametrize("state", list(STATES))
def test_expanded_stress_and_tangent_equal_the_direct_ones(space, state):
    V = space
    u = fem.Function(V)
    u.interpolate(STATES[state])
    u_state = fem.Function(V, x=u.x)  # u's vector: the values agree, always
    w = fem.Function(V)
    w.interpolate(lambda x: np.array([np.sin(x[1] + 2 * x[2]), x[0] * x[2] - 0.3,
                                      np.cos(3 * x[0]) * x[1]]))
    F, F_state = deformation_gradient(u), deformation_gradient(u_state)
    skin = mat.SKIN
    direct = mat.first_piola_kirchhoff(skin, F)
    expanded = mat.first_piola_kirchhoff(skin, F, F_state)
    for name, a, b in (("P", direct, expanded),
                       ("dP[w]", ufl.derivative(direct, u, w), ufl.derivative(expanded, u, w))):
        want, got = _values(a, V), _values(b, V)
        err = np.abs(got - want).max() / max(np.abs(want).max(), skin.mu0)
        print(f"{state}: {name} relative difference {err:.1e}, max {np.abs(want).max():.3e}")
        assert err < RTOL, (state, name, err)


def test_the_state_copy_is_not_differentiated(space):
    """The expansion's point: ufl.derivative sees u, not u_state. A u_state that were u itself
    would double the second-order term (the tangent off by G_ij terms); a copy whose values
    lag behind u would leave a − ā ≠ 0 in the stress. Here: the invariants of the copy's C
    equal u's bit for bit."""
    V = space
    u = fem.Function(V)
    u.interpolate(STATES["general"])
    u_state = fem.Function(V, x=u.x)
    C = deformation_gradient(u).T * deformation_gradient(u)
    C_state = deformation_gradient(u_state).T * deformation_gradient(u_state)
    a = _values(ufl.as_vector(invariants_3d(C)), V)
    a_state = _values(ufl.as_vector(invariants_3d(C_state)), V)
    assert np.array_equal(a, a_state)
    assert ufl.algorithms.expand_derivatives(ufl.derivative(
        ufl.as_vector(invariants_3d(C_state)), u, u)) == ufl.as_vector([0, 0, 0])


def test_only_a_3d_hyperfoam_is_expanded(space):
    """2D (plane strain) and the linear-elastic bone and nail keep the direct S = 2 ∂W/∂C (no
    state copy in it): their forms, and so their numbers, are unchanged bit for bit."""
    from ufl.algorithms import extract_coefficients

    V = space
    u = fem.Function(V)
    u_state = fem.Function(V, x=u.x)
    F, F_state = deformation_gradient(u), deformation_gradient(u_state)
    F2, F2_state = (ufl.as_matrix([[G[i, j] for j in range(2)] for i in range(2)])
                    for G in (F, F_state))

    def expanded(material, F, F_state):
        return u_state in extract_coefficients(mat.second_piola_kirchhoff(material, F, F_state))

    assert not expanded(mat.BONE, F, F_state)
    assert not expanded(mat.SKIN, F2, F2_state)
    assert expanded(mat.SKIN, F, F_state)


def test_the_problem_expands_in_3d_unless_nitsche_differentiates_the_stress():
    """Nitsche's θ = ±1 puts the stress's derivative in the residual, and its Jacobian needs
    the second, which the expansion (about a fixed state copy) does not have: direct S there."""
    from fingertip_dolfinx.model import ModelOptions
    from fingertip_dolfinx.problem import expands_stress

    assert expands_stress(3, ModelOptions(contact="penalty"))
    assert expands_stress(3, ModelOptions(contact="nitsche", contact_theta=0))
    assert not expands_stress(3, ModelOptions(contact="nitsche", contact_theta=1))
    assert not expands_stress(3, ModelOptions(contact="nitsche", contact_theta=-1))
    assert not expands_stress(2, ModelOptions())
