"""Material laws: closed-form homogeneous states, the tangent at u = 0, Newton's rate, inputs.

References in this file are written independently of the material code (numpy, principal axes;
the Prony ramp integral from the verification problems, `studies.problems`).
"""

import dolfinx.fem.petsc  # noqa: F401
import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI
from scipy.optimize import brentq

from fingertip_dolfinx import materials as mat
from fingertip_dolfinx.errors import InputError
from fingertip_dolfinx.kinematics import deformation_gradient
from fingertip_dolfinx.studies.problems import prony_ramp_integral

CELL = np.array([0], dtype=np.int32)
SKIN = mat.SKIN


def tau_np(lam, mu, alpha, nu):
    """Principal Kirchhoff stresses of the hyperfoam, from W by hand (test's own copy)."""
    b = nu / (1 - 2 * nu)
    J = np.prod(lam)
    return np.array([sum(2 * m / a * (la**a - J ** (-a * b)) for m, a in zip(mu, alpha))
                     for la in lam])


def cauchy_np(F, material):
    """σ = Σ τ_a/J n_a⊗n_a from b = F Fᵀ; plane strain adds λ3 = 1."""
    d = F.shape[0]
    c, n = np.linalg.eigh(F @ F.T)
    lam = np.sqrt(c) if d == 3 else np.append(np.sqrt(c), 1.0)
    tau = tau_np(lam, material.mu, material.alpha, material.nu)[:d]
    return (n * tau) @ n.T / np.linalg.det(F)


@pytest.fixture(scope="module")
def stress_at():
    """σ(F) for a constant 2×2 F through the package's UFL (energy -> ufl.diff -> σ)."""
    msh = mesh.create_unit_square(MPI.COMM_SELF, 1, 1)
    Fc = fem.Constant(msh, np.eye(2))
    expr = fem.Expression(mat.cauchy_stress(SKIN, Fc), np.array([[1 / 3, 1 / 3]]))

    def evaluate(F):
        Fc.value[:] = F
        return expr.eval(msh, CELL).reshape(2, 2)

    return evaluate


def test_plane_strain_uniaxial_stress_closed_form(stress_at):
    """σ22 = 0 fixes λ2 = λ1^(−β/(1+β)); σ11 = τ1/J with the closed-form τ1."""
    b = SKIN.beta
    for l1 in np.linspace(0.5, 1.5, 10):  # excludes λ1 = 1, where σ11 = 0
        l2 = brentq(lambda l2: stress_at(np.diag([l1, l2]))[1, 1], 0.5, 2.5,
                    xtol=1e-15, rtol=1e-15)
        l2_exact = l1 ** (-b / (1 + b))
        J = l1 * l2_exact
        s11_exact = sum(2 * m / a * (l1**a - J ** (-a * b))
                        for m, a in zip(SKIN.mu, SKIN.alpha)) / J
        s = stress_at(np.diag([l1, l2]))
        assert abs(l2 / l2_exact - 1) < 1e-8
        assert abs(s[0, 0] / s11_exact - 1) < 1e-8
        assert abs(s[0, 1]) < 1e-12 * abs(s[0, 0])


@pytest.mark.parametrize("F", [np.diag([0.6, 0.6]), np.diag([1.3, 1.3]),
                               np.array([[1.0, 0.4], [0.0, 1.0]]),
                               np.array([[1.0, 1e-6], [0.0, 1.0]])])
def test_equibiaxial_and_simple_shear_against_numpy(stress_at, F):
    got, ref = stress_at(F), cauchy_np(F, SKIN)
    assert np.abs(got - ref).max() <= 1e-9 * np.abs(ref).max()


def test_3d_energy_stress_at_a_general_state():
    msh = mesh.create_unit_square(MPI.COMM_SELF, 1, 1)
    F = np.array([[1.2, 0.1, 0.0], [-0.05, 0.8, 0.15], [0.02, 0.0, 1.05]])
    expr = fem.Expression(mat.cauchy_stress(SKIN, fem.Constant(msh, F)),
                          np.array([[1 / 3, 1 / 3]]))
    got, ref = expr.eval(msh, CELL).reshape(3, 3), cauchy_np(F, SKIN)
    assert np.abs(got - ref).max() <= 1e-10 * np.abs(ref).max()


def test_moduli_of_the_paper_sets():
    assert SKIN.mu0 == pytest.approx(1.16e-3, rel=1e-12)
    assert mat.SUBCUTANEOUS.mu0 == pytest.approx(0.579e-3, rel=1e-12)
    assert SKIN.beta == pytest.approx(2.0)
    # ν recovered from the small-strain moduli: ν = (3K − 2μ)/(2(3K + μ)).
    K, G = SKIN.K0, SKIN.mu0
    assert (3 * K - 2 * G) / (2 * (3 * K + G)) == pytest.approx(0.40, rel=1e-12)


# ---- tangent at u = 0 and Newton --------------------------------------------------------


