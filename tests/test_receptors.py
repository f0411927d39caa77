"""Receptor sites and afferent models: the integrate-and-fire neuron against its closed forms
and a fine reference, the site placement against the ellipse, the data's checks, the shipped
parameters against their stated criteria, the Cauchy stress field against the laws, and one
coarse one-point run that samples the sites at every step."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from fingertip_dolfinx.afferents.receptors import (
    LIF,
    RECEPTOR_COLUMNS,
    afferent_responses,
    constant_current_rate,
    lif_spikes,
    load_receptors,
    receptors_from_dict,
    saal_spikes,
    saturate,
    threshold_amplitude,
)
from fingertip_dolfinx.errors import InputError
from fingertip_dolfinx.geometry.section import load_section

COARSE = ["section.mesh.min_size=0.2", "section.mesh.max_size=1.0", "section.mesh.bone_size=2.0",
          "output.profile_points=61", "output.pictures=false", 'output.receptors="default"']
SECTION = load_section("male-index")


# --- the neuron ------------------------------------------------------------------------------


@pytest.mark.parametrize("current", [1.01, 1.5, 3.0, 40.0])
def test_constant_current_fires_at_the_closed_form_rate(current):
    """r = 1/(t_ref + τ ln(J/(J − 1))): first spike at τ ln(J/(J − 1)) from rest, then every
    1/r; on one long step and on 1000 short ones (the state carried across the steps)."""
    tau, t_ref = 0.01, 0.002
    period = 1.0 / constant_current_rate(current, tau, t_ref)
    assert period == pytest.approx(t_ref + tau * math.log(current / (current - 1)), rel=1e-15)
    for t in (np.array([0.0, 2.0]), np.linspace(0.0, 2.0, 1001)):
        j = np.full(len(t) - 1, current)
        spikes = lif_spikes(t, j, j, tau, t_ref)
        assert spikes[0] == pytest.approx(period - t_ref, rel=1e-12)
        assert len(spikes) == int((2.0 + t_ref) / period)
        np.testing.assert_allclose(np.diff(spikes), period, rtol=1e-12)


def test_no_spikes_at_or_below_the_threshold():
    t = np.linspace(0.0, 10.0, 11)
    for current in (0.0, 0.5, 0.999999, 1.0):
        j = np.full(10, current)
        assert len(lif_spikes(t, j, j, 0.01, 0.001)) == 0
        assert constant_current_rate(current, 0.01, 0.001) == 0.0
    # a ramp that ends on the threshold never reaches it; just above, it does
    assert len(lif_spikes([0.0, 1.0], [0.0], [1.0], 0.01, 0.001)) == 0
    assert len(lif_spikes([0.0, 1.0], [0.0], [1.1], 0.01, 0.001)) > 0


def test_the_saturation_caps_the_rate():
    p7 = 10.0
    current = np.array([-50.0, -1.0, 0.0, 1.0, 9.0, 1e3, 1e9])
    np.testing.assert_allclose(saturate(current, p7), p7 * current / (p7 + np.abs(current)))
    assert np.all(np.diff(saturate(current, p7)) > 0) and saturate(1e12, p7) < p7
    np.testing.assert_array_equal(saturate(current, 0.0), current)  # p7 = 0: none
    lif = LIF(tau=0.05, refractory=0.0012, saturation=p7, weights=(1.0, 0, 0, 0, 0, 0))
    cap = 1.0 / (0.0012 + 0.05 * math.log(p7 / (p7 - 1)))  # the rate as J -> p7
    t = np.linspace(0.0, 5.0, 6)
    rates = [len(lif.spikes(t, np.concatenate([[0.0], np.full(5, s)]), "constant")) / 5.0
             for s in (2.0, 20.0, 200.0, 2e6)]
    assert np.all(np.diff(rates) > 0) and rates[-1] <= cap * (1 + 1e-3)
    assert rates[-1] == pytest.approx(cap, rel=3e-3)


def _rk4_spikes(t_end, current, tau, t_ref, dt):
    """A fine reference: RK4 in steps of dt, the crossing located by linear interpolation."""
    spikes, v, t, free = [], 0.0, 0.0, 0.0
    def f(t, v):
        return (-v + current(t)) / tau
    while t < t_end - 1e-15:
        if t < free:
            t, v = min(free, t_end), 0.0
            continue
        k1 = f(t, v)
        k2 = f(t + dt / 2, v + dt / 2 * k1)
        k3 = f(t + dt / 2, v + dt / 2 * k2)
        k4 = f(t + dt, v + dt * k3)
        v_new = v + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        if v_new >= 1.0:
            crossing = t + dt * (1.0 - v) / (v_new - v)
            spikes.append(crossing)
            t, v, free = crossing, 0.0, crossing + t_ref
            continue
        t, v = t + dt, v_new
    return np.array(spikes)


@pytest.mark.parametrize("j0, j1", [(0.0, 6.0), (6.0, 0.5)])
def test_a_ramp_is_integrated_exactly(j0, j1):
    """Linear current on one step: the closed form's spikes agree with RK4 at dt = 2 µs (to
    10 ns), and with the same ramp cut into 500 steps to round-off (no time-step error)."""
    tau, t_ref, t_end = 0.02, 0.002, 1.0
    spikes = lif_spikes([0.0, t_end], [j0], [j1], tau, t_ref)
    t = np.linspace(0.0, t_end, 501)
    j = j0 + (j1 - j0) * t / t_end
    cut = lif_spikes(t, j[:-1], j[1:], tau, t_ref)
    reference = _rk4_spikes(t_end, lambda s: j0 + (j1 - j0) * s / t_end, tau, t_ref, 2e-6)
    assert len(spikes) > 20 and len(spikes) == len(cut) == len(reference)
    np.testing.assert_allclose(cut, spikes, rtol=0, atol=1e-13)
    np.testing.assert_allclose(reference, spikes, rtol=0, atol=1e-8)  # its interpolation


# --- the data and the sites ------------------------------------------------------------------


def test_sites_lie_at_the_class_depth_and_spacing():
    """Every site at its class depth below the outer ellipse (exact normal offset), one at
    x = 0, neighbours 1/sqrt(density) apart in arc length along the surface, all within the
    half-width and none missing at its ends."""
    population = load_receptors()
    sites = population.sites(SECTION.outer)
    outer = SECTION.outer
    assert len(sites) == 11 + 15 + 7
    for c in population.classes:
        mine = sites.cls == c.name
        np.testing.assert_allclose(outer.distance(sites.points[mine]), c.depth, atol=1e-12)
        np.testing.assert_array_equal(sites.index[mine], np.arange(mine.sum()))
        x = sites.x[mine]
        u = -np.arccos(x / outer.a)  # palmar arc: u in (−π, 0)
        arcs = [outer.arc_length(u[i], u[i + 1]) for i in range(len(u) - 1)]
        np.testing.assert_allclose(arcs, 10 / math.sqrt(c.density), rtol=1e-10)
        assert 0.0 in x and np.all(np.abs(x) <= population.half_width)
        assert outer.arc_length(u[-1], -math.acos(population.half_width / outer.a)) < c.spacing
        inward = sites.points[mine] - np.column_stack([x, outer.cy - outer.b * np.sqrt(
            1 - (x / outer.a) ** 2)])  # along the inward normal: towards the centre
        assert np.all(inward[:, 1] > 0)


def test_the_shipped_parameters_meet_their_criteria():
    """The criteria written next to the parameters in data/receptors/default.toml."""
    population = load_receptors()
    sa1, ra, pc = population["SA1"], population["RA"], population["PC"]
    assert (sa1.spacing, ra.spacing, pc.spacing) == pytest.approx((1.1952, 0.8452, 2.0),
                                                                  abs=1e-4)
    # I = 1 at the stated stimulus levels (before the saturation)
    assert sa1.lif.weights[0] * 1e-6 == pytest.approx(1.0)
    assert ra.lif.weights[2] * 1e-3 == ra.lif.weights[3] * 1e-3 == pytest.approx(1.0)
    assert pc.lif.weights[4] * 0.04 == pc.lif.weights[5] * 0.04 == pytest.approx(1.0)
    assert (2 * math.pi * 250) ** 2 * 0.016e-6 == pytest.approx(0.04, rel=0.02)
    assert sa1.sed_gain * 1e-4 == pytest.approx(100.0)
    # SA1 saturates towards 155 spikes/s
    assert sa1.lif.rate(sa1.lif.saturation * (1 - 1e-12)) == pytest.approx(154.6, abs=0.1)
    # the rheobase of a static SA1 input lies at p7/(p7 − 1) of the stated level
    t = np.array([0.0, 1e-6, 10.0])
    for level, fires in ((1e-6 * 10 / 9 * (1 - 1e-6), False), (1e-6 * 10 / 9 * 1.01, True)):
        assert (len(sa1.lif.spikes(t, [0.0, level, level])) > 0) == fires


def test_threshold_amplitude_follows_each_class_term_at_low_frequency():
    """Transduction stage alone, s = A sin(2π f t): a static weight's threshold tends to the
    rheobase, a rate weight's falls as 1/f, an acceleration weight's as 1/f²."""
    population = load_receptors()
    rheobase = 10 / 9  # I at J = 1 for p7 = 10
    sa1, ra, pc = (population[c].lif for c in ("SA1", "RA", "PC"))
    assert threshold_amplitude(sa1, 0.2) == pytest.approx(rheobase / sa1.weights[0], rel=5e-3)
    for f in (1.0, 2.0):
        expected = rheobase / (ra.weights[2] * 2 * math.pi * f)
        assert threshold_amplitude(ra, f) == pytest.approx(expected, rel=5e-3)
    expected = rheobase / (pc.weights[4] * (2 * math.pi * 10.0) ** 2)
    assert threshold_amplitude(pc, 10.0) == pytest.approx(expected, rel=5e-3)
    # the membrane's low pass: above 1/(2πτ) the threshold rises above the quasi-static one
    assert threshold_amplitude(sa1, 20.0) > 2 * threshold_amplitude(sa1, 0.2)


def test_a_set_reads_back_from_its_record():
    population = load_receptors()
    again = receptors_from_dict(population.record())
    assert again == population and again.description == population.description


@pytest.mark.parametrize("override, named", [
    ({"SA1": {"depht": 0.75}}, "SA1.depht"),
    ({"RA": {"density": -1.0}}, "RA.density"),
    ({"PC": {"quantity": "von_mises"}}, "PC.quantity"),
    ({"SA1": {"lif": {"tau": 0.0}}}, "SA1.lif.tau"),
    ({"SA1": {"lif": {"p1": 1.0}}}, "SA1.lif.p1"),
    ({"RA": {"lif": {"refractory": -1e-3}}}, "RA.lif.refractory"),
    ({"sites": {"half_width": "6"}}, "sites.half_width"),
    ({"SA2": {"depth": 0.3}}, "SA2"),
])
def test_bad_receptor_data_is_named(override, named):
    with pytest.raises(InputError) as error:
        load_receptors("default", override)
    assert named in str(error.value)


def test_bad_sites_and_scene_outputs_are_named():
    from fingertip_dolfinx.scene import load_scene

    with pytest.raises(InputError, match="sites.half_width"):
        load_receptors("default", {"sites": {"half_width": 9.0}}).sites(SECTION.outer)
    with pytest.raises(InputError, match="PC.depth"):
        load_receptors("default", {"PC": {"depth": 7.0}}).sites(SECTION.outer)
    with pytest.raises(InputError, match="output.receptors") as error:
        load_scene("1pt", ['output.receptors="no-such-set"'])
    assert "default" in str(error.value)  # the fix lists the built-in sets
    with pytest.raises(InputError, match="output.receptors"):
        load_scene("1pt", ["output.receptors=3"])
    assert load_scene("1pt", ["output.receptors=false"]).outputs.receptors == ""


# --- the stress field ------------------------------------------------------------------------


def test_cauchy_stress_is_each_laws_own_at_the_accepted_state():
    """A homogeneous deformation of a square of skin (QLV, with a stored history) and of
    bone: the DG1 field is F S Fᵀ/J with S = g∞ S_e + Σ g_i h_i, and F S_e Fᵀ/J (SVK)."""
    from dolfinx import fem, mesh

    from fingertip_dolfinx.model import Elastic, State, Viscoelastic
    from fingertip_dolfinx.physics.kinematics import deformation_gradient
    from fingertip_dolfinx.physics.materials import cauchy_stress, second_piola_kirchhoff
    from fingertip_dolfinx.physics.tissues import WU2004
    from fingertip_dolfinx.post import CauchyStress

    msh = mesh.create_unit_square(MPI.COMM_WORLD, 3, 3)
    n = msh.topology.index_map(2).size_local + msh.topology.index_map(2).num_ghosts
    cells = np.arange(n, dtype=np.int32)
    left = cells[mesh.compute_midpoints(msh, 2, cells)[:, 0] < 0.5]
    right = np.setdiff1d(cells, left)
    tags = mesh.meshtags(msh, 2, np.concatenate([left, right]),
                         np.concatenate([np.full(len(left), 1), np.full(len(right), 3)]
                                        ).astype(np.int32))
    u = fem.Function(fem.functionspace(msh, ("Lagrange", 2, (2,))))
    F0 = np.array([[1.1, 0.2], [-0.05, 0.8]])
    u.interpolate(lambda x: np.stack([(F0[0, 0] - 1) * x[0] + F0[0, 1] * x[1],
                                      F0[1, 0] * x[0] + (F0[1, 1] - 1) * x[1]]))
    F = deformation_gradient(u)
    state = State(u, F, fem.Constant(msh, 0.1), 4, {"skin": left})
    skin = Viscoelastic(WU2004.skin, WU2004.skin_prony, state, "skin")
    h = [np.array([[1e-3, 2e-4], [2e-4, -5e-4]]), np.array([[-3e-4, 0.0], [0.0, 7e-4]])]
    for f, value in zip(skin.history.h, h):
        f.x.array[:] = np.tile(value.ravel(), len(f.x.array) // 4)
    bone = Elastic(WU2004.bone, state)
    field = CauchyStress(u, tags, {1: skin, 3: bone}, 4)
    field.update()

    def at_a_point(expr):  # u is linear: F, and so every stress, is the same everywhere
        e = fem.Expression(expr, np.array([[0.3, 0.3]]))
        return e.eval(msh, np.array([0], dtype=np.int32)).reshape(2, 2)

    np.testing.assert_allclose(at_a_point(F), F0, rtol=1e-13)
    prony = WU2004.skin_prony
    S_e = at_a_point(second_piola_kirchhoff(WU2004.skin, F))
    S = prony.g_inf * S_e + sum(g * hi for g, hi in zip(prony.g, h))
    want = {1: F0 @ S @ F0.T / np.linalg.det(F0), 3: at_a_point(cauchy_stress(WU2004.bone, F))}
    values = field.stress.x.array.reshape(-1, 4)
    dofs = field.stress.function_space.dofmap.list
    for tag, mine in ((1, left), (3, right)):
        got = values[dofs[mine]].reshape(-1, 4)
        np.testing.assert_allclose(got, np.tile(want[tag].ravel(), (len(got), 1)),
                                   rtol=1e-10, atol=1e-14)


# --- a run -----------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def one_point(tmp_path_factory):
    from fingertip_dolfinx.runner import run
    from fingertip_dolfinx.scene import load_scene

    out = MPI.COMM_WORLD.bcast(tmp_path_factory.mktemp("1pt-receptors"), root=0)
    return run(load_scene("1pt", COARSE), out, progress=False)


def test_a_run_writes_every_site_at_every_step(one_point):
    table = one_point.receptors()
    assert tuple(table) == RECEPTOR_COLUMNS
    assert receptors_from_dict(json.loads((one_point.out / "receptors.json").read_text())) == (
        load_receptors())
    sites = load_receptors().sites(SECTION.outer)
    steps = one_point.time
    assert len(table["time_s"]) == len(sites) * len(steps)
    for t in steps:
        rows = table["time_s"] == t
        assert sorted(zip(table["class"][rows], table["index"][rows])) == sorted(
            zip(sites.cls, sites.index))
    # the pore pressure only in the subcutaneous tissue: at the PC sites (2 mm), not above
    pc = table["class"] == "PC"
    assert np.all(np.isfinite(table["p_MPa"][pc])) and np.all(np.isnan(table["p_MPa"][~pc]))


def test_the_sites_under_the_bar_see_the_most(one_point):
    """At the end of the ramp the SA1 site under the bar has the largest SED (by far), the
    largest compression, and a vertical stress of the order of the bar's mean pressure."""
    table, end = one_point.receptors(), one_point.time[-1]
    last = table["time_s"] == end
    for name in ("SA1", "RA", "PC"):
        rows = last & (table["class"] == name)
        centre = np.argmin(np.abs(table["x_mm"][rows]))
        assert table["x_mm"][rows][centre] == 0.0
        assert np.argmax(table["sed_MPa"][rows]) == centre
        assert np.argmin(table["e_min"][rows]) == centre
        assert np.argmin(table["sigma22_MPa"][rows]) == centre
    sa1 = last & (table["class"] == "SA1")
    sed = np.sort(table["sed_MPa"][sa1])
    assert sed[-1] > 10 * sed[-2]
    pressure = one_point.force[-1] / 1.0  # N/mm over the 1 mm wide bar
    ra = last & (table["class"] == "RA") & (table["x_mm"] == 0.0)
    assert 0.5 * pressure < -table["sigma22_MPa"][ra][0] < 2 * pressure


