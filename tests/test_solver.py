"""The time stepper on problems with exact answers: Terzaghi consolidation, confined-compression
creep of the Holmes–Mow tissue, and the relaxation of a viscoelastic skin strip.

Each problem is a `studies.problems.ConfinedBlock` (shared with the stability study): a column
[0, w] × [0, H] on rollers at the sides and the bottom, loaded on top, built from the same
residual functions (poroelasticity, viscoelasticity) and the same `TimeStepper` as the fingertip.
"""

import numpy as np
import pytest
from mpi4py import MPI

from fingertip_dolfinx.loading import RampHold
from fingertip_dolfinx.physics import materials as mat
from fingertip_dolfinx.stepping import StepOptions, TimeStepper
from fingertip_dolfinx.studies.problems import (
    ConfinedBlock,
    Terzaghi,
    confined_drained_stress,
    confined_modulus,
    prony_ramp_integral,
)

TIGHT = {"snes_rtol": 1e-12, "snes_atol": 1e-14}


def _terzaghi_errors(ny, dt, steps):
    # Constant permeability with c = k M = 1 mm²/s: T = t on a 1 mm layer; load 1e-5 M, the
    # small-strain limit of the finite-strain code.
    problem = Terzaghi()
    sigma0, M = problem.sigma0, problem.M
    column = problem.column(ny, comm=MPI.COMM_WORLD)
    stepper = TimeStepper(
        column, StepOptions(dt_initial=dt, dt_max=dt, growth=1.0, extrapolate=False), TIGHT,
        prefix=f"terzaghi{ny}_",
    )
    y = np.linspace(0, 1.0, 21)
    errors = []

    def compare(report):
        p_exact, s_exact = problem.series(y, report.time)
        p_err = np.max(np.abs(column.pressure_at(y) - p_exact)) / sigma0
        s_err = abs(column.settlement() - s_exact) / (sigma0 / M)
        errors.append((report.time, p_err, s_err))

    stepper.run(lambda t: sigma0, dt * steps, on_step=compare)
    return np.array(errors)


@pytest.mark.mpi
def test_terzaghi_consolidation_matches_the_series_solution():
    """Step load on a drained layer: p and settlement follow Terzaghi's series within 1 % after
    the first steps (backward Euler smears the initial jump), and the error halves with the
    step: the first-order rate of backward Euler (the P2/P1 space error is far smaller)."""
    coarse = _terzaghi_errors(ny=32, dt=0.005, steps=80)
    fine = _terzaghi_errors(ny=32, dt=0.0025, steps=160)
    late = fine[fine[:, 0] >= 0.04 - 1e-12]  # after 16 steps
    assert late[:, 1].max() < 0.01, late[:, 1].max()  # pressure, relative to the load
    assert late[:, 2].max() < 0.01, late[:, 2].max()  # settlement, relative to the final one
    at = {round(row[0], 9): row for row in fine}
    common = np.array([(row, at[round(row[0], 9)]) for row in coarse
                       if row[0] >= 0.1 - 1e-9 and round(row[0], 9) in at])
    order = np.log2(common[:, 0] / common[:, 1])  # observed order in Δt at common times
    assert np.all((order[:, 2] > 0.8) & (order[:, 2] < 1.3)), order[:, 2]  # settlement
    # The pressure's max-norm error also carries the space error near the drained top, which
    # takes over as the time error decays: first order holds in the median.
    assert 0.8 < np.median(order[:, 1]) < 1.3, order[:, 1]


def test_confined_creep_starts_undrained_and_ends_drained():
    """Holmes–Mow tissue under a suddenly applied confined load: at first the fluid carries it
    (J = 1, p = load), at the end the solid alone (p = 0, stretch of the drained hyperfoam)."""
    tissue = mat.SUBCUTANEOUS_BIPHASIC
    solid = tissue.solid
    lam_eq = 0.8  # drained stretch; its nominal stress P22 carries the load at the end
    load = -confined_drained_stress(solid, lam_eq)[1]
    t_drain = 1.0 / (tissue.permeability.k0 * confined_modulus(solid))
    ramp = 1e-4 * t_drain
    history = RampHold(load, ramp, 20 * t_drain)
    column = ConfinedBlock(1, 8, history, tissue=tissue, width=0.1, drained_top=True)
    stepper = TimeStepper(
        column, StepOptions(dt_initial=ramp / 4, dt_max=0.5 * t_drain, growth=2.0), TIGHT,
        prefix="creep_",
    )
    reports = stepper.run(history, history.end_time)
    # End: drained. The top moved by (1 − λ_eq) H.
    assert column.settlement() == pytest.approx(1 - lam_eq, rel=1e-6)
    assert np.max(np.abs(column.p.x.array)) < 1e-6 * load
    # Start: at the end of the fast ramp the physical drainage layer is sqrt(c t) = 1 % of H,
    # thinner than one element; the discrete one spreads over the top elements with the
    # checkerboard of small-Δt poroelasticity. The lower half stays undrained: J = 1.
    first = next(r for r in reports if r.time >= ramp)
    assert first.diagnostics["max_J_change_lower_half"] < 1e-3


