"""The adaptive loop (adaptivity.py): the Zienkiewicz–Zhu indicator, the size hook of the mesh,
the error estimates, and the loop on the coarse one-point scene against a finer run."""

import dataclasses
import math

import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from fingertip_dolfinx.errors import InputError
from fingertip_dolfinx.geometry.mesh import SizeMap, build_mesh
from fingertip_dolfinx.geometry.section import Section
from fingertip_dolfinx.keys import KEYS
from fingertip_dolfinx.physics.kinematics import hencky_strain
from fingertip_dolfinx.scene import load_scene
from fingertip_dolfinx.studies import adaptivity as ad

# --- the indicator on fields with known answers --------------------------------------------------

def dg1_log_strain(msh, u_exact, degree=2):
    """X (cells, 3, 2) and the DG1 log strain's corner values (cells, 3, 4) of the P2
    interpolant of u_exact, as the runs write them (post.FieldArrays)."""
    V = fem.functionspace(msh, ("Lagrange", degree, (2,)))
    u = fem.Function(V)
    u.interpolate(u_exact)
    T = fem.functionspace(msh, ("Discontinuous Lagrange", 1, (2, 2)))
    e = fem.Function(T)
    e.interpolate(fem.Expression(hencky_strain(ufl.Identity(2) + ufl.grad(u)),
                                 T.element.interpolation_points))
    n = msh.topology.index_map(2).size_local
    X = msh.geometry.x[msh.geometry.dofmaps[0][:n, :3]][..., :2]
    values = e.x.array.reshape(-1, 4)[T.dofmap.list[:n]]
    return X, values, u


def square(n):
    return dmesh.create_unit_square(MPI.COMM_SELF, n, n, diagonal=dmesh.DiagonalType.crossed)


def test_indicator_vanishes_for_a_linear_displacement():
    """A linear displacement has a constant strain: its recovery is exact, eta = 0."""
    X, values, _ = dg1_log_strain(square(6), lambda x: np.vstack([0.1 * x[0] + 0.05 * x[1],
                                                                  -0.08 * x[0] + 0.02 * x[1]]))
    assert np.ptp(values) > 0.01  # not a trivial field: e11, e12, e22 all differ
    eta = ad.zz_indicator(X, values)
    assert eta.max() < 1e-13


def test_recovery_stays_within_each_region():
    """Two regions with different constant strains (an interface, like skin on subcutaneous
    tissue): averaged across the interface the indicator would flag it; per region it is 0."""
    msh = square(6)
    X, values, _ = dg1_log_strain(msh, lambda x: np.vstack([0.1 * x[0], 0.0 * x[1]]))
    region = np.where(X.mean(axis=1)[:, 0] < 0.5, 1, 2)
    values = values * np.where(region == 1, 1.0, 3.0)[:, None, None]  # a jump at x = 0.5
    assert ad.zz_indicator(X, values, region).max() < 1e-13
    assert ad.zz_indicator(X, values).max() > 1e-3