def test_the_afferents_respond_to_the_ramp(one_point):
    """SED-proportional SA1 rates grow monotonically with the indentation under the bar;
    the LIF SA1 under the bar fires, the far ones do not; RA under the bar fires during the
    ramp."""
    r = afferent_responses(one_point)  # the set recorded in receptors.json
    assert r.time[0] == 0.0 and np.all(np.diff(r.time) > 0)
    sa1 = r.of("SA1")
    near = sa1 & (np.abs(r.x) < 1.5)
    assert near.sum() == 3
    assert np.all(np.diff(r.sed_rate[:, near], axis=0) > 0)
    np.testing.assert_allclose(r.sed_rate[:, sa1], 1e6 * r.stimulus[:, sa1])
    assert np.all(np.isnan(r.sed_rate[:, ~sa1]))
    centre = sa1 & (r.x == 0.0)
    assert r.mean_rate[centre][0] > 10 and r.rate[-1, centre][0] > 50
    assert np.all(r.mean_rate[sa1 & (np.abs(r.x) > 3)] == 0)
    ra = r.of("RA") & (r.x == 0.0)
    assert r.mean_rate[ra][0] > 0
    for spikes in r.spikes:
        assert np.all((spikes > 0) & (spikes <= r.time[-1]))


# --- the Saal et al. 2017 afferents as a class's model ----------------------------------------


