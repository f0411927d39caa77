"""Time integration and step-size control: the observed orders of backward Euler (1)
and BDF2 (2) on Terzaghi's consolidation and of the QLV recursion (2) on a smooth history,
Milne's error constants, and error control on the confined ramp-and-hold of the Holmes–Mow
tissue against a converged reference.

The orders are measured against exact answers (Terzaghi's series; the hereditary integral of a
sinusoidal strain in closed form) with fixed steps; the error control against a reference run
of the same mesh with a 1000× tighter tolerance (its own time error is 4e-5 of the peak force,
checked against one at 1e-7).
"""

import math

import numpy as np
import pytest
from dolfinx import fem, mesh
from mpi4py import MPI

from fingertip_dolfinx.loading import RampHold
from fingertip_dolfinx.physics import materials as mat
from fingertip_dolfinx.physics.kinematics import deformation_gradient
from fingertip_dolfinx.physics.viscoelasticity import QuasiLinearViscoelasticity
from fingertip_dolfinx.stepping import (
    StepOptions,
    TimeStepper,
    bdf2_weights,
    lagrange,
    milne_factor,
)
from fingertip_dolfinx.studies.problems import ConfinedBlock, Terzaghi, prony_ramp_integral

TIGHT = {"snes_rtol": 1e-12, "snes_atol": 1e-14}


# ---- the formulas -----------------------------------------------------------------------------


def test_bdf2_weights_are_exact_for_quadratics():
    """a₀ x_{n+1} + a₁ x_n + a₂ x_{n−1} = Δt ẋ_{n+1} for x = 1, t, t² at any step ratio."""
    for omega in (0.3, 1.0, 2.0):
        h = 0.7
        t = np.array([-h / omega, 0.0, h])  # t_{n−1}, t_n, t_{n+1}
        a0, a1, a2 = bdf2_weights(omega)
        for x, dx in ((lambda s: s**0, 0.0), (lambda s: s, 1.0), (lambda s: s**2, 2 * h)):
            assert a2 * x(t[0]) + a1 * x(t[1]) + a0 * x(t[2]) == pytest.approx(h * dx, abs=1e-14)
    assert bdf2_weights(1.0) == pytest.approx((1.5, -2.0, 0.5))


@pytest.mark.parametrize("order", [1, 2])
def test_milne_estimate_is_the_local_error(order):
    """One backward-Euler (order 1) or BDF2 (order 2) step of ẋ = f(t) from exact history at
    uneven step ratios: Milne's K/(K − K_p)·(corrector − predictor) is its local error, to a
    relative O(Δt)."""
    def x(t):
        return np.sin(3 * t) + t**3
    def dx(t):
        return 3 * np.cos(3 * t) + 3 * t**2
    for h, close in ((1e-2, 0.05), (1e-3, 0.01)):
        dts = [h, 1.6 * h, 0.7 * h]
        times = 0.3 - np.cumsum([0.0, dts[1], dts[2]])[::-1]  # t_{n−2}, t_{n−1}, t_n
        t_new = times[-1] + h
        if order == 1:
            corrector = x(times[-1]) + h * dx(t_new)
        else:
            a0, a1, a2 = bdf2_weights(h / dts[1])
            corrector = (h * dx(t_new) - a1 * x(times[-1]) - a2 * x(times[-2])) / a0
        points = [(s, [np.array(x(s))]) for s in times[-(order + 1):]]
        predictor = lagrange(points, t_new)[0]
        estimate = milne_factor(order, dts[: order + 1]) * (corrector - predictor)
        assert estimate / (corrector - x(t_new)) == pytest.approx(1.0, abs=close)
    assert milne_factor(1, [1.0, 1.0]) == pytest.approx(1 / 3)
    assert milne_factor(2, [1.0, 1.0, 1.0]) == pytest.approx(2 / 11)


def test_step_options_name_the_bad_value():
    with pytest.raises(ValueError, match="control"):
        StepOptions(control="cfl")
    with pytest.raises(ValueError, match="scheme"):
        StepOptions(scheme="crank-nicolson")
    with pytest.raises(ValueError, match="1 \\+ √2"):
        StepOptions(scheme="bdf2", growth=2.5)
    with pytest.raises(ValueError, match="rtol"):
        StepOptions(rtol=0.0, atol=0.0)


