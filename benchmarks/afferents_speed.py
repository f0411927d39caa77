"""Speed of the afferent transduction (afferents.transduction, Saal et al. 2017): responses of
~1,000 afferents (the 17 fits repeated, each its own site stimulus) to 1 s of a site stimulus
sampled at 5 kHz (a 1 mm-pin-like ramp with a 100 Hz vibration on its hold). Target: < 10 s.

    PYTHONPATH=. python benchmarks/afferents_speed.py
"""

import time

import numpy as np

from fingertip_dolfinx.afferents.transduction import load_afferents, site_inputs, spike_times

N = 1000


def main():
    fits = load_afferents()
    aff = fits.take(np.arange(N) % len(fits))
    fs = aff.fs
    t = np.arange(int(fs)) / fs
    ramp = np.clip(t / 0.05, 0, 1) * np.clip((1 - t) / 0.05, 0, 1)
    gain = np.linspace(0.1, 1.0, N)[:, None]  # afferents at different distances from the load
    s = gain * 0.01 * (ramp + 0.02 * np.sin(2 * np.pi * 100 * t) * (t > 0.3) * (t < 0.7))
    started = time.perf_counter()
    static, dynamic = site_inputs(s, fs, 1.0, 2.4)
    trains = spike_times(aff, static, dynamic, noisy=True, rng=np.random.default_rng(0))
    elapsed = time.perf_counter() - started
    spikes = sum(len(x) for x in trains)
    print(f"{N} afferents, 1 s at {fs:g} Hz: {elapsed:.2f} s ({spikes} spikes, "
          f"{np.mean([len(x) for x in trains]):.1f} per afferent); target < 10 s")


if __name__ == "__main__":
    main()
