r"""Afferent responses to vibration: firing vs amplitude, threshold curves, and the SED rate,
for any mechanics that gives the stimulus's transfer function at the receptor sites.

**Input.** Frequencies f_j (Hz), a receptor class (`receptors.load_receptors()[name]`), and per
site i the complex transfer function H_ji (the class's stimulus quantity, compression positive,
per mm of probe displacement: |H| its amplitude, arg H its phase) and the pressed value s0_i
of that quantity (the static state about which the probe vibrates). How H was computed
(frequency-domain mechanics, a time-domain run, a closed form) is no concern of this module.

**Stimulus at a site** for a probe displacement A sin(2π f t) (small signal, linear in A):

    s(t) = s0 + a sin θ,   ṡ = a ω cos θ,   s̈ = −a ω² sin θ,   a = A |H|,  θ = ωt + arg H,

with the exact derivatives (not differences). In steady state the phase arg H only shifts the
spike train in time: thresholds and rates depend on a, f and s0 only, so a probe threshold is
the stimulus threshold divided by |H| (exactly 1/|H| scaling).

**Neuron.** The class's LIF of `receptors` (current J = p7 I/(p7 + |I|) of the rectified input
I = p1[s]+ + p2[s]− + p3[ṡ]+ + p4[ṡ]− + p5[s̈]+ + p6[s̈]−; τ dv/dt = −v + J, spike at v = 1,
v = 0 held for t_ref). J is sampled at N points per cycle (phase 0 a sample, so with N
divisible by 4 the kinks of [ṡ]± and [s̈]± lie on samples) and is linear in between; on each
piece the membrane is integrated in closed form and every threshold crossing is found as the
root of that closed form (the same scheme as `receptors.lif_spikes`, vectorised over lanes =
(frequency, site, amplitude) here). The only approximation is the linear interpolation of J:
|δJ| <= h² max|J''| / 8 with h = T/N, i.e. a relative error <= (2π/N)²/8 = 1.2e-3 at the default N
= 64
(`SAMPLES`) on the smooth parts of a rectified sinusoid.

**Criteria** (the names of Freeman & Johnson 1982, J Physiol 323:43-64, abstract read: "Amplitudes,
I, less than I(0) produced no impulse on any stimulus cycles. Amplitudes greater than I(1)
produced one impulse on every cycle. As I rose from I(0) to I(1) the impulse rate rose
monotonically from 0 to 1 impulse/cycle"):

- *absolute threshold* I0: the smallest amplitude at which the neuron fires in steady state.
  This is exact without simulating spikes: the steady state without spikes is the periodic
  solution v_p of the linear ODE (v_p(0) = w / (1 − e^{−T/τ}), w the response over one cycle
  from 0); there are spikes in steady state iff max v_p > 1 (maximum over the samples and over
  each piece's interior, in closed form).
- *entrainment threshold* I1 (1:1, "tuning"): the smallest amplitude at which every one of the
  `cycles` counted cycles (after `_settle` cycles; the run starts from v_p(0), the steady state
  of the sub-threshold membrane) holds at least one spike. Impossible (inf) where the period is
  below the refractory period or f exceeds the rate of the saturated current.
- Both are thresholds of an afferent at rest: a site whose pressed value s0 alone fires (a
  pressed SA1 site; J(s0) > 1) gets NaN for both. (Counting "one spike more than s0 alone"
  was tried: the count is not monotone in the amplitude and the curve it gives is erratic.)

Both search the amplitude (k-section, geometric, to `rtol`, default 1e-2) and assume the
response grows with the amplitude (true for RA and PC inputs, which scale with a; for a static SA1
weight the negative
half-cycle lowers J, and monotonicity is an assumption). The *cycle response* (impulses per
cycle, Johansson, Landström & Lundström 1982, Brain Res 244:17, abstract: "the number of
impulses evoked per sine wave cycle") is the mean spike count per counted cycle; the rate is
that times f.

**SED-rate model** (`receptors`: r = k SED, classes with a gain reading SED): under vibration
r(t) = k [s0 + a sin θ]+, whose cycle mean is k s0 for a <= s0 (no response to vibration on
average: this model has no rate sensitivity) and k [s0 (1/2 + β/π) + a cos β / π],
β = arcsin(s0/a), above.

Timings: docs/benchmarks/measurements.md (`benchmarks/vibrotactile_thresholds.py`). The
transduction has no high-frequency roll-off of its own (TouchSim's input low-pass is left out, see
`receptors.threshold_amplitude`): with a frequency-independent H, RA thresholds fall as 1/f and
PC's as 1/f² without end; any U shape must come from the mechanics' H.

**The Saal et al. 2017 afferents** (a class with `model = "saal2017"`, receptors.SaalModel):
discrete-time models at 5 kHz with their own low-pass and post-spike current, so no closed
form per piece; `saal_thresholds_stimulus` simulates every (lane, fit) on s0 + a sin θ (after
SAAL_SETTLE, counting at least SAAL_COUNT seconds) and bisects the amplitude geometrically per
lane (SAAL_BISECTIONS rounds, 1 %); the stages before the rectification are linear in the
amplitude and run once per lane (`SineLanes`), and the neuron is a linear filter until its first
spike (`transduction.integrate_and_fire`). Per site the most sensitive fit counts. Fed
TouchSim's own quasi-static mechanics they have the classic tuning (PC I1 lowest near 200 Hz,
RA near 30 Hz, SA1 below 10 Hz; tests/test_vibrotactile.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..datafiles import builtin_dir
from ..errors import InputError
from .receptors import LIF, ReceptorClass, rectified_input, saturate
from .transduction import (
    Afferents,
    integrate_and_fire,
    lowpass,
    rectified,
    saturated,
    site_inputs,
    spike_flags,
)

SAMPLES = 64  # samples of J per cycle (divisible by 4): J interpolation error <= 1.2e-3 relative
SETTLE = 3  # cycles discarded at least (more for slow membranes, see _settle)
CYCLES = 10  # cycles counted
MAX_SETTLE = 20
SECTIONS = 6  # amplitudes per lane and round of the threshold search
NEWTON = 12  # iterations for a crossing time (monotone, quadratic: round-off in ~6)
# The Saal et al. 2017 afferents (discrete time at 5 kHz), simulated on a sinusoid:
SAAL_SETTLE = 0.25  # s discarded: 3 of the slowest fit's τ (409 samples = 82 ms), > the
#                     post-spike current (38 ms); the filters (>= 74 Hz) settle within it
SAAL_COUNT = 0.1  # s counted at least, and at least SAAL_CYCLES cycles, or one cycle when a
SAAL_CYCLES = 2  # cycle is longer than the settling time (the neuron forgets the last cycle)
SAAL_RANGE = (1e-8, 10.0)  # bracket of the model's input amplitude α·a (MPa of TouchSim stress)
SAAL_BISECTIONS = 11  # geometric: bracket ratio 1e9 -> 1e9^(2^-11) = 1.010 (1 %)
SAAL_BUDGET = 3e6  # lanes × samples simulated together (memory: ~10 arrays of 24 MB)


# --- the stimulus and the current over one cycle ---------------------------------------------


def site_stimulus(theta, a, omega, s0):
    """(s, ṡ, s̈) at phase θ for s = s0 + a sin θ (exact derivatives, θ = ωt + φ)."""
    return s0 + a * np.sin(theta), a * omega * np.cos(theta), -a * omega**2 * np.sin(theta)


def cycle_current(lif: LIF, frequency, a, s0, samples: int = SAMPLES) -> np.ndarray:
    """J at N + 1 equally spaced phases of one cycle (phase 0 to 2π) per lane: (L, N + 1)."""
    f, a, s0 = (np.asarray(x, dtype=float).reshape(-1, 1) for x in np.broadcast_arrays(
        frequency, a, s0))
    theta = np.linspace(0.0, 2 * np.pi, samples + 1)[None, :]
    s, ds, dds = site_stimulus(theta, a, 2 * np.pi * f, s0)
    return saturate(rectified_input(s, ds, dds, lif.weights), lif.saturation)


# --- the membrane: periodic sub-threshold solution and spiking lanes ------------------------


def _piece_end(v, j, m, tau, h):
    """v after h on a piece with J = j + m s from v: the closed form."""
    return j + m * (h - tau) + (v - j + m * tau) * np.exp(-h / tau)


def periodic_membrane(j: np.ndarray, period, tau: float) -> tuple[np.ndarray, np.ndarray]:
    """The periodic solution of τ v' = −v + J (no spikes) for J sampled over one cycle
    (L, N + 1): its samples (L, N + 1) and its maximum over the cycle (L,), piece interiors
    included (a concave piece, c = v − J + mτ < 0, m < 0, peaks at s* = −τ ln(mτ/c))."""
    n = j.shape[1] - 1
    h = np.asarray(period, dtype=float).reshape(-1) / n
    m = np.diff(j, axis=1) / h[:, None]
    w = np.zeros(len(j))
    for k in range(n):  # response over one cycle from v = 0
        w = _piece_end(w, j[:, k], m[:, k], tau, h)
    v = np.empty_like(j)
    v[:, 0] = w / -np.expm1(-n * h / tau)
    for k in range(n):
        v[:, k + 1] = _piece_end(v[:, k], j[:, k], m[:, k], tau, h)
    c = v[:, :-1] - j[:, :-1] + m * tau
    with np.errstate(divide="ignore", invalid="ignore"):
        s_star = -tau * np.log(m * tau / c)
    inside = (c < 0) & (m < 0) & (s_star > 0) & (s_star < h[:, None])
    peak = np.where(inside, j[:, :-1] + m * np.where(inside, s_star, 0.0), -np.inf)
    return v, np.maximum(v.max(axis=1), peak.max(axis=1))


def _first_crossing(v, j, m, tau, h):
    """First s in (0, h] with v(s) = 1 per lane (NaN where none): f(s) = v(s) − 1 is convex or
    concave, so its maximum over [0, h] lies at 0, h or s*, and it has one root before it."""
    c = v - j + m * tau

    def f(s, i=slice(None)):
        return j[i] - m[i] * tau - 1.0 + m[i] * s + c[i] * np.exp(-s / tau)

    with np.errstate(divide="ignore", invalid="ignore"):
        s_star = -tau * np.log(m * tau / c)
    s_star = np.where(np.isfinite(s_star), np.clip(s_star, 0.0, h), h)
    high = np.where(f(s_star) > f(h), s_star, h)
    cross = np.flatnonzero(f(high) >= 0)
    out = np.full(len(v), np.nan)
    if len(cross):
        # Newton converges monotonically: from 0 on a concave piece (the tangent lies above f,
        # so every iterate stays left of the root), from `high` on a convex one (below f).
        cc, mm, top = c[cross], m[cross], high[cross]
        const = j[cross] - mm * tau - 1.0
        x = np.where(cc < 0, 0.0, top)
        with np.errstate(divide="ignore", invalid="ignore"):
            for _ in range(NEWTON):
                decay = cc * np.exp(-x / tau)
                slope = mm - decay / tau
                step = np.where(slope > 0, (const + mm * x + decay) / slope, 0.0)
                x = np.minimum(np.maximum(x - step, 0.0), top)
                if np.all(np.abs(step) <= 1e-15 * top):
                    break
        out[cross] = x
    return out


def spike_counts(j: np.ndarray, period, tau: float, refractory: float, cycles: int,
                 v0=None) -> np.ndarray:
    """Spikes in each of `cycles` cycles (L, cycles) of the periodic current J (L, N + 1) from
    the membrane v0 at t = 0 (default 0): the exact piecewise integration, lane by lane."""
    n_lanes, n = j.shape[0], j.shape[1] - 1
    h = np.asarray(period, dtype=float).reshape(-1) / n * np.ones(n_lanes)
    m = np.diff(j, axis=1) / h[:, None]
    v = np.zeros(n_lanes) if v0 is None else np.array(v0, dtype=float)
    counts = np.zeros((n_lanes, cycles), dtype=int)
    rest = np.zeros(n_lanes)  # refractory time left at the start of the piece
    lanes = np.arange(n_lanes)
    for step in range(n * cycles):
        k, cycle = step % n, step // n
        pos = np.zeros(n_lanes)  # time into the piece
        todo = lanes
        while len(todo):
            held = rest[todo] >= h[todo] - pos[todo]
            done = todo[held]
            rest[done] -= h[done] - pos[done]
            v[done] = 0.0
            todo = todo[~held]
            if not len(todo):
                break
            start = pos[todo] + rest[todo]
            v[todo] = np.where(rest[todo] > 0, 0.0, v[todo])
            rest[todo] = 0.0
            jn = j[todo, k] + m[todo, k] * start
            left = h[todo] - start
            s = _first_crossing(v[todo], jn, m[todo, k], tau, left)
            quiet = np.isnan(s)
            q = todo[quiet]
            v[q] = _piece_end(v[q], jn[quiet], m[q, k], tau, left[quiet])
            fire = todo[~quiet]
            counts[fire, cycle] += 1
            v[fire] = 0.0
            pos[fire] = start[~quiet] + s[~quiet]
            rest[fire] = refractory
            todo = fire
    return counts


def _settle(tau: float, frequency) -> int:
    """Cycles discarded: at least SETTLE, three membrane time constants, at most MAX_SETTLE."""
    return int(min(MAX_SETTLE, max(SETTLE, math.ceil(3 * tau * float(np.max(frequency))))))


def cycle_response(lif: LIF, frequency, a, s0, *, cycles: int = CYCLES,
                   samples: int = SAMPLES) -> np.ndarray:
    """Steady-state spikes in each counted cycle (L, cycles) for lanes (f, a, s0) broadcast
    together, all in one batch (each lane its own period); `_settle` cycles of the highest
    frequency are discarded first. The run starts from the sub-threshold periodic state
    v_p(0) (0 where v_p reaches the threshold)."""
    f, a, s0 = (np.asarray(x, dtype=float).ravel() for x in np.broadcast_arrays(
        frequency, a, s0))
    if not len(f):
        return np.zeros((0, cycles), dtype=int)
    j = cycle_current(lif, f, a, s0, samples)
    vp, peak = periodic_membrane(j, 1 / f, lif.tau)
    v0 = np.where(peak < 1.0, vp[:, 0], 0.0)
    settle = _settle(lif.tau, f)
    counts = spike_counts(j, 1 / f, lif.tau, lif.refractory, settle + cycles, v0)
    return counts[:, settle:]


# --- thresholds ------------------------------------------------------------------------------


def _search(predicate, guess, todo, rtol: float, low=None, sections: int = 0,
            limit: float = 1e12) -> np.ndarray:
    """Smallest amplitude at which `predicate` holds, per lane, to rtol: a k-section search
    (k = `sections` amplitudes per lane and round, evaluated in one batch), the predicate
    assumed monotone in the amplitude. predicate(a, idx) -> bool for amplitudes a of the lanes
    idx (repeats allowed). Rounds: upward by factors 4 from `guess` (or above `low`, a known
    failing amplitude) while every candidate fails; downward while every one passes; then
    geometric sections of (low, high]. inf where nothing up to guess × limit passes."""
    k = sections or SECTIONS
    guess = np.asarray(guess, dtype=float)
    low = np.zeros(len(guess)) if low is None else np.array(low, dtype=float)
    high = np.full(len(guess), np.inf)
    active = np.array(todo, dtype=bool) & np.isfinite(guess) & (guess > 0)
    steps = np.arange(k, dtype=float)
    while np.any(active):
        idx = np.flatnonzero(active)
        lo, hi, g = low[idx], high[idx], guess[idx]
        base = np.where(lo >= g, 4 * lo, g)
        up = base[:, None] * 4.0 ** steps
        down = hi[:, None] * 4.0 ** -(steps + 1)
        ratio = np.where(lo > 0, hi / np.where(lo > 0, lo, 1.0), 1.0)
        mid = lo[:, None] * ratio[:, None] ** ((steps + 1) / (k + 1))
        cand = np.where(~np.isfinite(hi)[:, None], up, np.where((lo > 0)[:, None], mid, down))
        ok = predicate(cand.ravel(), np.repeat(idx, k)).reshape(cand.shape)
        new_high = np.minimum(np.min(np.where(ok, cand, np.inf), axis=1), hi)
        failing = ~ok & (cand < new_high[:, None])
        low[idx] = np.maximum(np.max(np.where(failing, cand, 0.0), axis=1), lo)
        high[idx] = new_high
        over = ~np.isfinite(new_high) & (cand[:, -1] > g * limit)
        tiny = (low[idx] == 0) & (new_high < g / limit)
        active[idx] = ~over & ~tiny & ~(new_high <= low[idx] * (1 + rtol))
    return np.where(np.array(todo, dtype=bool), high, np.inf)


def _guess(lif: LIF, frequency: np.ndarray) -> np.ndarray:
    """The amplitude at which the unsaturated input reaches 1 at its peak."""
    p = np.abs(np.asarray(lif.weights))
    w = 2 * np.pi * frequency
    gain = np.maximum(p[0], p[1]) + np.maximum(p[2], p[3]) * w + np.maximum(p[4], p[5]) * w**2
    return 1.0 / np.maximum(gain, 1e-300)


def static_fires(lif: LIF, s0) -> np.ndarray:
    """Whether the pressed value alone fires the neuron (J(s0) > 1)."""
    return saturate(rectified_input(np.asarray(s0, dtype=float), 0.0, 0.0, lif.weights),
                    lif.saturation) > 1.0


def absolute_threshold_stimulus(lif: LIF, frequency, s0=0.0, *, samples: int = SAMPLES,
                                rtol: float = 1e-2) -> np.ndarray:
    """I0 in the stimulus's units at the site, per lane (f, s0): max v_p = 1 (see the module
    docstring); NaN where s0 alone fires (the afferent is not at rest)."""
    f, s0 = (np.asarray(x, dtype=float).ravel() for x in np.broadcast_arrays(frequency, s0))
    busy = static_fires(lif, s0)

    def fires(a, lanes):
        j = cycle_current(lif, f[lanes], a, s0[lanes], samples)
        return periodic_membrane(j, 1 / f[lanes], lif.tau)[1] > 1

    out = _search(fires, _guess(lif, f), ~busy, rtol)
    return np.where(busy, np.nan, out)


def entrainment_threshold_stimulus(lif: LIF, frequency, s0=0.0, *, cycles: int = CYCLES,
                                   samples: int = SAMPLES, rtol: float = 1e-2,
                                   absolute=None) -> np.ndarray:
    """I1 (one spike on every counted cycle) in the stimulus's units, per lane (f, s0); inf
    where impossible (T <= t_ref, or f above the saturated rate), NaN where s0 alone fires."""
    f, s0 = (np.asarray(x, dtype=float).ravel() for x in np.broadcast_arrays(frequency, s0))
    if absolute is None:
        absolute = absolute_threshold_stimulus(lif, f, s0, samples=samples, rtol=rtol)
    ceiling = (lif.rate(lif.saturation * (1 - 1e-12)) if lif.saturation > 0 else np.inf)
    busy = static_fires(lif, s0)
    todo = (1 / f > lif.refractory) & (f < ceiling) & np.isfinite(absolute) & ~busy

    def entrained(a, lanes):
        counts = cycle_response(lif, f[lanes], a, s0[lanes], cycles=cycles, samples=samples)
        return np.all(counts >= 1, axis=1)

    start = np.where(todo, absolute, np.inf)
    out = _search(entrained, start, todo, rtol, low=np.where(todo, start * (1 - 2 * rtol), 0))
    return np.where(busy, np.nan, out)


# --- a class over sites and frequencies --------------------------------------------------------


@dataclass(frozen=True)
class VibrationThresholds:
    """Thresholds of one class: `absolute` (I0) and `entrainment` (I1) probe amplitudes (mm),
    shape (n_f, n_sites); the same at the site in the quantity's units (`*_stimulus`)."""

    name: str
    unit: str
    frequency: np.ndarray
    absolute: np.ndarray
    entrainment: np.ndarray
    absolute_stimulus: np.ndarray
    entrainment_stimulus: np.ndarray

    def best(self, criterion: str = "absolute") -> np.ndarray:
        """The most sensitive site's threshold per frequency (mm): min over the sites at rest
        (NaN sites, whose pressed value alone fires, left out; NaN if every site fires)."""
        values = getattr(self, criterion)
        with np.errstate(all="ignore"):
            return np.where(np.all(np.isnan(values), axis=1), np.nan,
                            np.nanmin(np.where(np.isnan(values), np.inf, values), axis=1))


