"""The tagged mesh: exact areas to chord accuracy at O(h^2), true skin thickness, tags, quads."""

import dataclasses
import math

import numpy as np
import pytest
from dolfinx.mesh import CellType, entities_to_geometry, exterior_facet_indices
from mpi4py import MPI

from fingertip_dolfinx.geometry.mesh import (
    CELL_TAGS,
    FACET_TAGS,
    build_mesh,
    read_xdmf,
    region_areas,
    write_xdmf,
)
from fingertip_dolfinx.geometry.section import Section

SIZES = (0.8, 0.4, 0.2)


def uniform(h: float, quadrilateral: bool = False) -> Section:
    """The default section meshed with one size h everywhere (a clean convergence study)."""
    s = Section()
    options = dataclasses.replace(
        s.mesh, min_size=h, max_size=h, bone_size=h, quadrilateral=quadrilateral
    )
    return dataclasses.replace(s, mesh=options)


@pytest.fixture(scope="module")
def meshes():
    return {h: build_mesh(uniform(h), MPI.COMM_SELF) for h in SIZES}


def chord_bounds(s: Section, h: float) -> dict[str, float]:
    """Largest area error from straight edges of length h on curved boundaries.

    A chord of length h on curvature k cuts off h^3 k / 12, so a boundary curve turning by
    the angle psi costs h^2 psi / 12. Each region adds this over its curved boundaries
    (the nail's bed and top turn by the nail's turning angle, its ends are straight).
    """
    u0, u1 = s.nail_params
    nail_turn = s.outer.normal_angle(u1) - s.outer.normal_angle(u0)
    turns = {"skin": 4 * math.pi, "subcutaneous": 4 * math.pi, "bone": 2 * math.pi,
             "nail": 2 * nail_turn}
    return {name: h**2 * psi / 12 for name, psi in turns.items()}


def test_region_areas_agree_with_exact_areas_to_chord_accuracy(meshes):
    exact = Section().exact_areas()
    for h, fm in meshes.items():
        areas, bounds = region_areas(fm), chord_bounds(Section(), h)
        for name in CELL_TAGS:
            # 1.5: gmsh's boundary edges are up to ~20 % longer than the target size.
            assert abs(areas[name] - exact[name]) < 1.5 * bounds[name], (h, name)


def test_area_error_falls_at_the_chord_rate_h2(meshes):
    # Single-boundary regions show the chord error cleanly; in the layers the errors of the
    # two boundaries (equal total turning 2 pi) cancel to leading order.
    exact = Section().exact_areas()
    errors = {"bone": [], "section": []}
    for h, fm in meshes.items():
        areas = region_areas(fm)
        errors["bone"].append(areas["bone"] - exact["bone"])
        section = sum(areas[n] - exact[n] for n in ("skin", "subcutaneous", "bone"))
        errors["section"].append(section)
        # The chord estimate itself, -2 pi h^2 / 12, for a closed convex curve.
        assert errors["bone"][-1] == pytest.approx(-2 * math.pi * h**2 / 12, rel=0.1)
    for e in errors.values():
        rates = np.log(np.abs(e[:-1]) / np.abs(e[1:])) / np.log(2.0)
        assert np.all((rates > 1.8) & (rates < 2.2)), rates


def facet_points(fm, name: str) -> np.ndarray:
    """Vertex coordinates (n, 2, 2) of the facets tagged `name`."""
    facets = fm.facet_tags.find(fm.names[name])
    return fm.mesh.geometry.x[entities_to_geometry(fm.mesh, 1, facets)][..., :2]


def test_skin_is_equally_thick_everywhere(meshes):
    s, fm = Section(), meshes[0.4]
    edges = facet_points(fm, "skin_subcutaneous")
    # The vertices lie on the exact parallel curve; the chords' midpoints bulge inwards by
    # at most the sagitta l^2 / (8 R), R the inner curve's smallest radius of curvature.
    assert np.allclose(s.outer.distance(edges.reshape(-1, 2)), s.skin_thickness, atol=1e-9)
    length = np.linalg.norm(edges[:, 1] - edges[:, 0], axis=1)
    sagitta = length**2 / (8 * (s.outer.min_curvature_radius - s.skin_thickness))
    excess = s.outer.distance(edges.mean(axis=1)) - s.skin_thickness
    assert np.all((excess > -1e-12) & (excess <= sagitta * (1 + 1e-6)))


def test_nail_centre_patch_has_a_vertex_at_the_top_of_the_nail(meshes):
    s, fm = Section(), meshes[0.8]
    points = facet_points(fm, "nail_centre").reshape(-1, 2)
    assert np.min(np.linalg.norm(points - s.nail_centre, axis=1)) < 1e-12
    assert np.max(np.abs(points[:, 0])) == pytest.approx(s.nail.centre_half_width, abs=1e-9)


def test_quadrilateral_option_gives_only_quadrilaterals():
    s = uniform(0.4, quadrilateral=True)
    fm = build_mesh(s, MPI.COMM_SELF)
    assert fm.mesh.topology.cell_type == CellType.quadrilateral
    assert fm.report.cell_type == "quadrilateral" and fm.report.min_quality > 0.3
    areas, exact, bounds = region_areas(fm), s.exact_areas(), chord_bounds(s, 0.4)
    for name in CELL_TAGS:
        assert abs(areas[name] - exact[name]) < 1.5 * bounds[name], name


