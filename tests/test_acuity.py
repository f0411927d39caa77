"""Acuity from the SA1 population (studies.acuity): the ideal observer's d′ of Poisson counts
against its closed form and against simulated observers, the rows at the real spacing, the
threshold's interpolation, the stimuli as indenters; one slow coarse study asserting the
physics (finer gratings are harder to tell apart)."""

import math

import numpy as np
import pytest

from fingertip_dolfinx.afferents.receptors import load_receptors
from fingertip_dolfinx.geometry.indenters import make_indenter
from fingertip_dolfinx.studies.acuity import (
    GAP_BAR,
    GRATING_SPAN,
    LEVEL,
    dprime_threshold,
    gap_table,
    grating_table,
    poisson_dprime,
    row_dprimes,
    same_sites,
    sampling_set,
)


def test_dprime_of_one_afferent_and_of_n_alike_is_the_closed_form():
    """One afferent: |a − b| / √((a + b)/2); n independent alike afferents: √n times that;
    silent afferents (a = b = 0) add nothing; the formula is symmetric."""
    assert poisson_dprime([9.0], [4.0]) == pytest.approx(5 / math.sqrt(6.5), rel=1e-15)
    assert poisson_dprime([9.0] * 16, [4.0] * 16) == pytest.approx(4 * 5 / math.sqrt(6.5))
    assert poisson_dprime([9.0, 0.0], [4.0, 0.0]) == poisson_dprime([9.0], [4.0])
    assert poisson_dprime([2.0, 0.0], [0.0, 3.0]) == poisson_dprime([0.0, 3.0], [2.0, 0.0])
    assert poisson_dprime([2.0, 0.0], [0.0, 3.0]) == pytest.approx(math.sqrt(4 / 1 + 9 / 1.5))
    with pytest.raises(ValueError):
        poisson_dprime([1.0, -1.0], [1.0, 1.0])


def test_dprime_is_what_the_optimal_linear_observer_of_poisson_counts_reaches():
    """Simulated trials: the observer weighting each afferent by Δμ/σ² separates the two
    stimuli by (mean difference)/√(mean variance) = d′. 40 000 trials per stimulus: the
    estimate's standard error is ~√((1 + d′²/4)/N) ≈ 0.006 here, so 3 % is 5 errors wide."""
    rng = np.random.default_rng(7)
    mu_a = np.array([0.5, 2.0, 6.0, 1.0, 0.0, 3.0])
    mu_b = np.array([1.5, 1.0, 4.0, 1.0, 0.2, 0.0])
    w = (mu_a - mu_b) / ((mu_a + mu_b) / 2)
    a = rng.poisson(mu_a, (40_000, 6)) @ w
    b = rng.poisson(mu_b, (40_000, 6)) @ w
    empirical = (a.mean() - b.mean()) / math.sqrt((a.var() + b.var()) / 2)
    assert empirical == pytest.approx(poisson_dprime(mu_a, mu_b), rel=0.03)


def test_rows_at_the_real_spacing_are_every_kth_site_of_the_dense_row():
    a, b = np.arange(12.0), np.zeros(12)
    rows = row_dprimes(a, b, k=4)
    assert len(rows) == 4
    for j in range(4):
        assert rows[j] == pytest.approx(poisson_dprime(a[j::4], b[j::4]), rel=1e-15)


def test_threshold_is_the_interpolated_crossing_of_the_level():
    """d′ 0.2, 0.8, 1.6 at 0.5, 1, 1.5 mm: crosses 1 at 1 + 0.5 (1 − 0.8)/(1.6 − 0.8)."""
    got = dprime_threshold([0.5, 1.0, 1.5], [0.2, 0.8, 1.6])
    assert got["threshold_mm"] == pytest.approx(1.125, rel=1e-12)
    assert got["smallest_resolved_mm"] == 1.5
    assert dprime_threshold([0.5, 1.0], [0.2, 0.9]) == {"smallest_resolved_mm": None,
                                                       "threshold_mm": None}
    assert dprime_threshold([0.5, 1.0], [1.2, 2.0])["threshold_mm"] is None  # all pass
    assert LEVEL == 1.0


def shape(table: dict):
    """The indenter a scene's table names (its `file` is the built-in grating)."""
    assert table["file"] == "grating"
    return make_indenter({"shape": "grating", **{k: v for k, v in table.items() if k != "file"}})