def _check(frequencies, transfer, static) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    f = np.atleast_1d(np.asarray(frequencies, dtype=float))
    h = np.asarray(transfer, dtype=complex)
    if h.ndim == 1:
        h = h[:, None]
    s0 = np.broadcast_to(np.asarray(static, dtype=float), (h.shape[1],)) if np.ndim(
        static) <= 1 else None
    if np.any(f <= 0) or not np.all(np.isfinite(f)):
        raise InputError("frequencies", f"must be finite and > 0 Hz, got {f}.")
    if h.shape[0] != len(f) or s0 is None:
        raise InputError("transfer", f"shape {h.shape} for {len(f)} frequencies and static "
                         f"shape {np.shape(static)}.", "give H as (n_frequencies, n_sites) "
                         "and s0 as (n_sites,).")
    return f, h, s0


def _lanes(cls: ReceptorClass, f, s0):
    """Unique (f, s0) lanes: s0 matters only to a class with a static weight."""
    weights = (cls.saal.afferents(cls.name).weights[:, :2].ravel() if cls.model == "saal2017"
               else cls.lif.weights[:2])
    uses_static = any(w != 0 for w in weights)
    ff, ss = np.meshgrid(f, s0 if uses_static else np.zeros_like(s0), indexing="ij")
    keys = np.stack([ff.ravel(), ss.ravel()], axis=1)
    unique, inverse = np.unique(keys, axis=0, return_inverse=True)
    return unique[:, 0], unique[:, 1], inverse.reshape(ff.shape)


