"""The canonical biphasic benchmarks, coarse (benchmarks/biphasic_*.py run them fine and time
them): confined compression and plane-strain unconfined compression (Mandel-type) of the
Holmes–Mow tissue by a platen ramp, then hold, for ν = 0.4 and ν = 0 (the hyperfoam limit,
"Ogden unconstrained"), against their exact limits (`studies.problems`):

- confined: undrained start (the core cannot deform: J = 1 and p = F/W), drained end (the
  confined hyperfoam stress in closed form);
- unconfined: at the end of a fast ramp the core's p equals the undrained closed form, at
  long times the force equals the drained closed form.

The limits are homogeneous states: P2/P1 holds them exactly, so the tolerances come from what
is not homogeneous, the drainage front and the slowest consolidation mode (see each test).
"""

import sys

import numpy as np
import pytest

from fingertip_dolfinx.physics import materials as mat
from fingertip_dolfinx.stepping import StepOptions
from fingertip_dolfinx.studies.problems import (
    ConfinedRelaxation,
    UnconfinedRelaxation,
    confined_drained_stress,
    run_relaxation,
    unconfined_drained_state,
    unconfined_undrained_state,
)

TIGHT = {"snes_rtol": 1e-12, "snes_atol": 1e-15}
NUS = [0.4, 0.0]


def _solid(nu):
    return mat.Hyperfoam(mu=mat.SUBCUTANEOUS.mu, alpha=mat.SUBCUTANEOUS.alpha, nu=nu)


def _run(problem, n=12, prefix="bench_"):
    h = problem.history
    options = StepOptions(dt_initial=h.ramp_time / 8, dt_min=1e-9 * h.ramp_time,
                          dt_max=h.end_time / 16)
    return run_relaxation(problem, problem.block(n, grading=10.0), options, TIGHT,
                          prefix=prefix)


# --- the closed forms ------------------------------------------------------------------------


@pytest.mark.parametrize("nu", NUS)
def test_unconfined_closed_forms_solve_their_conditions_and_match_small_strain(nu):
    """Drained: τ1 = 0 at the lateral stretch found; ν = 0: λx = 1 exactly. Undrained: J = 1,
    p = τ1, independent of ν. At 1e-5 strain both match plane-strain linear elasticity:
    P22 = −E' e with E' = 4μ(λ + μ)/(λ + 2μ) drained (σ_xx = 0, ε_zz = 0), and p = 2μ e,
    P22 = −4μ e undrained (incompressible: e_x = −e_y)."""
    solid = _solid(nu)
    for lam in (0.7, 0.9, 0.99):
        d = unconfined_drained_state(solid, lam)
        tau = solid.principal_kirchhoff(np.array([d.stretch_x, lam, 1.0]))
        assert abs(tau[0]) < 1e-15 and d.pressure == 0.0
        assert d.stretch_x == 1.0 if nu == 0 else 1.0 < d.stretch_x < 1.0 / lam
        u = unconfined_undrained_state(solid, lam)
        assert u.J == 1.0 and u.stretch_x == 1.0 / lam
        assert u == unconfined_undrained_state(_solid(0.4 - nu), lam)  # ν plays no part
        assert u.P22 < d.P22 < 0  # the undrained block is stiffer
    e = 1e-5
    mu, lm = solid.mu0, solid.lame_lambda0
    E_plane = 4 * mu * (lm + mu) / (lm + 2 * mu)
    assert unconfined_drained_state(solid, 1 - e).P22 == pytest.approx(-E_plane * e, rel=1e-4)
    u = unconfined_undrained_state(solid, 1 - e)
    assert u.pressure == pytest.approx(2 * mu * e, rel=1e-4)
    assert u.P22 == pytest.approx(-4 * mu * e, rel=1e-4)
    assert confined_drained_stress(solid, 1 - e)[1] == pytest.approx(-(lm + 2 * mu) * e,
                                                                     rel=1e-4)


# --- confined compression ----------------------------------------------------------------------


