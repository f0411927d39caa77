"""Rigid indenters: shapes as validated data, with exact signed distances in UFL and numpy.

An indenter sits below the pulp with its tip (highest point) at height `y_tip` and moves in +y.
Each shape gives the signed distance φ(x) (positive outside the indenter) and its outward unit
normal n = ∇φ, written once against a tiny backend (`_Ops`) so that the UFL form used in the
contact terms and the numpy version used to measure penetration are the same formula.

Round-tipped shapes are dilations: a sharp core (a point, a downward ray, a downward cone) grown
by the tip radius r. For a convex core K, SDF(K ⊕ disc_r) = SDF(K) − r exactly, inside and out,
so the round tip is exact, not smoothed. The flanks run down without end: the base only sets the
flank angle, and no part of a finger ever reaches the indenter's body below it.

In 3D (points with three coordinates; z along the finger) the 2D shapes are prisms: `axis = "z"`
(default) runs the edge along the finger, so every section z = const sees the 2D profile at
centre_x (the plane-strain model's line load); `axis = "x"` runs it across the finger, the
profile lying in the (z, y) plane at z = centre_z (centre_x then plays no part). `Sphere` is
3D only. In 2D (two coordinates) nothing changes; an "x" prism or a sphere is refused there.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import ufl
from dolfinx import fem

from ..datafiles import builtin_dir, find, read_toml
from ..errors import InputError

#: The built-in indenters, loadable by name (`load_indenter("wedge")`).
BUILTIN_DIR = builtin_dir("indenters")


@dataclass(frozen=True)
class _Ops:
    """The few operations the distance formulas need, for one backend."""

    where: Callable
    sqrt: Callable
    abs: Callable
    sign: Callable
    #: A shape's number (a size, a position) as the backend holds it: the float itself, or in
    #: a form a `fem.Constant` holding it (`_ufl_ops`), for the shapes that read their numbers
    #: through it (Grating): one compiled form then serves every width and orientation.
    number: Callable = float


_NUMPY = _Ops(np.where, np.sqrt, np.abs, np.sign)
_UFL = _Ops(ufl.conditional, ufl.sqrt, abs, ufl.sign)


def _ufl_ops(x) -> _Ops:
    """The UFL backend whose numbers are Constants on the mesh of the expression `x`: their
    values are runtime data, not part of the form's signature (so not of its compiled code)."""
    domain = ufl.domain.extract_unique_domain(x)
    return dataclasses.replace(_UFL, number=lambda v: fem.Constant(domain, float(v)))


#: Prism directions: "z" along the finger (the plane-strain line load), "x" across it.
AXES = ("z", "x")
#: Keys that have a default (every other size must be given).
OPTIONAL_KEYS = ("centre_x", "centre_z", "axis", "friction", "depth", "tilt")
#: Keys that are not sizes: any finite number (centres, a tilt), or >= 0 (friction).
_NOT_SIZES = ("centre_x", "centre_z", "friction", "tilt")
#: The largest tilt of a grating's plane (degrees): steeper, the plane would face the finger
#: edge-on (at 90° its ridges would run along the press direction).
MAX_TILT = 60.0
#: Sizes that may be infinite (a grating's groove depth: inf, no floor).
_UNBOUNDED = ("depth",)