@pytest.fixture(scope="module")
def square():
    msh = mesh.create_unit_square(MPI.COMM_SELF, 2, 2)
    V = fem.functionspace(msh, ("Lagrange", 1, (2,)))
    return msh, V


def dense(form):
    A = fem.assemble_matrix(fem.form(form))
    A.scatter_reverse()
    return A.to_dense()


def test_tangent_at_u0_is_the_linear_elastic_stiffness(square):
    """d²W at u = 0 must be the plane-strain Hooke tensor with μ0 and λ0 = K0 − 2μ0/3."""
    msh, V = square
    u, v, du = fem.Function(V), ufl.TestFunction(V), ufl.TrialFunction(V)
    R = ufl.inner(mat.first_piola_kirchhoff(SKIN, deformation_gradient(u)), ufl.grad(v)) * ufl.dx
    K = dense(ufl.derivative(R, u, du))
    eps = lambda w: ufl.sym(ufl.grad(w))  # noqa: E731
    K_lin = dense((SKIN.lame_lambda0 * ufl.tr(eps(du)) * ufl.tr(eps(v))
                   + 2 * SKIN.mu0 * ufl.inner(eps(du), eps(v))) * ufl.dx)
    err = np.abs(K - K_lin).max() / np.abs(K_lin).max()
    print(f"tangent at u = 0: max relative error {err:.2e}")
    assert err < 1e-10


def test_newton_converges_quadratically(square):
    """Plane-strain uniaxial compression to λ1 = 0.7 of a skin square, plain Newton (SNES)."""
    msh, V = square
    u, v = fem.Function(V), ufl.TestFunction(V)
    R = ufl.inner(mat.first_piola_kirchhoff(SKIN, deformation_gradient(u)), ufl.grad(v)) * ufl.dx
    fdim = msh.topology.dim - 1

    def bc(component, marker, value):
        facets = mesh.locate_entities_boundary(msh, fdim, marker)
        dofs = fem.locate_dofs_topological(V.sub(component), fdim, facets)
        return fem.dirichletbc(value, dofs, V.sub(component))

    bcs = [bc(0, lambda x: np.isclose(x[0], 0), 0.0), bc(1, lambda x: np.isclose(x[1], 0), 0.0),
           bc(0, lambda x: np.isclose(x[0], 1), -0.3)]
    problem = dolfinx.fem.petsc.NonlinearProblem(
        R, u, bcs=bcs, petsc_options_prefix="test_newton_",
        petsc_options={"snes_type": "newtonls", "snes_linesearch_type": "basic",
                       "snes_rtol": 1e-14, "snes_atol": 1e-22, "snes_stol": 0.0,
                       "snes_max_it": 30, "ksp_type": "preonly", "pc_type": "lu"})
    history = []
    problem.solver.setMonitor(lambda snes, it, norm: history.append(norm))
    problem.solve()
    reason = problem.solver.getConvergedReason()
    print("Newton residual norms:", " ".join(f"{r:.3e}" for r in history))
    assert reason > 0
    r = np.array(history)
    # History[0] contains the Dirichlet lift (the prescribed jump); the rate is read from
    # the iterates after it, down to round-off (~1e-12 of the first Newton residual).
    r = r[1:][r[1:] > 1e-12 * r[1]]
    orders = np.log(r[2:] / r[1:-1]) / np.log(r[1:-1] / r[:-2])
    constants = r[1:] / r[:-1] ** 2
    print("orders p_k = log(r_k+1/r_k)/log(r_k/r_k-1):", np.round(orders, 2))
    print("r_k+1 / r_k^2:", np.round(constants, 1))
    assert orders[-1] > 1.8 and orders[-2] > 1.8
    assert constants[-1] < 3 * constants[-2]  # bounded constant: r_{k+1} <= C r_k^2
    # The converged state is the closed-form one: λ2 = 0.7^(−β/(1+β)).
    lam2 = 1 + u.x.array.reshape(-1, 2)[:, 1].max()  # top edge at y = 1
    assert lam2 == pytest.approx(0.7 ** (-SKIN.beta / (1 + SKIN.beta)), rel=1e-10)


# ---- linear elastic (SVK) ------------------------------------------------------------------


def test_linear_elastic_is_objective_and_hookean():
    msh = mesh.create_unit_square(MPI.COMM_SELF, 1, 1)
    Fc = fem.Constant(msh, np.eye(2))
    expr = fem.Expression(mat.cauchy_stress(mat.NAIL, Fc), np.array([[1 / 3, 1 / 3]]))
    t = 0.7
    Fc.value[:] = [[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]]
    assert np.abs(expr.eval(msh, CELL)).max() < 1e-12 * mat.NAIL.E  # rigid rotation: no stress
    h = 1e-7
    Fc.value[:] = np.eye(2) + h * np.array([[1.0, 0.5], [0.0, -0.3]])
    eps = h * np.array([[1.0, 0.25], [0.25, -0.3]])
    hooke = mat.NAIL.lmbda * np.trace(eps) * np.eye(2) + 2 * mat.NAIL.mu * eps
    assert np.allclose(expr.eval(msh, CELL).reshape(2, 2), hooke, rtol=1e-5, atol=1e-5 * h * 170)


