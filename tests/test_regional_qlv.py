"""A QLV (Prony) law on more than one region: the skin and the subcutaneous solid.

- Time route: two cells, one skin and one subcutaneous, each with its own Prony series, strained
  homogeneously in one step of length T and then held. Each region's S(t) must be its own
  hereditary integral S_e(T) ∫_0^min(t,T) g(t − s) ds / T (studies.problems.prony_ramp_integral):
  the recursion is exact for S_e linear over each step, whatever the law, so the tolerance is
  round-off. The two regions' internal variables have distinct checkpoint names.
- Frequency route: a pulp series with one term g = 1/2 and τ = 1 ns relaxes within every time
  step and, at 2 Hz (ωτ ~ 1e-8), G*(ω) = 1/2 + O(ωτ): the fingertip's dynamic stiffness must
  equal that of the same finger whose pulp moduli are halved and elastic, and so must the
  transfer to the stress in the pulp (SiteTransfer: each QLV region's own G*(ω)). A route that
  ignored the pulp's G*(ω) (its instantaneous tangent) would be stiffer by the pulp's share.
"""

import numpy as np
import pytest
from dolfinx import fem, mesh
from mpi4py import MPI

from fingertip_dolfinx.geometry.mesh import build_mesh
from fingertip_dolfinx.harmonic import HarmonicSolver, linearise, press
from fingertip_dolfinx.loading import RampHold
from fingertip_dolfinx.model import ModelOptions, State, compose_laws
from fingertip_dolfinx.physics.kinematics import deformation_gradient
from fingertip_dolfinx.physics.tissues import load_materials
from fingertip_dolfinx.problem import FingertipProblem
from fingertip_dolfinx.scene import load_scene
from fingertip_dolfinx.studies.problems import prony_ramp_integral

#: Test values, not tissue data: a pulp series unlike the skin's (the damped set's).
PULP_PRONY = {"g": [0.3, 0.25], "tau": [0.002, 0.05]}
T_STEP = 0.004  # s: the one step that strains the cells (of the order of the fast τ)


@pytest.fixture(scope="module")
def two_cells():
    """The unit square's two triangles: cell 0 skin, cell 1 subcutaneous; the laws of the
    damped set with PULP_PRONY on the subcutaneous solid."""
    tissues = load_materials("damped-fingerpad", {"subcutaneous": {"prony": PULP_PRONY}})
    msh = mesh.create_unit_square(MPI.COMM_SELF, 1, 1)
    u = fem.Function(fem.functionspace(msh, ("Lagrange", 1, (2,))))
    dt = fem.Constant(msh, T_STEP)
    empty = np.array([], dtype=np.int32)
    cells = {"skin": np.array([0], dtype=np.int32), "subcutaneous": np.array([1], dtype=np.int32),
             "bone": empty, "nail": empty}
    options = ModelOptions()
    laws = compose_laws(tissues, options, State(u, deformation_gradient(u), dt,
                                                options.quadrature_degree, cells))
    return tissues, laws, u, dt, cells


def test_each_region_relaxes_with_its_own_series(two_cells):
    tissues, laws, u, dt, cells = two_cells
    # 10 % compression and 5 % shear, homogeneous: u = (γ y, −0.1 y).
    u.interpolate(lambda x: np.vstack([0.05 * x[1], -0.1 * x[1]]))
    series = {"skin": tissues.skin_prony, "subcutaneous": tissues.subcutaneous_prony}
    qlvs = {r: laws.regions[r].history for r in series}
    points = qlvs["skin"].space.element.interpolation_points
    total = {r: fem.Expression(q.stress(), points) for r, q in qlvs.items()}
    elastic = {r: fem.Expression(q.S_e, points).eval(u.function_space.mesh, cells[r])
               for r, q in qlvs.items()}
    t, worst = 0.0, 0.0
    for step in [T_STEP, 1e-3, 0.01, 0.03, 0.2, 1.0, 5.0, 20.0]:
        t += step
        dt.value = step
        for r in qlvs:
            S = total[r].eval(u.function_space.mesh, cells[r])
            exact = elastic[r] * prony_ramp_integral(series[r], t, T_STEP) / T_STEP
            worst = max(worst, np.abs(S - exact).max() / np.abs(exact).max())
        for q in laws.with_history():
            q.history.advance()
    assert worst < 1e-12
    # The series differ enough that swapping them would fail: g(t) at 10 ms differs by >10 %.
    g = {r: prony_ramp_integral(p, 0.01, 1e-9) / 1e-9 for r, p in series.items()}
    assert abs(g["skin"] - g["subcutaneous"]) > 0.1


def test_the_two_histories_have_their_own_checkpoint_names(two_cells):
    _, laws, *_ = two_cells
    names = set(laws.history_arrays())
    assert {"qlv_h0", "qlv_S_e_n", "qlv_subcutaneous_h0", "qlv_subcutaneous_h1",
            "qlv_subcutaneous_S_e_n"} <= names
    assert len(names) == 7 + 1 + 2 + 1  # the skin's 7 terms and S_e^n, the pulp's 2 and S_e^n


def _response_at_2hz(overrides: dict) -> tuple[complex, np.ndarray]:
    """The coarse 1pt fingertip pressed 0.5 mm and held: its dynamic stiffness at 2 Hz and the
    transfer to −σ22 − p at two points of the pulp under the bar (SiteTransfer)."""
    from fingertip_dolfinx.frequency_response import SiteTransfer

    scene = load_scene("1pt", ["section.mesh.min_size=0.2", "section.mesh.max_size=1.0",
                               "section.mesh.bone_size=2.0"])
    tissues = load_materials("wu2004", overrides)
    problem = FingertipProblem(build_mesh(scene.section), scene.indenters, scene.history,
                               tissues, scene.model)
    press(problem, RampHold(0.5, 1.0, 1.0), "held", scene.steps)
    solver = HarmonicSolver(linearise(problem))
    try:
        response = solver.solve(2.0)
        points = np.array([[0.0, problem.y_touch + 2.0], [0.3, problem.y_touch + 2.5]])
        stress = SiteTransfer(problem, points)(response)["compressive_stress"]
        return response.stiffness, stress
    finally:
        solver.close()


@pytest.mark.slow
def test_the_pulps_complex_modulus_enters_the_frequency_route():
    """Serial (SiteTransfer's values are on rank 0)."""
    mu = load_materials("wu2004").subcutaneous.solid.mu
    damped = _response_at_2hz({"subcutaneous": {"prony": {"g": [0.5], "tau": [1e-9]}}})
    halved = _response_at_2hz({"subcutaneous": {"mu": [0.5 * m for m in mu]}})
    full = _response_at_2hz({})
    # The pressed states agree to τ/Δt ~ 1e-8 and G*(2 Hz) = 1/2 to ωτ ~ 1e-8: the bound
    # leaves room for Newton's converged iterates; the pulp's share is far larger.
    assert abs(damped[0] - halved[0]) < 1e-5 * abs(halved[0])
    assert abs(full[0] - halved[0]) > 1e-3 * abs(halved[0])
    # The stress in the pulp: its own G*(ω) (the skin's G*(2 Hz) − g∞ = 0.85 would differ).
    np.testing.assert_allclose(damped[1], halved[1], rtol=1e-5)
    assert np.all(np.abs(full[1] - halved[1]) > 1e-3 * np.abs(halved[1]))
