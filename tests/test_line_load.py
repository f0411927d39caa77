"""The paper's line load: the 25 µm-tip wedge pushed 1 mm into the pulp in a 1 s ramp.

The tip must not pierce the body (penetration below 1 % of the indentation at every step),
the indenter force must balance the support reaction, and the force must rise over the ramp.
A mesh too coarse for the tip must not pass silently (TipResolutionWarning).
"""

import dataclasses
import warnings

import dolfinx.fem.petsc
import numpy as np
import pytest
from mpi4py import MPI

from fingertip_dolfinx.geometry.indenters import load_indenter, make_indenter
from fingertip_dolfinx.geometry.mesh import build_mesh
from fingertip_dolfinx.geometry.section import load_section
from fingertip_dolfinx.loading import RampHold
from fingertip_dolfinx.model import ModelOptions
from fingertip_dolfinx.outputs import read_csv
from fingertip_dolfinx.physics.contact import TipResolutionWarning
from fingertip_dolfinx.problem import FingertipProblem
from fingertip_dolfinx.runner import run_scene
from fingertip_dolfinx.scene import load_scene

#: Coarse away from the load, 20 µm elements (< the 25 µm tip radius) within 0.25 mm of the tip.
RESOLVED = dict(min_size=0.1, max_size=0.8, bone_size=1.5, refine_half_width=1.5,
                refine_depth=1.0, tips=(0.0,), tip_size=0.02, tip_zone=0.25)
#: The same without the tip refinement: surface elements of four tip radii under the tip.
COARSE = dict(RESOLVED, tips=())


def _problem(mesh_options, gamma0=100.0, contact="penalty", centre_x=0.0, indenter="wedge"):
    section = load_section("male-index")
    section = dataclasses.replace(section, mesh=dataclasses.replace(section.mesh, **mesh_options))
    history = RampHold(1.0, 1.0, 1.0)
    # The line-load scene's contact: penalty, γ0 = 100, smoothed over a 0.1 µm gap
    # (data/scenes/line-load.toml says why).
    options = ModelOptions(subcutaneous="biphasic", contact=contact, contact_gamma0=gamma0,
                           contact_smoothing=1e-4)
    shape = (make_indenter(indenter) if isinstance(indenter, dict) else
             dataclasses.replace(load_indenter(indenter), centre_x=centre_x))
    problem = FingertipProblem(build_mesh(section), [shape], history, options=options)
    return problem, history


def test_guard_fires_on_a_mesh_too_coarse_for_the_tip():
    with pytest.warns(TipResolutionWarning, match=r"tips = \[0\] with tip_size <= 0.05 mm"):
        problem, _ = _problem(COARSE)
    assert problem.tip_mesh_sizes[0] > 0.05


def test_tip_refinement_puts_fine_elements_under_the_tip_only():
    with warnings.catch_warnings():
        warnings.simplefilter("error", TipResolutionWarning)
        problem, _ = _problem(RESOLVED)
    assert problem.tip_mesh_sizes[0] <= 0.02 * 1.3  # gmsh meets the size field to ~30 %
    # The disc is small: the number of cells grows by far less than a fine zone would need.
    coarse = build_mesh(dataclasses.replace(
        load_section("male-index"),
        mesh=dataclasses.replace(load_section("male-index").mesh, **COARSE)))
    assert problem.fmesh.report.num_cells < 1.5 * coarse.report.num_cells


