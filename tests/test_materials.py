"""Material laws: closed-form homogeneous states, the tangent at u = 0, Newton's rate, inputs.

References in this file are written independently of the package (numpy, principal axes; the
Prony ramp integral from the verification problems, `studies.problems`).
Hyperfoam closed forms, by hand from W = Σ 2μ_i/α_i² [Σ_a λ_a^α_i − 3 + (J^(−α_iβ_i) − 1)/β_i]:
τ_a = λ_a ∂W/∂λ_a = Σ (2μ_i/α_i)(λ_a^α_i − J^(−α_iβ_i)) (the J-term: ∂/∂ ln λ_a of
(J^(−αβ) − 1)/β is −α J^(−αβ), at β = 0 of −α ln J it is −α: the same with J^0 = 1), and
σ_a = τ_a/J.
"""

from decimal import Decimal, localcontext

import dolfinx.fem.petsc  # noqa: F401
import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI
from scipy.optimize import brentq

from fingertip_dolfinx.errors import InputError
from fingertip_dolfinx.physics import materials as mat
from fingertip_dolfinx.physics.kinematics import deformation_gradient
from fingertip_dolfinx.studies.problems import prony_ramp_integral

CELL = np.array([0], dtype=np.int32)
SKIN = mat.SKIN
#: ν = 0.4 is the paper's; ν = 0 ABAQUS's default (β = 0: the volume term is −α ln J);
#: per-term ν_i as ABAQUS allows (one term with β = 0, one moderate, one stiff in volume).
NU_CASES = [0.0, 0.4, (0.0, 0.2, 0.45)]
NU_IDS = ["nu=0", "nu=0.4", "nu_i=(0,0.2,0.45)"]
LAMBDAS = np.linspace(0.5, 1.5, 10)  # excludes λ = 1, where every stress is 0


def foam(nu):
    """The skin's μ_i, α_i with another ν (a float for all terms or one per term)."""
    return mat.Hyperfoam(mu=SKIN.mu, alpha=SKIN.alpha, nu=nu, where=f"skin, nu = {nu}")


def betas_np(nu, n_terms):
    nus = nu if isinstance(nu, tuple) else (nu,) * n_terms
    return [v / (1 - 2 * v) for v in nus]


def tau_np(lam, mu, alpha, nu):
    """Principal Kirchhoff stresses of the hyperfoam, from W by hand (test's own copy)."""
    J = np.prod(lam)
    betas = betas_np(nu, len(mu))
    return np.array([sum(2 * m / a * (la**a - J ** (-a * b))
                         for m, a, b in zip(mu, alpha, betas)) for la in lam])


def tau_of(material, lam):
    return tau_np(np.asarray(lam, dtype=float), material.mu, material.alpha, material.nu)


def cauchy_np(F, material):
    """σ = Σ τ_a/J n_a⊗n_a from b = F Fᵀ; plane strain adds λ3 = 1."""
    d = F.shape[0]
    c, n = np.linalg.eigh(F @ F.T)
    lam = np.sqrt(c) if d == 3 else np.append(np.sqrt(c), 1.0)
    tau = tau_np(lam, material.mu, material.alpha, material.nu)[:d]
    return (n * tau) @ n.T / np.linalg.det(F)


def energy_decimal(lam, material, digits=40):
    """W at principal stretches in 40-digit decimal arithmetic: the closed form itself,
    (exp(−αβ ln J) − 1)/β, has no cancellation problem at that precision even for β ~ 1e-9
    (β = 0: the limit −α ln J)."""
    with localcontext() as ctx:
        ctx.prec = digits
        ln_lam = [Decimal(float(x)).ln() for x in lam]
        ln_J = sum(ln_lam)
        W = Decimal(0)
        for m, a, b in zip(material.mu, material.alpha, betas_np(material.nu, len(material.mu))):
            a, b = Decimal(a), Decimal(b)
            volume = -a * ln_J if b == 0 else ((-a * b * ln_J).exp() - 1) / b
            W += 2 * Decimal(m) / a**2 * (sum((a * x).exp() for x in ln_lam) - 3 + volume)
        return float(W)


