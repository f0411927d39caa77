import time, numpy as np
from fingertip_dolfinx.receptors import load_receptors, threshold_amplitude
from fingertip_dolfinx import vibrotactile as vt
pop = load_receptors()
f = np.geomspace(2, 1000, 40)
for name in ("RA", "PC", "SA1"):
    c = pop[name]
    H = np.ones((40, 20)) * np.exp(1j*0.3)
    s0 = np.linspace(0, 2e-6, 20) if name=="SA1" else np.zeros(20)
    t=time.time()
    th = vt.vibration_thresholds(c, f, H, s0)
    print(name, time.time()-t)
    print(np.array2string(th.best("absolute")[::5], precision=3), np.array2string(th.best("entrainment")[::5], precision=3))
    print("old", [threshold_amplitude(c.lif, ff) for ff in f[::10]])
