"""Scenes end to end on a coarse mesh: outputs, equilibrium, the paper's qualitative results for
a round-tipped bar, resuming an interrupted run, and the same numbers on 1 and 2 ranks."""

import dataclasses
import json
import re

import numpy as np
import pytest
from mpi4py import MPI

from fingertip_dolfinx.errors import InputError
from fingertip_dolfinx.outputs import DEPTH_COLUMNS, HISTORY_COLUMNS, SURFACE_COLUMNS, read_csv
from fingertip_dolfinx.runner import Run as Recorder
from fingertip_dolfinx.runner import run_scene
from fingertip_dolfinx.scene import load_scene
from fingertip_dolfinx.stepping import DEFAULT_PETSC_OPTIONS

COARSE = ["section.mesh.min_size=0.2", "section.mesh.max_size=1.0", "section.mesh.bone_size=2.0",
          "output.profile_points=121"]


def _one_point(extra=()):
    return load_scene("1pt", COARSE + list(extra))


@pytest.fixture(scope="module")
def one_point_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("1pt")
    out = MPI.COMM_WORLD.bcast(out, root=0)
    summary = run_scene(_one_point(), out, progress=False)
    return out, summary


def test_run_writes_every_documented_output(one_point_run):
    out, summary = one_point_run
    for key in ("dofs", "time_steps", "newton_iterations", "wall_time_s", "converged",
                "peak_force_N_per_mm", "max_penetration_mm", "force_at_output_times_N_per_mm"):
        assert key in summary
    assert summary["converged"] and summary["end_time_s"] == pytest.approx(1.0)
    assert json.loads((out / "summary.json").read_text())["dofs"] == summary["dofs"]
    assert tuple(read_csv(out / "history.csv")) == HISTORY_COLUMNS
    assert tuple(read_csv(out / "surface_profile.csv")) == SURFACE_COLUMNS
    assert not (out / "stick_slip.csv").exists()  # friction's, column for column as before
    assert tuple(read_csv(out / "depth_profiles.csv")) == DEPTH_COLUMNS
    for name in ("displacement.bp", "pore_pressure.bp", "log_strain.bp", "force_history.png",
                 "surface_profile.png", "depth_profiles_t1s.png", "field_u2_t1s.png",
                 "field_p_t1s.png", "mesh.xdmf"):
        assert (out / name).exists(), name


def test_history_counts_one_direct_solve_per_newton_iteration(one_point_run):
    """MUMPS (preonly) solves each Newton iteration's system in one "Krylov iteration", so the
    per-step Krylov column must equal the Newton column and the summary's totals agree."""
    out, summary = one_point_run
    h = read_csv(out / "history.csv")
    assert np.array_equal(h["krylov_iterations"], h["newton_iterations"])
    assert summary["krylov_iterations"] == summary["newton_iterations"] > 0


def test_force_equals_the_support_reaction_at_every_step(one_point_run):
    """Equilibrium of the discrete problem, to the Newton tolerance: the residual's norm is
    below max(1e-9 ‖R0‖, 1e-10 N/mm) (DEFAULT_PETSC_OPTIONS), and so is the force mismatch."""
    h = read_csv(one_point_run[0] / "history.csv")
    atol = DEFAULT_PETSC_OPTIONS["snes_atol"]
    np.testing.assert_allclose(h["reaction_N_per_mm"], h["force_N_per_mm"], rtol=1e-8, atol=atol)
    assert np.all(np.diff(h["force_N_per_mm"]) > 0), "the force must rise over the ramp"