def vibration_thresholds(cls: ReceptorClass, frequencies, transfer, static, *,
                         cycles: int = CYCLES, samples: int = SAMPLES,
                         rtol: float = 1e-2) -> VibrationThresholds:
    """I0 and I1 of a class at every frequency and site: the stimulus thresholds of the unique
    (f, s0) lanes, divided by |H| (mm of probe amplitude; inf where |H| = 0). A class with the
    Saal et al. 2017 model: per site the most sensitive of its fits (`saal_thresholds_stimulus`;
    `cycles`, `samples`, `rtol` are the LIF's)."""
    f, h, s0 = _check(frequencies, transfer, static)
    lf, ls, back = _lanes(cls, f, s0)
    if cls.model == "saal2017":
        a0, a1 = saal_thresholds_stimulus(cls, lf, ls)
    else:
        a0 = absolute_threshold_stimulus(cls.lif, lf, ls, samples=samples, rtol=rtol)
        a1 = entrainment_threshold_stimulus(cls.lif, lf, ls, cycles=cycles, samples=samples,
                                            rtol=rtol, absolute=a0)
    gain = np.abs(h)
    with np.errstate(divide="ignore"):
        return VibrationThresholds(cls.name, cls.unit, f, a0[back] / gain, a1[back] / gain,
                                   a0[back], a1[back])


