"""A 3D scene through the runner: the files it writes and the identities between them.

The probe sits at z = 3 mm with the radius of `test_physics3d`'s layered-block sphere, so the
two tests share one set of compiled forms (a cold compile of the 3D forms takes minutes).
"""

import json

import numpy as np
import pytest

from fingertip_dolfinx.outputs import read_csv
from fingertip_dolfinx.runner import run_scene
from fingertip_dolfinx.scene import load_scene

COARSE = ["section.mesh.min_size=0.8", "section.mesh.max_size=2.0",
          "section.mesh.bone_size=3.0", "section.mesh.refine_z_min=1.0",
          "section.mesh.refine_z_max=6.0", "indenters.0.centre_z=3.0",
          "protocol.depth=0.3", "protocol.end_time=1.0", "output.times=[1.0]",
          "steps.dt_initial=0.25", "output.pictures=false"]


@pytest.fixture(scope="module")
def probe_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("probe-3d")
    scene = load_scene("probe-3d", COARSE)
    summary = run_scene(scene, out, progress=False)
    return scene, out, summary


def test_the_force_balances_the_support_at_every_step(probe_run):
    _, out, summary = probe_run
    h = read_csv(out / "history.csv")
    assert summary["converged"] and summary["mirror_factor"] == 2
    assert np.all(h["force_N"] > 0)
    # Equilibrium: the indenter's force is the supports' reaction, to Newton's tolerance: the
    # residual's 2-norm (≤ snes_atol = 1e-8 N) summed over the n ≤ 100 dofs that carry the
    # load differs by at most √n·atol.
    np.testing.assert_allclose(h["reaction_N"], h["force_N"], rtol=0, atol=10 * 1e-8)
    assert summary["peak_force_N"] == pytest.approx(h["force_N"].max())


def test_the_line_force_integrates_to_the_whole_fingers_force(probe_run):
    """f(z) on slabs that tile the finger: Σ f Δz is the half model's force times 2 (the
    same residual, tested with e_y slab by slab: an identity up to round-off)."""
    _, out, _ = probe_run
    f = read_csv(out / "line_force.csv")
    h = read_csv(out / "history.csv")
    width = np.diff(f["z_mm"][:2])[0]
    assert np.sum(f["force_per_length_N_per_mm"]) * width == pytest.approx(
        2 * h["force_N"][-1], rel=1e-9)


def test_the_surface_is_pushed_most_under_the_probe(probe_run):
    scene, out, _ = probe_run
    along = read_csv(out / "surface_along.csv")
    across = read_csv(out / "surface_across.csv")
    assert not np.any(np.isnan(along["deflection_mm"]))  # every point found in the mesh
    h = 0.8  # mm, the mesh size under the load: the resolution of the peak's position
    assert abs(along["z_mm"][np.argmax(along["deflection_mm"])] - 3.0) < h
    assert across["x_mm"][np.argmax(across["deflection_mm"])] < h
    # The pulp's lowest point rises with the probe: by the indentation, to within the sag of
    # a facet under the exact surface where it is sampled (h²/8R, R = 6.125 mm), the P2
    # surface's freedom between the contact quadrature points on the sphere (h²/8R_s,
    # R_s = 2 mm: 0.8 mm facets on a 1.1 mm contact radius) and the penetration allowed.
    summary = json.loads((out / "summary.json").read_text())
    bound = h**2 / (8 * 6.125) + h**2 / (8 * 2.0) + summary["max_penetration_mm"]
    assert np.max(along["deflection_mm"]) == pytest.approx(scene.history.deepest, abs=bound)


def test_the_depth_profiles_lie_in_the_probes_cross_section(probe_run):
    _, out, summary = probe_run
    d = read_csv(out / "depth_profiles.csv")
    assert np.all(d["z_mm"] == 3.0) and np.all(d["x_mm"] >= 0)  # the half model's side
    assert np.all(np.isfinite(d["sed_MPa"])) and np.nanmax(d["sed_MPa"]) > 0
    record = json.loads((out / "summary.json").read_text())
    assert record["scene_data"]["section"]["half"] is True


@pytest.mark.mpi
def test_one_and_two_ranks_give_the_same_3d_numbers(world_and_alone):
    """The coarse probe on this run's ranks and on each rank alone agrees to Newton's
    tolerance: snes_atol = 1e-8 N on forces of 1e-4 N and more, 1e-4 relative at most."""
    scene = load_scene("probe-3d", COARSE + ["protocol.end_time=0.5", "protocol.ramp_time=0.5",
                                             "output.times=[0.5]"])
    shared, alone = world_and_alone(scene)
    a, b = read_csv(shared / "history.csv"), read_csv(alone / "history.csv")
    np.testing.assert_allclose(a["force_N"], b["force_N"], rtol=1e-4)
    la, lb = read_csv(shared / "line_force.csv"), read_csv(alone / "line_force.csv")
    scale = np.max(np.abs(lb["force_per_length_N_per_mm"]))
    np.testing.assert_allclose(la["force_per_length_N_per_mm"], lb["force_per_length_N_per_mm"],
                               atol=1e-4 * scale)