def test_strains_next_to_the_contact_match_the_paper(one_point_run):
    """MODEL.md §4: max strain parallel to the surface, min strain normal to it (under the
    bar the surface is horizontal: e_max ≈ e11 > 0, e_min ≈ e22 < 0); the shear strain changes
    sign across the contact point; strains and SED peak next to the contact."""
    d = read_csv(one_point_run[0] / "depth_profiles.csv")
    x = d["x_mm"]
    under = np.abs(x) <= 0.1 + 1e-9  # right under the bar's apex, where the surface is flat
    # Direction of the max principal strain from the x axis: tan 2θ = 2 e12 / (e11 − e22).
    theta = 0.5 * np.degrees(np.arctan2(2 * d["e12"][under], d["e11"][under] - d["e22"][under]))
    assert np.all(np.abs(theta) < 10), theta  # max strain along the surface, min along its normal
    np.testing.assert_allclose(theta, -theta[::-1], atol=1.0)  # mirror symmetry about x = 0
    assert np.all(d["e11"][under] > 0) and np.all(d["e22"][under] < 0)
    left, right = np.interp(-0.5, x, d["e12"]), np.interp(0.5, x, d["e12"])
    assert left * right < 0 and abs(left + right) < 0.05 * abs(left), (left, right)
    far = np.abs(x) > 3
    for key in ("e_max", "sed_MPa"):
        assert np.max(np.abs(d[key][far])) < 0.2 * np.max(np.abs(d[key][np.abs(x) < 1]))


def test_resume_continues_an_interrupted_run(one_point_run, tmp_path_factory):
    """A run killed after 3 steps and resumed gives the uninterrupted run's results."""
    comm = MPI.COMM_WORLD
    out = comm.bcast(tmp_path_factory.mktemp("resume") if comm.rank == 0 else None, root=0)
    scene = _one_point()

    class Killed(Exception):
        pass

    first = Recorder(scene, out, comm, resume=False, progress=False)
    on_step = first.on_step

    def die_after_three(report):
        on_step(report)
        if first.step_count == 3:  # noqa: F821 (bound above, before this closure runs)
            raise Killed

    first.on_step = die_after_three
    with pytest.raises(Killed):
        first.run()
    del first
    second = Recorder(scene, out, comm, resume=True, progress=False)
    assert second.start_time > 0
    second.run()
    second.finish(True, None, 0.0)
    resumed, reference = read_csv(out / "history.csv"), read_csv(one_point_run[0] / "history.csv")
    np.testing.assert_allclose(resumed["time_s"], reference["time_s"], rtol=1e-12)
    np.testing.assert_allclose(resumed["force_N_per_mm"], reference["force_N_per_mm"], rtol=1e-7)


def test_resume_without_a_checkpoint_says_so(tmp_path):
    with pytest.raises(InputError, match="no checkpoint"):
        Recorder(_one_point(), tmp_path, MPI.COMM_SELF, resume=True, progress=False)


@pytest.mark.mpi
def test_one_and_two_ranks_give_the_same_numbers(world_and_alone):
    """The same scene on this run's ranks and on each rank alone agrees to 1e-8."""
    shared, alone = world_and_alone(_one_point(["protocol.depth=0.4"]))
    a, b = read_csv(shared / "history.csv"), read_csv(alone / "history.csv")
    np.testing.assert_allclose(a["force_N_per_mm"], b["force_N_per_mm"], rtol=1e-8)
    pa, pb = read_csv(shared / "depth_profiles.csv"), read_csv(alone / "depth_profiles.csv")
    scale = np.nanmax(np.abs(pb["e_min"]))
    np.testing.assert_allclose(pa["e_min"], pb["e_min"], atol=1e-8 * scale)


