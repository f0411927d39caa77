"""The `scan` scene (docs/benchmarks/friction.md, "3D: the `scan` scene"): the forces and
Coulomb's law over the scan, the afferents' spikes against the ridges passing over their sites
(a raster by the site's position along the finger, with the ridges' centre lines), and each
class's population rate; prints the measured numbers: the modulation of the forces and of the
rates at the ridge frequency speed/period over the last two periods, the forces' repetition
from one period to the next, and each class's vector strength of its spikes' ridge phases.

Forces are taken in the grating's own frame (normal n and direction of travel t; a tilted
grating's plane is rotated about x). Run: `fingertip run scan --out DIR`, then
`python benchmarks/scan_figure.py DIR OUT.png`.
"""

import sys
from pathlib import Path

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from fingertip_dolfinx.outputs import read_csv  # noqa: E402
from fingertip_dolfinx.result import Result  # noqa: E402
from fingertip_dolfinx.scene import load_scene  # noqa: E402
from fingertip_dolfinx.studies.scan import (  # noqa: E402
    along_plane,
    friction_share,
    in_plane_frame,
    ridge_frequency,
    ridge_phases,
)
from fingertip_dolfinx.studies.signals import steady_state, vector_strength  # noqa: E402

CLASSES = {"SA1": "tab:blue", "RA": "tab:orange", "PC": "tab:green"}
STRIP_X = 2.0  # mm: afferents under the middle of the contact strip, |x| < this


