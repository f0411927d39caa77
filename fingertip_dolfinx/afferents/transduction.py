r"""Afferent transduction after Saal, Delhaye et al. 2017 (PNAS 114:E5693; TouchSim): a site
stimulus sampled in time -> spike times, vectorised over afferents (numpy).

The equations are those of TouchSim's `transduction.lif_neuron` (github.com/hsaal/touchsim,
commit 4ec9f5c), written here from its description; the numbers (4 SA1, 9 RA, 4 PC fits) are
data, `data/receptors/saal2017.toml`, each with its source. Per afferent, on samples k at
fs = 5 kHz (all times in samples; the fits were made on this grid):

1. **Inputs.** A static input s_k (TouchSim: the vertical stress of a Sneddon half-space at the
   afferent's depth, MPa) and a dynamic input u_k (TouchSim: the surface wave's rate term; this
   package: κ ṡ, see `site_inputs`).
2. **Low-pass.** Both pass a 3rd-order Butterworth low-pass at f_c = 10 c Hz (c = the fit's
   `cutoff_scale`; scipy's digital design at Wn = f_c / 2500); TouchSim filters the static input
   of SA1 only (RA and PC weigh it by 0).
3. **Rectified weights.** I_k = p1[s]+ + p2[s]- + p3[u]+ + p4[u]- + p5[Δu]+ + p6[Δu]-, with
   [x]- = max(-x, 0) and Δu_k = u_{k+1} - u_k (a forward difference per sample, 0 at the end).
4. **Noise** (optional): I_k += σ N(0, 1).
5. **Saturation** (p7 > 0): J = p7 I / (p7 + |I|).
6. **Neuron.** v_k = v_{k-1} (1 - 1/τ) + J_k + h_{n}, h = w1 b1 + w2 b2 the post-spike current
   (two basis functions of 190 samples, n samples since the last spike; none before the first
   spike or after the basis ends); a spike at sample k when v_k > 1 and at least 6 samples
   have passed since the last spike (refractory), then v = 0. Spike time (k + 1)/fs
   (+ the conduction delay, only if asked).

Closed forms the tests check: the filter's gain is 1 at DC and 1/√2 at f_c (Butterworth);
without post-spike current a constant J > 1/τ... fires every n samples, n the first k >= 6 with
J (1 - q^k)/(1 - q) > 1, q = 1 - 1/τ (the discrete leaky integrator's closed form).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import signal

from ..datafiles import find, read_toml
from ..errors import InputError

CLASSES = ("SA1", "RA", "PC")
MODEL = "saal2017"
#: Column order of a fit's parameters (TouchSim's 13 numbers, in its order).
WEIGHTS = ("s_pos", "s_neg", "ds_pos", "ds_neg", "dds_pos", "dds_neg")
#: Neurons that fire are stepped in up to this many groups of similar first-crossing time, each
#: from its own first crossing (`integrate_and_fire`).
LIF_GROUPS = 4
LIF_STEP_COST = 500  # lanes: a step's fixed cost (~12 numpy calls of ~1 µs)


@dataclass(frozen=True)
class Afferents:
    """n afferent models side by side: class names (n,), parameters as arrays."""

    cls: np.ndarray          # (n,) class names
    index: np.ndarray        # (n,) the fit's row in its class (TouchSim's idx)
    cutoff_Hz: np.ndarray    # (n,) low-pass cut-off, Hz
    weights: np.ndarray      # (n, 6) p1..p6
    saturation: np.ndarray   # (n,) p7 (0: none)
    noise: np.ndarray        # (n,) σ per sample
    tau: np.ndarray          # (n,) membrane time constant, samples
    post_spike: np.ndarray   # (n, m) h per sample after a spike
    delay_s: np.ndarray      # (n,) conduction delay, s
    fs: float = 5000.0
    refractory: int = 6

    def __len__(self) -> int:
        return len(self.cls)

    def take(self, rows) -> Afferents:
        """The afferents at `rows` (indices or a mask), same order."""
        rows = np.arange(len(self))[rows]
        pick = {k: getattr(self, k)[rows] for k in ("cls", "index", "cutoff_Hz", "weights",
                                                    "saturation", "noise", "tau", "post_spike",
                                                    "delay_s")}
        return Afferents(**pick, fs=self.fs, refractory=self.refractory)


def load_afferents(source: str | Path = MODEL, classes=CLASSES, rows=None) -> Afferents:
    """The fits of `classes` (all rows, or `rows`: {class: [indices]}) from a parameter file
    (built-in name or path), in class order then row order."""
    path = find("receptors", source, "afferent model")
    data = read_toml(path)
    basis = np.array([data["post_spike"]["basis1"], data["post_spike"]["basis2"]])
    fields = {k: [] for k in ("cls", "index", "cutoff_Hz", "weights", "saturation", "noise",
                              "tau", "post_spike", "delay_s")}
    for name in classes:
        fits = data.get(name)
        if not fits:
            raise InputError(f"{path}", f"has no fits of class {name!r}.",
                             f"use one of {', '.join(CLASSES)}.")
        chosen = range(len(fits)) if rows is None or name not in rows else rows[name]
        for i in chosen:
            if not 0 <= i < len(fits):
                raise InputError(f"{path}: {name}", f"has no fit {i} (0..{len(fits) - 1}).")
            p = fits[i]
            for key, value in (("cls", name), ("index", i),
                               ("cutoff_Hz", 10.0 * p["cutoff_scale"]),
                               ("weights", [p[w] for w in WEIGHTS]),
                               ("saturation", p["saturation"]), ("noise", p["noise"]),
                               ("tau", p["tau"]), ("post_spike", np.dot(p["ih_weights"], basis)),
                               ("delay_s", p["delay_ms"] / 1000.0)):
                fields[key].append(value)
    return Afferents(**{k: np.array(v) for k, v in fields.items()},
                     fs=float(data["sampling_Hz"]), refractory=int(data["refractory_samples"]))


def model_depths(source: str | Path = MODEL) -> dict[str, float]:
    """The depth (mm) at which the fits of each class read their half-space stress."""
    return {k: float(v) for k, v in read_toml(find("receptors", source, "afferent model"))[
        "depth_mm"].items()}


# --- the stages -------------------------------------------------------------------------------


def lowpass(x: np.ndarray, cutoff_Hz: np.ndarray, fs: float) -> np.ndarray:
    """Each row of x (n, T) through a 3rd-order Butterworth low-pass at its cut-off (zero
    initial state, as TouchSim); rows with the same cut-off share one filter."""
    y = np.empty_like(x, dtype=float)
    for fc in np.unique(cutoff_Hz):
        rows = cutoff_Hz == fc
        b, a = signal.butter(3, fc / (fs / 2))
        y[rows] = signal.lfilter(b, a, x[rows], axis=1)
    return y


def rectified(weights: np.ndarray, s: np.ndarray, u: np.ndarray) -> np.ndarray:
    """I = p1[s]+ + p2[s]- + p3[u]+ + p4[u]- + p5[Δu]+ + p6[Δu]- per sample, (n, T)."""
    du = np.diff(u, axis=1, append=u[:, -1:])
    terms = (s, u, du)
    current = np.zeros(np.broadcast_shapes(s.shape, u.shape))
    for k, x in enumerate(terms):
        for col, sign in ((2 * k, 1.0), (2 * k + 1, -1.0)):
            if np.any(weights[:, col]):  # (RA and PC weigh no [s], SA1 no [Δu])
                current += weights[:, col, None] * np.maximum(sign * x, 0.0)
    return current


def saturated(current: np.ndarray, saturation: np.ndarray) -> np.ndarray:
    """J = p7 I / (p7 + |I|) on the rows with p7 > 0; I elsewhere."""
    p7 = saturation[:, None]
    if np.all(saturation > 0):  # every row saturates (a group of such fits): no 0/0 to guard
        return p7 * current / (p7 + np.abs(current))
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(p7 > 0, p7 * current / (p7 + np.abs(current)), current)
    return np.nan_to_num(out, nan=0.0)


def integrate_and_fire(j: np.ndarray, tau: np.ndarray, post_spike: np.ndarray,
                       refractory: int) -> np.ndarray:
    """Spike flags (n, T) of the discrete leaky integrate-and-fire neurons driven by j (n, T).

    Until its first spike a neuron is the linear filter v_k = (1 - 1/τ) v_{k-1} + J_k (no
    post-spike current yet, no refractory period), which scipy runs in C: a neuron whose
    filtered current never exceeds 1 never fires, and the others are stepped sample by sample
    (`_lif_steps`) only from the first crossing of their group on, from the filter's state
    there (the same operations in the same order: the same flags)."""
    n, steps = j.shape
    j = np.asarray(j, dtype=float)
    spikes = np.zeros((n, steps), dtype=bool)
    if not n * steps:
        return spikes
    v_lin = np.empty_like(j)
    for t in np.unique(tau):  # one filter per membrane time constant
        rows = tau == t
        v_lin[rows] = signal.lfilter([1.0], [1.0, -(1.0 - 1.0 / t)], j[rows], axis=1)
    above = v_lin > 1.0
    first = np.where(above.any(axis=1), above.argmax(axis=1), steps)
    firing = np.flatnonzero(first < steps)
    order = firing[np.argsort(first[firing], kind="stable")]
    for group in _groups(order, first[order], steps):
        k0 = int(first[group[0]])
        v0 = v_lin[group, k0 - 1] if k0 > 0 else np.zeros(len(group))
        spikes[group, k0:] = _lif_steps(j[group, k0:], tau[group], post_spike[group],
                                        refractory, v0)
    return spikes


def _groups(order, start, steps: int) -> list[np.ndarray]:
    """`order` (rows sorted by their first crossing `start`) split into 1 to LIF_GROUPS groups
    of equal count, the number that costs least to step: a step costs LIF_STEP_COST lanes'
    worth of fixed overhead plus one per lane, from the group's first crossing on."""
    best, cost = [], np.inf
    for g in range(1, min(len(order), LIF_GROUPS) + 1):
        parts = np.array_split(np.arange(len(order)), g)
        c = sum((steps - start[p[0]]) * (LIF_STEP_COST + len(p)) for p in parts)
        if c < cost:
            best, cost = [order[p] for p in parts], c
    return best