def test_viscoelastic_skin_strip_relaxes_as_the_prony_series():
    """A skin strip compressed by a traction ramp, then held: the QLV stress relaxes exactly as
    the hereditary integral ∫ G(t − s) dS_e(s). Under the traction control used here the strain
    creeps instead; with the top displacement held we compare the reaction instead."""
    prony = mat.SKIN_PRONY
    strain = 1e-5  # small: S_e linear in the (linear) displacement ramp
    T = 1.0
    history = RampHold(strain, T, 60.0)
    # displacement-controlled top: the reaction is the residual tested with e_y there
    strip = ConfinedBlock(1, 2, history, solid=mat.SKIN, prony=prony, width=0.1,
                          top_displacement=True)
    stepper = TimeStepper(strip, StepOptions(dt_initial=0.25, dt_max=5.0), TIGHT, prefix="qlv_")
    reports = stepper.run(history, 60.0, breakpoints=[2, 5, 10, 20])

    def ramp_response(t):  # S(t) / S_e(T) for S_e ramped linearly over [0, T]
        return prony_ramp_integral(prony, t, T) / T

    elastic = next(r for r in reports if r.time == T).diagnostics["reaction"] / ramp_response(T)
    for r in reports:
        expected = elastic * ramp_response(r.time)
        assert r.diagnostics["reaction"] == pytest.approx(expected, rel=1e-4), r.time
    by_time = {round(r.time, 9): r.diagnostics["reaction"] for r in reports}
    # MODEL.md §4's scale: F/F(1 s) = 0.93, 0.81, 0.72, 0.66 at 2, 5, 10, 20 s.
    for t, ratio in ((2, 0.93), (5, 0.81), (10, 0.72), (20, 0.66)):
        assert by_time[t] / by_time[1.0] == pytest.approx(ratio, abs=0.006)


@pytest.mark.mpi
def test_jacobian_reuse_reaches_the_same_states_with_fewer_factorisations():
    """StepOptions.jacobian_reuse keeps the Jacobian (and its LU factorisation) for the next
    Newton iteration after one that cut the residual norm by 50x or more. That changes the path
    to Newton's tolerance, not the solution: on the same (fixed) steps of a Holmes–Mow creep,
    the settlement agrees with full Newton's at every step to far below its size (both solve
    to a residual 1e-12 of the first: 1e-8 relative leaves room for the conditioning), and
    Jacobians were kept."""
    tissue = mat.SUBCUTANEOUS_BIPHASIC
    load = -confined_drained_stress(tissue.solid, 0.8)[1]
    t_drain = 1.0 / (tissue.permeability.k0 * confined_modulus(tissue.solid))
    history = RampHold(load, 0.1 * t_drain, t_drain)
    settlements, kept = {}, {}
    for reuse in (0.0, 0.02):
        column = ConfinedBlock(1, 8, history, tissue=tissue, width=0.1, drained_top=True)
        fixed = StepOptions(dt_initial=0.05 * t_drain, dt_max=0.05 * t_drain, growth=1.0,
                            jacobian_reuse=reuse)
        stepper = TimeStepper(column, fixed, TIGHT, prefix=f"reuse{int(100 * reuse)}_")
        values = []
        stepper.run(history, history.end_time,
                    on_step=lambda r, values=values, column=column: values.append(
                        column.settlement()))
        settlements[reuse], kept[reuse] = np.array(values), stepper.reuse
        stepper.close()
    assert kept[0.0] is None and kept[0.02].reused > 0
    full, reused = settlements[0.0], settlements[0.02]
    assert len(full) == len(reused) == 20
    assert np.max(np.abs(reused - full)) < 1e-8 * np.max(np.abs(full))


