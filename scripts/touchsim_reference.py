"""Reference responses of TouchSim's afferents, for tests/test_transduction.py.

Runs in a separate environment with TouchSim installed (it is a calibration tool, not a
dependency of this package):

    python3 -m venv /tmp/ts-venv
    /tmp/ts-venv/bin/pip install numpy scipy numba scikit-image matplotlib
    git clone https://github.com/hsaal/touchsim /tmp/touchsim   # read at commit 4ec9f5c
    /tmp/ts-venv/bin/pip install --no-deps -e /tmp/touchsim     # -e: it reads surfaces/hand.png
    /tmp/ts-venv/bin/python scripts/touchsim_reference.py       # from this repository's root

Writes tests/data/touchsim_reference.json: per stimulus (TouchSim's own generators: the ramps
and sinusoids of its tests/test_response.py, a grid of sinusoids and two ramps under a 0.5 mm
pin) and per afferent (all 17 fits, noise off, no delay, placed under the pin's centre), the
spike count and the spike samples (spike time × 5 kHz − 1). TouchSim's input at an afferent
under a single pin is linear in the pin's trace: static = c_s · trace, dynamic = c_u ·
d(trace)/dt (central differences, end values copied). The script exports c_s and c_u per
(class, pin radius) from TouchSim's own `Stimulus.propagate` and checks that reconstruction
(its error is stored).
"""

import json
import sys
from pathlib import Path

import numpy as np
import touchsim as ts

OUT = Path(__file__).resolve().parents[1] / "tests" / "data" / "touchsim_reference.json"
NFITS = {"SA1": 4, "RA": 9, "PC": 4}
#: Depths (mm) of the ramps under the default 0.5 mm pin (benchmarks/touchsim_ramps.py).
RAMP_DEPTHS = (1.0, 0.25)


def stimuli():
    """(label, kind, keyword arguments) of TouchSim's generators."""
    yield "ramp 1 mm, 1 mm pin", "ramp", {"amp": 1.0, "pin_radius": 1.0}
    for f, a in ((10.0, 0.5), (25.0, 0.5), (250.0, 0.005)):  # its tests/test_response.py
        yield f"sine {f:g} Hz {a:g} mm", "sine", {"freq": f, "amp": a}
    for f in (5.0, 20.0, 50.0, 100.0, 200.0, 400.0):
        for a in (0.01, 0.1):
            yield f"sine {f:g} Hz {a:g} mm", "sine", {"freq": f, "amp": a}
    for a in RAMP_DEPTHS:  # ramps under the default pin, for the finite-element comparison
        yield f"ramp {a:g} mm, 0.5 mm pin", "ramp", {"amp": a, "pin_radius": 0.5}


def make(kind, args):
    return ts.stim_ramp(**args) if kind == "ramp" else ts.stim_sine(**args)


def central_rate(trace, fs):
    """TouchSim's time derivative of the deflection (transduction.skin_touch_profile)."""
    d = np.empty_like(trace)
    d[1:-1] = (trace[2:] - trace[:-2]) / 2.0 * fs
    d[0], d[-1] = d[1], d[-2]
    return d


def input_factors(stim, cls):
    """(c_s, c_u, relative reconstruction error) of TouchSim's inputs at an afferent under
    the pin."""
    aff = ts.Afferent(cls, idx=0, noisy=False)
    static, dynamic, fs = stim.propagate(aff)
    trace = stim.trace[0]
    rate = central_rate(trace, fs)
    c_s = float(np.dot(static[:, 0], trace) / np.dot(trace, trace))
    c_u = float(np.dot(dynamic[:, 0], rate) / np.dot(rate, rate))
    err = max(np.max(np.abs(static[:, 0] - c_s * trace)) / np.max(np.abs(static)),
              np.max(np.abs(dynamic[:, 0] - c_u * rate)) / np.max(np.abs(dynamic)))
    return c_s, c_u, float(err)


def main():
    records = []
    for label, kind, args in stimuli():
        stim = make(kind, args)
        rec = {"label": label, "kind": kind, "args": args, "fs": stim.fs,
               "pin_radius": stim.pin_radius, "samples": int(stim.trace.shape[1]),
               "input": {}, "responses": []}
        for cls, n in NFITS.items():
            c_s, c_u, err = input_factors(stim, cls)
            rec["input"][cls] = {"c_s": c_s, "c_u": c_u, "relative_error": err}
            for idx in range(n):
                r = ts.Afferent(cls, idx=idx, noisy=False).response(stim)
                samples = np.rint(np.asarray(r.spikes[0]) * stim.fs - 1).astype(int)
                rec["responses"].append({"class": cls, "index": idx, "count": int(len(samples)),
                                         "rate": float(r.rate()[0, 0]),
                                         "spike_samples": samples.tolist()})
        records.append(rec)
        print(label, {c: rec["input"][c]["relative_error"] for c in NFITS}, file=sys.stderr)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps({
        "source": "TouchSim (Saal, Delhaye et al. 2017, PNAS 114:E5693), github.com/hsaal/"
                  "touchsim commit 4ec9f5c382e7d48410566de743d7a4f05de75cec",
        "script": "scripts/touchsim_reference.py", "noisy": False, "delay": False,
        "stimuli": records}, separators=(",", ":")))
    print(f"written: {OUT} ({OUT.stat().st_size} bytes)")


if __name__ == "__main__":
    main()
