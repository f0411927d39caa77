r"""Signals of time-domain runs: the steady-state harmonic at a drive frequency.

A linear (or weakly nonlinear) damped system driven at ω settles, once its free transients
have decayed, to s(t) = c + Re(Z e^{iωt}); Z = A − iB for s = c + A cos ωt + B sin ωt. The
least-squares fit of (c, A, B) over a whole number of the last periods gives Z with the
components at other frequencies (harmonics of a nonlinear response, decayed transients)
orthogonal to cos and sin over those periods: exact for a pure harmonic plus a constant, and
for a slow drift (the skin's QLV relaxation under the held press) with `trend=True`, which adds
a column t. The time-domain and the frequency-domain results compare through Z: |Z| the
amplitude, arg Z the phase lead relative to cos ωt at t = 0 of `times`.

Spike trains locked to a periodic stimulus: the vector strength of their phases (`vector_strength`).
"""

from __future__ import annotations

import math

import numpy as np


def steady_state(times, signal, frequency: float, periods: float = 3.0, *,
                 trend: bool = False) -> complex:
    """The complex amplitude Z at `frequency` (Hz) of `signal` over its last `periods` periods:
    signal ≈ c (+ d t) + Re(Z e^{iωt}), ω = 2π·frequency, by least squares on
    [cos ωt, sin ωt, 1 (, t)]. Needs at least 4 samples per period over the window."""
    t, s = np.asarray(times, dtype=float), np.asarray(signal, dtype=float)
    if t.shape != s.shape or t.ndim != 1:
        raise ValueError(f"times {t.shape} and signal {s.shape} must be 1-D of equal length")
    if not (frequency > 0 and periods > 0):
        raise ValueError(f"need frequency > 0 and periods > 0, got {frequency}, {periods}")
    start = t[-1] - periods / frequency
    if start < t[0] - 1e-12 * max(1.0, abs(t[0])):
        raise ValueError(f"the signal covers {(t[-1] - t[0]) * frequency:.3g} periods, fewer "
                         f"than the {periods} asked")
    window = t >= start - 1e-9 / frequency
    t, s = t[window], s[window]
    if len(t) < 4 * periods:
        raise ValueError(f"{len(t)} samples over {periods} periods: too few to fit a harmonic")
    omega = 2 * math.pi * frequency
    columns = [np.cos(omega * t), np.sin(omega * t), np.ones_like(t)]
    if trend:
        columns.append(t - t.mean())
    coefficients, *_ = np.linalg.lstsq(np.column_stack(columns), s, rcond=None)
    return complex(coefficients[0], -coefficients[1])


def vector_strength(phases) -> float:
    """Goldberg & Brown's (1969) vector strength R = |mean e^{iφ}| of the events' phases φ
    (radians) in the stimulus cycle: 1 when every spike falls at the same phase, about
    1/sqrt(n) for n spikes uniform over the cycle (the mean of n unit vectors at random)."""
    phi = np.asarray(phases, dtype=float).ravel()
    if phi.size == 0:
        raise ValueError("no events: the vector strength needs at least one phase")
    return float(abs(np.exp(1j * phi).mean()))