@pytest.mark.parametrize("nu", NUS)
def test_confined_relaxation_starts_undrained_and_ends_drained(nu):
    """Start: in the lower half the fluid has not moved. At the first step (Δt = t0/8) the
    drainage front is sqrt(c Δt) = 0.016 H deep, e^(−31) at H/2: what is left of |J − 1|
    there is the discrete front's tail through the coarse cells (P2/P1 keeps J = J_n only
    in the P1-weighted mean), measured 4e-9, 4e-10, 1e-10 on 12, 24, 48 cells (graded ×10)
    with the Newton tolerance fixed: < 1e-8. At the ramp's end backward Euler's front has
    exponential, not Gaussian, tails (≈ e^(−z/ℓ)(z/ℓ)^(N−1)/(N−1)! after N steps of length
    ℓ²/c): measured ≤ 3e-7, < 1e-6. The undeformed core carries the load by its pressure:
    p(bottom) = F/W. End: the drained confined hyperfoam stress within `end_tolerance`."""
    problem = ConfinedRelaxation(solid=_solid(nu))
    run = _run(problem, prefix=f"bench_confined_{nu:g}_".replace(".", "p"))
    assert run.core_J_change[0] < 1e-8, run.core_J_change[0]
    i = run.at(problem.history.ramp_time)
    assert run.core_J_change[i] < 1e-6, run.core_J_change[i]
    assert run.core_pressure[i] == pytest.approx(run.force[i] / problem.width, rel=1e-7)
    assert run.J_min.min() > 0.6  # the top is squeezed, far from compaction (J = 0.4)
    drained = problem.drained_force()
    excess = run.force[i] / drained - 1
    hold = np.diff(run.time)[i:]
    tolerance = problem.end_tolerance(excess, hold) + 1e-9
    assert abs(run.force[-1] / drained - 1) < tolerance, (run.force[-1] / drained - 1, tolerance)
    assert abs(run.core_pressure[-1]) < tolerance * drained / problem.width
    print(f"nu = {nu}: end error {run.force[-1] / drained - 1:.1e} (tolerance {tolerance:.1e}), "
          f"core |J - 1| {run.core_J_change[0]:.1e}, {run.core_J_change[i]:.1e}")


# --- unconfined compression ------------------------------------------------------------------


@pytest.mark.parametrize("nu", NUS)
def test_unconfined_relaxation_core_undrained_early_and_force_drained_late(nu):
    """At the end of the fast ramp the centre's pressure is the undrained closed form: the
    front sqrt(c t0) is 0.045 W from the edge, and the discrete (exponential) tails leave
    |J − 1| ≤ 2e-6 in the core (x < W/2) and p at the centre within 3e-7 (measured on 12
    cells; 1e-8 on 48). At the end the force is the drained closed form within
    `end_tolerance`."""
    problem = UnconfinedRelaxation(solid=_solid(nu))
    run = _run(problem, prefix=f"bench_unconfined_{nu:g}_".replace(".", "p"))
    i = run.at(problem.history.ramp_time)
    undrained = problem.undrained()
    assert run.core_J_change[i] < 1e-5, run.core_J_change[i]
    assert run.core_pressure[i] == pytest.approx(undrained.pressure, rel=1e-6)
    assert run.force[i] < -undrained.P22 * problem.length  # the edge has drained a little
    drained = problem.drained_force()
    excess = run.force[i] / drained - 1
    tolerance = problem.end_tolerance(excess, np.diff(run.time)[i:]) + 1e-9
    assert abs(run.force[-1] / drained - 1) < tolerance, (run.force[-1] / drained - 1, tolerance)
    assert abs(run.core_pressure[-1]) < 1e-6 * undrained.pressure
    print(f"nu = {nu}: core p error {run.core_pressure[i] / undrained.pressure - 1:.1e}, end "
          f"error {run.force[-1] / drained - 1:.1e} (tolerance {tolerance:.1e})")


# --- the scripts' choice of the adaptive stepper ------------------------------------------------


def test_benchmark_scripts_use_error_controlled_bdf2(repo_root, monkeypatch):
    """The scripts' adaptive runs: error-controlled BDF2 at rtol 1e-2 and 1e-3, atol scaled."""
    monkeypatch.syspath_prepend(str(repo_root / "benchmarks"))
    sys.modules.pop("biphasic_common", None)
    import biphasic_common as common

    problem = UnconfinedRelaxation(solid=_solid(0.0))
    for level, tol in ((0, 1e-2), (1, 1e-3)):
        options, label = common.adaptive_options(level, problem)
        assert (options.control, options.rtol, options.scheme) == ("error", tol, "bdf2")
        assert options.atol == tol * common.ATOL_SCALE and str(tol) in label
        assert options.atol == tol * common.ATOL_SCALE and "rtol" in label


def test_asked_mode_reads_the_outputs_where_every_run_lands(repo_root, monkeypatch):
    """--asked: outputs at the ramp's middle and end, right after it (t0 1.01) and through the
    hold to its end, increasing: every run lands on them, so no output is interpolated. The
    issue's column: 20 % in 100 s, held to 3000 s."""
    monkeypatch.syspath_prepend(str(repo_root / "benchmarks"))
    sys.modules.pop("biphasic_common", None)
    sys.modules.pop("biphasic_confined", None)
    import biphasic_common as common
    import biphasic_confined as confined

    problem = confined.issue_column(_solid(0.4))
    h = problem.history
    assert (h.depth, h.ramp_time, h.end_time) == pytest.approx((0.2, 100.0, 3000.0))
    assert problem.k0 == 10.0
    t = common.output_times(problem)
    assert t[:3] == pytest.approx([50.0, 100.0, 101.0]) and t[-1] == 3000.0
    assert np.all(np.diff(t) > 0) and len(t) == 2 + common.OUTPUTS_IN_HOLD