@pytest.mark.parametrize("width", [0.5, 0.75, 2.0])
def test_gratings_span_the_contact_and_phase_b_puts_a_groove_at_the_centre(width):
    a, b = (shape(grating_table(width, p)) for p in "AB")
    assert a.period == 2 * width and a.ridges % 2 == 1  # ridges = grooves; a ridge at 0
    assert (a.ridges - 1) * a.period >= GRATING_SPAN
    assert b.centre_x - a.centre_x == width  # ridges where A's grooves are
    points = np.array([[0.0, 0.0]])
    assert a.signed_distance_np(points, 0.0)[0][0] == 0.0  # x = 0 on A's ridge top
    assert b.signed_distance_np(points, 0.0)[0][0] > 0  # and in B's groove


def test_the_gap_stimulus_is_the_bar_with_its_middle_removed():
    solid, gapped = shape(gap_table(0.0)), shape(gap_table(1.0))
    assert solid.ridges == 1 and solid.width == GAP_BAR
    assert gapped.ridges == 2 and gapped.period - gapped.width == 1.0  # the gap
    assert gapped.period + gapped.width == GAP_BAR  # the same outer edges
    x = np.array([[-1.9, -0.01], [0.0, -0.01], [1.9, -0.01]])
    assert np.all(solid.signed_distance_np(x, 0.0)[0] < 0)
    assert np.array_equal(gapped.signed_distance_np(x, 0.0)[0] < 0, [True, False, True])


def test_the_sampling_set_is_the_calibrated_sa1_k_times_denser(tmp_path):
    dense = load_receptors(sampling_set(tmp_path / "row.toml", k=4))
    sa1 = load_receptors("calibrated")["SA1"]
    assert [c.name for c in dense.classes] == ["SA1"]
    assert dense["SA1"].spacing == pytest.approx(sa1.spacing / 4, rel=1e-12)
    assert dense["SA1"].saal == sa1.saal and dense["SA1"].depth == sa1.depth


@pytest.mark.slow
def test_coarser_gratings_and_wider_gaps_are_told_apart_better(tmp_path):
    """The coarse study at two grating widths and one gap: the SA1 counts of the two phases
    differ more (root-mean-square over the row) and d′ is larger at the coarser grating, for
    every offset of the row; the bar's 2 mm gap changes the counts."""
    from fingertip_dolfinx.studies.acuity import COARSE, read_counts, run_acuity

    result = run_acuity(tmp_path, widths=(0.5, 2.0), gaps=(2.0,), overrides=COARSE,
                        progress=False)
    counts = read_counts(tmp_path / "counts.csv")

    def mu(label):
        return counts[label][1]

    rms = [np.sqrt(np.mean((mu(f"grating-w{w:g}-A") - mu(f"grating-w{w:g}-B")) ** 2))
           for w in (0.5, 2.0)]
    assert rms[1] > rms[0]
    grating = result["grating"]
    assert grating["dprime"][1] > grating["dprime"][0]
    assert all(b > a for a, b in zip(*grating["dprime_rows"]))
    assert result["gap"]["dprime"][0] > 0


# ---- 3D: oriented gratings and the gap on the 3D fingertip (helpers; the runs are a study) --


def test_the_oriented_gratings_are_one_grating_turned_and_span_the_contact():
    """Along ("z") and across ("x") are the same profile: φ_along(x, y, z) = φ_across(x', y,
    centre + x) for any x'; a ridge is centred at x = 0 (along) or z = centre (across), and
    the ridges cover the contact's ±12 mm around it."""
    from fingertip_dolfinx.studies.acuity import GRATING_SPAN_3D, oriented_table

    along, across = (shape(oriented_table(1.0, o, 9.0)) for o in ("along", "across"))
    assert (along.axis, across.axis) == ("z", "x") and along.ridges == across.ridges
    assert (along.ridges - 1) * along.period >= GRATING_SPAN_3D
    rng = np.random.default_rng(4)
    p = np.column_stack((rng.uniform(-12, 12, 400), rng.uniform(-1, 0.5, 400),
                         rng.uniform(-3, 21, 400)))
    turned = np.column_stack((p[:, 2] * 0 + 5.0, p[:, 1], 9.0 + p[:, 0]))
    assert np.allclose(along.signed_distance_np(p, 0.0)[0],
                       across.signed_distance_np(turned, 0.0)[0], rtol=0, atol=1e-13)
    tops = np.array([[0.0, 0.0, 2.0], [3.0, 0.0, 9.0]])
    assert along.signed_distance_np(tops[:1], 0.0)[0][0] == 0.0
    assert across.signed_distance_np(tops[1:], 0.0)[0][0] == 0.0