def rate_vs_amplitude(cls: ReceptorClass, frequencies, transfer, static, amplitudes, *,
                      cycles: int = 20, samples: int = SAMPLES) -> np.ndarray:
    """Steady-state firing rate (spikes/s) for probe amplitudes A (mm), shape
    (n_f, n_sites, n_A): mean spikes per counted cycle × f (resolution f / cycles). For the
    Saal et al. fits, site k uses fit k mod n (as the time route) and the counted cycles of
    `saal_cycle_counts` (`cycles`, `samples` unused)."""
    f, h, s0 = _check(frequencies, transfer, static)
    amps = np.atleast_1d(np.asarray(amplitudes, dtype=float))
    ff = np.broadcast_to(f[:, None, None], (len(f), len(s0), len(amps)))
    aa = np.abs(h)[:, :, None] * amps[None, None, :]
    ss = np.broadcast_to(s0[None, :, None], ff.shape)
    if cls.model == "saal2017":
        fits = cls.saal.afferents(cls.name)
        site = np.broadcast_to(np.arange(len(s0))[None, :, None], ff.shape).ravel()
        total, _ = saal_cycle_counts(fits.take(site % len(fits)), ff.ravel(), aa.ravel(),
                                     ss.ravel(), cls.saal.input_scale, cls.saal.kappa(cls.name))
        return (total / _saal_counted(ff.ravel()) * ff.ravel()).reshape(ff.shape)
    counts = cycle_response(cls.lif, ff.ravel(), aa.ravel(), ss.ravel(), cycles=cycles,
                            samples=samples)
    return (counts.mean(axis=1) * ff.ravel()).reshape(ff.shape)