def test_indicator_converges_at_order_two_and_tracks_the_true_error():
    """P2 displacements of a smooth field: the strain error is O(h^2), and so is the
    indicator. The effectivity (indicator / true error) settles to a constant, 0.29 here: the
    averaged P1 recovery of a P2 strain is no better than the strain itself (not
    superconvergent), so the indicator is equivalent to the error, not asymptotically exact.
    The loop uses it only for where to refine; how large the error is comes from the levels."""
    def u_exact(x):
        return np.vstack([0.05 * np.sin(np.pi * x[0]) * np.cos(np.pi * x[1]),
                          0.05 * np.cos(2 * x[0]) * np.sin(np.pi * x[1])])

    totals, true = [], []
    for n in (4, 8, 16, 32):
        msh = square(n)
        X, values, u = dg1_log_strain(msh, u_exact)
        totals.append(math.sqrt(np.sum(ad.zz_indicator(X, values) ** 2)))
        xs = ufl.SpatialCoordinate(msh)
        exact = ufl.as_vector([0.05 * ufl.sin(ufl.pi * xs[0]) * ufl.cos(ufl.pi * xs[1]),
                               0.05 * ufl.cos(2 * xs[0]) * ufl.sin(ufl.pi * xs[1])])
        diff = (hencky_strain(ufl.Identity(2) + ufl.grad(exact))
                - hencky_strain(ufl.Identity(2) + ufl.grad(u)))
        true.append(math.sqrt(fem.assemble_scalar(fem.form(
            ufl.inner(diff, diff) * ufl.dx(metadata={"quadrature_degree": 8})))))
    rates = np.log2(np.array(totals[:-1]) / totals[1:])
    true_rates = np.log2(np.array(true[:-1]) / true[1:])
    # measured: indicator 2.53, 2.19, 2.05 (towards 2 from above); true error 1.99, 2.00, 2.00
    assert np.all(rates > 1.9) and abs(rates[-1] - 2.0) < 0.1, rates
    assert np.all(np.abs(true_rates - 2.0) < 0.05), true_rates
    effectivity = np.array(totals) / np.array(true)
    # measured: 0.50, 0.34, 0.30, 0.29
    assert np.all((effectivity > 0.2) & (effectivity < 1.0)), effectivity
    assert abs(effectivity[-1] / effectivity[-2] - 1) < 0.05, effectivity  # settles


# --- sizes: grading, the size map and the hook in build_mesh -------------------------------------

def test_grading_limits_the_growth_between_neighbours():
    centroids = np.column_stack([np.arange(5.0), np.zeros(5)])
    pairs = np.array([[0, 1], [1, 2], [2, 3], [3, 4]])
    h = ad.graded(np.array([1.0, 1.0, 0.1, 1.0, 1.0]), centroids, pairs, growth=0.3)
    assert h == pytest.approx([0.7, 0.4, 0.1, 0.4, 0.7])



def test_a_peak_zone_smaller_than_its_cells_is_refined_through_the_nearest_cell():
    """`fingertip run 1pt --tol 0.05` on a 1.5 mm mesh: the 0.3 mm discs of a peak held no
    cell centroid, and planning the next level stopped on an empty average
    (ZeroDivisionError). The cell nearest to the disc stands for it: it is refined by the
    first level's ratio, and that is the zone's planned and measured ratio."""
    n = 6
    centroids = np.column_stack([1.5 * np.arange(n), np.zeros(n)])
    peak = ad.Zone(np.array([[4.0, 0.3]]), np.array([0.3]))  # 0.5 mm from the nearest centroid
    zones = {"load": ad.Zone(np.array([[3.75, 0.0]]), np.array([10.0])), "e_max": peak,
             "sed_MPa": peak}
    assert peak.distance(centroids).min() > 0
    data = {"h": np.full(n, 1.5), "density": np.ones(n), "area": np.full(n, 1.0),
            "centroids": centroids, "pairs": np.column_stack([np.arange(n - 1), np.arange(1, n)]),
            "zones": zones}
    plan = ad._plan_next(0, [{"cells": n, "dofs": 10 * n}], [data], ad.AdaptOptions(tol=0.05),
                         floor=0.01)
    assert plan["planned_ratios"]["e_max"] == pytest.approx(2.0)
    assert np.flatnonzero(peak.cells(centroids)).tolist() == [3]
    finer = {"centroids": centroids, "h": plan["sizes"], "area": data["area"]}
    assert ad.measured_ratio(data, finer, peak) == pytest.approx(2.0)

def test_size_map_answers_the_nearest_point_and_survives_a_file(tmp_path):
    points = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    sm = SizeMap(points, [0.1, 0.2, 0.3])
    assert [sm(0.1, 0.05), sm(0.9, 0.1), sm(-0.2, 1.3)] == [0.1, 0.2, 0.3]
    again = SizeMap.load(sm.save(tmp_path / "size_map.npz"))
    assert again(0.9, 0.1) == 0.2
    with pytest.raises(ValueError):
        SizeMap(points, [0.1, 0.0, 0.3])


def test_mesh_option_size_map_must_name_a_file(tmp_path):
    with pytest.raises(InputError, match="mesh.size_map"):
        dataclasses.replace(Section().mesh, size_map=str(tmp_path / "missing.npz"))


