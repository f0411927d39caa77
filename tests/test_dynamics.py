"""Time-domain dynamics: inertia (inertia.py) integrated by the Wood–Bossak–Zienkiewicz method
(generalised-α with α_f = 0, the time stepper's "generalized-alpha" scheme).

The problems are `studies.problems.ConfinedBlock` columns with a density: a laterally confined
column [0, W] × [0, H] on rollers, so that every motion along y is a one-dimensional P-wave
with the confined modulus M = λ + 2μ. Free vibration: the bottom held, the top free; its first
mode is u_y = sin(πy/2H), ω₁ = (π/2H) sqrt(M/ρ). It starts at rest in equilibrium (u = 0) with
the velocity of that mode, so a₀ = 0 is the consistent initial acceleration.
"""

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from fingertip_dolfinx.errors import FingertipError, InputError
from fingertip_dolfinx.harmonic import complex_modulus
from fingertip_dolfinx.loading import Vibration
from fingertip_dolfinx.physics import materials as mat
from fingertip_dolfinx.physics.inertia import wbz_parameters
from fingertip_dolfinx.scene import load_scene
from fingertip_dolfinx.stepping import StepOptions, TimeStepper
from fingertip_dolfinx.studies.problems import (
    ConfinedBlock,
    driven_layer,
    driven_layer_force,
)
from fingertip_dolfinx.studies.signals import steady_state

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from two_routes import scene_at  # noqa: E402

RHO, H, W = 1e-9, 1.0, 0.1  # N·s²/mm⁴ (1000 kg/m³), mm, mm
LINEAR = mat.LinearElastic(E=1e-3, nu=0.3)  # M = 1.35e-3 MPa: c = 1.16 m/s, T₁ = 3.4 ms
EXACT = {"snes_rtol": 1e-10, "snes_atol": 1e-22}  # Newton to round-off (forces ~1e-7 N/mm)


def _modulus(solid) -> float:
    if isinstance(solid, mat.LinearElastic):
        return solid.lmbda + 2 * solid.mu
    return solid.K0 + 4 * solid.mu0 / 3


def _period(solid) -> float:
    """The first free period of the column at small strain (s)."""
    return 4 * H / math.sqrt(_modulus(solid) / RHO)


def _fixed_steps(dt: float, rho_inf: float) -> StepOptions:
    return StepOptions(dt_initial=dt, dt_min=dt / 10, dt_max=dt, growth=1.0,
                       scheme="generalized-alpha", rho_inf=rho_inf)


def _free_vibration(steps_per_period, rho_inf, periods, solid=LINEAR, strain=1e-3):
    """The column's first mode from rest at u = 0 with the peak strain `strain`; returns the
    block and the total energy (kinetic + strain) at the start and after every step."""
    small = isinstance(solid, mat.LinearElastic)
    block = ConfinedBlock(1, 8, lambda t: 0.0, solid=solid, width=W, H=H, density=RHO,
                          small_strain=small)
    T = _period(solid)
    X = block.u.function_space.tabulate_dof_coordinates()
    # u = U sin(πy/2H) sin ωt: peak strain U π/2H, peak velocity U ω.
    U = strain * 2 * H / math.pi
    block.inertia.v_n.x.array.reshape(-1, 2)[:, 1] = U * 2 * math.pi / T * np.sin(
        math.pi * X[:, 1] / (2 * H))
    energy = [block.inertia.kinetic_energy() + block.strain_energy()]
    stepper = TimeStepper(block, _fixed_steps(T / steps_per_period, rho_inf), EXACT,
                          prefix=f"free{steps_per_period}_{rho_inf}_{small}_")

    def record(report):
        energy.append(block.inertia.kinetic_energy() + block.strain_energy())

    stepper.run(lambda t: 0.0, periods * T, on_step=record)
    stepper.close()
    return block, np.array(energy)


def _amplification(x: float, rho_inf: float) -> np.ndarray:
    """The roots of the method's amplification matrix for ü + ω²u = 0 at x = ωΔt (state u,
    Δt v, Δt² a)."""
    alpha_m, gamma, beta = wbz_parameters(rho_inf)
    A = np.zeros((3, 3))
    for j, (u0, v0, a0) in enumerate(np.eye(3)):
        a1 = -(alpha_m * a0 + x**2 * (u0 + v0 + (0.5 - beta) * a0)) / (1 - alpha_m + x**2 * beta)
        A[:, j] = (u0 + v0 + (0.5 - beta) * a0 + beta * a1, v0 + (1 - gamma) * a0 + gamma * a1,
                   a1)
    return np.linalg.eigvals(A)


