"""The gmsh (OpenCASCADE) model of a 3D fingertip (`geometry3d.Fingertip3D`) -> DOLFINx mesh of
tetrahedra with the cell and facet tags of `mesh.CELL_TAGS` and `mesh.FACET_TAGS_3D`.

What is exact and what is approximate (the CAD; the mesh's vertices lie on these surfaces):
- on the cylindrical part (0 <= z <= L) everything is exact: the outer elliptic cylinder; the
  skin's inner surface, the extrusion of the section's inward offset curve (OpenCASCADE's
  exact parallel curve, as in 2D); the bone, a ruled loft between two ellipses (an exact
  elliptic-cone frustum); the nail, the 2D nail plate (mesh.add_nail) extruded along z;
- the rounded ends (the outer tip cap, the skin's inner cap, the bone's end) are lofts
  (`_dome`, `addThruSections`) through exact copies of the cross-section scaled by cos(alpha)
  at z0 + length sin(alpha), alpha = 0 .. 88 deg, closed by a flat disc: the sections of the
  outer cap lie on the half-ellipsoid (a, b, c), those of the inner cap on the half-ellipsoid's
  inward parallel surface only where a = b = c. Measured on the built-in fingertip
  (`cap_deviations`): the outer cap is within 5.8e-3 mm of the half-ellipsoid, the skin on
  the cap is 0.798-0.804 mm thick (0.8 ideal).
  Why lofts: OpenCASCADE's offset (`addThickSolid`) fails on an ellipsoid ("Could not build
  thick solid", gmsh 4.15, also on the half- and full ellipsoid alone), and a dilated sphere
  (the exact ellipsoid) has its poles and seam where the model is split (x = 0, y = 0), which
  broke the booleans or the surface meshing. The skin's surfaces are made of faces that end on
  the planes x = 0 and y = 0 (`_quarter_arcs`; the offset curve comes in such arcs), so neither
  the pulp nor the half model cuts through one of them.
The outer skin faces end on y = 0 (pulp_surface: the palmar ones, cylinder and cap; the apex
disc, radius a cos 88 deg = 0.28 mm, is outer_surface) and the nail is split at |x| =
nail.centre_half_width (nail_centre: the strip's top face), so every tag is a union of whole
CAD faces. gmsh runs on rank 0 only; `dolfinx.io.gmsh.model_to_mesh` distributes.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable
from dataclasses import asdict

import gmsh
import numpy as np
from dolfinx import io
from mpi4py import MPI

from ..errors import on_root
from .fingertip3d import Fingertip3D, ellipsoid_distance
from .mesh import (
    CELL_TAGS,
    FACET_TAGS_3D,
    SIZE_GROWTH,
    FingertipMesh,
    MeshReport,
    add_nail,
    element_report,
    ellipse_curve,
    ellipse_loop,
    gmsh_model,
    graded_size,
    region_areas,
)
from .section import Ellipse

#: Sections of the lofted rounded ends (`_dome`), at alpha = 0 .. CAP_LAST_ANGLE (deg): with 12
#: the skin on the cap is 0.798-0.804 mm thick (0.8 ideal; the module's docstring).
CAP_SECTIONS = 12
CAP_LAST_ANGLE = 88.0
FLAT = 1e-2  # mm, see _classify_faces
#: mm, tolerance of the fuzzy fuse of a prism and its dome (`_glue`): 1e-3 left slivers
#: between the outer cylinder and its dome, 1e-2 glued all three pairs.
GLUE = 1e-2


def build_mesh3d(tip: Fingertip3D, comm: MPI.Comm = MPI.COMM_WORLD,
                 progress: Callable[[str], None] | None = None) -> FingertipMesh:
    """Mesh a 3D fingertip with its ``tip.section.mesh`` sizes; gmsh runs on rank 0 of `comm`.

    Parameters
    ----------
    tip : Fingertip3D
        The fingertip and its mesh sizes.
    comm : MPI.Comm, optional
        The communicator the mesh is distributed over.
    progress : callable or None, optional
        ``progress(message)``, called on rank 0 as the work advances.

    Returns
    -------
    FingertipMesh
        The distributed tetrahedral mesh with its cell and facet tags.
    """
    say = progress if progress is not None and comm.rank == 0 else (lambda message: None)
    with gmsh_model() if comm.rank == 0 else contextlib.nullcontext():
        report = on_root(comm, lambda: _generate(tip, say))  # a failure stops every rank
        say("distributing the mesh")
        data = io.gmsh.model_to_mesh(gmsh.model, comm, 0, gdim=3)
    data.cell_tags.name, data.facet_tags.name = "cell_tags", "facet_tags"
    names = {name: group.tag for name, group in data.physical_groups.items()}
    return FingertipMesh(data.mesh, data.cell_tags, data.facet_tags, names, report)


def _generate(tip: Fingertip3D, say: Callable[[str], None]) -> MeshReport:
    start = time.perf_counter()
    say("building the geometry")
    regions, faces = add_geometry(tip)
    for name, volumes in regions.items():
        gmsh.model.addPhysicalGroup(3, volumes, CELL_TAGS[name], name)
    for name, tag in FACET_TAGS_3D.items():
        if faces[name]:
            gmsh.model.addPhysicalGroup(2, faces[name], tag, name)
    _set_sizes(tip, regions, faces)
    say("meshing")
    gmsh.model.mesh.generate(3)
    return _report(time.perf_counter() - start)


# --- geometry ---


def add_geometry(tip: Fingertip3D) -> tuple[dict[str, list[int]], dict[str, list[int]]]:
    """Build and fragment the regions (in the current gmsh model); return region -> volumes and
    facet name -> surfaces."""
    occ, s = gmsh.model.occ, tip.section
    nail_loop = ellipse_loop(occ, s.outer)
    nail = add_nail(occ, s, nail_loop, occ.addPlaneSurface([nail_loop]))
    nail = _extrude(occ, nail, tip.nail_start_z, tip.nail_end_z)
    outer = _outer_solid(occ, tip)
    inner = _inner_solid(occ, tip)
    bone = _bone(occ, tip)
    big = 10.0 * (tip.total_length + s.outer.a + s.outer.b)
    if tip.half:  # keep x >= 0
        outer, inner, bone, nail = (_clip(occ, v, (0, -big, -big, big, 2 * big, 3 * big))
                                    for v in (outer, inner, bone, nail))
    skin = occ.cut(outer, inner, removeTool=False)[0]
    w = s.nail.centre_half_width
    nail = [*_clip(occ, nail, (-big, -big, -big, big - w, 2 * big, 3 * big), keep=True),
            *_clip(occ, nail, (-w, -big, -big, 2 * w, 2 * big, 3 * big), keep=True),
            *_clip(occ, nail, (w, -big, -big, big, 2 * big, 3 * big))]
    groups = [skin, inner, bone, nail]
    inputs = [v for group in groups for v in group]
    _, pieces = occ.fragment(inputs[:1], inputs[1:])
    occ.synchronize()
    _remove_strays(occ)
    owner = np.repeat(np.arange(4), [len(g) for g in groups])
    found = [{t for i in np.flatnonzero(owner == k) for d, t in pieces[i] if d == 3}
             for k in range(4)]
    regions = {"skin": sorted(found[0]), "subcutaneous": sorted(found[1] - found[2]),
               "bone": sorted(found[2]), "nail": sorted(found[3])}
    return regions, _classify_faces(tip, regions)


def _remove_strays(occ) -> None:
    """Remove the construction curves and points (the loft's sections, ...) that bound no
    volume: gmsh would mesh them too."""
    kept = set(gmsh.model.getEntities(3))
    for _ in range(3):
        below = gmsh.model.getBoundary(list(kept), combined=False, oriented=False)
        kept |= {(d, abs(t)) for d, t in below}
    strays = [e for e in gmsh.model.getEntities() if e not in kept]
    occ.remove(sorted(strays, reverse=True))
    occ.synchronize()


def _extrude(occ, face: int, z0: float, z1: float) -> list[tuple[int, int]]:
    """The prism of a face of the plane z = 0 between z0 and z1."""
    occ.translate([(2, face)], 0.0, 0.0, z0)
    return [e for e in occ.extrude([(2, face)], 0.0, 0.0, z1 - z0) if e[0] == 3]


def _clip(occ, volumes, box: tuple, keep: bool = False) -> list[tuple[int, int]]:
    """The part of `volumes` inside the box (x, y, z, dx, dy, dz); `keep`: do not delete them."""
    tool = [(3, occ.addBox(*box))]
    return occ.intersect(volumes, tool, removeObject=not keep, removeTool=True)[0]


def _dome(occ, curves, cy: float, z0: float, length: float) -> list[tuple[int, int]]:
    """The rounded end beyond z = z0 of a prism of the closed curve `curves` (in the plane
    z = 0, around the axis x = 0, y = cy): a loft through copies scaled by cos(alpha) about the
    axis at z0 + length sin(alpha), alpha = 0 .. CAP_LAST_ANGLE, closed by a flat disc. For an
    ellipse its sections lie on the half-ellipsoid of semi-axes (a, b, length)."""
    wires = []
    for alpha in np.radians(np.linspace(0.0, CAP_LAST_ANGLE, CAP_SECTIONS)):
        ring = occ.copy(curves)
        if alpha > 0:  # (a dilated curve becomes a B-spline: keep the first one exact)
            occ.dilate(ring, 0.0, cy, 0.0, math.cos(alpha), math.cos(alpha), 1.0)
        occ.translate(ring, 0.0, 0.0, z0 + length * math.sin(alpha))
        wires.append(occ.addWire([k for _, k in ring]))
    return [e for e in occ.addThruSections(wires, makeSolid=True, makeRuled=False) if e[0] == 3]


def _glue(occ, prism, dome) -> list[tuple[int, int]]:
    """Fuse a prism and its dome. The loft approximates its sections by B-splines: its lower
    edge lies off the prism's top edge (measured: slivers of ~1.5e-4 mm^2 and 1.7e-4 mm^3
    between them); a fuzzy fuse glues the two (gaps below GLUE are closed)."""
    fuzzy = gmsh.option.getNumber("Geometry.ToleranceBoolean")
    gmsh.option.setNumber("Geometry.ToleranceBoolean", GLUE)
    try:
        return occ.fuse(prism, dome)[0]
    finally:
        gmsh.option.setNumber("Geometry.ToleranceBoolean", fuzzy)


def _outer_solid(occ, tip: Fingertip3D) -> list[tuple[int, int]]:
    """The elliptic cylinder of the outer ellipse (exact) with its dome (the half-ellipsoid)."""
    quarters = _quarter_arcs(occ, tip.outer)
    dome = _dome(occ, quarters, 0.0, tip.cylinder_length, tip.tip_length)
    disk = occ.addPlaneSurface([occ.addCurveLoop([k for _, k in quarters])])
    return _glue(occ, _extrude(occ, disk, 0.0, tip.cylinder_length), dome)


def _quarter_arcs(occ, e: Ellipse) -> list[tuple[int, int]]:
    """The ellipse as four arcs ending on its axes, in the plane z = 0. The outer surface's
    faces then end on the planes y = 0 (pulp | outer surface) and x = 0 (the half model's
    cut) instead of crossing them: a loft seam or a face cut across those planes broke the
    booleans or the meshing (gmsh 4.15). The skin's offset curve comes in such arcs already."""
    ends = np.linspace(0.0, 2 * math.pi, 5)
    if e.a == e.b:
        arcs = [occ.addCircle(0.0, e.cy, 0.0, e.a, -1, u0, u1)
                for u0, u1 in zip(ends[:-1], ends[1:])]
    elif e.a > e.b:
        arcs = [occ.addEllipse(0.0, e.cy, 0.0, e.a, e.b, -1, u0, u1)
                for u0, u1 in zip(ends[:-1], ends[1:])]
    else:  # the major axis along y: angles from +y
        arcs = [occ.addEllipse(0.0, e.cy, 0.0, e.b, e.a, -1, u0, u1, zAxis=[0, 0, 1],
                               xAxis=[0, 1, 0]) for u0, u1 in zip(ends[:-1], ends[1:])]
    return [(1, k) for k in arcs]


