"""Accuracy study: how fine must the discretisation be, and what does accuracy cost?

`run_accuracy_study(scene, out)` runs the scene over

- mesh sizes: `min_size` refined by a factor r per level (in the full study `max_size` and
  `bone_size` with it, so the whole mesh refines; the coarse study keeps a coarse
  `max_size`/`bone_size` far from the load);
- element families: P2 displacement on triangles (Taylor–Hood P2/P1 where the model has a pore
  pressure), Q2 (Q2/Q1) on quadrilaterals, and P1 on triangles -- P1 only where the model allows
  it: with a pore pressure (biphasic or undrained subcutaneous tissue) equal-order u/p fails the
  inf-sup condition and the code refuses it, so the P1 curve then uses the *drained* model and
  is scored against that model's own converged value (its model error is the fidelity study's);
- time-step sizes: `dt_initial` and `dt_max` halved on one mesh of the reference family,

measures wall time, the peak resident memory during each run and the number of unknowns, and
scores the key outputs (`keys.KEY_OUTPUTS`) against a Richardson estimate of the converged value.

**Reference.** From the last three mesh levels of the reference family (the first one, P2 on
triangles) with ratio r: p = log(|f1 - f2| / |f2 - f3|) / log r, f_inf = f3 + (f3 - f2)/(r^p - 1).
A sequence that is not monotone and contracting (or already converged to round-off) gets
order NaN and f_inf = f3, and the study says so. The time-step error is removed additively
(f(h, dt) = f_inf + a h^p + b dt^q): reference = f_inf(h) + [f_inf(dt) - f(h_t, dt_0)], with
f_inf(dt) the Richardson value over the Δt levels (or, with only two, the smallest Δt's value).

**Outputs** in `out/`: one run per setting in `out/<slug>/`, `accuracy.csv` (one row per run),
`accuracy.md` (the table, the Richardson estimates and orders, and the cheapest setting that
reaches 1 % on every key output), `accuracy.png` (largest error against wall time, one curve per
family, the Pareto front marked) and `accuracy.json` (the returned dict without the rows).

**The adaptive loop's check** (`adapt_tol`): the adaptive mesh loop (`adaptivity.adapt`) runs
from the study's coarsest mesh of the reference family (out/adaptive/) with that tolerance,
and every level's key outputs are scored against the same reference. The loop's estimated
error of each key output must bound its true error (estimate >= error against the
Richardson value): accuracy.md tabulates both, per level, and says where the bound holds.
"""

from __future__ import annotations

import csv
import json
import math
import resource
import time
from dataclasses import dataclass
from pathlib import Path

from mpi4py import MPI

from ..errors import ConvergenceError, on_root
from ..keys import KEY_OUTPUTS, KEYS, TIME_COLUMNS, check_scene, key_outputs
from ..outputs import remove_outputs

TOL = 0.01  # "1 % on every key output"

#: Settings every study run gets (before the user's overrides): VTX fields only at the output
#: times -- the study reads the CSV outputs, and per-step field I/O is not discretisation cost.
STUDY_DEFAULTS = ("output.field_every=1000000",)


@dataclass(frozen=True)
class Plan:
    """What a study runs: base mesh sizes (min, max, bone), the refinement ratio, whether
    max/bone sizes refine with min_size, how many levels the non-reference families get, the
    Δt levels and the mesh level they run on."""

    sizes: tuple[float, float, float] | None  # None: the scene's own sizes
    ratio: float
    scale_outer: bool
    #: per family: (levels skipped at the coarse end, at the fine end), or None to leave the
    #: family out; None for the whole tuple: every family on every level
    family_levels: tuple[tuple[int, int] | None, ...] | None
    time_levels: int
    time_level: int | None  # mesh level index for the Δt refinement; None: the finest
    extra: tuple[str, ...] = ()


#: The coarse study (CI, < 90 s on two cores for the 1pt scene): min_size 0.4 -> 0.2 -> 0.1 with
#: a coarse max_size and bone_size (held: the estimate is then that of min_size -> 0 at this
#: far-field size); Q2/Q1 on the two finer meshes (on the 0.4 mm quadrilateral mesh Newton
#: fails near t = 0.33 s of the 1pt scene), P1 on the two coarser ones; Δt halved once on the
#: middle mesh (the 1pt scene's time error is ~1e-5, far below its mesh error). The depth
#: curves keep the scene's sampling: at 61 points (0.2 mm apart) the line load's SED peak,
#: 0.05 mm off the axis, was missed (2.16e-4 against 2.33e-4 MPa on the same run).
COARSE = Plan(sizes=(0.4, 1.2, 2.0), ratio=2.0, scale_outer=False,
              family_levels=((0, 0), (1, 0), (0, 1)), time_levels=2, time_level=1)
#: The full study: the scene's resolution and finer (whole mesh refined by sqrt 2 per level),
#: every family on every level, Δt halved twice on the finest mesh.
FULL = Plan(sizes=None, ratio=math.sqrt(2.0), scale_outer=True, family_levels=None,
            time_levels=3, time_level=None)


@dataclass(frozen=True)
class Family:
    name: str
    settings: tuple[str, ...]
    model: str  # "scene": the scene's model; otherwise the name of the substitute model
    degree: int
    cell: str