def _spectral_radius(x: float, rho_inf: float) -> float:
    return float(np.abs(_amplification(x, rho_inf)).max())


def _principal_radius(x: float, rho_inf: float) -> float:
    """|λ| of the oscillating root pair at x = ωΔt: the amplitude ratio per step of a resolved
    mode; its energy goes as |λ|²."""
    roots = _amplification(x, rho_inf)
    return float(np.abs(roots[np.abs(roots.imag) > 0]).max())


def test_wbz_parameters_are_the_trapezoidal_rule_at_rho_inf_one():
    assert wbz_parameters(1.0) == (0.0, 0.5, 0.25)
    alpha_m, gamma, beta = wbz_parameters(0.8)
    assert alpha_m == pytest.approx(-1 / 9) and gamma == pytest.approx(0.5 + 1 / 9)
    assert beta == pytest.approx((1 + 1 / 9) ** 2 / 4)
    # the spectral radius tends to ρ∞ as ωΔt → ∞ (its definition; Chung & Hulbert 1993)
    for rho_inf in (0.0, 0.5, 0.8, 1.0):
        assert _spectral_radius(1e6, rho_inf) == pytest.approx(rho_inf, abs=1e-3)
    with pytest.raises(InputError):
        wbz_parameters(1.2)


def test_trapezoidal_rule_conserves_the_energy_of_a_linear_column():
    """ρ∞ = 1 on the exactly linear (small-strain) column: ½vᵀMv + ½uᵀKu is the trapezoidal
    rule's invariant, so it is conserved to round-off over 5 periods (measured 2e-14)."""
    _, energy = _free_vibration(40, 1.0, periods=5)
    assert np.abs(energy - energy[0]).max() / energy[0] < 1e-11


def test_dissipation_per_period_is_the_methods():
    """ρ∞ = 0.8 and 0.5: the energy sampled once a period decreases monotonically, by the
    factor |λ|^(2N) of the method's amplification matrix at ωΔt = 2π/N (N = 40; measured
    8.16e-4 lost per period against 8.20e-4 predicted for ρ∞ = 0.8). The per-step energy is
    not monotone for α_m ≠ 0 (±2e-4 per step, and 0.3 % in the first step: a one-step O(Δt²)
    start-up of the velocity), so the check is per period, after the first."""
    N = 40
    for rho_inf in (0.8, 0.5):
        _, energy = _free_vibration(N, rho_inf, periods=4)
        per_period = energy[::N]
        assert np.all(np.diff(per_period) < 0), per_period
        measured = per_period[2:] / per_period[1:-1]
        predicted = _principal_radius(2 * math.pi / N, rho_inf) ** (2 * N)
        np.testing.assert_allclose(1 - measured, 1 - predicted, rtol=0.02)


def test_hyperfoam_energy_error_is_second_order():
    """ρ∞ = 1 on the finite-strain hyperfoam column (the skin's law, 5 % peak strain): the
    trapezoidal rule no longer conserves the energy exactly; its error is O(Δt²) (measured
    1.7e-2, 4.8e-3, 1.3e-3 at 20, 40, 80 steps a period: ratios 3.6, 3.8)."""
    errors = []
    for n in (20, 40, 80):
        _, energy = _free_vibration(n, 1.0, periods=2, solid=mat.SKIN, strain=0.05)
        errors.append(np.abs(energy - energy[0]).max() / energy[0])
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all(ratios > 3.2), (errors, ratios)


@pytest.mark.parametrize("rho_inf", [1.0, 0.8])
def test_observed_order_in_time_is_two(rho_inf):
    """Self-convergence over one period at 10, 20, 40, 80 steps: max|u_N − u_2N| falls by 4
    per halving (measured rates 1.91, 1.98 for ρ∞ = 1; 1.79, 1.94 for ρ∞ = 0.8)."""
    u = {}
    for n in (10, 20, 40, 80):
        block, _ = _free_vibration(n, rho_inf, periods=1)
        u[n] = block.u.x.array.copy()
    differences = [np.abs(u[n] - u[2 * n]).max() for n in (10, 20, 40)]
    rates = np.log2(np.array(differences[:-1]) / np.array(differences[1:]))
    assert rates[-1] > 1.85 and rates[0] > 1.7, rates


