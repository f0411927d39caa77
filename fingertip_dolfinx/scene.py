"""Experiments as data: a scene names the section, the materials, the indenters, the protocol,
the model options, the step control and the outputs. A scene is data only: `run.py` runs it.

A scene comes from a TOML file (built in: `fingertip_dolfinx/data/scenes/`, `line-load`, `1pt`,
`2pt`; or any path) with `key=value` overrides (`model.subcutaneous="drained"`,
`indenters.0.centre_x=1.5`: list entries by index), or from parts in Python:
`Scene(section=..., indenters=[...], history=...)`. Both are validated the same way.
"""

from __future__ import annotations

import dataclasses
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from .datafiles import builtin_dir, find, read_toml
from .errors import InputError
from .geometry import Section, load_section
from .geometry3d import Fingertip3D, load_fingertip3d, section_dimension
from .harmonic import HarmonicOptions
from .indenters import Indenter, load_indenter, make_indenter
from .linear_solvers import check_linear
from .loading import KINDS, LoadHistory, history_from_dict
from .model import ModelOptions
from .solver import StepOptions
from .tissues import DEFAULT_SET, WU2004, Tissues, load_materials
from .validation import check_keys, positive

#: The built-in scenes (inside the package: `fingertip_dolfinx/data/scenes/`).
SCENES_DIR = builtin_dir("scenes")
#: When a run writes its fields for ParaView (`[output] fields`).
FIELD_MODES = ("output-times", "every-step")
TABLES = ("name", "description", "section", "spacing", "indenters", "materials", "protocol",
          "model", "steps", "solver", "output", "accuracy", "harmonic")


@dataclass(frozen=True)
class Outputs:
    """What a run writes besides its history: profiles and pictures at `times` (s), along
    curves at `depths` (mm below the undeformed outer surface) over |x| <= profile_half_width,
    sampled at `profile_points`; fields for ParaView (`fields`: at the output `times`, or
    "every-step": every `field_every` steps and at the output times; a `field_every` above 1
    alone means "every-step"); `pictures = false` skips the PNG figures (a sweep of many runs
    may want only the numbers); `receptors` names a receptor set (`"default"` or a path,
    `data/receptors/`) whose sites are sampled at every step into receptors.csv ("" or false:
    none)."""

    times: tuple[float, ...] = ()
    depths: tuple[float, ...] = (0.5, 0.75, 1.0)
    profile_half_width: float = 6.0
    profile_points: int = 241
    field_every: int = 1
    pictures: bool = True
    receptors: str = ""
    #: 3D only: z (mm) of the cross-section with the across-finger profiles and depth curves
    #: (default: a sphere's or across-prism's centre_z, else mid-cylinder).
    section_z: float | None = None
    #: "output-times" or "every-step" (None: "every-step" if field_every > 1, else
    #: "output-times"; the record holds the one chosen).
    fields: str | None = None

    def __post_init__(self):
        if not isinstance(self.pictures, bool):
            raise InputError("output.pictures", f"got {self.pictures!r}.", "use true or false.")
        if self.receptors is False:
            object.__setattr__(self, "receptors", "")
        if not isinstance(self.receptors, str):
            raise InputError("output.receptors", f"got {self.receptors!r}.",
                             'name a receptor set ("default" or a path), or use false.')
        if self.receptors:
            try:
                find("receptors", self.receptors, "receptor set")
            except InputError as error:
                raise InputError("output.receptors", error.problem, error.fix) from None
        object.__setattr__(self, "times", tuple(float(t) for t in self.times))
        object.__setattr__(self, "depths", tuple(float(d) for d in self.depths))
        if any(d <= 0 for d in self.depths):
            raise InputError("output.depths", f"{self.depths}: depths are positive (mm).")
        if not (isinstance(self.profile_points, int) and self.profile_points >= 2):
            raise InputError("output.profile_points", f"got {self.profile_points!r}.",
                             "use an integer >= 2.")
        if not (isinstance(self.field_every, int) and self.field_every >= 1):
            raise InputError("output.field_every", f"got {self.field_every!r}.",
                             "use an integer >= 1.")
        object.__setattr__(self, "fields", self._field_mode())

    def _field_mode(self) -> str:
        """When fields go to ParaView: `fields`, or what `field_every` alone asks for."""
        if self.fields is None:
            return "every-step" if self.field_every > 1 else "output-times"
        if self.fields not in FIELD_MODES:
            raise InputError("output.fields", f"got {self.fields!r}.",
                             'use "output-times" (the default) or "every-step".')
        if self.fields == "output-times" and self.field_every > 1:
            raise InputError("output.field_every", f"{self.field_every} is the stride of "
                             'fields = "every-step", but output.fields = "output-times".',
                             'set output.fields = "every-step", or leave field_every out.')
        return self.fields