# ---- observed orders against exact answers ---------------------------------------------------


def _terzaghi_settlement_errors(scheme: str, dt: float, times=(0.2, 0.3, 0.4), ny: int = 64):
    """|settlement − Terzaghi's series| / (σ0 H/M) at `times`, fixed steps Δt (the first one
    backward Euler under either scheme). 64 P2/P1 cells: the space error is below BDF2's time
    error at the smallest step used (the slope stays 2 down to Δt = 0.00625)."""
    problem = Terzaghi()
    column = problem.column(ny)
    stepper = TimeStepper(column, StepOptions(dt_initial=dt, dt_max=dt, growth=1.0,
                                              extrapolate=False, scheme=scheme), TIGHT,
                          prefix=f"terzaghi_{scheme}_{round(1 / dt)}_")
    errors = {}

    def compare(report):
        for t in times:
            if abs(report.time - t) < 1e-9:
                _, exact = problem.series(np.zeros(1), t)
                errors[t] = abs(column.settlement() - exact) / (problem.sigma0 / problem.M)

    reports = stepper.run(lambda t: problem.sigma0, max(times), on_step=compare)
    return np.array([errors[t] for t in times]), len(reports)


@pytest.mark.parametrize(("scheme", "order"), [("backward-euler", 1), ("bdf2", 2)])
def test_terzaghi_observed_order(scheme, order):
    """Step load on a drained layer (c t/H² = t): the settlement error at t = 0.2, 0.3, 0.4
    falls as Δt^1 under backward Euler and Δt^2 under BDF2 (Δt = 0.025, 0.0125, 0.00625)."""
    errors = [_terzaghi_settlement_errors(scheme, dt)[0] for dt in (0.025, 0.0125, 0.00625)]
    slopes = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    print(f"{scheme}: settlement errors {np.array(errors).max(axis=1)}, slopes {slopes.ravel()}")
    assert np.all(np.abs(slopes - order) < 0.3), slopes


def test_terzaghi_bdf2_needs_fewer_steps_at_equal_accuracy():
    """BDF2 with 16 steps to t = 0.4 beats backward Euler with 64 (settlement errors ≈ 7.6e-4
    against 2.2e-3 of the final settlement): at 1e-3, backward Euler needs Δt ≈ 0.0028 (≈ 140
    steps, its error is 0.36 Δt), BDF2 Δt ≈ 0.029 (14 steps, 1.2 Δt²)."""
    bdf2, n_bdf2 = _terzaghi_settlement_errors("bdf2", 0.025)
    euler, n_euler = _terzaghi_settlement_errors("backward-euler", 0.00625)
    assert (n_bdf2, n_euler) == (16, 64)
    assert bdf2.max() < 1e-3 < euler.max() < 3e-3, (bdf2, euler)


#: The paper's skin Prony series (τ = 2.1, 9.4 s) and a fast one (τ = 4 ms).
SMOOTH_OMEGA, SMOOTH_T = math.pi, 2.0  # rad/s and s: one period of the strain


