"""Force control in 3D (force_control.py): the normal force held while the indenter slides
along the finger, on a coarse half model. The target is the whole finger's force (N); the
half model carries half of it, and history.csv's `normal_force_target_N` is that half, on the
footing of its `force_N` (summary.json's `mirror_factor` = 2 gives the whole's)."""

import numpy as np
import pytest
from mpi4py import MPI

from fingertip_dolfinx.outputs import read_csv
from fingertip_dolfinx.runner import run_scene
from fingertip_dolfinx.scene import load_scene

#: A coarse 3D half finger (1 mm elements under the load, the forms of shear-3d and slide-3d).
COARSE = ["section.mesh.min_size=1.0", "section.mesh.max_size=2.5",
          "section.mesh.bone_size=3.5", "output.pictures=false"]
#: shear-3d's plate pressed 0.5 mm in one step (depth control: the half's 4.68 mN), then
#: dragged 0.4 mm along the finger (steps of up to 0.5 s) with the whole finger's force held at
#: 10 mN (the half's 5 mN: deeper than 0.5 mm).
HELD_PLATE = [*COARSE, "protocol.end_time=1.0", "output.times=[0.5, 1.0]",
              "steps.dt_initial=0.5", "steps.dt_max=0.5",
              "protocol.tangential={times = [0.0, 0.5, 0.75, 1.0], values = [0.0, 0.0, 0.2, 0.4],"
              " direction = [0.0, 1.0]}"]
WHOLE, RTOL = 1.0e-2, 1e-3  # N, the whole finger's target; its relative tolerance


def held(rtol: float = RTOL, start: float = 0.5) -> str:
    return f"protocol.normal_force={{times = [{start}], values = [{WHOLE}], rtol = {rtol}}}"


@pytest.mark.slow  # minutes on 2 cores: a 3D press and two force-controlled drag steps
def test_the_plate_dragged_along_the_3d_finger_holds_the_whole_fingers_force(tmp_path):
    """Every force-controlled step: the half model's force within rtol of half the target
    (twice it, the whole finger's, within rtol of the target), the support balancing it, the
    depth found deeper than the protocol's 0.5 mm, and Coulomb's bound |(F_x, F_z)| <= μ F_y
    (under the flat plate the pressure is all along y and |f| <= μp pointwise by the
    projection, so it holds to rounding; the half's x-force is the mirror plane's)."""
    scene = load_scene("shear-3d", [*HELD_PLATE, held()])
    summary = run_scene(scene, tmp_path, progress=False)
    h = read_csv(tmp_path / "history.csv")
    assert summary["mirror_factor"] == 2 and "normal_force_target_N_per_mm" not in h
    on = h["time_s"] > 0.5 + 1e-9
    # the step onto the held force (4.68 → 5 mN on the half) is cut: steps, not a fact, vary
    assert on.sum() >= 2 and np.all(np.isnan(h["normal_force_target_N"][~on]))
    assert np.all(h["normal_force_target_N"][on] == WHOLE / 2)
    force = h["force_N"][on]
    assert np.all(np.abs(2 * force - WHOLE) <= RTOL * WHOLE), 2 * force
    np.testing.assert_allclose(h["reaction_N"][on], force, rtol=1e-5)
    assert np.all(h["indenter_displacement_mm"][on] > 0.5 + 5e-3)
    assert np.all(h["force_solves"][on] >= 1)
    mu = scene.indenters[0].friction
    tangential = np.hypot(h["tangential_x_force_N"], h["tangential_z_force_N"])
    assert np.all(tangential <= mu * h["force_N"] * (1 + 1e-9)), tangential / h["force_N"]
    assert h["tangential_z_force_N"][-1] > 0.5 * mu * force[-1]  # dragged, with friction


@pytest.mark.mpi
@pytest.mark.skipif(MPI.COMM_WORLD.size == 1, reason="one rank: the slow test above")
def test_the_held_force_is_held_on_two_ranks(shared_tmp_path, comm):
    """Under mpiexec the force controller's force is a sum over the ranks (all-reduced), so
    every rank solves for the same depth: the run ends (ranks that chose different depths would
    wait on each other), and the steps onto and along the held force keep the whole finger's
    force within rtol of the target, balanced by the support, deeper than the 0.5 mm press,
    within Coulomb's bound; every rank returns the same summary. The drag to 0.75 s only."""
    scene = load_scene("shear-3d", [
        *COARSE, "protocol.end_time=0.75", "output.times=[0.5, 0.75]", "steps.dt_initial=0.5",
        "steps.dt_max=0.5", "protocol.tangential={times = [0.0, 0.5, 0.75], values = [0.0, 0.0,"
        " 0.2], direction = [0.0, 1.0]}", held()])
    summary = run_scene(scene, shared_tmp_path, progress=False)
    ours = (summary["time_steps"], summary["newton_iterations"])
    assert comm.allgather(ours) == [ours] * comm.size
    h = read_csv(shared_tmp_path / "history.csv")
    on = h["time_s"] > 0.5 + 1e-9
    assert on.sum() >= 1 and h["time_s"][-1] == pytest.approx(0.75)
    force = h["force_N"][on]
    assert np.all(np.abs(2 * force - WHOLE) <= RTOL * WHOLE), 2 * force
    np.testing.assert_allclose(h["reaction_N"][on], force, rtol=1e-5)
    assert np.all(h["indenter_displacement_mm"][on] > 0.5 + 5e-3)
    mu = scene.indenters[0].friction
    tangential = np.hypot(h["tangential_x_force_N"], h["tangential_z_force_N"])
    assert np.all(tangential <= mu * h["force_N"] * (1 + 1e-9)), tangential / h["force_N"]