# ---- a harmonically driven viscoelastic layer -------------------------------------------------

OMEGA = 250.0  # rad/s: ωτ₁ = 1, the fast Prony term's peak loss
PRONY = mat.Prony(g=(0.3, 0.2), tau=(4e-3, 0.07))
M0 = RHO * (OMEGA * H / 2) ** 2  # |k|H ≈ 2: between the static limit and the first resonance


def _driven_layer(steps_per_period: int, periods: int = 12):
    """The QLV column driven at the top by u_y(H) = −U sin ωt from rest; returns the complex
    amplitudes of u_y at mid-height and of the top force, fitted over the last 3 periods."""
    nu = 0.3
    solid = mat.LinearElastic(E=M0 * (1 + nu) * (1 - 2 * nu) / (1 - nu), nu=nu)
    U, f = 1e-3, OMEGA / (2 * math.pi)
    block = ConfinedBlock(1, 8, lambda t: U * math.sin(OMEGA * t), solid=solid, prony=PRONY,
                          width=W, H=H, density=RHO, small_strain=True, top_displacement=True)
    X = block.u.function_space.tabulate_dof_coordinates()
    mid = int(np.flatnonzero(np.isclose(X[:, 0], 0) & np.isclose(X[:, 1], H / 2))[0])
    dt = 1 / f / steps_per_period
    stepper = TimeStepper(block, _fixed_steps(dt, 0.8), EXACT, prefix=f"layer{steps_per_period}_")
    t, u, force = [0.0], [0.0], [0.0]

    def record(report):  # the force from the diagnostics: before `accept` moves the history
        t.append(report.time)
        u.append(block.u.x.array[2 * mid + 1])
        force.append(report.diagnostics["reaction"])

    stepper.run(block.load, periods / f, on_step=record)
    stepper.close()
    modulus = M0 * complex_modulus(PRONY, OMEGA)
    drive = 1j * U  # −U sin ωt = Re(iU e^{iωt})
    exact_u = drive * driven_layer(np.array([H / 2]), H, OMEGA, RHO, modulus)[0]
    exact_force = drive * driven_layer_force(H, OMEGA, RHO, modulus) * W
    return (steady_state(t, u, f, 3) / exact_u, steady_state(t, force, f, 3) / exact_force)


def test_driven_viscoelastic_layer_matches_the_closed_form():
    """Steady state of the QLV layer under a harmonic top displacement against
    u(y) = U sin(ky)/sin(kH), k = ω sqrt(ρ/(M0 G*(ω))): |u(H/2)|/U = 1.02 (0.5 statically).
    40 steps a period: displacement within 0.5 %, force within 1.4 % and 0.1°; 80 steps: 4×
    closer (second order). Transients (first mode, loss tangent 0.16) decay by e^-7.7 over the
    9 periods before the fit."""
    errors = []
    for n in (40, 80):
        ratio_u, ratio_force = _driven_layer(n)
        errors.append((abs(ratio_u - 1), abs(ratio_force - 1)))
    coarse, fine = np.array(errors)
    assert coarse[0] < 0.01 and coarse[1] < 0.03, coarse
    assert np.all(fine < coarse / 3), (coarse, fine)


# ---- the stepper and the scene ---------------------------------------------------------------


def test_steps_resolve_the_period_after_the_onset():
    """A vibration protocol on the column: the press and hold grow the steps as usual, from the
    onset on every step is at most period/steps_per_period."""
    history = Vibration(depth=1e-3, ramp_time=0.1, hold_time=0.1, amplitudes=(1e-4,),
                        frequencies=(40.0,), cycles=2)
    block = ConfinedBlock(1, 4, history, solid=LINEAR, width=W, H=H, density=RHO,
                          small_strain=True, top_displacement=True)
    options = StepOptions(dt_initial=0.02, dt_max=0.1, scheme="generalized-alpha",
                          steps_per_period=20)
    stepper = TimeStepper(block, options, EXACT, prefix="onset_")
    reports = stepper.run(history, history.end_time)
    stepper.close()
    time = np.array([r.time for r in reports])
    dt = np.array([r.dt for r in reports])
    after = time > history.onset + 1e-12
    assert dt[after].max() <= history.period / 20 * (1 + 1e-9)
    assert dt[~after].max() > history.period  # no cap in the quasi-static part
    assert after.sum() == 2 * 20


