"""The gmsh (OpenCASCADE) model of a fingertip section -> DOLFINx mesh with cell and facet tags.

The regions are built as exact shapes: the ellipses, and gmsh's offset curves (OpenCASCADE
`Geom_OffsetCurve`, exact parallel curves) for the skin's inner boundary and the nail's outer
surface. One `fragment` makes them conform and splits the boundaries at the points where the
boundary tags change (pulp ends, refinement-zone ends, the nail-centre patch), so every mesh
vertex lies on the true curves and one vertex sits exactly at the centre of the nail surface.

The exposed boundary is partitioned by the tags pulp_surface, outer_surface, nail_surface (the
nail's ends included) and nail_centre; interfaces carry the two regions' names.
gmsh runs on rank 0 only; `dolfinx.io.gmsh.model_to_mesh` distributes the mesh.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import gmsh
import numpy as np
import ufl
from dolfinx import fem, io
from dolfinx import mesh as dmesh
from mpi4py import MPI

from ..errors import on_root
from .section import Section

CELL_TAGS = {"skin": 1, "subcutaneous": 2, "bone": 3, "nail": 4}
FACET_TAGS = {
    "pulp_surface": 11,
    "outer_surface": 12,
    "nail_surface": 13,
    "nail_centre": 14,
    "skin_subcutaneous": 21,
    "subcutaneous_bone": 22,
    "subcutaneous_nail": 23,  # only if the geometry makes them touch (not in the default one)
    "skin_nail": 24,  # the nail bed: the nail plate lies on the skin
}
#: A 3D mesh (mesh3d.py) has two more: the half model's mid-sagittal plane x = 0 and the plane
#: z = 0 where the model is cut from the rest of the finger.
FACET_TAGS_3D = FACET_TAGS | {"symmetry": 15, "proximal_cut": 16}
# Size growth per unit distance away from the refinement zone (dh/dx): neighbouring elements
# differ by about 30 %, gentle enough not to spoil the solution's accuracy.
SIZE_GROWTH = 0.3


@dataclass(frozen=True)
class MeshReport:
    """Counts and quality of the gmsh mesh (quality: gmsh's minSICN, 1 for the ideal shape)."""

    cell_type: str
    num_cells: int
    num_vertices: int
    min_quality: float
    mean_quality: float
    min_edge: float  # mm
    max_edge: float  # mm
    seconds: float  # wall time of geometry + meshing on rank 0


@dataclass(frozen=True)
class FingertipMesh:
    """The distributed mesh, its tags, and the name -> tag map of every tag present."""

    mesh: dmesh.Mesh
    cell_tags: dmesh.MeshTags
    facet_tags: dmesh.MeshTags
    names: dict[str, int]
    report: MeshReport | None = None

    @property
    def dx(self) -> ufl.Measure:
        return ufl.Measure("dx", domain=self.mesh, subdomain_data=self.cell_tags)

    @property
    def ds(self) -> ufl.Measure:
        return ufl.Measure("ds", domain=self.mesh, subdomain_data=self.facet_tags)

    @property
    def dS(self) -> ufl.Measure:
        return ufl.Measure("dS", domain=self.mesh, subdomain_data=self.facet_tags)


class SizeMap:
    """A target element size (mm) given at scattered points, read anywhere in the plane as the
    size at the nearest point: a piecewise-constant field on the Voronoi cells of `points`.

    The adaptive loop (`studies.adaptivity`) writes one per level, at the centroids of the previous
    mesh's cells; `section.mesh.size_map` names its file. Calls are answered from a regular
    grid of nearest-point values (spacing: half the smallest size, at most `max_grid` nodes),
    built once with a KD-tree: gmsh asks for the size at ~10 points per element, and a grid
    look-up costs ~0.3 µs against ~20 µs for a KD-tree query per point.
    """

    def __init__(self, points, sizes, max_grid: int = 4_000_000):
        from scipy.spatial import cKDTree

        self.points = np.asarray(points, dtype=float).reshape(-1, 2)
        self.sizes = np.asarray(sizes, dtype=float).ravel()
        if len(self.points) != len(self.sizes) or not len(self.sizes):
            raise ValueError("a size map needs as many sizes as points, and at least one")
        if not np.all(np.isfinite(self.sizes) & (self.sizes > 0)):
            raise ValueError("the sizes of a size map must be finite and positive")
        lo, hi = self.points.min(axis=0), self.points.max(axis=0)
        extent = np.maximum(hi - lo, 1e-12)
        step = max(0.5 * self.sizes.min(), math.sqrt(extent[0] * extent[1] / max_grid))
        shape = np.ceil(extent / step).astype(int) + 1
        axes = [lo[i] + step * np.arange(shape[i]) for i in range(2)]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 2)
        _, nearest = cKDTree(self.points).query(grid)
        self._grid = self.sizes[nearest].reshape(shape)
        self._origin, self._inv, self._last = lo - 0.5 * step, 1.0 / step, shape - 1

    def __call__(self, x: float, y: float) -> float:
        i = min(max(int((x - self._origin[0]) * self._inv), 0), self._last[0])
        j = min(max(int((y - self._origin[1]) * self._inv), 0), self._last[1])
        return float(self._grid[i, j])

    def save(self, path: str | Path) -> Path:
        path = Path(path)
        np.savez_compressed(path, points=self.points, sizes=self.sizes)
        return path

    @classmethod
    def load(cls, path: str | Path) -> SizeMap:
        with np.load(path) as data:
            return cls(data["points"], data["sizes"])


