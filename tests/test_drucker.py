"""Drucker stability of hyperfoam sets (numpy)."""

import numpy as np
import pytest

from fingertip_dolfinx import drucker as st
from fingertip_dolfinx import materials as mat
from fingertip_dolfinx.errors import InputError, MaterialInstabilityError

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


def test_tangent_is_diag_plus_rank_one():
    lam = np.array([0.8, 1.2, 1.0])
    d, v = st.coaxial_tangent_parts(mat.SKIN, lam)
    assert np.allclose(np.diag(d) + v, fd_tangent(mat.SKIN, lam), rtol=1e-7)


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