@dataclass(frozen=True, kw_only=True)
class Indenter:
    """Base class: a rigid shape whose highest point is at (centre_x, y_tip[, centre_z])."""

    centre_x: float = 0.0  # mm across the finger (0: under the pulp's lowest point)
    centre_z: float = 0.0  # mm along the finger (3D: an "x" prism's or a sphere's position)
    #: Coulomb's friction coefficient μ between this indenter and the skin (0: frictionless,
    #: the paper's contact; physics/friction.py, docs/theory/friction.md for measured values)
    friction: float = 0.0
    shape: ClassVar[str]

    def __post_init__(self):
        for f in fields(self):
            if f.name == "axis":
                continue
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise InputError(f"{self.shape}.{f.name}", f"must be a number, got {value!r}.")
            if not math.isfinite(value) and not (f.name in _UNBOUNDED and value == math.inf):
                raise InputError(f"{self.shape}.{f.name}", f"must be finite, got {value}.")
            if f.name not in _NOT_SIZES and value <= 0:
                raise InputError(
                    f"{self.shape}.{f.name}", f"must be positive (mm), got {value}.",
                    "give the size in mm as a positive number.",
                )
        if self.friction < 0:
            raise InputError(f"{self.shape}.friction", f"must be >= 0, got {self.friction}.",
                             "use 0 (frictionless) or a measured μ, typically 0.4-1.")

    def tip_curvature_radius(self) -> float:
        """Radius of curvature at the tip (mm): what the surface mesh must resolve."""
        return math.inf  # flat

    def z_direction(self) -> tuple[float, float, float] | None:
        """The unit vector along which a tangential move "along z" carries the indenter
        (3D), if it is not z itself (a tilted grating moves along its own plane); None: z."""
        return None

    def tip_xs(self) -> tuple[float, ...]:
        """x of the tops (mm) whose height is y_tip: where a tip could pierce the body."""
        return (self.centre_x,)

    def _field(self, coords: list, y_tip, ops: _Ops) -> tuple:
        """(φ, [n components]) at the point with coordinates `coords` (2 or 3 of them)."""
        raise NotImplementedError

    def signed_distance(self, x, y_tip) -> tuple[ufl.core.expr.Expr, ufl.core.expr.Expr]:
        """UFL (φ, n) at the current position `x` (a UFL 2- or 3-vector, e.g. X + u).

        `y_tip` is a `fem.Constant` (or a number): moving the indenter never recompiles a form.
        The numbers a shape reads through `_Ops.number` are Constants too.
        """
        phi, n = self._field([x[i] for i in range(x.ufl_shape[0])], y_tip, _ufl_ops(x))
        return phi, ufl.as_vector(n)

    def signed_distance_np(self, points, y_tip: float) -> tuple[np.ndarray, np.ndarray]:
        """The numpy form: φ of shape (m,), n of shape (m, d) at `points` (m, d), d = 2 or 3.

        A 2D section's points given with a third column (z = 0) are 3D points: a "z" prism's φ
        does not depend on z, so φ is the section's; n gets a third component 0."""
        p = np.asarray(points, dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):  # branches np.where discards
            phi, n = self._field([p[:, i] for i in range(p.shape[1])], float(y_tip), _NUMPY)
        return phi, np.column_stack(np.broadcast_arrays(*n))

    def _refuse_2d(self, what: str):
        raise InputError(f"{self.shape}", f"{what} needs a 3D mesh (points with x, y, z).",
                         "use a 3D fingertip mesh, or a 'z' prism in the plane-strain section.")


@dataclass(frozen=True, kw_only=True)
class _Prism(Indenter):
    """A 2D profile (`_distance` in its own plane) extruded along `axis` in 3D."""

    axis: str = "z"  # 3D: the prism's axis, "z" along the finger or "x" across it
    #: Whether the orientation is a number (`_Ops.number`) in the formula rather than a branch
    #: of it: then both orientations are one compiled form.
    _axis_as_number: ClassVar[bool] = False

    def __post_init__(self):
        super().__post_init__()
        if self.axis not in AXES:
            raise InputError(f"{self.shape}.axis", f"got {self.axis!r}.",
                             "use 'z' (edge along the finger) or 'x' (edge across it).")

    def _distance(self, px, py, y_tip, ops: _Ops):
        """(φ, n_a, n_y) of the profile at (px, py), components in the backend `ops`."""
        raise NotImplementedError

    def _field(self, coords, y_tip, ops):
        if len(coords) == 2:
            if self.axis != "z":
                self._refuse_2d("an 'x' prism (edge across the finger)")
            phi, na, ny = self._distance(coords[0], coords[1], y_tip, ops)
            return phi, [na, ny]
        x, y, z = coords
        if self._axis_as_number:
            return self._blended_field(x, y, z, y_tip, ops)
        zero = 0.0 * x
        if self.axis == "z":
            phi, na, ny = self._distance(x, y, y_tip, ops)
            return phi, [na, ny, zero]
        # The profile in the (z, y) plane: its horizontal coordinate is z − centre_z, put where
        # `_distance` expects it (relative to centre_x).
        phi, na, ny = self._distance(z - self.centre_z + self.centre_x, y, y_tip, ops)
        return phi, [zero, ny, na]

    def _blended_field(self, x, y, z, y_tip, ops):
        """The two orientations as one formula: s = 0 ("z") or 1 ("x") blends the profile's
        horizontal coordinate, x or centre_x + z − centre_z, and its normal's components. With
        s exactly 0 or 1 every product is by 0 or 1, so the values are the branches' own."""
        s = ops.number(self.axis == "x")
        h = (1 - s) * x + s * (z - ops.number(self.centre_z) + ops.number(self.centre_x))
        phi, na, ny = self._distance(h, y, y_tip, ops)
        return phi, [(1 - s) * na, ny, s * na]

    def shifted(self, distance: float) -> _Prism:
        """The same prism moved `distance` mm across its edge: along x for a "z" prism, along z
        for an "x" one (how a scan moves a grating over the skin). A tilted grating moves
        along its own plane, which raises its tip too: not a change of its centres."""
        if getattr(self, "tilt", 0.0) != 0:
            raise InputError(f"{self.shape}.tilt", "a tilted grating moved along its plane "
                             "also moves its tip height (y_tip), which it does not hold.",
                             "move it by the scene's tangential path (the contact's z_tip), "
                             "or shift the untilted grating.")
        if self.axis == "z":
            return dataclasses.replace(self, centre_x=self.centre_x + distance)
        return dataclasses.replace(self, centre_z=self.centre_z + distance)