def build_mesh(
    section: Section,
    comm: MPI.Comm = MPI.COMM_WORLD,
    progress: Callable[[str], None] | None = None,
    size: Callable[[float, float], float] | None = None,
) -> FingertipMesh:
    """Mesh a 2D section with its ``section.mesh`` options; gmsh runs on rank 0 of `comm`.

    Parameters
    ----------
    section : Section
        The cross-section and its mesh sizes.
    comm : MPI.Comm, optional
        The communicator the mesh is distributed over.
    progress : callable or None, optional
        ``progress(message)``, called on rank 0 as the work advances (for a status display).
    size : callable or None, optional
        ``size(x, y)`` (mm; needed on rank 0 only), or else the file ``section.mesh.size_map``,
        refines the mesh further: the size at a point is the smaller of the section's fields
        and this one. Without either the mesh is exactly the one the options alone give.

    Returns
    -------
    FingertipMesh
        The distributed mesh with its cell (region) and facet (boundary) tags.
    """
    say = progress if progress is not None and comm.rank == 0 else (lambda message: None)

    def generate():  # on rank 0; a failure there stops every rank (on_root)
        size_map = SizeMap.load(section.mesh.size_map) if size is None and \
            section.mesh.size_map else size
        return _generate(section, say, size_map)

    with gmsh_model() if comm.rank == 0 else contextlib.nullcontext():
        report = on_root(comm, generate)
        say("distributing the mesh")
        data = io.gmsh.model_to_mesh(gmsh.model, comm, 0, gdim=2)
    data.cell_tags.name, data.facet_tags.name = "cell_tags", "facet_tags"
    names = {name: group.tag for name, group in data.physical_groups.items()}
    return FingertipMesh(data.mesh, data.cell_tags, data.facet_tags, names, report)


@contextlib.contextmanager
def gmsh_model():
    """A fresh gmsh model; gmsh is initialised (and finalised) here unless a caller already did."""
    owner = not gmsh.isInitialized()
    if owner:
        gmsh.initialize(readConfigFiles=False, interruptible=False)
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("fingertip")
    try:
        yield
    finally:
        gmsh.model.remove()
        if owner:
            gmsh.finalize()


def _generate(section: Section, say: Callable[[str], None],
              size: Callable[[float, float], float] | None = None) -> MeshReport:
    start = time.perf_counter()
    say("building the geometry")
    regions, curves = _add_geometry(section)
    _add_physical_groups(regions, curves)
    _set_sizes(section, regions, curves)
    if size is not None:
        # gmsh passes lc, the size of the fields above, at every point where it needs one
        # (curves and surfaces): the finer of the two wins.
        gmsh.model.mesh.setSizeCallback(lambda dim, tag, x, y, z, lc: min(lc, size(x, y)))
    say("meshing")
    gmsh.model.mesh.generate(2)
    return _report(section, time.perf_counter() - start)


def ellipse_loop(occ, e, z: float = 0.0) -> int:
    """The ellipse `e` as a closed curve loop in the plane at height z (3D models, mesh3d.py)."""
    return occ.addCurveLoop([ellipse_curve(occ, e, z)])


def ellipse_curve(occ, e, z: float = 0.0) -> int:
    """The ellipse `e` (`geometry.Ellipse`) as one closed gmsh OCC curve at height z."""
    # gmsh 4.15 segfaults offsetting an ellipse whose radii agree to ~1e-9: draw a circle.
    if abs(e.a - e.b) <= 1e-7 * max(e.a, e.b):
        return occ.addCircle(0.0, e.cy, z, 0.5 * (e.a + e.b))
    # OpenCASCADE wants the major radius first; a tall ellipse gets its major axis along y.
    if e.a >= e.b:
        return occ.addEllipse(0.0, e.cy, z, e.a, e.b)
    return occ.addEllipse(0.0, e.cy, z, e.b, e.a, zAxis=[0, 0, 1], xAxis=[0, 1, 0])


