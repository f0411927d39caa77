"""The Saal et al. 2017 transduction (afferents.transduction): its stages against closed forms,
and the whole model against TouchSim's own responses (tests/data/touchsim_reference.json, made
by scripts/touchsim_reference.py in a separate environment with TouchSim installed)."""

import json
from pathlib import Path

import numpy as np
import pytest

from fingertip_dolfinx.afferents import transduction as tr
from fingertip_dolfinx.errors import InputError

REFERENCE = Path(__file__).parent / "data" / "touchsim_reference.json"
FS = 5000.0


@pytest.fixture(scope="module")
def fits():
    return tr.load_afferents()


def test_the_published_fits_are_all_there(fits):
    counts = {c: int(np.sum(fits.cls == c)) for c in tr.CLASSES}
    assert counts == {"SA1": 4, "RA": 9, "PC": 4}
    assert fits.post_spike.shape == (17, 190) and fits.fs == FS and fits.refractory == 6
    # TouchSim's first SA1 fit (constants.affparamsSA[0]): c = 10.13..., tau = 281.2 samples
    assert fits.cutoff_Hz[0] == pytest.approx(101.317138671875, rel=1e-15)
    assert fits.tau[0] == pytest.approx(281.20660400390625, rel=1e-15)


@pytest.mark.parametrize("fc", [101.3, 275.0])
def test_lowpass_gain_is_one_at_dc_and_one_over_root_two_at_cutoff(fc):
    """Butterworth: |H(0)| = 1, |H(f_c)| = 1/√2 (the bilinear design keeps f_c exactly). Measured
    on the filter's steady output: a constant, and 40 cycles of a sine at f_c after 20
    cycles of settling (transient of a 3rd-order filter at f_c: e^{-2π·20 ζ} ≪ 1e-6)."""
    n = int(FS * 60 / fc)
    t = np.arange(n) / FS
    x = np.vstack([np.ones(n), np.sin(2 * np.pi * fc * t)])
    y = tr.lowpass(x, np.array([fc, fc]), FS)
    assert y[0, -1] == pytest.approx(1.0, abs=1e-9)
    tail = t > 20 / fc
    # amplitude by least squares on sin and cos (exact for a steady sinusoid)
    basis = np.vstack([np.sin(2 * np.pi * fc * t[tail]), np.cos(2 * np.pi * fc * t[tail])]).T
    coef = np.linalg.lstsq(basis, y[1, tail], rcond=None)[0]
    assert np.hypot(*coef) == pytest.approx(1 / np.sqrt(2), abs=1e-6)


def test_rectified_weights_each_term_on_its_own_sign():
    w = np.array([[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]])
    s = np.array([[0.5, -0.5, 0.0, 0.0]])
    u = np.array([[0.0, 0.0, 1.0, 3.0]])  # Δu = [0, 1, 2, 0]
    got = tr.rectified(w, s, u)[0]
    assert got == pytest.approx([1 * 0.5 + 0, 2 * 0.5 + 5 * 1, 3 * 1 + 5 * 2, 3 * 3])
    u_down = -u
    assert tr.rectified(w, 0 * s, u_down)[0] == pytest.approx([0, 6 * 1, 4 + 6 * 2, 4 * 3])


def test_saturation_halves_at_p7_tends_to_p7_and_is_off_at_zero():
    current = np.array([[10.0, -10.0, 1e12], [10.0, -10.0, 1e12]])
    out = tr.saturated(current, np.array([10.0, 0.0]))
    assert out[0] == pytest.approx([5.0, -5.0, 10.0], rel=1e-10)
    assert out[1] == pytest.approx(current[1])


def _interval(j, tau, h, refractory=6):
    """Samples between spikes for a constant current J: v_k = Σ_{i=1..k} q^{k−i} (J + h_{i−1})
    after a spike (q = 1 − 1/τ, h = 0 beyond its end), the first k >= refractory with v_k > 1."""
    q = 1 - 1 / tau
    k = np.arange(1, 2000)
    hh = np.zeros(len(k))
    hh[: len(h)] = h[: len(k)]
    drive = j + hh
    v = np.convolve(drive, q ** np.arange(len(k)))[: len(k)]  # v_k: the sum, as a convolution
    return int(k[np.flatnonzero((v > 1) & (k >= refractory))[0]])