def test_inertia_needs_the_dynamic_scheme():
    block = ConfinedBlock(1, 2, lambda t: 0.0, solid=LINEAR, density=RHO, small_strain=True)
    with pytest.raises(FingertipError, match="generalized-alpha"):
        TimeStepper(block, StepOptions(scheme="bdf2"), prefix="refuse_")
    with pytest.raises(ValueError, match="error"):
        StepOptions(scheme="generalized-alpha", control="error")
    with pytest.raises(ValueError, match="rho_inf"):
        StepOptions(scheme="generalized-alpha", rho_inf=1.5)
    with pytest.raises(InputError, match="generalized-alpha"):
        load_scene("vibrotactile", ["steps.scheme=bdf2"])



def test_error_control_of_a_dynamic_scene_is_refused_with_its_fix():
    """The message was the problem with the fix inside it and a generic "Fix: check the
    values." after it, without a full stop between them."""
    with pytest.raises(InputError) as refused:
        load_scene("vibrotactile", ['steps.control="error"'])
    assert str(refused.value).endswith(
        "control: 'error' has no error estimate for the generalized-alpha scheme. "
        "Fix: use control = 'iterations' (steps_per_period sets the accuracy).")
    with pytest.raises(InputError) as refused:  # a ValueError of the options: one sentence
        load_scene("vibrotactile", ["steps.rho_inf=1.5"])
    assert "got 1.5. Fix: check the values." in str(refused.value)

def test_vibrotactile_scene_is_dynamic():
    scene = load_scene("vibrotactile")
    assert scene.model.inertia and scene.steps.scheme == "generalized-alpha"
    assert scene.history.period == pytest.approx(4e-3)
    assert scene.history.end_time == pytest.approx(2.04)


def _step_oscillation(t, force, onset, window):
    """max |f_{n+1} − 2 f_n + f_{n−1}| over the steps with window[0] <= t − onset < window[1]."""
    after = t >= onset - 1e-12
    t, force = t[after] - onset, force[after]
    d2, middle = np.abs(np.diff(force, 2)), t[1:-1]
    return d2[(middle >= window[0]) & (middle < window[1])].max()


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="serial: one run per rank would clash")
@pytest.mark.slow  # 10 periods at 250 Hz on the fingertip: minutes
def test_vibrotactile_contact_keeps_fine_steps_stable(tmp_path):
    """The coarse fingertip at 250 Hz, 80 steps a period (Δt = 50 µs), with the scene's
    (conservative, penalty) contact: the step-to-step oscillation of the force that the onset
    leaves does not grow. Generalised-α (ρ∞ = 0.8) dissipates, and a contact force with a
    potential adds no energy, so from 0.5–1.5 ms to 4–5 ms after the onset it can only decay
    (measured: 3.7e-7 → 6e-8 N/mm). With Nitsche's θ = 0 it grew ×155 over the same span
    (3.6e-5 → 5.6e-3 N/mm) and Newton failed at 6.4 ms."""
    from fingertip_dolfinx.result import Result
    from fingertip_dolfinx.runner import run_scene

    scene = scene_at(250.0, 1e-3, 1.25, "fast-relaxation", extra=["steps.steps_per_period=80"])
    assert scene.model.contact == "penalty"
    run_scene(scene, tmp_path / "run", progress=False)
    history = Result(tmp_path / "run").history
    t, force = np.asarray(history["time_s"]), np.asarray(history["force_N_per_mm"])
    early = _step_oscillation(t, force, scene.history.onset, (0.5e-3, 1.5e-3))
    late = _step_oscillation(t, force, scene.history.onset, (4e-3, 5e-3))
    assert late <= early, (early, late)


def test_non_conservative_contact_in_a_dynamic_run_is_flagged():
    from fingertip_dolfinx.geometry.mesh import build_mesh
    from fingertip_dolfinx.physics.contact import NonConservativeContactWarning
    from fingertip_dolfinx.problem import FingertipProblem

    scene = scene_at(250.0, 1e-3, 1.0, "fast-relaxation", extra=["model.contact=nitsche"])
    problem = FingertipProblem(build_mesh(scene.section, MPI.COMM_WORLD), scene.indenters,
                               scene.history, scene.materials, scene.model)
    assert not problem.contact.conservative
    with pytest.warns(NonConservativeContactWarning, match="penalty"):
        TimeStepper(problem, scene.steps, prefix="nonconservative_").close()


