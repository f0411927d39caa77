"""Afferent responses to vibration (vibrotactile.py) against closed forms, each tolerance
derived from the method: the vectorised integrator against the scalar one of receptors.py
(same piecewise-linear current: identical counts), the constant-current rate, the
quasi-static rate of a slow modulation, the periodic membrane of a linear low-pass, and the
1/(ω|H|) and 1/(ω²|H|) threshold laws of rate- and acceleration-driven classes."""

import dataclasses
import math

import numpy as np
import pytest

from fingertip_dolfinx.afferents import vibrotactile as vt
from fingertip_dolfinx.afferents.receptors import (
    LIF,
    constant_current_rate,
    lif_spikes,
    load_receptors,
)
from fingertip_dolfinx.errors import InputError

N = vt.SAMPLES
INTERP = (2 * math.pi / N) ** 2 / 8  # relative error of J's linear interpolation (smooth parts)


def static_lif(tau=0.01, t_ref=0.002, p1=1.0, saturation=0.0):
    return LIF(tau=tau, refractory=t_ref, saturation=saturation, weights=(p1, 0, 0, 0, 0, 0))


# --- the integrator ------------------------------------------------------------------------


@pytest.mark.parametrize("amplitude", [2e-5, 5e-5, 2e-4])
def test_lanes_match_the_scalar_exact_integrator(amplitude):
    """The same piecewise-linear current (one cycle of samples repeated) through
    receptors.lif_spikes and through the vectorised lanes: the same spikes in every cycle."""
    lif = load_receptors()["RA"].lif
    f, cycles = 40.0, 6
    j = vt.cycle_current(lif, f, amplitude, 0.0)
    counts = vt.spike_counts(j, 1 / f, lif.tau, lif.refractory, cycles)[0]
    t = np.linspace(0.0, cycles / f, cycles * N + 1)
    j0, j1 = np.tile(j[0, :-1], cycles), np.tile(j[0, 1:], cycles)
    spikes = lif_spikes(t, j0, j1, lif.tau, lif.refractory)
    reference = np.histogram(spikes, bins=np.arange(cycles + 1) / f)[0]
    assert reference.sum() > 0 or amplitude < 5e-5
    np.testing.assert_array_equal(counts, reference)


def test_a_constant_current_fires_at_the_closed_form_rate():
    """a = 0, J = p1 s0 constant: a regular train of period P = t_ref + τ ln(J/(J − 1)); the
    count over a window W is W/P to within one spike."""
    lif = static_lif()
    f, cycles = 10.0, 50
    for s0 in (1.2, 3.0, 30.0):
        counts = vt.cycle_response(lif, f, 0.0, s0, cycles=cycles)
        period = 1 / constant_current_rate(s0, lif.tau, lif.refractory)
        assert abs(counts.sum() - cycles / f / period) <= 1.0


def test_a_slow_modulation_follows_the_quasi_static_rate():
    """J = p1 (s0 + a sin ωt) with the ISI ≪ the period: the count over the window equals
    ∫ r(J(t)) dt to within 1 + (window's spikes) × max|P'/P| δJ, where δJ = max|J'| · max ISI
    bounds the change of J within one interval (each ISI lies between P(J ± δJ):
    comparison principle)."""
    lif = static_lif(tau=0.002, t_ref=0.001)
    f, cycles, s0, a = 1.0, 4, 3.0, 1.0
    counts = vt.cycle_response(lif, f, a, s0, cycles=cycles, samples=4096).sum()
    theta = np.linspace(0.0, 2 * np.pi, 200001)
    rate = constant_current_rate(s0 + a * np.sin(theta), lif.tau, lif.refractory)
    expected = cycles / f * np.trapezoid(rate, theta) / (2 * np.pi)
    def period(j):
        return lif.refractory + lif.tau * np.log(j / (j - 1))
    j_low = s0 - a
    delta_j = a * 2 * np.pi * f * period(j_low)
    log_slope = lif.tau / (j_low * (j_low - 1)) / period(j_low)  # max |P'/P| at the lowest J
    assert abs(counts - expected) <= 1 + expected * log_slope * delta_j
    assert expected > 1000  # the bound is a relative 5e-4 here, far below the cycle's 2:1 swing