QUANTITIES = {"sigma": mat.cauchy_stress, "S": mat.second_piola_kirchhoff,
              "W": mat.strain_energy_density}


@pytest.fixture(scope="module")
def evaluate():
    """evaluate(quantity, material, F): the package's UFL (energy -> ufl.diff -> stresses) at a
    constant 2×2 (plane strain) or 3×3 F, on a one-cell square or cube. Compiled once each."""
    meshes = {2: mesh.create_unit_square(MPI.COMM_SELF, 1, 1),
              3: mesh.create_unit_cube(MPI.COMM_SELF, 1, 1, 1)}
    points = {2: np.array([[1 / 3, 1 / 3]]), 3: np.array([[0.25, 0.25, 0.25]])}
    compiled = {}

    def run(quantity, material, F):
        F = np.asarray(F, dtype=float)
        d = F.shape[0]
        key = (quantity, material, d)
        if key not in compiled:
            Fc = fem.Constant(meshes[d], np.eye(d))
            compiled[key] = Fc, fem.Expression(QUANTITIES[quantity](material, Fc), points[d])
        Fc, expr = compiled[key]
        Fc.value[:] = F
        out = expr.eval(meshes[d], CELL)
        return out.reshape(d, d) if quantity != "W" else float(out.ravel()[0])

    return run


@pytest.fixture(scope="module")
def stress_at(evaluate):
    """σ(F) of the skin for a constant 2×2 F."""
    return lambda F: evaluate("sigma", SKIN, F)


# ---- hyperfoam: closed-form homogeneous states --------------------------------------------

#: Uniaxial states have a double eigenvalue (λ2 = λ3) away from C ∝ I, where the 3D sum's
#: Cardano form has 1/sqrt(1 − r²); kinematics._eigen_sum_3d takes its pair series there, so
#: the 3D checks use the exact uniaxial state (SPLIT = 0). A split t e^δ, t e^−δ keeps J and
#: σ11, and the comparison of σ22, σ33 with the closed form then holds at the split stretches.
SPLIT = 0.0
#: Round-off: the stresses are sums of terms up to ~10× the result (λ^α and J^(−αβ) of both
#: signs), evaluated in double precision; the measured worst relative error is printed.
RTOL = 1e-10


def lateral_stretch(material, l1, n_free):
    """Zero lateral stress: the stretch t of (λ1, t, t) (3D, n_free = 2) or (λ1, t, 1)
    (plane strain, n_free = 1) with τ2 = 0, by a scalar root find on the test's own τ."""
    def tau2(t):
        return tau_of(material, (l1, t, t) if n_free == 2 else (l1, t, 1.0))[1]
    return brentq(tau2, 0.2, 5.0, xtol=1e-15, rtol=1e-15)


@pytest.mark.parametrize("nu", NU_CASES, ids=NU_IDS)
def test_uniaxial_stress_3d_closed_form(evaluate, nu):
    """λ1 given, τ2 = τ3 = 0 fixes t; σ11 = τ1/J, J = λ1 t². One ν: t = J^(−β) zeroes every
    term of τ2, i.e. t = λ1^(−β/(1+2β)) (ν = 0: t = 1)."""
    m = foam(nu)
    worst = 0.0
    for l1 in LAMBDAS:
        t = lateral_stretch(m, l1, n_free=2)
        if not isinstance(nu, tuple):
            b = nu / (1 - 2 * nu)
            assert t == pytest.approx(l1 ** (-b / (1 + 2 * b)), rel=1e-14, abs=1e-15)
        s11 = tau_of(m, (l1, t, t))[0] / (l1 * t * t)
        lam = np.array([l1, t * np.exp(SPLIT), t * np.exp(-SPLIT)])
        got = evaluate("sigma", m, np.diag(lam))
        ref = np.diag(tau_of(m, lam) / np.prod(lam))
        worst = max(worst, abs(got[0, 0] / s11 - 1), np.abs(got - ref).max() / abs(s11))
    print(f"{m.where}: 3D uniaxial stress, max relative error {worst:.1e}")
    assert worst < RTOL