def test_every_oriented_grating_from_1_mm_up_is_one_compiled_form():
    """Widths 1, 1.5 and 2 mm in both orientations share the ridge count (the only part of a
    grating that is the form's structure, not a Constant), and each still spans the contact."""
    from fingertip_dolfinx.studies.acuity import GRATING_SPAN_3D, oriented_table

    gratings = [shape(oriented_table(w, o, 9.0)) for w in (1.0, 1.5, 2.0)
                for o in ("along", "across")]
    assert len({g.ridges for g in gratings}) == 1
    assert all((g.ridges - 1) * g.period >= GRATING_SPAN_3D for g in gratings)


def test_the_3d_table_quotes_the_2d_study_as_it_stands():
    """The 3D table's 2D column is the 2D study's result as shipped in docs/results/acuity."""
    import json
    from pathlib import Path

    from fingertip_dolfinx.studies.acuity import TWO_D

    shipped = Path(__file__).parents[1] / "docs" / "results" / "acuity" / "summary.json"
    gap = json.loads(shipped.read_text())["gap"]["threshold_mm"]
    assert TWO_D["gap"] == f"{gap:.2f}"


def test_the_3d_jobs_press_both_orientations_and_the_gap_on_one_mesh(tmp_path):
    from fingertip_dolfinx.studies.acuity import SAMPLING_3D, study_jobs_3d, window_of

    jobs = study_jobs_3d(tmp_path, (1.0,), (1.0,))
    labels = [label for label, _, _ in jobs]
    assert labels == ["orientation-w1-along", "orientation-w1-across", "gap-g0", "gap-g1"]
    scenes = [scene for _, scene, _ in jobs]
    assert [s.indenters[0].axis for s in scenes] == ["z", "x", "z", "z"]
    assert len({(s.section, s.outputs.receptors) for s in scenes}) == 1  # one mesh, one set
    half_width, z0, z1 = window_of(scenes[0])
    assert scenes[1].indenters[0].centre_z == (z0 + z1) / 2 and scenes[0].section.half
    dense = load_receptors(scenes[0].outputs.receptors)["SA1"]
    assert dense.density == load_receptors("calibrated")["SA1"].density * SAMPLING_3D**2


def test_the_3d_tasks_pair_the_runs_and_refuse_different_sites():
    """d′ per population from synthetic counts (4 populations interleaved), and an error when
    the two runs of a task were sampled at different sites."""
    from fingertip_dolfinx.studies.acuity import summarise_3d

    xz = np.column_stack((np.arange(8.0), np.zeros(8)))
    ones, twos = np.ones(8), np.full(8, 2.0)
    counts = {"orientation-w1-along": (xz, ones), "orientation-w1-across": (xz, twos),
              "gap-g0": (xz, ones), "gap-g1": (xz, ones)}
    result = summarise_3d(counts, (1.0,), (1.0,), (4.0, 4.0, 14.0))
    each = math.sqrt(2 * 1.0 / 1.5)  # two sites per population, (2 − 1)² / 1.5 each
    assert result["orientation"]["dprime_rows"][0] == pytest.approx([each] * 4)
    assert result["gap"]["dprime"] == [0.0] and result["afferents_per_population"] == 2
    counts["gap-g1"] = (xz + 1.0, ones)
    with pytest.raises(ValueError, match="gap-g0 and gap-g1 have different afferent sites"):
        summarise_3d(counts, (1.0,), (1.0,), (4.0, 4.0, 14.0))


def test_a_grating_record_keeps_a_finite_depth_and_leaves_out_inf():
    from fingertip_dolfinx.scene import load_scene, scene_record

    assert "depth" not in scene_record(load_scene("grating"))["indenters"][0]
    floored = load_scene("grating", ["indenters.0.depth=0.5"])
    assert scene_record(floored)["indenters"][0]["depth"] == 0.5