def _inner_solid(occ, tip: Fingertip3D) -> list[tuple[int, int]]:
    """The solid bounded by the skin's inner surface (see the module's docstring)."""
    t, L, c = tip.section.skin_thickness, tip.cylinder_length, tip.tip_length
    offset = occ.offsetCurve(ellipse_loop(occ, tip.outer), -t)  # exact parallel curve, inward
    face = occ.addPlaneSurface([occ.addCurveLoop([k for _, k in offset])])
    return _glue(occ, _extrude(occ, face, 0.0, L), _dome(occ, offset, 0.0, L, c - t))


def _bone(occ, tip: Fingertip3D) -> list[tuple[int, int]]:
    """Elliptic-cone frustum (a ruled loft) from z = 0 to the rounded end's start, then the
    rounded end."""
    bone, k, z_e = tip.section.bone, tip.bone_taper, tip.bone_cap_start
    # (Whole ellipses: the glued joint keeps a crescent of the plane z = z_e, 0.08 mm wide,
    # with the worst tetrahedra (minSICN 0.04) next to it. Quarter arcs, as for the skin, lost
    # it but broke the meshing of the rounded end at h = 0.8 mm.)
    end = Ellipse(k * bone.a, k * bone.b, bone.cy)
    loft = occ.addThruSections([ellipse_loop(occ, bone), ellipse_loop(occ, end, z_e)],
                               makeSolid=True, makeRuled=True)
    dome = _dome(occ, [(1, ellipse_curve(occ, end))], bone.cy, z_e, tip.bone_end_length)
    return _glue(occ, [e for e in loft if e[0] == 3], dome)


