r"""Spatial acuity from the SA1 population: gratings and gaps pressed into the section, the
SA1 spike counts along the pulp, and the widths at which an ideal observer of those counts
tells the stimuli apart, next to the measured thresholds.

**Stimuli** (the `grating` scene: 1 mm in 0.1 s, held to 1 s; `geometry.indenters.Grating`).
Gratings: ridges and grooves of equal width w (period 2w, as the gratings of Johnson &
Phillips 1981 and Van Boven & Johnson 1994), spanning at least `GRATING_SPAN` mm, in two
spatial phases: a ridge centred at x = 0 (A) and a groove there (B, shifted by w). Gaps: a
flat-topped bar `GAP_BAR` mm wide (no gap, A) against the same bar with a gap g cut in its
middle (two ridges (bar − g)/2 wide, B).

**Counts.** Each run samples a row of SA1 sites `SAMPLING` times denser than the class's
spacing (10/√ρ = 1.195 mm at 70 per cm²); every `SAMPLING`-th site of it is a row at the real
spacing, so one run gives `SAMPLING` populations offset from the stimulus by 0, s/k, 2s/k, ...
(the afferents' positions relative to a grating are not under the experimenter's control). At
each site the expected count μ over the whole run is the mean of the spike counts of the
class's fitted afferents (TouchSim's four SA1 fits, noise off; `afferents.receptors`).

**Criterion** (stated; this package's choice). The counts are Poisson with mean μ and the
afferents independent. The ideal linear observer of two stimuli A and B (the optimal weights
w_i = Δμ_i / σ_i²) reaches

    d′² = Σ_i (μ_A,i − μ_B,i)² / σ_i²,     σ_i² = (μ_A,i + μ_B,i) / 2,

summed over one row of afferents (sites with μ_A = μ_B = 0 add nothing). d′ is averaged over
the `SAMPLING` offsets of the row, and the threshold is the width at which that mean d′
reaches `LEVEL` = 1 (linear interpolation between the computed widths). The grating task (A vs
B) is the plane-strain stand-in for the orientation task: in both, the two stimuli differ
only in where the ridges and grooves fall on the afferents, not in the total load. One row is
a slice of the areal population (the section has no second direction): rows along the ridges
would add their d′² — n rows multiply d′ by √n, which lowers the threshold; see the docs.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from mpi4py import MPI

from ..errors import InputError
from ..outputs import read_csv, write_json
from .sweep import population_threshold

#: The d′ at which two stimuli count as told apart.
LEVEL = 1.0
#: The sampled SA1 row is this many times denser than the class's spacing.
SAMPLING = 4
#: A grating spans at least this (mm): wider than the contact of a 1 mm press (|x| < ~4 mm).
GRATING_SPAN = 12.0
#: The gap stimulus: a flat-topped bar this wide (mm), with or without a gap in its middle.
GAP_BAR = 4.0
#: Corner radius of every ridge (mm; the data file's, an assumption).
CORNER = 0.1
#: Ridge widths (grating) and gaps (gap stimulus) of the default study (mm).
WIDTHS = (0.5, 0.75, 1.0, 1.5, 2.0)
GAPS = (0.5, 1.0, 1.5, 2.0)
#: Measured thresholds at the fingertip (mm) with their sources.
MEASURED = {
    "grating": (0.94, "grating orientation, Van Boven & Johnson 1994 (Neurology 44:2361)"),
    "gap": (0.87, "gap detection at P = 0.75, Johnson & Phillips 1981 (J Neurophysiol "
                  "46:1177)"),
}
CRITERION = (f"ideal observer of one row of SA1 spike counts (Poisson, independent): d'^2 = "
             f"sum (muA - muB)^2 / ((muA + muB)/2), mean over {SAMPLING} offsets of the row; "
             f"threshold where d' = {LEVEL:g} (linear interpolation)")


def poisson_dprime(mu_a, mu_b) -> float:
    """d′ of the ideal linear observer of independent Poisson counts with means μ_A, μ_B:
    √Σ (μ_A − μ_B)² / ((μ_A + μ_B)/2) (the variance averaged over the two stimuli)."""
    a, b = np.asarray(mu_a, dtype=float), np.asarray(mu_b, dtype=float)
    if a.shape != b.shape or np.any(a < 0) or np.any(b < 0):
        raise ValueError("d': two arrays of non-negative mean counts of the same shape")
    firing = (a + b) > 0
    return float(np.sqrt(np.sum((a - b)[firing] ** 2 / ((a + b)[firing] / 2))))


def row_dprimes(mu_a, mu_b, k: int = SAMPLING) -> np.ndarray:
    """d′ of each of the k rows at the real spacing in a row sampled k times denser (sites
    ordered along x): row j is every k-th site from site j."""
    return np.array([poisson_dprime(mu_a[j::k], mu_b[j::k]) for j in range(k)])


def dprime_threshold(widths, dprimes, level: float = LEVEL) -> dict:
    """The width at which d′ rises through `level` (`threshold_mm`, linear interpolation,
    None unless bracketed) and the smallest width with d′ >= level at it and every larger one
    (`smallest_resolved_mm`): `sweep.population_threshold` on −d′ (there a ratio must fall
    below the criterion; here d′ must rise above it)."""
    return population_threshold(widths, -np.asarray(dprimes, dtype=float), -level)


def grating_table(width: float, phase: str, span: float = GRATING_SPAN) -> dict:
    """The indenter table of a grating of ridges and grooves `width` wide: phase "A" a ridge
    centred at x = 0, "B" a groove there; an odd number of ridges spanning `span`."""
    period = 2 * width
    ridges = 2 * math.ceil(span / 2 / period) + 1
    return {"file": "grating", "width": width, "period": period, "ridges": ridges,
            "corner_radius": CORNER, "centre_x": 0.0 if phase == "A" else width}


def gap_table(gap: float, bar: float = GAP_BAR) -> dict:
    """The indenter table of a flat-topped bar `bar` wide, with a gap `gap` in its middle (two
    ridges (bar − gap)/2 wide) or, for gap = 0, without."""
    if gap == 0:
        return {"file": "grating", "width": bar, "period": bar, "ridges": 1,
                "corner_radius": CORNER, "centre_x": 0.0}
    return {"file": "grating", "width": (bar - gap) / 2, "period": (bar + gap) / 2,
            "ridges": 2, "corner_radius": CORNER, "centre_x": 0.0}


#: The package's two-point answers (the 2pt sweep, not rerun here) and the measured 2PT.
TWO_POINT = (
    ("two-point, strain criterion", "2.08", "2.1 ± 1.0", "Perez et al. 2000 (as Wu et al. "
     "2004 cite); docs/benchmarks/2pt-sweep.md"),
    ("two-point, SA1 dip (1-D Rayleigh)", "1.2–1.5 (~1.3)", "2.1 ± 1.0",
     "coarse 2pt sweep: 1.2 mm merged, 1.5 mm resolved; docs/guide/frequency.md"),
)
#: The coarse mesh of the default study (the tests' and the docs' runs).
COARSE = ("section.mesh.min_size=0.2", "section.mesh.max_size=1.0",
          "section.mesh.bone_size=2.0", "output.pictures=false", "output.profile_points=61")


def sampling_set(path: Path, source: str = "calibrated", k: int = SAMPLING) -> Path:
    """A receptor set of the SA1 class of `source` only, its row sampled k times denser
    (density × k²), written as TOML to `path` (rank 0): the runs' `output.receptors`."""
    from ..afferents.receptors import load_receptors
    from ..scene import toml_value

    record = load_receptors(source).record()
    sa1 = dict(record["SA1"], density=record["SA1"]["density"] * k**2)
    sa1["description"] = f"{source}'s SA1, density x {k * k} ({k} times denser along a row)"
    lines = [f"name = {toml_value(f'{source}-sa1-x{k}')}", "[sites]",
             f"half_width = {toml_value(float(record['sites']['half_width']))}", "[SA1]"]
    lines += [f"{key} = {toml_value(value)}" for key, value in sa1.items()]
    if MPI.COMM_WORLD.rank == 0:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("\n".join(lines) + "\n")
    MPI.COMM_WORLD.barrier()
    return path


