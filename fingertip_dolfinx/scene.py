"""Experiments as data: a scene names the section, the materials, the indenters, the protocol,
the model options, the step control and the outputs. A scene is data only: `run.py` runs it.

A scene comes from a TOML file (built in: `fingertip_dolfinx/data/scenes/`, `line-load`, `1pt`,
`2pt`; or any path) with `key=value` overrides (`model.subcutaneous="drained"`,
`indenters.0.centre_x=1.5`: list entries by index; a list given whole replaces the list), or
from parts in Python: `Scene(section=..., indenters=[...], history=...)`. Both are validated the
same way. Every key remembers where it came from (the scene file, `--set`, `--config FILE`, a
Python override), and an error names that source. Relative paths in a scene file are read
against the scene file's folder.
"""

from __future__ import annotations

import dataclasses
import math
import re
import tomllib
from collections.abc import Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .datafiles import builtin_dir, find, read_toml
from .errors import InputError
from .geometry.fingertip3d import Fingertip3D, load_fingertip3d, section_dimension
from .geometry.indenters import Grating, Indenter, load_indenter, make_indenter
from .geometry.section import Section, load_section
from .harmonic_options import HarmonicOptions
from .loading import KINDS, LoadHistory, TangentialPath, check_tangential_path, history_from_dict
from .model import ModelOptions
from .physics.friction import check_dynamic_contact
from .physics.tissues import DEFAULT_SET, WU2004, Tissues, load_materials
from .stepping.options import (
    StepOptions,
    check_factor_reuse,
    check_linear,
    check_petsc_options,
)
from .validation import check_keys, numbers, positive

#: The built-in scenes (inside the package: `fingertip_dolfinx/data/scenes/`).
SCENES_DIR = builtin_dir("scenes")
#: When a run writes its fields for ParaView (`[output] fields`).
FIELD_MODES = ("output-times", "every-step")
TABLES = ("name", "description", "section", "spacing", "indenters", "materials", "protocol",
          "model", "steps", "solver", "output", "accuracy", "harmonic")