def penetration(indenter: Indenter, points, y_tip: float) -> np.ndarray:
    """How deep each point lies inside the indenter (0 outside), in mm."""
    phi, _ = indenter.signed_distance_np(points, y_tip)
    return np.maximum(-phi, 0.0)


@dataclass(frozen=True, kw_only=True)
class Plate(_Prism):
    """A flat rigid plate filling y < y_tip.

    Parameters
    ----------
    centre_x : float, optional
        Plays no part (kept for a uniform interface).
    """

    shape: ClassVar[str] = "plate"

    def _distance(self, px, py, y_tip, ops):
        return py - y_tip, 0.0 * px, 0.0 * px + 1.0


@dataclass(frozen=True, kw_only=True)
class Cylinder(_Prism):
    """A rigid cylinder: a disc in the 2D section; in 3D a prism along `axis`.

    Parameters
    ----------
    radius : float
        The radius (mm).
    centre_x, centre_z : float, optional
        Position of the axis across (and, in 3D, along) the finger (mm).
    axis : str, optional
        3D: ``"z"`` along the finger (the plane-strain load) or ``"x"`` across it.
    """

    radius: float  # mm
    shape: ClassVar[str] = "cylinder"

    def tip_curvature_radius(self) -> float:
        return self.radius

    def _distance(self, px, py, y_tip, ops):
        dx, dy = px - self.centre_x, py - (y_tip - self.radius)
        d = ops.sqrt(dx * dx + dy * dy)
        return d - self.radius, dx / d, dy / d


@dataclass(frozen=True, kw_only=True)
class _RoundCone(_Prism):
    """A downward cone of half-angle α (a ray if α = 0) dilated by the tip radius r."""

    def _tip(self) -> tuple[float, float]:
        """(r, α) of the shape."""
        raise NotImplementedError

    def tip_curvature_radius(self) -> float:
        return self._tip()[0]

    def _distance(self, px, py, y_tip, ops):
        r, alpha = self._tip()
        s, c = math.sin(alpha), math.cos(alpha)
        # Relative to the tip circle's centre, folded onto the right half (the shape is even).
        side = ops.sign(px - self.centre_x)
        qx, qy = ops.abs(px - self.centre_x), py - (y_tip - r)
        along = qx * s - qy * c  # > 0: nearest core point is on the right flank, not the apex
        to_centre = ops.sqrt(qx * qx + qy * qy)
        phi = ops.where(along > 0, qx * c + qy * s, to_centre) - r
        nx = side * ops.where(along > 0, c, qx / to_centre)
        ny = ops.where(along > 0, s, qy / to_centre)
        return phi, nx, ny