def test_the_periodic_membrane_of_a_linear_input_is_the_low_pass():
    """J = p1 (s0 + a sin θ) without rectification: v_p = p1 s0 + p1 a sin(θ − atan ωτ) /
    sqrt(1 + (ωτ)²); max to within the interpolation error p1 a (2π/N)²/8; and v_p is periodic."""
    lif = static_lif(tau=0.01)
    for f in (1.0, 15.9, 100.0):
        wt = 2 * np.pi * f * lif.tau
        j = vt.cycle_current(lif, f, 0.3, 0.5)
        v, peak = vt.periodic_membrane(j, [1 / f], lif.tau)
        assert v[0, -1] == pytest.approx(v[0, 0], rel=1e-12)
        assert peak[0] == pytest.approx(0.5 + 0.3 / math.hypot(1, wt), abs=0.3 * INTERP)


def test_the_absolute_threshold_of_a_linear_input_is_exact():
    """From the low-pass: I0 = (1 − p1 s0) sqrt(1 + (ωτ)²) / p1, while no rectification acts
    (I0 <= s0); tolerance: the bisection's rtol plus the interpolation error."""
    lif = static_lif(tau=0.01, p1=1.0)
    s0, rtol = 0.6, 1e-4
    f = np.array([0.5, 5.0, 15.0])
    got = vt.absolute_threshold_stimulus(lif, f, s0, rtol=rtol)
    expected = (1 - s0) * np.hypot(1, 2 * np.pi * f * lif.tau)
    np.testing.assert_allclose(got, expected, rtol=rtol + 2 * INTERP * 0.6 / 0.4)


# --- threshold laws of the classes -----------------------------------------------------------


@pytest.mark.parametrize("name, power", [("RA", 1), ("PC", 2)])
def test_rate_and_acceleration_classes_follow_omega_laws(name, power):
    """RA reads [ṡ]±, PC [s̈]±: with no saturation and ωτ ≪ 1 the membrane follows J, so
    I0 = 1/(p ω^k) times a factor in [1, 1/(1 − (ωτ)²)] (v(t*) >= Jmax (1 − (ωτ)²), since
    [cos]+ >= 1 − θ²/2), the interpolation error and the bisection's rtol on top. On the probe:
    I0 / |H| for every site."""
    lif0 = load_receptors()[name].lif
    lif = LIF(tau=lif0.tau, refractory=lif0.refractory, saturation=0.0, weights=lif0.weights)
    p = lif.weights[2 * power]
    rtol = 1e-4
    omega_tau = np.array([0.02, 0.05, 0.1])
    f = omega_tau / (2 * np.pi * lif.tau)
    got = vt.absolute_threshold_stimulus(lif, f, 0.0, rtol=rtol)
    law = 1 / (p * (2 * np.pi * f) ** power)
    assert np.all(got >= law * (1 - INTERP))
    assert np.all(got <= law / (1 - omega_tau**2) * (1 + INTERP) * (1 + rtol))
    # on the probe: the same stimulus threshold divided by |H|, whatever the phase
    cls = load_receptors()[name]
    gains = np.array([0.5, 1.0, 4.0]) * np.exp(1j * np.array([0.0, 1.0, -2.0]))
    th = vt.vibration_thresholds(cls, f[:1], gains[None, :], np.zeros(3), rtol=rtol)
    np.testing.assert_allclose(th.absolute[0] * np.abs(gains), th.absolute_stimulus[0, 0],
                               rtol=1e-14)


def test_entrainment_at_low_frequency_equals_the_absolute_threshold():
    """ωτ ≪ 1: every cycle starts from the silent half-cycle's v ≈ 0 (to e^{−T/2τ}), so a spike
    in one cycle is a spike in all: I1 = I0 to the two bisections' rtol. I1 >= I0 always; I1 =
    inf when the period is below the refractory period."""
    lif = load_receptors()["RA"].lif
    rtol = 1e-3
    f = np.array([2.0, 5.0, 900.0])
    i0 = vt.absolute_threshold_stimulus(lif, f, 0.0, rtol=rtol)
    i1 = vt.entrainment_threshold_stimulus(lif, f, 0.0, rtol=rtol, absolute=i0)
    np.testing.assert_allclose(i1[:2], i0[:2], rtol=2.5 * rtol)
    assert 1 / f[2] < lif.refractory and i1[2] == np.inf
    mid = np.geomspace(20, 400, 5)
    i0m = vt.absolute_threshold_stimulus(lif, mid, 0.0, rtol=rtol)
    i1m = vt.entrainment_threshold_stimulus(lif, mid, 0.0, rtol=rtol, absolute=i0m)
    assert np.all(i1m >= i0m * (1 - 2 * rtol))