@dataclass(frozen=True)
class Outputs:
    """What a run writes besides its history (a scene's ``[output]`` table).

    Parameters
    ----------
    times : tuple of float, optional
        Output times (s) of the profiles, field arrays and pictures; () means the protocol's end.
    depths : tuple of float, optional
        Depths (mm below the undeformed outer surface) of the depth curves.
    profile_half_width : float, optional
        The profiles cover |x| <= this (mm).
    profile_points : int, optional
        Points sampled along each profile.
    field_every : int, optional
        With ``fields = "every-step"``: write the fields every this many steps (and at the output
        times). Above 1 alone it means ``"every-step"``.
    pictures : bool, optional
        False skips the PNG figures (a sweep of many runs may want only the numbers).
    receptors : str, optional
        A receptor set (``"default"`` or a path, ``data/receptors/``) whose sites are sampled at
        every step into receptors.csv; ``""`` (or false): none.
    section_z : float or None, optional
        3D only: z (mm) of the cross-section where the profiles are read; None: the probe's z or
        the middle of the cylinder.
    fields : str or None, optional
        When the fields for ParaView are written: ``"output-times"`` (the default) or
        ``"every-step"``.
    """

    #: Output times (s): profiles, field arrays and pictures (default: the protocol's end).
    times: tuple[float, ...] = ()
    #: Depths (mm) below the undeformed outer surface of the depth curves.
    depths: tuple[float, ...] = (0.5, 0.75, 1.0)
    #: Half-width (mm) of the profiles along the pulp and at depth.
    profile_half_width: float = 6.0
    #: Points sampled along each profile.
    profile_points: int = 241
    #: With fields = "every-step": fields every this many steps (and at the output times).
    field_every: int = 1
    #: false: no PNG figures.
    pictures: bool = True
    #: A receptor set ("default" or a path) sampled at every step into receptors.csv.
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
        object.__setattr__(self, "times", numbers("output.times", self.times, "s"))
        object.__setattr__(self, "depths", numbers("output.depths", self.depths, "mm"))
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
    0.01), `fingertip run` refines the mesh (`studies.adaptivity`) until every key output's
    estimated error is below it, in at most `max_levels` runs; without it (the default) the
    scene runs once on its own mesh."""

    #: Relative error asked of every key output (space and time); none: one run.
    tol: float | None = None
    #: Most mesh levels of the adaptive loop.
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
    """One experiment: everything a run needs, validated on construction.

    Built by `load_scene` from a scene file, or from parts in Python. Defaults: the paper's
    materials (``wu2004``), the default model and step options, outputs at the protocol's end.

    Parameters
    ----------
    section : Section or Fingertip3D
        A 2D cross-section (plane strain) or a 3D fingertip, with its mesh options.
    indenters : list of Indenter
        The rigid indenters, moving together along `history`.
    history : LoadHistory
        The protocol: indentation d(t) in mm after first touch (`RampHold`, `PiecewiseLinear`,
        `Sinusoid`, `Vibration`).
    materials : Tissues, optional
        The materials of the four regions.
    model : ModelOptions, optional
        Modelling and discretisation choices (``[model]``).
    steps : StepOptions, optional
        Time stepping (``[steps]``).
    petsc_options : dict, optional
        PETSc options of the Newton solver (``[solver]``).
    outputs : Outputs, optional
        What is written besides the history (``[output]``).
    name, description : str, optional
        The scene's name (file name) and one line saying what it is.
    accuracy : Accuracy, optional
        ``[accuracy]``: the tolerance of the adaptive loop, if asked for.
    harmonic : HarmonicOptions or None, optional
        ``[harmonic]``: the frequency route's frequencies and pressed state; None: none.
    linear : str, optional
        The linear solver inside Newton: ``"direct"`` (MUMPS) or ``"iterative"``.
    changes : tuple of str, optional
        The overrides applied to the scene file, as given (the figures' titles name them).

    Raises
    ------
    InputError
        If a part is missing or inconsistent (no indenter, a protocol that never presses, ...).
    """

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
    #: (Krylov with a field-split multigrid preconditioner; stepping/linear.py).
    linear: str = "direct"
    #: The overrides applied to the scene file (`key=value`, as given): the figures' titles
    #: say what was changed (`title`).
    changes: tuple[str, ...] = ()

    def __post_init__(self):
        self.indenters = list(self.indenters)
        check_linear(self.linear, f"{self.name}: solver.linear")
        check_factor_reuse(self.steps.factor_reuse, self.linear, self.petsc_options,
                           f"{self.name}: steps.factor_reuse")
        if self.linear == "direct":  # the iterative route has no factors: it solves as before
            check_factor_reuse(self.steps.hold_factor_reuse, self.linear, self.petsc_options,
                               f"{self.name}: steps.hold_factor_reuse")
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
        self._check_depth_fits()
        three_d = isinstance(self.section, Fingertip3D)
        check_tangential_path(self.history, 3 if three_d else 2, three_d and self.section.half)
        if getattr(self.history, "normal_force", None) is not None and \
                self.steps.control == "error":
            raise InputError(f"{self.name}: steps.control", "error control redoes steps as "
                             "two halves at the protocol's depth, which force control finds "
                             "per step instead.", 'use control = "iterations" (the default).')
        for k, indenter in enumerate(self.indenters):
            check_scan_coverage(indenter, self.history, self.section,
                                f"{self.name}: indenters[{k}]")
        if self.model.inertia and self.steps.scheme != "generalized-alpha":
            raise InputError(f"{self.name}: steps.scheme", f"{self.steps.scheme!r} integrates "
                             "no acceleration, but model.inertia is on.",
                             'use scheme = "generalized-alpha", or inertia = false.')
        m = self.model
        if m.contact == "nitsche" and m.contact_theta != 0 and any(
                i.friction > 0 for i in self.indenters):  # physics/friction.py's θ = 0 form
            raise InputError(f"{self.name}: model.contact_theta", f"friction is written for "
                             f"Nitsche's θ = 0 (or the penalty), got θ = {m.contact_theta}.",
                             'use contact_theta = 0, or contact = "penalty" (the choice with '
                             "inertia).")
        check_dynamic_contact(m.contact, m.contact_theta, m.inertia,
                              [i.friction for i in self.indenters], f"{self.name}: ")
        if not self.outputs.times:
            self.outputs = dataclasses.replace(self.outputs, times=(self.history.end_time,))
        self._check_outputs()

    def _check_depth_fits(self):
        """An indentation as deep as the soft tissue under the bone is thick (at the pulp's
        centre, below the bone's lowest point) would crush that tissue to nothing: no tissue
        allows it, and the run would end in compaction or inverted elements after minutes. A
        depth in µm read as mm gives it."""
        plane = getattr(self.section, "section", self.section)  # a 3D fingertip's cross-section
        tissue = (plane.bone.cy - plane.bone.b) - (plane.outer.cy - plane.outer.b)
        if not self.history.deepest < tissue:
            raise InputError(f"{self.name}: protocol", f"the indentation reaches "
                             f"{self.history.deepest:g} mm, but the soft tissue between the "
                             f"pulp and the bone is {tissue:g} mm thick: the indenters would "
                             "crush it to nothing.", f"give the depth in mm, well below "
                             f"{tissue:g} mm (the paper's: 1 mm).")

    def _check_outputs(self):
        end, o = self.history.end_time, self.outputs
        if any(t <= 0 or t > end + 1e-12 for t in o.times):
            raise InputError(f"{self.name}: output.times",
                             f"{o.times} must lie in (0, end_time = {end}].",
                             "give output times within the run, or a later end_time.",
                             also=("protocol.end_time",))  # the end may be what was changed
        if not 0 < o.profile_half_width < self.section.outer.a:
            raise InputError(f"{self.name}: output.profile_half_width",
                             f"{o.profile_half_width} mm must lie in (0, {self.section.outer.a}) "
                             "(the section's half-width).")
        outer = self.section.outer
        x = np.linspace(-o.profile_half_width, o.profile_half_width, o.profile_points)
        for d in o.depths:  # a curve leaving the finger would sample nothing there
            if not np.all(outer.contains(outer.below_palmar(x, d))):
                raise InputError(f"{self.name}: output.depths", f"a depth curve {d:g} mm "
                                 f"below the pulp (|x| <= {o.profile_half_width:g} mm) leaves "
                                 f"the finger ({2 * outer.b:g} mm thick).", "give depths in "
                                 "mm inside it (e.g. 0.75), or a smaller profile_half_width.")
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

    @property
    def title(self) -> str:
        """The name and, compactly, the overrides applied ("1pt — indenters=[cylinder r=5],
        subcutaneous k0=1000"), cut with an ellipsis past TITLE_LENGTH characters: a figure
        of a changed scene must not pass for the built-in one."""
        if not self.changes:
            return self.name
        changes = sorted(self.changes, key=_numerical)  # the physics first, the mesh after
        title = f"{self.name} — " + ", ".join(_compact(text) for text in changes)
        return title if len(title) <= TITLE_LENGTH else title[:TITLE_LENGTH - 1] + "…"

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


#: Longest figure title (characters) before the overrides in it are cut with an ellipsis:
#: what the narrowest figure (force_history.png) shows whole at the default font.
TITLE_LENGTH = 60
#: Tables of numerical settings: a title names them after the physical ones.
_NUMERICAL = ("section.mesh", "steps", "solver", "output", "accuracy")
#: Short names of indenter sizes in titles.
_ABBREVIATIONS = {"radius": "r", "width": "w", "centre_x": "x", "centre_z": "z"}


def pulp_reach(section, depth: float, axis: str, tilt: float = 0.0) -> tuple[float, float]:
    """The strip of pulp an indentation `depth` mm after first touch can reach: where the
    undeformed pulp's lowest line lies within `depth` of its lowest point (the contact spreads
    a little further, by the skin's bulge). Across the finger (`axis` "z": the range of x) the
    outer ellipse's |x| <= a sqrt(1 − (1 − depth/b)²); along it ("x": the range of z, 3D) from
    the cut z = 0, where the finger continues, to the tip cap's z = cylinder_length +
    tip_length × the same root (the cap's cross-sections are the ellipse scaled down). A plane
    tilted by `tilt` degrees (rising towards the tip, "x" only) reaches where the lowest line
    lies within `depth` (along y) of the plane through its first touch."""
    if axis == "x" and tilt != 0:
        return _tilted_reach(section, depth, tilt)
    root = math.sqrt(1.0 - max(1.0 - depth / section.outer.b, 0.0) ** 2)
    if axis == "x":
        return 0.0, section.cylinder_length + section.tip_length * root
    return -section.outer.a * root, section.outer.a * root


def _tilted_reach(section, depth: float, tilt: float) -> tuple[float, float]:
    """`pulp_reach` along z for a plane tilted by `tilt` degrees, sampled every 10 µm."""
    length, cap, b = section.cylinder_length, section.tip_length, section.outer.b
    z = np.linspace(0.0, length + cap, int((length + cap) / 0.01) + 1)
    along_cap = np.clip((z - length) / cap, 0.0, 1.0)
    lowest = -b * np.sqrt(1.0 - along_cap**2)  # the pulp's lowest line, cylinder then cap
    above = lowest - z * math.tan(math.radians(tilt))  # its height over the tilted plane
    reached = z[above <= above.min() + depth]
    return float(reached.min()), float(reached.max())


def check_scan_coverage(indenter: Indenter, history, section, where: str) -> None:
    """A grating scanned across its ridges (an "x" grating along z, a "z" one along x) must
    lie under the whole reachable strip (`pulp_reach`) at every point of its path: else its
    end (an outermost ridge's flank, running down without end) passes through the contact,
    and the forces and spikes measure that end, not the texture. A bar (1 ridge) or a bar
    with a gap (2) is its own end: not checked. A tilted grating's ridges and path lie along
    its plane: their z is centre_z + (distance along the plane) × cos(tilt)."""
    if not (isinstance(indenter, Grating) and indenter.ridges > 2
            and hasattr(history, "tangential_at")):
        return
    d_x, d_z = getattr(history, "direction", (1.0, 0.0))
    along, centre = (d_z, indenter.centre_z) if indenter.axis == "x" else (d_x, indenter.centre_x)
    if along == 0:
        return
    s = [along * v for v in history.tangential.values]
    lo, hi = pulp_reach(section, history.deepest, indenter.axis, indenter.tilt)
    last = float(indenter.centres()[-1])  # the outermost ridges' centres: centre ± last
    cos = math.cos(math.radians(indenter.tilt))
    near, far = centre + (max(s) - last) * cos, centre + (min(s) + last) * cos
    if near > lo or far < hi:
        coordinate = "z" if indenter.axis == "x" else "x"
        covered = (f"covers {coordinate} = {near:.3g} to {far:.3g} mm throughout (its outermost "
                   "ridges' centres at the scan's two ends)" if near <= far else
                   f"covers no {coordinate} throughout: the scan ({max(s) - min(s):g} mm) is "
                   f"longer than the span of its outermost ridges' centres ({2 * last:g} mm)")
        raise InputError(
            where, f"over its scan the grating {covered}, but the pulp it presses "
            f"{history.deepest:g} mm reaches {coordinate} = {lo:.3g} to {hi:.3g} mm: the "
            "grating's end would pass through the contact.",
            f"add ridges (each adds {indenter.period:g} mm), or move centre_{coordinate} or "
            "shorten the scan.", also=("protocol.tangential",))  # the path as much as the grating


def _numerical(text: str) -> bool:
    return text.startswith(_NUMERICAL)


def _compact(text: str) -> str:
    """One override for a title: `materials.subcutaneous.permeability.k0=1000` ->
    `subcutaneous k0=1000`, `indenters=[{file = "cylinder", radius = 5.0}]` ->
    `indenters=[cylinder r=5]`, `section.mesh.min_size=0.2` -> `mesh min_size=0.2`."""
    keys, value = parse_override(text)
    if keys[0] == "indenters" and len(keys) > 1:
        name = f"indenters[{keys[1]}]" + "".join(f" {k}" for k in keys[2:])
    elif keys[0] in TABLES and len(keys) > 2:
        name = f"{keys[1]} {keys[-1]}"
    else:
        name = keys[-1]
    return f"{name}={_short(value)}"


def _short(value) -> str:
    if isinstance(value, Mapping):
        head = [Path(str(value[k])).stem for k in ("file", "shape") if k in value][:1]
        rest = [f"{_ABBREVIATIONS.get(k, k)}={_short(v)}" for k, v in value.items()
                if k not in ("file", "shape")]
        return " ".join(head + rest)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_short(v) for v in value) + "]"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


# --- reading scene files --------------------------------------------------------------------


def scene_path(source: str | Path) -> Path:
    return find("scenes", source, "scene")


class Override(str):
    """A `key=value` override that knows its `source`, the words an error message names it by:
    `--set key=value`, `--config FILE`, `overrides["model"]["tissue"]` (a Python mapping)."""

    source: str

    def __new__(cls, text: str, source: str | None = None):
        self = super().__new__(cls, text)
        self.source = source or getattr(text, "source", None) or f'override "{text}"'
        return self

    def __reduce__(self):  # pickled as itself (sweeps send scenes' overrides between ranks)
        return Override, (str(self), self.source)


def parse_override(text: str) -> tuple[list[str], object]:
    """`a.b.c=value` -> (["a", "b", "c"], value), the value read as TOML (else a string)."""
    key, sep, raw = text.partition("=")
    if not sep or not key.strip():
        raise InputError(getattr(text, "source", f"--set {text}"), "is not of the form key=value.",
                         "write e.g. --set model.subcutaneous=drained.")
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError as error:
        if raw.strip()[:1] in ("[", "{", '"', "'"):  # a list, table or string cut short
            raise InputError(getattr(text, "source", f"--set {text}"), f"{raw.strip()} is not "
                             f"a TOML value ({error}).", 'close the brackets or quotes: '
                             'e.g. --set "output.times=[1, 5]" (quoted for the shell).'
                             ) from None
        value = raw  # a bare word: a string (--set model.subcutaneous=drained)
    return key.strip().split("."), value


def apply_override(data: dict, text: str) -> tuple:
    """Set one `key=value` in the scene's tables; list entries are addressed by index
    (`indenters.0.centre_x=1.5`), a list given whole replaces the list. Returns the key path
    (list indices as integers)."""
    where = Override(text).source
    keys, value = parse_override(text)
    node, path = data, []
    for depth, k in enumerate(keys):
        if isinstance(node, list):
            if not (k.isdigit() and int(k) < len(node)):
                raise InputError(where, f"{'.'.join(keys[:depth]) or 'it'} is a list of "
                                 f"{len(node)}; {k!r} is not an index of it.",
                                 f"use an index from 0 to {len(node) - 1}.")
            k = int(k)
        elif not isinstance(node, dict):
            raise InputError(where, f"{'.'.join(keys[:depth])!r} is a value, not a table.",
                             "check the key.")
        path.append(k)
        if depth == len(keys) - 1:
            node[k] = value
        else:
            node = node.setdefault(k, {}) if isinstance(node, dict) else node[k]
    return tuple(path)


def overrides_as_text(overrides: Mapping | Sequence[str], source: str | None = None
                      ) -> list[Override]:
    """`key=value` overrides from a nested mapping ({"model": {"tissue": "continuum"}}: tables
    are merged key by key, any other value, a list of tables too, replaces the scene's), so
    that Python callers and --config files take the path of --set; strings pass through.
    Each remembers its source: `source` if given, else `overrides["model"]["tissue"]`."""
    if not isinstance(overrides, Mapping):
        return [Override(text, source) for text in overrides]

    def flatten(prefix: tuple, node: Mapping):
        for key, value in node.items():
            if isinstance(value, Mapping):
                yield from flatten((*prefix, key), value)
            else:
                label = source or "overrides" + "".join(f'["{k}"]' for k in (*prefix, key))
                yield Override(f"{'.'.join((*prefix, key))}={toml_value(value)}", label)

    return list(flatten((), overrides))


def toml_value(value) -> str:
    """A Python value written as a TOML value (a mapping as an inline table)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{toml_value(str(k))} = {toml_value(v)}"
                               for k, v in value.items()) + "}"
    if isinstance(value, list | tuple):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, Path):
        return toml_value(str(value))
    return repr(float(value)) if isinstance(value, float) else repr(value)


# --- relative paths ----------------------------------------------------------------------------

#: The keys of a scene that name files: (key path, "*" for every list entry; True if the value
#: is always a path, False if it may also be a built-in's name).
PATH_KEYS = ((("section", "file"), False), (("section", "mesh", "size_map"), True),
             (("indenters", "*", "file"), False), (("materials", "set"), False),
             (("output", "receptors"), False))


def anchor_paths(data: dict, folder: Path) -> dict:
    """`data` (a scene file's or a --config file's tables) with its relative file paths made
    relative to `folder`, the file's own folder, so that the file means the same from any
    working directory. Built-in names (`cylinder`) stay names. In place; returns `data`."""
    for keys, always in PATH_KEYS:
        for parent, key in _holders(data, keys):
            value = parent[key]
            if isinstance(value, str) and value and not Path(value).is_absolute():
                candidate = folder / value
                if always or Path(value).suffix == ".toml" or candidate.is_file():
                    parent[key] = str(candidate)
    return data


def _holders(node, keys: tuple):
    """(table, key) of every value at `keys` in `node` ("*": each entry of a list)."""
    *head, last = keys
    nodes = [node]
    for k in head:
        nodes = [n for n in nodes if isinstance(n, Mapping) and k in n] if k != "*" else nodes
        nodes = ([e for n in nodes if isinstance(n, list) for e in n] if k == "*"
                 else [n[k] for n in nodes])
    return [(n, last) for n in nodes if isinstance(n, dict) and last in n]


# --- loading, and naming the source of a bad value ------------------------------------------


def load_scene(source: str | Path, overrides: Mapping | Sequence[str] = (),
               spacing: float | None = None) -> Scene:
    """Read a scene file, apply overrides and validate everything.

    Parameters
    ----------
    source : str or Path
        A built-in scene's name (``"1pt"``, ``"line-load"``, ...) or a scene TOML file. Relative
        paths inside a file are read from its folder.
    overrides : mapping or sequence of str, optional
        A nested mapping of tables (``{"model": {"subcutaneous": "drained"}}``) or ``key=value``
        strings (``["protocol.depth=0.5"]``), merged key by key; a list given whole replaces
        the scene's list.
    spacing : float or None, optional
        Centre spacing (mm) of a two-indenter scene (the two-point test); None: the file's.

    Returns
    -------
    Scene
        The validated scene.

    Raises
    ------
    InputError
        For any bad value; the message names where it came from (the scene file, a file it
        names, ``--set``, ``--config FILE`` or the Python override), the key and the fix.
    """
    if not isinstance(source, str | Path):
        raise InputError(f"load_scene({source!r})", "is not a scene's name or file.",
                         'give a built-in scene\'s name ("1pt") or a path to a .toml file.')
    if isinstance(overrides, str) or not isinstance(overrides, Mapping | Sequence):
        raise InputError(f"overrides={overrides!r}", "is not a table or a list of overrides.",
                         'give {"protocol": {"depth": 0.5}} or ["protocol.depth=0.5"].')
    path = scene_path(source)
    data = anchor_paths(read_toml(path), path.parent)
    sources = {leaf: str(path) for leaf in _leaves(data)}
    changes = overrides_as_text(overrides)
    if spacing is not None:
        changes.append(Override(f"spacing={toml_value(spacing)}", f"spacing {spacing:g}"))
    for text in changes:
        keys = apply_override(data, text)
        _replace_sources(sources, keys, _leaves(_at(data, keys)), text.source)
    return scene_from_dict(data, where=str(path), sources=sources, changes=tuple(changes))


def _leaves(node, prefix: tuple = ()) -> list[tuple]:
    """The key paths of the values in `node` (into tables, and lists of tables by index)."""
    if isinstance(node, Mapping):
        return [leaf for k, v in node.items() for leaf in _leaves(v, (*prefix, k))]
    if isinstance(node, list) and node and all(isinstance(v, Mapping) for v in node):
        return [leaf for i, v in enumerate(node) for leaf in _leaves(v, (*prefix, i))]
    return [prefix]


def _at(data, keys: tuple):
    for k in keys:
        data = data[k]
    return data


def _replace_sources(sources: dict, keys: tuple, leaves: list[tuple], source: str) -> None:
    """An override at `keys` replaces whatever was below it, and names its own source."""
    for old in [p for p in sources if p[:len(keys)] == keys]:
        del sources[old]
    for leaf in leaves:
        sources[(*keys, *leaf)] = source


def blamed(scene: Scene, error: InputError) -> InputError:
    """`error`, found after loading (e.g. an indenter that never reaches the skin), with its
    `where` naming the override it comes from, if one of the scene's `changes` set it."""
    sources = {}
    for text in scene.changes:
        keys, value = parse_override(text)
        keys = tuple(int(k) if k.isdigit() else k for k in keys)
        _replace_sources(sources, keys, _leaves(value), Override(text).source)
    return _Blame(sources, "", scene.name).rewritten(error, None)


class _Blame:
    """Rewrites an `InputError` raised while a table is built so that its `where` names the
    source of the value at fault (sources: key path -> source). The value is found by the keys
    the message names: the source whose key path shares the longest beginning with them (the
    latest-applied on a tie). A value no key of the scene set came from a file the scene names
    (a materials set, a section, an indenter file), which the message already names."""

    def __init__(self, sources: dict, file: str, name: str):
        self.sources, self.file, self.name = sources, file, name
        self.order = {s: i for i, s in enumerate(dict.fromkeys(sources.values()))}

    @contextmanager
    def __call__(self, table: str | None):
        try:
            yield
        except InputError as error:
            raise self.rewritten(error, table) from None

    def rewritten(self, error: InputError, table: str | None) -> InputError:
        rest = self._key_part(error.where)
        words = [w for w in re.split(r"[.:\[\],\s]+", re.sub(r"\([^)]*\)", "", rest)) if w]
        if words[:1] == ["scene"]:  # the scene's own keys, the tables
            rest, words = rest.removeprefix("scene.").removeprefix("scene"), words[1:]
        elif words and words[0] in TABLES:
            table, words = words[0], words[1:]
            rest = rest.removeprefix(f"{table}: ")  # `model: model.tissue` says it twice
            words = words[1:] if words[:1] == [table] else words
        elif table is not None and rest:
            rest = f"{table}.{rest}"
        elif table is not None:
            rest = table
        source = self._latest(self._source(table, words), *(
            self._source(path.split(".")[0], path.split(".")[1:])
            for path in error.also))  # other keys the error names
        kind = self.sources.get((table, "kind")) if "unknown key" in error.problem else None
        if kind is not None and (source is None or self.order[kind] > self.order[source]):
            # keys the table's new kind does not take: the change of kind is at fault (a
            # `--set protocol.kind=...` keeps the file's ramp-hold keys), not the file
            return InputError(f"{kind}: {rest}", error.problem,
                              f"{error.fix.removesuffix(' (check the spelling).')}; a new kind "
                              f"keeps the scene's other {table} keys: give the {table} table "
                              "whole, e.g. --set '" + table + "={kind = ..., ...}'.")
        if source is None:
            return error
        return InputError(f"{source}: {rest}", error.problem, error.fix)

    def _latest(self, *sources: str | None) -> str | None:
        """The latest-applied of `sources` (a --set over a --config over the file)."""
        given = [s for s in sources if s is not None]
        return max(given, key=self.order.__getitem__) if given else None

    def _key_part(self, where: str) -> str:
        """`where` without the file or scene name it starts with."""
        rest = re.sub(r"^.*?\.toml(?::\s+|,\s*key\s+|$)", "", where, count=1)
        return rest.removeprefix(f"{self.name}: ")

    def _source(self, table: str | None, words: list[str]) -> str | None:
        best, score = None, (-1, -1)
        head = () if table is None else (table,)
        for keys, source in self.sources.items():
            if keys[:len(head)] != head:
                continue
            inner = [str(k) for k in keys[len(head):]]
            common = next((i for i, (a, b) in enumerate(zip(inner, words)) if a != b),
                          min(len(inner), len(words)))
            if common or not inner or not words:
                if (common, self.order[source]) > score:
                    best, score = source, (common, self.order[source])
        return best


def scene_from_dict(data: dict, where: str = "scene", sources: dict | None = None,
                    changes: tuple[str, ...] = ()) -> Scene:
    """A scene from the tables of a scene file. With `sources` (key path -> where the value
    came from, `load_scene` makes it), errors name the source of the bad value."""
    name = str(data.get("name", Path(where).stem))
    context = _Blame(sources or {}, where, name)
    with context(None):
        check_keys(f"{where}: scene", data, TABLES, what="table")
    with context("section"):
        section_data = dict(data.get("section", {}))
        source = section_data.pop("file", "male-index")
        _named_file("sections", source, "section", f"{where}: section.file")
        loader = load_fingertip3d if section_dimension(source) == 3 else load_section
        section = loader(source, overrides=section_data)
    with context("indenters"):
        indenters = _indenters(data, where)
    with context("protocol"):
        history = history_from_dict(data.get("protocol", {}), where=f"{where}: protocol")
    with context("materials"):
        materials = _materials(data.get("materials", {}), f"{where}: materials")
    tables = {"harmonic": None}
    for table, cls in (("model", ModelOptions), ("steps", StepOptions), ("output", Outputs),
                       ("accuracy", Accuracy), ("harmonic", HarmonicOptions)):
        if table in data or table != "harmonic":  # no [harmonic]: no frequency response
            with context(table):
                tables[table] = _options(cls, data.get(table, {}), f"{where}: {table}")
    with context("solver"):
        petsc_options = _petsc_options(data.get("solver", {}), f"{where}: solver")
    with context(None):
        return Scene(
            name=name, description=str(data.get("description", "")), section=section,
            indenters=indenters, history=history, materials=materials, model=tables["model"],
            steps=tables["steps"], petsc_options=petsc_options,
            linear=data.get("solver", {}).get("linear", "direct"), outputs=tables["output"],
            accuracy=tables["accuracy"],
            harmonic=tables["harmonic"], changes=changes)


def _indenters(data: dict, where: str) -> list[Indenter]:
    indenters, tables = [], data.get("indenters", [])
    if not isinstance(tables, list):
        raise InputError(f"{where}: indenters", f"must be a list of tables, got {tables!r}.",
                         'write indenters = [{file = "cylinder", radius = 5.0}].')
    for i, table in enumerate(tables):
        if not isinstance(table, Mapping):
            raise InputError(f"{where}: indenters[{i}]", f"must be a table, got {table!r}.",
                             'write {file = "cylinder", radius = 5.0}: a file and sizes.')
        table = dict(table)
        base = table.pop("file", None)
        if base is not None:
            try:
                builtin = load_indenter(base)
            except InputError as error:
                raise InputError(f"{where}: indenters[{i}].file",  # and the file's own key
                                 f"{error.where}: {error.problem}", error.fix) from None
            table = dataclasses.asdict(builtin) | {"shape": builtin.shape} | table
        indenters.append(make_indenter(table, where=f"{where}: indenters[{i}]"))
    if "spacing" in data:
        indenters = _pair(indenters, data["spacing"], f"{where}: spacing")
    return indenters


def _pair(indenters: list[Indenter], spacing, where: str) -> list[Indenter]:
    """Two copies of the one indenter at x = ±spacing/2 (the two-point test)."""
    spacing = positive(where, spacing, "mm")  # a NaN or inf, too, is no spacing
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
    return check_petsc_options(options | dict(extra), where)


def _materials(data: Mapping, where: str) -> Tissues:
    """`[materials]`: `set` names a materials file; the other tables override its values."""
    if not isinstance(data, Mapping):
        raise InputError(where, f"must be a table, got {data!r}.", "write [materials].")
    data = dict(data)
    source = data.pop("set", DEFAULT_SET)
    _named_file("materials", source, "materials set", f"{where}.set")
    return load_materials(source, overrides=data)


def _named_file(kind: str, source, what: str, where: str) -> None:
    """A file a scene names must exist; the error names the scene's key, not only the file."""
    if not isinstance(source, str | Path):
        raise InputError(where, f"must be a file name, got {source!r}.",
                         f"give a built-in {what}'s name or a path to a .toml file.")
    try:
        find(kind, source, what)
    except InputError as error:
        raise InputError(where, f"{source}: {error.problem}", error.fix) from None


def _options(cls, data: Mapping, where: str):
    """An options dataclass from a table: unknown keys and impossible values named."""
    check_keys(where, data, [f.name for f in dataclasses.fields(cls)], what="option")
    try:
        return cls(**data)
    except InputError as error:
        raise InputError(f"{where}: {error.where}", error.problem, error.fix) from None
    except (TypeError, ValueError) as error:
        problem = str(error).rstrip(".") + "."  # a sentence, before the "Fix:"
        raise InputError(where, problem, "check the values.") from None


# --- the record -----------------------------------------------------------------------------


def scene_record(scene: Scene) -> dict:
    """The scene as plain data, in the scene file's own tables (for summary.json)."""
    return _plain({
        "name": scene.name,
        "description": scene.description,
        "section": dataclasses.asdict(scene.section),
        "indenters": [_indenter_record(i) for i in scene.indenters],
        "materials": scene.materials.record(),
        "protocol": _protocol_record(scene.history),
        "model": dataclasses.asdict(scene.model),
        "steps": _steps_record(scene.steps),
        "solver": {"linear": scene.linear, **scene.petsc_options},
        "output": dataclasses.asdict(scene.outputs),
        "accuracy": dataclasses.asdict(scene.accuracy),
    } | ({} if scene.harmonic is None else {"harmonic": dataclasses.asdict(scene.harmonic)}))


def _steps_record(steps) -> dict:
    """The `[steps]` table; `tangent_start`, `tangent_reuse`, `jacobian_carry`,
    `factor_reuse` and `hold_factor_reuse` only where they are on (a scene without them has the
    record it had before the options existed: its runs resume)."""
    table = dataclasses.asdict(steps)
    for key in ("tangent_start", "tangent_reuse", "jacobian_carry", "factor_reuse",
                "hold_factor_reuse"):
        if not table[key]:
            del table[key]
    return table


def _indenter_record(indenter: Indenter) -> dict:
    """An indenter's table; `friction` only where it is not 0 and a grating's `depth` only
    where it is finite (the record is the one it had before these keys: its runs still
    resume, and JSON gets no infinity)."""
    table = {"shape": indenter.shape, **dataclasses.asdict(indenter)}
    if table["friction"] == 0:
        del table["friction"]
    if table.get("depth") == math.inf:
        del table["depth"]
    return table


def _protocol_record(history) -> dict:
    """The `[protocol]` table of `history` (a tangential path: its normal protocol's table with
    the `tangential` points, and their `direction` where it is not +x: the record of a path
    along x is the one it had before the key), as `loading.history_from_dict` reads it back."""
    if isinstance(history, TangentialPath):
        path = history.tangential
        table = {"times": path.times, "values": path.values}
        if history.direction != (1.0, 0.0):
            table["direction"] = history.direction
        force = history.normal_force  # force control: its target (no key without it)
        held = {} if force is None else {"normal_force": dataclasses.asdict(force)}
        return _protocol_record(history.normal) | {"tangential": table} | held
    kind = next((k for k, cls in KINDS.items() if isinstance(history, cls)), type(history).__name__)
    return {"kind": kind, **{f.name: getattr(history, f.name)
                             for f in dataclasses.fields(history) if f.init}}


def _plain(value):
    """Tuples as lists, numbers as numbers: JSON-ready."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    return value