def _classify_faces(tip: Fingertip3D, regions: dict[str, list[int]]) -> dict[str, list[int]]:
    """Facet name of every surface, from the regions on its two sides (or its place if exposed)."""
    region_of = {v: name for name, volumes in regions.items() for v in volumes}
    faces: dict[str, list[int]] = {name: [] for name in FACET_TAGS_3D}
    # A face lies in a plane x = 0 or z = 0 if its centre does (to round-off) and its bounding
    # box is flat (to FLAT: OpenCASCADE pads the boxes of offset curves by ~3e-3 mm).
    tol = 1e-9 * tip.total_length
    for _, face in gmsh.model.getEntities(2):
        volumes = gmsh.model.getAdjacencies(2, face)[0]
        sides = sorted({region_of[v] for v in volumes}, key=CELL_TAGS.get)
        x0, y0, z0, x1, y1, z1 = gmsh.model.getBoundingBox(2, face)
        x, y, z = gmsh.model.occ.getCenterOfMass(2, face)
        if len(volumes) == 2:
            if len(sides) == 2:
                faces["_".join(sides)].append(face)
            continue  # inside one region (where the skin and nail were split)
        if len(volumes) != 1:
            raise RuntimeError(f"surface {face} bounds {len(volumes)} volumes: broken geometry")
        if tip.half and abs(x) < tol and x1 - x0 < FLAT:
            name = "symmetry"
        elif abs(z) < tol and z1 - z0 < FLAT:
            name = "proximal_cut"
        elif sides == ["skin"]:
            # (the flat disc closing the cap's loft at its apex straddles y = 0: outer_surface)
            name = "pulp_surface" if y < -FLAT else "outer_surface"
        elif sides == ["nail"]:
            on_top = (abs(x) < tip.section.nail.centre_half_width and y > tip.outer.b
                      and z1 - z0 > FLAT)  # not the strip's ends (z = start_z, end_z)
            name = "nail_centre" if on_top else "nail_surface"
        else:
            raise RuntimeError(f"surface {face} of {sides} is exposed: broken geometry")
        faces[name].append(face)
    return faces