@pytest.mark.parametrize("nu", NU_CASES, ids=NU_IDS)
def test_uniaxial_stress_plane_strain_closed_form(evaluate, nu):
    """λ3 = 1, τ2(λ1, t, 1) = 0 (one ν: t = λ1^(−β/(1+β))); σ11 = τ1/(λ1 t). The root of the
    package's σ22 must be the closed-form t."""
    m = foam(nu)
    worst = 0.0
    for l1 in LAMBDAS:
        t = lateral_stretch(m, l1, n_free=1)
        if not isinstance(nu, tuple):
            b = nu / (1 - 2 * nu)
            assert t == pytest.approx(l1 ** (-b / (1 + b)), rel=1e-14, abs=1e-15)
        t_ufl = brentq(lambda l2, l1=l1: evaluate("sigma", m, np.diag([l1, l2]))[1, 1], 0.2, 5.0,
                       xtol=1e-15, rtol=1e-15)
        s11 = tau_of(m, (l1, t, 1.0))[0] / (l1 * t)
        got = evaluate("sigma", m, np.diag([l1, t]))
        worst = max(worst, abs(t_ufl / t - 1), abs(got[0, 0] / s11 - 1),
                    np.abs(got - np.diag([s11, 0.0])).max() / abs(s11))
    print(f"{m.where}: plane-strain uniaxial stress, max relative error {worst:.1e}")
    assert worst < RTOL


def confined_closed_form(material, lam):
    """Uniaxial strain F = diag(λ, 1, 1), J = λ, by hand:
    σ1 = Σ(2μ_i/α_i)(λ^α_i − λ^(−α_iβ_i))/λ, σ2 = σ3 = Σ(2μ_i/α_i)(1 − λ^(−α_iβ_i))/λ."""
    terms = list(zip(material.mu, material.alpha, betas_np(material.nu, len(material.mu))))
    s1 = sum(2 * m / a * (lam**a - lam ** (-a * b)) for m, a, b in terms) / lam
    s2 = sum(2 * m / a * (1.0 - lam ** (-a * b)) for m, a, b in terms) / lam
    return s1, s2


@pytest.mark.parametrize("nu", NU_CASES, ids=NU_IDS)
def test_confined_compression_closed_form(evaluate, nu):
    """Uniaxial strain (confined compression and its tension counterpart). At ν = 0 the
    lateral stress vanishes identically: no lateral stress without lateral strain."""
    m = foam(nu)
    worst = 0.0
    for lam in LAMBDAS:
        s1, s2 = confined_closed_form(m, lam)
        if nu == 0.0:
            assert s2 == 0.0
        got = evaluate("sigma", m, np.diag([lam, 1.0]))  # plane strain: exactly this state
        worst = max(worst, np.abs(got - np.diag([s1, s2])).max() / abs(s1))
        split = np.array([lam, np.exp(SPLIT), np.exp(-SPLIT)])  # J = λ still
        got = evaluate("sigma", m, np.diag(split))
        ref = np.diag(tau_of(m, split) / np.prod(split))
        worst = max(worst, abs(got[0, 0] / s1 - 1), np.abs(got - ref).max() / abs(s1))
    print(f"{m.where}: confined compression, max relative error {worst:.1e}")
    assert worst < RTOL