@dataclass(frozen=True)
class Accuracy:
    """`[accuracy]`: ask for an accuracy instead of a mesh. With `tol` (a relative error, e.g.
    0.01), `fingertip run` refines the mesh (`adaptivity.py`) until every key output's
    estimated error is below it, in at most `max_levels` runs; without it (the default) the
    scene runs once on its own mesh."""

    tol: float | None = None
    max_levels: int = 4

    def __post_init__(self):
        if self.tol is not None and not positive("accuracy.tol", self.tol) < 1:
            raise InputError("accuracy.tol", f"{self.tol} is a relative error of "
                             f"{self.tol:.0%}.", "give a fraction, e.g. 0.01 for 1 %.")
        if isinstance(self.max_levels, bool) or not (
                isinstance(self.max_levels, int) and self.max_levels >= 2):
            raise InputError("accuracy.max_levels", f"got {self.max_levels!r}: an error "
                             "estimate needs two levels.", "give an integer >= 2.")


@dataclass
class Scene:
    """One experiment: everything a run needs, validated. Defaults: the paper's materials
    (`wu2004`), the default model and step options, outputs at the protocol's end."""

    section: Section | Fingertip3D  # a 2D section (plane strain) or a 3D fingertip
    indenters: list[Indenter]
    history: LoadHistory
    materials: Tissues = WU2004
    model: ModelOptions = field(default_factory=ModelOptions)
    steps: StepOptions = field(default_factory=StepOptions)
    petsc_options: dict = field(default_factory=dict)
    outputs: Outputs = field(default_factory=Outputs)
    name: str = "scene"
    description: str = ""
    accuracy: Accuracy = field(default_factory=Accuracy)  # last: positional calls unchanged
    #: `[harmonic]`: the small-signal frequency response about the pressed state
    #: (harmonic.py); None: the scene has no such table.
    harmonic: HarmonicOptions | None = None
    #: `[solver] linear`: the linear solver inside Newton, "direct" (MUMPS) or "iterative"
    #: (Krylov with a field-split multigrid preconditioner; linear_solvers.py).
    linear: str = "direct"

    def __post_init__(self):
        self.indenters = list(self.indenters)
        check_linear(self.linear, f"{self.name}: solver.linear")
        if not self.indenters:
            raise InputError(f"{self.name}: indenters", "no indenter given.",
                             "add an [[indenters]] table.")
        if not isinstance(self.history, LoadHistory):
            raise InputError(f"{self.name}: protocol", f"{self.history!r} is not a protocol.",
                             "use RampHold, PiecewiseLinear or Sinusoid (loading.py).")
        if not self.history.deepest > 0:
            raise InputError(f"{self.name}: protocol", f"the indentation never exceeds "
                             f"{self.history.deepest:g} mm: the indenters would not press.",
                             "give a positive depth (mm after first touch).")
        if self.model.inertia and self.steps.scheme != "generalized-alpha":
            raise InputError(f"{self.name}: steps.scheme", f"{self.steps.scheme!r} integrates "
                             "no acceleration, but model.inertia is on.",
                             'use scheme = "generalized-alpha", or inertia = false.')
        if not self.outputs.times:
            self.outputs = dataclasses.replace(self.outputs, times=(self.history.end_time,))
        self._check_outputs()

    def _check_outputs(self):
        end, o = self.history.end_time, self.outputs
        if any(t <= 0 or t > end + 1e-12 for t in o.times):
            raise InputError(f"{self.name}: output.times",
                             f"{o.times} must lie in (0, end_time = {end}].")
        if not 0 < o.profile_half_width < self.section.outer.a:
            raise InputError(f"{self.name}: output.profile_half_width",
                             f"{o.profile_half_width} mm must lie in (0, {self.section.outer.a}) "
                             "(the section's half-width).")
        z = o.section_z
        if z is None:
            return
        if not isinstance(self.section, Fingertip3D):
            raise InputError(f"{self.name}: output.section_z", "is for 3D fingertips only.",
                             "leave it out of a 2D scene.")
        if not 0 < z < self.section.cylinder_length:
            raise InputError(f"{self.name}: output.section_z", f"{z} mm must lie in (0, "
                             f"{self.section.cylinder_length}) (the cylindrical part, whose "
                             "cross-section is the 2D section).", "pick a z on it.")

    # The names the run and the studies read.
    @property
    def output_times(self) -> tuple[float, ...]:
        return self.outputs.times

    @property
    def depths(self) -> tuple[float, ...]:
        return self.outputs.depths

    @property
    def profile_half_width(self) -> float:
        return self.outputs.profile_half_width

    @property
    def profile_points(self) -> int:
        return self.outputs.profile_points

    @property
    def field_every(self) -> int:
        return self.outputs.field_every


