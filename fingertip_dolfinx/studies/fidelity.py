"""Which physics does a scene need? The same scene with a ladder of models, cheapest first.

| rung | model |
| --- | --- |
| continuum | one homogeneous small-strain linear-elastic section (the subcutaneous E, ν) |
| hyperfoam | layered hyperfoam, no time dependence (skin elastic, subcutaneous drained) |
| + skin QLV | the skin's viscoelasticity added |
| + undrained | the subcutaneous tissue incompressible (no flow) |
| full | biphasic subcutaneous tissue (the reference) |
| full, rigid bone | the full model with bone and nail rigid and held |

Each rung's key outputs (`keys.KEY_OUTPUTS`) are compared with the full model's; `pick` names the
cheapest rung whose largest relative error stays under a tolerance.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

from mpi4py import MPI

from ..errors import ConvergenceError, InputError
from ..keys import KEY_OUTPUTS, KEYS, TIME_COLUMNS, check_scene, key_outputs, relative_errors
from ..outputs import remove_outputs

LADDER = (
    ("continuum", ["model.tissue=\"continuum\""]),
    ("hyperfoam", ["model.subcutaneous=\"drained\"", "model.skin_viscoelastic=false"]),
    ("+ skin QLV", ["model.subcutaneous=\"drained\"", "model.skin_viscoelastic=true"]),
    ("+ undrained", ["model.subcutaneous=\"undrained\"", "model.skin_viscoelastic=true"]),
    ("full", ["model.subcutaneous=\"biphasic\"", "model.skin_viscoelastic=true"]),
    ("full, rigid bone", ["model.subcutaneous=\"biphasic\"", "model.rigid_bone=true"]),
)
REFERENCE = "full"


def _slug(name: str) -> str:
    return name.replace("+ ", "plus-").replace(", ", "-").replace(" ", "-")


#: The study's own report files in its folder.
FIDELITY_OUTPUTS = ("fidelity.csv", "fidelity.md", "fidelity.png")


def run_fidelity_study(scene_name: str, out: Path, overrides=(), progress: bool = True) -> list:
    """Run the ladder for `scene_name` into out/<rung>/; write fidelity.csv, .md and a chart."""
    from ..runner import run_scene
    from ..scene import load_scene

    comm = MPI.COMM_WORLD
    out = Path(out)
    # An earlier study's report must not stay beside these runs if this study stops part-way.
    remove_outputs(out, FIDELITY_OUTPUTS, comm)
    results, failures = {}, {}
    for name, settings in LADDER:
        scene = load_scene(scene_name, list(overrides) + settings)
        check_scene(scene, f"fidelity study of {scene_name}")
        try:
            run_scene(scene, out / _slug(name), progress=progress)
        except ConvergenceError as error:
            # A model that cannot carry the scene is a finding (e.g. the small-strain continuum
            # under a sharp tip inverts elements): record it, go on with the ladder.
            if name == REFERENCE:
                raise
            failures[name] = str(error)
            summary = json.loads((out / _slug(name) / "summary.json").read_text())
            results[name] = {"wall_time_s": summary["wall_time_s"], "dofs": summary["dofs"],
                             **dict.fromkeys(KEYS, math.nan)}
            continue
        results[name] = key_outputs(out / _slug(name))
    rows = []
    reference = results[REFERENCE]
    for name, _ in LADDER:
        errors = relative_errors(results[name], reference)
        rows.append({"model": name, "wall_time_s": results[name]["wall_time_s"],
                     "dofs": results[name]["dofs"],
                     "max_error": math.inf if name in failures else max(errors.values()),
                     **{f"error_{k}": v for k, v in errors.items()},
                     **{k: results[name].get(k, math.nan) for k in (*KEYS, *TIME_COLUMNS)},
                     "failure": failures.get(name, "")})
    if comm.rank == 0:
        _write(rows, out, scene_name)
    return rows


def pick(rows: list[dict], tol: float) -> tuple[str, str]:
    """The lowest rung of the ladder whose largest key-output error is below `tol`.

    The ladder is ordered by modelling cost (unknowns, history, nonlinearity); measured wall
    times of small runs are too noisy to rank models that differ little.
    """
    ladder = [r for r in rows if r["model"] != "full, rigid bone"]
    best = next(r for r in ladder if r["max_error"] <= tol)
    worst = max(KEYS, key=lambda k: best[f"error_{k}"])
    cheaper = ladder[:ladder.index(best)]
    why = (f"'{best['model']}' is the cheapest model whose largest error against the full model "
           f"is {best['max_error']:.2%} <= {tol:.2%} (worst output: {worst})")
    if cheaper:
        why += "; cheaper ones miss: " + ", ".join(
            f"{r['model']} ({'failed' if r.get('failure') else format(r['max_error'], '.1%')})"
            for r in cheaper)
    return best["model"], why


def read_table(path: Path) -> list[dict]:
    """The rows of a fidelity.csv; InputError for a table without today's key outputs (one
    written before they were named by quantity, unit, place and time)."""
    with Path(path).open() as f:
        rows = list(csv.DictReader(f))
    missing = [f"error_{k}" for k in KEYS if rows and f"error_{k}" not in rows[0]]
    if not rows or missing:
        raise InputError(str(path), "is not a fidelity table with today's key outputs (no "
                         + (", ".join(missing[:2]) + ", ..." if missing else "rows") + ").",
                         "run `fingertip study fidelity` again for this scene.")
    return [{k: (v if k in ("model", "failure") else float(v or "nan")) for k, v in r.items()}
            for r in rows]


def settings_of(model: str) -> list[str]:
    return dict(LADDER)[model]


def _write(rows, out: Path, scene_name: str):
    columns = list(rows[0])
    with (out / "fidelity.csv").open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)
    lines = [f"Fidelity ladder for `{scene_name}`: relative error of each key output against "
             "the full model. Key outputs: " + ", ".join(
                 f"{k.short} = `{k.column}`" for k in KEY_OUTPUTS) + ".", "",
             "| model | wall time (s) | " + " | ".join(k.short for k in KEY_OUTPUTS)
             + " | max |",
             "| --- | ---: | " + " | ".join("---:" for _ in KEYS) + " | ---: |"]
    for r in rows:
        if r.get("failure"):
            lines.append(f"| {r['model']} | {r['wall_time_s']:.1f} | "
                         + " | ".join("—" for _ in KEYS) + " | failed |")
            continue
        lines.append(f"| {r['model']} | {r['wall_time_s']:.1f} | "
                     + " | ".join(f"{100 * r[f'error_{k}']:.1f} %" for k in KEYS)
                     + f" | {100 * r['max_error']:.1f} % |")
    lines += ["", *(f"- {r['model']} failed: {r['failure']}" for r in rows if r.get("failure"))]
    (out / "fidelity.md").write_text("\n".join(lines) + "\n")

    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.6, 4.2))
    ax = fig.subplots()
    markers = "osD^vP*X"
    for i, r in enumerate(rows):
        if r.get("failure"):
            continue
        ax.scatter(r["wall_time_s"], max(r["max_error"], 1e-6), s=36, marker=markers[i % 8],
                   label=r["model"])
    # a legend, not labels at the points: models of nearly equal cost and error overlap
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.set_yscale("log")
    ax.set_xlabel("wall time (s)")
    ax.set_ylabel("largest relative error of the key outputs\n"
                  "(against the full model; floor 1e-6)")
    ax.set_title(f"{scene_name}: model fidelity against cost")
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(out / "fidelity.png", dpi=150)