def test_rate_grows_from_zero_to_one_per_cycle_between_the_thresholds():
    """Freeman & Johnson's ramp: 0 impulses/cycle below I0, 1 per cycle at I1 and a little
    above, monotone in between (one RA site, 40 Hz)."""
    cls = load_receptors()["RA"]
    f = 40.0
    th = vt.vibration_thresholds(cls, [f], [[1.0]], [0.0], rtol=1e-3)
    i0, i1 = th.absolute[0, 0], th.entrainment[0, 0]
    amps = np.array([0.98 * i0, i1 * 1.01])
    rates = vt.rate_vs_amplitude(cls, [f], [[1.0]], [0.0], amps)[0, 0]
    assert rates[0] == 0.0 and rates[1] == pytest.approx(f)
    ramp = vt.rate_vs_amplitude(cls, [f], [[1.0]], [0.0], np.geomspace(i0, i1, 8))[0, 0]
    assert np.all(np.diff(ramp) >= -f / 20)  # monotone to one count in the 20 cycles


# --- the SED rate and the checks -----------------------------------------------------------


def test_sed_rate_is_the_mean_of_the_rectified_stimulus():
    s0 = np.array([0.0, 1.0, 1.0, 1.0])
    a = np.array([1.0, 0.5, 1.0, 3.0])
    theta = np.linspace(0.0, 2 * np.pi, 2_000_001)
    numeric = [np.trapezoid(np.maximum(s + b * np.sin(theta), 0), theta) / (2 * np.pi)
               for s, b in zip(s0, a)]
    np.testing.assert_allclose(vt.rectified_sine_mean(s0, a), numeric, rtol=1e-10)
    assert vt.rectified_sine_mean(0.0, 1.0) == pytest.approx(1 / np.pi, rel=1e-15)
    sa1 = load_receptors()["SA1"]
    mean, peak = vt.sed_rate(sa1, [10.0], [[2.0]], [1e-4], [1e-5, 1e-4])
    np.testing.assert_allclose(mean[0, 0], sa1.sed_gain * np.array([1e-4, 2e-4 / np.pi * (
        math.sqrt(3) / 2) + 1e-4 * (0.5 + math.asin(0.5) / np.pi)]), rtol=1e-12)
    np.testing.assert_allclose(peak[0, 0], sa1.sed_gain * (1e-4 + 2 * np.array([1e-5, 1e-4])))


def test_bad_input_is_named():
    cls = load_receptors()["RA"]
    with pytest.raises(InputError, match="transfer"):
        vt.vibration_thresholds(cls, [10.0, 20.0], np.ones((3, 2)), np.zeros(2))
    with pytest.raises(InputError, match="frequencies"):
        vt.vibration_thresholds(cls, [0.0], np.ones((1, 2)), np.zeros(2))
    with pytest.raises(InputError, match="SED-rate"):
        vt.sed_rate(cls, [10.0], [[1.0]], [0.0], [1.0])


def test_the_threshold_figure_is_drawn(tmp_path):
    pop = load_receptors()
    f = np.geomspace(5, 500, 6)
    curves = [vt.vibration_thresholds(pop[name], f, np.ones((6, 2)), np.zeros(2))
              for name in ("RA", "PC")]
    legend = vt.plot_threshold_curves(curves, tmp_path / "thresholds.png")
    assert (tmp_path / "thresholds.png").stat().st_size > 10_000
    assert all(p.source and p.read for p in vt.PUBLISHED)
    # every shaded band and bar drawn is explained in the legend: its class and band in Hz
    for p in vt.PUBLISHED:
        if p.band is not None:
            band = f"{p.band[0]:g}–{p.band[1]:g} Hz"
            assert sum(band in entry for entry in legend) >= 1, (p.cls, band, legend)
    assert {"RA I0 absolute", "PC I1 1:1"} <= set(legend)