def _qlv_sinusoid_error(prony: mat.Prony, n: int) -> float:
    """The QLV recursion on one homogeneous St Venant–Kirchhoff cell whose Green strain is
    sin(ωt) E₁ (E₁ with a stretch and a shear), in n equal steps over one period; max error of
    the total PK2 stress against the hereditary integral in closed form, relative to |S_e(E₁)|:
    S = g∞ S_e + Σ g_i h_i, h_i = S₁ ω ∫_0^t exp(−(t − s)/τ_i) cos(ωs) ds
      = S₁ ω (A_i cos ωt + B_i sin ωt − A_i exp(−t/τ_i)), A_i = τ_i/(1 + ω²τ_i²), B_i = ωτ_i A_i.
    """
    omega, T = SMOOTH_OMEGA, SMOOTH_T
    msh = mesh.create_unit_square(MPI.COMM_SELF, 1, 1)
    V = fem.functionspace(msh, ("Lagrange", 1, (2,)))
    u = fem.Function(V)
    dt = fem.Constant(msh, T / n)
    S_e = mat.second_piola_kirchhoff(mat.LinearElastic(E=0.01, nu=0.4), deformation_gradient(u))
    qlv = QuasiLinearViscoelasticity(S_e, prony, msh, 2, dt)
    points = qlv.space.element.interpolation_points
    total, elastic = fem.Expression(qlv.stress(), points), fem.Expression(S_e, points)
    cells = np.arange(msh.topology.index_map(2).size_local, dtype=np.int32)

    def strain(s):  # F = [[f, 0], [g, 1]]: E11 = 0.15 s, E12 = 0.1 s, E22 = 0
        g = 0.2 * s
        f = math.sqrt(1 + 0.3 * s - g**2)
        u.interpolate(lambda x: np.vstack([(f - 1) * x[0], g * x[0]]))

    strain(1.0)
    S1 = elastic.eval(msh, cells)
    worst = 0.0
    for k in range(1, n + 1):
        t = k * T / n
        strain(math.sin(omega * t))
        exact = prony.g_inf * math.sin(omega * t) * S1
        for g, tau in zip(prony.g, prony.tau):
            A = tau / (1 + (omega * tau) ** 2)
            exact = exact + g * omega * A * (math.cos(omega * t) + omega * tau * math.sin(omega * t)
                                             - math.exp(-t / tau)) * S1
        worst = max(worst, float(np.abs(total.eval(msh, cells) - exact).max()))
        qlv.advance()
    return worst / float(np.abs(S1).max())


def test_qlv_recursion_is_second_order_on_a_smooth_history():
    """h_i^{n+1} = a_i h_i^n + b_i (S_e^{n+1} − S_e^n) is exact for S_e linear over a step, so
    on a smooth S_e its error is that of the piecewise-linear interpolant under the integral:
    second order (measured 2.00 with the skin's τ = 2.1, 9.4 s). For τ ≪ Δt it is τΔt/2·|S̈_e|
    instead (first order, times the small τ: 1.05 at τ = 4 ms, Δt = 0.2 s, turning to 2 as Δt
    nears τ)."""
    skin = [_qlv_sinusoid_error(mat.SKIN_PRONY, n) for n in (10, 20, 40, 80)]
    slopes = np.log2(np.array(skin[:-1]) / np.array(skin[1:]))
    print(f"skin Prony: errors {skin}, slopes {slopes}")
    assert np.all(np.abs(slopes - 2) < 0.3), slopes
    fast = mat.Prony(g=(0.3,), tau=(0.004,))
    error = _qlv_sinusoid_error(fast, 10)
    bound = 0.3 * 0.004 * (SMOOTH_T / 10) / 2 * SMOOTH_OMEGA**2  # g τ Δt/2 max|S̈_e|/|S₁|
    assert error == pytest.approx(bound, rel=0.1)


# ---- error control -----------------------------------------------------------------------------

#: The issue's test: Holmes–Mow tissue in a 1 mm confined column (20 uniform P2/P1 cells),
#: its drained top pushed down by 0.01 mm over 100 s and held to 3000 s.
RAMP = RampHold(0.01, 100.0, 3000.0)


def _confined(options: StepOptions, prefix: str, petsc=None):
    column = ConfinedBlock(1, 20, RAMP, tissue=mat.SUBCUTANEOUS_BIPHASIC, width=0.1,
                           drained_top=True, top_displacement=True)
    reports = TimeStepper(column, options, petsc, prefix=prefix).run(RAMP, RAMP.end_time)
    t = np.array([0.0] + [r.time for r in reports])
    force = np.array([0.0] + [r.diagnostics["reaction"] for r in reports])
    return t, force, reports


@pytest.fixture(scope="module")
def reference():
    """BDF2 at rtol = 1e-6 with tight Newton tolerances (650 steps): 4e-5 of the peak force
    from a run at 1e-7."""
    options = StepOptions(control="error", scheme="bdf2", rtol=1e-6, atol=1e-12,
                          dt_initial=0.01, dt_min=1e-8, dt_max=RAMP.end_time)
    t, force, _ = _confined(options, "reference_",
                            {"snes_rtol": 1e-11, "snes_atol": 1e-15, "snes_max_it": 30})
    return t, force


