"""Coulomb friction (physics/friction.py) against Cattaneo–Mindlin: a rigid cylinder pressed into
a large elastic block, then dragged along it (`studies.problems.CattaneoMindlin`).

Closed form (plane strain, Johnson §7.1): under P and a monotonic tangential load Q < μP the
contact of Hertz half-width a sticks on |x| < c = a sqrt(1 − Q/(μP)); Q = μP is gross slip.
"""

import dataclasses
from functools import cache

import numpy as np
import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI

from fingertip_dolfinx.errors import InputError
from fingertip_dolfinx.geometry.indenters import Cylinder
from fingertip_dolfinx.loading import LoadHistory, PiecewiseLinear, RampHold, TangentialPath
from fingertip_dolfinx.physics.contact import NitscheContact, Obstacle
from fingertip_dolfinx.physics.friction import CoulombFriction, friction_coefficients
from fingertip_dolfinx.studies.problems import Hertz, newton_problem
from fingertip_dolfinx.studies.problems.mindlin import CattaneoMindlin, drag, stick_halfwidth

MINDLIN = CattaneoMindlin()  # E = 1 MPa, ν = 0.49, μ = 0.5, R = 1 mm, a ≈ 0.02 mm
#: Cylinder shifts (mm): partial stick at Q/μP ≈ 0.44 and 0.87, gross slip at the last
#: (measured: Q reaches μP near 1e-3 mm on this block).
SHIFTS = (4e-4, 8e-4, 1.2e-3)


@cache
def dragged(n: float) -> tuple[dict, ...]:
    """The press (2 steps) and the drag through SHIFTS on a mesh of a/n at the contact."""
    return tuple(drag(MINDLIN, MINDLIN.a_target / n, SHIFTS, prefix=f"drag_{n}_".replace(".", "_")))


def stick_errors(rows) -> np.ndarray:
    """|c − c_theory|/a of the partial-stick steps."""
    return np.array([abs(r["c"] - r["c_theory"]) / r["a"] for r in rows if 0.1 < r["ratio"] < 0.95])


def test_coulomb_bound_holds_at_every_step_and_gross_slip_carries_mu_times_the_load():
    rows = dragged(2.5)
    for r in rows:  # pointwise |f| <= μp at the quadrature points that also integrate the forces
        assert abs(r["Q"]) <= MINDLIN.mu * abs(r["P"]) * (1 + 1e-9), r
    # Gross slip: |f| = μp everywhere in contact; Q/μP differs from 1 only by the surface's tilt
    # under the cylinder, of order (a/R)² = 4e-4, and by the pressure's x-share.
    assert rows[-1]["ratio"] == pytest.approx(1.0, abs=2e-3)
    assert rows[-1]["c"] == 0.0


def test_stick_zone_matches_cattaneo_mindlin_on_a_coarse_mesh():
    rows = dragged(2.5)
    errors = stick_errors(rows)
    assert len(errors) == 2, [r["ratio"] for r in rows]
    # The stick edge is an active-set edge on P2 elements of a/2.5 at the contact, as the contact
    # edge of Hertz is: located to within a quarter element, h/4 = 0.1 a (measured 0.07 a).
    assert errors.max() < 0.1, errors
    # Pressing with friction: ν = 0.49 (β ≈ 0.02) locks in almost no shear, all of it sticks.
    press = rows[1]
    assert abs(press["ratio"]) < 1e-2 and press["c"] == pytest.approx(press["a"], rel=0.1)


@pytest.mark.slow
def test_stick_zone_converges_with_the_mesh():
    errors = [stick_errors(dragged(n)).max() for n in (2.5, 5, 10)]
    assert errors[2] < errors[0] and errors[2] < 0.03, errors


#: The block on which the closed form is exact as the mesh is refined: incompressible (β = 0,
#: no coupling), Taylor–Hood, R = 10 mm (a/R = 0.002: the pressure's x-share negligible).
EXACT = CattaneoMindlin.exact()
#: The same Q/(μP) ≈ 0.44, 0.86 and gross slip as SHIFTS: at the same a, Q ∝ P ∝ 1/R.
EXACT_SHIFTS = tuple(s / EXACT.R for s in SHIFTS)


@cache
def dragged_exact(n: float) -> tuple[dict, ...]:
    """`CattaneoMindlin.exact()` pressed (2 steps) and dragged through EXACT_SHIFTS, a/n."""
    return tuple(drag(EXACT, EXACT.a_target / n, EXACT_SHIFTS,
                      prefix=f"exact_{n}_".replace(".", "_")))