def coarse_section() -> Section:
    s = Section()
    return dataclasses.replace(s, mesh=dataclasses.replace(s.mesh, min_size=0.4, max_size=1.0,
                                                           bone_size=2.0))


def edges_and_centres(fm):
    msh = fm.mesh
    n = msh.topology.index_map(2).size_local
    X = msh.geometry.x[msh.geometry.dofmaps[0][:n, :3]][..., :2]
    return ad.cell_sizes(X), X.mean(axis=1)


def test_size_hook_leaves_the_mesh_alone_unless_asked():
    """No hook, or a hook that asks for nothing finer than the fields: the same mesh."""
    section = coarse_section()
    plain = build_mesh(section, MPI.COMM_SELF)
    same = build_mesh(section, MPI.COMM_SELF, size=None)
    loose = build_mesh(section, MPI.COMM_SELF, size=lambda x, y: 100.0)
    for other in (same, loose):
        assert other.report.num_cells == plain.report.num_cells
        assert np.array_equal(other.mesh.geometry.x, plain.mesh.geometry.x)


def test_size_hook_refines_where_asked_and_nowhere_else():
    section = coarse_section()
    centre, radius, h = np.array([0.0, -6.0]), 0.5, 0.05
    plain = build_mesh(section, MPI.COMM_SELF)
    fine = build_mesh(section, MPI.COMM_SELF, size=lambda x, y: h if math.hypot(
        x - centre[0], y - centre[1]) < radius else 100.0)
    sizes, centres = edges_and_centres(fine)
    inside = np.linalg.norm(centres - centre, axis=1) < radius - 2 * h
    assert inside.sum() > 150
    assert np.median(sizes[inside]) < 1.1 * h and np.quantile(sizes[inside], 0.95) < 1.3 * h
    # away from the disc (beyond the fields' own growth), the sizes are the plain mesh's
    plain_sizes, plain_centres = edges_and_centres(plain)
    far = np.linalg.norm(centres - centre, axis=1) > 3.0
    plain_far = np.linalg.norm(plain_centres - centre, axis=1) > 3.0
    assert np.median(sizes[far]) == pytest.approx(np.median(plain_sizes[plain_far]), rel=0.05)
    assert abs(far.sum() - plain_far.sum()) < 0.05 * plain_far.sum()
    # the new cells are those of the disc: its area over the area of a cell of size h
    added = fine.report.num_cells - plain.report.num_cells
    assert 0.5 < added / (math.pi * radius**2 / (math.sqrt(3) / 4 * h**2)) < 1.5


# --- the estimates on synthetic sequences --------------------------------------------------------

def test_observed_order_with_unequal_ratios():
    h = np.array([0.4, 0.4 / 1.7, 0.4 / 1.7 / 1.3])
    f = 2.0 + 0.3 * h**2.2
    assert ad.observed_order(tuple(f), 1.3, 1.7) == pytest.approx(2.2, rel=1e-8)
    assert math.isnan(ad.observed_order((1.0, 1.1, 1.05), 2.0, 2.0))


def test_estimates_bound_a_second_order_error_by_their_safety_factor():
    def f(h):
        return 1.0 + 0.2 * h**2

    two = ad.estimate([f(0.2), f(0.1)], [2.0], order=2.0)
    assert two["error"] == pytest.approx(1.25 * (f(0.1) - 1.0) / f(0.1))
    three = ad.estimate([f(0.4), f(0.2), f(0.1)], [2.0, 2.0], order=2.0)
    assert three["observed_order"] == pytest.approx(2.0)
    assert three["error"] == pytest.approx(1.25 * (f(0.1) - 1.0) / f(0.1))
    assert three["extrapolated"] == pytest.approx(1.0)
    # a faster observed order is capped at the assumed one: the estimate only grows
    fast = ad.estimate([1.0 + 0.2 * h**3 for h in (0.4, 0.2, 0.1)], [2.0, 2.0], order=2.0)
    assert fast["order"] == 2.0 and fast["error"] > 1.25 * 0.2 * 0.1**3 / 1.0002
    # an oscillating sequence gets Roache's factor 3 and the assumed order
    osc = ad.estimate([1.0, 1.1, 1.05], [2.0, 2.0], order=2.0)
    assert osc["safety"] == 3.0 and osc["error"] == pytest.approx(3 * 0.05 / 3 / 1.05)
    # a region that was not refined gives no estimate
    assert ad.estimate([1.0, 1.01], [1.01], order=2.0)["error"] == math.inf