# --- small pure helpers (unit-tested on synthetic data) ---------------------------------------

def richardson(f1: float, f2: float, f3: float, r: float) -> dict:
    """Richardson extrapolation from three levels refined by r (f3 the finest).

    Returns {"estimate", "order", "note"}; a non-monotone or non-contracting sequence, or one
    converged to round-off, gives order NaN and the finest value as the estimate.
    """
    f1, f2, f3 = float(f1), float(f2), float(f3)
    if not all(math.isfinite(v) for v in (f1, f2, f3)):
        return {"estimate": f3, "order": math.nan, "note": "a level is missing: finest value used"}
    d12, d23 = f1 - f2, f2 - f3
    scale = max(abs(f1), abs(f2), abs(f3), 1e-300)
    if abs(d12) <= 1e-10 * scale and abs(d23) <= 1e-10 * scale:
        return {"estimate": f3, "order": math.nan, "note": "converged to round-off: finest value"}
    if d12 * d23 <= 0.0 or abs(d23) >= abs(d12):
        return {"estimate": f3, "order": math.nan,
                "note": "non-monotone or not contracting: order NaN, finest value used"}
    p = math.log(abs(d12) / abs(d23)) / math.log(r)
    return {"estimate": f3 + (f3 - f2) / (r ** p - 1.0), "order": p, "note": ""}


def pareto_front(costs, errors) -> list[int]:
    """Indices of the points not dominated in (cost, error), both minimised, by cost.

    A point is dominated if another is no worse in both and better in one; NaN points are out.
    """
    pts = [(float(c), float(e), i) for i, (c, e) in enumerate(zip(costs, errors))
           if math.isfinite(float(c)) and math.isfinite(float(e))]
    pts.sort(key=lambda t: (t[0], t[1]))
    front, best = [], math.inf
    for _c, e, i in pts:
        if e < best:
            front.append(i)
            best = e
    return front


def cheapest_within(rows: list[dict], tol: float = TOL, model: str = "scene",
                    tie: float = 0.1) -> dict | None:
    """The row of `model` with the smallest wall time whose error on every key is <= tol.

    Wall times within `tie` (relative) of the smallest are timing noise: among those, the
    fewest unknowns, then the fewest time steps, then the smallest error win.
    """
    ok = [r for r in rows if r.get("converged", True) and r.get("model", "scene") == model
          and all(math.isfinite(r[f"error_{k}"]) and r[f"error_{k}"] <= tol for k in KEYS)]
    if not ok:
        return None
    fastest = min(r["wall_time_s"] for r in ok)
    close = [r for r in ok if r["wall_time_s"] <= fastest * (1.0 + tie)]
    best = min(close, key=lambda r: (r["dofs"], r.get("time_steps", 0),
                                     max(r[f"error_{k}"] for k in KEYS)))
    return dict(best)


# --- the study ---------------------------------------------------------------------------------

def families_for(scene) -> tuple[list[Family], list[str]]:
    """The element families the scene's model admits, and notes on what was substituted."""
    m = scene.model
    has_pressure = m.tissue == "layered" and m.subcutaneous != "drained"
    notes = []
    if has_pressure:
        fams = [Family("P2/P1 triangles", ("model.displacement_degree=2",
                                           "section.mesh.quadrilateral=false"), "scene", 2, "tri"),
                Family("Q2/Q1 quadrilaterals", ("model.displacement_degree=2",
                                                "section.mesh.quadrilateral=true"), "scene", 2,
                       "quad"),
                Family("P1 triangles (drained model)",
                       ("model.displacement_degree=1", "model.subcutaneous=\"drained\"",
                        "section.mesh.quadrilateral=false"), "drained", 1, "tri")]
        notes.append(f"P1 displacement is not allowed with the {m.subcutaneous} subcutaneous "
                     "tissue (equal-order u/p fails the inf-sup condition; the code refuses it): "
                     "the P1 curve uses the drained model and its errors are against the drained "
                     "model's own converged value (Richardson over the P1 levels), not against "
                     "the scene's model. Its model error is the fidelity study's.")
    else:
        fams = [Family("P2 triangles", ("model.displacement_degree=2",
                                        "section.mesh.quadrilateral=false"), "scene", 2, "tri"),
                Family("Q2 quadrilaterals", ("model.displacement_degree=2",
                                             "section.mesh.quadrilateral=true"), "scene", 2,
                       "quad"),
                Family("P1 triangles", ("model.displacement_degree=1",
                                        "section.mesh.quadrilateral=false"), "scene", 1, "tri")]
        notes.append("The scene's model has no pore pressure: P1 is allowed and scored against "
                     "the same reference as P2.")
    return fams, notes


def _slug(text: str) -> str:
    out = text.lower().replace("/", "").replace("(", "").replace(")", "")
    return "-".join(out.split())


def _memory_mark() -> tuple[str, float]:
    """Reset the peak-RSS counter of this process if Linux allows it; return (method, baseline
    in MB). With /proc/self/clear_refs ('5' resets VmHWM) the peak after a run is that run's
    peak; otherwise ru_maxrss only grows, and its increase is a lower bound."""
    try:
        Path("/proc/self/clear_refs").write_text("5")
        return "VmHWM", _proc_status("VmRSS")
    except OSError:
        return "ru_maxrss", resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _proc_status(field: str) -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return float(line.split()[1]) / 1024.0  # kB -> MB
    return math.nan


