"""Two-point discrimination: the 2pt scene over bar spacings, and the threshold it implies.

For each spacing d the bars sit at x = ±d/2. At the output time and the first output depth
(0.75 mm in the 2pt scene) each quantity f ∈ {e11, e22, e12, u2, sed} gives the normalised
variation (the paper's Fig. 9)

    V_f(d) = [f(contact point) − f(centre)] / f(contact point),

with the contact point under a bar centre (x = ±d/2, the two sides averaged) and the centre
x = 0. The shear strain e12 is odd about x = 0 and changes sign under each bar, so its value at
both points is ~0 and the formula degenerates; for e12, f is its peak-to-peak variation over a
window one bar width wide around the point (the paper's "peak-to-peak variations in the strain
around the contact point", its Fig. 8), our reading of the paper for this quantity. Two bars
read as two when the field dips between them, so V is large; as d shrinks the dip fills in.
The paper gives no quantitative criterion; ours, fixed here and reported with the result: the
threshold is the spacing at which the mean of V over e11, e22 and SED (the
quantities the paper names) falls `DROP` = 10 % below its value at the largest spacing, i.e. the
dip between the bars has lost a tenth of what well separated bars produce; linear
interpolation between the computed spacings.

**Population criterion** (from the SA1 afferents, next to the strain one). At the output time
the SA1 population response along the pulp is the SED-rate model at the SA1 sites, r_i =
k SED_i (`receptors`; one value per site, 1.195 mm apart). Two bars read as two when the
profile has two local maxima and the lowest site between the two largest is at most
`RESOLVED` = 8/π² ≈ 0.81 of the smaller of them: the Rayleigh criterion of optics for two 1-D
(slit) diffraction patterns sinc², whose sum at the first-zero separation dips to exactly
2 sinc²(1/2) = 8/π² of the peak. Borrowing it for afferent populations is this package's
assumption (no afferent-population criterion was verified in the literature); a dip ratio is
1 when the profile has one maximum. The population threshold is the spacing at which the dip
ratio crosses RESOLVED (linear interpolation between computed spacings), with the smallest
computed spacing that passes (and every larger one does too). The sites sample the pulp
discretely: bars closer than about two site spacings share their nearest site, which bounds
what this criterion can resolve (on the coarse default run: one peak at d = 1.2 mm, two at
1.5 mm and above).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from mpi4py import MPI

from ..errors import on_root
from ..outputs import read_csv, remove_outputs, whole, write_json
from ..plotting.figures import plot_spacing_profiles

QUANTITIES = ("e11", "e22", "e12", "u2", "sed")
_COLUMNS = {"e11": "e11", "e22": "e22", "e12": "e12", "u2": "u2_mm", "sed": "sed_MPa"}
DROP = 0.10
RESOLVED = 8 / np.pi**2
POPULATION_CRITERION = (f"SA1 SED-rate profile at the sites: two local maxima with the lowest "
                        f"site between them <= 8/pi^2 = {RESOLVED:.3f} of the smaller (1-D "
                        f"Rayleigh); linear interpolation of that dip ratio between spacings")
CRITERION = (f"spacing at which the mean normalised variation of e11, e22 and SED falls "
             f"{DROP:.0%} below its value at the largest spacing (linear interpolation)")


def normalized_variation(depth: dict, spacing: float, time_s: float, depth_mm: float,
                         bar_width: float = 1.0) -> dict:
    rows = np.isclose(depth["time_s"], time_s) & np.isclose(depth["depth_mm"], depth_mm)
    x = depth["x_mm"][rows]
    order = np.argsort(x)
    xs = x[order]
    out = {}
    for name, column in _COLUMNS.items():
        f = depth[column][rows][order]
        if name == "e12":
            at_contact = 0.5 * (_peak_to_peak(xs, f, spacing / 2, bar_width)
                                + _peak_to_peak(xs, f, -spacing / 2, bar_width))
            centre = _peak_to_peak(xs, f, 0.0, bar_width)
        else:
            at_contact = 0.5 * (np.interp(spacing / 2, xs, f) + np.interp(-spacing / 2, xs, f))
            centre = np.interp(0.0, xs, f)
        out[name] = float((at_contact - centre) / at_contact) if at_contact != 0 else np.nan
    return out


def _peak_to_peak(x: np.ndarray, f: np.ndarray, x0: float, width: float) -> float:
    """max − min of the profile f(x) over |x − x0| <= width/2 (window ends interpolated)."""
    inside = np.abs(x - x0) <= width / 2
    values = np.concatenate([f[inside], np.interp([x0 - width / 2, x0 + width / 2], x, f)])
    return float(values.max() - values.min())


def threshold(spacings: np.ndarray, variations: dict) -> float | None:
    """The spacing where mean(V_e11, V_e22, V_sed) falls DROP below its largest-spacing value."""
    order = np.argsort(spacings)
    d = np.asarray(spacings)[order]
    v = np.mean([np.asarray(variations[q])[order] for q in ("e11", "e22", "sed")], axis=0)
    target = (1 - DROP) * v[-1]
    for i in range(len(d) - 1, 0, -1):
        lo, hi = v[i - 1], v[i]
        if (lo - target) * (hi - target) <= 0 and lo != hi:
            return float(d[i - 1] + (target - lo) / (hi - lo) * (d[i] - d[i - 1]))
    return None


def dip_ratio(profile) -> float:
    """Lowest value between the two largest local maxima over the smaller maximum (samples in
    order along x); 1.0 when there are fewer than two interior maxima (one peak, no dip)."""
    p = np.asarray(profile, dtype=float)
    inner = np.flatnonzero((p[1:-1] > p[:-2]) & (p[1:-1] >= p[2:])) + 1
    if len(inner) < 2:
        return 1.0
    i, j = sorted(inner[np.argsort(p[inner])[-2:]])
    return float(p[i:j + 1].min() / min(p[i], p[j]))


def population_profile(run_dir, time_s: float, name: str = "SA1") -> tuple[np.ndarray, ...]:
    """(x_mm, rate) of a class's SED-rate model (k SED) at its sites at `time_s`, from a run
    written with `output.receptors`, ordered along x."""
    from ..afferents.receptors import load_receptors
    from ..result import Result

    table = Result(run_dir).receptors()
    rows = (table["class"] == name) & np.isclose(table["time_s"], time_s)
    order = np.argsort(table["x_mm"][rows])
    recorded = Path(run_dir) / "receptors.json"
    gain = _recorded_gain(recorded, name) if recorded.exists() else load_receptors()[name].sed_gain
    return table["x_mm"][rows][order], gain * np.maximum(table["sed_MPa"][rows][order], 0.0)


def _recorded_gain(path: Path, name: str) -> float:
    import json

    from ..afferents.receptors import receptors_from_dict

    return receptors_from_dict(json.loads(path.read_text()), str(path))[name].sed_gain


def population_threshold(spacings, ratios, fraction: float = RESOLVED) -> dict:
    """From the dip ratios per spacing: `smallest_resolved_mm` (the smallest spacing that
    passes, ratio <= fraction, with every larger one passing too; None if the largest fails)
    and `threshold_mm` (the ratio's crossing of `fraction`, linear interpolation; None unless
    bracketed by a failing and a passing spacing)."""
    order = np.argsort(spacings)
    d, r = np.asarray(spacings, dtype=float)[order], np.asarray(ratios, dtype=float)[order]
    passing = r <= fraction
    smallest, crossing = None, None
    for i in range(len(d) - 1, -1, -1):
        if not passing[i]:
            if smallest is not None:
                crossing = float(d[i] + (fraction - r[i]) / (r[i + 1] - r[i]) * (d[i + 1] - d[i]))
            break
        smallest = float(d[i])
    return {"smallest_resolved_mm": smallest, "threshold_mm": crossing}


#: The files a spacing sweep writes beside its runs' folders.
SWEEP_OUTPUTS = ("summary.json", "normalized_variation.csv", "normalized_variation.png",
                 "profiles_by_spacing.png")


def run_sweep(scene_name: str, spacings, out: Path, overrides=(), progress=True,
              population: bool = True, spots: bool = False, resume: bool = False) -> dict:
    """Run the scene at every spacing side by side, then the strain threshold and (with
    `population`: the runs sample the default receptor set) the SA1 population's. With
    `spots`, each spacing's mesh gets a fine disc (`section.mesh.spots`) at the three points
    the variations are read at (`sweep_scenes`). `resume`: continue the runs of a sweep
    stopped part-way (`run_side_by_side`)."""
    from ..runner import run_side_by_side

    world = MPI.COMM_WORLD
    out = Path(out)
    overrides = list(overrides)
    if population and not any(str(o).startswith("output.receptors") for o in overrides):
        overrides.append('output.receptors="default"')
    scenes = sweep_scenes(scene_name, spacings, overrides, spots)
    # An earlier sweep's table must not stay beside these runs if this sweep stops part-way.
    remove_outputs(out, SWEEP_OUTPUTS, world)
    run_side_by_side([(scene, out / f"d{d:g}") for d, scene in zip(spacings, scenes)],
                     progress=progress, resume=resume)

    result = on_root(world, lambda: _tabulate(scenes, spacings, out))  # rank 0 reads, writes
    write_json(out / "summary.json", result, world)
    return result


def _tabulate(scenes: list, spacings: Sequence[float], out: Path) -> dict:
    """The sweep's table from its runs' files (on one rank): the normalized variations, their
    strain threshold, the SA1 population's where the runs sampled it, and the files."""
    scene = scenes[0]
    t, depth_mm = scene.output_times[-1], scene.depths[0]
    table = {q: [] for q in QUANTITIES}
    profiles = {d: read_csv(out / f"d{d:g}" / "depth_profiles.csv") for d in spacings}
    for d in spacings:
        v = normalized_variation(profiles[d], d, t, depth_mm,
                                 getattr(scene.indenters[0], "width", 1.0))
        for q in QUANTITIES:
            table[q].append(v[q])
    plot_spacing_profiles(profiles, out / "profiles_by_spacing.png", t, depth_mm,
                          title=f"{scene.name}: two bars at spacing d")
    with whole(out / "normalized_variation.csv") as tmp, tmp.open("w") as f:  # no half table
        f.write("spacing_mm," + ",".join(QUANTITIES) + "\n")
        for i, d in enumerate(spacings):
            f.write(f"{d:g}," + ",".join(f"{table[q][i]:.8g}" for q in QUANTITIES) + "\n")
    result = {
        "scene": scene.name,
        "spacings_mm": list(spacings),
        "time_s": t,
        "depth_mm": depth_mm,
        "normalized_variation": table,
        "threshold_mm": threshold(np.array(spacings), table),
        "threshold_criterion": CRITERION,
    }
    if all((out / f"d{d:g}" / "receptors.csv").exists() for d in spacings):
        ratios = [dip_ratio(population_profile(out / f"d{d:g}", t)[1]) for d in spacings]
        result["population"] = {"dip_ratio": ratios, "criterion": POPULATION_CRITERION,
                                **population_threshold(spacings, ratios)}
    _plot(np.array(spacings), table, out / "normalized_variation.png", result["threshold_mm"])
    return result