def sed_rate(cls: ReceptorClass, frequencies, transfer, static, amplitudes):
    """The SED-proportional rate under vibration, (mean, peak) over a cycle (spikes/s), shape
    (n_f, n_sites, n_A): k·mean([s0 + a sin θ]+) in closed form, and k·(s0 + a). For a class
    with a gain that reads SED; an error otherwise."""
    if cls.sed_gain is None or cls.quantity != "sed":
        raise InputError(f"class {cls.name}", "has no SED-rate model (needs sed_gain and "
                         "quantity = \"sed\").", "use a class such as SA1 of the default set.")
    _, h, s0 = _check(frequencies, transfer, static)
    a = np.abs(h)[:, :, None] * np.atleast_1d(np.asarray(amplitudes, dtype=float))
    s = np.broadcast_to(np.maximum(s0, 0.0)[None, :, None], a.shape)
    return cls.sed_gain * rectified_sine_mean(s, a), cls.sed_gain * (s + a)


def rectified_sine_mean(s0, a):
    """mean over θ of [s0 + a sin θ]+ for s0 >= 0: s0 if a <= s0, else
    s0 (1/2 + β/π) + a cos β / π with β = arcsin(s0/a)."""
    s0, a = np.broadcast_arrays(np.asarray(s0, dtype=float), np.asarray(a, dtype=float))
    with np.errstate(divide="ignore", invalid="ignore"):
        beta = np.arcsin(np.clip(s0 / a, -1.0, 1.0))
        above = s0 * (0.5 + beta / np.pi) + a * np.cos(beta) / np.pi
    return np.where(a <= s0, s0, above)


# --- the Saal et al. 2017 afferents: thresholds by simulation --------------------------------


def saal_cycle_counts(aff: Afferents, frequency, a, s0, scale: float, kappa: float):
    """Spike counts of each lane (one fit, frequency, amplitude a and pressed value s0 of the
    site quantity per lane) in its counted cycles: (total, fewest per cycle). The site quantity
    s = s0 + a sin(2π f t) from t = 0, sampled at the model's 5 kHz, mapped to its inputs
    (`site_inputs`: central differences, as its fits were made); cycles counted after
    SAAL_SETTLE, max(SAAL_CYCLES, SAAL_COUNT f) of them."""
    f = np.asarray(frequency, dtype=float)
    t, cycle, inside = _saal_clock(f, aff.fs)
    s = s0[:, None] + a[:, None] * np.sin(2 * np.pi * f[:, None] * t[None, :])
    flags = spike_flags(aff, *site_inputs(s, aff.fs, scale, kappa))
    return _saal_tally(flags, cycle, inside, _saal_counted(f))


def _saal_clock(f, fs: float):
    """The samples' times (T,) of lanes of frequencies f (long enough for the slowest lane),
    each sample's counted cycle (n, T) and whether it is counted (n, T)."""
    counted = _saal_counted(f)
    steps = int(math.ceil((SAAL_SETTLE + np.max(counted / f)) * fs)) + 1
    t = np.arange(steps) / fs
    cycle = np.floor((t[None, :] - SAAL_SETTLE) * f[:, None]).astype(int)
    return t, cycle, (cycle >= 0) & (cycle < counted[:, None])