def test_tip_penetration_is_measured_exactly_on_the_undeformed_surface():
    """With u = 0, moving the wedge to depth d above first touch puts its tip d inside the
    body (the pulp's lowest point is at y = -7 mm, a mesh vertex). The guard must report it."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TipResolutionWarning)
        problem, _ = _problem(RESOLVED)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TipResolutionWarning)
        for t in (0.05, 0.3):
            problem.set_time(t)
            assert problem.tip_penetration() == pytest.approx(t, abs=1e-9)
    problem.set_time(0.0)
    assert problem.tip_penetration() == pytest.approx(0.0, abs=1e-9)


def test_a_bar_with_a_gap_is_not_pierced_where_its_gap_is():
    """A 4 mm flat bar with a 2 mm gap (ridges 1 mm wide at x = ±1.5) at first touch, u = 0:
    it touches the curved pulp at the gap's edges, and the pulp's lowest point (x = 0) lies
    inside the gap, above the bar's top. Nothing pierces: the tip check reads the ridges'
    tops, not the gap's middle (there it reported the pulp's rise over the gap's half-width
    as penetration, ~0.06 mm on this section)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TipResolutionWarning)
        problem, _ = _problem(COARSE, indenter={"shape": "grating", "width": 1.0,
                                                "period": 3.0, "ridges": 2,
                                                "corner_radius": 0.1})
        problem.set_time(0.0)
        assert problem.tip_penetration() == pytest.approx(0.0, abs=1e-9)
        assert problem.contact.max_penetration() == pytest.approx(0.0, abs=1e-9)


def test_a_tip_as_deep_as_the_surface_nodes_is_not_a_resolution_problem():
    """The 1pt scene's round bar (tip radius 0.5 mm) on the vertex at x = 0, u = 0, moved
    10 µm in: the tip is 10 µm inside, and so is the vertex under it (its normal there is
    vertical). Every contact law lets the nodes overlap the indenter a little (penalty p/γ,
    Nitsche as far as t_n − γg needs: 0.39 µm of tip for 0.38 µm of nodes at t = 0.05 s of the
    1pt scene on a 0.4 mm mesh); that overlap is the law's, reported as max_penetration, not
    a tip between the nodes: no warning, although 10 µm is ten times the 1 µm tolerance."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TipResolutionWarning)
        problem, _ = _problem(COARSE, indenter="bar")
    problem.set_time(0.01)
    assert problem.contact.max_penetration() == pytest.approx(0.01, abs=1e-9)
    with warnings.catch_warnings():
        warnings.simplefilter("error", TipResolutionWarning)
        assert problem.tip_penetration() == pytest.approx(0.01, abs=1e-9)


def test_a_sharp_tip_between_the_surface_nodes_warns():
    """The 25 µm wedge a quarter of a surface element off the vertex at x = 0 of the coarse
    mesh (0.1 mm elements, P2: nodes every 0.05 mm): its flanks reach the nodes on either side
    only when the tip is already inside the chord between them, by about the flank's rise over
    a quarter element (tens of µm). The tip is deeper than the nodes by far more than the
    1 µm tolerance: it slipped between them, which the warning must say."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TipResolutionWarning)
        h = _problem(COARSE)[0].tip_mesh_sizes[0]
        problem, _ = _problem(COARSE, centre_x=h / 4)
    problem.set_time(0.0)  # first touch: the flank meets a node
    nodes = problem.contact.max_penetration()
    with pytest.warns(TipResolutionWarning, match="deeper than the surface nodes"):
        depth = problem.tip_penetration()
    assert depth - nodes > 1e-3


@pytest.fixture(scope="module")
def line_load(tmp_path_factory):
    """The line-load scene, whole protocol (1 mm in 1 s, hold to 100 s), on a coarse mesh with
    the scene's tip refinement and contact settings."""
    out = tmp_path_factory.mktemp("line-load")
    sizes = {k: v for k, v in RESOLVED.items() if k != "tips"}
    overrides = [f"section.mesh.{k}={v}" for k, v in sizes.items()] + ["output.profile_points=121"]
    with warnings.catch_warnings():
        warnings.simplefilter("error", TipResolutionWarning)  # a pierced tip fails the test
        summary = run_scene(load_scene("line-load", overrides), out, progress=False,
                            comm=MPI.COMM_SELF)
    return out, summary


def test_line_load_tip_stays_outside_and_force_balances(line_load):
    out, summary = line_load
    h = read_csv(out / "history.csv")
    assert summary["converged"] and h["time_s"][-1] == pytest.approx(100.0)
    depth = h["indenter_displacement_mm"]
    assert np.all(h["max_penetration_mm"] < 0.01 * depth)
    # Force and reaction differ by a sum of the residual's entries left at Newton's absolute
    # tolerance (the scene's snes_atol), at most sqrt(#dofs) times it.
    atol = load_scene("line-load").petsc_options["snes_atol"]
    assert np.all(np.abs(h["force_N_per_mm"] - h["reaction_N_per_mm"])
                  <= np.sqrt(summary["dofs"]) * atol)