@pytest.mark.slow  # a sweep of runs: a study, run with `make test-slow`
@pytest.mark.mpi
def test_two_point_sweep_reproduces_the_papers_trends(tmp_path_factory):
    """MODEL.md §4: the normalised variations of e11, e22 and SED change little from d = 4 to
    3 mm and drop sharply from 3 to 2 mm; u2's falls steadily with d. Under mpiexec the three
    scenes run side by side."""
    from fingertip_dolfinx.studies.sweep import run_sweep

    comm = MPI.COMM_WORLD
    out = comm.bcast(tmp_path_factory.mktemp("sweep") if comm.rank == 0 else None, root=0)
    result = run_sweep("2pt", [2.0, 3.0, 4.0], out, COARSE, progress=False)
    v = {q: dict(zip(result["spacings_mm"], result["normalized_variation"][q]))
         for q in ("e11", "e22", "sed", "u2")}
    for q in ("e11", "e22", "sed"):
        plateau = abs(v[q][4.0] - v[q][3.0])
        assert plateau < 0.05 * abs(v[q][4.0]), (q, v[q])
        assert v[q][3.0] - v[q][2.0] > 2 * plateau, (q, v[q])
    assert v["u2"][4.0] > v["u2"][3.0] > v["u2"][2.0] > 0
    for name in ("normalized_variation.csv", "normalized_variation.png", "profiles_by_spacing.png"):
        assert (out / name).exists(), name
    assert result["threshold_criterion"]
    # the SA1 population (sites 1.195 mm apart) resolves every spacing here: no crossing
    population = result["population"]
    assert population["smallest_resolved_mm"] == 2.0 and population["threshold_mm"] is None
    assert max(population["dip_ratio"]) < 0.81


def test_an_impossible_indentation_stops_clearly_and_keeps_the_results(tmp_path):
    """6.9 mm into a pulp that is 7 mm thick down to the bone (Newton fails near 2 mm): the run
    must stop with a message that says when, where and why, and leave every accepted step on
    disk. (9 mm, deeper than the tissue, is refused before the run.)"""
    from fingertip_dolfinx.errors import ConvergenceError

    scene = _one_point(["protocol.depth=6.9", "steps.dt_initial=0.01", "steps.dt_max=0.05",
                        "steps.dt_min=0.005", "steps.max_cuts=2"])
    with pytest.raises(ConvergenceError) as error:
        run_scene(scene, tmp_path, progress=False, comm=MPI.COMM_SELF)
    message = str(error.value)
    assert re.search(r"failed (once|\d+ times)", message) and "Results up to t =" in message
    assert "near x = (" in message  # where: an inverted element or the largest residual
    saved = float(message.split("Results up to t = ")[1].split(" s")[0])
    h = read_csv(tmp_path / "history.csv")
    assert len(h["time_s"]) >= 1 and h["time_s"][-1] == pytest.approx(saved, rel=1e-5)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["converged"] is False and summary["failure"] == message


def test_an_indentation_deeper_than_the_tissue_is_refused_before_the_run():
    # 9 mm (or 1000: µm read as mm) into 7 mm of tissue under the bone was accepted, and the
    # run failed minutes later in Newton.
    with pytest.raises(InputError, match=r"reaches 1000 mm, but the soft tissue between the "
                       r"pulp and the bone is 7 mm thick.*Fix: give the depth in mm"):
        load_scene("1pt", ["protocol.depth=1000"])
    assert load_scene("1pt", ["protocol.depth=6.9"]).history.deepest == 6.9


def test_a_depth_curve_outside_the_finger_is_refused():
    with pytest.raises(InputError, match=r"output.depths: a depth curve 100 mm below the pulp "
                       r".* leaves the finger \(14 mm thick\)"):
        load_scene("1pt", ["output.depths=[100]"])


def test_shear_variation_is_the_peak_to_peak_around_each_point():
    """e12 is odd and changes sign under each bar: its normalised variation compares the
    peak-to-peak over one bar width around the contact point and around the centre. Two sharp
    steps of height 2 at the bars, flat between them: ≈ 1; a straight line: exactly 0."""
    from fingertip_dolfinx.studies.sweep import normalized_variation

    x = np.linspace(-6.0, 6.0, 2401)
    d = 3.0
    columns = {c: np.ones_like(x) for c in ("e11", "e22", "u2_mm", "sed_MPa")}
    base = {"time_s": np.ones_like(x), "depth_mm": np.full_like(x, 0.75), "x_mm": x, **columns}
    steps = np.tanh((x - d / 2) / 0.01) + np.tanh((x + d / 2) / 0.01)
    assert normalized_variation(base | {"e12": steps}, d, 1.0, 0.75)["e12"] == pytest.approx(
        1.0, abs=1e-6)
    assert normalized_variation(base | {"e12": 0.1 * x}, d, 1.0, 0.75)["e12"] == pytest.approx(
        0.0, abs=1e-12)


