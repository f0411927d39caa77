"""Parameter sweeps: one scene run for each value of one input, and the key outputs side by side.

The first study anyone runs on this model: the permeability of the subcutaneous tissue has
never been measured (Wu et al. 2004 borrow cartilage's), and the moduli and Prony terms are
fits. `parameter_sweep("1pt", "materials.subcutaneous.permeability.k0", values=[...])` runs
the scene for each value (any scene key, in the scene file's tables, a materials value
included); `factors=[...]` instead multiplies the scene's own value (a number or a list, e.g.
all the skin's μ_i at once). It writes DIR/<label>/ per run, DIR/sweep.csv with the key outputs
(`keys.KEYS`), DIR/summary.json and DIR/sweep.png (force against time, one curve per value).
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from mpi4py import MPI

from ..errors import InputError
from ..outputs import read_csv, write_json
from .keys import KEYS, key_outputs


def parameter_sweep(scene_name: str, key: str, out: Path, *, values: Sequence | None = None,
                    factors: Sequence[float] | None = None, overrides: Sequence[str] = (),
                    progress: bool = True) -> dict:
    """Run `scene_name` once per value of `key`; returns (and writes) the table of key outputs."""
    from ..runner import run_side_by_side
    from ..scene import load_scene, scene_record, toml_value

    if (values is None) == (factors is None):
        raise InputError("sweep", "give either values or factors.", "use one of the two.")
    out = Path(out)
    base = scene_record(load_scene(scene_name, list(overrides)))
    settings = (list(values) if values is not None
                else [_scaled(_lookup(base, key), f, key) for f in factors])
    labels = _labels(key.rsplit(".", 1)[-1], settings, factors)
    jobs = [(load_scene(scene_name, [*overrides, f"{key}={toml_value(v)}"]), out / label)
            for label, v in zip(labels, settings)]
    run_side_by_side(jobs, progress=progress)
    result = None
    if MPI.COMM_WORLD.rank == 0:
        rows = [{"label": label, "value": v, **key_outputs(out / label)}
                for label, v in zip(labels, settings)]
        result = {"scene": scene_name, "key": key, "factors": list(factors or []), "rows": rows}
        _write(rows, out)
        _plot(out, labels, key)
    result = MPI.COMM_WORLD.bcast(result, root=0)
    write_json(out / "summary.json", result, MPI.COMM_WORLD)
    return result


def _labels(name: str, settings: list, factors) -> list[str]:
    """Directory names: k0=0.01, mu-x2, or name-0, name-1, ... for list values."""
    if factors is not None:
        return [f"{name}-x{f:g}" for f in factors]
    if all(isinstance(v, int | float) and not isinstance(v, bool) for v in settings):
        return [f"{name}={v:g}" for v in settings]
    return [f"{name}-{i}" for i in range(len(settings))]


def _lookup(record: dict, key: str):
    """The value at `key` (dotted, list entries by index) in a scene record."""
    node = record
    for part in key.split("."):
        try:
            node = node[int(part)] if isinstance(node, list) else node[part]
        except (KeyError, IndexError, ValueError):
            raise InputError(f"--param {key}", f"the scene has no value at {part!r}.",
                             "give a key of the scene's tables (e.g. materials.skin.mu).") from None
    return node


def _scaled(value, factor: float, key: str):
    if isinstance(value, bool) or not isinstance(value, int | float | list):
        raise InputError(f"--param {key}", f"{value!r} is not a number or a list of numbers: "
                         "it cannot be scaled.", "use --values instead of --factors.")
    return [factor * v for v in value] if isinstance(value, list) else factor * value


def _write(rows: list[dict], out: Path) -> None:
    columns = ["label", "value", *KEYS, "wall_time_s", "dofs"]
    with (out / "sweep.csv").open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=columns, extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow({**row, "value": str(row["value"])})


def _plot(out: Path, labels: list[str], key: str) -> None:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.4, 4.2))
    ax = fig.subplots()
    for label in labels:
        h = read_csv(out / label / "history.csv")
        ax.plot(h["time_s"], h["force_N_per_mm"], "-", label=label)
    ax.set_xscale("symlog", linthresh=1.0)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("force (N/mm)")
    ax.set_title(f"sweep over {key}")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "sweep.png", dpi=150)


def force_table(result: dict) -> np.ndarray:
    """(values or factors, peak force, final force) rows of a sweep's result."""
    scale = result["factors"] or [r["value"] for r in result["rows"]]
    return np.array([[s, r["peak_force"], r["final_force"]]
                     for s, r in zip(scale, result["rows"])])