def _add_geometry(section: Section) -> tuple[dict[str, list[int]], dict[str, list[int]]]:
    """Build and fragment the regions; return region -> surfaces and facet name -> curves."""
    occ = gmsh.model.occ
    outer_loop = ellipse_loop(occ, section.outer)
    # Offsets of the counter-clockwise ellipse: negative is inward.
    inward = occ.offsetCurve(outer_loop, -section.skin_thickness)
    skin_loop = occ.addCurveLoop([c for _, c in inward])
    outer_disk = occ.addPlaneSurface([outer_loop])
    inner_disk = occ.addPlaneSurface([skin_loop])
    bone_disk = occ.addPlaneSurface([ellipse_loop(occ, section.bone)])
    nail = add_nail(occ, section, outer_loop, outer_disk)

    # Vertices where the boundary tags change: the ends of the pulp and of the refinement zone
    # on the outer ellipse, and the nail-centre patch (its middle point included).
    params = [*section.pulp_params, *section.refine_params, *section.tip_params]
    split = [section.outer.point(u) for u in params]
    u_right, u_left = section.nail_patch_params
    split += [section.nail_surface_point(u) for u in (u_right, math.pi / 2, u_left)]
    points = [(0, occ.addPoint(x, y, 0.0)) for x, y in split]

    inputs = [(2, outer_disk), (2, inner_disk), (2, bone_disk), (2, nail)]
    _, pieces = occ.fragment(inputs, points)
    occ.synchronize()
    outer, inner, bone, nail_ = ({t for d, t in p if d == 2} for p in pieces[:4])
    regions = {
        "skin": sorted(outer - inner),
        "subcutaneous": sorted(inner - bone),
        "bone": sorted(bone),
        "nail": sorted(nail_),
    }
    return regions, _classify_curves(section, regions)


def add_nail(occ, section: Section, outer_loop: int, outer_disk: int) -> int:
    """The nail plate: the band outside the outer ellipse, cut along the normals at its ends."""
    band = occ.addCurveLoop([c for _, c in occ.offsetCurve(outer_loop, section.nail.thickness)])
    annulus, _ = occ.cut(
        [(2, occ.addPlaneSurface([band]))], [(2, outer_disk)], removeTool=False
    )
    # A wedge bounded by the two normal lines through the nail's ends, from their crossing
    # point c out past the plate: its intersection with the band is the nail.
    u0, u1 = section.nail_params
    p0, p1 = section.outer.point(u0), section.outer.point(u1)
    n0, n1 = section.outer.normal(u0), section.outer.normal(u1)
    s = np.linalg.solve(np.column_stack([n0, -n1]), p1 - p0)
    c = p0 + s[0] * n0
    reach = 4.0 * (section.outer.a + section.outer.b + section.nail.thickness)
    angles = np.linspace(math.atan2(*n0[::-1]), math.atan2(*n1[::-1]), 16)
    corners = [c, *(c + reach * np.array([math.cos(a), math.sin(a)]) for a in angles)]
    tags = [occ.addPoint(x, y, 0.0) for x, y in corners]
    lines = [occ.addLine(tags[i - 1], tags[i]) for i in range(len(tags))]
    wedge = occ.addPlaneSurface([occ.addCurveLoop(lines)])
    (nail,), _ = occ.intersect(annulus, [(2, wedge)])
    return nail[1]


def _classify_curves(section: Section, regions: dict[str, list[int]]) -> dict[str, list[int]]:
    """Facet name of every curve, from the regions on its two sides (or its place if exposed)."""
    region_of = {s: name for name, surfaces in regions.items() for s in surfaces}
    curves: dict[str, list[int]] = {name: [] for name in FACET_TAGS}
    curves["refinement_zone"] = []  # not a tag: the pulp curves the fine size is measured from
    for _, curve in gmsh.model.getEntities(1):
        sides = sorted({region_of[s] for s in gmsh.model.getAdjacencies(1, curve)[0]},
                       key=CELL_TAGS.get)
        lo, hi = gmsh.model.getParametrizationBounds(1, curve)
        x, y, _ = gmsh.model.getValue(1, curve, [0.5 * (lo[0] + hi[0])])
        if len(sides) == 2:
            name = "_".join(sides)
        elif sides == ["skin"]:
            from_palmar = math.degrees(math.atan2(abs(x), -y))  # polar angle from -y
            name = "pulp_surface" if from_palmar < section.pulp_half_angle else "outer_surface"
            if name == "pulp_surface" and abs(x) < section.mesh.refine_half_width:
                curves["refinement_zone"].append(curve)
        elif sides == ["nail"]:
            on_top = abs(x) < section.nail.centre_half_width and y > section.outer.b
            name = "nail_centre" if on_top else "nail_surface"
        else:
            raise RuntimeError(f"curve {curve} bounds only {sides}: the geometry is broken")
        curves[name].append(curve)
    return curves