def test_nu0_uniaxial_stress_has_no_lateral_contraction(evaluate):
    """ν = 0: J^(−α·0) = 1, so τ_a = Σ(2μ_i/α_i)(λ_a^α_i − 1) depends on λ_a alone and zero
    lateral stress means λ2 = 1 for every λ1. The root is unique: the sum's derivative
    Σ 2μ_i λ2^(α_i − 1) is positive for the skin's μ_i, α_i (checked below)."""
    m = foam(0.0)
    t = np.linspace(0.05, 5.0, 4000)
    assert np.all(sum(2 * mu * t ** (a - 1) for mu, a in zip(m.mu, m.alpha)) > 0)
    for l1 in LAMBDAS:
        l2 = brentq(lambda l2, l1=l1: evaluate("sigma", m, np.diag([l1, l2]))[1, 1], 0.2, 5.0,
                    xtol=1e-15, rtol=1e-15)
        assert abs(l2 - 1) < 1e-14
        # 3D: σ22 = 0 at (λ1, 1, λ3) whatever λ3 (distinct stretches: no double eigenvalue).
        s = evaluate("sigma", m, np.diag([l1, 1.0, 0.77]))
        assert abs(s[1, 1]) < 1e-13 * np.abs(s).max()  # round-off of terms ~10× σ


@pytest.mark.parametrize("F", [np.diag([0.6, 0.6]), np.diag([1.3, 1.3]),
                               np.array([[1.0, 0.4], [0.0, 1.0]]),
                               np.array([[1.0, 1e-6], [0.0, 1.0]])])
@pytest.mark.parametrize("nu", NU_CASES, ids=NU_IDS)
def test_equibiaxial_and_simple_shear_against_numpy(evaluate, F, nu):
    """The tiny shear (γ = 1e-6, σ ~ μ0γ) is a difference of terms ~2μ_i/α_i (1 + α_iβ_i)
    (stretch and volume parts at J ≈ 1): their round-off is an absolute floor."""
    m = foam(nu)
    got, ref = evaluate("sigma", m, F), cauchy_np(F, m)
    floor = 1e-15 * sum(abs(2 * mu / a) * (1 + abs(a * b))
                        for mu, a, b in zip(m.mu, m.alpha, betas_np(nu, len(m.mu))))
    assert np.abs(got - ref).max() <= 1e-9 * np.abs(ref).max() + floor


@pytest.mark.parametrize("nu", NU_CASES, ids=NU_IDS)
def test_3d_energy_stress_at_a_general_state(evaluate, nu):
    m = foam(nu)
    F = np.array([[1.2, 0.1, 0.0], [-0.05, 0.8, 0.15], [0.02, 0.0, 1.05]])
    got, ref = evaluate("sigma", m, F), cauchy_np(F, m)
    assert np.abs(got - ref).max() <= 1e-10 * np.abs(ref).max()


def test_principal_kirchhoff_is_the_closed_form():
    lam = np.array([[0.5, 0.8, 1.3], [1.4, 1.1, 0.6], [1.0, 1.0, 1.0]])
    for nu in NU_CASES:
        m = foam(nu)
        ref = np.array([tau_of(m, x) for x in lam])
        assert np.abs(m.principal_kirchhoff(lam) - ref).max() <= 1e-14 * np.abs(ref).max()


# ---- hyperfoam: the β → 0 limit (ν = 0) ----------------------------------------------------

ENERGY_STATES = [(1.3, 0.7, 0.9), (0.4, 0.5, 0.6), (2.0, 1.5, 1.2), (0.7, 1.2, 1.0)]


@pytest.mark.parametrize("nu", [0.0, 1e-9, 2e-4, 0.0098, 0.0102, 0.4, (0.0, 0.2, 0.45),
                                (1e-9, 0.2, 0.0)])
def test_energy_against_40_digit_closed_form(evaluate, nu):
    """UFL W (3D; plane strain with λ3 = 1) and numpy against the closed form evaluated in
    40-digit arithmetic. |β| < 0.01 (ν = 1e-9, 2e-4, 0.0098) takes the sinh form, ν = 0.0102
    the closed form just above the switch (its error ~eps/β of the term scale there)."""
    m = foam(nu)
    worst = 0.0
    for lam in ENERGY_STATES:
        ref = energy_decimal(lam, m)
        worst = max(worst, abs(evaluate("W", m, np.diag(lam)) / ref - 1),
                    abs(m.principal_energy(np.array(lam)) / ref - 1))
        ref2 = energy_decimal((lam[0], lam[1], 1.0), m)
        worst = max(worst, abs(evaluate("W", m, np.diag(lam[:2])) / ref2 - 1))
    print(f"{m.where}: W, max relative error {worst:.1e}")
    assert worst < 1e-11