def test_a_run_without_pictures_writes_the_numbers_only(tmp_path, monkeypatch):
    """`output.pictures = false` (sweeps of many runs): every table, no PNG; and a folder in
    the working directory named like a built-in scene does not hide the scene."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "1pt").mkdir()
    run_scene(_one_point(["output.pictures=false", "protocol.depth=0.2"]), tmp_path / "1pt",
              progress=False, comm=MPI.COMM_SELF)
    assert (tmp_path / "1pt" / "depth_profiles.csv").exists()
    assert not list((tmp_path / "1pt").glob("*.png"))


@pytest.mark.parametrize("name", ["line-load-3d", "2pt-3d", "probe-3d", "vibrotactile-3d",
                                  "grating-3d", "shear-3d", "slide-3d"])
def test_the_3d_scenes_load_with_a_3d_fingertip(name):
    from fingertip_dolfinx.geometry.fingertip3d import Fingertip3D

    scene = load_scene(name)
    assert isinstance(scene.section, Fingertip3D) and scene.section.half


def test_shear_3d_drags_along_the_finger_and_checks_from_the_command_line(capsys):
    from fingertip_dolfinx.cli import main

    scene = load_scene("shear-3d")
    assert scene.history.direction == (0.0, 1.0) and scene.indenters[0].friction == 0.5
    assert main(["run", "shear-3d", "--check"]) == 0
    assert "check passed" in capsys.readouterr().err
    # across the finger the half model's mirror symmetry breaks; a 2D section has no z
    with pytest.raises(InputError, match="half model"):
        load_scene("shear-3d", ["protocol.tangential.direction=[1.0, 1.0]"])
    with pytest.raises(InputError, match="section is 2D"):
        load_scene("shear", ["protocol.tangential.direction=[0.0, 1.0]"])


def test_section_z_is_refused_in_2d_and_off_the_cylinder():
    with pytest.raises(InputError, match="3D fingertips only"):
        load_scene("1pt", ["output.section_z=5.0"])
    with pytest.raises(InputError, match="cylindrical part"):
        load_scene("probe-3d", ["output.section_z=18.0"])


def test_the_one_percent_line_load_is_the_line_load_on_a_cheaper_mesh():
    # A preset that may change how the answer is computed (mesh, Newton tolerance, outputs),
    # never what is computed: the same section, wedge, tissues, protocol, model and steps.
    fast, full = load_scene("line-load-1pct"), load_scene("line-load")
    for part in ("indenters", "history", "materials", "model", "linear"):
        assert getattr(fast, part) == getattr(full, part), part
    # the steps too, but for when Newton keeps its Jacobian (its tolerances are unchanged)
    assert dataclasses.replace(fast.steps, jacobian_reuse=full.steps.jacobian_reuse) == full.steps
    assert dataclasses.replace(fast.section, mesh=full.section.mesh) == full.section
    assert dataclasses.replace(fast.outputs, pictures=True, fields="output-times",
                               field_every=1) == full.outputs
    # its fine disc sits where the key outputs' SED and e_max peaks are read: the first output
    # time's depth curve at 0.75 mm, under the wedge's tip
    (x, depth), = fast.section.mesh.spots
    assert depth in full.depths and x == full.section.mesh.tips[0] == full.indenters[0].centre_x
    assert fast.section.mesh.spot_size < full.section.mesh.min_size < fast.section.mesh.min_size
    # a Newton residual tolerance still far below the 1 % asked: 1e-3 of the peak force
    # (1.18e-3 N/mm)
    assert float(fast.petsc_options["snes_atol"]) <= 1e-3 * 1.18e-3


def test_sweep_spots_sit_under_the_bars_and_midway_at_the_output_depth():
    # normalized_variation reads the fields at x = ±d/2 (the bar centres) and 0, at the first
    # output depth: the discs must follow the bars as the spacing changes
    from fingertip_dolfinx.studies.sweep import sweep_scenes

    spacings = [1.5, 3.0]
    for d, scene in zip(spacings, sweep_scenes("2pt", spacings, ["section.mesh.min_size=0.2"],
                                               spots=True)):
        assert sorted(x for x, _ in scene.section.mesh.spots) == [-d / 2, 0.0, d / 2]
        assert {depth for _, depth in scene.section.mesh.spots} == {scene.depths[0]}
        assert sorted(i.centre_x for i in scene.indenters) == [-d / 2, d / 2]
    assert sweep_scenes("2pt", spacings[:1])[0].section.mesh.spots == ()


def test_a_changed_protocol_kind_is_blamed_for_the_keys_it_does_not_take():
    """`--set protocol.kind=piecewise-linear` keeps the file's ramp-hold keys, which the new
    kind refuses: the message names the --set that changed the kind, not the built-in file
    (which was blamed before), and says to give the table whole. A misspelled key of the
    file's own kind is still blamed on its --set."""
    from fingertip_dolfinx.scene import Override

    with pytest.raises(InputError) as error:
        load_scene("1pt", [Override("protocol.kind=piecewise-linear",
                                    "--set protocol.kind=piecewise-linear")])
    assert error.value.where.startswith("--set protocol.kind=piecewise-linear: ")
    assert "1pt.toml" not in str(error.value) and "protocol={kind" in error.value.fix
    with pytest.raises(InputError) as error:
        load_scene("1pt", [Override("protocol.dept=1", "--set protocol.dept=1")])
    assert error.value.where.startswith("--set protocol.dept=1: ")