def _held_column(carry: int):
    """A displacement-held Holmes–Mow column relaxing (ramp 0.1 s, hold to 30 s with its steps
    grown x3, so that the Jacobian's Δt-dependent Darcy block changes from step to step): its
    reports, the reactions and the stepper's JacobianReuse."""
    history = RampHold(0.01, 0.1, 30.0)
    column = ConfinedBlock(1, 8, history, tissue=mat.SUBCUTANEOUS_BIPHASIC, width=0.1,
                           drained_top=True, top_displacement=True)
    options = StepOptions(dt_initial=0.025, dt_max=30.0, growth=1.0, hold_growth=3.0,
                          jacobian_reuse=0.02, jacobian_carry=carry)
    stepper = TimeStepper(column, options, TIGHT, prefix=f"carry{carry}_")
    reports = stepper.run(history, history.end_time)
    stepper.close()
    return reports, np.array([r.diagnostics["reaction"] for r in reports]), stepper.reuse


def test_jacobian_carry_reaches_the_same_states_with_fewer_factorisations():
    """StepOptions.jacobian_carry starts a held step from the Jacobian (and LU factors) the last
    easy held step ended with. Only Newton's path changes: the same steps (all easy) reach the
    same reactions to far below Newton's tolerance (a residual 1e-12 of the first; 1e-8 leaves
    room for the conditioning), with fewer Jacobians assembled over the relaxation, although
    each hold step is 3x longer than the last."""
    plain, plain_force, plain_reuse = _held_column(0)
    kept, kept_force, kept_reuse = _held_column(4)
    assert [r.time for r in kept] == [r.time for r in plain] and len(plain) >= 8
    assert np.max(np.abs(kept_force - plain_force)) < 1e-8 * np.max(np.abs(plain_force))
    assert kept_reuse.assembled < plain_reuse.assembled


@pytest.mark.parametrize("values, word", [
    ({"jacobian_reuse": 0.05, "jacobian_carry": -1}, "whole number"),
    ({"jacobian_reuse": 0.05, "jacobian_carry": 2.5}, "whole number"),
    ({"jacobian_reuse": 0.05, "jacobian_carry": True}, "whole number"),
    ({"jacobian_carry": 3}, "jacobian_reuse"),
])
def test_jacobian_carry_refuses_what_it_cannot_use(values, word):
    """A carry that is no count of iterations, or one without `jacobian_reuse` (whose threshold
    is what reassembles a kept Jacobian that stops contracting), is refused, naming the key."""
    from fingertip_dolfinx.errors import InputError

    with pytest.raises(InputError, match=word) as error:
        StepOptions(**values)
    assert "jacobian_carry" in error.value.where


def test_jacobian_carry_is_refused_from_a_scene_naming_the_table():
    from fingertip_dolfinx.errors import InputError
    from fingertip_dolfinx.scene import load_scene

    with pytest.raises(InputError, match="jacobian_reuse") as error:
        load_scene("line-load", ["steps.jacobian_reuse=0", "steps.jacobian_carry=3"])
    assert error.value.where.endswith("steps.jacobian_carry=3\": jacobian_carry")


def _relaxing_column(prefix: str, **steps):
    """The held column of `_held_column` (its Jacobian's Darcy block changes with the steps,
    x3 each in the hold), stepped with the StepOptions `steps` besides its own: its reports,
    reactions, stepper and the MUMPS numerical factorisations it did (PETSc's MatLUFactorNum
    events)."""
    from petsc4py import PETSc

    PETSc.Log.begin()
    event = PETSc.Log.Event("MatLUFactorNum")
    history = RampHold(0.01, 0.1, 30.0)
    column = ConfinedBlock(1, 8, history, tissue=mat.SUBCUTANEOUS_BIPHASIC, width=0.1,
                           drained_top=True, top_displacement=True)
    options = StepOptions(dt_initial=0.025, dt_max=30.0, growth=1.0, hold_growth=3.0, **steps)
    stepper = TimeStepper(column, options, TIGHT, prefix=prefix)
    before = event.getPerfInfo()["count"]
    reports = stepper.run(history, history.end_time)
    factorisations = event.getPerfInfo()["count"] - before
    stepper.close()
    return reports, np.array([r.diagnostics["reaction"] for r in reports]), stepper, \
        factorisations