def test_refinement_zone_gets_the_fine_size():
    s = Section()
    fm = build_mesh(s, MPI.COMM_SELF)
    edges = facet_points(fm, "pulp_surface")
    length = np.linalg.norm(edges[:, 1] - edges[:, 0], axis=1)
    mid_x = np.abs(edges[:, :, 0].mean(axis=1))
    fine, coarse = length[mid_x < 3.0], length[mid_x > 7.5]
    assert fine.max() < 1.5 * s.mesh.min_size
    assert coarse.min() > 2 * s.mesh.min_size and coarse.max() < 1.5 * s.mesh.max_size
    assert fm.report.min_quality > 0.3


def test_a_spot_gets_its_fine_disc_and_nothing_else_changes():
    # The disc of spot_size under the load: cells inside it are spot-sized, while without
    # the spot the same place has the zone's 4x coarser cells; the disc (radius 0.3 mm) adds
    # about its area over spot-sized cells, not a refined mesh.
    base = dataclasses.replace(Section().mesh, min_size=0.4, max_size=0.8, bone_size=1.5,
                               refine_depth=1.5)
    spot = dataclasses.replace(base, spots=((0.5, 0.75),), spot_size=0.1, spot_zone=0.3)
    centre = Section().outer.below_palmar(0.5, 0.75)[0]
    sizes = {}
    for name, options in (("plain", base), ("spot", spot)):
        fm = build_mesh(dataclasses.replace(Section(), mesh=options), MPI.COMM_SELF)
        cells = np.arange(fm.mesh.topology.index_map(2).size_local)
        x = fm.mesh.geometry.x[entities_to_geometry(fm.mesh, 2, cells)][..., :2]
        edges = np.linalg.norm(x - np.roll(x, 1, axis=1), axis=2).max(axis=1)
        inside = np.linalg.norm(x.mean(axis=1) - centre, axis=1) < 0.25
        sizes[name] = (edges[inside].max(), edges[inside].min(), len(cells))
        assert fm.report.min_quality > 0.3
    assert sizes["spot"][0] < 1.5 * 0.1 and sizes["plain"][1] > 2 * 0.1
    disc_cells = math.pi * (0.3 + 0.4) ** 2 / (math.sqrt(3) / 4 * 0.1**2)  # with its rim
    assert 0 < sizes["spot"][2] - sizes["plain"][2] < disc_cells


def owned(fm, dim: int, entities: np.ndarray) -> np.ndarray:
    return entities[entities < fm.mesh.topology.index_map(dim).size_local]


@pytest.mark.mpi
def test_every_tag_is_present_and_the_exposed_boundary_is_partitioned(comm):
    fm = build_mesh(uniform(0.8), comm)
    expected = set(CELL_TAGS) | set(FACET_TAGS) - {"subcutaneous_nail"}
    assert set(fm.names) == expected
    assert all(fm.names[n] == t for n, t in (CELL_TAGS | FACET_TAGS).items() if n in fm.names)
    for name, tag in fm.names.items():
        tags = fm.cell_tags if name in CELL_TAGS else fm.facet_tags
        count = comm.allreduce(len(owned(fm, tags.dim, tags.find(tag))), op=MPI.SUM)
        assert count > 0, name
    # The exposed facets are exactly those tagged 11-14: a non-conforming interface would
    # show up as exposed facets with an interface tag, or untagged.
    fm.mesh.topology.create_connectivity(1, 2)
    exposed = set(owned(fm, 1, exterior_facet_indices(fm.mesh.topology)))
    outside = np.concatenate([fm.facet_tags.find(t) for t in (11, 12, 13, 14)])
    assert exposed == set(owned(fm, 1, outside))
    areas, exact = region_areas(fm), Section().exact_areas()
    bounds = chord_bounds(Section(), 0.8)
    assert all(abs(areas[n] - exact[n]) < 1.5 * bounds[n] for n in CELL_TAGS)


@pytest.mark.mpi
def test_xdmf_round_trip_keeps_the_tags(comm, shared_tmp_path):
    fm = build_mesh(uniform(0.8), comm)
    back = read_xdmf(write_xdmf(fm, shared_tmp_path / "mesh.xdmf"), comm)
    assert back.names == fm.names
    for a, b in ((fm.cell_tags, back.cell_tags), (fm.facet_tags, back.facet_tags)):
        for tag in fm.names.values():
            count = [comm.allreduce(len(owned(m, t.dim, t.find(tag))), op=MPI.SUM)
                     for m, t in ((fm, a), (back, b))]
            assert count[0] == count[1]


@pytest.mark.mpi
def test_a_meshing_failure_on_rank_zero_stops_every_rank(shared_tmp_path, comm):
    """gmsh runs on rank 0 alone; an unreadable size map fails there, and the other ranks must
    stop too instead of waiting in the mesh's distribution (the test would hang)."""
    from fingertip_dolfinx.errors import RootRankError

    broken = shared_tmp_path / "size_map.npz"
    if comm.rank == 0:
        broken.write_text("not a size map")
    comm.barrier()
    s = Section()
    section = dataclasses.replace(s, mesh=dataclasses.replace(s.mesh, size_map=str(broken)))
    with pytest.raises(Exception) as raised:
        build_mesh(section, comm)
    assert (comm.rank == 0) != isinstance(raised.value, RootRankError)
