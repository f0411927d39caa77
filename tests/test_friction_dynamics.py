"""Friction on both time routes: the penalty law's memory of the tangential traction between
steps, and a block dragged by Coulomb friction with inertia (`studies.problems.SlidingBlock`),
whose discrete energy balance closes and whose mean velocity grows at μ Fn/m in gross slip.
"""

from functools import cache

import pytest

from fingertip_dolfinx.errors import InputError
from fingertip_dolfinx.geometry.indenters import Plate
from fingertip_dolfinx.physics.contact import NitscheContact, Obstacle
from fingertip_dolfinx.physics.friction import CoulombFriction
from fingertip_dolfinx.studies.problems import newton_problem
from fingertip_dolfinx.studies.problems.mindlin import CattaneoMindlin, press_and_drag
from fingertip_dolfinx.studies.problems.sliding import SlidingBlock, drag_block, energy_balance

MINDLIN = CattaneoMindlin()
BLOCK = SlidingBlock()  # μ = 0.5, penalty contact, the plate at 0.05 mm/s after a 1 s start


def test_a_held_shear_keeps_its_tangential_force_under_the_penalty_law():
    # The cylinder pressed, moved 4e-4 mm along x (partial stick, Q ≈ 0.44 μP), then held for
    # three steps: the block is in the same equilibrium, so Q stays. The penalty law without its
    # elastic slip forgot the traction at every step (f = −γ Δs_t): held, Q fell by 1.6 % a
    # step (measured: 4.7 % after three), a relaxation in steps, not in time.
    domain, tags = MINDLIN.mesh(MINDLIN.a_target / 2.5)
    built = MINDLIN.block(domain, tags, method="penalty",
                          gamma_ratio=MINDLIN.shear_modulus / MINDLIN.modulus)
    newton = newton_problem(built.residual, built.u, built.bcs, "held_penalty_",
                            snes_rtol=1e-10, snes_atol=1e-13, snes_max_it=80)
    rows = press_and_drag(built, newton, MINDLIN.depth, 2, (4e-4,) * 4,
                          lambda x_tip, its: built.forces())
    (Q, P), held = rows[2], [q for q, _ in rows[3:]]
    assert 0.1 < Q / (MINDLIN.mu * P) < 0.9, (Q, P)  # partial stick
    # The elastic slip is kept at the nodes (P2), the traction at the quadrature points: the
    # first held step re-balances the interpolated spring once (measured +8e-4 of Q) ...
    assert held[0] == pytest.approx(Q, rel=2e-3)
    # ... after which nothing is forgotten: the held state is a fixed point (measured 5e-7;
    # Newton's relative tolerance is 1e-10)
    assert held[2] == pytest.approx(held[1], rel=1e-5) == held[0]


@pytest.mark.parametrize("theta", [1, -1])
def test_friction_refuses_a_nitsche_contact_other_than_theta_0(theta):
    import ufl
    from dolfinx import fem, mesh
    from mpi4py import MPI

    domain = mesh.create_unit_square(MPI.COMM_SELF, 1, 1)
    u = fem.Function(fem.functionspace(domain, ("Lagrange", 1, (2,))))
    contact = NitscheContact(u, ufl.grad(u), ufl.ds, [Obstacle.at(domain, Plate())],
                             modulus=1.0, theta=theta)
    with pytest.raises(InputError, match="contact_theta"):
        CoulombFriction(contact, 0.5)


