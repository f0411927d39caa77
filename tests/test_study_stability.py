"""The stability study detects each known failure where it is expected, and the stable method
stays within its accuracy. One coarse run of the whole study (files included) feeds every test.

Measured on the coarse study (serial, DOLFINx 0.11), for the margins below:
- P1/P1 vs Taylor–Hood, undrained strip load: checkerboard RMS ratio 8.5, max off the footing
  edge 14.8; settlement error 5.0 % (P1/P1) vs 0.14 % (TH).
- Nitsche θ = 0: γ0 = 10 → 19 iterations, penetration 9e-5 of the depth; γ0 = 100 → 42
  iterations (peak pressure 90 % off); γ0 = 1000 → DIVERGED_LINE_SEARCH; γ0 = 0.1 → penetration
  5.8e-3 of the depth.
- tangent at C = I: exact 7e-16; ε = 3e-16 → 1.5e-7; ε = 1e-6 → 7.3e-7; naive → NaN.
- Terzaghi first step, Δt/bound = 0.0015 … 0.15: overshoot 51 … 40 % (TH), 185 … 89 % (P1/P1);
  from 15× the bound on: p stays below the load (as the exact one-step solution does).
"""

import math

import pytest
from mpi4py import MPI

from fingertip_dolfinx.studies.stability import run_stability_study


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("stability")
    rows = run_stability_study(out, coarse=True, comm=MPI.COMM_SELF)
    return out, rows


def pick(rows, case, method=None, value=None):
    found = [r for r in rows if r["case"].startswith(case)
             and (method is None or r["method"] == method)
             and (value is None or r["value"] == value)]
    assert found, (case, method, value)
    return found


def test_every_case_ran_and_the_files_are_written(study):
    out, rows = study
    assert not [r for r in rows if r["method"] == "(case failed)"]
    assert {r["case"][0] for r in rows} == set("12345")
    header = (out / "stability.csv").read_text().splitlines()[0].split(",")
    assert header[:4] == ["case", "method", "parameter", "value"]
    md = (out / "stability.md").read_text()
    assert md.count("## Case") == 5 and "no interpretation" not in md
    for name in ("p1p1_vs_taylor_hood", "nitsche", "time_step"):
        assert (out / f"stability_{name}.png").stat().st_size > 10_000


def test_p1p1_checkerboards_where_taylor_hood_does_not(study):
    _, rows = study
    (th,) = pick(rows, "1", "Taylor-Hood P2/P1")
    (p1,) = pick(rows, "1", "P1/P1")
    assert th["converged"] and p1["converged"]
    # measured 8.5 (RMS) and 14.8 (max away from the footing edge): assert about half
    assert p1["checkerboard_rms"] > 4 * th["checkerboard_rms"]
    assert p1["checkerboard_max_off_edge"] > 7 * th["checkerboard_max_off_edge"]
    assert th["settlement_error"] < 0.01  # undrained settlement (measured 0.14 %)
    assert p1["settlement_error"] > 3 * th["settlement_error"]
    assert th["J_change_max"] < 2e-3  # undrained: the volume is kept


def test_nitsche_gamma_sweep_theta_zero(study):
    _, rows = study
    g = {r["value"]: r for r in pick(rows, "2", "theta=+0")}
    good = g[10.0]
    assert good["converged"]
    assert good["penetration_over_depth"] < 1e-3
    assert good["halfwidth_error"] < 0.06 and good["peak_pressure_error"] < 0.02
    # γ0 = 100: converges, but needs about twice the iterations (measured 42 vs 19) and its
    # peak pressure is far off; γ0 = 1000 fails (measured: line search) or needs ≥ 3×.
    assert g[100.0]["newton_iterations"] >= 1.8 * good["newton_iterations"]
    assert g[100.0]["peak_pressure_error"] > 0.3
    assert (not g[1000.0]["converged"]
            or g[1000.0]["newton_iterations"] >= 3 * good["newton_iterations"])
    # too small γ0: the surface sinks into the cylinder (measured 60× more)
    assert g[0.1]["penetration_over_depth"] > 10 * good["penetration_over_depth"]


def test_nitsche_theta_variants_at_gamma_ten_agree(study):
    _, rows = study
    for theta in ("theta=-1", "theta=+1"):
        (r,) = pick(rows, "2", theta, 10.0)
        assert r["converged"] and abs(r["force_vs_theta0_gamma10"]) < 1e-3