def test_a_scan_run_off_its_grating_blames_the_path_that_was_changed():
    """The scan scene with its path lengthened to 20 mm (`--set protocol.tangential...`): the
    grating (its outermost ridges' centres 18 mm apart) cannot cover the pulp throughout. The
    refusal names the --set that lengthened the path, not the built-in scene file (blamed
    before, for the indenter it names), and says the scan is longer than the grating instead
    of giving an interval that ends before it starts."""
    from fingertip_dolfinx.scene import Override

    text = "protocol.tangential.values=[0.0, 0.0, 20.0]"
    with pytest.raises(InputError) as error:
        load_scene("scan", [Override(text, f"--set {text}")])
    assert error.value.where.startswith(f"--set {text}: indenters[0]"), error.value.where
    assert "the scan (20 mm) is longer than the span of its outermost ridges' centres (18 mm)" \
        in error.value.problem


@pytest.mark.parametrize("scene, text, problem", [
    ("line-load", "protocol.end_time=50", "output.times: (1.0, 100.0) must lie in"),
    ("1pt", "section.mesh.min_size=5", "section.mesh.max_size: 0.8 mm is smaller"),
    ("1pt", "section.mesh.max_size=3", "section.mesh.bone_size: 1.5 mm is smaller"),
    ("line-load", "section.mesh.min_size=0.01", "section.mesh.tip_size: 0.02 mm is coarser"),
])
def test_a_relation_broken_by_an_override_names_the_override(scene, text, problem):
    """Two keys that must agree (the output times and the end, the mesh sizes): when an
    override changes one, the refusal names that override, not the built-in file that gave
    the other (which it blamed before: 'a built-in file is never blamed for a value you
    gave', docs/guide/scenes.md)."""
    from fingertip_dolfinx.scene import Override

    with pytest.raises(InputError) as error:
        load_scene(scene, [Override(text, f"--set {text}")])
    assert str(error.value).startswith(f"--set {text}: {problem}"), str(error.value)


@pytest.mark.parametrize("source, overrides, where", [
    (None, (), "load_scene(None)"), ("1pt", 5, "overrides=5"),
    ("1pt", "protocol.depth=0.5", "overrides='protocol.depth=0.5'")])
def test_load_scene_of_a_wrong_kind_is_an_input_error(source, overrides, where):
    # Were TypeErrors from deep inside (a Path of None, iterating an int), or a string of
    # overrides read character by character.
    with pytest.raises(InputError, match=re.escape(where)):
        load_scene(source, overrides)