def expected_counts(run_dir, population) -> tuple[np.ndarray, np.ndarray]:
    """(x_mm, μ) of the SA1 sites of a run, ordered along x: μ is the mean over the class's
    fits of each fitted afferent's spike count over the whole run, all driven by the site's
    own samples (noise off)."""
    from ..afferents.receptors import afferent_responses

    responses = afferent_responses(run_dir, population)
    sa1 = responses.of("SA1")
    order = np.argsort(responses.x[sa1])
    return responses.x[sa1][order], fit_mean_counts(population["SA1"], responses.time,
                                                    responses.stimulus[:, sa1][:, order])


def fit_mean_counts(c, time, stimulus, until: float | None = None) -> np.ndarray:
    """Per site (columns of `stimulus`, sampled at `time`) the mean over the class's fits of
    each fit's spike count over the whole run (or over 0 to `until` s: the samples up to it),
    every fit driven by the site's samples."""
    from ..afferents.receptors import saal_spikes

    if until is not None:
        keep = np.asarray(time) <= until
        time, stimulus = np.asarray(time)[keep], stimulus[keep]
    fits = list(range(len(c.saal.fits)))
    drives = np.repeat(stimulus.T, len(fits), axis=0)  # each site once per fit
    trains = saal_spikes(c, fits * stimulus.shape[1], time, drives)
    counts = np.array([len(t) for t in trains], dtype=float).reshape(-1, len(fits))
    return counts.mean(axis=1)