def _lif_steps(j: np.ndarray, tau: np.ndarray, post_spike: np.ndarray, refractory: int,
               v0: np.ndarray) -> np.ndarray:
    """Spike flags (n, T) of the neurons from membrane v0 and no spike yet, stepped sample by
    sample, each step vectorised over the afferents (in-place updates: the cost is per step,
    nearly independent of n up to ~1e3)."""
    n, steps = j.shape
    m = post_spike.shape[1]
    h = np.concatenate([post_spike, np.zeros((n, 1))], axis=1).ravel()  # column m: none
    base = np.arange(n) * (m + 1)
    cap, ready = base + m, base + refractory
    leak = 1.0 - 1.0 / tau
    drive = np.ascontiguousarray(j.T)
    v = np.array(v0, dtype=float)
    at = cap.copy()  # base + samples since the last spike, capped at m (none yet: m)
    spikes = np.zeros((steps, n), dtype=bool)
    fire, free = np.empty(n, dtype=bool), np.empty(n, dtype=bool)
    for k in range(steps):
        v *= leak
        v += drive[k]
        v += h.take(at)
        at += 1
        np.minimum(at, cap, out=at)
        np.greater(v, 1.0, out=fire)
        np.greater_equal(at, ready, out=free)
        fire &= free
        spikes[k] = fire
        np.putmask(v, fire, 0.0)
        np.putmask(at, fire, base)
    return spikes.T