def test_the_3d_files_hold_each_sites_position_and_every_populations_dprime(tmp_path):
    """acuity.csv has one d′ column per population, counts.csv each site's x and z with its
    expected count, acuity.md the criterion and table, and the figure is drawn (synthetic
    counts: ridges along the finger fire in bands of x, across it in bands of z)."""
    from fingertip_dolfinx.studies.acuity import (
        _write_tables_3d,
        plot_acuity_3d,
        summarise_3d,
    )

    rng = np.random.default_rng(6)
    xz = np.column_stack((rng.uniform(-3, 3, 40), rng.uniform(6, 12, 40)))
    bands = {"orientation-w1-along": xz[:, 0], "orientation-w1-across": xz[:, 1] - 9.0,
             "gap-g0": 0 * xz[:, 0], "gap-g1": np.abs(xz[:, 0]) + 1.0}
    counts = {k: (xz, 3.0 * (np.cos(np.pi * u) > 0)) for k, u in bands.items()}
    result = summarise_3d(counts, (1.0,), (1.0,), (3.0, 6.0, 12.0))
    _write_tables_3d(tmp_path, counts, result)
    plot_acuity_3d(result, counts, tmp_path / "acuity.png")
    lines = (tmp_path / "acuity.csv").read_text().splitlines()
    assert lines[0] == "task,width_mm,dprime,dprime_pop0,dprime_pop1,dprime_pop2,dprime_pop3"
    rows = (tmp_path / "counts.csv").read_text().splitlines()
    assert rows[0] == "run,x_mm,z_mm,expected_count" and len(rows) == 1 + 4 * 40
    label, x, z, mu = rows[1].split(",")
    assert label == "orientation-w1-along" and float(x) == pytest.approx(xz[0, 0], abs=1e-6)
    assert float(z) == pytest.approx(xz[0, 1], abs=1e-6)
    assert "ridges along vs across" in (tmp_path / "acuity.md").read_text()
    assert (tmp_path / "acuity.png").stat().st_size > 10_000


def test_a_run_is_reused_for_a_new_calibration_but_not_for_other_sites(tmp_path):
    """The study counts spikes from each run's sampled stimulus, so a run that sampled the same
    sites is reused when only the transduction (its input scale) changed, and run again when
    the sites moved (depth) or read another quantity."""
    import json

    sites = sampling_set(tmp_path / "sa1-row.toml")
    run = tmp_path / "run"
    run.mkdir()
    record = load_receptors(sites).record()

    def ran_with(**changes):
        ran = json.loads(json.dumps(record))
        ran["SA1"].update(changes)
        (run / "receptors.json").write_text(json.dumps(ran))
        return same_sites(run, sites)

    assert ran_with()
    assert ran_with(saal2017=dict(record["SA1"]["saal2017"], input_scale=1.0))
    assert not ran_with(depth=record["SA1"]["depth"] + 0.25)
    assert not ran_with(quantity="strain_energy_density")
    (run / "receptors.json").unlink()
    assert not same_sites(run, sites)


@pytest.mark.parametrize("argv, gaps", [([], (1.0,)), (["--gaps"], []), (["--gaps", "1.5"], [1.5])])
def test_the_3d_command_runs_the_orientation_task_alone_when_given_no_gap(
        tmp_path, monkeypatch, argv, gaps):
    """`--3d --gaps` with no value asks for no gap runs (the orientation pair only)."""
    from fingertip_dolfinx import cli
    from fingertip_dolfinx.studies import acuity

    asked = {}
    monkeypatch.setattr(acuity, "run_acuity_3d", lambda out, widths, gaps, *a, **k: asked.update(
        widths=widths, gaps=gaps) or {"criterion": "-"})
    monkeypatch.setattr(acuity, "acuity_table_3d", lambda result: "")
    assert cli.main(["study", "acuity", "--3d", *argv, "--out", str(tmp_path)]) == 0
    assert asked == {"widths": acuity.WIDTHS_3D, "gaps": gaps}


def test_the_3d_figure_has_a_row_per_task_that_ran(tmp_path):
    """Without the gap runs (`--gaps` with no value) the figure is the orientation row alone,
    not a row of empty panels."""
    from matplotlib.image import imread

    from fingertip_dolfinx.studies.acuity import plot_acuity_3d, summarise_3d

    xz = np.column_stack((np.linspace(-3, 3, 30), np.linspace(1, 17, 30)))
    counts = {k: (xz, np.cos(xz[:, i % 2] * (i + 1)) + 1.0) for i, k in enumerate(
        ("orientation-w1-along", "orientation-w1-across", "gap-g0", "gap-g1"))}
    heights = []
    for gaps in ((1.0,), ()):
        runs = {k: v for k, v in counts.items() if gaps or not k.startswith("gap")}
        plot_acuity_3d(summarise_3d(runs, (1.0,), gaps, (3.0, 0.5, 17.5)), runs,
                       tmp_path / "acuity.png")
        heights.append(imread(tmp_path / "acuity.png").shape[0])
    assert heights[1] < 0.6 * heights[0]