@cache
def dragged(dt: float, rho_inf: float = 1.0, end: float = 6.0) -> tuple[dict, ...]:
    """The block pressed, then dragged to `end` s in steps of `dt` (coarse: 8 × 4 P2)."""
    return tuple(drag_block(BLOCK, 8, 4, dt, end, rho_inf=rho_inf,
                            prefix=f"slid_{dt}_{rho_inf}_".replace(".", "_")))


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_a_block_dragged_with_inertia_slips_at_mu_fn_and_gains_momentum_at_that_rate():
    rows = dragged(0.25)
    Fn = rows[0]["force_y"]
    sliding = [r for r in rows if r["time"] >= 2.0]  # after the start, before the catch-up
    assert BLOCK.catch_up(Fn) > rows[-1]["time"] + 1.0
    for r in sliding:  # gross slip: the friction force is μ times the normal force
        assert r["force_x"] == pytest.approx(BLOCK.mu * r["force_y"], rel=1e-9)
    # Momentum: nothing else holds the block along x (rollers on top), so m Δv̄ is the trapezoid
    # of the friction force over the step, exactly for the trapezoidal rule (ρ∞ = 1) ...
    for a, b in zip(sliding, sliding[1:]):
        impulse = 0.5 * (a["force_x"] + b["force_x"]) * (b["time"] - a["time"])
        assert BLOCK.mass * (b["velocity"] - a["velocity"]) == pytest.approx(impulse, rel=1e-8)
    # ... and the closed form's rate μ Fn/m (Fn the static press's) up to the normal force's
    # own oscillation: the bottom's shear traction sets the finite block bouncing on the plate
    # (measured Fy between 0.94 and 1.04 Fn; the mean rate 0.985 μ Fn/m)
    assert max(abs(r["force_y"] / Fn - 1) for r in sliding) < 0.1
    rate = (sliding[-1]["velocity"] - sliding[0]["velocity"]) / (
        sliding[-1]["time"] - sliding[0]["time"])
    assert rate == pytest.approx(BLOCK.mu * Fn / BLOCK.mass, rel=3e-2)


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_the_discrete_energy_balance_of_a_dragged_block_closes():
    # The plate's work = Δ(kinetic) + Δ(strain) + Δ(penalty) energy + the friction's work
    # against the slip. For the trapezoidal rule (ρ∞ = 1) on a linear-elastic block the
    # identity is exact with the friction work as the trapezoid of the step's two tractions,
    # −½ ∫ (f_n + f_{n+1})·Δs ds: only the penalty's energy (a trapezoid of its quadratic
    # potential, exact while a point stays in contact) and Newton's tolerance remain: measured
    # 2e-5 of the work (≤ 6e-8 N mm/mm of 3e-3).
    balance = energy_balance(dragged(0.25))
    assert abs(balance["error_trapezoidal"]) < 1e-4 * balance["work"], balance
    # The recorded dissipation, −∫ f_{n+1}·Δs ds (the return mapping's own step), differs from
    # the trapezoid by ½ ∫ (f_{n+1} − f_n)·Δs per step: first order in Δt where the traction
    # changes while the skin slips (measured 3e-4 of it at Δt = 0.25 s).
    assert balance["dissipated"] == pytest.approx(balance["dissipated_trapezoidal"], rel=1e-2)
    # Numerical dissipation, ρ∞ = 0.8: generalised-α damps the modes above ~1/Δt that the
    # friction's onset excites; the energy it takes falls with the step (measured 1.8e-3 of
    # the work at Δt = 0.25 s, 8.4e-4 at 0.125 s)
    lost = [energy_balance(dragged(dt, 0.8))["error_trapezoidal"] for dt in (0.25, 0.125)]
    assert 0 < lost[1] < 0.6 * lost[0] < 1e-2 * balance["work"], lost


def test_a_frictional_scene_with_a_nitsche_theta_other_than_0_is_refused_when_loaded():
    from fingertip_dolfinx.scene import load_scene

    with pytest.raises(InputError, match="contact_theta"):
        load_scene("shear", ["model.contact_theta=1"])
    # the penalty, the dynamic route's contact, is taken with friction, inertia on
    scene = load_scene("slide", ["model.inertia=true", 'steps.scheme="generalized-alpha"',
                                 'model.contact="penalty"'])
    assert scene.model.inertia and scene.indenters[0].friction == 0.5


DYNAMIC = ["model.inertia=true", 'steps.scheme="generalized-alpha"']