def test_the_calibrated_set_reads_back_and_names_its_model():
    population = load_receptors("calibrated")
    assert {c.model for c in population.classes} == {"saal2017"}
    assert receptors_from_dict(population.record()) == population
    assert len(population["RA"].saal.afferents("RA")) == 9


@pytest.mark.parametrize("base, cls, change, named", [
    ("default", "PC", {"model": "hodgkin-huxley"}, "PC.model"),
    ("default", "PC", {"model": "saal2017"}, "[PC.saal2017]"),
    ("calibrated", "RA", {"saal2017": {"input_scale": 1.0, "fits": [9]}}, "RA.saal2017.fits"),
    ("calibrated", "SA1", {"saal2017": {"input_scale": -1.0}}, "SA1.saal2017.input_scale"),
    ("calibrated", "PC", {"model": "lif"}, "[PC.lif]"),
])
def test_bad_model_choices_are_named(base, cls, change, named):
    data = load_receptors(base).record()
    data[cls].update(change)
    with pytest.raises(InputError) as error:
        receptors_from_dict(data)
    assert named in str(error.value)


def test_the_fitted_afferents_respond_to_the_ramp(one_point):
    """The time route with TouchSim's fits on the same run (the calibrated set reads −σ22):
    the far SA1 sites stay silent; the slow ramp (1 mm in 1 s; TouchSim's own ramps take 50 ms)
    leaves the RA and PC fits, driven by the rate of the stress, silent (RA under the bar:
    α κ ṡ ≈ 0.013 per sample with the wu2004 calibration's α, v ≈ 0.1 < 1)."""
    r = afferent_responses(one_point, "calibrated")
    sa1 = r.of("SA1")
    assert np.all(r.mean_rate[sa1 & (r.x != 0.0)] == 0)
    assert np.all(r.mean_rate[~sa1] == 0)