def test_steady_state_recovers_a_harmonic_with_drift():
    """The fit is exact for c + d t + Re(Z e^{iωt}) over whole periods (trend on), and the
    phase convention is Re(Z e^{iωt}): Z = A − iB for A cos + B sin."""
    f, Z = 250.0, 0.3 * np.exp(0.7j)
    t = np.linspace(0, 10 / f, 401)
    s = 1.5 + 2.0 * t + (Z * np.exp(2j * np.pi * f * t)).real
    assert abs(steady_state(t, s, f, 3, trend=True) - Z) < 1e-12
    assert abs(steady_state(t, np.sin(2 * np.pi * f * t), f, 2) - (-1j)) < 1e-12
    with pytest.raises(ValueError):
        steady_state(t, s, f, 20)


# ---- the fingertip ---------------------------------------------------------------------------


@pytest.mark.mpi
def test_fingertip_momentum_balance_with_inertia():
    """The 1 mm bar on a coarse section, pressed 0.3 mm in 0.2 s, then one period at 250 Hz
    with inertia. The discrete momentum balance tested with e_y everywhere (internal forces
    and the pore pressure sum to zero on a rigid translation) says: indenter force − support
    load = ∫ ρ [(1 − α_m) a_{n+1} + α_m a_n]_y dX, to Newton's tolerance, at every step; and
    the inertia matters in the vibration (the two forces differ by more than 1e3 × that).
    The protocol starts at the ramp: the stepper's first steps are quasi-static ones."""
    import dataclasses

    from dolfinx import fem

    from fingertip_dolfinx.geometry.indenters import load_indenter
    from fingertip_dolfinx.geometry.mesh import build_mesh
    from fingertip_dolfinx.geometry.section import load_section
    from fingertip_dolfinx.model import ModelOptions
    from fingertip_dolfinx.problem import FingertipProblem

    section = load_section("male-index")
    section = dataclasses.replace(section, mesh=dataclasses.replace(
        section.mesh, min_size=0.25, max_size=1.5, bone_size=2.0, refine_half_width=2.0,
        refine_depth=1.0))
    history = Vibration(depth=0.3, ramp_time=0.2, hold_time=0.0, amplitudes=(0.02,),
                        frequencies=(250.0,), cycles=1)
    problem = FingertipProblem(build_mesh(section), [load_indenter("bar")], history,
                               options=ModelOptions(inertia=True, contact="penalty",
                                                    contact_gamma0=100.0))  # conservative
    assert set(problem.state_arrays()) >= {"v_n", "a_n"}
    e_y = fem.Function(problem.V)
    e_y.x.array.reshape(-1, 2)[:, 1] = 1.0
    inertial = fem.form(problem.inertia.residual(e_y))
    diagnostics = problem.diagnostics

    def with_inertia():  # before `accept`: a_{n+1} still from this step's u_n
        local = fem.assemble_scalar(inertial)
        return diagnostics() | {"inertia": problem.mesh.comm.allreduce(local)}

    problem.diagnostics = with_inertia
    options = StepOptions(dt_initial=0.05, dt_max=0.1, scheme="generalized-alpha",
                          steps_per_period=20)
    stepper = TimeStepper(problem, options, prefix="fingertip_dynamic_")
    reports = stepper.run(history, history.end_time)
    stepper.close()
    d = [r.diagnostics for r in reports]
    imbalance = [abs(x["force_N_per_mm"] - x["reaction_N_per_mm"] - x["inertia"]) for x in d]
    # Newton stops at |r| <= snes_atol = 1e-10 N/mm; a sum over n dofs is within √n of it
    # (measured 1.2e-10 against inertial forces up to 9.5e-5 N/mm, on 2888 dofs).
    bound = math.sqrt(2 * problem.V.dofmap.index_map.size_global) * 1e-10
    assert max(imbalance) < bound, (imbalance, bound)
    vibration = [x for r, x in zip(reports, d) if r.time > history.onset + 1e-12]
    assert len(vibration) == 20
    assert max(abs(x["inertia"]) for x in vibration) > 1e3 * max(imbalance)


def test_quasi_static_problems_have_no_inertia():
    block = ConfinedBlock(1, 2, lambda t: 0.0, solid=LINEAR, small_strain=True)
    assert block.inertia is None and "v_n" not in block.state_arrays()