# ---- Prony ---------------------------------------------------------------------------------


def test_prony_relaxation_and_model_md_numbers():
    p = mat.SKIN_PRONY
    assert p.g_inf == pytest.approx(0.60)
    assert p.relaxation(0.0) == pytest.approx(1.0)
    assert p.relaxation(1e6) == pytest.approx(0.60)
    # MODEL.md §4: Prony terms alone on a stress ramped linearly over 1 s.
    def ramp_response(t, T=1.0):  # ∫ g(t − s) ds over [0, min(t, T)]
        return prony_ramp_integral(p, t, T)
    ratios = [ramp_response(t) / ramp_response(1.0) for t in (2, 5, 10, 20, 100)]
    assert np.allclose(ratios, [0.93, 0.81, 0.72, 0.66, 0.63], atol=0.006)


# ---- inputs --------------------------------------------------------------------------------


@pytest.mark.parametrize("kwargs, words", [
    (dict(mu=(0.1, 0.2), alpha=(2.0,), nu=0.3), "'alpha' has 1"),
    (dict(mu=(0.1,), alpha=(0.0,), nu=0.3), "contains 0"),
    (dict(mu=(0.1,), alpha=(2.0,), nu=0.5), "outside (-1, 0.5)"),
    (dict(mu=(-0.1, 0.05), alpha=(2.0, 3.0), nu=0.3), "mu0"),
    (dict(mu=(), alpha=(), nu=0.3), "empty"),
    (dict(mu="0.1", alpha=(2.0,), nu=0.3), "list of numbers"),
    (dict(mu=(0.1,), alpha=(float("nan"),), nu=0.3), "non-finite"),
])
def test_hyperfoam_rejects_bad_parameters(kwargs, words):
    with pytest.raises(InputError, match=None) as err:
        mat.Hyperfoam(**kwargs, where="[materials.skin]")
    assert words in str(err.value) and "[materials.skin]" in str(err.value)


def test_bulk_modulus_follows_from_mu0_and_nu():
    """K0 = Σ2μ_i(1/3 + β) = 2μ0(1 + ν)/(3(1 − 2ν)): positive whenever μ0 > 0, −1 < ν < ½."""
    for nu in (-0.9, 0.0, 0.4, 0.49):
        m = mat.Hyperfoam(mu=(-0.05, 0.06), alpha=(2.0, 5.0), nu=nu)
        assert m.K0 == pytest.approx(2 * m.mu0 * (1 + nu) / (3 * (1 - 2 * nu)), rel=1e-12)


def test_from_dict_keys_and_values():
    ok = mat.Hyperfoam.from_dict({"mu": [1e-3], "alpha": [2.0], "nu": 0.3}, where="t.toml")
    assert ok.mu == (1e-3,) and isinstance(ok.mu, tuple)
    with pytest.raises(InputError, match=r"unknown parameter\(s\) \['alpha1'\]"):
        mat.Hyperfoam.from_dict({"mu": [1e-3], "alpha1": [2.0], "nu": 0.3})
    with pytest.raises(InputError, match=r"missing parameter\(s\) \['nu'\]"):
        mat.Hyperfoam.from_dict({"mu": [1e-3], "alpha": [2.0]})
    with pytest.raises(InputError, match="'E' = -1.0"):
        mat.LinearElastic.from_dict({"E": -1.0, "nu": 0.3})
    with pytest.raises(InputError, match="must be a number"):
        mat.LinearElastic.from_dict({"E": "stiff", "nu": 0.3})


@pytest.mark.parametrize("kwargs, words", [
    (dict(g=(0.5, 0.6), tau=(1.0, 2.0)), "sum(g)"),
    (dict(g=(0.1, -0.1), tau=(1.0, 2.0)), "must be > 0"),
    (dict(g=(0.1,), tau=(1.0, 2.0)), "'tau' has 2"),
    (dict(g=(0.1,), tau=(0.0,)), "relaxation times"),
])
def test_prony_rejects_bad_parameters(kwargs, words):
    with pytest.raises(InputError) as err:
        mat.Prony(**kwargs)
    assert words in str(err.value)


@pytest.mark.parametrize("kwargs, words", [
    (dict(k0=0.0, phi0=0.4, kappa=0.1, M=1.0), "'k0'"),
    (dict(k0=1e-3, phi0=1.0, kappa=0.1, M=1.0), "'phi0'"),
    (dict(k0=1e-3, phi0=0.4, kappa=-0.1, M=1.0), "'kappa'"),
])
def test_holmes_mow_rejects_bad_parameters(kwargs, words):
    with pytest.raises(InputError) as err:
        mat.HolmesMow(**kwargs)
    assert words in str(err.value)