def _memory_peak(method: str) -> float:
    if method == "VmHWM":
        return _proc_status("VmHWM")
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _run_one(scene_name, settings, out_dir: Path, progress: bool, comm) -> dict:
    """One run: the key outputs, wall time, memory; a failed run is a row with its reason."""
    from ..runner import run_scene
    from ..scene import load_scene

    method, before = _memory_mark()
    started, cpu = time.perf_counter(), time.process_time()
    row = {"converged": True, "failure": ""}
    try:
        scene = load_scene(scene_name, list(settings))
        summary = run_scene(scene, out_dir, progress=progress)
        values = key_outputs(out_dir)
        row.update(values)
        row["time_steps"] = int(summary.get("time_steps", 0))
        row["newton_iterations"] = int(summary.get("newton_iterations", 0))
    except ConvergenceError as error:
        row.update({k: math.nan for k in KEYS})
        row.update(converged=False, failure=str(error).split(". Results")[0],
                   wall_time_s=math.nan, dofs=0, time_steps=0, newton_iterations=0)
        try:
            row["dofs"] = int(json.loads((out_dir / "summary.json").read_text())["dofs"])
        except (OSError, KeyError, ValueError):
            pass
    row["total_time_s"] = time.perf_counter() - started
    row["cpu_time_s"] = comm.allreduce(time.process_time() - cpu, op=MPI.SUM)
    peak = _memory_peak(method)
    row["peak_rss_MB"] = comm.allreduce(peak, op=MPI.SUM)
    row["run_memory_MB"] = comm.allreduce(max(peak - before, 0.0), op=MPI.SUM)
    row["memory_method"] = method
    return row


def _mesh_plan(scene_name, overrides, plan: Plan, levels: int):
    from ..scene import load_scene

    scene = load_scene(scene_name, list(overrides))
    mesh = scene.section.mesh
    base = plan.sizes or (mesh.min_size, mesh.max_size, mesh.bone_size)
    out = []
    for k in range(levels):
        f = plan.ratio ** -k
        h = base[0] * f
        mx, bone = (base[1] * f, base[2] * f) if plan.scale_outer else (base[1], base[2])
        out.append((h, max(mx, h), max(bone, h)))
    return scene, out


def _mesh_settings(h: float, max_size: float, bone_size: float) -> list[str]:
    """The overrides of a run's mesh sizes (mm)."""
    return [f"section.mesh.min_size={h!r}", f"section.mesh.max_size={max_size!r}",
            f"section.mesh.bone_size={bone_size!r}"]


@dataclass(frozen=True)
class _Runs:
    """What every run of one study shares: the scene, the study's overrides (before each
    run's own), the output folder, progress and the communicator."""

    scene_name: str
    overrides: tuple[str, ...]
    out: Path
    progress: bool
    comm: MPI.Comm

    def say(self, text: str) -> None:
        if self.progress and self.comm.rank == 0:
            print(f"[accuracy] {text}", flush=True)

    def run(self, settings: list[str], slug: str) -> dict:
        """One run into out/<slug>/ (`_run_one`)."""
        return _run_one(self.scene_name, settings, self.out / slug, self.progress, self.comm)


#: What the coarse study's plan means for its reference (accuracy.md's notes).
COARSE_NOTE = ("Coarse study: max_size and bone_size are held at a coarse value while min_size "
               "refines, so the Richardson value is the limit min_size -> 0 at that far-field "
               "size (the full study refines the whole mesh); Q2/Q1 runs on the two finer "
               "meshes (Newton fails on the coarsest quadrilateral mesh of the 1pt scene), P1 "
               "on the two coarser ones; Δt is refined on the middle mesh.")


#: The study's own report files in its folder.
ACCURACY_OUTPUTS = ("accuracy.csv", "accuracy.json", "accuracy.md", "accuracy.png")