def _add_physical_groups(regions: dict[str, list[int]], curves: dict[str, list[int]]) -> None:
    for name, surfaces in regions.items():
        gmsh.model.addPhysicalGroup(2, surfaces, CELL_TAGS[name], name)
    for name, tag in FACET_TAGS.items():
        if curves[name]:
            gmsh.model.addPhysicalGroup(1, curves[name], tag, name)


def _set_sizes(section: Section, regions: dict[str, list[int]], curves: dict[str, list[int]]):
    """min_size within refine_depth of the pulp's refinement zone, growing away from it to
    max_size in the soft tissue and nail and to bone_size deep inside the bone; tip_size within
    tip_zone of each tip point; spot_size within spot_zone of each spot."""
    opts, field = section.mesh, gmsh.model.mesh.field
    zone_length = section.outer.arc_length(*section.refine_params)
    distance = field.add("Distance")
    field.setNumbers(distance, "CurvesList", curves["refinement_zone"])
    # Sample the zone twice per fine element, so that its distance is accurate to min_size / 4.
    field.setNumber(distance, "Sampling", math.ceil(2 * zone_length / opts.min_size))
    graded = graded_size(distance, opts.min_size, opts.refine_depth, opts.bone_size)
    cap = field.add("Constant")  # max_size everywhere but inside the bone
    field.setNumber(cap, "VIn", opts.bone_size)
    field.setNumber(cap, "VOut", opts.max_size)
    field.setNumber(cap, "IncludeBoundary", 0)
    field.setNumbers(cap, "SurfacesList", regions["bone"])
    fields = [graded, cap]
    if opts.tips:  # a disc of tip_size around each point where a sharp tip acts
        targets = section.outer.point(np.array(section.tip_params))
        vertices = [
            tag for _, tag in gmsh.model.getEntities(0)
            if np.min(np.linalg.norm(targets - gmsh.model.getValue(0, tag, [])[:2], axis=1)) < 1e-9
        ]
        if len(vertices) != len(targets):
            raise RuntimeError(f"tip points {opts.tips} did not all become mesh vertices")
        near_tip = field.add("Distance")
        field.setNumbers(near_tip, "PointsList", vertices)
        fields.append(graded_size(near_tip, opts.tip_size, opts.tip_zone, opts.bone_size))
    fields += _spot_fields(section)
    size = field.add("Min")
    field.setNumbers(size, "FieldsList", fields)
    field.setAsBackgroundMesh(size)
    # The field alone sets the sizes (not the CAD points, curvature or boundary).
    for option in ("MeshSizeFromPoints", "MeshSizeFromCurvature", "MeshSizeExtendFromBoundary"):
        gmsh.option.setNumber(f"Mesh.{option}", 0)
    # Set every option each time: they outlive the model if the caller keeps gmsh running.
    gmsh.option.setNumber("Mesh.Algorithm", 8 if opts.quadrilateral else 6)  # Frontal-Delaunay
    gmsh.option.setNumber("Mesh.RecombineAll", int(opts.quadrilateral))
    gmsh.option.setNumber("Mesh.RecombinationAlgorithm", 2)  # "simple full-quad": no triangle left
    # Full-quad fails ("1D mesh cannot be divided by 2") on a curve meshed with a single
    # segment, such as a nail end shorter than the element size: ask for two at least.
    for kind in ("Curve", "Line"):
        gmsh.option.setNumber(f"Mesh.Minimum{kind}Nodes", 3)


def graded_size(distance: int, size: float, within: float, far: float) -> int:
    """A gmsh Threshold field on the Distance field `distance`: `size` within `within` (mm) of
    its entities, growing by SIZE_GROWTH per mm beyond to `far`. Returns its tag."""
    field = gmsh.model.mesh.field
    tag = field.add("Threshold")
    field.setNumber(tag, "InField", distance)
    for key, value in (("SizeMin", size), ("SizeMax", far), ("DistMin", within),
                       ("DistMax", within + (far - size) / SIZE_GROWTH)):
        field.setNumber(tag, key, value)
    return tag