def test_options_are_checked():
    with pytest.raises(InputError, match="tol"):
        ad.AdaptOptions(tol=0.0)
    with pytest.raises(InputError, match="max_levels"):
        ad.AdaptOptions(max_levels=1)
    with pytest.raises(InputError, match="time_share"):
        ad.AdaptOptions(time_share=1.0)
    with pytest.raises(InputError, match="max_time_runs"):
        ad.AdaptOptions(max_time_runs=1)


def test_a_tolerance_governs_the_time_steps_too():
    """tol is split: the mesh gets tol (1 - time_share), the time stepping the rest, as
    error-controlled BDF2 steps whose tolerances scale with it (the scene's own step control
    grows steps by Newton's effort, whatever the error). A dynamic scene's scheme has no error
    estimate: refused, with the way to adapt the mesh alone; time_share 0 keeps the scene's
    steps."""
    from fingertip_dolfinx.stepping import ATOL_PER_RTOL, RTOL_PER_BUDGET

    options = ad.AdaptOptions(tol=0.02)
    assert options.space_tol + options.time_tol == pytest.approx(0.02)
    assert 0 < options.time_tol < options.space_tol
    scene = load_scene("1pt")
    steps = ad.timed_scene(scene, options).steps
    assert (scene.steps.control, steps.control, steps.scheme) == ("iterations", "error", "bdf2")
    assert steps.rtol == pytest.approx(RTOL_PER_BUDGET * options.time_tol)
    assert steps.atol == pytest.approx(ATOL_PER_RTOL * steps.rtol)
    assert (steps.dt_max, steps.dt_initial) == (scene.steps.dt_max, scene.steps.dt_initial)
    assert ad.timed_scene(scene, ad.AdaptOptions(time_share=0)) is scene
    with pytest.raises(InputError, match="generalized-alpha.*time_share=0"):
        ad.timed_scene(load_scene("vibrotactile"), options)


def test_scene_accuracy_table():
    assert load_scene("1pt").accuracy.tol is None
    scene = load_scene("1pt", ["accuracy.tol=0.02", "accuracy.max_levels=3"])
    assert (scene.accuracy.tol, scene.accuracy.max_levels) == (0.02, 3)
    with pytest.raises(InputError, match="accuracy.tol"):
        load_scene("1pt", ["accuracy.tol=2.0"])
    with pytest.raises(InputError, match="max_levels"):
        load_scene("1pt", ["accuracy.max_levels=1"])
    with pytest.raises(InputError, match="takes: tol, max_levels"):
        load_scene("1pt", ["accuracy.tolerance=0.01"])