@pytest.mark.parametrize("limit", [2, 10])
def test_factor_reuse_keeps_newton_and_its_answers_with_fewer_factorisations(limit):
    """StepOptions.factor_reuse solves each Newton iteration's system, with the Jacobian
    assembled fresh, by GMRES preconditioned by the LU factors of an older Jacobian; a solve
    still short of the tolerance after 2 x `limit` iterations is finished with a new
    factorisation, and one that took more than `limit` has the next Jacobian factorised.
    Newton's convergence is the exact Jacobian's: the same steps, in the same Newton iterations
    per step, reach the same reactions to far below Newton's tolerance (a residual 1e-12 of
    the first; GMRES solves to 1e-10: 1e-8 leaves room for the conditioning), while MUMPS
    factorises fewer matrices (one per Newton iteration without it): with a limit of 10,
    fewer than a fifth, the factors kept across the hold's steps although each changes the
    Darcy block by x3; with 2, most solves need the new factorisation, and still fewer."""
    plain, plain_force, plain_stepper, plain_lu = _relaxing_column("kf0_")
    kept, kept_force, stepper, kept_lu = _relaxing_column(f"kf{limit}_", factor_reuse=limit)
    assert plain_stepper.factor is None and len(plain) >= 8
    assert [r.time for r in kept] == [r.time for r in plain]
    assert [r.newton_iterations for r in kept] == [r.newton_iterations for r in plain]
    assert np.max(np.abs(kept_force - plain_force)) < 1e-8 * np.max(np.abs(plain_force))
    assert plain_lu == sum(r.newton_iterations for r in plain)
    factor = stepper.factor
    assert kept_lu == factor.factorisations and factor.kept > 0
    assert factor.fallbacks > 0 or limit == 10  # a limit of 2 needs the fallback
    assert kept_lu < (0.2 if limit == 10 else 0.9) * plain_lu
    assert all(r.linear_iterations <= 2 * limit * r.newton_iterations for r in kept)


def test_hold_factor_reuse_keeps_the_factors_in_the_hold_only():
    """StepOptions.hold_factor_reuse solves Newton's systems of held steps by flexible GMRES on
    the LU factors the solver holds (FactorReuse in held steps only); the ramp's solves are the
    direct route's, one factorisation each. The same steps, in the same Newton iterations, reach
    the same reactions (to far below Newton's tolerance, as for factor_reuse); the ramp keeps
    its factorisations (one per Newton iteration: each of its solves is one LU application)
    and the hold, whose steps grow x3, needs fewer than half of its own."""
    plain, plain_force, _, plain_lu = _relaxing_column("hf0_")
    kept, kept_force, stepper, kept_lu = _relaxing_column("hf10_", hold_factor_reuse=10)
    assert len(plain) >= 8 and [r.time for r in kept] == [r.time for r in plain]
    assert [r.newton_iterations for r in kept] == [r.newton_iterations for r in plain]
    assert np.max(np.abs(kept_force - plain_force)) < 1e-8 * np.max(np.abs(plain_force))
    ramp = [r for r in kept if r.time <= 0.1 + 1e-12]
    hold = [r for r in kept if r.time > 0.1 + 1e-12]
    assert all(r.linear_iterations == r.newton_iterations for r in ramp)
    assert stepper.factor.held_only and stepper.factor.kept > 0
    ramp_lu = sum(r.newton_iterations for r in ramp)
    hold_lu = sum(r.newton_iterations for r in hold)
    assert plain_lu == ramp_lu + hold_lu
    assert ramp_lu < kept_lu < ramp_lu + 0.5 * hold_lu


@pytest.mark.parametrize("values, word", [
    ({"hold_factor_reuse": -1}, "whole number"),
    ({"hold_factor_reuse": True}, "whole number"),
    ({"hold_factor_reuse": 10, "factor_reuse": 10}, "one of them"),
])
def test_hold_factor_reuse_refuses_what_it_cannot_use(values, word):
    """No count of iterations, or both reuses at once (factor_reuse keeps the factors in every
    step already), is refused, naming the key."""
    from fingertip_dolfinx.errors import InputError

    with pytest.raises(InputError, match=word) as error:
        StepOptions(**values)
    assert "hold_factor_reuse" in error.value.where


def test_hold_factor_reuse_is_the_direct_routes_only():
    """The kept factors are the direct route's LU: the iterative route, which has none, runs a
    scene with the option as without it (the 3D line load's cluster recipe, `--set
    solver.linear=iterative`); inexact Newton on the direct route is refused, naming the key
    (its tolerance is set in the KSP pre-solve hook the kept factors replace)."""
    from fingertip_dolfinx.errors import InputError
    from fingertip_dolfinx.scene import load_scene

    assert load_scene("line-load-3d").steps.hold_factor_reuse > 0
    scene = load_scene("line-load-3d", ["solver.linear=iterative"])
    assert scene.linear == "iterative" and scene.steps.hold_factor_reuse > 0
    with pytest.raises(InputError, match="snes_ksp_ew") as error:
        load_scene("line-load", ["steps.hold_factor_reuse=15", "solver.snes_ksp_ew=true"])
    assert error.value.where.endswith("steps.hold_factor_reuse")