def test_beta_to_zero_is_continuous(evaluate):
    """(J^(−αβ) − 1)/β = −α ln J + α²β ln²J/2 + O(β²), so for one β
    W(β) − W(0) = Σ 2μ_i/α_i² · α_i²β ln²J/2 = μ0 β ln²J and
    S(β) − S(0) = 2 ∂/∂C (μ0 β ln²J) = 2μ0 β ln J C⁻¹ (∂ ln J/∂C = C⁻¹/2), up to O(β²).
    ν = 1e-9: W and S agree with ν = 0 to ~1e-8; ν = 1e-6 (large enough for the difference to
    stand above round-off, small enough for O(β²) to be ~1e-6 of it): the first-order term
    itself, to 1e-5."""
    zero = foam(0.0)
    states = [np.array([[1.2, 0.1, 0.0], [-0.05, 0.6, 0.15], [0.02, 0.0, 0.7]]),
              np.array([[1.4, 0.3], [0.1, 1.3]]), np.diag([0.5, 0.8])]
    for F in states:
        W0, S0 = evaluate("W", zero, F), evaluate("S", zero, F)
        for nu, rtol in ((1e-9, 1e-8), (1e-6, 1e-5)):
            m = foam(nu)
            b = nu / (1 - 2 * nu)
            W, S = evaluate("W", m, F), evaluate("S", m, F)
            ln_J = np.log(np.linalg.det(F))
            dW = m.mu0 * b * ln_J**2
            dS = 2 * m.mu0 * b * ln_J * np.linalg.inv(F.T @ F)
            print(f"nu = {nu:g}: W/W0 − 1 = {W / W0 - 1:.2e}, "
                  f"(W − W0)/(μ0 β ln²J) − 1 = {(W - W0) / dW - 1:.1e}")
            if nu == 1e-9:
                assert abs(W / W0 - 1) < 1e-8
                assert np.abs(S - S0).max() < 1e-8 * np.abs(S0).max()
            else:
                assert (W - W0) == pytest.approx(dW, rel=rtol)
                assert np.abs(S - S0 - dS).max() < rtol * np.abs(dS).max()


def test_nu0_is_finite_far_from_J_1(evaluate):
    """ν = 0: W, S, σ and the tangent ∂P/∂F finite at J from 1e-3 to 1e3 (and at F = I)."""
    m = foam(0.0)
    states = [np.diag([0.05, 0.02]), np.diag([40.0, 25.0]), np.eye(2),
              np.array([[0.1, 0.05], [0.0, 0.01]]),
              np.diag([0.05, 0.1, 0.2]), np.diag([12.0, 9.0, 10.5]), np.eye(3)]
    meshes = {2: mesh.create_unit_square(MPI.COMM_SELF, 1, 1),
              3: mesh.create_unit_cube(MPI.COMM_SELF, 1, 1, 1)}
    tangents = {}
    for d, msh in meshes.items():
        Fc = fem.Constant(msh, np.eye(d))
        Fv = ufl.variable(Fc)
        A = ufl.diff(mat.first_piola_kirchhoff(m, Fv), Fv)
        tangents[d] = Fc, fem.Expression(A, np.full((1, d), 0.25))
    for F in states:
        d = F.shape[0]
        Fc, expr = tangents[d]
        Fc.value[:] = F
        values = [evaluate("W", m, F), evaluate("S", m, F), evaluate("sigma", m, F),
                  expr.eval(meshes[d], CELL)]
        assert all(np.all(np.isfinite(v)) for v in values), F
    lam = np.array([[0.05, 0.02, 1.0], [40.0, 25.0, 1.0], [1e-3, 1.0, 1.0], [1e3, 1.0, 1.0]])
    assert np.all(np.isfinite(m.principal_kirchhoff(lam)))
    assert np.all(np.isfinite(m.principal_energy(lam)))