def test_the_2d_figure_has_a_panel_per_task_that_ran(tmp_path):
    """Without the gap runs the figure is d′ and the grating's profiles, not a third, empty
    panel: two panels of the same size, two thirds of the width."""
    from matplotlib.image import imread

    from fingertip_dolfinx.studies.acuity import plot_acuity, summarise

    x = np.linspace(-6.0, 6.0, 41)
    counts = {k: (x, np.cos(x * (i + 1)) + 1.0) for i, k in enumerate(
        ("grating-w1-A", "grating-w1-B", "gap-g0", "gap-g1"))}
    widths = []
    for gaps in ((1.0,), ()):
        runs = {k: v for k, v in counts.items() if gaps or not k.startswith("gap")}
        plot_acuity(summarise(runs, (1.0,), gaps), runs, tmp_path / "acuity.png")
        widths.append(imread(tmp_path / "acuity.png").shape[1])
    assert abs(widths[1] / widths[0] - 2 / 3) < 0.01, widths


def test_the_count_profiles_say_the_time_they_were_counted_over(tmp_path, monkeypatch):
    """The counts are over the whole stimulus, whose length a scene override may change: the
    profiles' axis gives the runs' common end (`stimulus_duration`), and no number where the
    runs end at different times."""
    from matplotlib.figure import Figure

    from fingertip_dolfinx.studies.acuity import plot_acuity, stimulus_duration, summarise

    for name, end in (("a", 0.5), ("b", 0.5), ("c", 2.0)):
        (tmp_path / name).mkdir()
        (tmp_path / name / "history.csv").write_text(f"time_s,force_N_per_mm\n0.1,0\n{end},1\n")
    assert stimulus_duration([tmp_path / "a", tmp_path / "b"]) == 0.5
    assert stimulus_duration([tmp_path / "a", tmp_path / "c"]) is None
    assert stimulus_duration([tmp_path / "a", tmp_path / "missing"]) is None
    drawn = []
    monkeypatch.setattr(Figure, "savefig", lambda fig, *a, **k: drawn.append(fig))
    x = np.linspace(-6.0, 6.0, 41)
    counts = {k: (x, np.cos(x * (i + 1)) + 1.0) for i, k in enumerate(("grating-w1-A",
                                                                        "grating-w1-B"))}
    for duration, label in ((0.5, "expected SA1 spikes in 0.5 s"),
                            (None, "expected SA1 spikes over the stimulus")):
        result = {**summarise(counts, (1.0,), ()), "counted_over_s": duration}
        plot_acuity(result, counts, tmp_path / "acuity.png")
        assert drawn[-1].axes[1].get_ylabel() == label


def test_counts_up_to_a_time_are_the_counts_of_the_samples_up_to_it():
    """`until` counts a run's spikes over 0..until only: the same as the samples cut there, and
    never more than over the whole run (a pair read before its end is compared over the time
    both reached)."""
    from fingertip_dolfinx.studies.acuity import fit_mean_counts

    sa1 = load_receptors("calibrated")["SA1"]
    time = np.linspace(0.0, 1.0, 101)
    stimulus = np.column_stack([np.minimum(time / 0.1, 1.0) * s for s in (2e-3, 5e-3, 1e-2)])
    part = fit_mean_counts(sa1, time, stimulus, until=0.3)
    assert np.array_equal(part, fit_mean_counts(sa1, time[:31], stimulus[:31]))
    whole = fit_mean_counts(sa1, time, stimulus)
    assert np.all(part <= whole) and np.any(part < whole) and part[-1] > 0


def test_runs_read_before_their_end_are_refused_past_the_time_they_reached(tmp_path):
    """`count_acuity_3d(..., until=T)` compares a pair over 0..T: a run that stopped before T
    would count over a shorter stimulus, so the study names the runs and the latest T."""
    from fingertip_dolfinx.errors import InputError
    from fingertip_dolfinx.studies.acuity import count_acuity_3d, study_jobs_3d

    for label, _, where in study_jobs_3d(tmp_path, (1.0,), ()):
        where.mkdir()
        last = 0.15 if label.endswith("along") else 0.12
        (where / "history.csv").write_text(f"time_s,newton_iterations\n0.1,4\n{last},3\n")
    with pytest.raises(InputError, match=r"until.*0\.2 s is later.*use until <= 0\.12"):
        count_acuity_3d(tmp_path, (1.0,), (), until=0.2)