def sweep_scenes(scene_name: str, spacings, overrides=(), spots: bool = False) -> list:
    """The scene at each spacing. With `spots`, a disc of `section.mesh.spot_size` around each
    point where `normalized_variation` reads the fields: under both bar centres and midway, at
    the first output depth: the key outputs there are read on fine elements while the rest of
    the mesh stays coarse (the accuracy bought: docs/benchmarks/measurements.md)."""
    from ..scene import load_scene

    scenes = []
    for d in spacings:
        scene = load_scene(scene_name, list(overrides), spacing=d)
        if spots:
            points = [[x, scene.depths[0]] for x in (-d / 2, 0.0, d / 2)]
            scene = load_scene(scene_name, [*overrides, f"section.mesh.spots={points}"],
                               spacing=d)
        scenes.append(scene)
    return scenes


def _plot(spacings, table, path, threshold_mm):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.6, 4.2))
    ax = fig.subplots()
    order = np.argsort(spacings)
    for q in QUANTITIES:
        ax.plot(spacings[order], np.asarray(table[q])[order], "o-", label=q)
    if threshold_mm is not None:  # the criterion named: the reader cannot guess it
        ax.axvline(threshold_mm, color="k", ls="--", label=(
            f"threshold {threshold_mm:.2f} mm:\nmean V of e11, e22, sed\n{DROP:.0%} below "
            "its value at\nthe largest spacing"))
    ax.set_xlabel("bar spacing d (mm)")
    ax.set_ylabel("normalised variation V (-)")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)  # off the data
    fig.tight_layout()
    fig.savefig(path, dpi=150)