def _errors(run, reference):
    """(max |F − F_ref| / max |F_ref| over the run, max |F/F_ref − 1| over the hold)."""
    t, force, _ = run
    t_ref, f_ref = reference
    exact = np.interp(t, t_ref, f_ref)
    hold = t >= RAMP.ramp_time
    return (np.max(np.abs(force - exact)) / np.max(np.abs(f_ref)),
            np.max(np.abs(force[hold] / exact[hold] - 1)))


def test_error_control_on_the_confined_ramp_and_hold(reference):
    """Today's growth (×1.5 after easy steps, to 10 s) is 14 % off in force at the first step
    of the hold; BDF2 with rtol = 1e-3 (and dt_max the whole run) is within 4.7 × rtol of the
    peak force in 80 steps, against 600 fixed BDF2 steps of 5 s that are 10 × worse (3000
    fixed steps of 1 s reach its accuracy: benchmarks/time_control.py). Backward Euler at the
    same rtol needs 160 steps and is 13 × rtol off: the local error is controlled, the global
    one accumulates over the ramp."""
    today = _confined(StepOptions(), "today_")
    t, force, _ = today
    after = np.searchsorted(t, RAMP.ramp_time) + 1  # the first step of the hold
    first_hold_error = force[after] / np.interp(t[after], *reference) - 1
    assert t[after] == pytest.approx(110.0)
    assert 0.12 < first_hold_error < 0.16, first_hold_error

    control = {"control": "error", "rtol": 1e-3, "atol": 1e-12, "dt_max": RAMP.end_time}
    bdf2 = _confined(StepOptions(scheme="bdf2", **control), "bdf2_")
    euler = _confined(StepOptions(**control), "euler_")
    fixed = _confined(StepOptions(scheme="bdf2", dt_initial=5.0, dt_max=5.0, growth=1.0),
                      "fixed_")
    runs = {"today": today, "bdf2": bdf2, "euler": euler, "fixed": fixed}
    errors = {name: _errors(run, reference) for name, run in runs.items()}
    steps = {name: len(run[2]) for name, run in runs.items()}
    for name in runs:
        print(f"{name}: {steps[name]} steps, error {errors[name][0]:.2e} of the peak force, "
              f"{errors[name][1]:.2e} relative in the hold")
    assert 100.0 in bdf2[0] and 100.0 in euler[0]  # the kink is a step
    assert errors["bdf2"][0] < 6e-3 and errors["bdf2"][1] < 1e-2  # measured 4.7e-3, 6.8e-3
    assert errors["euler"][0] < 2e-2
    assert steps["bdf2"] < 100 < steps["euler"] < 200 < steps["today"] < steps["fixed"]
    assert errors["fixed"][0] > 5 * errors["bdf2"][0]


def test_error_control_keeps_the_qlv_history_through_redone_steps():
    """A viscoelastic strip relaxing under a held displacement (test_solver's): the QLV
    recursion is exact here, so error control may take any steps, but every first step after
    a kink is doubled and rejected ones are redone from a restored history: the reaction must
    still follow the hereditary integral."""
    prony, T = mat.SKIN_PRONY, 1.0
    history = RampHold(1e-5, T, 60.0)
    strip = ConfinedBlock(1, 2, history, solid=mat.SKIN, prony=prony, width=0.1,
                          top_displacement=True)
    options = StepOptions(control="error", scheme="bdf2", rtol=1e-4, atol=1e-14,
                          dt_initial=0.5, dt_max=60.0)
    reports = TimeStepper(strip, options, TIGHT, prefix="qlv_error_").run(history, 60.0)
    elastic = next(r for r in reports if r.time == T).diagnostics["reaction"]
    elastic /= prony_ramp_integral(prony, T, T) / T
    for r in reports:
        expected = elastic * prony_ramp_integral(prony, r.time, T) / T
        assert r.diagnostics["reaction"] == pytest.approx(expected, rel=1e-6), r.time
    assert len(reports) < 40