@pytest.mark.parametrize("argv, message", [
    (["--tol", "1.5"], "--tol 1.5: must be a relative error in (0, 1)"),
    (["--max-levels", "3"], "--max-levels: is for the adaptive loop"),
    (["--tol", "0.01", "--max-levels", "1"], "an error estimate needs two levels"),
    (["--tol", "0.01", "--resume"], "--resume: cannot continue the adaptive loop"),
])
def test_run_tol_refuses_bad_input(tmp_path, capsys, argv, message):
    from fingertip_dolfinx.cli import main

    assert main(["run", "1pt", *argv, "--out", str(tmp_path / "x")]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


# --- the loop ------------------------------------------------------------------------------------

#: The coarse 1pt scene: with the loop's default coarsen = 2, level 0 has min_size 0.4 under the
#: pulp and 1.2 mm elsewhere (the coarse accuracy study's coarsest mesh).
COARSE = ["--set", "section.mesh.min_size=0.2", "--set", "section.mesh.max_size=1.2",
          "--set", "section.mesh.bone_size=2.0", "--set", "output.field_every=1000000"]


@pytest.fixture(scope="module")
def loop(tmp_path_factory):
    """`fingertip run 1pt --tol 0.05` on the coarse scene, and a finer reference run: the
    scene's own mesh refined by sqrt 2 everywhere (min 0.071, max 0.57, bone 1.06 mm; 34k
    unknowns, within 0.2 % of the Richardson value of 0.1 -> 0.071 -> 0.05 mm on every key
    output, measured)."""
    from fingertip_dolfinx.cli import main
    from fingertip_dolfinx.keys import key_outputs
    from fingertip_dolfinx.runner import run_scene

    out = MPI.COMM_WORLD.bcast(tmp_path_factory.mktemp("adapt"), root=0)
    assert main(["run", "1pt", "--tol", "0.05", *COARSE, "--quiet",
                 "--out", str(out / "loop")]) == 0
    h = 0.1 / math.sqrt(2)
    run_scene(load_scene("1pt", [f"section.mesh.min_size={h}", f"section.mesh.max_size={8 * h}",
                                 f"section.mesh.bone_size={15 * h}",
                                 "output.field_every=1000000"]), out / "reference",
              progress=False)
    return out, ad.read_adapt(out / "loop"), key_outputs(out / "reference")


@pytest.mark.slow  # the loop fixture: three levels of runs
def test_loop_stops_and_writes_a_normal_run_plus_adapt_json(loop):
    out, report, _ = loop
    from fingertip_dolfinx.result import Result

    assert report["converged"], report["message"]
    assert 2 <= report["cost"]["levels"] <= 4
    assert set(report["estimated_errors"]) == set(KEYS)
    assert all(v <= 0.05 for v in report["estimated_errors"].values())
    # the time error: estimated from a run of the finest mesh 4x tighter, within its share
    space, times = report["estimated_space_errors"], report["estimated_time_errors"]
    assert set(times) == set(KEYS) and report["tol_time"] == pytest.approx(0.05 * 0.25)
    for key in KEYS:
        assert 0 <= times[key] <= report["tol_time"] and space[key] <= report["tol_space"]
        assert report["estimated_errors"][key] == pytest.approx(space[key] + times[key])
    runs = report["time"]["runs"]
    assert len(runs) >= 2 and runs[-1]["rtol"] < runs[0]["rtol"]
    assert report["time"]["published"] == runs[-1]["run"] != report["levels"][-1]["run"]
    result = Result(out / "loop")  # the finest level's files, read as any run
    summary = result.summary
    assert summary["adaptivity"]["converged"] and summary["adaptivity"]["tol"] == 0.05
    assert summary["adaptivity"]["estimated_time_errors"] == report["estimated_time_errors"]
    assert summary["scene_data"]["steps"]["rtol"] == pytest.approx(runs[-1]["rtol"])
    assert summary["adaptivity"]["mesh"]["cells"] == summary["mesh"]["cells"]
    assert summary["mesh"]["cells"] == report["levels"][-1]["cells"]
    assert summary["scene_data"]["accuracy"] == {"tol": 0.05, "max_levels": 4}
    assert summary["scene_data"]["section"]["mesh"]["min_size"] == 0.4  # level 0's
    last = len(report["levels"]) - 1
    assert (out / "loop" / f"level-{last}" / "size_map.npz").is_file()
    assert result.force.max() == pytest.approx(report["values"]["force_N_per_mm_max_over_run"])
    cells = [lv["cells"] for lv in report["levels"]]
    assert cells == sorted(cells) and cells[-1] > cells[0]


@pytest.mark.slow  # the loop fixture: three levels of runs
def test_loop_estimates_bound_the_errors_against_a_finer_run(loop):
    _, report, reference = loop
    final = report["levels"][-1]
    for key in KEYS:
        true = abs(final["values"][key] - reference[key]) / abs(reference[key])
        assert report["estimated_errors"][key] >= true, (key, report["estimated_errors"][key],
                                                          true)