# --- reading scene files --------------------------------------------------------------------


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


def apply_override(data: dict, text: str) -> None:
    """Set one `key=value` in the scene's tables; list entries are addressed by index
    (`indenters.0.centre_x=1.5`)."""
    keys, value = parse_override(text)
    node = data
    for depth, k in enumerate(keys):
        last = depth == len(keys) - 1
        if isinstance(node, list):
            if not (k.isdigit() and int(k) < len(node)):
                raise InputError(f"--set {text}", f"{'.'.join(keys[:depth]) or 'it'} is a list "
                                 f"of {len(node)}; {k!r} is not an index of it.",
                                 f"use an index from 0 to {len(node) - 1}.")
            k = int(k)
        elif not isinstance(node, dict):
            raise InputError(f"--set {text}", f"{'.'.join(keys[:depth])!r} is a value, not a "
                             "table.", "check the key.")
        if last:
            node[k] = value
        else:
            node = node.setdefault(k, {}) if isinstance(node, dict) else node[k]


def overrides_as_text(overrides: Mapping | Sequence[str]) -> list[str]:
    """`key=value` strings from a nested mapping ({"model": {"tissue": "continuum"}}), so that
    Python callers can pass tables; strings pass through."""
    if not isinstance(overrides, Mapping):
        return list(overrides)

    def flatten(prefix: str, node: Mapping):
        for key, value in node.items():
            if isinstance(value, Mapping):
                yield from flatten(f"{prefix}{key}.", value)
            else:
                yield f"{prefix}{key}={toml_value(value)}"

    return list(flatten("", overrides))