# --- sizes, report ---


def _set_sizes(tip: Fingertip3D, regions, faces) -> None:
    """min_size within refine_depth of the pulp and inside the (x, z) footprint |x| <
    refine_half_width, refine_z_min < z < refine_z_max, growing by SIZE_GROWTH per mm away from
    it to max_size in the soft tissue and nail and to bone_size deep inside the bone."""
    opts, field, L = tip.section.mesh, gmsh.model.mesh.field, tip.total_length
    growth = (opts.bone_size - opts.min_size) / SIZE_GROWTH
    depth = field.add("Distance")
    field.setNumbers(depth, "SurfacesList", faces["pulp_surface"])
    # Points per direction of each face: two per fine element along the longest extent.
    extent = max(0.5 * tip.outer.perimeter, L)
    field.setNumber(depth, "Sampling", math.ceil(2 * extent / opts.min_size))
    near_pulp = graded_size(depth, opts.min_size, opts.refine_depth, opts.bone_size)
    footprint = field.add("Box")  # the zone's extent in x and z (all y)
    w, big = opts.refine_half_width, 10.0 * L
    for key, value in (("VIn", opts.min_size), ("VOut", opts.bone_size), ("XMin", -w),
                       ("XMax", w), ("YMin", -big), ("YMax", big), ("ZMin", tip.refine_z_min),
                       ("ZMax", tip.refine_z_max), ("Thickness", growth)):
        field.setNumber(footprint, key, value)
    zone = field.add("Max")  # fine only where both are: near the pulp AND in the footprint
    field.setNumbers(zone, "FieldsList", [near_pulp, footprint])
    cap = field.add("Constant")  # max_size everywhere but inside the bone
    field.setNumber(cap, "VIn", opts.bone_size)
    field.setNumber(cap, "VOut", opts.max_size)
    field.setNumber(cap, "IncludeBoundary", 0)
    field.setNumbers(cap, "VolumesList", regions["bone"])
    size = field.add("Min")
    field.setNumbers(size, "FieldsList", [zone, cap])
    field.setAsBackgroundMesh(size)
    for option in ("MeshSizeFromPoints", "MeshSizeFromCurvature", "MeshSizeExtendFromBoundary"):
        gmsh.option.setNumber(f"Mesh.{option}", 0)
    gmsh.option.setNumber("Mesh.Algorithm", 6)  # Frontal-Delaunay surfaces
    gmsh.option.setNumber("Mesh.Algorithm3D", 1)  # Delaunay tetrahedra
    gmsh.option.setNumber("Mesh.RecombineAll", 0)
    gmsh.option.setNumber("Mesh.ElementOrder", 1)  # affine tetrahedra (P2 spaces work on them)


