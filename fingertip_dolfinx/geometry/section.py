"""The fingertip cross-section as validated data, read from TOML files (built in:
`fingertip_dolfinx/data/sections/`).

Conventions (docs/DESIGN.md): lengths in mm, the origin at the centre of the outer ellipse, `x`
across the finger, `y` from the pulp (`y < 0`) to the nail (`y > 0`).

Layers, from outside in:
- the **nail** is a plate of constant thickness lying on the skin, *outside* the outer ellipse:
  the region between the outer ellipse and its outward parallel curve at the nail thickness,
  over the dorsal arc whose polar angles (measured at the origin) lie within `nail.half_angle`
  of `+y`; its two ends are cut along the surface normal;
- the **skin** is the layer between the outer ellipse and its inward parallel (offset) curve at
  the skin thickness, so it is equally thick everywhere, not a smaller ellipse;
- the **subcutaneous** tissue fills the rest, around the elliptic **bone**.
The **pulp surface** is the arc of the outer surface whose polar angles lie within
`pulp.half_angle` of `-y` (90 deg: the whole palmar half, `y < 0`).

Every value is checked on construction; a bad one raises `InputError` naming the key and the fix.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.integrate import quad
from scipy.optimize import brentq

from ..datafiles import builtin_dir, find, read_toml
from ..errors import InputError

#: The built-in sections (inside the package: `fingertip_dolfinx/data/sections/`).
SECTIONS_DIR = builtin_dir("sections")

# Thinnest subcutaneous layer allowed between the bone and the skin: thinner is not a tissue
# layer one can mesh sensibly, and it hides a geometry that is almost certainly a typo.
MIN_TISSUE_GAP = 0.1


def _is_number(value) -> bool:
    """A finite int or float; bool is an int in Python: `thickness = true` must not pass as 1."""
    return (isinstance(value, int | float) and not isinstance(value, bool)
            and math.isfinite(value))


def _number(where: str, value) -> float:
    if not _is_number(value):
        raise InputError(where, f"must be a finite number, got {value!r}.", "write a number.")
    return float(value)


def _positive(where: str, value: float, unit: str = "mm") -> None:
    if not value > 0:
        raise InputError(where, f"must be positive, got {value} {unit}.", "use a size > 0.")


@dataclass(frozen=True)
class Ellipse:
    """Axis-aligned ellipse x = a cos u, y = cy + b sin u (u: the parametric angle)."""

    a: float  # semi-axis along x (half the width), mm
    b: float  # semi-axis along y (half the height), mm
    cy: float = 0.0  # centre's y, mm

    @property
    def area(self) -> float:
        return math.pi * self.a * self.b

    def point(self, u):
        u = np.asarray(u, dtype=float)
        return np.stack([self.a * np.cos(u), self.cy + self.b * np.sin(u)], axis=-1)

    def normal(self, u):
        """Outward unit normal at parameter u."""
        u = np.asarray(u, dtype=float)
        n = np.stack([self.b * np.cos(u), self.a * np.sin(u)], axis=-1)
        return n / np.linalg.norm(n, axis=-1, keepdims=True)

    def normal_angle(self, u: float) -> float:
        return math.atan2(self.a * math.sin(u), self.b * math.cos(u))

    def param_at_polar(self, theta: float) -> float:
        """Parameter u of the point seen from the centre at polar angle theta (rad, from +x)."""
        return math.atan2(self.a * math.sin(theta), self.b * math.cos(theta))

    def arc_length(self, u0: float, u1: float) -> float:
        # The integrand is smooth and periodic: adaptive quadrature reaches round-off.
        speed = lambda u: math.hypot(self.a * math.sin(u), self.b * math.cos(u))  # noqa: E731
        return quad(speed, u0, u1, epsabs=0.0, epsrel=1e-12, limit=200)[0]

    @property
    def perimeter(self) -> float:
        return self.arc_length(0.0, 2 * math.pi)

    @property
    def min_curvature_radius(self) -> float:
        return min(self.a, self.b) ** 2 / max(self.a, self.b)

    def below_palmar(self, x, depth: float) -> np.ndarray:
        """Points (n, 2) at `depth` (mm) below the palmar (lower) points of abscissae `x`,
        along the inward normals: where the depth curves of the outputs run."""
        x = np.atleast_1d(np.asarray(x, dtype=float))
        y = self.cy - self.b * np.sqrt(np.clip(1 - (x / self.a) ** 2, 0.0, None))
        normal = np.column_stack([x / self.a**2, (y - self.cy) / self.b**2])
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        return np.column_stack([x, y]) - depth * normal

    def contains(self, points) -> np.ndarray:
        p = np.atleast_2d(points)
        return (p[:, 0] / self.a) ** 2 + ((p[:, 1] - self.cy) / self.b) ** 2 < 1.0

    def distance(self, points, iterations: int = 30) -> np.ndarray:
        """Unsigned distance from points (n, 2) to the ellipse, to round-off.

        Start from the nearest of many samples, then Newton on d/du |P(u) - p|^2 = 0.
        """
        p = np.atleast_2d(np.asarray(points, dtype=float))
        samples = np.linspace(0.0, 2 * math.pi, 2048, endpoint=False)
        sq = ((self.point(samples)[None, :, :] - p[:, None, :]) ** 2).sum(axis=-1)
        u = samples[np.argmin(sq, axis=1)]
        x, y = p[:, 0], p[:, 1] - self.cy
        for _ in range(iterations):
            c, s = np.cos(u), np.sin(u)
            # g = (P - p) . P', g' = |P'|^2 + (P - p) . P''
            g = (self.a * c - x) * (-self.a * s) + (self.b * s - y) * (self.b * c)
            dg = (self.a * s) ** 2 + (self.b * c) ** 2 - (self.a * c - x) * self.a * c
            dg -= (self.b * s - y) * self.b * s
            u = u - g / dg
        return np.linalg.norm(self.point(u) - p, axis=1)


@dataclass(frozen=True)
class Nail:
    thickness: float = 0.6  # mm, constant, normal to the outer surface
    half_angle: float = 60.0  # deg, polar half-angle of the covered dorsal arc, about +y
    centre_half_width: float = 0.25  # mm, half-width in x of the held patch atop the nail


@dataclass(frozen=True)
class MeshOptions:
    """Target element sizes (mm) and element kind of a section's mesh; checked on construction.

    Parameters
    ----------
    min_size : float, optional
        Size in the refinement zone under the pulp, where indenters act.
    max_size : float, optional
        Size everywhere else in the soft tissue, skin and nail.
    bone_size : float, optional
        Size deep inside the (nearly rigid) bone.
    refine_half_width, refine_depth : float, optional
        The refinement zone: |x| below this on the pulp surface, down to this depth under it.
    quadrilateral : bool, optional
        Recombine into quadrilaterals (Q2/Q1) instead of triangles.
    tips : tuple of float, optional
        x of the pulp points where a sharp indenter tip acts: each gets a disc of radius
        `tip_zone` meshed at `tip_size`, with a mesh vertex exactly at the point.
    tip_size, tip_zone : float, optional
        Size (below the tip radius) and radius of those discs.
    spots : tuple of (float, float), optional
        (x, depth) points where a key output peaks inside the tissue: each gets a disc of radius
        `spot_zone` meshed at `spot_size`.
    spot_size, spot_zone : float, optional
        Size and radius of those discs.
    size_map : str, optional
        An .npz size map (points and sizes, written by the adaptive loop): the size there, where
        finer than the fields above; ``""``: none.
    """

    min_size: float = 0.1  # in the refinement zone under the pulp, where indenters act
    max_size: float = 0.4  # everywhere else in the soft tissue, skin and nail
    bone_size: float = 1.0  # deep inside the (nearly rigid) bone
    refine_half_width: float = 4.0  # zone: |x| < this on the pulp surface ...
    refine_depth: float = 2.0  # ... and down to this depth under it
    quadrilateral: bool = False  # recombine into quadrilaterals (Q2/Q1) instead of triangles
    #: x (mm) of the pulp points where a sharp indenter tip acts: each gets a disc of radius
    #: tip_zone meshed at tip_size (a tip narrower than the surface elements slips between
    #: the contact quadrature points). A mesh vertex sits exactly at each such point.
    tips: tuple[float, ...] = ()
    tip_size: float = 0.02  # mm, below the tip radius (the paper's wedge: 25 µm)
    tip_zone: float = 0.25  # mm, radius of the disc meshed at tip_size around each tip point
    #: (x, depth) pairs (mm; depth below the undeformed outer surface along its inward
    #: normal, as the output depth curves) where a key output peaks inside the tissue: each
    #: gets a disc of radius spot_zone meshed at spot_size, growing to the sizes around it at
    #: the rate of the other fields. The line load's SED peak at 0.75 mm under the wedge
    #: needs 0.05 mm there, not everywhere (docs: README "Asking for an accuracy").
    spots: tuple[tuple[float, float], ...] = ()
    spot_size: float = 0.05  # mm
    spot_zone: float = 0.3  # mm, the disc's radius
    #: An .npz file of a size map (`mesh.SizeMap`: points and target sizes, written by the
    #: adaptive loop, `studies.adaptivity`): the size there, where finer than the fields
    #: above. "": none.
    size_map: str = ""

    def __post_init__(self):
        for key in ("min_size", "max_size", "bone_size", "refine_half_width", "refine_depth",
                    "tip_size", "tip_zone", "spot_size", "spot_zone"):
            _positive(f"mesh.{key}", _number(f"mesh.{key}", getattr(self, key)))
        if isinstance(self.tips, int | float) or not all(_is_number(x) for x in self.tips):
            raise InputError("mesh.tips", f"must be a list of x positions (mm), got {self.tips!r}.",
                             "write e.g. tips = [0.0].")
        object.__setattr__(self, "tips", tuple(float(x) for x in self.tips))
        self._check_spots()
        if self.tips and self.tip_size > self.min_size:
            raise _related(InputError(
                "mesh.tip_size", f"{self.tip_size} mm is coarser than mesh.min_size = "
                f"{self.min_size} mm: tip refinement must be finer.",
                "make tip_size <= min_size (or leave tips empty)."), "min_size")
        if self.max_size < self.min_size:
            raise _related(InputError(
                "mesh.max_size",
                f"{self.max_size} mm is smaller than mesh.min_size = {self.min_size} mm.",
                "make max_size >= min_size.",
            ), "min_size")
        if self.bone_size < self.max_size:
            raise _related(InputError(
                "mesh.bone_size",
                f"{self.bone_size} mm is smaller than mesh.max_size = {self.max_size} mm: the "
                "bone is nearly rigid and is meshed coarser than the soft tissue.",
                "make bone_size >= max_size.",
            ), "max_size")
        if self.spots and self.spot_size > self.min_size:
            raise InputError("mesh.spot_size", f"{self.spot_size} mm is coarser than "
                             f"mesh.min_size = {self.min_size} mm: a spot must be finer.",
                             "make spot_size <= min_size (or leave spots empty).")
        if not isinstance(self.size_map, str):
            raise InputError("mesh.size_map", f"must be a file name, got {self.size_map!r}.",
                             'write a path in quotes, or "" for none.')
        if self.size_map and not Path(self.size_map).is_file():
            raise InputError("mesh.size_map", f"{self.size_map}: no such file.",
                             "give the size_map.npz of an adaptive run (DIR/level-<k>/), or \"\".")
        if not isinstance(self.quadrilateral, bool):
            raise InputError(
                "mesh.quadrilateral",
                f"must be true or false, got {self.quadrilateral!r}.",
                "write true or false (lower case, no quotes).",
            )

    def _check_spots(self):
        pairs = self.spots
        ok = not isinstance(pairs, str | dict) and all(
            isinstance(p, list | tuple) and len(p) == 2 and all(_is_number(v) for v in p)
            and p[1] > 0 for p in pairs)
        if not ok:
            raise InputError("mesh.spots", f"must be a list of [x, depth] pairs (mm, depth > 0), "
                             f"got {pairs!r}.", "write e.g. spots = [[0.0, 0.75]].")
        object.__setattr__(self, "spots", tuple((float(x), float(d)) for x, d in pairs))


@dataclass(frozen=True)
class Section:
    """A validated fingertip cross-section (all lengths mm, angles deg).

    The skin is the layer between the outer ellipse and its inward parallel curve at the skin
    thickness; the subcutaneous tissue fills the rest around the bone; the nail is a plate on the
    dorsal arc. Every value is checked on construction.

    Parameters
    ----------
    outer : Ellipse, optional
        The outer surface (semi-axes 8 × 7 mm by default).
    skin_thickness : float, optional
        The skin's thickness (0.8 mm: Wu et al. 2004).
    bone : Ellipse, optional
        The distal phalanx, off centre towards the nail.
    nail : Nail, optional
        The nail plate: thickness and the half-angle of the dorsal arc it covers.
    pulp_half_angle : float, optional
        The pulp surface is the arc within this angle of −y (90: the whole palmar half).
    mesh : MeshOptions, optional
        The mesh sizes.
    name : str, optional
        The section's name (its file name).

    Raises
    ------
    InputError
        If a layer does not fit (e.g. the bone leaves the subcutaneous tissue), naming the fix.
    """

    outer: Ellipse = Ellipse(8.0, 7.0)
    skin_thickness: float = 0.8
    bone: Ellipse = Ellipse(3.5, 2.0, 2.0)
    nail: Nail = Nail()
    pulp_half_angle: float = 90.0
    mesh: MeshOptions = field(default_factory=MeshOptions)
    name: str = "custom"

    def __post_init__(self):
        self._check_sizes()
        self._check_angles()
        self._check_skin()
        self._check_bone()
        self._check_refinement_zone()

    # --- validation, one check (and one message) per kind of mistake ---

    def _check_sizes(self):
        for where, value in [
            ("outer.width", 2 * self.outer.a), ("outer.height", 2 * self.outer.b),
            ("skin.thickness", self.skin_thickness),
            ("bone.width", 2 * self.bone.a), ("bone.height", 2 * self.bone.b),
            ("nail.thickness", self.nail.thickness),
            ("nail.centre_half_width", self.nail.centre_half_width),
        ]:
            _positive(where, _number(where, value))
        _number("bone.centre_y", self.bone.cy)

    def _check_angles(self):
        nail = _number("nail.half_angle", self.nail.half_angle)
        if not 0 < nail < 90:
            raise InputError(
                "nail.half_angle",
                f"must lie strictly between 0 and 90 deg (polar half-angle of the dorsal arc "
                f"the nail covers), got {nail} deg.",
                "use e.g. 60.",
            )
        pulp = _number("pulp.half_angle", self.pulp_half_angle)
        if not 0 < pulp < 180 - nail:
            raise InputError(
                "pulp.half_angle",
                f"must lie strictly between 0 and 180 - nail.half_angle = {180 - nail} deg so "
                f"that the pulp neither vanishes nor reaches the nail, got {pulp} deg.",
                "use e.g. 90 (the palmar half, y < 0).",
            )
        u0, _ = self.nail_params
        x_end = self.nail_surface_point(u0)[0]
        if not self.nail.centre_half_width < x_end:
            raise InputError(
                "nail.centre_half_width",
                f"{self.nail.centre_half_width} mm reaches beyond the nail's end at x = "
                f"{x_end:.3f} mm.",
                "use a small patch, e.g. 0.25 mm.",
            )

    def _check_skin(self):
        # The inward parallel curve at distance t is a simple closed curve, and the skin area
        # t L - pi t^2 holds, only where t is below every radius of curvature (else it folds).
        r = self.outer.min_curvature_radius
        if not self.skin_thickness < r:
            raise InputError(
                "skin.thickness",
                f"{self.skin_thickness} mm is not smaller than the outer surface's smallest "
                f"radius of curvature {r:.3f} mm (min(a, b)^2 / max(a, b) of the outer ellipse): "
                "the skin would fill the section and its inner boundary fold on itself.",
                "use a thinner skin (the paper's is 0.8 mm) or a larger, rounder section.",
            )

    def _check_bone(self):
        u = np.linspace(0.0, 2 * math.pi, 720, endpoint=False)
        p = self.bone.point(u)
        outside = ~self.outer.contains(p)
        polar = np.degrees(np.arctan2(p[:, 0], p[:, 1]))  # from +y
        if np.any(outside & (np.abs(polar) <= self.nail.half_angle)):
            raise InputError(
                "bone",
                "the bone ellipse reaches through the skin into the nail plate.",
                "lower bone.centre_y or make the bone smaller.",
            )
        gap = np.where(outside, -1.0, self.outer.distance(p) - self.skin_thickness)
        if gap.min() < MIN_TISSUE_GAP:
            x, y = p[np.argmin(gap)]
            raise InputError(
                "bone",
                f"the bone ellipse leaves the subcutaneous tissue near ({x:.2f}, {y:.2f}) mm: it "
                f"must lie inside the skin's inner boundary with at least {MIN_TISSUE_GAP} mm of "
                "tissue to spare.",
                "make the bone smaller, move bone.centre_y, or enlarge the outer ellipse.",
            )

    def _check_refinement_zone(self):
        # The zone's ends (|x| = refine_half_width on the palmar surface) must lie on the pulp,
        # and so must the tip points.
        for x in self.mesh.tips:
            if not abs(x) < self.mesh.refine_half_width:
                raise InputError(
                    "mesh.tips", f"the tip point x = {x} mm lies outside the refinement zone "
                    f"|x| < refine_half_width = {self.mesh.refine_half_width} mm.",
                    "put indenters inside the refinement zone or widen it.",
                )
        w = self.mesh.refine_half_width
        theta_end = math.radians(270.0 - self.pulp_half_angle)  # left end of the pulp arc
        x_pulp = abs(self.outer.point(self.outer.param_at_polar(theta_end))[0])
        if self.pulp_half_angle >= 90.0:
            x_pulp = self.outer.a
        if not w < x_pulp:
            raise InputError(
                "mesh.refine_half_width",
                f"{w} mm reaches beyond the pulp surface, which ends at |x| = {x_pulp:.3f} mm.",
                "use a smaller half-width or a larger pulp.half_angle.",
            )

    # --- derived geometry (parameters u on the outer ellipse) ---

    @property
    def nail_params(self) -> tuple[float, float]:
        """Parameters (right end, left end) of the nail's arc on the outer ellipse."""
        h = math.radians(self.nail.half_angle)
        right = self.outer.param_at_polar(math.pi / 2 - h)
        return right, math.pi - right  # mirror image about x = 0

    @property
    def pulp_params(self) -> tuple[float, float]:
        """Parameters (left end, right end) of the pulp arc, in increasing order."""
        h = math.radians(self.pulp_half_angle)
        left = self.outer.param_at_polar(1.5 * math.pi - h) % (2 * math.pi)
        return left, 3 * math.pi - left  # mirror image about x = 0: u -> pi - u

    @property
    def tip_params(self) -> tuple[float, ...]:
        """Parameters of the palmar points at the tip positions x = mesh.tips."""
        return tuple(2 * math.pi - math.acos(x / self.outer.a) for x in self.mesh.tips)

    @property
    def refine_params(self) -> tuple[float, float]:
        """Parameters of the palmar points with x = -/+ refine_half_width."""
        c = self.mesh.refine_half_width / self.outer.a
        return math.pi + math.acos(c), 2 * math.pi - math.acos(c)

    def nail_surface_point(self, u: float) -> np.ndarray:
        """Point of the nail's outer surface above the outer-ellipse point of parameter u."""
        return self.outer.point(u) + self.nail.thickness * self.outer.normal(u)

    @property
    def nail_centre(self) -> np.ndarray:
        return self.nail_surface_point(math.pi / 2)

    @property
    def nail_patch_params(self) -> tuple[float, float]:
        """Parameters whose nail-surface points have x = +/- nail.centre_half_width."""
        w = self.nail.centre_half_width
        u_end, _ = self.nail_params
        right = brentq(lambda u: self.nail_surface_point(u)[0] - w, u_end, math.pi / 2, xtol=1e-15)
        return right, math.pi - right  # the section is symmetric about x = 0

    def exact_areas(self) -> dict[str, float]:
        """Areas (mm^2) of the four regions, to round-off.

        A convex curve of length L enclosing A has an inward parallel curve at distance t
        (t below every radius of curvature) enclosing A - t L + pi t^2; a band of width t
        outside an arc of length l turning by angle dpsi has area t l + t^2 dpsi / 2.
        """
        t, outer = self.skin_thickness, self.outer
        skin = t * outer.perimeter - math.pi * t**2
        u0, u1 = self.nail_params
        tn = self.nail.thickness
        turning = outer.normal_angle(u1) - outer.normal_angle(u0)
        nail = tn * outer.arc_length(u0, u1) + 0.5 * tn**2 * turning
        return {
            "skin": skin,
            "subcutaneous": outer.area - skin - self.bone.area,
            "bone": self.bone.area,
            "nail": nail,
        }