@pytest.mark.parametrize("j,tau", [(0.02, 100.0), (0.3, 10.0), (0.9, 5.0)])
def test_lif_rate_under_constant_current_without_post_spike_current(j, tau):
    """Closed form: v_k = J (1 − q^k)/(1 − q); spikes every n samples, n the first k >= 6 with
    v_k > 1; the first at sample n0 − 1 (v = J after sample 0), n0 the first k with v_k > 1 (no
    refractory period before the first spike). Exact in the spike count."""
    steps = 5000
    spikes = tr.integrate_and_fire(np.full((1, steps), j), np.array([tau]), np.zeros((1, 190)), 6)
    q = 1 - 1 / tau
    k = np.arange(1, 5000)
    above = j * (1 - q**k) / (1 - q) > 1
    n0, n = int(k[np.flatnonzero(above)[0]]), int(k[np.flatnonzero(above & (k >= 6))[0]])
    got = np.flatnonzero(spikes[0])
    assert got[0] == n0 - 1
    assert np.all(np.diff(got) == n)
    assert n == _interval(j, tau, np.zeros(0))


def test_lif_interval_with_the_post_spike_current_of_every_fit(fits):
    """With each fit's own post-spike current h (its weights on TouchSim's two basis functions;
    negative: a relative refractory period), the interval under a constant current is the
    closed-form sum of `_interval` and differs from the interval without h."""
    steps = 3000
    for j in (0.05, 0.2):
        drive = np.full((len(fits), steps), j)
        spikes = tr.integrate_and_fire(drive, fits.tau, fits.post_spike, 6)
        for i in range(len(fits)):
            got = np.flatnonzero(spikes[i])
            if len(got) < 3:
                continue
            n = _interval(j, fits.tau[i], fits.post_spike[i])
            assert np.all(np.diff(got) == n), (fits.cls[i], fits.index[i], j)
    # the post-spike current matters: first PC fit at J = 0.2 (h < 0 lengthens the interval)
    pc = np.flatnonzero(fits.cls == "PC")[0]
    assert _interval(0.2, fits.tau[pc], fits.post_spike[pc]) > _interval(0.2, fits.tau[pc], [])


def _touchsim_trace(rec):
    """TouchSim's stim_ramp / stim_sine trace (generators.py): 50 ms linear on/off ramps."""
    fs, n, args = rec["fs"], rec["samples"], rec["args"]
    if rec["kind"] == "ramp":
        x = args["amp"] * np.ones(n)
    else:
        x = args["amp"] * np.sin(np.linspace(0.0, 2 * np.pi * args["freq"] * n / fs, n))
    r = round(0.05 * fs)
    x[:r] *= np.linspace(0, 1, r)
    x[-r:] *= np.linspace(1, 0, r)
    return x


def test_the_linear_start_gives_the_stepped_neurons_spikes(fits):
    """integrate_and_fire runs each neuron as a linear filter until its first crossing and steps
    only the firing ones, in groups from their first crossing: exactly the flags of stepping
    every neuron from rest (`_lif_steps` from v = 0). Lanes that never fire, fire at once,
    fire late (a ramp) and fire with the post-spike current of every fit; identical flags."""
    rng = np.random.default_rng(7)
    steps, n = 2000, 3 * len(fits)
    aff = fits.take(np.arange(n) % len(fits))
    t = np.arange(steps) / 5000.0
    ramp = np.clip(t / rng.uniform(0.02, 0.5, n)[:, None], 0, 1)  # crossings spread in time
    drive = rng.uniform(0.0, 0.2, n)[:, None] * ramp * (1 + 0.5 * np.sin(2 * np.pi * 37 * t))
    drive[::5] *= 1e-3  # some never fire
    got = tr.integrate_and_fire(drive, aff.tau, aff.post_spike, 6)
    want = tr._lif_steps(drive, aff.tau, aff.post_spike, 6, np.zeros(n))
    assert 0 < got.any(axis=1).sum() < n
    np.testing.assert_array_equal(got, want)
    assert tr.integrate_and_fire(drive[:, :0], aff.tau, aff.post_spike, 6).shape == (n, 0)