def test_the_incompressible_block_matches_cattaneo_mindlin_on_a_coarse_mesh():
    rows = dragged_exact(2.5)
    partial = [r for r in rows if 0.1 < r["ratio"] < 0.95]
    assert len(partial) == 2, [r["ratio"] for r in rows]
    for r in partial:  # the stick edge to a quarter element, h/4 = 0.1 a (measured 0.03-0.05)
        assert abs(r["c"] - r["c_theory"]) / r["a"] < 0.1, r["ratio"]
        # five elements across the contact: q and p (square-root edges, the active set edge
        # inside an element) within 15 % and 5 % in L1 (measured 0.04-0.09 and 0.02-0.03)
        assert r["q_error"] < 0.15 and r["p_error"] < 0.05, r
    # gross slip: Q/(μP) − 1 is the cylinder's tilt over the contact, (a/R)² = 4e-6 on R = 10 mm
    assert rows[-1]["c"] == 0.0 and rows[-1]["ratio"] == pytest.approx(1.0, abs=1e-4)


@pytest.mark.slow
def test_the_tangential_traction_and_the_pressure_converge_on_the_incompressible_block():
    coarse, fine = ([r for r in dragged_exact(n) if r["shift"] > 0] for n in (2.5, 10))
    for c, f in zip(coarse, fine):
        # a quarter of h (a/2.5 to a/10) at least halves both L1 distances (a rate >= 0.5;
        # measured 3-4x, q's rate ~0.9 from a/2.5 to a/20: the benchmarks page)
        assert f["q_error"] < c["q_error"] / 2 and f["p_error"] < c["p_error"] / 2, (c, f)
        # at a/10: q within 4 %, p within 1 %, c within 0.02 a (measured 2.8 %, 0.7 %, 0.01 a)
        assert f["q_error"] < 0.04 and f["p_error"] < 0.01, f
        assert abs(f["c"] - f["c_theory"]) < 0.02 * f["a"], f


def test_an_incompressible_block_needs_the_mixed_element():
    with pytest.raises(InputError, match="mixed"):
        CattaneoMindlin(nu=0.5)  # the displacement element's λ is infinite
    with pytest.raises(InputError, match="mixed"):
        CattaneoMindlin(nu=0.0, mixed=True)  # p = −λ tr ε needs λ > 0
    assert EXACT.nu == 0.5 and EXACT.mixed and EXACT.modulus == pytest.approx(4 / 3)


def test_the_l1_distance_weighs_the_points_by_the_facets_they_span():
    from fingertip_dolfinx.studies.problems.mindlin import l1_distance

    # a semi-ellipse 10 % off on x > 0 only, and 0.05 where it is 0 on 1 < x < 1.2: exactly
    # (0.1 π/4 + 0.05 × 0.2)/(π/2). The points crowd on x < 0 (fine facets there): a plain
    # mean over the points within |x| < 1 weighs the error by 1/11 and gives 0.009
    x = np.concatenate([np.linspace(-1.5, 0.0, 3001), np.linspace(0.0, 1.5, 301)])
    theory = np.sqrt(np.clip(1 - x**2, 0, None))
    values = theory * np.where(x > 0, 1.1, 1.0) + np.where((x > 1) & (x < 1.2), 0.05, 0.0)
    exact = (0.1 * np.pi / 4 + 0.05 * 0.2) / (np.pi / 2)
    assert l1_distance(x, values, theory) == pytest.approx(exact, rel=1e-2)


def _hertz_forces(friction_mu: float | None) -> tuple[float, np.ndarray]:
    """The Hertz half block pressed in 2 steps: the cylinder's force and the displacement; with
    `friction_mu`, its obstacle has an x_tip Constant and a CoulombFriction of that μ is added."""
    hertz = Hertz()
    domain, tags = hertz.mesh(hertz.a_target / 2.5, MPI.COMM_SELF)
    V = fem.functionspace(domain, ("Lagrange", 2, (2,)))
    u, v = fem.Function(V), ufl.TestFunction(V)
    P = hertz.stress(u)

    x_tip = None if friction_mu is None else 0.0
    obstacle = Obstacle.at(domain, Cylinder(radius=hertz.R), y_tip=0.0, x_tip=x_tip)
    ds = ufl.Measure("ds", domain, subdomain_data=tags)
    contact = NitscheContact(u, P, ds(hertz.BOTTOM), [obstacle], modulus=hertz.modulus)
    residual = ufl.inner(P, ufl.grad(v)) * ufl.dx + contact.residual(v)
    if friction_mu is not None:
        residual += CoulombFriction(contact, friction_mu).residual(v)
    top = fem.locate_dofs_topological(V, 1, tags.find(hertz.TOP))
    side = fem.locate_dofs_topological(V.sub(0), 1, tags.find(hertz.SYMMETRY))
    bcs = [fem.dirichletbc(np.zeros(2), top, V), fem.dirichletbc(0.0, side, V.sub(0))]
    problem = newton_problem(residual, u, bcs, f"unchanged_{friction_mu}_".replace(".", "_"))
    for k in (1, 2):
        obstacle.y_tip.value = hertz.depth * k / 2
        problem.solve()
        assert problem.solver.getConvergedReason() > 0
    return float(contact.forces()[0]), u.x.array.copy()


