"""Parameter sweeps: one scene run for each value of one input, and the key outputs side by side.

The first study anyone runs on this model: the permeability of the subcutaneous tissue has
never been measured (Wu et al. 2004 borrow cartilage's), and the moduli and Prony terms are
fits. `parameter_sweep("1pt", "materials.subcutaneous.permeability.k0", values=[...])` runs
the scene for each value (any scene key, in the scene file's tables, a materials value
included); `factors=[...]` instead multiplies the scene's own value (a number or a list, e.g.
all the skin's μ_i at once). It writes DIR/<label>/ per run, DIR/sweep.csv with the key outputs
(`keys.KEY_OUTPUTS`: each column names its quantity, unit, place and time, with the time it was
read at beside it), DIR/summary.json and DIR/sweep.png (the force histories coloured by the
parameter, and one panel per key output against it).
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from mpi4py import MPI

from ..errors import InputError, on_root
from ..keys import KEY_OUTPUTS, KEYS, TIME_COLUMNS, check_scene, key_outputs
from ..outputs import read_csv, remove_outputs, whole, write_json
from ..plotting.figures import display_unit

#: The files a parameter sweep writes beside its runs' folders.
SWEEP_OUTPUTS = ("sweep.csv", "summary.json", "sweep.png")


def parameter_sweep(scene_name: str, key: str, out: Path, *, values: Sequence | None = None,
                    factors: Sequence[float] | None = None, overrides: Sequence[str] = (),
                    progress: bool = True, resume: bool = False) -> dict:
    """Run `scene_name` once per value of `key`; returns (and writes) the table of key outputs.
    `resume`: continue the runs of a sweep stopped part-way (`run_side_by_side`)."""
    from ..runner import run_side_by_side
    from ..scene import load_scene, scene_record, toml_value

    if (values is None) == (factors is None):
        raise InputError("sweep", "give either values or factors.", "use one of the two.")
    out = Path(out)
    base = scene_record(load_scene(scene_name, list(overrides)))
    settings = (list(values) if values is not None
                else [scaled_value(value_at(base, key), f, key) for f in factors])
    labels = _labels(key.rsplit(".", 1)[-1], settings, factors)
    jobs = [(load_scene(scene_name, [*overrides, f"{key}={toml_value(v)}"]), out / label)
            for label, v in zip(labels, settings)]
    for scene, _ in jobs:  # before any run: every run must write what the key outputs read
        check_scene(scene, f"sweep {scene_name} --param {key}")
    # An earlier sweep's table must not stay beside these runs if this sweep stops part-way.
    remove_outputs(out, SWEEP_OUTPUTS, MPI.COMM_WORLD)
    run_side_by_side(jobs, progress=progress, resume=resume)

    def tabulate() -> dict:  # on rank 0: the table, its files and its figure
        rows = [{"label": label, "value": v, **key_outputs(out / label)}
                for label, v in zip(labels, settings)]
        result = {"scene": scene_name, "key": key, "factors": list(factors or []), "rows": rows,
                  "key_outputs": {k.column: k.record() for k in KEY_OUTPUTS}}
        _write(rows, out)
        _plot(out, result)
        return result

    result = on_root(MPI.COMM_WORLD, tabulate)
    write_json(out / "summary.json", result, MPI.COMM_WORLD)
    return result


def _labels(name: str, settings: list, factors) -> list[str]:
    """Directory names: k0=0.01, mu-x2, or name-0, name-1, ... for list values."""
    if factors is not None:
        return [f"{name}-x{f:g}" for f in factors]
    if all(isinstance(v, int | float) and not isinstance(v, bool) for v in settings):
        return [f"{name}={v:g}" for v in settings]
    return [f"{name}-{i}" for i in range(len(settings))]


def value_at(record: dict, key: str):
    """The value at `key` (dotted, list entries by index) in a scene record."""
    node = record
    for part in key.split("."):
        try:
            node = node[int(part)] if isinstance(node, list) else node[part]
        except (KeyError, IndexError, ValueError):
            raise InputError(f"--param {key}", f"the scene has no value at {part!r}.",
                             "give a key of the scene's tables (e.g. materials.skin.mu).") from None
    return node


def scaled_value(value, factor: float, key: str):
    """`value` (a number or a list of numbers) times `factor`; `key` names it in errors."""
    if isinstance(value, bool) or not isinstance(value, int | float | list):
        raise InputError(f"--param {key}", f"{value!r} is not a number or a list of numbers: "
                         "it cannot be scaled.", "use --values instead of --factors.")
    return [factor * v for v in value] if isinstance(value, list) else factor * value


def _write(rows: list[dict], out: Path) -> None:
    columns = ["label", "value", *KEYS, *TIME_COLUMNS, "wall_time_s", "dofs"]
    with whole(out / "sweep.csv") as tmp, tmp.open("w", newline="") as f:  # no half table
        writer = csv.DictWriter(f, fieldnames=columns, extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow({**row, "value": str(row["value"])})


#: Units of the scene keys most often swept (the last part of the dotted key), for the figure.
UNITS = {"k0": "mm⁴/(N·s)", "mu": "MPa", "E": "MPa", "depth": "mm", "ramp_time": "s",
         "end_time": "s", "hold_time": "s", "tau": "s", "radius": "mm", "width": "mm",
         "tip_radius": "mm", "min_size": "mm", "max_size": "mm", "dt_max": "s",
         "dt_initial": "s"}


def sweep_axis(result: dict) -> tuple[np.ndarray, str, bool, list[str] | None]:
    """(x, axis label, log scale?, tick labels or None) of a sweep's parameter: the factors,
    the numeric values (log where they are positive and span a decade or more), or the run
    index for list values."""
    key, rows = result["key"], result["rows"]
    name = key.rsplit(".", 1)[-1]
    if result["factors"]:
        x, label = np.array(result["factors"], dtype=float), f"factor on {name} (× scene value)"
    elif all(isinstance(r["value"], int | float) and not isinstance(r["value"], bool)
             for r in rows):
        unit = UNITS.get(name)
        x = np.array([r["value"] for r in rows], dtype=float)
        label = f"{name} ({unit})" if unit else f"{name} (units of the scene file)"
    else:
        return np.arange(len(rows), dtype=float), f"{name} (run)", False, [
            r["label"] for r in rows]
    log = bool(np.all(x > 0) and x.max() / x.min() >= 10.0)
    return x, label, log, None


def _plot(out: Path, result: dict) -> None:
    """sweep.png: the force histories coloured by the parameter (a colour bar with its unit),
    and one panel per key output against the parameter."""
    from matplotlib import colormaps
    from matplotlib.colors import LogNorm, Normalize
    from matplotlib.figure import Figure

    x, label, log, ticks = sweep_axis(result)
    norm = (LogNorm if log else Normalize)(x.min(), x.max() if x.max() > x.min() else x.min() + 1)
    colours = colormaps["viridis"](norm(x) * 0.9)  # the yellow end is unreadable on white
    fig = Figure(figsize=(13.0, 6.6), layout="constrained")
    axes = fig.subplots(2, 4).ravel()
    _plot_histories(axes[0], out, result["rows"], colours)
    for ax, key in zip(axes[1:], KEY_OUTPUTS):
        _plot_key(ax, key, x, result["rows"], colours, log, ticks)
        ax.set_xlabel(label, fontsize=8)
    bar = fig.colorbar(_mappable(norm, colormaps["viridis"]), ax=axes.tolist(), shrink=0.8)
    bar.set_label(label)
    if ticks:
        bar.set_ticks(x, labels=ticks)
    fig.suptitle(f"{result['scene']}: sweep over {result['key']} ({len(x)} runs)")
    fig.savefig(out / "sweep.png", dpi=100)


def _mappable(norm, cmap):
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import ListedColormap

    return ScalarMappable(norm, ListedColormap(cmap(np.linspace(0, 0.9, 256))))


def _plot_histories(ax, out: Path, rows: list[dict], colours) -> None:
    """Force against time, one curve per run; thicker lines underneath so that curves that
    coincide stay visible; a symlog time axis (linear up to the force peak) for long holds."""
    from matplotlib.ticker import FuncFormatter

    histories = [read_csv(out / row["label"] / "history.csv") for row in rows]
    # in mN/mm below 0.1 N/mm, as the runs' own force figures (figures.display_unit)
    factor, unit_label = display_unit("force (N/mm)", max(
        float(np.max(np.abs(h["force_N_per_mm"]))) for h in histories))
    end = 0.0
    for i, (row, h, colour) in enumerate(zip(rows, histories, colours)):
        width = 1.0 + 2.5 * (len(rows) - 1 - i) / max(len(rows) - 1, 1)
        ax.plot(h["time_s"], factor * h["force_N_per_mm"], "-", color=colour, lw=width,
                solid_capstyle="butt", label=row["label"])
        end = max(end, float(h["time_s"][-1]))
    # The force peaks at the end of the ramp: linear up to there, logarithmic over a hold
    # much longer than the ramp.
    ramp = min(float(r["force_N_per_mm_max_over_run_t_s"]) for r in rows)
    if end / max(ramp, 1e-12) > 20:
        ax.set_xscale("symlog", linthresh=ramp, linscale=1.0)
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.set_xlim(0, end)
    ax.set_xlabel("time (s)", fontsize=8)
    ax.set_ylabel(unit_label, fontsize=8)
    ax.set_title("force against time\n(thicker: earlier runs, seen where curves coincide)",
                 fontsize=8)
    _sci(ax)
    ax.grid(alpha=0.3)
    if len(rows) <= 8:
        ax.legend(fontsize=7)


def _plot_key(ax, key, x, rows: list[dict], colours, log: bool, ticks) -> None:
    """One key output against the parameter, each point in its run's colour; the time it was
    read at in the title (the peak's time, for a max over the run)."""
    quantity, where = key.label.split("\n", 1)
    y = np.array([r[key.column] for r in rows], dtype=float)
    factor, quantity = display_unit(quantity, float(np.nanmax(np.abs(y))))  # 0.22 kPa, 1.44 mN/mm
    y = factor * y
    order = np.argsort(x)
    ax.plot(x[order], y[order], "-", color="0.6", lw=1.0, zorder=1)
    ax.scatter(x, y, c=colours, s=36, edgecolors="k", linewidths=0.5, zorder=2)
    if log:
        ax.set_xscale("log")
    if ticks:
        ax.set_xticks(x, labels=ticks, fontsize=7, rotation=30)
    read = np.array([r[f"{key.column}_t_s"] for r in rows], dtype=float)
    times = sorted({round(float(t), 9) for t in read})
    if len(times) > 1:  # the peak came at different times: say which at each point
        for xi, yi, ti in zip(x, y, read):
            ax.annotate(f"{ti:g} s", (xi, yi), fontsize=6, xytext=(4, 3),
                        textcoords="offset points")
    when = ", ".join(f"{t:g}" for t in times[:4]) + (", …" if len(times) > 4 else "")
    ax.set_title(f"{quantity}\n{where}\nread at t = {when} s", fontsize=8)
    _sci(ax)
    ax.grid(alpha=0.3)


def _sci(ax) -> None:
    """y ticks as 1.40 with a ×10⁻³ above the axis, not 0.0014; values that differ in their
    sixth digit (a parameter the output hardly feels) as 1.439380 ×10⁻³, not as an offset
    (×10⁻⁹ + 1.4393×10⁻³ above the axis, ticks 74–80), which reads as a different number."""
    from matplotlib.ticker import ScalarFormatter

    formatter = ScalarFormatter(useMathText=True, useOffset=False)
    formatter.set_powerlimits((-2, 3))
    ax.yaxis.set_major_formatter(formatter)
    ax.tick_params(labelsize=7)