def test_reproduces_touchsim_spike_for_spike(fits):
    """Fed TouchSim's own input at the afferent (static c_s·trace, dynamic c_u·d(trace)/dt,
    reconstructed to 1e-13 of TouchSim's `propagate`, error stored with the data), all 17 fits
    give TouchSim's spike samples exactly (noise off) on its 18 reference stimuli: the model is
    the same discrete-time system, so the tolerance is zero spikes and zero samples."""
    ref = json.loads(REFERENCE.read_text())
    assert len(ref["stimuli"]) == 18
    total = 0
    for rec in ref["stimuli"]:
        assert max(v["relative_error"] for v in rec["input"].values()) < 1e-13
        cs = np.array([rec["input"][c]["c_s"] for c in fits.cls])
        cu = np.array([rec["input"][c]["c_u"] for c in fits.cls])
        x = np.tile(_touchsim_trace(rec), (len(fits), 1))
        s, u = tr.site_inputs(x, rec["fs"], cs, cu / cs)
        flags = tr.spike_flags(fits, s, u)
        for i, r in enumerate(rec["responses"]):
            assert (r["class"], r["index"]) == (fits.cls[i], fits.index[i])
            assert np.flatnonzero(flags[i]).tolist() == r["spike_samples"], rec["label"]
            total += r["count"]
    assert total > 5000  # the comparison is not of silent afferents


def test_touchsim_regression_values(fits):
    """TouchSim's own tests/test_response.py numbers (rates ±1 spikes/s, first spike ±0.25 ms),
    through the stored reference: SA1 idx 0 ramp 22/s, first at 6.2 ms; PC idx 0 250 Hz 5 µm
    247/s, first at 4.2 ms."""
    ref = {r["label"]: r for r in json.loads(REFERENCE.read_text())["stimuli"]}
    sa1 = ref["ramp 1 mm, 1 mm pin"]["responses"][0]
    pc = [r for r in ref["sine 250 Hz 0.005 mm"]["responses"] if r["class"] == "PC"][0]
    assert abs(sa1["rate"] - 22) <= 1 and abs((sa1["spike_samples"][0] + 1) / FS - 0.0062) <= 2.5e-4
    assert abs(pc["rate"] - 247) <= 1 and abs((pc["spike_samples"][0] + 1) / FS - 0.0042) <= 2.5e-4


def test_noise_changes_the_train_and_is_reproducible_with_a_seed(fits):
    pc = fits.take(fits.cls == "PC")
    t = np.arange(2500) / FS
    s, u = tr.site_inputs(0.001 * np.sin(2 * np.pi * 250 * t), FS, 1.0, 1.0)
    quiet = tr.spike_flags(pc, s, u)
    a = tr.spike_flags(pc, s, u, noisy=True, rng=np.random.default_rng(1))
    b = tr.spike_flags(pc, s, u, noisy=True, rng=np.random.default_rng(1))
    assert np.array_equal(a, b) and not np.array_equal(a, quiet)


def test_rate_factor_and_bad_inputs():
    """κ = π a / (z² F(z/a)); on the surface F = 1 (the punch's centre pressure P/(2πa²))."""
    assert tr.sneddon_axis_factor(0.0) == 1.0
    assert tr.rate_factor(1.6, 0.5) == pytest.approx(
        np.pi * 0.5 / (1.6**2 * (1 / (1 + 3.2**2) + 2 * 3.2**2 / (1 + 3.2**2) ** 2)))
    with pytest.raises(InputError):
        tr.rate_factor(0.0, 0.5)
    with pytest.raises(InputError):
        tr.load_afferents(rows={"RA": [9]})