def run_accuracy_study(scene_name: str, out: Path, *, levels: int = 3, coarse: bool = True,
                       overrides=(), progress: bool = False, plan: Plan | None = None,
                       adapt_tol: float | None = None) -> dict:
    """Run the accuracy study of `scene_name` into `out` (see the module docstring).

    Returns {"rows": [...], "richardson": {key: {"estimate", "order", "note"}} (reference
    family, mesh), "richardson_by_family", "time_richardson", "reference": {key: value},
    "cheapest_1pct": row or None, "sentence", "notes", "adaptive": the loop's check (None
    without `adapt_tol`)}.
    """
    comm = MPI.COMM_WORLD
    out = Path(out)
    plan = plan or (COARSE if coarse else FULL)
    if levels < 2:
        raise ValueError("levels must be >= 2")
    base_overrides = list(STUDY_DEFAULTS) + list(plan.extra) + list(overrides)
    scene, sizes = _mesh_plan(scene_name, base_overrides, plan, levels)
    check_scene(scene, f"accuracy study of {scene_name}")
    families, notes = families_for(scene)
    if plan is COARSE:
        notes.append(COARSE_NOTE)
    # An earlier study's report must not stay beside these runs if this study stops part-way.
    remove_outputs(out, ACCURACY_OUTPUTS, comm)
    runs = _Runs(scene_name, tuple(base_overrides), out, progress, comm)
    dt = (scene.steps.dt_initial, scene.steps.dt_max)
    rows = _mesh_rows(runs, families, sizes, plan, dt)
    time_rows = _time_rows(runs, families[0], rows, sizes, plan, dt)
    rows += time_rows[1:]
    by_family = {fam.name: _extrapolate([r for r in rows if r["family"] == fam.name
                                         and r["kind"] == "mesh"], plan.ratio)
                 for fam in families}
    time_est = _extrapolate(time_rows, 2.0)
    references = _references(families, by_family, time_est, time_rows[0])
    _score(rows, references)
    best = cheapest_within(rows, TOL)
    adaptive = None
    if adapt_tol is not None:
        adaptive = _check_the_loop(runs, families[0], rows, sizes, plan, references["scene"],
                                   adapt_tol)
    result = {"scene": scene_name, "coarse": coarse, "ratio": plan.ratio,
              "rows": rows, "richardson": by_family[families[0].name],
              "richardson_by_family": by_family, "time_richardson": time_est,
              "reference": references["scene"], "references": references,
              "cheapest_1pct": best, "sentence": _sentence(best, rows, scene_name),
              "notes": notes, "adaptive": adaptive}
    on_root(comm, lambda: _write(result, out))  # rank 0 writes; a failure stops every rank
    return result


def _mesh_rows(runs: _Runs, families: list[Family], sizes: list, plan: Plan,
               dt: tuple[float, float]) -> list[dict]:
    """Every family on its mesh levels of the plan, at the scene's time steps."""
    rows = []
    for fi, fam in enumerate(families):
        if plan.family_levels is not None and plan.family_levels[fi] is None:
            continue
        first, drop = (0, 0) if plan.family_levels is None else plan.family_levels[fi]
        for k, (h, mx, bone) in list(enumerate(sizes))[first:len(sizes) - drop]:
            slug = f"{_slug(fam.name)}-h{h:.4g}"
            settings = list(runs.overrides) + list(fam.settings) + _mesh_settings(h, mx, bone)
            runs.say(f"{fam.name}, h = {h:.4g} mm")
            row = {"family": fam.name, "model": fam.model, "kind": "mesh", "level": k,
                   "h_mm": h, "max_size_mm": mx, "bone_size_mm": bone, "degree": fam.degree,
                   "cell": fam.cell, "dt_initial_s": dt[0], "dt_max_s": dt[1], "run": slug}
            row.update(runs.run(settings, slug))
            row["settings"] = " ".join(list(fam.settings) + settings[-3:])
            rows.append(row)
    return rows


def _time_rows(runs: _Runs, ref: Family, rows: list[dict], sizes: list, plan: Plan,
               dt: tuple[float, float]) -> list[dict]:
    """The Δt refinement on one mesh of the reference family `ref`: its run at the scene's
    steps (from `rows`), then dt_initial and dt_max halved per level."""
    levels = len(sizes)
    t_index = (levels - 1) if plan.time_level is None else min(plan.time_level, levels - 1)
    h, mx, bone = sizes[t_index]
    dt0, dtmax0 = dt
    time_rows = [next(r for r in rows if r["family"] == ref.name and r["level"] == t_index)]
    for j in range(1, plan.time_levels):
        f = 0.5 ** j
        slug = f"{_slug(ref.name)}-h{h:.4g}-dt{dtmax0 * f:.4g}"
        settings = list(runs.overrides) + list(ref.settings) + _mesh_settings(h, mx, bone) + [
            f"steps.dt_initial={dt0 * f!r}", f"steps.dt_max={dtmax0 * f!r}"]
        runs.say(f"{ref.name}, h = {h:.4g} mm, dt_max = {dtmax0 * f:.4g} s")
        row = {"family": f"{ref.name}, Δt refined", "model": "scene", "kind": "time",
               "level": j, "h_mm": h, "max_size_mm": mx, "bone_size_mm": bone,
               "degree": ref.degree, "cell": ref.cell, "dt_initial_s": dt0 * f,
               "dt_max_s": dtmax0 * f, "run": slug}
        row.update(runs.run(settings, slug))
        row["settings"] = " ".join(list(ref.settings) + settings[-5:])
        time_rows.append(row)
    return time_rows


def _references(families: list[Family], by_family: dict, time_est: dict,
                base_t: dict) -> dict:
    """The converged value of each model (the scene's, a substitute's) per key: the first
    family of the model's Richardson value, for the scene's model plus the time-step
    correction (time_est's value minus `base_t`, the base-Δt run it started from)."""
    references = {}
    for fam in families:
        if fam.model in references:
            continue
        est = by_family[fam.name]
        if fam.model == "scene":
            references["scene"] = {
                k: est[k]["estimate"] + (time_est[k]["estimate"] - base_t[k]) for k in KEYS}
        else:
            references[fam.model] = {k: est[k]["estimate"] for k in KEYS}
    return references


