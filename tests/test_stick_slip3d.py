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