def toml_value(value) -> str:
    """A Python value written as a TOML value."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, list | tuple):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    return repr(float(value)) if isinstance(value, float) else repr(value)


def load_scene(source: str | Path, overrides: Mapping | Sequence[str] = (),
               spacing: float | None = None) -> Scene:
    """Read a scene file (built-in name or path), apply overrides (`key=value` strings or a
    nested mapping of tables), and validate everything."""
    path = scene_path(source)
    data = read_toml(path)
    for text in overrides_as_text(overrides):
        apply_override(data, text)
    if spacing is not None:
        data["spacing"] = spacing
    return scene_from_dict(data, where=str(path))


def scene_from_dict(data: dict, where: str = "scene") -> Scene:
    """A scene from the tables of a scene file."""
    check_keys(where, data, TABLES, what="table")
    section_data = dict(data.get("section", {}))
    source = section_data.pop("file", "male-index")
    loader = load_fingertip3d if section_dimension(source) == 3 else load_section
    section = loader(source, overrides=section_data)
    indenters = _indenters(data, where)
    return Scene(
        name=str(data.get("name", Path(where).stem)),
        description=str(data.get("description", "")),
        section=section,
        indenters=indenters,
        history=history_from_dict(data.get("protocol", {}), where=f"{where}: protocol"),
        materials=_materials(data.get("materials", {}), f"{where}: materials"),
        model=_options(ModelOptions, data.get("model", {}), f"{where}: model"),
        steps=_options(StepOptions, data.get("steps", {}), f"{where}: steps"),
        petsc_options=_petsc_options(data.get("solver", {}), f"{where}: solver"),
        linear=data.get("solver", {}).get("linear", "direct"),
        outputs=_options(Outputs, data.get("output", {}), f"{where}: output"),
        accuracy=_options(Accuracy, data.get("accuracy", {}), f"{where}: accuracy"),
        harmonic=(_options(HarmonicOptions, data["harmonic"], f"{where}: harmonic")
                  if "harmonic" in data else None),
    )


def _indenters(data: dict, where: str) -> list[Indenter]:
    indenters = []
    for i, table in enumerate(data.get("indenters", [])):
        table = dict(table)
        base = table.pop("file", None)
        if base is not None:
            builtin = load_indenter(base)
            table = dataclasses.asdict(builtin) | {"shape": builtin.shape} | table
        indenters.append(make_indenter(table, where=f"{where}: indenters[{i}]"))
    if "spacing" in data:
        indenters = _pair(indenters, data["spacing"], f"{where}: spacing")
    return indenters


def _pair(indenters: list[Indenter], spacing, where: str) -> list[Indenter]:
    """Two copies of the one indenter at x = ±spacing/2 (the two-point test)."""
    spacing = float(spacing)
    if spacing <= 0:
        raise InputError(where, f"must be positive, got {spacing}.")
    if len(indenters) != 1:
        raise InputError(where, "places a pair: give exactly one indenter.")
    width = getattr(indenters[0], "width", 0.0)
    if spacing <= width:
        raise InputError(where, f"{spacing} mm does not separate two indenters {width} mm "
                         "wide.", f"use a spacing above {width} mm.")
    return [dataclasses.replace(indenters[0], centre_x=s * spacing / 2) for s in (-1, 1)]


def _petsc_options(data: Mapping, where: str) -> dict:
    """`[solver]`: `linear` picks the linear solver; every other key is a PETSc option of the
    time stepper's SNES (as `snes_atol = 1e-9`), and so is every key of an optional
    `petsc_options` sub-table."""
    if not isinstance(data, Mapping):
        raise InputError(where, f"must be a table, got {data!r}.", "write [solver].")
    options = {k: v for k, v in data.items() if k not in ("linear", "petsc_options")}
    extra = data.get("petsc_options", {})
    if not isinstance(extra, Mapping):
        raise InputError(f"{where}.petsc_options", f"must be a table, got {extra!r}.",
                         "write petsc_options = { ksp_rtol = 1e-10 }.")
    return options | dict(extra)


def _materials(data: Mapping, where: str) -> Tissues:
    """`[materials]`: `set` names a materials file; the other tables override its values."""
    if not isinstance(data, Mapping):
        raise InputError(where, f"must be a table, got {data!r}.", "write [materials].")
    data = dict(data)
    return load_materials(data.pop("set", DEFAULT_SET), overrides=data)


def _options(cls, data: Mapping, where: str):
    """An options dataclass from a table: unknown keys and impossible values named."""
    check_keys(where, data, [f.name for f in dataclasses.fields(cls)], what="option")
    try:
        return cls(**data)
    except InputError as error:
        raise InputError(f"{where}: {error.where}", error.problem, error.fix) from None
    except (TypeError, ValueError) as error:
        raise InputError(where, str(error), "check the values.") from None


# --- the record -----------------------------------------------------------------------------


def scene_record(scene: Scene) -> dict:
    """The scene as plain data, in the scene file's own tables (for summary.json)."""
    history = scene.history
    kind = next((k for k, cls in KINDS.items() if isinstance(history, cls)), type(history).__name__)
    return _plain({
        "name": scene.name,
        "description": scene.description,
        "section": dataclasses.asdict(scene.section),
        "indenters": [{"shape": i.shape, **dataclasses.asdict(i)} for i in scene.indenters],
        "materials": scene.materials.record(),
        "protocol": {"kind": kind, **{f.name: getattr(history, f.name)
                                      for f in dataclasses.fields(history) if f.init}},
        "model": dataclasses.asdict(scene.model),
        "steps": dataclasses.asdict(scene.steps),
        "solver": {"linear": scene.linear, **scene.petsc_options},
        "output": dataclasses.asdict(scene.outputs),
        "accuracy": dataclasses.asdict(scene.accuracy),
    } | ({} if scene.harmonic is None else {"harmonic": dataclasses.asdict(scene.harmonic)}))


def _plain(value):
    """Tuples as lists, numbers as numbers: JSON-ready."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    return value