def _score(rows: list[dict], references: dict) -> None:
    """Each row's relative error per key against its model's reference, and the largest."""
    for r in rows:
        refv = references[r["model"]]
        errs = {k: abs(r[k] - refv[k]) / max(abs(refv[k]), 1e-300) for k in KEYS}
        for k in KEYS:
            r[f"error_{k}"] = errs[k]
        r["max_error"] = max(errs.values()) if r["converged"] else math.nan


def _check_the_loop(runs: _Runs, ref: Family, rows: list[dict], sizes: list, plan: Plan,
                    reference: dict, adapt_tol: float) -> dict:
    """The adaptive loop from the coarsest mesh of the reference family, scored against the
    study's `reference` with that reference's own uncertainty (`check_adaptive`)."""
    ladder = [r for r in rows if r["family"] == ref.name and r["kind"] == "mesh"
              and r["converged"]]
    finest = ladder[-1]
    previous = ladder[-2] if len(ladder) > 1 and (
        ladder[-1]["level"] - ladder[-2]["level"] == 1) else None
    far = None
    if not plan.scale_outer:  # the far field is held: how much does it matter?
        far = _far_field_halved(runs, ref, sizes[finest["level"]])
    uncertainty = reference_uncertainty(finest, previous, reference, plan.ratio, far)
    runs.say(f"adaptive loop, tol = {adapt_tol:g}, from h = {sizes[0][0]:.4g} mm")
    return check_adaptive(runs.scene_name, list(runs.overrides) + list(ref.settings), sizes[0],
                          runs.out / "adaptive", adapt_tol, reference, uncertainty,
                          runs.progress)


def _far_field_halved(runs: _Runs, ref: Family, size: tuple[float, float, float]) -> dict | None:
    """The finest run of the reference family again with max_size and bone_size halved (not
    below min_size); None if it fails."""
    h, mx, bone = size
    runs.say(f"{ref.name}, h = {h:.4g} mm, far field halved (the reference's uncertainty)")
    settings = list(runs.overrides) + list(ref.settings) + _mesh_settings(
        h, max(mx / 2, h), max(bone / 2, h))
    far = runs.run(settings, f"{_slug(ref.name)}-h{h:.4g}-far-halved")
    return far if far["converged"] else None


def check_adaptive(scene_name, settings, start, out: Path, tol: float, reference: dict,
                   uncertainty: dict, progress: bool = False) -> dict:
    """Run the adaptive loop (as `fingertip run --tol` does) from the mesh sizes `start` =
    (min, max, bone), score every level against `reference` and check the loop's final
    estimates against its true errors.

    `uncertainty[key]`: how far the reference itself may be off (relative), see
    `reference_uncertainty`. Per key the verdict is "yes" (estimate >= true error), "within
    the reference's uncertainty" (true error <= estimate + uncertainty: the reference cannot
    tell) or "no".

    Returns {"tol", "converged", "message", "levels": [{level, cells, dofs, wall_time_s,
    error_<key>, estimate_<key>}], "estimated", "true", "uncertainty", "verdict",
    "bound": {key: bool}, "all_bound", "sentence", "failure"}.
    """
    report, failure = _run_the_loop(scene_name, settings, start, out, tol, progress)
    if report is None or not report["levels"]:
        return {"tol": tol, "failure": failure, "levels": [], "all_bound": False,
                "sentence": f"The adaptive loop failed: {failure}"}
    levels = _scored_levels(report["levels"], reference)
    final = levels[-1]
    estimated = {k: final[f"estimate_{k}"] for k in KEYS}
    true = {k: final[f"error_{k}"] for k in KEYS}
    verdict = {k: "yes" if estimated[k] >= true[k] else
               "within the reference's uncertainty" if true[k] <= estimated[k] + uncertainty[k]
               else "no" for k in KEYS}
    bound = {k: verdict[k] == "yes" for k in KEYS}
    unsure = [k for k in KEYS if verdict[k] != "yes"]
    status = "converged" if report["converged"] else "stopped"
    sentence = (f"The adaptive loop (tol = {tol:g}) {status} after {len(levels)} levels "
                f"({final['dofs']} unknowns, {sum(r['wall_time_s'] for r in levels):.1f} s "
                "of time stepping in all); its estimated errors bound the true errors of "
                + ("every key output." if not unsure else "every key output but " + ", ".join(
                    f"{k} (estimated {estimated[k]:.3%}, true {true[k]:.3%}: "
                    + ("the reference's own uncertainty, " + f"{uncertainty[k]:.3%}, covers it)"
                       if verdict[k] != "no" else "NOT bounded)") for k in unsure) + "."))
    return {"tol": tol, "converged": report["converged"], "message": report["message"],
            "failure": failure, "levels": levels, "estimated": estimated, "true": true,
            "uncertainty": uncertainty, "verdict": verdict, "bound": bound,
            "all_bound": not unsure, "no_failures": "no" not in verdict.values(),
            "sentence": sentence}