def study_jobs(out: Path, widths, gaps, overrides=()) -> list[tuple]:
    """(label, scene, directory) of every run: each width's gratings A and B, the bar without
    a gap and each gap."""
    from ..scene import load_scene, toml_value

    receptors = sampling_set(out / "sa1-row.toml")
    common = [*overrides, f"output.receptors={toml_value(str(receptors))}"]
    tables = [(f"grating-w{w:g}-{p}", grating_table(w, p)) for w in widths for p in "AB"]
    tables += [(f"gap-g{g:g}", gap_table(g)) for g in ((0.0, *gaps) if gaps else ())]
    return [(label, load_scene("grating", [*common, f"indenters=[{toml_value(t)}]"]),
             out / label) for label, t in tables]


def run_acuity(out, widths=WIDTHS, gaps=GAPS, overrides=(), progress: bool = True) -> dict:
    """Run every stimulus not already finished in `out` (side by side under MPI), then per task
    the d′ of each width and the threshold: out/acuity.csv, counts.csv, summary.json,
    acuity.md (the table) and acuity.png. Returns the summary (on every rank)."""
    from ..afferents.receptors import load_receptors
    from ..runner import run_side_by_side

    out = Path(out)
    jobs = study_jobs(out, widths, gaps, overrides)
    todo = [(scene, where) for _, scene, where in jobs
            if not finished(scene, where, out / "sa1-row.toml")]
    run_side_by_side(todo, progress=progress)
    result = None
    if MPI.COMM_WORLD.rank == 0:
        population = load_receptors(out / "sa1-row.toml")
        counts = {label: expected_counts(where, population) for label, _, where in jobs}
        result = summarise(counts, widths, gaps)
        result["counted_over_s"] = stimulus_duration([where for _, _, where in jobs])
        _write_tables(out, counts, result)
        plot_acuity(result, counts, out / "acuity.png")
    result = MPI.COMM_WORLD.bcast(result, root=0)
    write_json(out / "summary.json", result, MPI.COMM_WORLD)
    return result


def stimulus_duration(runs) -> float | None:
    """The time every run in `runs` (folders) ended at, over which its spikes are counted
    (`expected_counts`: the whole run), or None if they differ or a run has no history."""
    ends = set()
    for where in runs:
        path = Path(where) / "history.csv"
        if not path.exists():
            return None
        ends.add(round(float(read_csv(path)["time_s"].max()), 9))
    return ends.pop() if len(ends) == 1 else None


def summarise(counts: dict, widths, gaps) -> dict:
    """Per task the widths, the d′ per row offset and their mean, the threshold and the
    measured one, from the expected counts of every run ({label: (x, μ)})."""
    return {"criterion": CRITERION, "sampling": SAMPLING, "gap_bar_mm": GAP_BAR,
            "grating": _task(counts, [(f"grating-w{w:g}-A", f"grating-w{w:g}-B")
                                      for w in widths], widths, "grating", SAMPLING),
            "gap": _task(counts, [("gap-g0", f"gap-g{g:g}") for g in gaps], gaps, "gap",
                         SAMPLING)}


def _task(counts: dict, pairs, sizes, name: str, k: int) -> dict:
    """One task's d′ per population (`row_dprimes` with k) and their mean for each pair of
    runs (A, B), its threshold and the measured one."""
    rows = [row_dprimes(counts[a][1], counts[b][1], k).tolist() for a, b in pairs]
    mean = [float(np.mean(r)) for r in rows]
    return {"widths_mm": list(sizes), "dprime_rows": rows, "dprime": mean,
            **dprime_threshold(sizes, mean), "measured_mm": MEASURED[name][0],
            "measured_source": MEASURED[name][1]}


