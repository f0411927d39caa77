"""3D afferent populations: the sites over the 3D fingertip's pulp surface (counts from the
densities and the pulp area, depths below the surface, the half model's mirrored half), the
bad inputs, and one coarse probe-3d run with spike trains (slow)."""

import math

import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

from fingertip_dolfinx.afferents.receptors import (
    load_receptors,
    pulp_triangles,
    surface_sites,
    triangle_areas,
)
from fingertip_dolfinx.errors import InputError
from fingertip_dolfinx.geometry.fingertip3d import half_ellipsoid_area_and_mean_curvature
from fingertip_dolfinx.geometry.mesh import FingertipMesh
from fingertip_dolfinx.scene import load_scene

#: The coarse mesh of tests/test_run3d.py's probe at z = 3 mm, 1 mm in 0.5 s, held to 1 s,
#: with the calibrated afferents (about 4 minutes on 2 shared cores).
COARSE = ["section.mesh.min_size=0.8", "section.mesh.max_size=2.0",
          "section.mesh.bone_size=3.0", "section.mesh.refine_z_min=1.0",
          "section.mesh.refine_z_max=6.0", "indenters.0.centre_z=3.0",
          "protocol.depth=1.0", "protocol.ramp_time=0.5", "protocol.end_time=1.0",
          "output.times=[1.0]", "steps.dt_initial=0.1", 'output.receptors="calibrated"']


@pytest.fixture(scope="module")
def coarse_mesh():
    from fingertip_dolfinx.geometry.mesh3d import build_mesh3d

    scene = load_scene("probe-3d", COARSE)
    return scene.section, build_mesh3d(scene.section, MPI.COMM_WORLD)


def exact_pulp_area(finger) -> float:
    """The whole finger's pulp (the palmar half of the outer surface, y < 0): half the
    cylinder's lateral surface and half the half-ellipsoidal cap (mm²)."""
    a, b, c = finger.outer.a, finger.outer.b, finger.tip_length
    cap = half_ellipsoid_area_and_mean_curvature(a, b, c)[0]
    return 0.5 * finger.outer.perimeter * finger.cylinder_length + 0.5 * cap


def test_the_counts_are_the_densities_times_the_pulp_area(coarse_mesh):
    """round(density × area) afferents per class, the area the meshed pulp's (doubled for the
    half model); the meshed area is the exact one within its discretisation error: flat
    facets of edge h inscribed in a surface of smallest radius R tilt by up to h/(2R) from it,
    a relative area deficit of order (h/R)²/8; allowed: 2 (h/(2R))² = (h/R)²/2."""
    finger, fm = coarse_mesh
    corners, _ = pulp_triangles(fm)
    meshed = 2.0 * triangle_areas(corners).sum()
    h = np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2).max()
    r = min(finger.outer.a, finger.outer.b, finger.tip_length) ** 2 / max(
        finger.outer.a, finger.outer.b, finger.tip_length)
    assert meshed == pytest.approx(exact_pulp_area(finger), rel=2 * (h / (2 * r)) ** 2)
    population = load_receptors("calibrated")
    sites = surface_sites(population, fm, half=True)
    for c in population.classes:
        assert np.sum(sites.cls == c.name) == round(c.density * meshed / 100.0)
    # TouchSim's distal-pad densities (per cm²) over ~5 cm² of pulp: about 1,150 afferents
    assert 1000 < len(sites) < 1300