def test_zero_friction_and_a_resting_tangential_constant_change_nothing_to_the_last_digit():
    force, u = _hertz_forces(None)
    force_mu0, u_mu0 = _hertz_forces(0.0)
    assert force_mu0 == force
    assert np.array_equal(u_mu0, u)


def test_stick_halfwidth_interpolates_the_zero_crossings():
    x = np.linspace(-2.0, 2.0, 9)
    margin = 1.0 - np.abs(x)  # sticks on |x| < 1
    assert stick_halfwidth(x, margin) == pytest.approx(1.0)
    assert stick_halfwidth(x, -np.ones_like(x)) == 0.0


@pytest.mark.parametrize("mu, count", [(-0.1, 1), (float("nan"), 1), ((0.5, 0.5), 1), (True, 1)])
def test_bad_friction_coefficients_are_refused(mu, count):
    with pytest.raises(InputError, match="friction"):
        friction_coefficients(mu, count)


def test_cattaneo_mindlin_traction_carries_the_tangential_force():
    # ∫ q dx = μP − μP c²/a² = Q: the closed form's two ellipses are consistent with c(Q).
    P, Q = 1e-3, 0.6 * MINDLIN.mu * 1e-3
    a, _ = MINDLIN.theory(P)
    x = np.linspace(-a, a, 200001)
    q = MINDLIN.traction_theory(x, P, Q)
    assert np.trapezoid(q, x) == pytest.approx(Q, rel=1e-4)
    c = MINDLIN.stick_theory(P, Q)
    outside = np.abs(x) > c  # the slip annulus carries μp
    _, p0 = MINDLIN.theory(P)
    p = p0 * np.sqrt(np.clip(1 - (x / a) ** 2, 0, None))
    assert np.allclose(q[outside], MINDLIN.mu * p[outside], atol=1e-12)


def test_a_tangential_path_presses_as_its_normal_protocol_and_moves_along_x():
    normal = RampHold(depth=0.5, ramp_time=0.5, end_time=1.5)
    path = TangentialPath(normal, PiecewiseLinear((0.0, 0.5, 1.2), (0.0, 0.0, 1.0)))
    assert isinstance(path, LoadHistory)
    for t in (0.0, 0.25, 0.5, 1.0, 1.5):
        assert path(t) == normal(t)
    assert path.end_time == 1.5 and path.deepest == 0.5
    assert path.tangential_at(0.5) == 0.0 and path.tangential_at(0.85) == pytest.approx(0.5)
    assert path.tangential_at(1.5) == 1.0  # held after its last point
    assert path.breakpoints == (0.0, 0.5, 1.2, 1.5)  # the stepper lands on both parts' kinks
    with pytest.raises(InputError, match="after the protocol's end"):
        TangentialPath(normal, PiecewiseLinear((0.0, 2.0), (0.0, 1.0)))


def test_a_tangential_path_has_a_direction_across_or_along_the_finger():
    normal = RampHold(depth=0.5, ramp_time=0.5, end_time=1.5)
    drag = PiecewiseLinear((0.0, 0.5, 1.5), (0.0, 0.0, 2.0))
    along_x = TangentialPath(normal, drag)  # the default: +x, as every 2D path
    assert along_x.direction == (1.0, 0.0) and along_x.displacement_at(1.0) == (1.0, 0.0)
    along_z = TangentialPath(normal, drag, direction=(0.0, 3.0))  # only the direction counts
    assert along_z.direction == (0.0, 1.0) and along_z.displacement_at(1.5) == (0.0, 2.0)
    assert along_z.tangential_at(1.0) == 1.0  # s(t): the distance along the direction
    oblique = TangentialPath(normal, drag, direction=(1.0, -1.0))
    assert oblique.displacement_at(1.5) == pytest.approx((2 ** 0.5, -(2 ** 0.5)), abs=1e-15)
    for bad in ((0.0, 0.0), (1.0, 0.0, 0.0), (float("nan"), 1.0), (True, 0.0), "z"):
        with pytest.raises(InputError, match="direction"):
            TangentialPath(normal, drag, direction=bad)