def _run_the_loop(scene_name, settings, start, out: Path, tol: float,
                  progress: bool) -> tuple[dict | None, str | None]:
    """`adapt` from the mesh sizes `start`: (its report, None), or after a failure (the
    adapt.json it wrote, or None; the failure's message)."""
    from ..scene import load_scene
    from .adaptivity import AdaptOptions, adapt

    scene = load_scene(scene_name, list(settings) + _mesh_settings(*start))
    try:
        return adapt(scene, out, AdaptOptions(tol=tol, coarsen=1.0), progress=progress), None
    except ConvergenceError as error:
        path = Path(out) / "adapt.json"
        return (json.loads(path.read_text()) if path.is_file() else None), str(error)


def _scored_levels(levels: list[dict], reference: dict) -> list[dict]:
    """The loop's levels, each key output's true error (against `reference`) beside the
    loop's estimate (NaN at level 0)."""
    def error(value, key):
        return abs(value - reference[key]) / max(abs(reference[key]), 1e-300)

    scored = []
    for lv in levels:
        row = {k: lv[k] for k in ("level", "cells", "dofs", "wall_time_s")}
        row.update({f"error_{k}": error(lv["values"][k], k) for k in KEYS})
        row.update({f"estimate_{k}": lv["estimates"][k]["error"] if "estimates" in lv
                    else math.nan for k in KEYS})
        scored.append(row)
    return scored


def reference_uncertainty(finest: dict, previous: dict | None, reference: dict, ratio: float,
                          far: dict | None = None, order: float = 2.0) -> dict:
    """How far the study's reference may itself be off, per key (relative): the Richardson
    correction it applied to the finest run, |f_finest - f_ref|, plus the finest run's grid
    convergence index at the formal order, |f_finest - f_previous| / (r^p - 1) (Roache 1998;
    Celik et al. 2008 report it as the uncertainty of the fine solution: it is what remains
    when three levels give an order far above the formal one, or none, and the correction is
    then small or zero), plus, for a plan that holds the far field, how much the finest run
    moves when the far field is halved, |f_far - f_finest| (the reference is the limit at a
    coarse far field; the loop refines it)."""
    out = {}
    for k in KEYS:
        scale = max(abs(reference[k]), 1e-300)
        u = abs(finest[k] - reference[k]) / scale
        if previous is not None:
            u += abs(finest[k] - previous[k]) / (ratio**order - 1.0) / scale
        if far is not None:
            u += abs(far[k] - finest[k]) / scale
        out[k] = u
    return out


def _extrapolate(seq: list[dict], ratio: float) -> dict:
    """Richardson per key over the last three converged, consecutive levels of `seq`."""
    good = [r for r in seq if r["converged"]]
    if not good:
        return {k: {"estimate": math.nan, "order": math.nan, "note": "no converged run"}
                for k in KEYS}
    last = good[-3:]
    consecutive = len(last) == 3 and last[2]["level"] - last[0]["level"] == 2
    out = {}
    for k in KEYS:
        if consecutive:
            out[k] = richardson(last[0][k], last[1][k], last[2][k], ratio)
        else:
            out[k] = {"estimate": float(good[-1][k]), "order": math.nan,
                      "note": "fewer than three consecutive levels: finest value used"}
    return out


def _sentence(best, rows, scene_name) -> str:
    if best is None:
        worst = min((r for r in rows if r["model"] == "scene" and r["converged"]),
                    key=lambda r: r["max_error"], default=None)
        tail = (f" (the best, {worst['family']} at h = {worst['h_mm']:.3g} mm, is off by "
                f"{worst['max_error']:.2%})" if worst else "")
        return (f"No setting of the study reaches 1 % on every key output of `{scene_name}`"
                f"{tail}: refine further (`coarse=False`, more levels).")
    worst_key = max(KEYS, key=lambda k: best[f"error_{k}"])
    return (f"The cheapest setting that reaches 1 % on every key output of `{scene_name}` is "
            f"{best['family']} at min_size = {best['h_mm']:.4g} mm (max_size "
            f"{best['max_size_mm']:.4g}, bone_size {best['bone_size_mm']:.4g}, dt_max "
            f"{best['dt_max_s']:.4g} s): {best['dofs']} unknowns, {best['wall_time_s']:.1f} s, "
            f"largest error {best['max_error']:.2%} ({worst_key}). Settings: "
            f"`{best['settings']}`.")


# --- files ---------------------------------------------------------------------------------------

CSV_COLUMNS = ("family", "model", "kind", "level", "h_mm", "max_size_mm", "bone_size_mm",
               "degree", "cell", "dt_initial_s", "dt_max_s", "dofs", "time_steps",
               "newton_iterations", "wall_time_s", "total_time_s", "cpu_time_s", "peak_rss_MB",
               "run_memory_MB", "memory_method", "converged", "max_error",
               *(f"error_{k}" for k in KEYS), *KEYS, *TIME_COLUMNS, "run", "settings", "failure")


def read_table(path: Path) -> list[dict]:
    text = ("family", "model", "kind", "cell", "memory_method", "run", "settings", "failure")
    with Path(path).open() as f:
        rows = list(csv.DictReader(f))
    out = []
    for r in rows:
        d = {}
        for k, v in r.items():
            if k in text:
                d[k] = v
            elif k == "converged":
                d[k] = v == "True"
            elif k in ("level", "degree", "dofs", "time_steps", "newton_iterations"):
                d[k] = int(float(v))
            else:
                d[k] = float(v) if v not in ("", "nan") else math.nan
        out.append(d)
    return out


