"""The 3D fingertip mesh: every tag present and where it belongs, region volumes converging to
their closed forms (geometry3d.Fingertip3D.exact_volumes), the half model, and the distributed
mesh. Coarse meshes (h = 1.6 and 0.8 mm: ~4 and ~7 s each)."""

import json
import math

import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx.mesh import entities_to_geometry, exterior_facet_indices
from mpi4py import MPI

from fingertip_dolfinx.geometry.fingertip3d import (
    half_ellipsoid_area_and_mean_curvature,
    load_fingertip3d,
)
from fingertip_dolfinx.geometry.mesh import CELL_TAGS, FACET_TAGS_3D, region_areas
from fingertip_dolfinx.geometry.mesh3d import build_mesh3d


def coarse(h: float, half: bool = False):
    return load_fingertip3d(overrides={"half": half, "mesh": {
        "min_size": h, "max_size": h, "bone_size": 2 * h}})


@pytest.fixture(scope="module")
def full():
    return coarse(1.6), build_mesh3d(coarse(1.6), MPI.COMM_WORLD)


@pytest.fixture(scope="module")
def half():
    return coarse(1.6, True), build_mesh3d(coarse(1.6, True), MPI.COMM_WORLD)


def owned(fm, dim: int, entities: np.ndarray) -> np.ndarray:
    return entities[entities < fm.mesh.topology.index_map(dim).size_local]


def facet_points(fm, name: str) -> np.ndarray:
    """Coordinates (n, 3) of the vertices of the facets tagged `name` on this rank."""
    facets = fm.facet_tags.find(fm.names[name])
    nodes = entities_to_geometry(fm.mesh, 2, facets)
    return fm.mesh.geometry.x[nodes.ravel()]


def area(fm, name: str) -> float:
    one = fem.Constant(fm.mesh, 1.0)
    form = fem.form(one * fm.ds(fm.names[name]))
    return fm.mesh.comm.allreduce(fem.assemble_scalar(form), op=MPI.SUM)


@pytest.mark.mpi
@pytest.mark.parametrize("which", ["full", "half"])
def test_every_tag_is_present_and_the_exposed_boundary_is_partitioned(which, request):
    tip, fm = request.getfixturevalue(which)
    comm = fm.mesh.comm
    expected = set(CELL_TAGS) | set(FACET_TAGS_3D) - {"subcutaneous_nail"}
    if not tip.half:
        expected.remove("symmetry")
    assert set(fm.names) == expected
    assert all(fm.names[n] == FACET_TAGS_3D.get(n, CELL_TAGS.get(n)) for n in fm.names)
    for name, tag in fm.names.items():
        tags = fm.cell_tags if name in CELL_TAGS else fm.facet_tags
        assert comm.allreduce(len(owned(fm, tags.dim, tags.find(tag))), op=MPI.SUM) > 0, name
    # Exposed facets are exactly those tagged 11-16 (a non-conforming interface would leave
    # exposed facets untagged or tagged as an interface).
    fm.mesh.topology.create_connectivity(2, 3)
    exposed = set(owned(fm, 2, exterior_facet_indices(fm.mesh.topology)))
    outside = np.concatenate([fm.facet_tags.find(t) for t in range(11, 17)])
    assert exposed == set(owned(fm, 2, outside))


def test_tagged_facets_lie_where_they_belong(half):
    tip, fm = half
    # the symmetry plane x = 0, the proximal cut z = 0, the pulp y <= 0 (mesh vertices lie on
    # the CAD faces, whose ends are on these planes to round-off)
    assert np.abs(facet_points(fm, "symmetry")[:, 0]).max() < 1e-9
    assert np.abs(facet_points(fm, "proximal_cut")[:, 2]).max() < 1e-9
    assert facet_points(fm, "pulp_surface")[:, 1].max() < 1e-9
    centre = facet_points(fm, "nail_centre")
    assert centre[:, 0].max() <= tip.section.nail.centre_half_width + 1e-9
    assert centre[:, 1].min() > tip.outer.b


def test_pulp_and_nail_centre_areas_approach_their_exact_values(full):
    tip, fm = full
    # Pulp: the palmar half of the cylinder's side and of the cap. Nail centre: the nail's top
    # (the outer ellipse's parallel curve at the nail thickness) for |x| < centre_half_width,
    # times the nail's length. A surface of curvature <= kappa meshed by triangles of edge <= h
    # loses a relative area of order (kappa h)^2 / 8: kappa = 1 / 6.125, h = 1.6 -> 0.9 %.
    s = tip.section
    cap = half_ellipsoid_area_and_mean_curvature(s.outer.a, s.outer.b, tip.tip_length)[0]
    pulp = 0.5 * s.outer.perimeter * tip.cylinder_length + 0.5 * cap
    assert area(fm, "pulp_surface") == pytest.approx(pulp, rel=0.02)
    u = np.linspace(*s.nail_patch_params, 2001)
    top = np.array([s.nail_surface_point(v) for v in u])
    arc = np.linalg.norm(np.diff(top, axis=0), axis=1).sum()
    strip = arc * (tip.nail_end_z - tip.nail_start_z)
    assert area(fm, "nail_centre") == pytest.approx(strip, rel=1e-3)  # nearly flat: 0.5 mm wide