def test_tangent_at_identity(study):
    _, rows = study
    (exact,) = pick(rows, "3", "exact series switch (kinematics.eigen_sum)")
    assert exact["d2W_rel_error"] <= 1e-12 and exact["jacobian_rel_error"] <= 1e-12
    for eps in (3e-16, 1e-6):
        (r,) = pick(rows, "3", "epsilon in sqrt", eps)
        assert r["finite"] and r["d2W_rel_error"] > 1e-10, r
    (naive,) = pick(rows, "3", "naive closed form")
    assert not naive["finite"] and math.isnan(naive["d2W_rel_error"])


@pytest.mark.parametrize("method", ["Taylor-Hood P2/P1", "P1/P1"])
def test_pressure_overshoot_below_the_time_step_bound_only(study, method):
    _, rows = study
    rs = pick(rows, "4", method)
    assert all(r["converged"] for r in rs)
    small = [r for r in rs if r["dt_over_bound"] < 0.2]
    large = [r for r in rs if r["dt_over_bound"] > 10]
    assert small and large
    assert min(r["overshoot"] for r in small) > 0.2  # measured ≥ 0.40 (TH), ≥ 0.89 (P1/P1)
    assert max(r["overshoot"] for r in large) < 1e-3  # p never above the load (measured < 0)


def test_p1p1_overshoots_more_than_taylor_hood(study):
    _, rows = study
    th = {r["value"]: r["overshoot"] for r in pick(rows, "4", "Taylor-Hood P2/P1")}
    p1 = {r["value"]: r["overshoot"] for r in pick(rows, "4", "P1/P1")}
    small = [dt for dt in th if dt < 1e-4 * 1.01]
    assert all(p1[dt] > 1.5 * th[dt] for dt in small)


def test_compaction_is_reported_by_name(study):
    _, rows = study
    (direct,) = pick(rows, "5", "materials.check_compaction")
    assert direct["detected"] and "phi0 = 0.4" in direct["message"]
    runs = {r["value"]: r for r in pick(rows, "5", "TimeStepper, column squeezed")}
    named = runs["subcutaneous, default SNES tolerances"]
    assert named["detected"], named["message"]
    assert "the step from t" in named["message"] and "solid volume fraction" in named["message"]
    assert 0.4 < named["J_min_last_accepted"] < 0.45
    assert runs["nu = 0.05 (soft in volume), default SNES tolerances"]["detected"]


def test_unstable_foam_is_detected_and_the_paper_sets_are_not(study):
    _, rows = study
    foams = {r["value"]: r for r in pick(rows, "5", "stability.drucker_check")}
    bad = foams["unstable test foam"]
    assert bad["detected"]
    compression, tension = bad["first_unstable_equibiaxial"]
    assert tension == pytest.approx(2 ** 0.25, abs=0.01)  # d = 0.2λ² − 0.1λ⁶ < 0 ⇔ λ⁴ > 2
    assert compression is not None and 0.2 < compression < 1
    assert not foams["skin"]["detected"] and not foams["subcutaneous"]["detected"]
    for mode in ("warn", "error"):
        (r,) = pick(rows, "5", f"stability.check_state ({mode})")
        assert r["detected"] and "violate the Drucker condition" in r["message"]


def test_the_nitsche_chart_draws_an_exact_constraint_at_its_floor(tmp_path, monkeypatch):
    """A penetration of 0 (the constraint met exactly) has no place on the log axis: it is
    drawn at the floor the axis names, not dropped; a failed run's (NaN) stays out."""
    from matplotlib.figure import Figure

    from fingertip_dolfinx.studies.stability import _figure_nitsche

    drawn = []
    monkeypatch.setattr(Figure, "savefig", lambda fig, *a, **k: drawn.append(fig))
    rows = [{"method": "nitsche_theta1", "value": g, "penetration_over_depth": p,
             "newton_iterations": 4, "converged": ok}
            for g, p, ok in ((1.0, 1e-2, True), (10.0, 0.0, True), (100.0, float("nan"), False))]
    _figure_nitsche(tmp_path, rows)
    ax = drawn[-1].axes[0]
    y = ax.get_lines()[0].get_ydata()
    assert y[0] == 1e-2 and y[1] == 1e-6 and y[2] != y[2]  # the NaN
    assert "floor 1e-6" in ax.get_ylabel()