@dataclass(frozen=True, kw_only=True)
class Wedge(_RoundCone):
    """A symmetric wedge, tip up: a round tip of `tip_radius`, flanks through the base corners.

    The flanks are tangent to the tip circle and pass through (centre_x ± base/2, y_tip − height).

    Parameters
    ----------
    tip_radius : float
        Radius of the round tip (mm; the paper's 50 µm tip is 0.025), at most base/2.
    base : float
        Width of the wedge at `height` below its tip (mm).
    height : float
        The height at which `base` is measured (mm); with the tip radius it sets the flank angle.
    centre_x, centre_z : float, optional
        Position of the tip across (and, in 3D, along) the finger (mm).
    axis : str, optional
        3D: ``"z"`` along the finger (the plane-strain line load) or ``"x"`` across it.
    """

    tip_radius: float  # mm: the round tip
    base: float  # mm: the width at the base
    height: float  # mm: tip to base
    shape: ClassVar[str] = "wedge"

    def __post_init__(self):
        super().__post_init__()
        if self.tip_radius > self.base / 2:
            raise InputError(
                "wedge.tip_radius", f"{self.tip_radius} mm is larger than half the base "
                f"({self.base / 2} mm): the round tip would be wider than the wedge.",
                "use tip_radius <= base/2 (tip_radius = base/2 is a round-tipped bar).",
            )
        if self.height <= self.tip_radius:
            raise InputError(
                "wedge.height", f"{self.height} mm does not exceed tip_radius "
                f"{self.tip_radius} mm.", "make the wedge taller than its tip radius.",
            )

    def _tip(self):
        # Tangency of the flank {q·(cos α, sin α) = r} (q from the tip centre) through the base
        # corner (a, −b): a cos α − b sin α = r, i.e. ρ cos(α + β) = r with ρ, β polar of (a, b).
        r, a, b = self.tip_radius, self.base / 2, self.height - self.tip_radius
        return r, math.acos(r / math.hypot(a, b)) - math.atan2(b, a)

    @property
    def half_angle(self) -> float:
        """Half the opening angle of the flanks (rad)."""
        return self._tip()[1]


@dataclass(frozen=True, kw_only=True)
class Bar(_RoundCone):
    """A bar with vertical flanks and a semicircular tip (the one- and two-point tests).

    Parameters
    ----------
    width : float
        The bar's width (mm); the tip's radius is width/2.
    centre_x, centre_z : float, optional
        Position of the tip across (and, in 3D, along) the finger (mm).
    axis : str, optional
        3D: ``"z"`` along the finger or ``"x"`` across it.
    """

    width: float  # mm (the tip's radius is half of it)
    shape: ClassVar[str] = "bar"

    def _tip(self):
        return self.width / 2, 0.0