def test_a_threshold_found_at_no_frequency_is_named_so_in_the_legend(tmp_path):
    """A class and criterion without a threshold at any computed frequency draws no marker;
    its legend entry says so, rather than naming markers the axes do not show."""
    from types import SimpleNamespace

    f = np.array([10.0, 100.0])
    th = SimpleNamespace(name="RA", frequency=f, best=lambda criterion: (
        np.array([2e-3, np.nan]) if criterion == "absolute" else np.full(2, np.nan)))
    legend = vt.plot_threshold_curves([th], tmp_path / "thresholds.png", touchsim=False)
    assert legend[:2] == ["RA I0 absolute", "RA I1 1:1: none"]


def test_a_site_already_firing_has_no_threshold():
    """SA1 reads [s]+ of SED (p1 = 1e6 /MPa, p7 = 10: the rheobase lies at SED = 10/9 × 1e-6
    MPa): a pressed site above it fires without vibration, so neither threshold applies (NaN);
    `best` takes the sites at rest. Below it, the threshold falls as s0 rises."""
    sa1 = load_receptors()["SA1"]
    rheobase = 1e-6 * 10 / 9
    s0 = np.array([0.0, 0.5 * rheobase, 2 * rheobase])
    th = vt.vibration_thresholds(sa1, [5.0], np.ones((1, 3)), s0)
    assert np.isnan(th.absolute[0, 2]) and np.isnan(th.entrainment[0, 2])
    assert th.absolute[0, 1] < th.absolute[0, 0] < np.inf
    assert th.best("absolute")[0] == th.absolute[0, 1]


def test_agrees_with_the_sampled_threshold_of_receptors():
    """receptors.threshold_amplitude (400 samples per cycle, finite-difference rates, from
    rest) and I0 here (exact rates, periodic state) at frequencies where the start-up does not
    matter: both to their rtol (1e-4, 1e-3) plus the differences' O((2π/400)²) = 2.5e-4 and the
    interpolation error here."""
    from fingertip_dolfinx.afferents.receptors import threshold_amplitude

    pop = load_receptors()
    for name, f in (("RA", 5.0), ("PC", 20.0)):
        lif = pop[name].lif
        here = vt.absolute_threshold_stimulus(lif, [f], 0.0, rtol=1e-3)[0]
        there = threshold_amplitude(lif, f)
        assert here == pytest.approx(there, rel=1e-3 + 1e-4 + 2.5e-4 + INTERP)


# --- the Saal et al. 2017 afferents (afferents.transduction) ----------------------------------


def _touchsim_class(name):
    """A class fed TouchSim's own input: α = 1 on its stress, its κ (0.5 mm pin)."""
    import dataclasses

    cls = load_receptors("calibrated")[name]
    return dataclasses.replace(cls, saal=dataclasses.replace(cls.saal, input_scale=1.0))


def test_kappa_is_touchsims_own_rate_input():
    """κ of the calibrated set (rate_factor at TouchSim's depth, 0.5 mm pin) equals the ratio
    c_u/c_s exported from TouchSim's `propagate` (tests/data/touchsim_reference.json) to
    round-off: the dynamic input is TouchSim's, only the input scale α is fitted."""
    import json
    from pathlib import Path

    ref = json.loads((Path(__file__).parent / "data" / "touchsim_reference.json").read_text())
    rec = next(r for r in ref["stimuli"] if r["pin_radius"] == 0.5)
    for cls in load_receptors("calibrated").classes:
        c = rec["input"][cls.name]
        assert cls.saal.kappa(cls.name) == pytest.approx(c["c_u"] / c["c_s"], rel=1e-12)


def test_saal_thresholds_scale_as_one_over_the_input_scale():
    """RA and PC fits weigh only the rate input: doubling α halves both thresholds (to the
    search's 1 % bracket, twice)."""
    import dataclasses

    cls = _touchsim_class("PC")
    twice = dataclasses.replace(cls, saal=dataclasses.replace(cls.saal, input_scale=2.0))
    f = np.array([30.0, 250.0])
    one, two = vt.saal_thresholds_stimulus(cls, f, 0.0), vt.saal_thresholds_stimulus(twice, f, 0.0)
    for a, b in zip(one, two):
        np.testing.assert_allclose(b, a / 2, rtol=0.021)


