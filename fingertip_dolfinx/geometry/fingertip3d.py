"""The 3D distal fingertip as validated data, read from TOML files with `dimension = 3`
(built in: `fingertip_dolfinx/data/sections/male-index-3d.toml`).

Conventions (docs/DESIGN.md): mm; x across the finger, y from the pulp (y < 0) to the nail,
z along the finger from the proximal cut (z = 0) towards the tip.

The shape is the 2D cross-section (`geometry.Section`, whose checks all apply) carried along z:
- the **outer surface** is the elliptic cylinder of the section's outer ellipse (semi-axes a, b)
  for 0 <= z <= L (`outer.cylinder_length`), closed by the half-ellipsoid of semi-axes
  (a, b, c = `outer.tip_length`) beyond z = L; the tip is at z = L + c;
- the **skin** is the layer within `skin.thickness` t of the outer surface (its inner surface is
  the inward parallel surface: exact on the cylinder, a loft on the cap, see mesh3d.py);
- the **bone** (distal phalanx) is the section's bone ellipse (centre_y off-centre towards the
  nail) at z = 0, shrinking linearly (an elliptic-cone frustum) to `taper` times its size at
  z = bone.length - bone.end_length, then closed by a half-ellipsoid of length `end_length`:
  it ends at z = `bone.length`, before the tip;
- the **nail** is the 2D nail plate (constant thickness, over the dorsal arc of half-angle
  nail.half_angle) extruded over nail.start_z <= z <= nail.end_z, on the cylindrical part;
- the **pulp surface** is the palmar half of the skin's outer surface, y < 0 (cylinder and cap).
`half = true` keeps only x >= 0 (the mid-sagittal plane x = 0 is tagged `symmetry`).

Every value is checked on construction; a bad one raises `InputError` naming the key and the fix.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from ..datafiles import read_toml
from ..errors import InputError
from ..validation import check_keys, number, positive
from .section import MIN_TISSUE_GAP, MeshOptions, Section, section_from_dict, section_path

#: The 3D keys of each table; every other key allowed is one of the 2D section's.
_KEYS_3D = {
    "outer": {"cylinder_length": "cylinder_length", "tip_length": "tip_length"},
    "bone": {"length": "bone_length", "taper": "bone_taper", "end_length": "bone_end_length"},
    "nail": {"start_z": "nail_start_z", "end_z": "nail_end_z"},
    "mesh": {"refine_z_min": "refine_z_min", "refine_z_max": "refine_z_max"},
}
#: The 2D section's keys a 3D file takes (pulp: always the palmar half y < 0 in 3D; no
#: quadrilaterals, sharp-tip discs or size maps in 3D yet).
_KEYS_2D = {
    "outer": ("width", "height"),
    "skin": ("thickness",),
    "bone": ("width", "height", "centre_y"),
    "nail": ("thickness", "half_angle", "centre_half_width"),
    "mesh": ("min_size", "max_size", "bone_size", "refine_half_width", "refine_depth"),
}
#: 3D meshes are coarser than 2D ones (a tetrahedral mesh at the 2D sizes has ~1e7 cells).
DEFAULT_MESH_3D = MeshOptions(min_size=0.4, max_size=1.0, bone_size=2.0)


@dataclass(frozen=True)
class Fingertip3D:
    """A validated 3D distal fingertip (mm): the 2D section carried along z, closed by a tip.

    x across the finger, y from the pulp to the nail, z along the finger from the proximal cut
    (z = 0). Every value is checked on construction.

    Parameters
    ----------
    section : Section, optional
        The cross-section carried along z (outer, skin, bone, nail, mesh).
    cylinder_length : float, optional
        L: the elliptic cylinder from z = 0 to z = L.
    tip_length : float, optional
        c: the cap's semi-axis along z; the tip is at z = L + c.
    bone_length : float, optional
        z of the bone's rounded end.
    bone_taper : float, optional
        The bone ellipse's size where its end cap starts, over its size at z = 0.
    bone_end_length : float, optional
        Length along z of the bone's half-ellipsoidal end.
    nail_start_z, nail_end_z : float, optional
        Where the nail plate starts and ends along z.
    refine_z_min, refine_z_max : float, optional
        The refinement zone's extent along z (under the pulp, |x| < ``mesh.refine_half_width``).
    half : bool, optional
        Keep only x >= 0, with the symmetry plane x = 0 (forces are then half the finger's).
    name : str, optional
        The fingertip's name (its file name).
    """

    #: The cross-section carried along z (a 2D section's tables: outer, skin, bone, nail, mesh).
    section: Section = field(default_factory=lambda: Section(mesh=DEFAULT_MESH_3D))
    cylinder_length: float = 14.0  # L: the elliptic cylinder from z = 0 to z = L
    tip_length: float = 7.0  # c: the cap's semi-axis along z; the tip is at z = L + c
    bone_length: float = 17.0  # z of the bone's rounded end
    bone_taper: float = 0.6  # bone ellipse's size where its end cap starts, over its size at z = 0
    bone_end_length: float = 2.0  # length along z of the bone's half-ellipsoidal end
    nail_start_z: float = 3.0  # z where the nail plate starts
    nail_end_z: float = 13.0  # z where it ends
    refine_z_min: float = 6.0  # refinement zone under the pulp: |x| < mesh.refine_half_width,
    refine_z_max: float = 16.0  # refine_z_min < z < refine_z_max, within mesh.refine_depth
    half: bool = False  # only x >= 0, with the symmetry plane x = 0
    name: str = "custom"  # set from the file's name

    def __post_init__(self):
        self._check_numbers()
        if not self.section.pulp_half_angle == 90.0:
            raise InputError("pulp.half_angle", "in 3D the pulp surface is the palmar half "
                             "(y < 0) of the skin; other angles are not supported.",
                             "leave [pulp] out of a 3D file.")
        self._check_skin()
        self._check_bone()
        self._check_nail()
        self._check_refinement_zone()

    # --- validation, one check (and one message) per kind of mistake ---

    def _check_numbers(self):
        for table, keys in _KEYS_3D.items():
            for key, attr in keys.items():
                check = positive if table in ("outer", "bone") else number
                check(f"{table}.{key}", getattr(self, attr))
        if not isinstance(self.half, bool):
            raise InputError("half", f"must be true or false, got {self.half!r}.",
                             "write half = true (x >= 0 only) or half = false.")

    def _check_skin(self):
        # The inward parallel surface at distance t is regular only where t is below every
        # principal radius of curvature; the smallest on the half-ellipsoid of semi-axes
        # p <= q <= r is p^2 / r (the cylinder's, min(a, b)^2 / max(a, b), is not smaller).
        axes = sorted((self.outer.a, self.outer.b, self.tip_length))
        r = axes[0] ** 2 / axes[2]
        if not self.section.skin_thickness < r:
            raise InputError(
                "skin.thickness", f"{self.section.skin_thickness} mm is not smaller than the "
                f"tip cap's smallest radius of curvature {r:.3f} mm (smallest semi-axis^2 / "
                "largest of outer width/2, height/2, tip_length): the skin's inner surface "
                "would fold on itself.",
                "use a thinner skin (Wu 2004: 0.8 mm) or a longer, rounder tip (outer.tip_length).")

    def _check_bone(self):
        if not self.bone_taper <= 1.0:
            raise InputError("bone.taper", f"must lie in (0, 1] (the bone narrows towards the "
                             f"tip), got {self.bone_taper}.", "use e.g. 0.6.")
        if not self.bone_end_length < self.bone_length:
            raise InputError("bone.end_length", f"{self.bone_end_length} mm is not shorter "
                             f"than bone.length = {self.bone_length} mm.",
                             "use a rounded end shorter than the bone, e.g. 2 mm.")
        if not self.bone_length < self.total_length:
            raise InputError("bone.length", f"{self.bone_length} mm reaches past the tip at "
                             f"z = {self.total_length} mm.", "use a shorter bone.")
        p = self.bone_surface_points()
        gap = np.where(self.contains(p), self.distance_to_outer(p) - self.section.skin_thickness,
                       -1.0)
        if gap.min() < MIN_TISSUE_GAP:
            x, y, z = p[np.argmin(gap)]
            raise InputError(
                "bone", f"the bone leaves the subcutaneous tissue near ({x:.2f}, {y:.2f}, "
                f"{z:.2f}) mm: it must lie inside the skin's inner surface with at least "
                f"{MIN_TISSUE_GAP} mm of tissue to spare.",
                "shorten bone.length, lower bone.taper, move bone.centre_y, or make the bone "
                "smaller.")

    def _check_nail(self):
        z0, z1 = self.nail_start_z, self.nail_end_z
        if not 0.0 <= z0 < z1:
            raise InputError("nail.start_z", f"must satisfy 0 <= nail.start_z < nail.end_z, got "
                             f"{z0} and {z1} mm.", "use e.g. start_z = 3, end_z = 14.")
        # (A nail ending exactly where the cap starts left a face gmsh could not mesh.)
        if not z1 < self.cylinder_length:
            raise InputError("nail.end_z", f"{z1} mm is not before the end of the cylindrical "
                             f"part at outer.cylinder_length = {self.cylinder_length} mm: the "
                             "nail plate lies on the cylinder only.",
                             "use end_z < outer.cylinder_length.")

    def _check_refinement_zone(self):
        z0, z1, w = self.refine_z_min, self.refine_z_max, self.section.mesh.refine_half_width
        if not 0.0 <= z0 < z1:
            raise InputError("mesh.refine_z_min", f"must satisfy 0 <= refine_z_min < "
                             f"refine_z_max, got {z0} and {z1} mm.",
                             "use e.g. refine_z_min = 6, refine_z_max = 16.")
        # The zone's corners (|x| = w, z = refine_z_max) must lie on the pulp surface.
        if not z1 < self.total_length or not w < self.outer_semi_axes(z1)[0]:
            raise InputError(
                "mesh.refine_z_max", f"the refinement zone's far corners (|x| = {w}, z = {z1}) "
                f"mm lie outside the pulp surface (the tip is at z = {self.total_length} mm).",
                "lower refine_z_max or mesh.refine_half_width.")

    # --- derived geometry ---

    @property
    def outer(self):
        return self.section.outer

    @property
    def total_length(self) -> float:
        return self.cylinder_length + self.tip_length

    def outer_semi_axes(self, z) -> tuple:
        """Semi-axes (along x, y) of the outer cross-section at z (0 beyond the tip)."""
        zeta = np.clip((np.asarray(z, dtype=float) - self.cylinder_length) / self.tip_length,
                       0.0, 1.0)
        s = np.sqrt(1.0 - zeta**2)
        return self.outer.a * s, self.outer.b * s

    @property
    def bone_cap_start(self) -> float:
        return self.bone_length - self.bone_end_length

    def bone_scale(self, z):
        """Size of the bone's cross-section at z over its size at z = 0."""
        z = np.asarray(z, dtype=float)
        z_e, k = self.bone_cap_start, self.bone_taper
        cone = 1.0 - (1.0 - k) * np.minimum(z, z_e) / z_e
        cap = np.sqrt(np.clip(1.0 - ((z - z_e) / self.bone_end_length) ** 2, 0.0, 1.0))
        return np.where(z <= z_e, cone, k * cap)

    def bone_surface_points(self, nz: int = 60, nu: int = 90) -> np.ndarray:
        """Points (n, 3) on the bone's lateral surface and rounded end."""
        z = np.linspace(0.0, self.bone_length, nz)
        u = np.linspace(0.0, 2 * math.pi, nu, endpoint=False)
        zz, uu = np.meshgrid(z, u, indexing="ij")
        s, bone = self.bone_scale(zz), self.section.bone
        return np.stack([s * bone.a * np.cos(uu), bone.cy + s * bone.b * np.sin(uu), zz],
                        axis=-1).reshape(-1, 3)

    def contains(self, points) -> np.ndarray:
        """Whether points (n, 3) lie strictly inside the outer surface (and z > 0)."""
        p = np.atleast_2d(points)
        zeta = np.maximum(p[:, 2] - self.cylinder_length, 0.0) / self.tip_length
        r2 = (p[:, 0] / self.outer.a) ** 2 + (p[:, 1] / self.outer.b) ** 2 + zeta**2
        return (r2 < 1.0) & (p[:, 2] >= 0.0)

    def distance_to_outer(self, points, spacing: float = 0.25) -> np.ndarray:
        """Distance (mm) from points (n, 3) to the outer surface (lateral and cap).

        The nearest of samples `spacing` apart: one lies within spacing / sqrt(2) of the foot
        point, so the result is too large by at most ~spacing^2 / (4 d) at distance d: 0.017 mm
        at the default spacing where it matters (d = skin + MIN_TISSUE_GAP = 0.9 mm).
        """
        from scipy.spatial import cKDTree

        a, b, L, c = self.outer.a, self.outer.b, self.cylinder_length, self.tip_length
        nu = math.ceil(self.outer.perimeter / spacing)
        u = np.linspace(0.0, 2 * math.pi, nu, endpoint=False)
        z = np.linspace(0.0, L, math.ceil(L / spacing) + 1)
        zz, uu = np.meshgrid(z, u, indexing="ij")
        lateral = np.stack([a * np.cos(uu), b * np.sin(uu), zz], axis=-1).reshape(-1, 3)
        th = np.linspace(0.0, 0.5 * math.pi, math.ceil(0.5 * math.pi * max(a, b, c) / spacing))
        tt, uu = np.meshgrid(th, u, indexing="ij")
        cap = np.stack([a * np.sin(tt) * np.cos(uu), b * np.sin(tt) * np.sin(uu),
                        L + c * np.cos(tt)], axis=-1).reshape(-1, 3)
        return cKDTree(np.concatenate([lateral, cap])).query(np.atleast_2d(points))[0]

    def exact_volumes(self) -> dict[str, float]:
        """Volumes (mm^3) of the four regions of the full model (halve them for `half`).

        Outer: pi a b L + (2/3) pi a b c. Bone: an elliptic-cone frustum pi a0 b0 h (1 + k +
        k^2) / 3 plus the half-ellipsoid (2/3) pi k^2 a0 b0 e. Nail: the 2D nail's area times
        its length. Skin, the parallel shell of thickness t under the outer surface S (open at
        z = 0, where the surface's normal lies in the plane): its volume is the integral over S
        of t - H t^2 + K t^3 / 3 (H mean, K Gauss curvature), i.e. (2D skin area) L on the
        cylinder and t A - t^2 M + (2 pi / 3) t^3 on the cap (Gauss-Bonnet: the half-ellipsoid's
        total Gauss curvature is 2 pi), with its area A and total mean curvature M by quadrature.
        """
        a, b, L, c = self.outer.a, self.outer.b, self.cylinder_length, self.tip_length
        t, areas2d = self.section.skin_thickness, self.section.exact_areas()
        area, mean = half_ellipsoid_area_and_mean_curvature(a, b, c)
        skin = areas2d["skin"] * L + t * area - t**2 * mean + 2 * math.pi * t**3 / 3
        bone, k = self.section.bone, self.bone_taper
        bone_volume = (math.pi * bone.a * bone.b * self.bone_cap_start * (1 + k + k * k) / 3
                       + 2 * math.pi * k * k * bone.a * bone.b * self.bone_end_length / 3)
        outer = math.pi * a * b * (L + 2 * c / 3)
        volumes = {
            "skin": skin,
            "subcutaneous": outer - skin - bone_volume,
            "bone": bone_volume,
            "nail": areas2d["nail"] * (self.nail_end_z - self.nail_start_z),
        }
        return {k: v / 2 if self.half else v for k, v in volumes.items()}


def half_ellipsoid_area_and_mean_curvature(a: float, b: float, c: float, n: int = 200):
    """Area and integral of the mean curvature H = (k1 + k2) / 2 over the half-ellipsoid
    x^2/a^2 + y^2/b^2 + z^2/c^2 = 1, z >= 0, by Gauss-Legendre quadrature in (theta, phi)
    (smooth periodic integrands: n = 200 points a direction reach round-off).

    With h = 1 / |(x/a^2, y/b^2, z/c^2)| (the distance from the centre to the tangent plane),
    H = h^3 (a^2 + b^2 + c^2 - |p|^2) / (2 a^2 b^2 c^2).
    """
    g, w = np.polynomial.legendre.leggauss(n)
    theta, wt = 0.25 * math.pi * (g + 1), 0.25 * math.pi * w  # [0, pi/2]
    phi, wp = math.pi * (g + 1), math.pi * w  # [0, 2 pi]
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    st, ct, sp, cp = np.sin(th), np.cos(th), np.sin(ph), np.cos(ph)
    p = np.stack([a * st * cp, b * st * sp, c * ct])
    d_theta = np.stack([a * ct * cp, b * ct * sp, -c * st])
    d_phi = np.stack([-a * st * sp, b * st * cp, np.zeros_like(st)])
    jac = np.linalg.norm(np.cross(d_theta, d_phi, axis=0), axis=0)
    h = 1.0 / np.sqrt((p[0] / a**2) ** 2 + (p[1] / b**2) ** 2 + (p[2] / c**2) ** 2)
    mean = h**3 * (a * a + b * b + c * c - (p**2).sum(axis=0)) / (2 * a * a * b * b * c * c)
    weights = np.outer(wt, wp)
    return float((weights * jac).sum()), float((weights * jac * mean).sum())


def ellipsoid_distance(points, axes, iterations: int = 200) -> np.ndarray:
    """Distance from points (n, 3) (relative to the centre) to the ellipsoid of semi-axes
    `axes`, to round-off.

    The nearest point is q_i = a_i^2 p_i / (s + a_i^2) for the largest root s > -min(a_i^2) of
    sum_i (a_i p_i / (s + a_i^2))^2 = 1 (Eberly, "Distance from a point to an ellipse, an
    ellipsoid, or a hyperellipsoid", 2013); the sum falls monotonically there: bisection.
    Points on the plane of the shortest axis (p_i = 0 for it) are not handled.
    """
    p = np.atleast_2d(np.asarray(points, dtype=float))
    a2 = np.asarray(axes, dtype=float) ** 2
    f = lambda s: (((np.sqrt(a2) * p) / (s[:, None] + a2)) ** 2).sum(axis=1) - 1.0  # noqa: E731
    lo = np.full(len(p), -a2.min() * (1 - 1e-15))
    hi = 2.0 * np.sqrt(a2.max()) * np.linalg.norm(p, axis=1) + 1.0
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        above = f(mid) > 0.0
        lo, hi = np.where(above, mid, lo), np.where(above, hi, mid)
    root = 0.5 * (lo + hi)
    return np.linalg.norm(p - a2 * p / (root[:, None] + a2), axis=1)


# --- reading TOML ---


def section_dimension(source) -> int:
    """2 or 3: the `dimension` key of a section file (2 if absent)."""
    path = section_path(source)
    dimension = read_toml(path).get("dimension", 2)
    if dimension not in (2, 3) or isinstance(dimension, bool):
        raise InputError(f"{path}, key dimension", f"must be 2 or 3, got {dimension!r}.",
                         "write dimension = 3 for a 3D fingertip (or leave it out for 2D).")
    return dimension


def load_fingertip3d(source="male-index-3d", overrides: dict | None = None) -> Fingertip3D:
    """Read and validate a 3D fingertip from a built-in name or a TOML path (``dimension = 3``).

    Parameters
    ----------
    source : str or Path, optional
        A built-in name (``"male-index-3d"``) or a TOML file. Keys left out keep the defaults
        of `Fingertip3D`.
    overrides : dict or None, optional
        Tables of the file (``{"mesh": {"min_size": 0.8}}``, ``{"half": True}``); they win.

    Returns
    -------
    Fingertip3D
        The validated fingertip.
    """
    path = section_path(source)
    data = read_toml(path)
    for table, values in (overrides or {}).items():
        data[table] = {**data.get(table, {}), **values} if isinstance(values, dict) else values
    try:
        return _fingertip_from_dict(data, name=path.stem)
    except InputError as e:
        raise InputError(f"{path}, key {e.where}", e.problem, e.fix) from None


def _fingertip_from_dict(data: dict, name: str) -> Fingertip3D:
    data = dict(data)
    if data.pop("dimension", None) != 3:
        raise InputError("dimension", "a 3D fingertip file must say dimension = 3.",
                         "add the line dimension = 3 at the top (before any [table]).")
    top = {"half": data.pop("half")} if "half" in data else {}
    unknown = sorted(set(data) - set(_KEYS_2D))
    if unknown:
        raise InputError(", ".join(unknown), "unknown table(s) or key(s) of a 3D fingertip file "
                         "(in 3D the pulp is always the palmar half, y < 0).",
                         f"use only dimension, half and [{'], ['.join(_KEYS_2D)}].")
    flat, kwargs = {}, {}
    for table, values in data.items():
        allowed = [*_KEYS_2D[table], *_KEYS_3D.get(table, {})]
        check_keys(table, values, allowed)
        flat[table] = {k: v for k, v in values.items() if k in _KEYS_2D[table]}
        kwargs |= {_KEYS_3D[table][k]: v for k, v in values.items() if k not in _KEYS_2D[table]}
    flat["mesh"] = {**dataclasses.asdict(DEFAULT_MESH_3D), **flat.get("mesh", {})}
    return Fingertip3D(section=section_from_dict(flat, name), name=name, **top, **kwargs)
