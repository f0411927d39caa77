"""The damped-fingerpad materials set (data/materials/damped-fingerpad.toml): it loads and is
valid (Prony series, Drucker stability), the file is what scripts/fit_damping.py fits, its
complex modulus G*(ω) (harmonic.complex_modulus, the frequency route's) reproduces the fitted
loss tangent over 20–1000 Hz within the stated residual, and the paper's behaviour at
t ≫ 10 ms is kept (identity of the construction; a coarse 1pt ramp and hold)."""

import numpy as np
import pytest

from fingertip_dolfinx.harmonic import complex_modulus
from fingertip_dolfinx.physics.drucker import drucker_check
from fingertip_dolfinx.physics.tissues import WU2004, load_materials

DAMPED = load_materials("damped-fingerpad")
FAST = 5  # the first five terms are the fitted fast ones (0.1–10 ms)
SCALE = 1 / (1 - sum(DAMPED.skin_prony.g[:FAST]))  # the mu scale of the construction
ETA0 = 0.81 / (np.pi * (1 - 0.81 / 2))  # the target loss tangent (data file: one tap, D = 0.81)
BAND = np.logspace(np.log10(20.0), np.log10(1000.0), 25)  # Hz, the fit's points


def test_it_loads_with_a_valid_series():
    prony = DAMPED.skin_prony
    assert prony.tau[:FAST] == pytest.approx(np.logspace(-4, -2, 5), rel=1e-4)  # 0.1–10 ms
    assert prony.tau[FAST:] == (2.123, 9.371)  # Wu 2004
    assert 0 < prony.g_inf < 1 and all(g > 0 for g in prony.g)
    assert np.all(np.diff(prony.relaxation(np.logspace(-6, 2, 400))) < 0)  # relaxes, monotone
    for region in ("bone", "nail"):  # every other region is the paper's
        assert getattr(DAMPED, region) == getattr(WU2004, region)
    sub, paper = DAMPED.subcutaneous, WU2004.subcutaneous  # the pulp: its solid's mu scaled
    assert (sub.phi0, sub.permeability) == (paper.phi0, paper.permeability)
    assert sub.solid.alpha == paper.solid.alpha and sub.solid.nu == paper.solid.nu
    assert DAMPED.subcutaneous_prony.g == prony.g[:FAST]  # the pulp: the fast terms alone
    assert DAMPED.subcutaneous_prony.tau == prony.tau[:FAST]
    assert DAMPED.densities() == WU2004.densities()
    assert DAMPED.skin.alpha == WU2004.skin.alpha and DAMPED.skin.nu == WU2004.skin.nu
    assert load_materials("damped-fingerpad", DAMPED.record()) == DAMPED  # the record reads back


def test_a_uniform_scale_keeps_drucker_stability():
    assert drucker_check(DAMPED.skin).stable_everywhere == drucker_check(
        WU2004.skin).stable_everywhere


def test_the_file_is_the_fit(repo_root, monkeypatch):
    """scripts/fit_damping.py's weights (rounded as shipped) and mu scale are the file's."""
    monkeypatch.syspath_prepend(str(repo_root / "scripts"))
    import fit_damping

    g_fast, residual, _ = fit_damping.fit(fit_damping.tomllib.loads(fit_damping.DATA.read_text()))
    assert tuple(g_fast) == DAMPED.skin_prony.g[:FAST]
    g, tau = fit_damping.full_series(g_fast)
    assert DAMPED.skin_prony.g == pytest.approx(g, abs=5e-7)  # the slow terms to 6 digits
    assert DAMPED.skin_prony.tau == pytest.approx(tau, rel=1e-12)
    for mu, mu_p in zip(DAMPED.skin.mu, WU2004.skin.mu):
        assert mu == pytest.approx(SCALE * mu_p, rel=1e-5)  # printed to 6 digits
    assert residual["loss_rel"] < 0.03 and residual["magnitude_rel"] < 0.03
    # The pulp: the same fit without slow terms; its relaxed modulus is the paper's.
    slow, _ = fit_damping.REGIONS["subcutaneous"]
    g_pulp, residual, _ = fit_damping.fit(fit_damping.tomllib.loads(fit_damping.DATA.read_text()),
                                          slow)
    assert tuple(g_pulp) == DAMPED.subcutaneous_prony.g
    for mu, mu_p in zip(DAMPED.subcutaneous.solid.mu, WU2004.subcutaneous.solid.mu):
        assert mu == pytest.approx(mu_p / (1 - sum(g_pulp)), rel=1e-5)
    assert residual["loss_rel"] < 0.03 and residual["magnitude_rel"] < 0.03