def test_the_sa1_under_the_bar_fires_on_the_ramp(one_point):
    """The SA1 under the bar fires as the press deepens, as TouchSim's SA1 fits fire on its own
    1 mm ramp (tests/data/touchsim_reference.json) and recorded SA1 fire to sustained
    indentation. It runs fit 1, the least sensitive of the four; it fires because SA1's input
    scale is fitted to the sustained static input of TouchSim's ramp-and-hold (α = 45.3;
    measured: 17 spikes from 0.40 s, 37 spikes/s over the last step, 0.71-1 s). With the
    sinusoids' α (12.44) it was silent: the next test."""
    r = afferent_responses(one_point, "calibrated")
    centre = r.of("SA1") & (r.x == 0.0)
    assert r.mean_rate[centre][0] > 1 and r.rate[-1, centre][0] > 5


def test_the_sa1_static_input_at_1_mm_exceeds_every_fits_rheobase(one_point):
    """Why the SA1 under the bar fires: at the end of the 1 mm ramp its static input α s
    exceeds the rheobase 1/(p1 τ) of each of TouchSim's four SA1 fits (the constant static
    input at which the leaky integrator's v = J τ reaches 1; fit 1, run by the site under the
    bar, has the highest, 0.0166 MPa). The slow ramp's rate input adds only ~10 % of the
    threshold, so below every rheobase nothing fires: with the sinusoids' α = 12.44,
    α s = 0.0136 MPa and fit 1 was silent. Now (α = 45.3) α s ≈ 0.05 MPa, ~1.2 of TouchSim's
    own static input under its pin at 1 mm (c_s · 1 mm = 0.0426 MPa), and every fit fires,
    fit 1 the fewest, as on each of TouchSim's stored ramps."""
    r = afferent_responses(one_point, "calibrated")
    j = np.flatnonzero(r.of("SA1") & (r.x == 0.0))[0]
    sa1 = load_receptors("calibrated")["SA1"]
    aff = sa1.saal.afferents("SA1")
    rheobase = 1.0 / (aff.weights[:, 0] * aff.tau)
    assert r.index[j] % 4 == 1 and np.argmax(rheobase) == 1
    assert sa1.saal.input_scale * r.stimulus[-1, j] > rheobase.max()
    trains = saal_spikes(sa1, [4, 5, 6, 7], r.time, np.tile(r.stimulus[:, j], (4, 1)))
    counts = [len(t) for t in trains]
    assert min(counts) > 0 and np.argmin(counts) == 1, counts
    ref = json.loads((Path(__file__).parent / "data" / "touchsim_reference.json").read_text())
    for rec in (x for x in ref["stimuli"] if x["kind"] == "ramp"):
        sa1_counts = [x["count"] for x in rec["responses"] if x["class"] == "SA1"]
        assert sa1_counts[1] == min(sa1_counts), (rec["label"], sa1_counts)