def test_the_sites_lie_at_their_class_depth_below_the_surface(coarse_mesh):
    """Each site is its class depth below its facet along the facet's normal: its distance to
    the exact outer surface differs from the depth by at most the facets' chordal error
    h²/(8R) (the facet lies inside the surface) plus the tilt of a facet's normal, depth ×
    (h/R)²/2, plus the distance function's own sampling error (spacing² / (4 d))."""
    finger, fm = coarse_mesh
    corners, _ = pulp_triangles(fm)
    h = np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2).max()
    r = finger.outer.min_curvature_radius
    sites = surface_sites(load_receptors("calibrated"), fm, half=True)
    spacing = 0.1
    for name in ("SA1", "RA", "PC"):
        rows = sites.cls == name
        depth = sites.depth[rows][0]
        error = finger.distance_to_outer(sites.points[rows], spacing) - depth
        tilt = depth * (h / r) ** 2 / 2
        sampling = spacing**2 / (4 * depth)
        assert error.max() <= h**2 / (8 * r) + sampling
        assert error.min() >= -(tilt + sampling)
    # inside the finger, on both halves; the mirrored ones read their mirror image on the
    # meshed half
    assert np.all(finger.contains(sites.points))
    left = sites.points[:, 0] < 0
    assert 0.4 < left.mean() < 0.6
    np.testing.assert_array_equal(sites.sample_points[:, 0], np.abs(sites.points[:, 0]))
    np.testing.assert_array_equal(sites.sample_points[:, 1:], sites.points[:, 1:])


def test_the_placement_is_the_same_every_time(coarse_mesh):
    _, fm = coarse_mesh
    population = load_receptors("calibrated")
    first, again = surface_sites(population, fm, True), surface_sites(population, fm, True)
    np.testing.assert_array_equal(first.points, again.points)


def test_a_mesh_without_a_pulp_surface_is_refused(coarse_mesh):
    _, fm = coarse_mesh
    empty = dmesh.meshtags(fm.mesh, 2, np.zeros(0, dtype=np.int32), np.zeros(0, dtype=np.int32))
    bare = FingertipMesh(fm.mesh, fm.cell_tags, empty, fm.names)
    with pytest.raises(InputError, match="no pulp surface"):
        surface_sites(load_receptors("calibrated"), bare, half=True)


@pytest.mark.slow
def test_a_coarse_3d_probe_run_writes_its_population(tmp_path):
    """probe-3d (coarse, 1 mm in 0.5 s) with the calibrated afferents: every site sampled at
    every step, spikes.csv ↔ the responses, the rate histories as counts per bin, the SA1
    afferents firing are the ones near the probe (x = 0, z = 3 mm; measured: one, 0.68 mm from
    its axis, 10 spikes) and the picture drawn."""
    from fingertip_dolfinx.afferents.receptors import afferent_responses
    from fingertip_dolfinx.runner import run

    out = MPI.COMM_WORLD.bcast(tmp_path, root=0)
    result = run(load_scene("probe-3d", COARSE), out, progress=False)
    a, spikes, rates = result.afferents, result.spikes, result.rates
    table = result.receptors()
    assert len(table["time_s"]) == len(a["afferent"]) * len(result.time)
    r = afferent_responses(result)
    for j, train in enumerate(r.spikes):
        np.testing.assert_array_equal(spikes["time_s"][spikes["afferent"] == j], train)
    assert rates["counts"].sum() == len(spikes["time_s"])
    sa1 = (a["class"] == "SA1") & (a["spikes"] > 0)
    assert sa1.any()
    distance = np.hypot(a["x_mm"][sa1], a["z_mm"][sa1] - 3.0)
    assert distance.max() < 2.0
    assert (out / "population.png").exists()
    assert math.isclose(result.time[-1], 1.0)


@pytest.mark.mpi
def test_the_placement_does_not_depend_on_the_partition(coarse_mesh):
    """The same sites, bit for bit, from the mesh distributed over the ranks and from a copy
    on each rank alone (the draw is made from the facets in one canonical order)."""
    from fingertip_dolfinx.geometry.mesh3d import build_mesh3d

    finger, fm = coarse_mesh
    population = load_receptors("calibrated")
    alone = build_mesh3d(finger, MPI.COMM_SELF)
    np.testing.assert_array_equal(surface_sites(population, fm, True).points,
                                  surface_sites(population, alone, True).points)