def read_counts(path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """counts.csv read back: {run: (x_mm, expected_count)}."""
    import csv

    runs: dict[str, list] = {}
    with Path(path).open() as f:
        for row in csv.DictReader(f):
            runs.setdefault(row["run"], []).append((float(row["x_mm"]),
                                                    float(row["expected_count"])))
    return {label: tuple(np.array(column) for column in zip(*rows))
            for label, rows in runs.items()}


def acuity_table(result: dict) -> str:
    """The predicted thresholds next to the measured ones, and the package's 2PT answers, as
    a Markdown table."""
    lines = ["| task | this package (mm) | measured (mm) | source / criterion |",
             "| --- | --- | --- | --- |"]
    for name, what in (("grating", "grating (ridge = groove width), A vs B"),
                       ("gap", f"gap in a {result['gap_bar_mm']:g} mm bar vs none")):
        t = result[name]
        if t["widths_mm"]:
            lines.append(f"| {what} | {_threshold_text(t)} | {t['measured_mm']:g} | "
                         f"{t['measured_source']} |")
    lines += [f"| {what} | {ours} | {measured} | {source} |"
              for what, ours, measured, source in TWO_POINT]
    return "\n".join(lines) + "\n"


def _write_dprimes(path: Path, result: dict, tasks, part: str, parts: int) -> None:
    """acuity.csv: per task and width the d′ and that of each of its `parts` (a row offset
    in 2D, a population in 3D; columns `part`0, `part`1, ...)."""
    with path.open("w") as f:
        f.write("task,width_mm,dprime," + ",".join(f"{part}{j}" for j in range(parts)) + "\n")
        for name in tasks:
            t = result[name]
            for w, d, rows in zip(t["widths_mm"], t["dprime"], t["dprime_rows"]):
                f.write(f"{name},{w:g},{d:.6g}," + ",".join(f"{r:.6g}" for r in rows) + "\n")


def _write_tables(out: Path, counts: dict, result: dict) -> None:
    """acuity.csv (d′ per task and width), counts.csv (μ per run and site), acuity.md."""
    _write_dprimes(out / "acuity.csv", result, ("grating", "gap"), "dprime_row", SAMPLING)
    with (out / "counts.csv").open("w") as f:
        f.write("run,x_mm,expected_count\n")
        for label, (x, mu) in counts.items():
            f.writelines(f"{label},{xi:.6f},{m:.6g}\n" for xi, m in zip(x, mu))
    (out / "acuity.md").write_text(f"Criterion: {result['criterion']}.\n\n"
                                   + acuity_table(result))


def plot_acuity(result: dict, counts: dict, path: Path) -> None:
    """d′ against width per task with the criterion and the measured thresholds; the count
    profiles of the two stimuli of one grating and one gap (a panel per task that was run)."""
    from matplotlib.figure import Figure

    run = [name for name in ("grating", "gap") if result[name]["widths_mm"]]
    fig = Figure(figsize=(4.0 * (1 + len(run)), 3.9), layout="constrained")
    ax, *panels = fig.subplots(1, 1 + len(run), squeeze=False)[0]
    for name, colour in (("grating", "C0"), ("gap", "C1")):
        t = result[name]
        if not t["widths_mm"]:
            continue
        ax.plot(t["widths_mm"], t["dprime"], "o-", color=colour,
                label=f"{name}: predicted {_threshold_text(t).split(' (')[0]} mm")
        ax.plot(np.repeat(t["widths_mm"], SAMPLING), np.ravel(t["dprime_rows"]), ".",
                color=colour, alpha=0.35)
        ax.axvline(t["measured_mm"], color=colour, ls=":",
                   label=f"{name}: measured {t['measured_mm']:g} mm")
    ax.axhline(LEVEL, color="k", lw=0.8, ls="--", label=f"d′ = {LEVEL:g}")
    ax.set(xlabel="ridge width or gap (mm)", ylabel="d′ of one SA1 row (dots: its offsets)",
           title="SA1 ideal observer, Poisson counts")
    ax.legend(fontsize=7)
    duration = result.get("counted_over_s")
    for panel, name in zip(panels, run):
        w = min(result[name]["widths_mm"], key=lambda v: abs(v - 1.0))  # the one nearest 1 mm
        if name == "grating":
            _profiles(panel, counts, f"grating-w{w:g}-A", f"grating-w{w:g}-B",
                      ("ridge at x = 0", "groove at x = 0"),
                      f"grating, {w:g} mm ridges and grooves", duration)
        else:
            _profiles(panel, counts, "gap-g0", f"gap-g{w:g}", ("no gap", f"{w:g} mm gap"),
                      f"{result['gap_bar_mm']:g} mm bar, with and without a gap", duration)
    fig.savefig(path, dpi=150)


def _threshold_text(task: dict) -> str:
    """The threshold, or where it lies when the computed widths do not bracket it."""
    if task["threshold_mm"] is not None:
        return f"{task['threshold_mm']:.2f}"
    if task["smallest_resolved_mm"] is not None:  # every width passes
        return f"< {min(task['widths_mm']):g} (d′ ≥ 1 at every width)"
    return f"> {max(task['widths_mm']):g} (d′ < 1 at the largest)"


def _profiles(ax, counts: dict, a: str, b: str, labels, title: str,
              duration: float | None = None) -> None:
    """The expected counts of the dense row of two runs (if both were run), counted over the
    whole stimulus (`duration` s, where known: `stimulus_duration`)."""
    for label, name, style in zip((a, b), labels, ("o-", "s--")):
        if label in counts:
            ax.plot(*counts[label], style, ms=3, label=name)
    over = f"in {duration:g} s" if duration else "over the stimulus"
    ax.set(xlabel="x of the site (mm)", ylabel=f"expected SA1 spikes {over}", title=title,
           xlim=(-5, 5))
    ax.legend(fontsize=7)


# --- 3D: oriented gratings and a gap on the 3D fingertip -----------------------------------
#
# The tasks need no stand-in there. Orientation: the same grating (ridge = groove = w, a ridge
# centred under the middle of the window) with its ridges along the finger (axis "z") or
# across it ("x"). Gap: the GAP_BAR bar along the finger, with or without a gap g along its
# middle (the 2D stimulus extruded along z). The SA1 population covers the pulp surface at
# SAMPLING_3D² times the class's density (`afferents.receptors.surface_sites`, uniform at
# random, fixed seed): every (SAMPLING_3D²)-th site of it is a population at the real density,
# so one run gives SAMPLING_3D² populations. Only the sites inside the mesh's refinement
# window (|x| < refine_half_width, refine_z_min < z < refine_z_max: where the 0.4 mm elements
# resolve the ridges) are read: the observer's population is the window's, not the whole
# contact's (which runs along the whole cylinder under a flat indenter).

#: The 3D study's scene (half model; every stimulus is symmetric about x = 0).
SCENE_3D = "grating-3d"
#: Ridge width and gap of the default 3D study (mm): the smallest the scene's 0.4 mm surface
#: elements (P2: nodes 0.2 mm apart) resolve, 2.5 elements across a ridge (four 3D runs).
WIDTHS_3D = (1.0,)
GAPS_3D = (1.0,)
#: The grating's orientations: ridges along the finger (a "z" prism) or across it ("x").
ORIENTATIONS = {"along": "z", "across": "x"}
#: An oriented grating spans at least this (mm): the contact of a 1 mm press covers |x| < ~4
#: mm and the whole cylinder along z (0 to ~17 mm), around the window's middle.
GRATING_SPAN_3D = 24.0
#: The oriented gratings' ridge count, at least: the count spanning GRATING_SPAN_3D at 1 mm.
#: Wider gratings keep it (and span more), so every width >= 1 mm and both orientations are
#: one compiled contact form (a grating's numbers are Constants; its ridge count is not).
RIDGES_3D = 13
#: The 3D population is SAMPLING_3D² times the class's density.
SAMPLING_3D = 2
CRITERION_3D = (f"ideal observer of the SA1 spike counts in the refined window (Poisson, "
                f"independent): d'^2 = sum (muA - muB)^2 / ((muA + muB)/2), mean over "
                f"{SAMPLING_3D ** 2} random populations at the class's density; threshold "
                f"where d' = {LEVEL:g} (linear interpolation)")
#: The 2D study's answers (docs/results/acuity/; its grating task is the phase stand-in).
TWO_D = {"orientation": "< 0.5 (phase A vs B)", "gap": "0.60"}


def window_of(scene) -> tuple[float, float, float]:
    """(half-width, z_min, z_max) of a 3D scene's mesh refinement footprint (mm)."""
    tip = scene.section
    return tip.section.mesh.refine_half_width, tip.refine_z_min, tip.refine_z_max


def oriented_table(width: float, orientation: str, centre_z: float) -> dict:
    """The indenter table of the grating `width` wide with its ridges `orientation` ("along"
    or "across" the finger), a ridge centred at x = 0 (along) or z = centre_z (across), with
    at least RIDGES_3D ridges."""
    table = grating_table(width, "A", GRATING_SPAN_3D)
    return {**table, "ridges": max(table["ridges"], RIDGES_3D),
            "axis": ORIENTATIONS[orientation], "centre_z": centre_z}


def study_jobs_3d(out: Path, widths, gaps, overrides=()) -> list[tuple]:
    """(label, scene, directory) of every 3D run: each width's grating along and across the
    finger, the bar along the finger without a gap and with each gap."""
    from ..scene import load_scene, toml_value

    receptors = sampling_set(out / "sa1-row.toml", k=SAMPLING_3D)
    common = [*overrides, f"output.receptors={toml_value(str(receptors))}"]
    z0, z1 = window_of(load_scene(SCENE_3D, common))[1:]
    centre = (z0 + z1) / 2
    tables = [(f"orientation-w{w:g}-{o}", oriented_table(w, o, centre))
              for w in widths for o in ORIENTATIONS]
    tables += [(f"gap-g{g:g}", {**gap_table(g), "axis": "z", "centre_z": centre})
               for g in ((0.0, *gaps) if gaps else ())]
    return [(label, load_scene(SCENE_3D, [*common, f"indenters=[{toml_value(t)}]"]),
             out / label) for label, t in tables]


#: What places and samples a class's sites; the rest of its record (the transduction model and
#: its input scale) is applied to the sampled stimulus when the study counts spikes.
SITE_KEYS = ("depth", "density", "quantity")


def finished(scene, where: Path, sites: Path | None = None) -> bool:
    """Whether `where` holds a finished run of exactly this scene (its summary's scene record
    equal to the scene's) and, given the receptor set `sites`, one that sampled the same sites
    (`same_sites`): the study reuses it instead of running it again. So a study rerun after
    a change of the afferents' calibration counts again from the runs' mechanics."""
    import json

    from ..scene import scene_record

    path = Path(where) / "summary.json"
    if not path.exists():
        return False
    recorded = json.loads(path.read_text()).get("scene_data")
    same = recorded == json.loads(json.dumps(scene_record(scene), default=str))
    return same and (sites is None or same_sites(where, sites))


def same_sites(where: Path, sites: Path) -> bool:
    """Whether the run in `where` sampled the sites of the receptor set file `sites`: the same
    site table and, per class, the same depth, density and quantity (its receptors.json)."""
    import json

    from ..afferents.receptors import load_receptors

    path = Path(where) / "receptors.json"
    if not path.exists():
        return False
    ran, now = json.loads(path.read_text()), load_receptors(sites).record()
    classes = [k for k in now if isinstance(now[k], dict) and k != "sites"]
    return (ran.get("sites") == now.get("sites") and set(classes) <= set(ran)
            and all({k: ran[c].get(k) for k in SITE_KEYS} == {k: now[c].get(k) for k in SITE_KEYS}
                    for c in classes))


def expected_counts_3d(run_dir, population, window,
                       until: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """((x, z) of each SA1 site inside the window, μ): the sites in their population's order
    (x < 0: a site on the mirrored half), μ the mean over the class's fits of the spike count
    over the whole run, or over 0 to `until` s (`fit_mean_counts`; a run read before its end
    counts over the time both runs of a pair reached)."""
    from ..afferents.receptors import afferent_responses
    from ..result import Result

    responses = afferent_responses(run_dir, population)
    sa1 = np.flatnonzero(responses.of("SA1"))
    table = Result(run_dir).receptors()
    rows = table["class"] == "SA1"
    z_of = dict(zip(table["index"][rows].tolist(), table["z_mm"][rows].tolist()))
    x, z = responses.x[sa1], np.array([z_of[i] for i in responses.index[sa1].tolist()])
    half_width, z_min, z_max = window
    inside = (np.abs(x) < half_width) & (z > z_min) & (z < z_max)
    mu = fit_mean_counts(population["SA1"], responses.time, responses.stimulus[:, sa1[inside]],
                         until)
    return np.column_stack((x[inside], z[inside])), mu


def run_acuity_3d(out, widths=WIDTHS_3D, gaps=GAPS_3D, overrides=(),
                  progress: bool = True) -> dict:
    """Run every 3D stimulus not already finished in `out` (side by side under MPI), then the
    d′ of each task and width and the thresholds: out/acuity.csv, counts.csv (μ per run and
    site), summary.json, acuity.md and acuity.png. Returns the summary (on every rank)."""
    from ..runner import run_side_by_side

    out = Path(out)
    jobs = study_jobs_3d(out, widths, gaps, overrides)
    todo = [(scene, where) for _, scene, where in jobs
            if not finished(scene, where, out / "sa1-row.toml")]
    run_side_by_side(todo, progress=progress)
    result = None
    if MPI.COMM_WORLD.rank == 0:
        result = count_acuity_3d(out, widths, gaps, overrides)
    result = MPI.COMM_WORLD.bcast(result, root=0)
    write_json(out / "summary.json", result, MPI.COMM_WORLD)
    return result


def count_acuity_3d(out, widths=WIDTHS_3D, gaps=GAPS_3D, overrides=(),
                    until: float | None = None) -> dict:
    """The 3D tasks' d′ from the runs in `out` as they stand, running nothing (one rank):
    counts over each finished run, or, given `until` (s), over 0 to `until` of runs read
    before their end (every run must have reached it). Writes the study's files into `out`."""
    from ..afferents.receptors import load_receptors

    out = Path(out)
    jobs = study_jobs_3d(out, widths, gaps, overrides)
    if until is not None:
        reached = {label: float(read_csv(where / "history.csv")["time_s"][-1])
                   for label, _, where in jobs}
        short = {label: t for label, t in reached.items() if t < until}
        if short:
            raise InputError("acuity 3D: until", f"{until:g} s is later than the runs "
                             f"reached: {short}.", f"use until <= {min(reached.values()):g}.")
    population = load_receptors(out / "sa1-row.toml")
    window = window_of(jobs[0][1])
    counts = {label: expected_counts_3d(where, population, window, until)
              for label, _, where in jobs}
    result = summarise_3d(counts, widths, gaps, window)
    if until is None:
        result["runs"] = {label: run_cost(where) for label, _, where in jobs}
    else:
        result["counted_until_s"], result["reached_s"] = until, reached
    _write_tables_3d(out, counts, result)
    plot_acuity_3d(result, counts, out / "acuity.png")
    return result


def summarise_3d(counts: dict, widths, gaps, window) -> dict:
    """The 3D tasks' d′ (per population and mean) and thresholds from the expected counts of
    every run ({label: (positions, μ)}); the two runs of a task must share their sites."""
    pairs = {"orientation": [(f"orientation-w{w:g}-along", f"orientation-w{w:g}-across")
                             for w in widths],
             "gap": [("gap-g0", f"gap-g{g:g}") for g in gaps]}
    for a, b in (p for task in pairs.values() for p in task):
        if not np.array_equal(counts[a][0], counts[b][0]):
            raise ValueError(f"acuity 3D: runs {a} and {b} have different afferent sites")
    k = SAMPLING_3D**2
    some = next(iter(counts.values()))[0]
    return {"criterion": CRITERION_3D, "populations": k, "gap_bar_mm": GAP_BAR,
            "window_mm": dict(zip(("half_width", "z_min", "z_max"), window)),
            "afferents_per_population": len(some) / k,
            "orientation": _task(counts, pairs["orientation"], widths, "grating", k),
            "gap": _task(counts, pairs["gap"], gaps, "gap", k)}


def run_cost(where) -> dict:
    """Steps, Newton iterations, wall time and dofs of a finished run (its summary.json); a
    run that stopped early is an error (its counts would be a shorter stimulus's)."""
    import json

    summary = json.loads((Path(where) / "summary.json").read_text())
    if not summary.get("converged"):
        raise RuntimeError(f"acuity 3D: the run in {where} stopped early: "
                           f"{summary.get('failure')}; delete it and run the study again")
    keys = ("time_steps", "newton_iterations", "wall_time_s", "dofs")
    return {key: summary.get(key) for key in keys}


def acuity_table_3d(result: dict) -> str:
    """The 3D predictions beside the 2D study's and the measured thresholds (Markdown)."""
    lines = ["| task | this package, 3D (mm) | 2D (mm) | measured (mm) | source |",
             "| --- | --- | --- | --- | --- |"]
    for name, what in (("orientation", "grating orientation (ridges along vs across)"),
                       ("gap", f"gap in a {result['gap_bar_mm']:g} mm bar vs none")):
        t = result[name]
        if t["widths_mm"]:
            lines.append(f"| {what} | {_threshold_text(t)} | {TWO_D[name]} | "
                         f"{t['measured_mm']:g} | {t['measured_source']} |")
    return "\n".join(lines) + "\n"


def _write_tables_3d(out: Path, counts: dict, result: dict) -> None:
    """acuity.csv (d′ per task, width and population), counts.csv (μ per run and site with
    its x, z), acuity.md (criterion and table)."""
    _write_dprimes(out / "acuity.csv", result, ("orientation", "gap"), "dprime_pop",
                   result["populations"])
    with (out / "counts.csv").open("w") as f:
        f.write("run,x_mm,z_mm,expected_count\n")
        for label, (xz, mu) in counts.items():
            f.writelines(f"{label},{p[0]:.6f},{p[1]:.6f},{m:.6g}\n" for p, m in zip(xz, mu))
    (out / "acuity.md").write_text(f"Criterion: {result['criterion']}.\n\n"
                                   + acuity_table_3d(result))


def plot_acuity_3d(result: dict, counts: dict, path: Path) -> None:
    """The expected counts of the window's sites over the surface (x across, z along the
    finger; both halves) for the grating along and across the finger and the bar without and
    with a gap (each pair on one colour scale), and d′ against width per task; a task that
    was not run (`--gaps` with no value) has no row."""
    from matplotlib.figure import Figure

    w = min(result["orientation"]["widths_mm"] or [1.0], key=lambda v: abs(v - 1.0))
    g = min(result["gap"]["widths_mm"] or [1.0], key=lambda v: abs(v - 1.0))
    rows = ((f"orientation-w{w:g}-along", f"{w:g} mm grating, ridges along the finger"),
            (f"orientation-w{w:g}-across", f"{w:g} mm grating, ridges across the finger")), (
           ("gap-g0", f"{result['gap_bar_mm']:g} mm bar along the finger, no gap"),
           (f"gap-g{g:g}", f"the same bar with a {g:g} mm gap"))
    rows = [pair for pair in rows if pair[0][0] in counts] or rows[:1]
    fig = Figure(figsize=(12.5, 0.6 + 3.5 * len(rows)), layout="constrained")
    axes = fig.subplots(len(rows), 3, squeeze=False)
    until = result.get("counted_until_s")
    label = "expected SA1 spikes " + (f"over 0–{until:.3g} s" if until else "in the run")
    for panels, pair in zip(axes[:, :2], rows):
        _surface_counts(fig, panels, counts, pair, label)
    _dprime_panel(axes[0, 2], result)
    for ax in axes[1:, 2]:
        ax.set_axis_off()
    fig.savefig(path, dpi=150)


def _surface_counts(fig, panels, counts: dict, pair, bar_label: str) -> None:
    """Two runs' expected counts at their sites, on one colour scale."""
    present = [(label, title) for label, title in pair if label in counts]
    top = max([counts[label][1].max() for label, _ in present] + [1.0])
    for ax, (label, title) in zip(panels, present):
        xz, mu = counts[label]
        dots = ax.scatter(xz[:, 1], xz[:, 0], c=mu, s=14, cmap="viridis", vmin=0, vmax=top)
        ax.set(xlabel="z along the finger (mm)", ylabel="x across the finger (mm)",
               title=title, aspect="equal")
        ax.title.set_fontsize(9)
    if present:
        fig.colorbar(dots, ax=list(panels), label=bar_label, shrink=0.8)


def _dprime_panel(ax, result: dict) -> None:
    """d′ against width per 3D task, its populations as dots, the criterion, the measured."""
    k = result["populations"]
    for name, colour in (("orientation", "C0"), ("gap", "C1")):
        t = result[name]
        if not t["widths_mm"]:
            continue
        ax.plot(t["widths_mm"], t["dprime"], "o-", color=colour,
                label=f"{name}: predicted {_threshold_text(t).split(' (')[0]} mm")
        ax.plot(np.repeat(t["widths_mm"], k), np.ravel(t["dprime_rows"]), ".", color=colour,
                alpha=0.35)
        ax.axvline(t["measured_mm"], color=colour, ls=":",
                   label=f"{name}: measured {t['measured_mm']:g} mm")
    ax.axhline(LEVEL, color="k", lw=0.8, ls="--", label=f"d′ = {LEVEL:g}")
    sizes = [v for name in ("orientation", "gap") for v in result[name]["widths_mm"]]
    ax.set(xlabel="ridge width or gap (mm)", ylabel="d′ of the window's SA1 (dots: populations)",
           title="3D: SA1 ideal observer, Poisson counts", xlim=(0, 1.3 * max(sizes + [1.0])))
    ax.title.set_fontsize(9)
    ax.legend(fontsize=7, loc="upper left")