@pytest.mark.slow
def test_touchsims_own_tuning_has_the_classic_shape():
    """TouchSim's mechanics (H = c_s, flat; no pre-indentation) through the fits: the 1:1
    threshold of the most sensitive fit is lowest at 150-400 Hz for PC and at least 3× higher
    at 1000 Hz (there: inf, 1000 Hz is above the 833/s the 6-sample refractory period
    allows), lowest at 10-80 Hz for RA, below 20 Hz for SA1 (measured: PC 0.66 µm at 198 Hz,
    RA 22 µm at 30 Hz, SA1 58 µm at 6 Hz)."""
    f = np.geomspace(2.0, 1000.0, 16)
    best = {}
    for name in ("SA1", "RA", "PC"):
        i1 = vt.saal_thresholds_stimulus(_touchsim_class(name), f, 0.0)[1]
        best[name] = (f[np.argmin(i1)], i1)
    assert 150 <= best["PC"][0] <= 400 and best["PC"][1][-1] >= 3 * best["PC"][1].min()
    assert 10 <= best["RA"][0] <= 80
    assert best["SA1"][0] < 20


def test_saal_model_site_firing_on_its_pressed_value_has_no_threshold():
    """An SA1 site pressed enough to fire on s0 alone (the fits' static weight) gets NaN."""
    cls = _touchsim_class("SA1")
    i0, i1 = vt.saal_thresholds_stimulus(cls, [10.0, 10.0], [0.0, 0.5])
    assert np.isfinite(i0[0]) and np.isnan(i0[1]) and np.isnan(i1[1])


def test_saal_site_firing_on_its_pressed_value_has_no_entrainment_threshold_either():
    """A pressed SA1 whose ongoing discharge (below the vibration's frequency) could be
    entrained by a small vibration has no I1: I1 is a threshold of an afferent at rest
    (measured before the fix: I1 = 8.7 µm at 23 Hz on the coarse vibrotactile run, with no I0,
    below every I0 of the class)."""
    cls = _touchsim_class("SA1")
    s0 = 0.02  # MPa of TouchSim stress: fires ~10-30 spikes/s on its own (fits 0-3)
    i0, i1 = vt.saal_thresholds_stimulus(cls, [40.0], [s0])
    assert np.isnan(i0[0]) and np.isnan(i1[0])


def test_saal_rate_is_zero_below_i0_and_one_per_cycle_at_i1():
    """Impulses per cycle vs amplitude for a fitted RA (site 0 uses fit 0): none just below
    that fit's I0, at least one per cycle just above its I1 (1 % search brackets: 3 %
    margins)."""
    import dataclasses

    cls = _touchsim_class("RA")
    cls = dataclasses.replace(cls, saal=dataclasses.replace(cls.saal, fits=(0,)))
    f = 40.0
    i0, i1 = vt.saal_thresholds_stimulus(cls, [f], [0.0])
    rates = vt.rate_vs_amplitude(cls, [f], [[1.0]], [0.0], [0.97 * i0[0], 1.03 * i1[0]])[0, 0]
    assert rates[0] == 0 and rates[1] >= f


def test_sine_lanes_count_as_the_direct_simulation():
    """SineLanes (the amplitude-independent filtering done once) against saal_cycle_counts
    (the stimulus simulated whole at each amplitude), random lanes of every class with
    pressed values: the same totals and fewest-per-cycle counts (the linear stages commute
    with the amplitude up to round-off, which moves no spike here)."""
    rng = np.random.default_rng(1)
    population = load_receptors("calibrated")
    for c in population.classes:
        aff, n = c.saal.afferents(c.name), 40
        fits = aff.take(rng.integers(0, len(aff), n))
        f = np.exp(rng.uniform(np.log(2.0), np.log(1000.0), n))
        s0 = rng.uniform(0.0, 2e-3, n)
        a = np.exp(rng.uniform(np.log(1e-4), np.log(1e-1), n)) / c.saal.input_scale
        args = (c.saal.input_scale, c.saal.kappa(c.name))
        direct = vt.saal_cycle_counts(fits, f, a, s0, *args)
        lanes = vt.SineLanes(fits, f, s0, *args).counts(a)
        assert direct[0].sum() > 0
        np.testing.assert_array_equal(direct[0], lanes[0])
        np.testing.assert_array_equal(direct[1], lanes[1])