def _saal_tally(flags, cycle, inside, counted):
    """(total, fewest per counted cycle) of spike flags (n, T)."""
    counts = np.zeros((len(flags), counted.max()))
    lane, k = np.nonzero(flags & inside)
    np.add.at(counts, (lane, cycle[lane, k]), 1)
    unused = np.arange(counted.max())[None, :] >= counted[:, None]
    return counts.sum(axis=1), np.where(unused, np.inf, counts).min(axis=1)


class SineLanes:
    """`saal_cycle_counts` of fixed lanes (fit, f, s0) at any amplitudes, with the work that
    does not depend on the amplitude done once. Everything before the rectification is linear
    in the stimulus (central differences, the low-pass), so the filtered inputs are
    S0 + a·S1 (static; S0 of s0 alone, S1 of the unit sine) and a·U (dynamic); a > 0 passes
    through the rectification of the dynamic terms, whose current is a·D. Each amplitude then
    costs the static terms (classes with a static weight), the saturation, the neuron and the
    tally: the same numbers as `saal_cycle_counts` up to round-off."""

    def __init__(self, aff: Afferents, frequency, s0, scale: float, kappa: float):
        f, s0 = np.asarray(frequency, dtype=float), np.asarray(s0, dtype=float)
        self.aff, self.counted = aff, _saal_counted(f)
        self.t, self.cycle, self.inside = _saal_clock(f, aff.fs)
        unit = np.sin(2 * np.pi * f[:, None] * self.t[None, :])
        s1, u1 = site_inputs(unit, aff.fs, scale, kappa)
        dynamic_weights = aff.weights * np.array([0, 0, 1, 1, 1, 1])
        self.dynamic = rectified(dynamic_weights, np.zeros_like(u1),
                                 lowpass(u1, aff.cutoff_Hz, aff.fs))
        self.static_weights = aff.weights[:, :2]
        self.static = None
        if np.any(self.static_weights):  # SA1: TouchSim filters its static input only
            s00 = site_inputs(np.broadcast_to(s0[:, None], unit.shape), aff.fs, scale, kappa)[0]
            sa1 = aff.cls == "SA1"
            s00[sa1] = lowpass(s00[sa1], aff.cutoff_Hz[sa1], aff.fs)
            s1[sa1] = lowpass(s1[sa1], aff.cutoff_Hz[sa1], aff.fs)
            self.static = (s00, s1)

    def counts(self, a):
        """(total, fewest per counted cycle) per lane at amplitudes a (n,) > 0."""
        a = np.asarray(a, dtype=float)[:, None]
        current = self.dynamic * a
        if self.static is not None:
            s = self.static[0] + a * self.static[1]
            p = self.static_weights
            current += p[:, :1] * np.maximum(s, 0.0) + p[:, 1:] * np.maximum(-s, 0.0)
        j = saturated(current, self.aff.saturation)
        flags = integrate_and_fire(j, self.aff.tau, self.aff.post_spike, self.aff.refractory)
        return _saal_tally(flags, self.cycle, self.inside, self.counted)


def _saal_search(aff, f, s0, scale, kappa):
    """Geometric bisection per lane of the smallest amplitude with a spike in the counted
    cycles (I0) and with one in each (I1), in the site quantity's units, both in one
    simulation per round (lanes doubled); inf if SAAL_RANGE's top does not meet the criterion,
    NaN (both) if its bottom already fires (the pressed value alone fires)."""
    both = aff.take(np.tile(np.arange(len(aff)), 2))
    f2, s02 = np.tile(f, 2), np.tile(s0, 2)
    entrain = np.arange(2 * len(f)) >= len(f)
    lo = np.full(2 * len(f), SAAL_RANGE[0] / scale)
    hi = np.full(2 * len(f), SAAL_RANGE[1] / scale)
    lanes = SineLanes(both, f2, s02, scale, kappa)

    def meets(a):
        total, fewest = lanes.counts(a)
        return np.where(entrain, fewest >= 1, total > 0)

    top, bottom = meets(hi), meets(lo)
    for _ in range(SAAL_BISECTIONS):
        mid = np.sqrt(lo * hi)
        ok = meets(mid)
        hi, lo = np.where(ok, mid, hi), np.where(ok, lo, mid)
    # at rest or not is the I0 criterion's bottom (any spike on s0 alone): a site that fires
    # on its pressed value has neither threshold (an ongoing discharge the vibration merely
    # entrains is not an I1), as for the LIF
    busy = np.tile(bottom[: len(f)], 2)
    out = np.where(busy, np.nan, np.where(top, hi, np.inf))
    return out[: len(f)], out[len(f):]


def _saal_counted(f) -> np.ndarray:
    """Cycles counted per lane: SAAL_COUNT seconds' worth, at least SAAL_CYCLES, or one where
    a period exceeds SAAL_SETTLE (every cycle then starts from a rested neuron)."""
    least = np.where(1.0 / f > SAAL_SETTLE, 1, SAAL_CYCLES)
    return np.maximum(least, np.ceil(SAAL_COUNT * f)).astype(int)


def _saal_duration(f):
    """Simulated time per lane (s): SAAL_SETTLE plus the counted cycles."""
    return SAAL_SETTLE + _saal_counted(f) / f


def _saal_chunks(f) -> list[np.ndarray]:
    """Lanes grouped by frequency (highest first) so that lanes × samples of each group stays
    within SAAL_BUDGET: a group is simulated as long as its slowest lane needs."""
    order = np.argsort(-f, kind="stable")
    chunks, start = [], 0
    for k in range(1, len(order) + 1):
        if k == len(order) or 2 * (k + 1 - start) * _saal_duration(f[order[k]]) * 5000 > (
                SAAL_BUDGET):
            chunks.append(order[start:k])
            start = k
    return chunks