def relative_errors(tip, fm) -> dict[str, float]:
    exact, volumes = tip.exact_volumes(), region_areas(fm)
    return {name: abs(volumes[name] / exact[name] - 1.0) for name in CELL_TAGS}


def test_region_volumes_converge_to_their_closed_forms(full):
    # P1 tetrahedra inscribed in curved surfaces: the volume error is O(h^2) (measured ratio
    # 3.5-6.8 from h = 1.6 to 0.8); asking for at least first order (ratio 2) leaves room for
    # the unstructured meshes. The CAD's own deviation from the closed forms (the lofted caps,
    # ~1e-5 relative) is far below both errors.
    coarse_errors = relative_errors(*full)
    tip = coarse(0.8)
    fine_errors = relative_errors(tip, build_mesh3d(tip, MPI.COMM_WORLD))
    for name in CELL_TAGS:
        assert fine_errors[name] < coarse_errors[name] / 2, (name, coarse_errors, fine_errors)
    assert max(fine_errors[n] for n in ("skin", "subcutaneous", "nail")) < 2e-3


def test_the_half_model_has_half_the_volumes(full, half):
    # The two meshes discretise the same surfaces at the same sizes: the half model's volumes
    # differ from half the full model's by no more than twice the full model's own error.
    (tip, fm), (_, fm_half) = full, half
    exact, v_full, v_half = tip.exact_volumes(), region_areas(fm), region_areas(fm_half)
    for name in CELL_TAGS:
        error = abs(v_full[name] - exact[name])
        assert abs(2 * v_half[name] - v_full[name]) <= 2 * error, name


@pytest.mark.mpi
def test_the_distributed_mesh_has_the_serial_volume_and_cells(full):
    tip, fm = full
    serial = build_mesh3d(tip, MPI.COMM_SELF)  # the same gmsh mesh, on one rank
    total = sum(region_areas(fm).values())
    assert total == pytest.approx(sum(region_areas(serial).values()), rel=1e-12)
    cells = fm.mesh.topology.index_map(3)
    assert cells.size_global == serial.report.num_cells == fm.report.num_cells
    one = fem.Constant(fm.mesh, 1.0)
    whole = fm.mesh.comm.allreduce(fem.assemble_scalar(fem.form(one * ufl.dx(fm.mesh))), MPI.SUM)
    assert whole == pytest.approx(total, rel=1e-12)  # the regions cover the mesh
    assert math.isclose(total, sum(tip.exact_volumes().values()), rel_tol=1e-2)


def test_the_mesh_command_picks_3d_by_the_file_and_writes_readable_tags(tmp_path):
    from fingertip_dolfinx.cli import main
    from fingertip_dolfinx.geometry.mesh import read_xdmf

    out = tmp_path / "mesh3d"
    assert main(["mesh", "--section", "male-index-3d", "--min-size", "1.6", "--max-size", "1.6",
                 "--out", str(out)]) == 0
    for name in ("mesh.xdmf", "mesh.h5", "mesh.png", "mesh_report.json"):
        assert (out / name).stat().st_size > 0, name
    report = json.loads((out / "mesh_report.json").read_text())
    assert report["mesh"]["cell_type"] == "tetrahedron" and report["options"]["min_size"] == 1.6
    back = read_xdmf(out / "mesh.xdmf", MPI.COMM_SELF)
    assert back.mesh.geometry.dim == 3 and back.names == report["tags"]
    assert main(["mesh", "--section", "male-index-3d", "--quad", "--out", str(out)]) == 2


def test_the_lofted_tip_cap_is_close_to_the_ideal_shapes():
    # The cap's surfaces are lofts through exact sections (mesh3d's docstring): between the
    # sections and at the flat apex disc (alpha = 88 deg: c (1 - sin 88 deg) = 4.3e-3 mm) they
    # depart from the half-ellipsoid and its parallel surface by a few micrometres, far below
    # the element sizes (>= 0.1 mm). Measured: 5.8e-3 mm; skin 0.798-0.804 mm.
    from fingertip_dolfinx.geometry.mesh3d import cap_deviations

    tip = load_fingertip3d()
    deviation = cap_deviations(tip)
    assert deviation["outer"][1] < 0.01
    t = tip.section.skin_thickness
    assert t - 0.01 < deviation["skin_thickness"][0] < deviation["skin_thickness"][1] < t + 0.01