def test_friction_with_inertia_refuses_nitsches_contact_when_loaded():
    # Nitsche's θ = 0 force derives from no potential: with inertia it fed energy into the
    # dragged block (the balance's error grew at the smallest step, the contact's work reached
    # −0.13 of the plate's), and was only warned about. The slide scene's own contact with
    # inertia switched on is now refused, with the penalty as the fix.
    from fingertip_dolfinx.scene import load_scene

    with pytest.raises(InputError, match=r"slide: model\.contact.*penalty"):
        load_scene("slide", DYNAMIC)
    # frictionless dynamic runs keep Nitsche's contact (the stepper's warning, as before)
    frictionless = load_scene("slide", DYNAMIC + ["indenters.0.friction=0.0"])
    assert frictionless.model.contact == "nitsche" and frictionless.model.inertia


def test_friction_with_inertia_refuses_nitsches_contact_when_built():
    import dataclasses

    from fingertip_dolfinx.geometry.mesh import build_mesh
    from fingertip_dolfinx.problem import FingertipProblem
    from fingertip_dolfinx.scene import load_scene

    scene = load_scene("slide", DYNAMIC + ['model.contact="penalty"'])
    nitsche = dataclasses.replace(scene.model, contact="nitsche")
    with pytest.raises(InputError, match=r"model\.contact.*penalty"):
        FingertipProblem(build_mesh(scene.section), scene.indenters, scene.history,
                         scene.materials, nitsche, friction=0.5)


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_the_acceleration_after_a_velocity_step_makes_the_first_step_carry_its_impulse():
    # The plate started by a velocity step: the friction jumps from 0 to μ Fn at t = 0+. From
    # rest's a = 0 the trapezoidal rule averages the step's two ends, so the block gains half
    # the impulse in the first step (and keeps lagging by it), and the recorded dissipation,
    # which takes the step's end, misses the balance by ½ μ Fn V Δt (measured 1.8e-2 of the
    # work at Δt = 0.25 s). Started from the acceleration after the jump, the first step's
    # momentum is the friction's impulse and the recorded D closes the balance.
    import dataclasses

    dt = 0.25
    data = dataclasses.replace(BLOCK, ramp=0.0, jump_acceleration=True)
    rows = drag_block(data, 8, 4, dt, 2.0, prefix="slid_jump_")
    first = rows[1]
    # the momentum after one step against the friction's impulse μ Fn Δt, to the normal
    # force's change within the step (the block's bounce: 1.7 %): measured +0.9 %; from a = 0
    # it is −50 % (the trapezoid of 0 and μ Fn)
    assert data.mass * first["velocity"] == pytest.approx(first["force_x"] * dt, rel=2e-2)
    balance = energy_balance(rows)  # measured 1.4e-4 of W over 2 s (from a = 0: −6.1e-2)
    assert abs(balance["error"]) < 2e-3 * balance["work"], balance


def test_a_failed_step_with_friction_and_inertia_names_the_onset_and_the_penalty_that_works():
    # The slide scene with inertia and the penalty at γ0 = 100 failed at the onset of sliding
    # (the bar's velocity jump: the skin that sticks in the first step gets up to twice the
    # bar's speed from Newmark's update) with the generic advice only; γ0 = 10 ran.
    from types import SimpleNamespace

    from fingertip_dolfinx.stepping.diagnosis import cuts_error, dynamic_friction_note

    dynamic = SimpleNamespace(inertia=object(), friction=object())
    text = str(cuts_error(0.1003, 0.10032, (0.5, 0.5), 5, "Newton did not converge", 0,
                          dynamic_friction_note(dynamic)))
    assert "model.contact_gamma0 = 10" in text and "tangential velocity" in text
    for other in (SimpleNamespace(inertia=None, friction=object()),  # quasi-static
                  SimpleNamespace(inertia=object(), friction=None)):  # frictionless
        assert dynamic_friction_note(other) == ""