def test_moduli_of_the_paper_sets():
    assert SKIN.mu0 == pytest.approx(1.16e-3, rel=1e-12)
    assert mat.SUBCUTANEOUS.mu0 == pytest.approx(0.579e-3, rel=1e-12)
    assert SKIN.beta == pytest.approx(2.0)
    # ν recovered from the small-strain moduli: ν = (3K − 2μ)/(2(3K + μ)).
    K, G = SKIN.K0, SKIN.mu0
    assert (3 * K - 2 * G) / (2 * (3 * K + G)) == pytest.approx(0.40, rel=1e-12)
    assert SKIN.nu0 == 0.4 and SKIN.betas == (SKIN.beta,) * 3


def test_moduli_with_nu0_and_per_term_nu():
    zero = foam(0.0)
    assert zero.beta == 0.0 and zero.betas == (0.0, 0.0, 0.0)
    assert zero.K0 == pytest.approx(2 * zero.mu0 / 3, rel=1e-12)  # λ0 = 0: no volume coupling
    assert zero.lame_lambda0 == 0.0
    m = foam((0.0, 0.2, 0.45))
    betas = (0.0, 0.2 / 0.6, 0.45 / 0.1)
    assert m.nu == (0.0, 0.2, 0.45) and m.nus == m.nu
    assert m.betas == pytest.approx(betas, rel=1e-15)
    K = sum(2 * mu * (1 / 3 + b) for mu, b in zip(m.mu, betas))
    assert m.K0 == pytest.approx(K, rel=1e-14)
    assert m.nu0 == pytest.approx((3 * K - 2 * m.mu0) / (2 * (3 * K + m.mu0)), rel=1e-14)
    with pytest.raises(InputError, match="differs per term.*betas"):
        _ = m.beta
    # The same ν written per term is the same material (and has a single β).
    same = foam((0.4, 0.4, 0.4))
    assert same.beta == SKIN.beta and same.K0 == SKIN.K0


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