def test_a_direction_along_z_reads_back_and_is_refused_in_2d():
    from fingertip_dolfinx.loading import check_tangential_path, history_from_dict
    from fingertip_dolfinx.scene import _protocol_record

    table = {"kind": "ramp-hold", "depth": 0.5, "ramp_time": 0.5, "end_time": 1.5,
             "tangential": {"times": [0.0, 0.5, 1.5], "values": [0.0, 0.0, 1.5],
                            "direction": [0, 2]}}
    path = history_from_dict(table)
    assert path.direction == (0.0, 1.0) and path.displacement_at(1.0) == (0.0, 0.75)
    assert history_from_dict(_protocol_record(path)) == path  # summary.json reads back
    with pytest.raises(InputError, match="direction"):
        history_from_dict(table | {"tangential": table["tangential"] | {"direction": [0, 0]}})
    with pytest.raises(InputError, match="section is 2D"):
        check_tangential_path(path, 2, half=False)
    check_tangential_path(path, 3, half=True)  # the mirror symmetry holds for a drag along z
    # a path along x has the record it had before the key: its runs still resume
    del table["tangential"]["direction"]
    assert "direction" not in _protocol_record(history_from_dict(table))["tangential"]


def _rigid_slide(axis: int, moved: bool) -> tuple[np.ndarray, np.ndarray]:
    """A unit cube pressed 0.01 mm into a plate (penalty contact, μ = 0.5), then translated
    rigidly by 0.1 mm along `axis` (0: x, 2: z) without a solve, the plate with it if `moved`:
    (the indenter's total force, the pressure's share, the contact and stick areas), from
    `CoulombFriction`."""
    from dolfinx import mesh as dmesh

    from fingertip_dolfinx.geometry.indenters import Plate

    domain = dmesh.create_unit_cube(MPI.COMM_SELF, 2, 2, 2)
    V = fem.functionspace(domain, ("Lagrange", 1, (3,)))
    u = fem.Function(V)
    obstacle = Obstacle.at(domain, Plate(), y_tip=0.01, x_tip=0.0, z_tip=0.0)
    contact = NitscheContact(u, ufl.grad(u), ufl.ds, [obstacle], modulus=1.0, method="penalty")
    friction = CoulombFriction(contact, 0.5)  # its start: the pressed state, u = 0
    u.x.array.reshape(-1, 3)[:, axis] = 0.1
    if moved:
        (obstacle.x_tip if axis == 0 else obstacle.z_tip).value = 0.1
    return friction.forces()[0], friction.pressure_forces()[0], friction.areas()


@pytest.mark.parametrize("axis", [0, 2])
def test_friction_in_3d_follows_the_indenter_along_x_and_z(axis):
    # The body and the plate moved together: no slip, no friction force (before z_tip existed,
    # a move along z was slip against a plate that stayed, and took μ times the load).
    force, pressure, areas = _rigid_slide(axis, moved=True)
    assert np.allclose(force, pressure, rtol=0, atol=1e-14 * abs(pressure[1]))
    assert areas == pytest.approx((1.0, 1.0), rel=1e-12)  # the cube's bottom face sticks
    # The body slid over a plate that stays: gross slip against the slip, μ times the load
    force, pressure, areas = _rigid_slide(axis, moved=False)
    assert areas == pytest.approx((1.0, 0.0), abs=1e-12)  # all of it in contact slips
    friction = force - pressure
    assert pressure[1] > 0 and friction[axis] == pytest.approx(-0.5 * pressure[1], rel=1e-12)
    assert abs(friction[2 - axis]) < 1e-14 * pressure[1] and abs(friction[1]) < 1e-14


def shear_run(mu: float) -> list:
    """A plate pressed 0.5 mm into the coarse 2D pulp in 0.5 s, then dragged 1 mm along x in
    1 s (the stepper's own steps of <= 0.1 s)."""
    import dataclasses

    from fingertip_dolfinx.geometry.indenters import load_indenter
    from fingertip_dolfinx.geometry.mesh import build_mesh
    from fingertip_dolfinx.geometry.section import load_section
    from fingertip_dolfinx.problem import FingertipProblem
    from fingertip_dolfinx.stepping import StepOptions, TimeStepper

    section = load_section("male-index")
    section = dataclasses.replace(section, mesh=dataclasses.replace(
        section.mesh, min_size=0.25, max_size=1.5, bone_size=2.0, refine_half_width=4.0,
        refine_depth=1.0))
    history = TangentialPath(RampHold(depth=0.5, ramp_time=0.5, end_time=1.5),
                             PiecewiseLinear((0.0, 0.5, 1.5), (0.0, 0.0, 1.0)))
    problem = FingertipProblem(build_mesh(section, MPI.COMM_WORLD), [load_indenter("plate")],
                               history, friction=mu)
    stepper = TimeStepper(problem, StepOptions(dt_initial=0.1, dt_max=0.1),
                          prefix=f"shear_{mu}_".replace(".", "_"))
    reports = stepper.run(history, history.end_time)
    stepper.close()
    return reports