def test_the_calibrated_set_holds_the_calibrations_scales():
    """calibrated.toml's α per class is the one its calibration record states (docs/results/
    afferents/calibration.json, scripts/calibrate_afferents.py), to the file's 4 digits, and
    SA1's was fitted to the hold of TouchSim's ramps, RA's and PC's to the sinusoids."""
    record = json.loads((Path(__file__).parents[1] / "docs" / "results" / "afferents" /
                         "calibration.json").read_text())["classes"]
    for c in load_receptors("calibrated").classes:
        assert c.saal.input_scale == pytest.approx(record[c.name]["input_scale"], rel=5e-4)
        assert ("hold" in record[c.name]["fitted_to"]) == (c.name == "SA1")


@pytest.mark.slow
def test_sa1_fire_in_the_hold_of_a_quarter_millimetre_press(tmp_path, monkeypatch):
    """TouchSim's 0.25 mm ramp-and-hold (50 ms ramp, held) on the coarse damped section
    (benchmarks/touchsim_ramps.py, ~2 min): the SA1 under the bar fire in the hold, as
    TouchSim's fits do (7.5 spikes/s, the mean of its four) and recorded SA1 do under a few
    hundred µm of sustained indentation. With the sinusoids' α (12.44) no fit fired in the
    hold nor the ramp; now measured 4.7 spikes/s (0.63 of TouchSim's)."""
    monkeypatch.syspath_prepend(str(Path(__file__).parents[1] / "benchmarks"))
    from touchsim_ramps import package_rates, run_ramp, touchsim_rates

    sa1 = load_receptors("calibrated")["SA1"]
    ours, _ = package_rates(run_ramp(0.25, tmp_path / "ramp"), sa1)
    theirs, _ = touchsim_rates(0.25, "SA1")
    assert theirs[:, 1].mean() > 0 and ours[:, 1].mean() > 0.25 * theirs[:, 1].mean()