@dataclass(frozen=True, kw_only=True)
class Grating(_Prism):
    """A square-wave grating, ridges up: `ridges` flat-topped ridges `width` wide, `period`
    apart (grooves period − width wide, `depth` deep: their floor at y_tip − depth; by default
    their flanks run down without end), centred on centre_x; each ridge's top corners rounded
    by `corner_radius`. One ridge is a flat-topped bar; two ridges, a bar with a gap of
    period − width in its middle (Johnson & Phillips 1981's gap stimulus). In 3D `axis` is the
    grating's orientation: "z", ridges along the finger; "x", across it (centred on centre_z).

    Each ridge is a dilation (by the corner radius r) of a convex core: the strip |q_x| <= a
    (a = width/2 − r) below the top. Distances to identical ridges at the same height grow
    with the horizontal distance to their centre lines, so the nearest ridge is the one whose
    centre line is nearest: x is folded onto it (one comparison per ridge) and that ridge's
    exact distance taken; the union's distance is then exact. A floor (finite `depth`) joins
    the union as the half-space below it: the distance stays exact outside the indenter and
    near its surface; deep inside, near a groove's inner corners, it is the smaller of the two
    depths (a lower bound of the penetration).

    Parameters
    ----------
    width : float
        Width of each ridge's top (mm).
    period : float
        Centre-to-centre distance of neighbouring ridges (mm); above `width` when ridges > 1.
    ridges : int
        How many ridges (1: a flat-topped bar).
    corner_radius : float
        Radius of the rounded top corners (mm), at most width/2 (width/2: the round-tipped bar).
    centre_x, centre_z : float, optional
        Position of the grating's centre across (and, in 3D, along) the finger (mm).
    depth : float, optional
        Depth of the grooves, ridge top to groove floor (mm), above corner_radius; inf (the
        default): no floor.
    axis : str, optional
        3D: the orientation, ``"z"`` (ridges along the finger) or ``"x"`` (across it).
    tilt : float, optional
        3D, ``"x"`` only: the plane's angle (degrees, 0 to 60) to the finger's axis, rising
        towards the tip, about the line (y_tip, centre_z); the distance is the flat grating's
        in the rotated frame (exact: a rigid rotation), and a move along z runs along the
        plane (`z_direction`). 0: flat.
    """

    width: float  # mm: the top of each ridge
    period: float  # mm: ridge centre to ridge centre
    ridges: int  # how many
    corner_radius: float  # mm: the rounded top corners
    depth: float = math.inf  # mm: ridge top to groove floor (inf: the flanks run down)
    #: degrees, 0 to 60: an "x" grating's plane rotated about x about the line (y_tip,
    #: centre_z), rising towards the tip (+z), as a finger meets a surface at a contact angle;
    #: a tangential move along z then runs along the plane. 0 (the default): flat.
    tilt: float = 0.0
    shape: ClassVar[str] = "grating"
    #: Every number of the grating (and its orientation) is an `_Ops.number`: gratings with
    #: the same ridge count and floor or none share one compiled contact form (acuity study).
    _axis_as_number: ClassVar[bool] = True

    def __post_init__(self):
        super().__post_init__()
        if not isinstance(self.ridges, int):
            raise InputError("grating.ridges", f"must be a whole number, got {self.ridges!r}.",
                             "give the number of ridges, e.g. ridges = 5.")
        if self.corner_radius > self.width / 2:
            raise InputError("grating.corner_radius", f"{self.corner_radius} mm is larger than "
                             f"half the ridge width ({self.width / 2} mm).",
                             "use corner_radius <= width/2.")
        if self.ridges > 1 and self.period <= self.width:
            raise InputError("grating.period", f"{self.period} mm does not exceed the ridge "
                             f"width {self.width} mm: the ridges would touch.",
                             "use period > width (the groove is period − width wide).")
        if self.depth <= self.corner_radius:
            raise InputError("grating.depth", f"{self.depth} mm does not exceed the corner "
                             f"radius {self.corner_radius} mm: the floor would cut the ridges' "
                             "rounded corners.", "use depth > corner_radius, or leave depth "
                             "out (grooves without a floor).")
        self._check_tilt()

    def _check_tilt(self):
        if self.tilt != 0 and self.axis != "x":
            raise InputError("grating.tilt", f"{self.tilt}° needs ridges across the finger "
                             "(axis = 'x'): the plane is rotated about x.",
                             "set axis = 'x', or leave tilt out (0).")
        if not 0 <= self.tilt <= MAX_TILT:
            raise InputError("grating.tilt", f"must be between 0 and {MAX_TILT:g} degrees, got "
                             f"{self.tilt}.", "give the angle between the grating's plane and "
                             "the finger's axis, e.g. 20 (a finger exploring a surface).")

    def _tilt_frame(self) -> tuple[float, float]:
        """(cos, sin) of the tilt: the plane's direction along +z is (0, sin, cos), its
        normal towards the finger (0, cos, −sin)."""
        angle = math.radians(self.tilt)
        return math.cos(angle), math.sin(angle)

    def z_direction(self):
        if self.tilt == 0:
            return None
        c, s = self._tilt_frame()
        return (0.0, s, c)

    def _field(self, coords, y_tip, ops):
        """A tilted grating: the profile in the plane's own frame about the line (y_tip,
        centre_z) (h along the plane, v along its normal), the normal rotated back; a rigid
        rotation keeps the distance exact. Untilted: the prism's field, unchanged."""
        if self.tilt == 0 or len(coords) != 3:
            return super()._field(coords, y_tip, ops)
        x, y, z = coords
        c, s = self._tilt_frame()
        dz, dy = z - ops.number(self.centre_z), y - y_tip
        h, v = dz * c + dy * s, dy * c - dz * s
        phi, na, nv = self._distance(h + ops.number(self.centre_x), v + y_tip, y_tip, ops)
        return phi, [0.0 * x, na * s + nv * c, na * c - nv * s]

    def tip_curvature_radius(self) -> float:
        return self.corner_radius

    def centres(self) -> np.ndarray:
        """The ridges' centre lines relative to centre_x (mm), ascending."""
        return (np.arange(self.ridges) - (self.ridges - 1) / 2) * self.period

    def tip_xs(self) -> tuple[float, ...]:
        """The middles of the ridges' tops (centre_x is a groove's middle for an even count)."""
        return tuple(float(c) for c in self.centre_x + self.centres())

    def _distance(self, px, py, y_tip, ops):
        number = ops.number  # the same floats as numbers or Constants: the same arithmetic
        r, a = number(self.corner_radius), number(self.width / 2 - self.corner_radius)
        u = px - number(self.centre_x)
        last = number(self.centres()[-1])
        q = ops.where(u > 0, u - last, u + last)  # beyond the ends: the outermost ridge
        half = number(self.period / 2)
        for c in map(number, self.centres()[1:-1]):  # <=: midway, either ridge is nearest
            q = ops.where(ops.abs(u - c) <= half, u - c, q)
        side, dx, dy = ops.sign(q), ops.abs(q) - a, py - (y_tip - r)
        corner = ops.sqrt(dx * dx + dy * dy)
        # Four parts of the core's distance: its corner (dx, dy > 0), its side (dx > dy), its
        # top (dy >= dx); inside the core the larger of dx, dy is the (negative) distance.
        phi = ops.where(dx > 0, ops.where(dy > 0, corner, dx), ops.where(dy > dx, dy, dx)) - r
        nx = side * ops.where(dx > 0, ops.where(dy > 0, dx / corner, 1.0),
                              ops.where(dy > dx, 0.0, 1.0))
        ny = ops.where(dx > 0, ops.where(dy > 0, dy / corner, 0.0), ops.where(dy > dx, 1.0, 0.0))
        if math.isinf(self.depth):
            return phi, nx, ny
        floor = py - (y_tip - number(self.depth))  # the half-space below the grooves' floor
        below = floor < phi
        return (ops.where(below, floor, phi), ops.where(below, 0.0 * px, nx),
                ops.where(below, 0.0 * px + 1.0, ny))

    def profile(self, s) -> np.ndarray:
        """The grating's top surface as data: its height relative to the tip (mm, <= 0) at `s`
        mm from the grating's centre across the ridges (x − centre_x for a "z" grating,
        z − centre_z for an "x" one): 0 on the ridges' tops, the corners' arcs, −depth (−inf
        without a floor) over the grooves."""
        u = np.asarray(s, dtype=float)
        r, a = self.corner_radius, self.width / 2 - self.corner_radius
        q = np.min(np.abs(u[..., None] - self.centres()), axis=-1) - a  # beyond the flat top
        with np.errstate(invalid="ignore"):
            arc = r - np.sqrt(r * r - q * q)
        h = np.where(q <= 0, 0.0, np.where(q <= r, -arc, -np.inf))
        return np.maximum(h, -self.depth)