@pytest.mark.slow
def test_a_plate_dragged_over_the_pulp_sticks_partly_then_slips_at_mu_times_the_load():
    mu = 0.5
    reports = shear_run(mu)
    ratios = np.array([abs(r.diagnostics["tangential_force_N_per_mm"])
                       / (mu * abs(r.diagnostics["force_N_per_mm"])) for r in reports])
    assert np.all(ratios <= 1 + 1e-6), ratios.max()  # Coulomb's bound at every step
    assert np.any((ratios > 0.1) & (ratios < 0.9))  # a partial-stick phase before gross slip
    assert ratios[-1] == pytest.approx(1.0, abs=0.02)  # gross slip at the end
    for r in reports:  # the friction's y-share counted: the support balances the indenter
        d = r.diagnostics
        assert d["force_N_per_mm"] == pytest.approx(d["reaction_N_per_mm"], rel=1e-5)


def test_friction_is_indenter_data_and_the_shear_scene_drags_a_plate():
    from fingertip_dolfinx.geometry.indenters import make_indenter
    from fingertip_dolfinx.loading import history_from_dict
    from fingertip_dolfinx.scene import load_scene, scene_record

    with pytest.raises(InputError, match="friction"):
        make_indenter({"shape": "plate", "friction": -0.2})
    scene = load_scene("shear")
    assert scene.indenters[0].friction == 0.5
    record = scene_record(scene)
    assert record["indenters"][0]["friction"] == 0.5  # summary.json records μ
    back = history_from_dict(dict(record["protocol"]))  # the record reads back
    assert back.tangential_at(1.0) == scene.history.tangential_at(1.0) == 0.5
    # a frictionless scene's record is as before: its runs still resume
    assert "friction" not in scene_record(load_scene("1pt"))["indenters"][0]


def test_the_step_record_names_tangent_start_only_where_it_is_on():
    from fingertip_dolfinx.scene import load_scene, scene_record

    assert scene_record(load_scene("shear"))["steps"]["tangent_start"] is True
    # a scene without it has the record it had before the option: its runs still resume
    assert "tangent_start" not in scene_record(load_scene("1pt"))["steps"]


def test_a_resume_with_another_tangential_path_is_refused(tmp_path):
    from fingertip_dolfinx.outputs import check_resume
    from fingertip_dolfinx.scene import load_scene, scene_record

    old = scene_record(load_scene("shear"))
    new = scene_record(load_scene("shear", {"protocol": {"tangential": {
        "times": [0.0, 0.5, 1.5], "values": [0.0, 0.0, 2.0]}}}))
    with pytest.raises(InputError, match="tangential"):
        check_resume(old, new, 1.0, tmp_path)
    check_resume(old, new, 0.5, tmp_path)  # the same path up to 0.5 s: allowed


def test_a_half_model_is_not_dragged_across_its_symmetry_plane():
    from types import SimpleNamespace

    from fingertip_dolfinx.problem import check_tangential

    path = TangentialPath(RampHold(depth=0.5, ramp_time=0.5, end_time=1.5),
                          PiecewiseLinear((0.0, 0.5, 1.5), (0.0, 0.0, 1.0)))
    mesh3d = SimpleNamespace(geometry=SimpleNamespace(dim=3))
    half = SimpleNamespace(names={"symmetry": 7, "pulp_surface": 1}, mesh=mesh3d)
    with pytest.raises(InputError, match="half model"):
        check_tangential(half, path)
    check_tangential(half, path.normal)  # pressing a half model stays as it was
    section = SimpleNamespace(geometry=SimpleNamespace(dim=2))
    check_tangential(SimpleNamespace(names={"pulp_surface": 1}, mesh=section), path)  # 2D
    # along the finger the mirror symmetry holds: the half model is exact for the drag
    check_tangential(half, dataclasses.replace(path, direction=(0.0, 1.0)))
    with pytest.raises(InputError, match="half model"):  # a part along x breaks it
        check_tangential(half, dataclasses.replace(path, direction=(1.0, 1.0)))


#: A longer drag: Q/(μP) ≈ 0.22, 0.44, 0.66, 0.87 (partial stick), then gross slip from ~1e-3 mm
#: (measured), two steps past it in steady sliding.
LONG_SHIFTS = (2e-4, 4e-4, 6e-4, 8e-4, 1.2e-3, 1.6e-3, 2.0e-3)


@cache
def dragged_far() -> tuple[dict, ...]:
    return tuple(drag(MINDLIN, MINDLIN.a_target / 2.5, LONG_SHIFTS, prefix="drag_far_"))