# --- reading TOML ---

# TOML table -> key -> (Section field path, converter); the single source of the file format.
_KEYS = {
    "outer": {"width": ("outer.a", 0.5), "height": ("outer.b", 0.5)},
    "skin": {"thickness": ("skin_thickness", 1.0)},
    "bone": {"width": ("bone.a", 0.5), "height": ("bone.b", 0.5), "centre_y": ("bone.cy", 1.0)},
    "nail": {
        "thickness": ("nail.thickness", 1.0),
        "half_angle": ("nail.half_angle", 1.0),
        "centre_half_width": ("nail.centre_half_width", 1.0),
    },
    "pulp": {"half_angle": ("pulp_half_angle", 1.0)},
    "mesh": {f.name: (f"mesh.{f.name}", None) for f in dataclasses.fields(MeshOptions)},
}


def section_path(source: str | Path) -> Path:
    """A built-in section by name (`male-index`) or a TOML file path."""
    return find("sections", source, "section")


def load_section(source: str | Path = "male-index", overrides: dict | None = None) -> Section:
    """Read and validate a section (with its ``[mesh]`` options) from a built-in name or a path.

    Parameters
    ----------
    source : str or Path, optional
        A built-in section's name (``"male-index"``) or a section TOML file. Keys left out keep
        the defaults of `Section` (those of ``male-index``).
    overrides : dict or None, optional
        Tables of a section file (``{"mesh": {"min_size": 0.05}}``); they win.

    Returns
    -------
    Section
        The validated section.
    """
    path = section_path(source)
    data = read_toml(path)
    # A 3D fingertip file (geometry3d.py) says `dimension = 3`; a 2D one may say 2.
    if data.pop("dimension", 2) != 2:
        raise InputError(f"{path}, key dimension", "is not 2: this is a 3D fingertip file, "
                         "not a 2D section.", "read it with geometry3d.load_fingertip3d "
                         "(`fingertip mesh` picks by itself), or use a 2D section file.")
    for table, values in (overrides or {}).items():
        if not isinstance(values, dict):
            raise InputError(f"section.{table}", "must be a table.", f"write [section.{table}].")
        data[table] = {**data.get(table, {}), **values}
    try:
        return section_from_dict(data, name=path.stem)
    except InputError as e:
        raise InputError(f"{path}, key {e.where}", e.problem, e.fix, e.also) from None