def currents(aff: Afferents, static, dynamic, *, noisy: bool = False, rng=None) -> np.ndarray:
    """J (n, T) for the inputs (n, T) (or (T,), the same for every afferent) at aff.fs."""
    n = len(aff)
    s = np.broadcast_to(np.atleast_2d(np.asarray(static, dtype=float)), (n, np.shape(static)[-1]))
    u = np.broadcast_to(np.atleast_2d(np.asarray(dynamic, dtype=float)), s.shape)
    sa1 = aff.cls == "SA1"
    s = s.copy()
    if np.any(sa1):  # TouchSim filters the static input of SA1 only (RA and PC weigh it 0)
        s[sa1] = lowpass(s[sa1], aff.cutoff_Hz[sa1], aff.fs)
    u = lowpass(np.array(u), aff.cutoff_Hz, aff.fs)
    current = rectified(aff.weights, s, u)
    if noisy:
        rng = np.random.default_rng() if rng is None else rng
        current = current + aff.noise[:, None] * rng.standard_normal(current.shape)
    return saturated(current, aff.saturation)


def spike_flags(aff: Afferents, static, dynamic, *, noisy: bool = False, rng=None):
    """Spike flags (n, T) on the inputs' samples (see `currents`)."""
    j = currents(aff, static, dynamic, noisy=noisy, rng=rng)
    return integrate_and_fire(j, aff.tau, aff.post_spike, aff.refractory)