def test_line_load_force_rises_then_relaxes_mostly_by_20s(line_load):
    """MODEL.md §4 / the paper's Fig. 3: the force rises over the ramp, then relaxes, most of
    the decay within 1-20 s."""
    h = read_csv(line_load[0] / "history.csv")
    t, force = h["time_s"], h["force_N_per_mm"]
    ramp, hold = t <= 1.0 + 1e-9, t >= 1.0 - 1e-9
    assert np.all(np.diff(force[ramp]) > 0)
    assert np.all(np.diff(force[hold]) < 0)
    f1, f20, f100 = (np.interp(s, t, force) for s in (1.0, 20.0, 100.0))
    assert f100 < f1
    assert (f1 - f20) > 0.75 * (f1 - f100)


def test_line_load_deflection_changes_little_during_the_hold(line_load):
    """The paper's Fig. 2: the surface deflection profile at 100 s is close to that at 1 s
    (here: everywhere within 10 % of the 1 mm indentation), the peak under the wedge."""
    s = read_csv(line_load[0] / "surface_profile.csv")
    profiles = {}
    for time in (1.0, 100.0):
        rows = np.isclose(s["time_s"], time)
        order = np.argsort(s["x_mm"][rows])
        profiles[time] = (s["x_mm"][rows][order], s["deflection_mm"][rows][order])
    (x, w1), (_, w100) = profiles[1.0], profiles[100.0]
    assert np.max(np.abs(w100 - w1)) < 0.1
    assert abs(x[np.argmax(w1)]) < 0.1 and np.max(w1) == pytest.approx(1.0, abs=0.05)


def _mid_ramp(tmp_path, t_stop: float):
    """The `line-load-1pct` scene stepped to `t_stop`, then moved to the next step's time:
    (stepper, problem) ready for a Newton iteration."""
    from fingertip_dolfinx.runner import Run

    scene = load_scene("line-load-1pct", ["protocol.end_time=1.0", "output.times=[1.0]"])
    job = Run(scene, tmp_path, MPI.COMM_WORLD, resume=False, progress=False)
    reports = job.stepper.run(scene.history, t_stop)
    job.problem.set_time(t_stop + reports[-1].next_dt)
    return job.stepper, job.problem


@pytest.mark.mpi
def test_jacobian_is_the_residuals_derivative_in_contact(shared_tmp_path,
                                                         directional_error):
    """Mid-ramp (0.3 mm into the wedge; penalty contact, biphasic pulp, QLV skin), the
    assembled Jacobian times the Newton direction d equals the central difference
    (R(x + εd) − R(x − εd)) / 2ε to O(ε²): the error falls ~100× per decade of ε. A tangent
    missing a term would leave an O(1) error. (The ramp's steps converge linearly, at ~0.3
    per iteration with full steps, because the contact set changes between iterates: the
    README's "Speed" paragraph; this test rules out the other cause.)"""
    stepper, problem = _mid_ramp(shared_tmp_path, 0.3)
    snes, x = stepper.snes, stepper.nonlinear.x
    dolfinx.fem.petsc.assign(problem.unknowns, x)  # the accepted state, at the new time
    (F, _), (J, P, _) = snes.getFunction(), snes.getJacobian()
    snes.computeFunction(x, F)
    if stepper.reuse is not None:
        stepper.reuse.start()
    snes.computeJacobian(x, J, P)
    error = directional_error(snes, x)  # d from the run's own linear solver (MUMPS)
    coarse, fine = error(1e-2), error(1e-3)
    print(f"central-difference error of J d: {coarse:.2e} (eps 1e-2), {fine:.2e} (1e-3)")
    assert fine < 1e-5
    assert coarse / fine > 20  # second order: 100; first order (a wrong tangent): <= 10