def saal_thresholds_stimulus(cls: ReceptorClass, frequency, s0) -> tuple[np.ndarray, ...]:
    """(I0, I1) per lane (f, s0) in the site quantity's units for a class with the Saal et al.
    2017 model: the most sensitive of its fits (min over them; NaN if every fit fires on s0
    alone). Lanes × fits simulated together, grouped by frequency (`_saal_chunks`)."""
    f, s0 = (np.asarray(x, dtype=float).ravel() for x in np.broadcast_arrays(frequency, s0))
    fits = cls.saal.afferents(cls.name)
    n = len(fits)
    lane = np.repeat(np.arange(len(f)), n)
    fit = np.tile(np.arange(n), len(f))
    out = np.full((2, len(lane)), np.nan)
    for chunk in _saal_chunks(f[lane]):
        out[:, chunk] = _saal_search(fits.take(fit[chunk]), f[lane[chunk]], s0[lane[chunk]],
                                     cls.saal.input_scale, cls.saal.kappa(cls.name))
    out = out.reshape(2, len(f), n)
    with np.errstate(all="ignore"):
        best = np.where(np.all(np.isnan(out), axis=2), np.nan,
                        np.nanmin(np.where(np.isnan(out), np.inf, out), axis=2))
    return best[0], best[1]


# --- published afferent tuning, to overlay -------------------------------------------------


@dataclass(frozen=True)
class Published:
    """A published fact about vibrotactile sensitivity: the band of best frequencies (Hz),
    and a threshold amplitude (mm) where one was read; `source` (exact citation), `read`
    (what was read: primary abstract or secondary table) and `note`."""

    cls: str  # "SA1", "RA", "PC" or "psychophysics"
    band: tuple[float, float] | None
    amplitude: float | None
    source: str
    read: str
    note: str = ""


#: Verified by reading (see `read`); nothing else is overlaid. NOT verified (not overlaid):
#: the threshold points RECEPTORS.md lists (PC ~0.05 µm near 250-340 Hz, SA1 ~6 µm near
#: 16 Hz, RA ~47 µm near 33 Hz): digitised curves in github.com/ouyangqq/model_tactile_pop_
#: response, Data/txtdata/fitting_NTH_*.txt and Neural_threhold_all.txt, whose original
#: source, preparation and threshold definition are named nowhere in that repository (its
#: Fig.4_Model_fitting.py only loads them); no primary source with those numbers was found.
#: Talbot et al. 1968 (J Neurophysiol 31:301) and Mountcastle, LaMotte & Carli 1972 could not
#: be read (no abstract found): their "tuning point" naming is left out.
PUBLISHED = (
    Published("RA", (8.0, 64.0), None,
              "Johansson, Landström & Lundström 1982, Brain Res 244:17-25, "
              "doi 10.1016/0006-8993(82)90899-x",
              "abstract (PubMed): 'The rapidly adapting units (RA) were most easily excited at "
              "stimulus frequencies between 8 and 64 Hz'",
              "human median nerve, 0.5-400 Hz, 0.001-1 mm; cycle response = impulses per cycle"),
    Published("PC", (64.0, 400.0), None,
              "Johansson, Landström & Lundström 1982, Brain Res 244:17-25",
              "abstract: 'the corresponding frequencies for the Pacinian units (PC) were above "
              "64 Hz' (400 Hz: the highest frequency tested)"),
    Published("SA1", None, None,
              "Johansson, Landström & Lundström 1982, Brain Res 244:17-25",
              "abstract: 'The sensitivities of the slowly adapting unit types (SA I and SA II) "
              "were greatest at lower frequencies' (no band given)"),
    Published("RA", (40.0, 60.0), 2e-5,
              "table 1 of doi 10.1152/jn.90990.2008 (J Neurophysiol 101:1033-1042, 2009), "
              "a secondary summary of primate afferents",
              "'RA afferent ... 40-60 Hz  Threshold >= 2 x 10^-5 mm' (as printed; its primary "
              "sources not read)",
              "a lower bound, not a typical threshold"),
    Published("PC", (200.0, 300.0), 1e-5,
              "table 1 of doi 10.1152/jn.90990.2008 (secondary)",
              "'PC afferent ... 200-300 Hz  Threshold >= 10^-5 mm' (as printed)",
              "a lower bound, not a typical threshold"),
    Published("psychophysics", (250.0, 300.0), None,
              "Gescheider & Verrillo, 'Vibrotactile frequency characteristics as determined by "
              "adaptation and masking procedures', doi 10.1007/978-1-4613-3039-4_10",
              "chapter abstract: the vibrotactile threshold 'is a U-shaped function of frequency "
              "with the lowest values at approximately 250-300 Hz'; with contactors >= 2.9 cm² "
              "(Verrillo 1963) flat to 40 Hz, then falling 12 dB/octave to ~250 Hz"),
)


def _short_source(source: str) -> str:
    """First author and year of a citation ("Johansson 1982"); "secondary table" for a
    summary table (doi 10.1152/jn.90990.2008, 2009)."""
    import re

    if source.startswith("table"):
        return "secondary table, J Neurophysiol 2009"
    year = re.search(r"\b(19|20)\d\d\b", source)
    return source.split(",")[0] + (f" {year.group(0)}" if year else "")