#: (I0, I1) in the site quantity (MPa) of the calibrated set's classes, from the threshold
#: search before its speed-up (every lane simulated whole at each amplitude, every neuron
#: stepped sample by sample), at these (f, s0) lanes, with the input scales of that time
#: (BEFORE_SCALES; SA1's has since been refitted to sustained pressure).
BEFORE_SCALES = {"SA1": 12.44, "RA": 2.052, "PC": 3.724}
BEFORE_SPEED_UP = {
    "SA1": ([3.0, 30.0, 300.0, 30.0], [0.0, 0.0, 0.0, 4e-4],
            [2.3077429459856665e-04, 9.282813381748057e-05, 4.545912015909913e-04,
             2.1620569015876555e-05],
            [2.3077429459856665e-04, 3.2226041600964274e-04, 2.0210182936919733e-02,
             2.4521928378352296e-04]),
    "RA": ([10.0, 40.0, 200.0], [0.0, 0.0, 0.0],
           [2.195994445629841e-04, 6.721575497795861e-05, 3.310197402561148e-05],
           [2.195994445629841e-04, 1.1148017545411285e-04, 5.459326265558997e-04]),
    "PC": ([50.0, 250.0, 800.0], [0.0, 0.0, 0.0],
           [2.1566292140684035e-06, 6.982796574472815e-08, 1.7011716640992703e-07],
           [7.796163754716563e-06, 1.988928788473939e-06, 1.1555251176862285e-03]),
}


@pytest.mark.parametrize("name", ["SA1", "RA", "PC"])
def test_the_fast_threshold_search_keeps_the_thresholds(name):
    """The search's thresholds equal those before its speed-up within the search tolerance
    (one geometric bisection step, ratio 1e9^(2^-11) = 1.0102; measured: identical)."""
    f, s0, i0, i1 = BEFORE_SPEED_UP[name]
    cls = load_receptors("calibrated")[name]
    cls = dataclasses.replace(cls, saal=dataclasses.replace(
        cls.saal, input_scale=BEFORE_SCALES[name]))
    a0, a1 = vt.saal_thresholds_stimulus(cls, f, s0)
    step = (vt.SAAL_RANGE[1] / vt.SAAL_RANGE[0]) ** (2.0 ** -vt.SAAL_BISECTIONS)
    np.testing.assert_allclose(a0, i0, rtol=step - 1)
    np.testing.assert_allclose(a1, i1, rtol=step - 1)


def test_touchsims_own_curves_are_the_search_on_its_mechanics_and_are_drawn(tmp_path):
    """data/receptors/touchsim_thresholds.csv holds TouchSim's thresholds: its fits through the
    search with its own input per mm of pin motion (c_s from TouchSim's `propagate`, α = 1);
    recomputed at three frequencies per class, equal to the file's 6 digits. The threshold
    figure draws them, one legend entry per class."""
    import json
    from pathlib import Path

    ref = json.loads((Path(__file__).parent / "data" / "touchsim_reference.json").read_text())
    c_s = next(r for r in ref["stimuli"] if r["pin_radius"] == 0.5)["input"]
    curves = vt.touchsim_thresholds()
    assert set(curves) == {"SA1", "RA", "PC"}
    for name, (f, i0, i1) in curves.items():
        pick = [4, 20, 33]  # 2.0, 35 and 346 Hz
        a0, a1 = vt.saal_thresholds_stimulus(_touchsim_class(name), f[pick], 0.0)
        np.testing.assert_allclose(a0 / c_s[name]["c_s"], i0[pick], rtol=1e-5)
        np.testing.assert_allclose(a1 / c_s[name]["c_s"], i1[pick], rtol=1e-5)
    th = vt.vibration_thresholds(_touchsim_class("PC"), f[::8], np.ones((5, 1)), np.zeros(1))
    legend = vt.plot_threshold_curves([th], tmp_path / "thresholds.png")
    assert "PC TouchSim (Saal et al. 2017)" in legend
    assert not any(entry.startswith("RA TouchSim") for entry in legend)  # only classes drawn
