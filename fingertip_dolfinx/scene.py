"""Experiments as data: a scene file names the section, the indenters, the protocol, the model
and the outputs; `run_scene` builds the problem, steps it, and writes results as it goes.

Built-in scene files live in `fingertip_dolfinx/data/scenes/` (`line-load`, `1pt`, `2pt`) or anywhere as TOML. The
command line only picks a scene and overrides keys (`--set model.subcutaneous=drained`).
"""

from __future__ import annotations

import dataclasses
import json
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from .datafiles import builtin_dir, find, read_toml
from .errors import ConvergenceError, InputError
from .geometry import load_section
from .indenters import load_indenter, make_indenter
from .loading import history_from_dict

#: The built-in scenes (inside the package: `fingertip_dolfinx/data/scenes/`).
SCENES_DIR = builtin_dir("scenes")
TABLES = ("name", "description", "section", "spacing", "indenters", "protocol", "model",
          "steps", "solver", "output")


@dataclass
class Scene:
    """A scene file's content, validated; `data` keeps the (merged) raw tables for the record."""

    name: str
    data: dict
    section: object
    indenters: list
    history: object
    model: object
    steps: object
    petsc_options: dict
    output_times: tuple[float, ...]
    depths: tuple[float, ...]
    profile_half_width: float
    profile_points: int
    field_every: int = 1
    extra: dict = field(default_factory=dict)


def scene_path(source: str | Path) -> Path:
    return find("scenes", source, "scene")


def parse_override(text: str) -> tuple[list[str], object]:
    """`a.b.c=value` -> (["a", "b", "c"], value), the value read as TOML (else a string)."""
    key, sep, raw = text.partition("=")
    if not sep or not key.strip():
        raise InputError(f"--set {text}", "is not of the form key=value.",
                         "write e.g. --set model.subcutaneous=drained.")
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    return key.strip().split("."), value


def load_scene(source: str | Path, overrides: list[str] = (), spacing: float | None = None) -> Scene:
    """Read a scene file, apply `key=value` overrides, and validate everything."""
    path = scene_path(source)
    data = read_toml(path)
    for text in overrides:
        keys, value = parse_override(text)
        node = data
        for k in keys[:-1]:
            node = node.setdefault(k, {})
            if not isinstance(node, dict):
                raise InputError(f"--set {text}", f"{k!r} is not a table.")
        node[keys[-1]] = value
    if spacing is not None:
        data["spacing"] = spacing
    return scene_from_dict(data, where=str(path))


def scene_from_dict(data: dict, where: str = "scene") -> Scene:
    from .forms import ModelOptions
    from .solver import StepOptions

    unknown = sorted(set(data) - set(TABLES))
    if unknown:
        raise InputError(f"{where}: {', '.join(unknown)}", "unknown key(s) of a scene.",
                         f"a scene has: {', '.join(TABLES)}.")
    section_data = dict(data.get("section", {}))
    section = load_section(section_data.pop("file", "male-index"), overrides=section_data)

    indenters = []
    for i, table in enumerate(data.get("indenters", [])):
        table = dict(table)
        base = table.pop("file", None)
        if base is not None:
            base_data = dataclasses.asdict(load_indenter(base)) | {"shape": load_indenter(base).shape}
            table = base_data | table
        indenters.append(make_indenter(table, where=f"{where}: indenters[{i}]"))
    if not indenters:
        raise InputError(f"{where}: indenters", "no indenter given.", "add an [[indenters]] table.")
    if "spacing" in data:
        spacing = float(data["spacing"])
        if spacing <= 0:
            raise InputError(f"{where}: spacing", f"must be positive, got {spacing}.")
        if len(indenters) != 1:
            raise InputError(f"{where}: spacing", "places a pair: give exactly one indenter.")
        width = getattr(indenters[0], "width", 0.0)
        if spacing <= width:
            raise InputError(f"{where}: spacing", f"{spacing} mm does not separate two "
                             f"indenters {width} mm wide.", f"use a spacing above {width} mm.")
        indenters = [dataclasses.replace(indenters[0], centre_x=s * spacing / 2) for s in (-1, 1)]

    history = history_from_dict(data.get("protocol", {}), where=f"{where}: protocol")
    model_data = dict(data.get("model", {}))
    allowed = [f.name for f in dataclasses.fields(ModelOptions) if f.name != "extra"]
    bad = sorted(set(model_data) - set(allowed))
    if bad:
        raise InputError(f"{where}: model.{', '.join(bad)}", "unknown model option(s).",
                         f"[model] takes: {', '.join(allowed)}.")
    model = ModelOptions(**model_data)
    steps_data = dict(data.get("steps", {}))
    allowed = [f.name for f in dataclasses.fields(StepOptions)]
    bad = sorted(set(steps_data) - set(allowed))
    if bad:
        raise InputError(f"{where}: steps.{', '.join(bad)}", "unknown step option(s).",
                         f"[steps] takes: {', '.join(allowed)}.")
    try:
        steps = StepOptions(**steps_data)
    except ValueError as e:
        raise InputError(f"{where}: steps", str(e)) from None

    out = dict(data.get("output", {}))
    end = getattr(history, "end_time", None)
    times = tuple(float(t) for t in out.pop("times", [end]))
    if any(t <= 0 or (end is not None and t > end + 1e-12) for t in times):
        raise InputError(f"{where}: output.times", f"{times} must lie in (0, end_time = {end}].")
    depths = tuple(float(d) for d in out.pop("depths", [0.5, 0.75, 1.0]))
    if any(d <= 0 for d in depths):
        raise InputError(f"{where}: output.depths", f"{depths}: depths are positive (mm).")
    half_width = float(out.pop("profile_half_width", 6.0))
    if not 0 < half_width < section.outer.a:
        raise InputError(f"{where}: output.profile_half_width",
                         f"{half_width} mm must lie in (0, {section.outer.a}) (the half-width).")
    n_points = int(out.pop("profile_points", 241))
    field_every = int(out.pop("field_every", 1))
    if out:
        raise InputError(f"{where}: output.{', '.join(out)}", "unknown output option(s).",
                         "[output] takes: times, depths, profile_half_width, profile_points, "
                         "field_every.")
    return Scene(
        name=str(data.get("name", Path(where).stem)),
        data=data,
        section=section,
        indenters=indenters,
        history=history,
        model=model,
        steps=steps,
        petsc_options=dict(data.get("solver", {})),
        output_times=times,
        depths=depths,
        profile_half_width=half_width,
        profile_points=n_points,
        field_every=field_every,
    )


def run_scene(scene: Scene, out: Path, *, resume: bool = False, progress: bool = True,
              comm=None) -> dict:
    """Run `scene`, writing into `out` as it goes; returns the summary (also summary.json)."""
    from mpi4py import MPI

    from .recorder import Recorder

    comm = comm or MPI.COMM_WORLD
    recorder = Recorder(scene, Path(out), comm, resume=resume, progress=progress)
    started = time.perf_counter()
    try:
        recorder.run()
        converged, failure = True, None
    except ConvergenceError as error:
        converged, failure = False, str(error)
    summary = recorder.finish(converged, failure, time.perf_counter() - started)
    if failure is not None:
        raise ConvergenceError(failure)
    return summary


def scene_record(scene: Scene) -> dict:
    """The scene as plain data, for summary.json."""
    return json.loads(json.dumps(scene.data, default=str))

