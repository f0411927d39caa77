"""The fast-relaxation materials set (data/materials/fast-relaxation.toml): it loads, its
Prony series is valid, its construction keeps the paper's stress history at t >> 70 ms (an
identity of the construction, to round-off), and its record reads back."""

import numpy as np
import pytest

from fingertip_dolfinx.physics.drucker import drucker_check
from fingertip_dolfinx.physics.tissues import WU2004, load_materials

FAST = load_materials("fast-relaxation")


def test_it_loads_with_a_valid_series():
    prony = FAST.skin_prony
    assert prony.tau == (0.004, 0.070, 2.123, 9.371)  # Pawluk & Howe 1999 (4, 70 ms); Wu 2004
    assert prony.g_inf == pytest.approx(0.30, abs=1e-15)
    assert 0 < prony.g_inf < 1 and all(g > 0 for g in prony.g)
    assert prony.relaxation(0.0) == pytest.approx(1.0, abs=1e-15)
    assert np.all(np.diff(prony.relaxation(np.logspace(-5, 2, 200))) < 0)  # relaxes, monotone
    # every other region and every density is the paper's set
    assert FAST.densities() == WU2004.densities()
    for region in ("subcutaneous", "bone", "nail"):
        assert getattr(FAST, region) == getattr(WU2004, region)
    assert FAST.skin.alpha == WU2004.skin.alpha and FAST.skin.nu == WU2004.skin.nu


def test_the_paper_s_history_is_kept_at_long_times():
    """mu' G'(t) − mu G_p(t) = mu' (0.30 e^{−t/4 ms} + 0.20 e^{−t/70 ms}) for every term
    (mu' = 2 mu): the identity of the construction, so round-off only (1e-12)."""
    t = np.array([0.0, 0.001, 0.01, 0.1, 0.5, 1.0, 5.0, 30.0])
    fast = FAST.skin_prony.relaxation(t)
    paper = WU2004.skin_prony.relaxation(t)
    tail = 0.30 * np.exp(-t / 0.004) + 0.20 * np.exp(-t / 0.070)
    for mu_new, mu_old in zip(FAST.skin.mu, WU2004.skin.mu):
        assert mu_new == pytest.approx(2 * mu_old, rel=1e-12)
        np.testing.assert_allclose(mu_new * fast - mu_old * paper, mu_new * tail,
                                   rtol=1e-12, atol=1e-15)
    # at 1 s the difference is below 1e-6 of the paper's stress (e^{−1/0.07} = 6e-7)
    assert abs(fast[5] * 2 / paper[5] - 1) < 1e-6


def test_a_uniform_scale_keeps_drucker_stability():
    assert drucker_check(FAST.skin).stable_everywhere == drucker_check(
        WU2004.skin).stable_everywhere


def test_the_record_reads_back():
    assert load_materials("fast-relaxation", FAST.record()) == FAST
    assert load_materials("fast-relaxation", FAST.record()).densities() == FAST.densities()


def test_a_ramp_is_stiffer_by_the_fast_terms_only(shared_tmp_path):
    """Coarse 1pt ramp (1 mm in 1 s) with both sets. By construction the fast set's skin
    stress exceeds the paper's by ∫ 2·(0.30 e^{−(t−s)/4 ms} + 0.20 e^{−(t−s)/70 ms}) dS_e(s),
    S_e the paper's instantaneous response: > 0 under monotone loading and at most
    2 Σ g_k τ_k max Ṡ_e ≈ 2 Σ g_k τ_k n S_e / t, with n = d ln F / d ln t at the ramp's end
    (the force's exponent standing in for the skin stress's; the subcutaneous tissue, without
    fast terms, carries part of the load, which only lowers the total's share)."""
    from fingertip_dolfinx.runner import run
    from fingertip_dolfinx.scene import load_scene

    coarse = ["section.mesh.min_size=0.2", "section.mesh.max_size=1.0",
              "section.mesh.bone_size=2.0", "output.pictures=false"]
    runs = {m: run(load_scene("1pt", [*coarse, f'materials.set="{m}"']), shared_tmp_path / m,
                   progress=False) for m in ("wu2004", "fast-relaxation")}
    paper, fast = runs["wu2004"], runs["fast-relaxation"]
    t, force = paper.time[1:], paper.force[1:]
    n = np.gradient(np.log(force), np.log(t))[-1]
    bound = 2 * (0.30 * 0.004 + 0.20 * 0.070) * n / t[-1]
    assert 0 < fast.force[-1] / force[-1] - 1 < bound