def test_the_stick_flag_is_the_margin_and_the_stick_zone_shrinks_as_q_grows():
    rows = dragged_far()[2:]  # the drag steps
    for r in rows:
        assert np.array_equal(r["state"] == 2, r["margin"] > 0)  # the flag is the margin's sign
    ratios = [r["ratio"] for r in rows]
    assert np.all(np.diff(ratios) >= -1e-6), ratios  # Q grows monotonically to μP
    # Cattaneo–Mindlin: the stick zone shrinks from the edges inward as Q grows, every point
    # that sticks under a larger Q stuck under every smaller one (a point once slipping keeps
    # slipping under a monotonic load); it is empty in gross slip
    sticks = [r["state"] == 2 for r in rows]
    for before, after in zip(sticks, sticks[1:]):
        assert not np.any(after & ~before), np.flatnonzero(after & ~before)
    counts = [int(s.sum()) for s in sticks]
    assert all(a > b for a, b in zip(counts[:4], counts[1:4])), counts  # strictly, Q < μP
    assert counts[-1] == 0


def test_steady_sliding_dissipates_mu_times_the_load_times_the_slip_distance():
    rows = dragged_far()
    previous = [0.0] + [r["shift"] for r in rows[:-1]]
    steps = [(r, r["shift"] - s) for r, s in zip(rows, previous)]
    for r, ds in steps[2:]:
        # partial stick dissipates in the slip annulus only: more than nothing, less than sliding
        if r["c"] > 0:
            assert 0 < r["dissipated"] < MINDLIN.mu * r["P"] * ds, r
    # the steps that start in gross slip (the one to 1.2e-3 mm still starts in partial stick)
    sliding = [(r, ds) for r, ds in steps if r["shift"] > 1.2e-3 + 1e-12]
    assert len(sliding) == 2 and all(r["c"] == 0.0 for r, _ in sliding)
    dissipated = sum(r["dissipated"] for r, _ in sliding)
    expected = sum(MINDLIN.mu * r["P"] * ds for r, ds in sliding)
    # In gross slip every contact point slips by the drag less the change of the surface's own
    # displacement under the moving contact, a tangential strain of order p0/E* ~ a/2R = 1e-2
    # whose pressure-weighted mean vanishes to first order by the contact's symmetry, and
    # |f| = μp with Q/(μP) − 1 of order (a/R)² = 4e-4 (the tilt of the surface): 1e-3
    # (measured 1e-4).
    assert dissipated == pytest.approx(expected, rel=1e-3)


@pytest.mark.slow
def test_the_shear_run_writes_stick_slip_surfaces_and_their_figure(tmp_path):
    from fingertip_dolfinx.outputs import (
        FRICTION_SURFACE_COLUMNS,
        STICK_SLIP_COLUMNS,
        SURFACE_COLUMNS,
        read_csv,
    )
    from fingertip_dolfinx.runner import run_scene
    from fingertip_dolfinx.scene import load_scene

    run_scene(load_scene("shear"), tmp_path, progress=False)
    surface = read_csv(tmp_path / "surface_profile.csv")
    assert tuple(surface) == SURFACE_COLUMNS + FRICTION_SURFACE_COLUMNS
    s = read_csv(tmp_path / "stick_slip.csv")
    assert tuple(s) == STICK_SLIP_COLUMNS
    history = read_csv(tmp_path / "history.csv")
    assert np.array_equal(np.unique(s["time_s"]), history["time_s"])  # a map row every step
    assert np.array_equal(s["contact_state"] == 2, s["stick_margin_MPa"] > 0)
    assert np.all(s["pressure_MPa"][s["contact_state"] == 0] == 0)
    stick = [np.sum(s["contact_state"][s["time_s"] == t] == 2) for t in history["time_s"]]
    drag = history["tangential_displacement_mm"] > 0
    assert max(stick) > 10 and stick[-1] <= 1  # a stick zone; gross slip at the end
    # |q| <= μp at every node, to the rounding of the written values
    assert np.all(np.abs(s["tangential_traction_MPa"]) <= 0.5 * s["pressure_MPa"] * (1 + 1e-9))
    assert drag[-1] and (tmp_path / "friction.png").exists()


#: The shear scene shortened: pressed 0.5 mm, dragged 0.2 mm (partial stick), no pictures.
SHORT_SHEAR = ["protocol.end_time=0.7", "output.times=[0.5, 0.7]", "output.pictures=false",
               "protocol.tangential={times = [0.0, 0.5, 0.7], values = [0.0, 0.0, 0.2]}",
               "steps.dt_initial=0.25", "steps.dt_max=0.25"]