def _published_handle(p: Published, colour):
    """The overlay of one published fact and its legend entry (band shaded, hatched for the
    psychophysical one; a threshold as a bar over its band)."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    band = f"{p.band[0]:g}–{p.band[1]:g} Hz"
    who = "human psychophysics" if p.cls == "psychophysics" else p.cls
    if p.amplitude is None:
        return Patch(facecolor=colour, alpha=0.15, hatch="//" if p.cls == "psychophysics"
                     else None, label=f"{who}: best band {band} ({_short_source(p.source)})")
    return Line2D([], [], color=colour, lw=4, alpha=0.5, label=(
        f"{who}: threshold ≥ {p.amplitude * 1e3:g} µm at {band} (lower bound; "
        f"{_short_source(p.source)})"))


def touchsim_thresholds() -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """TouchSim's own thresholds per class: (frequency Hz, I0 mm, I1 mm), the most sensitive of
    its fits under its 0.5 mm pin about rest (data/receptors/touchsim_thresholds.csv, made by
    scripts/calibrate_afferents.py --touchsim-curves; its source in the file's header)."""
    path = builtin_dir("receptors") / "touchsim_thresholds.csv"
    rows = [line.split(",") for line in path.read_text().splitlines()
            if line and not line.startswith("#")][1:]
    out = {}
    for name in dict.fromkeys(r[0] for r in rows):
        values = np.array([[float(x) for x in r[1:]] for r in rows if r[0] == name])
        out[name] = (values[:, 0], values[:, 1] * 1e-3, values[:, 2] * 1e-3)
    return out


def _touchsim_lines(ax, curves, colours) -> list:
    """TouchSim's own I0 (thin solid) and I1 (dashed) per class of `curves`, over their
    frequency range; one legend handle per class."""
    from matplotlib.lines import Line2D

    reference, handles = touchsim_thresholds(), []
    for th in curves:
        if th.name not in reference:
            continue
        f, i0, i1 = reference[th.name]
        keep = (f >= th.frequency.min() / 1.2) & (f <= th.frequency.max() * 1.2)
        c = colours.get(th.name, "k")
        ax.loglog(f[keep], i0[keep] * 1e3, "-", color=c, lw=0.8, alpha=0.6)
        ax.loglog(f[keep], i1[keep] * 1e3, "--", color=c, lw=0.8, alpha=0.6)
        handles.append(Line2D([], [], color=c, lw=0.8, ls="--", label=(
            f"{th.name} TouchSim (Saal et al. 2017)")))
    return handles


def plot_threshold_curves(curves, path, *, published=PUBLISHED, title: str = "",
                          note: str = "", touchsim: bool = True) -> list[str]:
    """Threshold vs frequency, log-log, amplitudes in µm: per class (colour) the most
    sensitive site's absolute threshold I0 (filled circles) and 1:1 entrainment threshold I1
    (open triangles), at the computed frequencies only (markers: a line would pass across
    resonances the sweep did not compute); the published bands of best frequency as shaded
    spans (hatched for the psychophysical one) and published threshold amplitudes as bars
    over their band, each named in the legend below the axes. A missing marker: no threshold
    there (the pressed state alone fires the site, or it cannot follow 1:1). `note`: a
    warning written in red above the axes (the frequency route's resolution warning).
    `touchsim`: TouchSim's own thresholds of the classes drawn as lines (`touchsim_thresholds`).
    `curves`: VibrationThresholds, one per class. Returns the legend's entries."""
    from matplotlib.figure import Figure

    from ..plotting.figures import plain_log_ticks

    colours = {"SA1": "tab:blue", "RA": "tab:green", "PC": "tab:red",
               "psychophysics": "0.5"}
    fig = Figure(figsize=(7.2, 7.6 if touchsim else 7.0))
    ax = fig.subplots()
    handles = []
    for th in curves:
        c = colours.get(th.name, "k")
        for criterion, marker, fill, name in (("absolute", "o", c, "I0 absolute"),
                                              ("entrainment", "^", "none", "I1 1:1")):
            y = th.best(criterion) * 1e3
            keep = np.isfinite(y) & (y > 0)
            handles += ax.loglog(th.frequency[keep], y[keep], marker, color=c, mfc=fill, ms=5,
                                 ls="none", label=f"{th.name} {name}" + (
                                     "" if keep.any() else ": none"))
    if touchsim:
        handles += _touchsim_lines(ax, curves, colours)
    for p in published:
        c = colours.get(p.cls, "k")
        if p.band is None:
            continue
        if p.amplitude is None:
            ax.axvspan(*p.band, color=c, alpha=0.08, hatch="//" if p.cls == "psychophysics"
                       else None)
        else:
            ax.plot(p.band, [p.amplitude * 1e3] * 2, color=c, lw=4, alpha=0.5,
                    solid_capstyle="butt")
        handles.append(_published_handle(p, c))
    ax.set_xlabel("vibration frequency (Hz)")
    ax.set_ylabel("probe amplitude at threshold (µm)")
    plain_log_ticks(ax, "x")
    ax.grid(alpha=0.3, which="both")
    ax.set_title(title or "afferent thresholds (most sensitive site)", fontsize=9)
    fig.legend(handles=handles, loc="lower center", bbox_to_anchor=(0.5, 0.025), fontsize=7,
               ncol=2, frameon=False)
    fig.text(0.5, 0.005, "markers: computed frequencies; no marker: no threshold there (the "
             "pressed state alone fires, or the site cannot follow 1:1)" + (
                 "\nlines: TouchSim's own fits on its half-space under its 0.5 mm pin, about "
                 "rest: I1 dashed, I0 solid" if touchsim else ""),
             ha="center", fontsize=7, color="0.3")
    if note:
        fig.text(0.5, 0.975, note, ha="center", va="top", fontsize=7, color="tab:red")
    fig.tight_layout(rect=(0, 0.23 if touchsim else 0.19, 1, 0.96 if note else 1))
    fig.savefig(path, dpi=150)
    return [h.get_label() for h in handles]