def test_a_rejected_doubled_step_restores_the_whole_state():
    """Biphasic tissue with a QLV solid, two steps in: a doubled first step after a kink that
    is rejected (a tolerance no step can meet) leaves u, u_n, u_{n−1}, p and the QLV history
    exactly as they were."""
    history = RampHold(0.01, 1.0, 2.0)
    column = ConfinedBlock(1, 4, history, tissue=mat.SUBCUTANEOUS_BIPHASIC, prony=mat.SKIN_PRONY,
                           width=0.1, drained_top=True, top_displacement=True)
    stepper = TimeStepper(column, StepOptions(dt_initial=0.5, dt_max=0.5), prefix="rollback_")
    stepper.run(history, 1.0)
    stepper.options = StepOptions(control="error", rtol=1e-12, atol=0.0)
    stepper._peaks = [1e-30] * len(column.unknowns)
    saved = {name: a.copy() for name, a in column.state_arrays().items()}
    start = [f.x.array.copy() for f in column.unknowns]
    column.dt.value = 0.5
    column.set_time(1.5)
    assert stepper.solve_once()[0] > 0
    err, middle, _ = stepper._double(1.0, 1.5, saved, start)
    assert err > 1 and middle is None
    for name, a in column.state_arrays().items():
        assert np.array_equal(a, saved[name]), name
    assert any(np.any(a != 0) for n, a in saved.items() if n.startswith("qlv"))


class _Stop(Exception):
    pass


def test_a_resumed_error_controlled_run_continues_within_the_tolerance():
    """Stopped after 30 steps and resumed from the state and the one before it (what a
    checkpoint holds): the resumed run takes one backward-Euler step (its u_{n−1} may be a
    half step of a doubled step) and goes on with BDF2; its force at the end agrees with the
    uninterrupted run's to the tolerance."""
    history = RampHold(0.01, 100.0, 300.0)
    options = StepOptions(control="error", scheme="bdf2", rtol=1e-3, atol=1e-12, dt_max=300.0)

    def column():
        return ConfinedBlock(1, 20, history, tissue=mat.SUBCUTANEOUS_BIPHASIC, width=0.1,
                             drained_top=True, top_displacement=True)

    whole = column()
    reports = TimeStepper(whole, options, prefix="whole_").run(history, history.end_time)
    stopped = column()
    states = []

    def stop(report):
        states.append((report.time, [f.x.array.copy() for f in stopped.unknowns]))
        if len(states) == 30:
            raise _Stop

    with pytest.raises(_Stop):
        TimeStepper(stopped, options, prefix="stopped_").run(history, history.end_time,
                                                            on_step=stop)
    resumed = TimeStepper(stopped, options, prefix="resumed_").run(
        history, history.end_time, start_time=states[-1][0], previous=states[-2])
    assert resumed[0].error <= 1 and resumed[-1].time == history.end_time
    peak = max(abs(r.diagnostics["reaction"]) for r in reports)
    end = reports[-1].diagnostics["reaction"]
    assert abs(resumed[-1].diagnostics["reaction"] - end) < 2e-3 * peak


# ---- a tolerance asked of the outputs -----------------------------------------------------------

#: The column above, coarser (6 cells) and held to 1000 s; outputs at the ramp's middle and end,
#: right after it and through the hold, every step landing on them.
OUTPUT_TIMES = (50.0, 100.0, 101.0, 110.0, 300.0, 1000.0)


def _column_outputs(options: StepOptions, petsc=None, prefix="outputs_") -> dict[str, float]:
    """The force and the bottom pore pressure at OUTPUT_TIMES."""
    ramp = RampHold(RAMP.depth, RAMP.ramp_time, OUTPUT_TIMES[-1])
    column = ConfinedBlock(1, 6, ramp, tissue=mat.SUBCUTANEOUS_BIPHASIC, width=0.1,
                           drained_top=True, top_displacement=True)
    stepper = TimeStepper(column, options, petsc or {"snes_atol": 1e-14}, prefix=prefix)
    reports = stepper.run(ramp, ramp.end_time, breakpoints=OUTPUT_TIMES[:-1])
    stepper.close()
    at = {r.time: r.diagnostics for r in reports}
    out = {}
    for t in OUTPUT_TIMES:
        d = next(v for s, v in at.items() if abs(s - t) < 1e-9 * t)
        out[f"force@{t:g}"], out[f"pressure@{t:g}"] = -d["reaction"], d["core_pressure"]
    return out