@pytest.mark.mpi
def test_stick_slip_surfaces_are_the_same_on_two_ranks_as_on_one(world_and_alone):
    """The friction's surface sampling is collective: every rank joins it at output times."""
    from fingertip_dolfinx.outputs import read_csv
    from fingertip_dolfinx.scene import load_scene

    shared, alone = world_and_alone(load_scene("shear", SHORT_SHEAR))
    for name in ("stick_slip.csv", "surface_profile.csv"):
        a, b = read_csv(shared / name), read_csv(alone / name)
        assert tuple(a) == tuple(b) and len(a["x_mm"]) == len(b["x_mm"]) > 0
        np.testing.assert_array_equal(a["contact_state"], b["contact_state"])
        scale = np.max(b["pressure_MPa"])  # the sums' order differs: rounding only
        np.testing.assert_allclose(a["pressure_MPa"], b["pressure_MPa"], atol=1e-8 * scale)


def test_the_tip_check_follows_an_indenter_moved_along_x():
    """u = 0, the round bar pressed 0.05 mm past first touch at x = 0, then moved 3 mm along x:
    there the undeformed pulp lies ~0.5 mm lower (the section's radius ~9 mm: 3²/18), so the
    tip is clear of the body. The check read the surface at the bar's starting x and reported
    the 0.05 mm it had there as penetration (the slide scene's history said 0.2 mm)."""
    import dataclasses
    import warnings

    from fingertip_dolfinx.geometry.indenters import load_indenter
    from fingertip_dolfinx.geometry.mesh import build_mesh
    from fingertip_dolfinx.geometry.section import load_section
    from fingertip_dolfinx.physics.contact import TipResolutionWarning
    from fingertip_dolfinx.problem import FingertipProblem

    section = load_section("male-index")
    section = dataclasses.replace(section, mesh=dataclasses.replace(
        section.mesh, min_size=0.25, max_size=1.5, bone_size=2.0, refine_half_width=4.0))
    path = TangentialPath(RampHold(depth=0.05, ramp_time=0.5, end_time=1.0),
                          PiecewiseLinear((0.0, 0.5, 1.0), (0.0, 0.0, 3.0)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TipResolutionWarning)
        problem = FingertipProblem(build_mesh(section, MPI.COMM_WORLD), [load_indenter("bar")],
                                   path, friction=0.5)
        problem.set_time(0.5)  # pressed, not moved: the tip 0.05 mm in
        assert problem.tip_penetration() == pytest.approx(0.05, abs=1e-9)
        problem.set_time(1.0)  # moved 3 mm: clear
        assert problem.contact.max_penetration() == 0.0
        assert problem.tip_penetration() == 0.0


def test_pictures_draw_an_indenter_moved_along_x_where_it_is():
    """The field pictures drew a slid bar at its starting x, beside the dent it makes."""
    from types import SimpleNamespace

    from fingertip_dolfinx.geometry.indenters import Bar
    from fingertip_dolfinx.plotting.pictures import placed_indenters

    bar = Bar(width=1.0, centre_x=-1.0)
    moved = SimpleNamespace(indenter=bar, y_tip=SimpleNamespace(value=-6.5),
                            x_tip=SimpleNamespace(value=1.5))
    still = SimpleNamespace(indenter=bar, y_tip=SimpleNamespace(value=-6.5), x_tip=None)
    (shape, y), (same, _) = placed_indenters([moved, still])
    assert shape.centre_x == pytest.approx(0.5) and y == -6.5 and same is bar
    # the drawn shape is the moved one: its tip at x = 0.5 touches y_tip
    phi = shape.signed_distance_np(np.array([[0.5, -6.5], [-1.0, -6.5]]), -6.5)[0]
    assert phi[0] == pytest.approx(0.0, abs=1e-12) and phi[1] > 1.0


def press_then_drag(options):
    """The coarse shear scene's press (5 steps of 0.1 s to 0.5 mm) and its first drag step
    (0.1 mm in 0.1 s), with the step options `options`; the reports."""
    from fingertip_dolfinx.geometry.mesh import build_mesh
    from fingertip_dolfinx.problem import FingertipProblem
    from fingertip_dolfinx.scene import load_scene
    from fingertip_dolfinx.stepping import TimeStepper

    scene = load_scene("shear")
    problem = FingertipProblem(build_mesh(scene.section, MPI.COMM_WORLD), scene.indenters,
                               scene.history, friction=[i.friction for i in scene.indenters])
    stepper = TimeStepper(problem, options, scene.petsc_options, prefix="drag_start_")
    try:
        return stepper.run(scene.history, 0.6)
    finally:
        stepper.close()


@pytest.mark.slow
def test_the_tangent_predictor_takes_the_first_drag_step_whole():
    # From the pressed state with the plate moved 0.1 mm, Newton's first linearisation puts
    # every contact point on the slip branch (the trial traction γ_τ Δx is far outside the
    # cone) and the plain start fails; the tangent predictor, linearised at the accepted
    # (sticking) state, moves the skin with the plate and the step converges uncut.
    from fingertip_dolfinx.errors import FingertipError
    from fingertip_dolfinx.stepping import StepOptions

    steps = dict(dt_initial=0.1, dt_max=0.1, max_cuts=1)  # the press's last step cuts once
    with pytest.raises(FingertipError, match="from t = 0.5 s"):
        press_then_drag(StepOptions(**steps))
    reports = press_then_drag(StepOptions(**steps, tangent_start=True))
    first = next(r for r in reports if r.time > 0.5 + 1e-9)  # the step the controller planned
    assert first.cuts == 0 and first.dt >= 0.05
    d = first.diagnostics
    ratio = abs(d["tangential_force_N_per_mm"]) / (0.5 * abs(d["force_N_per_mm"]))
    assert 0.05 < ratio < 0.9  # sticking at the centre: 0.075 mm of drag carries ~0.09 μFn


@pytest.mark.slow
def test_the_jacobian_is_the_residuals_derivative_in_partial_stick(directional_error):
    """The shear scene dragged 0.2 mm (partial stick), then its next step's tangent predictor
    (contact points sticking and slipping): the assembled Jacobian times the Newton direction
    d equals the central difference of the residual along d to round-off, as the contact's
    does (test_line_load.py). The tangent is UFL's derivative of the residual; this guards
    the conditionals and clippings of Coulomb's projection, where a derivative taken on the
    wrong branch would leave an error that does not fall with ε."""
    import dolfinx.fem.petsc

    from fingertip_dolfinx.geometry.mesh import build_mesh
    from fingertip_dolfinx.problem import FingertipProblem
    from fingertip_dolfinx.scene import load_scene
    from fingertip_dolfinx.stepping import TimeStepper

    scene = load_scene("shear")
    problem = FingertipProblem(build_mesh(scene.section, MPI.COMM_WORLD), scene.indenters,
                               scene.history, friction=[i.friction for i in scene.indenters])
    stepper = TimeStepper(problem, scene.steps, scene.petsc_options, prefix="fd_friction_")
    stepper.run(scene.history, 0.7)
    problem.dt.value = 0.05
    problem.set_time(0.75)
    stepper.tangent.predict(problem, 0.7, 0.75)
    snes, x = stepper.snes, stepper.nonlinear.x
    dolfinx.fem.petsc.assign(problem.unknowns, x)
    (F, _), (J, P, _) = snes.getFunction(), snes.getJacobian()
    snes.computeFunction(x, F)
    snes.computeJacobian(x, J, P)
    error = directional_error(snes, x)
    try:
        assert error(1e-2) < 1e-6  # measured 1.5e-8 at 0.8 s; round-off grows below ε = 1e-2
    finally:
        stepper.close()


def check_shear_3d(history: dict, mu: float) -> None:
    """The shear-3d scene's history: Coulomb's bound at every step, a partial-stick phase of the
    drag, then gross slip (the issue's checks of the 2D shear scene, the tangential force
    |(F_x, F_z)| of the half model), the stick area going from the contact's to none."""
    ft = np.hypot(history["tangential_x_force_N"], history["tangential_z_force_N"])
    ratio = ft / (mu * np.abs(history["force_N"]))
    # Under the flat plate the pressure is all along y and |f| <= μp holds at every surface
    # quadrature point by construction (the projection), so its integral holds to rounding.
    assert np.all(ratio <= 1 + 1e-9), ratio.max()
    drag = history["tangential_z_displacement_mm"] > 0
    assert np.any(drag & (ratio > 0.1) & (ratio < 0.9)), ratio  # partial stick
    assert ratio[-1] == pytest.approx(1.0, abs=0.02)  # gross slip at the end
    fraction = history["stick_area_mm2"] / history["contact_area_mm2"]
    assert fraction[~drag][-1] > 0.9 and fraction[-1] == 0.0, fraction
    # the friction's y-share counted: the support balances the indenter
    assert np.allclose(history["force_N"], history["reaction_N"], rtol=1e-5)


@pytest.mark.slow
def test_the_shear_3d_scene_sticks_partly_then_slips_at_mu_times_the_load(tmp_path):
    from fingertip_dolfinx.outputs import read_csv
    from fingertip_dolfinx.runner import run_scene
    from fingertip_dolfinx.scene import load_scene

    scene = load_scene("shear-3d", ["output.pictures=false"])
    run_scene(scene, tmp_path, progress=False)
    check_shear_3d(read_csv(tmp_path / "history.csv"), scene.indenters[0].friction)