def _spot_fields(section: Section) -> list[int]:
    """A gmsh Ball field per `mesh.spots` entry: spot_size within spot_zone of the point at that
    depth below the pulp, growing at SIZE_GROWTH (as the tip discs) to bone_size."""
    opts, fields = section.mesh, []
    for x0, depth in opts.spots:
        x, y = section.outer.below_palmar(x0, depth)[0]
        spot = gmsh.model.mesh.field.add("Ball")
        for key, value in (("XCenter", x), ("YCenter", y), ("Radius", opts.spot_zone),
                           ("VIn", opts.spot_size), ("VOut", opts.bone_size),
                           ("Thickness", (opts.bone_size - opts.spot_size) / SIZE_GROWTH)):
            gmsh.model.mesh.field.setNumber(spot, key, value)
        fields.append(spot)
    return fields


def _report(section: Section, seconds: float) -> MeshReport:
    types, elements, _ = gmsh.model.mesh.getElements(2)
    names = [gmsh.model.mesh.getElementProperties(t)[0] for t in types]
    if section.mesh.quadrilateral and names != ["Quadrilateral 4"]:
        raise RuntimeError(f"recombination left non-quadrilateral cells: {names}")
    cell_type = "quadrilateral" if section.mesh.quadrilateral else "triangle"
    return element_report(np.concatenate(elements), cell_type, seconds)


def element_report(tags: np.ndarray, cell_type: str, seconds: float) -> MeshReport:
    """Counts, quality and edge lengths of the gmsh elements `tags` (2D and 3D meshes)."""
    quality = gmsh.model.mesh.getElementQualities(tags, "minSICN")
    return MeshReport(
        cell_type=cell_type,
        num_cells=len(tags),
        num_vertices=len(gmsh.model.mesh.getNodes()[0]),
        min_quality=float(quality.min()),
        mean_quality=float(quality.mean()),
        min_edge=float(gmsh.model.mesh.getElementQualities(tags, "minEdge").min()),
        max_edge=float(gmsh.model.mesh.getElementQualities(tags, "maxEdge").max()),
        seconds=seconds,
    )


def region_areas(fm: FingertipMesh) -> dict[str, float]:
    """Area (mm^2) of each cell region, assembled as the integral of 1 over it."""
    comm = fm.mesh.comm
    one = fem.Constant(fm.mesh, fm.mesh.geometry.x.dtype.type(1.0))
    return {
        name: comm.allreduce(fem.assemble_scalar(fem.form(one * fm.dx(tag))), op=MPI.SUM)
        for name, tag in fm.names.items()
        if name in CELL_TAGS
    }


def write_xdmf(fm: FingertipMesh, path: str | Path) -> Path:
    """Mesh, cell tags and facet tags in one XDMF file (+ .h5) that ParaView opens."""
    path = Path(path).with_suffix(".xdmf")
    fm.mesh.topology.create_connectivity(fm.mesh.topology.dim - 1, fm.mesh.topology.dim)
    with io.XDMFFile(fm.mesh.comm, str(path), "w") as f:
        f.write_mesh(fm.mesh)
        f.write_meshtags(fm.cell_tags, fm.mesh.geometry)
        f.write_meshtags(fm.facet_tags, fm.mesh.geometry)
    return path


def read_xdmf(path: str | Path, comm: MPI.Comm = MPI.COMM_WORLD) -> FingertipMesh:
    """A mesh written by `write_xdmf` (the names of the tags present are recovered)."""
    with io.XDMFFile(comm, str(path), "r") as f:
        mesh = f.read_mesh()
        mesh.topology.create_connectivity(mesh.topology.dim - 1, mesh.topology.dim)
        cell_tags = f.read_meshtags(mesh, "cell_tags")
        facet_tags = f.read_meshtags(mesh, "facet_tags")
    present = set(comm.allreduce([*cell_tags.values, *facet_tags.values], op=MPI.SUM))
    names = {n: t for n, t in (CELL_TAGS | FACET_TAGS_3D).items() if t in present}
    return FingertipMesh(mesh, cell_tags, facet_tags, names)


def report_dict(fm: FingertipMesh, section: Section) -> dict:
    """What `fingertip mesh` writes to mesh_report.json: counts, quality and area errors."""
    exact, areas = section.exact_areas(), region_areas(fm)
    return {
        "section": section.name,
        "options": asdict(section.mesh),
        "mesh": asdict(fm.report) if fm.report else None,
        "tags": fm.names,
        "areas_mm2": {
            name: {"mesh": areas[name], "exact": exact[name],
                   "relative_error": areas[name] / exact[name] - 1.0}
            for name in areas
        },
    }