@pytest.mark.parametrize("nu", NU_CASES, ids=NU_IDS)
def test_tangent_at_u0_is_the_linear_elastic_stiffness(square, nu):
    """d²W at u = 0 must be the plane-strain Hooke tensor with μ0 = Σμ_i and
    λ0 = K0 − 2μ0/3 = Σ 2μ_iβ_i (K0 = Σ 2μ_i(1/3 + β_i)); λ0 = 0 at ν = 0."""
    m = foam(nu)
    mu0 = sum(m.mu)
    lam0 = sum(2 * mu * b for mu, b in zip(m.mu, betas_np(nu, len(m.mu))))
    assert m.mu0 == pytest.approx(mu0, rel=1e-14)
    assert m.lame_lambda0 == pytest.approx(lam0, rel=1e-12, abs=1e-15 * mu0)
    _, V = square
    u, v, du = fem.Function(V), ufl.TestFunction(V), ufl.TrialFunction(V)
    R = ufl.inner(mat.first_piola_kirchhoff(m, deformation_gradient(u)), ufl.grad(v)) * ufl.dx
    K = dense(ufl.derivative(R, u, du))

    def eps(w):
        return ufl.sym(ufl.grad(w))

    K_lin = dense((lam0 * ufl.tr(eps(du)) * ufl.tr(eps(v))
                   + 2 * mu0 * ufl.inner(eps(du), eps(v))) * ufl.dx)
    err = np.abs(K - K_lin).max() / np.abs(K_lin).max()
    print(f"{m.where}: tangent at u = 0, max relative error {err:.2e}")
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
    ({"mu": (0.1, 0.2), "alpha": (2.0,), "nu": 0.3}, "'alpha' has 1"),
    ({"mu": (0.1,), "alpha": (0.0,), "nu": 0.3}, "contains 0"),
    ({"mu": (0.1,), "alpha": (2.0,), "nu": 0.5}, "outside (-1, 0.5)"),
    ({"mu": (-0.1, 0.05), "alpha": (2.0, 3.0), "nu": 0.3}, "mu0"),
    ({"mu": (), "alpha": (), "nu": 0.3}, "empty"),
    ({"mu": "0.1", "alpha": (2.0,), "nu": 0.3}, "list of numbers"),
    ({"mu": (0.1,), "alpha": (float("nan"),), "nu": 0.3}, "non-finite"),
    ({"mu": (0.1, 0.2), "alpha": (2.0, 3.0), "nu": (0.3,)}, "'nu' has 1 values"),
    ({"mu": (0.1, 0.2), "alpha": (2.0, 3.0), "nu": (0.3, 0.5)}, "[0.5] are outside (-1, 0.5)"),
    ({"mu": (0.1, 0.2), "alpha": (2.0, 3.0), "nu": (0.3, "x")}, "list of numbers"),
    # μ0 = 0.05 > 0, but K0 = 2(−0.1(1/3 + 24.5) + 0.15/3) < 0: a stiff-in-volume negative term
    ({"mu": (-0.1, 0.15), "alpha": (2.0, 3.0), "nu": (0.49, 0.0)}, "K0"),
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
    per_term = mat.Hyperfoam.from_dict({"mu": [1e-3, 2e-3], "alpha": [2.0, 4.0], "nu": [0, 0.2]})
    assert per_term.nu == (0.0, 0.2) and per_term.betas == (0.0, 0.2 / 0.6)
    assert mat.Hyperfoam.from_dict({"mu": [1e-3], "alpha": [2.0], "nu": 0}).nu == 0.0
    with pytest.raises(InputError, match=r"hyperfoam\.alpha1: unknown parameter\(s\).*"
                                         r"takes: mu, alpha, nu"):
        mat.Hyperfoam.from_dict({"mu": [1e-3], "alpha1": [2.0], "nu": 0.3})
    with pytest.raises(InputError, match=r"missing parameter\(s\) nu"):
        mat.Hyperfoam.from_dict({"mu": [1e-3], "alpha": [2.0]})
    with pytest.raises(InputError, match="must be a table"):
        mat.Hyperfoam.from_dict([1e-3, 2.0, 0.3])
    with pytest.raises(InputError, match="'E' = -1.0"):
        mat.LinearElastic.from_dict({"E": -1.0, "nu": 0.3})
    with pytest.raises(InputError, match="must be a number"):
        mat.LinearElastic.from_dict({"E": "stiff", "nu": 0.3})


@pytest.mark.parametrize("kwargs, words", [
    ({"g": (0.5, 0.6), "tau": (1.0, 2.0)}, "sum(g)"),
    ({"g": (0.1, -0.1), "tau": (1.0, 2.0)}, "must be > 0"),
    ({"g": (0.1,), "tau": (1.0, 2.0)}, "'tau' has 2"),
    ({"g": (0.1,), "tau": (0.0,)}, "relaxation times"),
])
def test_prony_rejects_bad_parameters(kwargs, words):
    with pytest.raises(InputError) as err:
        mat.Prony(**kwargs)
    assert words in str(err.value)


@pytest.mark.parametrize("kwargs, words", [
    ({"k0": 0.0, "phi0": 0.4, "kappa": 0.1, "M": 1.0}, "'k0'"),
    ({"k0": 1e-3, "phi0": 1.0, "kappa": 0.1, "M": 1.0}, "'phi0'"),
    ({"k0": 1e-3, "phi0": 0.4, "kappa": -0.1, "M": 1.0}, "'kappa'"),
])
def test_holmes_mow_rejects_bad_parameters(kwargs, words):
    with pytest.raises(InputError) as err:
        mat.HolmesMow(**kwargs)
    assert words in str(err.value)
