"""Friction on the 3D surfaces: the stick/slip columns of surface_across/along.csv and
stick_slip.csv (post.SurfaceFriction), and the `slide-3d` scene."""

import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from fingertip_dolfinx.geometry.indenters import Plate
from fingertip_dolfinx.physics.contact import NitscheContact, Obstacle
from fingertip_dolfinx.physics.friction import CoulombFriction
from fingertip_dolfinx.post import SurfaceFriction

MU = 0.5


def _cube_on_plate(axis: int, moved: bool):
    """A unit cube pressed 0.01 mm into a plate under its face y = 0 (penalty contact, μ = 0.5),
    then translated rigidly by 0.1 mm along `axis` (0: x, 2: z), the plate with it if `moved`
    (the whole face sticks) or not (it all slips), and that step accepted: the friction's
    values at the points below (`SurfaceFriction`, rank 0) and the pressure's force on the
    cube."""
    domain = dmesh.create_unit_cube(MPI.COMM_WORLD, 2, 2, 2)
    u = fem.Function(fem.functionspace(domain, ("Lagrange", 1, (3,))))
    obstacle = Obstacle.at(domain, Plate(), y_tip=0.01, x_tip=0.0, z_tip=0.0)
    contact = NitscheContact(u, ufl.grad(u), ufl.ds, [obstacle], modulus=1.0, method="penalty")
    friction = CoulombFriction(contact, MU)  # its start: the pressed state, u = 0
    u.x.array.reshape(-1, 3)[:, axis] = 0.1
    if moved:
        (obstacle.x_tip if axis == 0 else obstacle.z_tip).value = 0.1
    load = friction.pressure_forces()[0][1]
    # the step accepted: a run writes its surfaces then (`mark_accepted` moves the slip's start)
    friction.mark_accepted()
    points = np.array([[0.3, 0.0, 0.2], [0.5, 0.0, 0.5], [0.9, -0.001, 0.7],  # the pressed face
                       [0.5, 1.0, 0.5],  # the top face: on the contact surface, free
                       [0.5, -0.5, 0.5]])  # 0.5 mm below the cube: on no facet
    return SurfaceFriction(contact, friction).at(points, reach=0.01), load


@pytest.mark.mpi
@pytest.mark.parametrize("axis", [0, 2])
@pytest.mark.parametrize("moved", [True, False])
def test_the_3d_surface_rows_carry_the_pressure_traction_and_stick_or_slip(axis, moved):
    values, load = _cube_on_plate(axis, moved)
    if MPI.COMM_WORLD.rank != 0:
        assert values is None
        return
    pressed, top, off = values[:3], values[3], values[4]
    p, q, margin, state = pressed[:, 0], pressed[:, 1:4], pressed[:, 4], pressed[:, 5]
    # a uniform pressure over the unit face: the pressure's force is p × 1 mm²
    assert load > 0 and np.allclose(p, load, rtol=1e-12)
    expected = np.zeros(3)
    if not moved:  # gross slip: |q| = μp against the slip (+0.1 mm along the axis)
        expected[axis] = -MU * load
    assert np.allclose(q, expected, rtol=0, atol=1e-12 * load)
    # the margin μp − |t_t − γΔs|: μp where the face moved with the plate, < 0 where it slips
    assert np.all(margin > 0) if moved else np.all(margin < 0)
    assert np.all(state == (2 if moved else 1))
    assert top[0] == 0 and top[5] == 0  # on the surface, out of contact: free
    assert np.all(np.isnan(off[:5])) and off[5] == 0  # on no contact facet: NaN, free


def check_slide_3d(out, mu: float, radius: float) -> None:
    """The slide-3d scene's files: equilibrium; the stick/slip map at every step, its state
    that of its margin, |f| <= μp at each of its points; Coulomb's bound at every step on the
    friction's share of the tangential force; a partial-stick phase, then gross slip; the
    contact carried along the finger with the probe; every receptor site at every step."""
    from fingertip_dolfinx.outputs import read_csv
    from fingertip_dolfinx.result import Result

    h, s = read_csv(out / "history.csv"), read_csv(out / "stick_slip.csv")
    assert np.allclose(h["force_N"], h["reaction_N"], rtol=1e-5)  # the friction's y-share too
    assert np.array_equal(np.unique(s["time_s"]), h["time_s"])  # a map row every step
    assert np.array_equal(s["contact_state"] == 2, s["stick_margin_MPa"] > 0)
    f = np.sqrt(sum(s[f"tangential_traction_{a}_MPa"] ** 2 for a in "xyz"))
    assert np.all(f <= mu * s["pressure_MPa"] * (1 + 1e-9) + 1e-15)  # the projection on μp
    # |F_f| <= μ∫p ds <= μ F_p,y / cos θ: F_p,y = ∫p n_y ds, n tilted by at most θ from y
    # at the contact's edge, sin θ = a/R (a the radius of the whole contact, 2 × the half's area)
    friction = np.hypot(h["tangential_x_force_N"] - h["pressure_tangential_x_force_N"],
                        h["tangential_z_force_N"] - h["pressure_tangential_z_force_N"])
    a = np.sqrt(2 * h["contact_area_mm2"] / np.pi)
    assert np.all(friction <= mu * h["pressure_normal_force_N"] / np.sqrt(1 - (a / radius)**2))
    slide = h["tangential_z_displacement_mm"] > 0
    stick = h["stick_area_mm2"] / h["contact_area_mm2"]
    assert np.any(slide & (stick > 0.1) & (stick < 0.9)), stick  # a partial-stick phase
    assert stick[-1] == 0.0, stick  # gross slip at the end
    share = (h["tangential_z_force_N"] - h["pressure_tangential_z_force_N"]) / (
        mu * h["pressure_normal_force_N"])
    # in gross slip |f| = μp at every point, along the tangent: the share is μ∫p t_z ds over
    # μ∫p n_y ds, 1 on a flat contact, at most 1/cos θ on the sphere (measured 1.016)
    assert 0.98 <= share[-1] <= 1 / np.sqrt(1 - (a[-1] / radius) ** 2), share
    # the contact zone on the path (x = 0, reference z) moves along with the probe: its mean
    # by the travel, to an element (0.8 mm: the map's points take their facets' values)
    z = [s["z_mm"][(s["time_s"] == t) & (s["pressure_MPa"] > 0)] for t in h["time_s"]]
    shift = np.mean(z[-1]) - np.mean(z[int(np.argmax(slide)) - 1])
    assert shift == pytest.approx(h["tangential_z_displacement_mm"][-1], abs=0.8), shift
    r = Result(out).receptors()
    sites = len(r["time_s"]) // len(h["time_s"])
    assert sites > 100 and len(r["time_s"]) == sites * len(h["time_s"])
    assert np.array_equal(np.unique(r["time_s"]), h["time_s"])


@pytest.mark.slow
def test_the_slide_3d_scene_slides_the_probe_along_the_finger(tmp_path):
    from fingertip_dolfinx.runner import run_scene
    from fingertip_dolfinx.scene import load_scene

    scene = load_scene("slide-3d", ["output.pictures=false"])
    summary = run_scene(scene, tmp_path, progress=False)
    assert summary["converged"]
    check_slide_3d(tmp_path, scene.indenters[0].friction, scene.indenters[0].radius)