def section_from_dict(data: dict, name: str) -> Section:
    """A `Section` from the tables of a section file (`[outer]`, `[bone]`, `[nail]`, `[mesh]`
    and the top level, in the file's units), validated; `geometry3d` reads its 2D part so."""
    parts: dict[str, dict[str, object]] = {"outer": {}, "bone": {}, "nail": {}, "mesh": {}, "": {}}
    for table, values in data.items():
        if table not in _KEYS or not isinstance(values, dict):
            raise InputError(
                table, "is not a table of a section file.", f"use only [{'], ['.join(_KEYS)}]."
            )
        for key, value in values.items():
            if key not in _KEYS[table]:
                raise InputError(
                    f"{table}.{key}",
                    "is not a known key.",
                    f"[{table}] takes only: {', '.join(_KEYS[table])}.",
                )
            target, scale = _KEYS[table][key]
            if scale is not None:
                value = scale * _number(f"{table}.{key}", value)
            owner, _, attr = target.rpartition(".")
            parts[owner][attr] = value
    d = Section()
    return Section(
        outer=dataclasses.replace(d.outer, **parts["outer"]),
        bone=dataclasses.replace(d.bone, **parts["bone"]),
        nail=dataclasses.replace(d.nail, **parts["nail"]),
        mesh=MeshOptions(**parts["mesh"]),
        name=name,
        **parts[""],
    )


def _related(error: InputError, other: str) -> InputError:
    """`error` about a relation between two mesh sizes, marked as naming `other` too: a scene's
    error then names the override of either that came last (scene._Blame), not the file that
    gave the one a --set did not change."""
    error.also = (f"section.mesh.{other}",)
    return error