@dataclass(frozen=True, kw_only=True)
class Sphere(Indenter):
    """A rigid sphere (a round probe, 3D only): centre (centre_x, y_tip − radius, centre_z).
    φ = |x − c| − radius and n = (x − c)/|x − c|, exact everywhere but at the centre."""

    radius: float  # mm
    shape: ClassVar[str] = "sphere"

    def tip_curvature_radius(self) -> float:
        return self.radius

    def _field(self, coords, y_tip, ops):
        if len(coords) != 3:
            self._refuse_2d("a sphere")
        x, y, z = coords
        dx, dy, dz = x - self.centre_x, y - (y_tip - self.radius), z - self.centre_z
        d = ops.sqrt(dx * dx + dy * dy + dz * dz)
        return d - self.radius, [dx / d, dy / d, dz / d]


SHAPES: dict[str, type[Indenter]] = {
    cls.shape: cls for cls in (Wedge, Bar, Plate, Cylinder, Grating, Sphere)}


def make_indenter(data: dict[str, Any], where: str = "indenter") -> Indenter:
    """An indenter from a table {"shape": ..., sizes...} (one TOML file's content)."""
    data = dict(data)
    shape = data.pop("shape", None)
    if shape not in SHAPES:
        raise InputError(
            f"{where}: shape", f"got {shape!r}.", f"set shape to one of {', '.join(SHAPES)}."
        )
    cls = SHAPES[shape]
    allowed = [f.name for f in fields(cls)]
    unknown = sorted(set(data) - set(allowed))
    if unknown:
        raise InputError(
            f"{where}: {', '.join(unknown)}", f"unknown key(s) for a {shape}.",
            f"the keys of a {shape} are: shape, {', '.join(allowed)}.",
        )
    missing = [f.name for f in fields(cls) if f.name not in data and f.name not in OPTIONAL_KEYS]
    if missing:
        raise InputError(
            f"{where}: {', '.join(missing)}", f"missing for a {shape}.",
            f"give every size of a {shape}: {', '.join(allowed)} (centre_x, centre_z "
            "default to 0, axis to 'z').",
        )
    try:
        return cls(**data)
    except InputError as error:
        raise InputError(f"{where}: {error.where}", error.problem, error.fix) from None


def load_indenter(source: str | Path) -> Indenter:
    """Read an indenter from a built-in name or a TOML file.

    Parameters
    ----------
    source : str or Path
        ``"wedge"``, ``"bar"``, ``"plate"``, ``"cylinder"``, ``"sphere"`` or a path to a TOML
        file with ``shape`` and its sizes.

    Returns
    -------
    Indenter
        The validated indenter.

    Raises
    ------
    InputError
        For a missing file, an unknown shape or a bad size.
    """
    path = find("indenters", source, "indenter")
    data = read_toml(path)
    return make_indenter(data, where=str(path))