@pytest.mark.parametrize("value", [-1, 2.5, True, "15"])
def test_factor_reuse_refuses_what_is_no_count_of_iterations(value):
    from fingertip_dolfinx.errors import InputError

    with pytest.raises(InputError, match="whole number") as error:
        StepOptions(factor_reuse=value)
    assert "factor_reuse" in error.value.where


@pytest.mark.parametrize("solver, word", [("solver.linear=iterative", "iterative"),
                                          ("solver.snes_ksp_ew=true", "snes_ksp_ew")])
def test_factor_reuse_is_refused_where_it_would_not_solve_exactly(solver, word):
    """The kept factorisation is the direct route's LU (the iterative route has none), and its
    solves are exact: inexact Newton's tolerance would be lost with the KSP's pre-solve hook."""
    from fingertip_dolfinx.errors import InputError
    from fingertip_dolfinx.scene import load_scene

    with pytest.raises(InputError, match=word) as error:
        load_scene("line-load", ["steps.factor_reuse=15", solver])
    assert error.value.where.endswith("steps.factor_reuse")


@pytest.mark.mpi
def test_tangent_reuse_predicts_the_same_steps_without_factorising_for_them():
    """StepOptions.tangent_reuse solves the tangent predictor's system (the accepted state's
    Jacobian, assembled fresh) by GMRES to a relative 1e-8 on the LU factors the last step's
    Newton solve ended with, not by factorising it. The predictor is then the exact one to
    that tolerance, so Newton takes the same steps in the same iterations to the same
    reactions (to far below its tolerance, a residual 1e-12 of the first: 1e-8 leaves room
    for the conditioning); every predictor (every step's but the first's, which starts from
    rest) is solved on kept factors, and each saves MUMPS a factorisation."""
    predicted = {"tangent_start": True, "extrapolate": False}  # every step after the first
    plain, plain_force, plain_stepper, plain_lu = _relaxing_column("tr0_", **predicted)
    kept, kept_force, stepper, kept_lu = _relaxing_column("tr1_", **predicted,
                                                          tangent_reuse=True)
    tangent = stepper.tangent
    assert len(plain) >= 8 and plain_stepper.tangent.kept == 0
    assert [r.time for r in kept] == [r.time for r in plain]
    assert [r.newton_iterations for r in kept] == [r.newton_iterations for r in plain]
    assert np.max(np.abs(kept_force - plain_force)) < 1e-8 * np.max(np.abs(plain_force))
    predictors = len(plain) - 1  # every step but the first
    assert tangent.kept == predictors and tangent.refactored == 0
    assert kept_lu == plain_lu - predictors


def test_tangent_reuse_lets_a_scene_switch_to_the_iterative_route():
    """The 3D line load keeps its factors for the predictor; the iterative route has none, and
    the scene still runs on it (the guide's cluster recipe: `--set solver.linear=iterative`),
    its predictor solved by the route's own Krylov solver."""
    from fingertip_dolfinx.scene import load_scene

    assert load_scene("line-load-3d").steps.tangent_reuse
    scene = load_scene("line-load-3d", ["solver.linear=iterative"])
    assert scene.linear == "iterative" and scene.steps.tangent_reuse


def test_tangent_reuse_is_refused_without_the_tangent_predictor():
    """The option serves the tangent predictor: refused without it, naming the key."""
    from fingertip_dolfinx.errors import InputError
    from fingertip_dolfinx.scene import load_scene

    with pytest.raises(InputError, match="tangent_start") as error:
        load_scene("line-load", ["steps.tangent_reuse=true"])
    assert "tangent_reuse" in error.value.where


def test_krylov_column_counts_the_newton_iterations_it_reports(shared_tmp_path):
    """With MUMPS every Newton iteration is one linear solve of one "Krylov iteration", so the
    history's per-step Krylov count must equal its Newton count also in steps whose first
    attempt failed and was cut (that attempt counts in neither). A 0.02 s first step of the
    line load fails at the first touch and is cut, as does one later ramp step."""
    from fingertip_dolfinx.outputs import read_csv
    from fingertip_dolfinx.runner import run_scene
    from fingertip_dolfinx.scene import load_scene

    scene = load_scene("line-load-1pct", ["steps.dt_initial=0.02", "protocol.end_time=1.0",
                                          "output.times=[1.0]"])
    run_scene(scene, shared_tmp_path, progress=False)
    h = read_csv(shared_tmp_path / "history.csv")
    assert h["cuts"].sum() >= 1
    assert np.array_equal(h["krylov_iterations"], h["newton_iterations"])