def _fmt(v, spec=".3g"):
    return "—" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, spec)


def _write(result: dict, out: Path):
    """accuracy.csv, accuracy.json, accuracy.md and accuracy.png of `result` into `out`."""
    out.mkdir(parents=True, exist_ok=True)
    with (out / "accuracy.csv").open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=CSV_COLUMNS, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(result["rows"])
    meta = {k: v for k, v in result.items() if k != "rows"}
    (out / "accuracy.json").write_text(json.dumps(meta, indent=1, default=str))
    short = {k.column: k.short for k in KEY_OUTPUTS}
    lines = (_runs_table(result, short) + _richardson_table(result, short)
             + _adaptive_table(result.get("adaptive"), short) + _notes(result))
    (out / "accuracy.md").write_text("\n".join(lines) + "\n")
    _chart(result, out / "accuracy.png")


def _runs_table(result: dict, short: dict) -> list[str]:
    """accuracy.md's title, sentence and the table of every run's errors and cost."""
    lines = [f"# Accuracy study: `{result['scene']}` "
             f"({'coarse' if result['coarse'] else 'full'}; mesh ratio r = {result['ratio']:.4g})",
             "", "**" + result["sentence"] + "**", "",
             "Relative error of each key output against the Richardson estimate of the converged "
             "value (mesh levels of the reference family, plus the Δt correction). Wall time: "
             "the time stepping (summary.json); memory: the process's peak resident set during "
             "the run, summed over ranks. Key outputs: " + ", ".join(
                 f"{k.short} = `{k.column}`" for k in KEY_OUTPUTS) + ".", "",
             "| family | h (mm) | dt_max (s) | dofs | wall (s) | peak RSS (MB) | "
             + " | ".join(short[k] for k in KEYS) + " | max |",
             "| --- | ---: | ---: | ---: | ---: | ---: | " + " | ".join("---:" for _ in KEYS)
             + " | ---: |"]
    for r in result["rows"]:
        if not r["converged"]:
            lines.append(f"| {r['family']} | {r['h_mm']:.4g} | {r['dt_max_s']:.4g} | "
                         f"{r['dofs'] or '—'} | — | — | failed: {r['failure']} |"
                         + " |" * len(KEYS))
            continue
        lines.append(f"| {r['family']} | {r['h_mm']:.4g} | {r['dt_max_s']:.4g} | {r['dofs']} | "
                     f"{r['wall_time_s']:.1f} | {r['peak_rss_MB']:.0f} | "
                     + " | ".join(f"{100 * r[f'error_{k}']:.3f} %" for k in KEYS)
                     + f" | {100 * r['max_error']:.3f} % |")
    return lines


def _richardson_table(result: dict, short: dict) -> list[str]:
    """accuracy.md's Richardson estimates and observed orders, per family and in Δt, and the
    reference."""
    lines = ["", "## Richardson estimates (mesh) and observed orders", "",
             "| family | " + " | ".join(short[k] for k in KEYS) + " |",
             "| --- | " + " | ".join("---:" for _ in KEYS) + " |"]
    for fam, est in result["richardson_by_family"].items():
        lines.append(f"| {fam}: f∞ | " + " | ".join(_fmt(est[k]["estimate"], ".6g")
                                                    for k in KEYS) + " |")
        lines.append(f"| {fam}: order p | " + " | ".join(_fmt(est[k]["order"], ".2f")
                                                        for k in KEYS) + " |")
    est = result["time_richardson"]
    lines.append("| Δt: f∞ | " + " | ".join(_fmt(est[k]["estimate"], ".6g") for k in KEYS) + " |")
    lines.append("| Δt: order q | " + " | ".join(_fmt(est[k]["order"], ".2f") for k in KEYS)
                 + " |")
    lines.append("| reference | " + " | ".join(_fmt(result["reference"][k], ".6g") for k in KEYS)
                 + " |")
    return lines


def _adaptive_table(adaptive: dict | None, short: dict) -> list[str]:
    """accuracy.md's check of the adaptive loop (none without one): per level the true error
    beside the estimate, the reference's uncertainty and where the bound holds."""
    if not adaptive:
        return []
    lines = ["", (f"## The adaptive loop (tol = {adaptive['tol']:g}): estimated against "
                  "true errors"), "", "**" + adaptive["sentence"] + "**", "",
             ("Per level: the true error against the reference above / the loop's "
              "estimate (none at level 0). The loop starts from the coarsest mesh of the "
              "reference family (`studies.adaptivity`)."), "",
             "| level | cells | dofs | wall (s) | " + " | ".join(short[k] for k in KEYS)
             + " |", "| ---: | ---: | ---: | ---: | " + " | ".join("---:" for _ in KEYS)
             + " |"]
    for r in adaptive["levels"]:
        lines.append(f"| {r['level']} | {r['cells']} | {r['dofs']} | {r['wall_time_s']:.1f} | "
                     + " | ".join(f"{100 * r[f'error_{k}']:.3f} / "
                                  f"{_fmt(100 * r[f'estimate_{k}'], '.3f')} %" for k in KEYS)
                     + " |")
    lines.append("| the reference's uncertainty | | | | " + " | ".join(
        f"{100 * adaptive['uncertainty'][k]:.3f} %" for k in KEYS) + " |")
    lines.append("| bound holds | | | | " + " | ".join(
        {"yes": "yes", "no": "**no**"}.get(adaptive["verdict"][k], "within the "
                                            "reference's uncertainty") for k in KEYS)
                 + " |")
    return lines + ["", ("The reference's uncertainty: the Richardson correction it applied "
                         "to the finest run, plus that run's grid convergence index at the "
                         "formal order 2, |f_finest - f_previous| / (r^2 - 1), plus, where the "
                         "study holds the far field, how much the finest run moves when the "
                         "far field is halved (the loop refines the far field where its "
                         "indicator asks). An error within it cannot be judged by this "
                         "reference.")]