def test_the_shipped_modulus_has_the_fitted_loss_over_the_band():
    """The frequency route's G*(ω) of the shipped series: loss tangent within 3 % of 0.433
    (the stated residual, 2.8 %) at the fit's 25 points, and |G*| within 3 % of the power law
    f^n, n = (2/π) atan(0.433), through its band mean (stated: 2.5 %). Fails for the paper's
    set (loss < 1e-3) and for the fast-relaxation set (loss 0.19 at 40 Hz, 0.01 at 1 kHz)."""
    G = np.array([complex_modulus(DAMPED.skin_prony, 2 * np.pi * f) for f in BAND])
    np.testing.assert_allclose(G.imag / G.real, ETA0, rtol=0.03)
    law = np.abs(G) / BAND ** (2 / np.pi * np.arctan(ETA0))
    np.testing.assert_allclose(law, np.exp(np.mean(np.log(law))), rtol=0.03)
    # the dynamic modulus of the skin, mu G*: the paper's at 1 Hz, ~4.7 times it at 1 kHz
    assert SCALE * abs(complex_modulus(DAMPED.skin_prony, 2 * np.pi)) == pytest.approx(1, abs=0.01)
    assert SCALE * abs(G[-1]) == pytest.approx(4.73, rel=0.01)


def test_the_paper_s_history_is_kept_at_long_times():
    """mu' G'(t) − mu G_p(t) = mu' Σ_fast g_f e^{−t/τ_f} for every term (mu' = mu/(1 − S)): the
    identity of the construction, to the 6 printed digits of mu' and of the slow g."""
    t = np.array([0.0, 1e-4, 1e-3, 0.01, 0.05, 0.1, 1.0, 5.0, 30.0])
    damped, paper = DAMPED.skin_prony.relaxation(t), WU2004.skin_prony.relaxation(t)
    prony = DAMPED.skin_prony
    tail = sum(g * np.exp(-t / tau) for g, tau in zip(prony.g[:FAST], prony.tau[:FAST]))
    for mu_new, mu_old in zip(DAMPED.skin.mu, WU2004.skin.mu):
        np.testing.assert_allclose(mu_new * damped - mu_old * paper, mu_new * tail,
                                   rtol=0, atol=2e-6 * abs(mu_old))
    assert abs(SCALE * damped[6] / paper[6] - 1) < 1e-5  # at 1 s: the paper's relaxation


@pytest.mark.slow
def test_a_coarse_1pt_ramp_and_hold_is_the_paper_s(shared_tmp_path):
    """Coarse 1pt (1 mm in 1 s, steps ≤ 0.05 s) held to 1.2 s, both sets.

    The contact reads the skin's instantaneous modulus (γ = γ0 M/h and Nitsche's traction
    estimate from the elastic stress), 6.85 times the paper's here: its O(1/γ0) error differs
    between the sets, 1.0 % of the held force at the default γ0 = 10 (measured), 0.10 % at
    γ0 = 100, used here. After 0.2 s of hold (20 τ_max) the fast terms are gone: the forces
    agree to 2e-3. At the ramp's end the fast terms act as a viscous stress mu' Σ g_f τ_f Ṡ_e:
    the force exceeds the paper's by about E = SCALE Σ g_f τ_f Ḟ/F, the excess if the whole
    force relaxes with the fast series, as it now does (skin and pulp carry the same fast terms;
    measured 1.52 % against E = 1.47 %, and 0.47 % when only the skin had them), plus the
    contact's difference between the sets (held: 0.1 % at γ0 = 100, bounded by the 2e-3
    asserted for the held force)."""
    from fingertip_dolfinx.runner import run
    from fingertip_dolfinx.scene import load_scene

    coarse = ["section.mesh.min_size=0.2", "section.mesh.max_size=1.0",
              "section.mesh.bone_size=2.0", "output.pictures=false", "protocol.end_time=1.2",
              "steps.dt_max=0.05", "model.contact_gamma0=100.0"]
    runs = {m: run(load_scene("1pt", [*coarse, f'materials.set="{m}"']),
                   shared_tmp_path / f"damping-{m}", progress=False)
            for m in ("wu2004", "damped-fingerpad")}
    paper, damped = runs["wu2004"], runs["damped-fingerpad"]
    end = {m: int(np.argmin(abs(r.time - 1.0))) for m, r in runs.items()}
    assert paper.time[end["wu2004"]] == pytest.approx(1.0) == damped.time[end["damped-fingerpad"]]
    i, f = end["wu2004"], paper.force
    rate = (f[i] - f[i - 1]) / (paper.time[i] - paper.time[i - 1]) / f[i]
    prony = DAMPED.skin_prony
    bound = SCALE * sum(g * tau for g, tau in zip(prony.g[:FAST], prony.tau[:FAST])) * rate
    assert 0 < damped.force[end["damped-fingerpad"]] / f[i] - 1 < bound + 2e-3
    assert paper.time[-1] == pytest.approx(1.2) == damped.time[-1]
    assert damped.force[-1] == pytest.approx(f[-1], rel=2e-3)