# --- spike trains, the afferent list and the rate histories of a run --------------------------


def test_the_spike_file_holds_the_responses_spike_times(one_point):
    """spikes.csv holds exactly the spike times of `afferent_responses` on the run's own set
    (full precision: read back bit for bit), afferent by afferent, in time order."""
    r = afferent_responses(one_point)
    spikes = one_point.spikes
    assert sum(len(s) for s in r.spikes) == len(spikes["time_s"]) > 0
    for j, train in enumerate(r.spikes):
        rows = spikes["afferent"] == j
        np.testing.assert_array_equal(spikes["time_s"][rows], train)
        assert set(spikes["class"][rows]) <= {r.cls[j]}
        assert set(spikes["site"][rows]) <= {r.index[j]}


def test_the_afferent_list_names_each_site_and_its_model(one_point):
    """afferents.csv: one row per site of the set, at the site's reference position and
    depth, with its model and its spike count over the run."""
    from fingertip_dolfinx.afferents.receptors import AFFERENT_COLUMNS

    a = one_point.afferents
    assert tuple(a) == AFFERENT_COLUMNS
    sites = load_receptors().sites(SECTION.outer)
    assert len(a["afferent"]) == len(sites)
    np.testing.assert_array_equal(a["afferent"], np.arange(len(sites)))
    np.testing.assert_array_equal(a["class"], sites.cls)
    np.testing.assert_array_equal(a["site"], sites.index)
    np.testing.assert_array_equal(np.column_stack([a["x_mm"], a["y_mm"]]), sites.points)
    np.testing.assert_array_equal(a["depth_mm"], sites.depth)
    assert set(a["model"]) == {"lif"} and set(a["fit"]) == {-1}
    counts = np.bincount(one_point.spikes["afferent"], minlength=len(sites))
    np.testing.assert_array_equal(a["spikes"], counts)
    np.testing.assert_array_equal(a["mean_rate_per_s"], counts / one_point.time[-1])