def _notes(result: dict) -> list[str]:
    """accuracy.md's notes: the study's, where Richardson was not applied, and the caveats."""
    lines = ["", "## Notes", ""] + [f"- {n}" for n in result["notes"]]
    for fam, est in list(result["richardson_by_family"].items()) + [
            ("Δt", result["time_richardson"])]:
        notes = {}
        for k in KEYS:
            if est[k]["note"]:
                notes.setdefault(est[k]["note"], []).append(k)
        for note, keys in notes.items():
            lines.append(f"- Richardson not applied (order NaN) for {fam}, "
                         f"{'all key outputs' if len(keys) == len(KEYS) else ', '.join(keys)}: "
                         f"{note}.")
    lines.append("- Unstructured meshes are not nested: orders from three levels carry mesh "
                 "noise; the Δt levels halve dt_initial and dt_max (the adaptive step control "
                 "then picks its steps, cuts included).")
    lines.append("- The Pareto front (accuracy.png) is over the runs of the scene's model.")
    return lines


def _chart(result: dict, path: Path):
    from matplotlib.figure import Figure

    rows = [r for r in result["rows"] if r["converged"]]
    fig = Figure(figsize=(7.2, 4.8))
    ax = fig.subplots()
    floor = 1e-6
    for name in dict.fromkeys(r["family"] for r in rows):
        seq = [r for r in rows if r["family"] == name]
        if seq[0]["kind"] == "time":  # the Δt curve starts at its base-Δt mesh run
            base = next((r for r in rows if r["kind"] == "mesh" and r["h_mm"] == seq[0]["h_mm"]
                         and r["family"] == name.removesuffix(", Δt refined")), None)
            seq = ([base] if base else []) + seq
        # a run that is its own reference (no Richardson value) has error 0: not plotted
        seq = [r for r in seq if r["max_error"] > 0]
        if not seq:
            continue
        x = [r["wall_time_s"] for r in seq]
        y = [max(r["max_error"], floor) for r in seq]
        drained = seq[-1]["model"] != "scene"
        label = name + (" — vs its own model's converged value" if drained else "")
        ax.plot(x, y, "--" if seq[-1]["kind"] == "time" else "-", marker="o",
                mfc="none" if drained else None, label=label)
        for r, xi, yi in zip(seq, x, y):
            tag = (f"Δt/{round(seq[0]['dt_max_s'] / r['dt_max_s'])}" if r["kind"] == "time"
                   else f"h={r['h_mm']:.3g}")
            ax.annotate(tag, (xi, yi), fontsize=7, xytext=(3, 3), textcoords="offset points")
    scene_rows = [r for r in rows if r["model"] == "scene" and r["max_error"] > 0]
    front = [scene_rows[i] for i in pareto_front([r["wall_time_s"] for r in scene_rows],
                                                 [r["max_error"] for r in scene_rows])]
    if front:
        ax.step([r["wall_time_s"] for r in front], [max(r["max_error"], floor) for r in front],
                where="post", color="k", lw=1.0, alpha=0.6)
        ax.scatter([r["wall_time_s"] for r in front], [max(r["max_error"], floor) for r in front],
                   s=140, facecolors="none", edgecolors="k", label="Pareto front (scene's model)")
    adaptive = result.get("adaptive")
    if adaptive and adaptive["levels"]:
        seq = adaptive["levels"]
        x = [r["wall_time_s"] for r in seq]
        y = [max(max(r[f"error_{k}"] for k in KEYS), floor) for r in seq]
        ax.plot(x, y, ":", marker="s", color="purple",
                label=f"adaptive loop (tol {adaptive['tol']:g}), per level")
        for r, xi, yi in zip(seq, x, y):
            ax.annotate(f"L{r['level']}", (xi, yi), fontsize=7, xytext=(3, -9),
                        textcoords="offset points")
    best = result["cheapest_1pct"]
    if best:
        ax.scatter([best["wall_time_s"]], [max(best["max_error"], floor)], marker="*", s=220,
                   color="gold", edgecolors="k", zorder=5, label="cheapest within 1 %")
    ax.axhline(TOL, color="r", lw=0.8, ls=":", label="1 %")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time of the time stepping (s)")
    ax.set_ylabel(f"largest relative error of the key outputs (floor {floor:g})")
    ax.set_title(f"{result['scene']}: error against cost")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
