"""Drucker stability of hyperfoam sets (numpy)."""

import numpy as np
import pytest

from fingertip_dolfinx.errors import InputError, MaterialInstabilityError
from fingertip_dolfinx.physics import drucker as st
from fingertip_dolfinx.physics import materials as mat

#: μ0 = 0.3 > 0 (stable at small strain) but d(λ) = 2(−0.2λ + 0.5λ³) < 0 for λ < sqrt(0.4):
#: loses stability in plane-strain equibiaxial compression at exactly λ = 0.6325.
SOFTENING = mat.Hyperfoam(mu=(-0.2, 0.5), alpha=(1.0, 3.0), nu=0.3, where="softening foam")


def fd_tangent(material, lam, h=1e-6):
    """∂τ_a/∂(ln λ_b) by central differences of the principal Kirchhoff stresses."""
    D = np.zeros((3, 3))
    for b in range(3):
        e = np.zeros(3)
        e[b] = h
        D[:, b] = (material.principal_kirchhoff(lam * np.exp(e))
                   - material.principal_kirchhoff(lam * np.exp(-e))) / (2 * h)
    return D


def foam(nu):
    return mat.Hyperfoam(mu=mat.SKIN.mu, alpha=mat.SKIN.alpha, nu=nu, where=f"skin, nu = {nu}")


NU_CASES = [0.0, 0.4, (0.0, 0.2, 0.45)]
NU_IDS = ["nu=0", "nu=0.4", "nu_i=(0,0.2,0.45)"]


@pytest.mark.parametrize("nu", NU_CASES, ids=NU_IDS)
@pytest.mark.parametrize("lam", [(0.8, 1.2, 1.0), (0.5, 0.6, 1.0), (1.4, 0.9, 1.1)])
def test_tangent_is_diag_plus_rank_one(nu, lam):
    """D = ∂τ/∂ ln λ = diag(d) + v 11ᵀ, v = Σ 2μ_iβ_i J^(−α_iβ_i) (0 at ν = 0), against
    central differences of principal_kirchhoff (error ~h² ≈ 1e-12 relative, plus round-off
    eps/h of the stresses)."""
    m = foam(nu)
    lam = np.array(lam)
    d, v = st.coaxial_tangent_parts(m, lam)
    D = fd_tangent(m, lam)
    assert np.abs(np.diag(d) + v - D).max() < 1e-8 * np.abs(D).max()
    if nu == 0.0:
        assert v == 0.0  # no volumetric coupling: τ_a depends on λ_a alone
        assert np.abs(D - np.diag(np.diag(D))).max() < 1e-8 * np.abs(D).max()


@pytest.mark.parametrize("plane_strain", [True, False])
def test_per_term_nu_paths_have_zero_free_stress(plane_strain):
    """Per-term ν_i: the free stretches of the test paths come from Newton continuation (no
    closed form); their stresses vanish, and with ν_i equal up to 1e-13 they are the one-ν
    closed form t = s^(−β n_s/(1 + n_f β)) (to the 2.5e-12 that δβ = δν/(1 − 2ν)² makes)."""
    s = np.concatenate([np.arange(1.0, 0.2, -1e-2), np.arange(1.0, 2.0, 1e-2)])
    m = foam((0.0, 0.2, 0.45))
    for name, path in st.loading_paths(m, plane_strain).items():
        lam = path(s)
        assert np.all(np.isfinite(lam)), name
        lam3 = np.concatenate([lam, np.ones((len(s), 1))], -1) if plane_strain else lam
        tau = m.principal_kirchhoff(lam3)
        axes = (st.PATHS_PLANE if plane_strain else st.PATHS_3D)[name]
        free = [i for i, a in enumerate(axes) if a == "t"]
        assert np.abs(tau[:, free]).max(initial=0.0) < 1e-13 * np.abs(tau).max(), name
    near, one = foam((0.4, 0.4, 0.4 + 1e-13)), mat.SKIN
    for (name, a), b in zip(st.loading_paths(near, plane_strain).items(),
                            st.loading_paths(one, plane_strain).values()):
        assert np.abs(a(s) / b(s) - 1).max() < 1e-11, name


@pytest.mark.parametrize("nu", [0.0, (0.0, 0.2, 0.45)], ids=["nu=0", "nu_i=(0,0.2,0.45)"])
def test_nu0_and_per_term_skin_are_drucker_stable(nu):
    """With the skin's μ_i, α_i the extreme exponents carry positive μ_i (d_a > 0), and the
    terms with β_i > 0 have μ_i > 0 (v ≥ 0): stable everywhere, as with the paper's ν."""
    for plane_strain in (True, False):
        result = st.drucker_check(foam(nu), plane_strain=plane_strain)
        print(result.describe())
        assert result.stable_everywhere


@pytest.mark.parametrize("material", [mat.SKIN, mat.SUBCUTANEOUS])
def test_paper_sets_are_drucker_stable_in_plane_strain(material):
    """Finding (see drucker.py): d_a > 0 and v > 0 at every stretch, so the paper's sets
    never lose stability on [0.2, 2]²; MODEL.md's 0.40 / 0.45 is not reproduced."""
    result = st.drucker_check(material, plane_strain=True)
    print(result.describe())
    assert result.stable_everywhere
    assert all(c is None and t is None for c, t in result.first_unstable.values())
    lam = np.linspace(0.05, 5.0, 2000)
    d, v = st.coaxial_tangent_parts(material, np.stack([lam, lam, lam], -1))
    assert np.all(d > 0) and np.all(v > 0)


def test_naive_eigensolver_reports_false_instability():
    """Why the minors: at λ1 = λ2 = 0.3 (plane strain) v/d ~ 1e16 and eigvalsh loses the
    small eigenvalue; the exact minors say stable."""
    lam = np.array([0.3, 0.3, 1.0])
    d, v = st.coaxial_tangent_parts(mat.SKIN, lam)
    naive = np.linalg.eigvalsh((np.diag(d) + v)[:2, :2]).min()
    assert naive <= 0 < d[0]
    assert st.is_stable(mat.SKIN, lam[:2])


def test_softening_set_first_instability():
    result = st.drucker_check(SOFTENING, plane_strain=True)
    print(result.describe())
    c, t = result.first_unstable["equibiaxial"]
    assert c == pytest.approx(np.sqrt(0.4), abs=1.5e-3) and t is None
    assert not result.stable_everywhere
    assert st.drucker_check(SOFTENING, plane_strain=False).first_unstable["volumetric"][0] \
        == pytest.approx(np.sqrt(0.4), abs=1.5e-3)


def test_check_state_warns_or_raises():
    states = np.array([[0.9, 0.9], [0.5, 0.5]])
    assert st.check_state(SOFTENING, states[:1], "skin")
    with pytest.warns(RuntimeWarning, match="Drucker"):
        assert not st.check_state(SOFTENING, states, "skin at step 3")
    with pytest.raises(MaterialInstabilityError, match="skin at step 3.*0.5"):
        st.check_state(SOFTENING, states, "skin at step 3", mode="error")
    with pytest.raises(InputError, match="mode"):
        st.check_state(SOFTENING, states, "skin", mode="loud")


def test_unstable_at_small_strain_is_an_input_error():
    with pytest.raises(InputError, match="mu0"):
        mat.Hyperfoam(mu=tuple(-m for m in mat.SKIN.mu), alpha=mat.SKIN.alpha, nu=0.4)