def test_the_rate_histories_are_the_spike_counts_per_bin(one_point):
    """rates.npz: per afferent and 10 ms bin the count of spikes.csv's times in the bin
    (exact), the rate = count / width; the bins cover the run."""
    rates, spikes = one_point.rates, one_point.spikes
    edges = rates["edges_s"]
    assert edges[0] == 0.0 and edges[-1] == one_point.time[-1]
    np.testing.assert_allclose(np.diff(edges), 0.01, rtol=1e-9)
    for j in rates["afferent"]:
        times = spikes["time_s"][spikes["afferent"] == j]
        expected = [np.sum((times >= lo) & ((times < hi) | (hi == edges[-1])))
                    for lo, hi in zip(edges[:-1], edges[1:])]
        np.testing.assert_array_equal(rates["counts"][:, j], expected)
    np.testing.assert_array_equal(rates["rate_per_s"], rates["counts"] / np.diff(edges)[:, None])
    assert rates["counts"].sum() == len(spikes["time_s"])


def test_rate_bins_end_at_the_run_and_stay_few():
    from fingertip_dolfinx.afferents.receptors import rate_bins

    np.testing.assert_allclose(rate_bins(0.025), [0.0, 0.01, 0.02, 0.025])
    assert len(rate_bins(1.0)) == 101 and rate_bins(1.0)[-1] == 1.0
    long = rate_bins(100.0)
    assert len(long) == 1001 and np.allclose(np.diff(long), 0.1)
    with pytest.raises(InputError, match="end"):
        rate_bins(0.0)


def test_spike_trains_need_a_model_for_every_class_sampled(one_point):
    """A set without the class a run sampled cannot give its spikes: the error names the
    class and the set; a run without receptors says it has no spike file."""
    data = load_receptors().record()
    del data["PC"]
    with pytest.raises(InputError, match="'PC'.*not in the set"):
        afferent_responses(one_point, receptors_from_dict(data))
    from fingertip_dolfinx.result import Result

    bare = Result(one_point.out)
    bare.out = one_point.out / "checkpoint"  # a folder without the files
    with pytest.raises(InputError, match="spikes.csv"):
        _ = bare.spikes
