"""The fast-relaxation materials set (data/materials/fast-relaxation.toml): it loads, its
Prony series is valid, its construction keeps the paper's stress history at t >> 70 ms (an
identity of the construction, to round-off), and its record reads back."""

import numpy as np
import pytest

from fingertip_dolfinx.drucker import drucker_check
from fingertip_dolfinx.tissues import WU2004, load_materials

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