def spike_times(aff: Afferents, static, dynamic, *, noisy: bool = False, rng=None,
                delay: bool = False) -> list[np.ndarray]:
    """Spike times (s) per afferent for the inputs sampled at aff.fs from t = 0: sample k's spike
    at (k + 1)/fs, plus the conduction delay if `delay`."""
    flags = spike_flags(aff, static, dynamic, noisy=noisy, rng=rng)
    return [(np.flatnonzero(f) + 1) / aff.fs + (aff.delay_s[i] if delay else 0.0)
            for i, f in enumerate(flags)]


# --- this package's site quantity as the model's inputs ---------------------------------------


def sneddon_axis_factor(xi):
    """σz(0, z) / (P / (2π a²)) under a flat round punch of radius a at depth ξ = z/a on its
    axis (Sneddon 1946): 1/(1 + ξ²) + 2ξ²/(1 + ξ²)²."""
    xi = np.asarray(xi, dtype=float)
    return 1.0 / (1.0 + xi**2) + 2.0 * xi**2 / (1.0 + xi**2) ** 2


def rate_factor(depth: float, radius: float) -> float:
    """κ (1/mm) with u = κ ṡ under the pin's axis in TouchSim's mechanics: its dynamic input is
    Ṗ/(2a) / z² (deflection decay 1/(2a) under the pin, 1/z² with depth) while its static input
    is P (Sneddon factor)/(2π a²), so u/ṡ = π a / (z² factor(z/a))."""
    if depth <= 0 or radius <= 0:
        raise InputError("rate_factor", f"depth {depth} and radius {radius} mm must be > 0.")
    return float(np.pi * radius / (depth**2 * sneddon_axis_factor(depth / radius)))


def site_inputs(s, fs: float, scale, kappa) -> tuple[np.ndarray, np.ndarray]:
    """(static, dynamic) model inputs from a site quantity s (n, T) sampled at fs (compression
    positive): static = α s, dynamic = α κ ds/dt (central differences, the end values copied from
    their neighbours, as TouchSim differentiates its deflection). α, κ per row or scalars."""
    s = np.atleast_2d(np.asarray(s, dtype=float))
    rate = np.zeros_like(s)
    if s.shape[1] > 2:
        rate[:, 1:-1] = (s[:, 2:] - s[:, :-2]) * (fs / 2.0)
        rate[:, 0], rate[:, -1] = rate[:, 1], rate[:, -2]
    alpha = np.reshape(np.asarray(scale, dtype=float), (-1, 1))
    kappa = np.reshape(np.asarray(kappa, dtype=float), (-1, 1))
    return alpha * s, alpha * kappa * rate