def window(scene, h: dict) -> tuple[float, float, int]:
    """(start, end (s), whole periods) of the analysis: the run's last two periods of scan, or
    its last one when it was stopped before two (its end is the history's last step)."""
    _, _, f = ridge_frequency(scene)
    end = h["time_s"][-1]
    periods = min(2, int(scene.history.tangential_at(end) // scene.indenters[0].period))
    if periods < 1:
        raise SystemExit("the run scanned less than one period: nothing to analyse")
    return end - periods / f, end, periods


def force_measures(scene, h: dict) -> dict:
    """Coulomb's ratios and the forces' modulation at the ridge frequency."""
    mu, (_, _, f) = scene.indenters[0].friction, ridge_frequency(scene)
    t = h["time_s"]
    t0, _, periods = window(scene, h)
    last = t >= t0 - 1e-9
    out = {"coulomb": friction_share(h, mu), "window": last, "periods": periods,
           "ft_mu_fn": np.hypot(h["tangential_x_force_N"], h["tangential_z_force_N"])
           / (mu * np.abs(h["force_N"]))}
    for k in ("force_N", "tangential_z_force_N"):
        s = h[k][last]
        # one period back, where the skin was already slipping (no stick left)
        back = t[last] - 1 / f >= t[(t > ridge_frequency(scene)[0]) & (h["stick_area_mm2"] == 0)][0]
        repeat = s[back] - np.interp(t[last][back] - 1 / f, t, h[k])
        out[k] = {"mean": s.mean(), "peak_to_peak": np.ptp(s),
                  "harmonic": abs(steady_state(t, h[k], f, periods=periods, trend=True)),
                  "repeat": np.abs(repeat).max() if back.any() else np.nan}
    return out


def spike_measures(scene, h: dict, afferents: dict, spikes: dict) -> dict:
    """Per class, over the last two periods, afferents under the strip: spikes, vector
    strength of the ridge phases, the population rate's harmonic at f over its mean."""
    start, _, f = ridge_frequency(scene)
    t0, end, periods = window(scene, h)
    along_of = dict(zip(afferents["afferent"],
                        along_plane(scene, afferents["y_mm"], afferents["z_mm"])))
    strip = set(afferents["afferent"][np.abs(afferents["x_mm"]) < STRIP_X])
    out = {}
    for name in CLASSES:
        rows = ((spikes["class"] == name) & (spikes["time_s"] >= t0)
                & np.isin(spikes["afferent"], list(strip)))
        times = spikes["time_s"][rows]
        n_aff = int(np.sum((afferents["class"] == name) & np.isin(afferents["afferent"],
                                                                   list(strip))))
        entry = {"afferents": n_aff, "spikes": int(rows.sum())}
        if rows.sum() > 0:
            along = [along_of[a] for a in spikes["afferent"][rows]]
            entry["R"] = vector_strength(ridge_phases(scene, times, along))
            edges = np.linspace(t0, end, 6 * periods + 1)  # 6 bins a period
            rate = np.histogram(times, edges)[0] / np.diff(edges) / n_aff
            mid = 0.5 * (edges[1:] + edges[:-1])
            entry["rate_mean"] = rate.mean()
            entry["rate_harmonic"] = abs(steady_state(mid, rate, f, periods=periods - 1 / 6))
        out[name] = entry
    return out


def forces_panel(ax, scene, h: dict, m: dict) -> None:
    start, _, _ = ridge_frequency(scene)
    t = 1e3 * h["time_s"]
    ax.plot(t, 1e3 * h["force_N"], "k-", label="normal force $F_n$ (half model)")
    ax.plot(t, 1e3 * h["tangential_z_force_N"], "-", color="tab:red",
            label="tangential force $F_t$")
    ax.plot(t, 1e3 * h["pressure_tangential_z_force_N"], ":", color="tab:purple",
            label="its pressure share (ridges' flanks)")
    ax.set_ylabel("force (mN)")
    ax.set_ylim(top=1.35e3 * np.max(h["force_N"]))  # room for the legend above the peak
    ax.axvline(1e3 * start, color="0.6", lw=0.8)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", ncol=3)
    ratio = ax.twinx()
    ratio.plot(t, m["ft_mu_fn"], "--", color="tab:red", lw=0.9)
    ratio.plot(t, m["coulomb"], "--", color="tab:green", lw=0.9)
    ratio.set_ylabel(r"$|F_t|/(\mu F_n)$ (red), $F_{f,t}/(\mu F_{p,n})$ (green)", fontsize=8)
    ratio.set_ylim(0, 1.6)


def raster_panel(ax, scene, afferents: dict, spikes: dict) -> None:
    """Each spike at (time, its site's place along the grating's plane, `along_plane`) for
    the afferents under the strip, with the ridges' centre lines s(t) + kP sweeping up."""
    grating, path = scene.indenters[0], scene.history
    z_of = dict(zip(afferents["afferent"],
                    along_plane(scene, afferents["y_mm"], afferents["z_mm"])))
    x_of = dict(zip(afferents["afferent"], afferents["x_mm"]))
    for name, colour in CLASSES.items():
        rows = (spikes["class"] == name) & np.array(
            [abs(x_of[a]) < STRIP_X for a in spikes["afferent"]], dtype=bool)
        ax.plot(1e3 * spikes["time_s"][rows], [z_of[a] for a in spikes["afferent"][rows]],
                "|", ms=4, color=colour, label=name)
    t = np.linspace(0, path.end_time, 400)
    s = np.array([path.tangential_at(v) for v in t])
    for c in grating.centres():
        ax.plot(1e3 * t, c + s, "-", color="0.75", lw=0.6, zorder=0)
    fired = [z_of[a] for a in spikes["afferent"] if abs(x_of[a]) < STRIP_X]
    ax.set_ylim(min(fired) - 1.0, max(fired) + 1.0)
    ax.set_ylabel(f"site along the grating (mm), |x| < {STRIP_X:g} mm")
    ax.legend(fontsize=7, loc="upper left", ncol=3, title="spikes; grey: ridge centres",
              title_fontsize=7)


def rates_panel(ax, scene, h: dict, afferents: dict, spikes: dict) -> None:
    _, _, f = ridge_frequency(scene)
    end = window(scene, h)[1]
    edges = np.arange(0, end + 1e-9, 1 / (6 * f))
    strip = np.abs(afferents["x_mm"]) < STRIP_X
    for name, colour in CLASSES.items():
        ids = afferents["afferent"][strip & (afferents["class"] == name)]
        times = spikes["time_s"][np.isin(spikes["afferent"], ids)]
        rate = np.histogram(times, edges)[0] / np.diff(edges) / max(len(ids), 1)
        ax.stairs(rate, 1e3 * edges, color=colour, label=f"{name} ({len(ids)} afferents)")
    for k in range(1, 20):
        tk = end - k / f
        if tk > ridge_frequency(scene)[0]:
            ax.axvline(1e3 * tk, color="0.8", lw=0.6, zorder=0)
    ax.set_ylabel("population rate\n(spikes/s per afferent)")
    ax.set_xlabel("time (ms): pressed to 25 ms, then scanned at 80 mm/s")
    ax.legend(fontsize=7, loc="upper left")
    ax.grid(alpha=0.3, axis="y")


def main(run: Path, out: Path) -> None:
    scene = load_scene("scan")
    g = scene.indenters[0]
    h = in_plane_frame(read_csv(run / "history.csv"), g.tilt)  # F_n, F_t: the grating's
    afferents, spikes = Result(run).afferents, Result(run).spikes
    m = force_measures(scene, h)
    fig, axes = plt.subplots(3, 1, figsize=(7.0, 9.0), sharex=True, constrained_layout=True,
                             height_ratios=(3, 4, 3))
    forces_panel(axes[0], scene, h, m)
    axes[0].set_title(f"scan: grating (ridges {g.width:g} mm, period {g.period:g} mm) tilted "
                      f"{g.tilt:g}°, pressed 0.5 mm, scanned along its plane at 80 mm/s; "
                      f"μ = {g.friction:g}", fontsize=8)
    raster_panel(axes[1], scene, afferents, spikes)
    rates_panel(axes[2], scene, h, afferents, spikes)
    axes[2].set_xlim(0, 1e3 * h["time_s"][-1])  # a stopped run: its own end
    fig.savefig(out, dpi=120)
    report(h, m, spike_measures(scene, h, afferents, spikes))


def report(h: dict, m: dict, s: dict) -> None:
    scanning = h["tangential_z_displacement_mm"] > 0
    c = m["coulomb"]
    w = m["window"]
    print(f"max F_ft/(mu F_pn) = {c.max():.12g}; last two periods: {c[w].min():.12g}"
          f" .. {c[w].max():.12g}")
    r = m["ft_mu_fn"][scanning]
    print(f"|Ft|/(mu Fn) over the scan: {r.min():.3g} .. {r.max():.3g}")
    for k in ("force_N", "tangential_z_force_N"):
        print(k, {a: f"{b:.4g}" for a, b in m[k].items()})
    for k in ("time_s", "tangential_z_displacement_mm", "force_N", "tangential_z_force_N",
              "pressure_tangential_z_force_N", "tangential_x_force_N", "contact_area_mm2",
              "stick_area_mm2", "newton_iterations", "cuts", "wall_time_s"):
        print(f"{k:32s}", " ".join(f"{v:.4g}" for v in h[k]))
    for name, e in s.items():
        print(name, {a: (f"{b:.3g}" if isinstance(b, float) else b) for a, b in e.items()})


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]))