def _relative_to_peaks(values: dict[str, float]) -> dict[str, float]:
    """Each output's scale: the peak of its history (force or pressure) over OUTPUT_TIMES."""
    peak = {q: max(abs(v) for k, v in values.items() if k.startswith(q))
            for q in ("force", "pressure")}
    return {k: peak[k.split("@")[0]] for k in values}


def _delivered(values: dict, exact: dict) -> float:
    scales = _relative_to_peaks(exact)
    return max(abs(values[k] - exact[k]) / scales[k] for k in exact)


@pytest.mark.parametrize("exponent", [0.5, 2 / 3, 1.0])
def test_time_estimate_bounds_errors_that_fall_with_the_tolerance(exponent):
    """f(tol) = f* + C tol^a for the exponents a of BE-restarted BDF2 (1/2), of BDF2 with
    error-per-step control (2/3) and of tolerance proportionality (1): the estimate of the
    tighter of two runs 4x apart, with the assumed a = 1/2, bounds its true error (by the
    safety factor 1.25 at a = 1/2 exactly)."""
    from fingertip_dolfinx.stepping import time_estimates

    def f(tol):
        return {"x": 1.0 + 0.3 * tol**exponent, "y": 2.0 - 0.5 * tol**exponent}

    for tol in (1e-2, 1e-4):
        estimate = time_estimates(f(tol), f(tol / 4), 4.0)
        for key, exact in (("x", 1.0), ("y", 2.0)):
            true = abs(f(tol / 4)[key] - exact) / abs(f(tol / 4)[key])
            assert true <= estimate[key] <= (1.3 if exponent == 0.5 else 4.0) * true


def test_time_check_tightens_until_within_budget_and_survives_a_failed_run():
    """An output whose error is 0.3 tol^(1/2): from rtol 1e-3 the estimate after the first
    check (5.9e-3) is above a 1e-3 budget, so a third run tightens by (E/(budget/2))^2, at
    most 16, and a fourth once more; when the third run fails (a tolerance Newton cannot resolve),
    the check ends unconverged with the last
    finished run as the answer and the failure recorded, instead of losing everything."""
    from fingertip_dolfinx.errors import ConvergenceError
    from fingertip_dolfinx.stepping import verify_time

    def run(options, i):
        return {"f": 1.0 + 0.3 * math.sqrt(options.rtol)}

    start = StepOptions(control="error", scheme="bdf2", rtol=1e-3, atol=1e-6)
    check = verify_time(run, start, 1e-3)
    rtols = [r["rtol"] for r in check["runs"]]
    assert check["converged"] and len(rtols) == 4 and rtols[1] == pytest.approx(2.5e-4)
    assert rtols[2] == pytest.approx(rtols[1] / 16) and rtols[3] < rtols[2] / 2
    true = 0.3 * math.sqrt(rtols[3])
    assert true <= check["estimates"]["f"] <= 1e-3

    def failing(options, i):
        if i == 2:
            raise ConvergenceError("below Newton's accuracy")
        return run(options, i)

    check = verify_time(failing, start, 1e-3)
    assert not check["converged"] and "Newton" in check["runs"][-1]["failed"]
    assert check["options"].rtol == pytest.approx(2.5e-4)  # the last run that finished
    assert check["values"] == run(check["options"], 1) and check["estimates"]["f"] > 1e-3