def _report(seconds: float) -> MeshReport:
    _, elements, _ = gmsh.model.mesh.getElements(3)
    return element_report(np.concatenate(elements), "tetrahedron", seconds)


def cap_deviations(tip: Fingertip3D, samples: int = 30) -> dict[str, tuple[float, float]]:
    """How far the lofted CAD of the tip cap is from the ideal shapes (mm; run on one rank).

    Samples the cap's faces (z > cylinder_length) of the outer skin surface and of the skin's
    inner surface; returns, as (min, max) over the samples, "outer": the distance of the outer
    points to the half-ellipsoid (a, b, tip_length), and "skin_thickness": the distance of the
    inner points to it (the ideal is the skin thickness everywhere).
    """
    L, axes = tip.cylinder_length, (tip.outer.a, tip.outer.b, tip.tip_length)
    with gmsh_model():
        _, faces = add_geometry(tip)
        outer = _sample(faces["pulp_surface"] + faces["outer_surface"], L, samples)
        inner = _sample(faces["skin_subcutaneous"], L, samples)
    centre = np.array([0.0, 0.0, L])
    dist = {"outer": ellipsoid_distance(outer - centre, axes),
            "skin_thickness": ellipsoid_distance(inner - centre, axes)}
    return {k: (float(v.min()), float(v.max())) for k, v in dist.items()}


def _sample(faces: list[int], z_min: float, n: int) -> np.ndarray:
    """Points (m, 3) on a parameter grid of each face lying above z_min + GLUE."""
    points = []
    for face in faces:
        lo, hi = gmsh.model.getParametrizationBounds(2, face)
        uv = np.stack(np.meshgrid(*(np.linspace(lo[i], hi[i], n) for i in range(2))), -1)
        uv = uv.reshape(-1, 2)
        inside = [gmsh.model.isInside(2, face, list(q), parametric=True) for q in uv]
        xyz = gmsh.model.getValue(2, face, uv[np.array(inside, bool)].ravel()).reshape(-1, 3)
        points.append(xyz[xyz[:, 2] > z_min + GLUE])
    return np.concatenate(points)


def report_dict3d(fm: FingertipMesh, tip: Fingertip3D) -> dict:
    """What `fingertip mesh` writes to mesh_report.json for a 3D fingertip: counts, quality,
    region volumes (integral of 1 over each region) against the closed forms."""
    exact, volumes = tip.exact_volumes(), region_areas(fm)
    return {
        "fingertip": tip.name,
        "half": tip.half,
        "options": asdict(tip.section.mesh),
        "mesh": asdict(fm.report) if fm.report else None,
        "tags": fm.names,
        "volumes_mm3": {
            name: {"mesh": volumes[name], "exact": exact[name],
                   "relative_error": volumes[name] / exact[name] - 1.0}
            for name in volumes
        },
    }
