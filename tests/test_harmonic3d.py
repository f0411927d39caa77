"""The frequency route on the 3D fingertip (harmonic.py, frequency_response.py), very coarse.

The half model pressed 0.5 mm by the round probe, on the paper's tissue (Prony times 2.1 and
9.4 s): at 2 Hz (ωτ_i = 26 and 118, the subcutaneous tissue undrained, far below the first
resonance) the small-signal response is the instantaneous one, so

- Re K(2 Hz) equals the tangent of one vanishing backward-Euler step to d ± δ, and
- Re of the transfer functions to the receptor quantities equals the central difference of
  what the receptor recorder samples after those steps: the 3D σ22 component, the 3D minimum
  principal log strain (the eigenvalue at the DG1 nodes) and the pore pressure.
"""

import numpy as np
import pytest
from mpi4py import MPI

from fingertip_dolfinx.afferents.receptors import ReceptorRecorder, Sites, load_receptors
from fingertip_dolfinx.frequency_response import SiteTransfer, mesh_and_sites
from fingertip_dolfinx.harmonic import (
    HarmonicSolver,
    linearise,
    press,
    step_force,
)
from fingertip_dolfinx.loading import RampHold
from fingertip_dolfinx.post import DerivedFields
from fingertip_dolfinx.problem import FingertipProblem
from fingertip_dolfinx.scene import load_scene

pytestmark = pytest.mark.slow

VERY_COARSE = ["section.mesh.min_size=1.0", "section.mesh.max_size=2.5",
               "section.mesh.bone_size=3.5", 'materials.set="wu2004"',
               "model.inertia=false", 'steps.scheme="backward-euler"']
DEPTH, DELTA = 0.5, 1e-4


@pytest.fixture(scope="module")
def pressed3d():
    scene = load_scene("vibrotactile-3d", VERY_COARSE)
    population = load_receptors("calibrated")
    fm, _ = mesh_and_sites(scene, population, MPI.COMM_WORLD)
    problem = FingertipProblem(fm, scene.indenters, scene.history, scene.materials, scene.model)
    press(problem, RampHold(DEPTH, 0.5, 0.5), "held", scene.steps)
    solver = HarmonicSolver(linearise(problem))
    yield problem, solver, population, scene.indenters[0].centre_z
    solver.close()


def test_two_hertz_stiffness_is_the_instantaneous_tangent_in_3d(pressed3d):
    """To 1 % (G*(2 Hz) = 1 − O(1e-3) on this tissue; the step's tangent is exact)."""
    problem, solver, _, _ = pressed3d
    tangent = (step_force(problem, DEPTH + DELTA, [1e-9])
               - step_force(problem, DEPTH - DELTA, [1e-9])) / (2 * DELTA)
    K = solver.solve(2.0).stiffness
    assert tangent > 0
    assert K.real == pytest.approx(tangent, rel=1e-2)
    assert K.imag > 0  # the skin's QLV dissipates: the force leads the drive


def _recorded(problem, population, sites, out) -> dict[str, np.ndarray]:
    """sed, −e_min and −σ22 total at the sites, as the run's receptor recorder samples them."""
    derived = DerivedFields(problem.u, problem.fmesh.cell_tags, problem.region_energies())
    recorder = ReceptorRecorder(problem, derived, population, None, out,
                                problem.mesh.comm, sites=sites)
    rows = recorder.sample(0.0)
    recorder.close()
    return {"sed": np.array([r["sed_MPa"] for r in rows]),
            "compressive_strain": -np.array([r["e_min"] for r in rows]),
            "compressive_stress": -np.array([r["sigma22_MPa"] for r in rows])}


def test_site_transfer_at_two_hertz_is_the_instantaneous_change_in_3d(pressed3d, tmp_path,
                                                                    vanishing_steps):
    """Serial (samples on rank 0). Two points in the subcutaneous tissue under the probe, off
    its axis (so σ22 is not σ's (1, 0) entry by symmetry): Re H(2 Hz) = the central difference
    of the recorded quantities over a vanishing step to d ± δ, to 1 %."""
    problem, solver, population, z = pressed3d
    points = np.array([[0.4, problem.y_touch + 2.0, z + 0.3],
                       [0.8, problem.y_touch + 2.5, z - 0.5]])
    sites = Sites(np.array(["SA1", "SA1"]), np.arange(2), points[:, 0], np.full(2, 2.0),
                  points)
    transfer = SiteTransfer(problem, points)(solver.solve(2.0))
    values = vanishing_steps(problem, (DEPTH + DELTA, DEPTH - DELTA),
                             lambda: _recorded(problem, population, sites, tmp_path),
                             "transfer3d_check_")
    for q, v in transfer.items():
        difference = (values[0][q] - values[1][q]) / (2 * DELTA)
        assert np.all(np.abs(difference) > 0), q
        assert v.real == pytest.approx(difference, rel=1e-2), q