def test_a_tolerance_asked_of_the_outputs_is_delivered():
    """The tolerance-driven control (the time share of tol; its steps checked against a run 4
    times tighter, rtol and atol alike) delivers the outputs within the time share, and its
    estimate, reported per output, bounds what it delivered. "Exact": the same mesh at rtol
    1e-5, Newton to 1e-15 N/mm (7e-5 of the peaks from one at 1e-6, against 2.5e-3 asked).
    Local error control alone does not do this: on the issue's column (benchmarks/
    biphasic_confined.py --issue) rtol 1e-4 ends 6.5e-3 off in the pore pressure."""
    from fingertip_dolfinx.stepping import TIME_SHARE, tolerance_steps, verify_time

    exact = _column_outputs(StepOptions(control="error", scheme="bdf2", rtol=1e-5, atol=1e-11,
                                        dt_initial=1e-2, dt_min=1e-9, dt_max=1000.0),
                            {"snes_rtol": 1e-12, "snes_atol": 1e-15, "snes_max_it": 30},
                            "exact_")
    tol = 1e-2
    budget = TIME_SHARE * tol
    check = verify_time(lambda options, i: _column_outputs(options, None, f"asked{i}_"),
                        tolerance_steps(budget, StepOptions(dt_max=1000.0)), budget,
                        scales=_relative_to_peaks)
    delivered, estimated = _delivered(check["values"], exact), max(check["estimates"].values())
    print(f"asked {tol:g} (time share {budget:g}): delivered {delivered:.2e}, estimated "
          f"{estimated:.2e}, runs {check['runs']}")
    assert check["converged"] and set(check["estimates"]) == set(exact)
    assert delivered <= budget <= tol  # measured 2.5e-4 (3.2e-4 against rtol 1e-6)
    assert estimated >= delivered  # measured 4.9e-4: the reported estimate bounds it
    assert check["runs"][-1]["rtol"] < check["runs"][0]["rtol"]  # the answer is the tighter


def test_a_step_that_ends_exactly_on_a_kink_stops_there():
    """From t = 90 s a 10 s step ends on the ramp's end (100 s) exactly; with an output at
    101 s it was stretched there (the sliver rule), stepping over the kink: the ramp's end
    was never a step and its force never computed."""
    from fingertip_dolfinx.loading import step_times

    marks = [100.0, 101.0, 3000.0]
    assert step_times(marks, 90.0, 10.0, 3000.0) == 100.0
    assert step_times(marks, 90.0, 10.0 + 1e-13, 3000.0) == 100.0
    assert step_times(marks, 90.0, 9.9, 3000.0) == 100.0  # a sliver short: stretched to it
    assert step_times(marks, 90.0, 5.0, 3000.0) == 95.0


def test_hold_growth_grows_only_the_held_steps():
    """`hold_growth` = 3 changes no step of the ramp (the load moves) and grows every easy step
    of the hold ×3 (×1.5 without it), up to dt_max and the end. (What longer steps cost in
    accuracy is the scene's to measure: here, still relaxing at 3000 s, the last force moves by
    2.5 %.)"""
    common = {"dt_initial": 5.0, "dt_max": 1000.0}
    plain = _confined(StepOptions(**common), "hold_plain_")
    fast = _confined(StepOptions(hold_growth=3.0, **common), "hold_fast_")
    ramp = [r.time for r in plain[2] if r.time <= RAMP.ramp_time + 1e-9]
    assert [r.time for r in fast[2]][:len(ramp)] == ramp and ramp[-1] == RAMP.ramp_time
    hold = [r for r in fast[2] if r.time > RAMP.ramp_time]
    grown = 0
    for before, after in zip(hold, hold[1:]):
        if after.time < RAMP.end_time and before.newton_iterations <= 6:
            assert after.dt == pytest.approx(min(3.0 * before.dt, common["dt_max"]))
            grown += 1
    assert grown >= 2 and len(fast[2]) < len(plain[2])  # measured: 12 steps against 14


def test_a_hold_is_a_constant_load_along_every_axis():
    """A step is held when the indentation and, on a tangential path, the displacement along
    the skin are the same at its start, middle and end: a shear under a held indentation is no
    hold, nor is a step over a sinusoid's whole period."""
    from fingertip_dolfinx.loading import PiecewiseLinear, Sinusoid, TangentialPath
    from fingertip_dolfinx.stepping.stepper import _held

    press = RampHold(0.5, 0.5, 2.0)
    assert not _held(press, 0.2, 0.5) and _held(press, 0.5, 2.0)
    shear = TangentialPath(press, PiecewiseLinear((0.0, 1.0, 2.0), (0.0, 0.0, 1.0)))
    assert _held(shear, 0.5, 1.0) and not _held(shear, 1.0, 1.5)
    wave = Sinusoid(amplitude=0.1, frequency=1.0, end_time=10.0, offset=0.5)
    assert wave(1.25) == wave(2.25) and not _held(wave, 1.25, 2.25)
