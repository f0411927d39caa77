"""Compaction is a physical limit: the time stepper recognises the approach to
J = φ0 where it first happens (nodes included), stops at once with a `CompactionError` that
names compaction, the time, the place, the permeability and what it means, keeps the results
up to the last good step, and prints times that can be told apart.

The issue's column: the Holmes–Mow tissue with ν = 0 (the hyperfoam limit) and k0 = 1
mm⁴/(N·s), 1 mm high, drained on top, compressed by 20 % of its height over 100 s. The
drainage time H²/(k0 M) is ~1700 s, so the fluid leaves only through a thin layer under the
drained top, which is squeezed to its solid fraction near t = 36 s; with ν = 0 the drained
hyperfoam cannot resist (its confined stress grows only like 1/λ), so no time step can avoid it.
"""

import json
import re

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI

from fingertip_dolfinx.errors import CompactionError, ConvergenceError, InputError
from fingertip_dolfinx.loading import RampHold
from fingertip_dolfinx.physics import materials as mat
from fingertip_dolfinx.physics.admissibility import Admissibility, Compaction, quadrature_points
from fingertip_dolfinx.stepping import StepOptions, TimeStepper, crosses, distinct
from fingertip_dolfinx.studies.problems import ConfinedBlock

HM = mat.HOLMES_MOW_SUBCUTANEOUS
SOLID_NU0 = mat.Hyperfoam(mu=mat.SUBCUTANEOUS.mu, alpha=mat.SUBCUTANEOUS.alpha, nu=0.0)
TISSUE = mat.Biphasic(SOLID_NU0, mat.HolmesMow(k0=1.0, phi0=HM.phi0, kappa=HM.kappa, M=HM.M))
RAMP = RampHold(0.2, 100.0, 100.0)  # 20 % of the 1 mm height over 100 s
STEP_RE = r"compaction at t = (\S+) s \(the step from t = (\S+) s, Δt = (\S+) s\)"


def _issue_column(margin: float):
    """Run the issue's column until it stops; returns (error, accepted reports, column, the
    last accepted unknowns)."""
    column = ConfinedBlock(1, 20, RAMP, tissue=TISSUE, width=0.1, drained_top=True,
                           top_displacement=True, compaction_margin=margin)
    stepper = TimeStepper(column, StepOptions(), prefix=f"issue11_{abs(margin):g}_")
    reports, states = [], []

    def keep(report):
        reports.append(report)
        states.append([f.x.array.copy() for f in column.unknowns])

    with pytest.raises(CompactionError) as error:
        stepper.run(RAMP, RAMP.end_time, on_step=keep)
    stepper.close()
    return error.value, reports, column, states[-1]


@pytest.mark.parametrize("margin", [0.0, 0.02])
def test_the_issue_column_stops_at_compaction_and_says_so(margin):
    """Margin 0 (the issue's first try: it ended in NaN after cuts to Δt = 1e-5 s) and the
    fingertip's 0.02: both stop at once, between 30 and 40 s, at the drained top."""
    error, reports, column, last = _issue_column(margin)
    message = str(error)
    assert isinstance(error, ConvergenceError)  # the runner's path: results kept, summary
    t_end, t_start, dt = re.search(STEP_RE, message).groups()
    assert t_end != t_start and float(t_end) > float(t_start)
    assert 30.0 < float(t_end) < 40.0, message
    assert float(dt) > 0.1, "stopped at once, not after cutting the step down"
    x, y = (float(v) for v in re.search(r"near x = \((\S+), (\S+)\) mm", message).groups())
    assert 0 <= x <= 0.1 and y > 0.95, message  # at the drained top
    assert "k0 = 1 mm^4/(N s)" in message and "phi0 = 0.4" in message
    assert "too fast or too large" in message and "smaller time steps cannot help" in message
    assert "allow smaller steps" not in message
    crossing = float(re.search(r"crossed \S+ near t = (\S+) s", message).group(1))
    assert float(t_start) < crossing < float(t_end)
    J = float(re.search(r"J reached (\S+) at a node", message).group(1))
    assert J <= 0.4 + margin
    # results up to the last good step: reported, and the state restored to it
    saved = float(re.search(r"Results up to t = (\S+) s are saved", message).group(1))
    assert reports[-1].time == pytest.approx(saved, rel=1e-5)  # printed to 6 digits
    assert saved == float(t_start)
    assert reports[-1].diagnostics["J_min"] > 0.4 + margin
    for f, a in zip(column.unknowns, last):
        np.testing.assert_array_equal(f.x.array, a)


@pytest.mark.parametrize("line_search", ["bt", "basic"])
def test_closed_pores_in_a_failing_newton_iterate_are_compaction(line_search):
    """Without the predictor, the step that crosses the limit fails in Newton: the residual
    turns non-finite at an iterate whose pores closed ((J − φ0)^κ is NaN at a quadrature
    point below φ0). Found in two attempts in a row (the step and its half), that is
    compaction: the stepper stops at once and says so."""
    column = ConfinedBlock(1, 20, RAMP, tissue=TISSUE, width=0.1, drained_top=True,
                           top_displacement=True, compaction_margin=0.0)
    stepper = TimeStepper(column, StepOptions(extrapolate=False),
                          {"snes_linesearch_type": line_search}, prefix=f"issue11_{line_search}_")
    with pytest.raises(CompactionError, match="in the last Newton iterate") as error:
        stepper.run(RAMP, RAMP.end_time)
    stepper.close()
    message = str(error.value)
    assert "at a quadrature point" in message and "smaller time steps cannot help" in message
    _, t_start, dt = re.search(STEP_RE, message).groups()
    assert 30.0 < float(t_start) < 40.0 and float(dt) > 0.1, message
    with pytest.raises(InputError, match="compaction_margin"):
        ConfinedBlock(1, 2, RAMP, tissue=TISSUE, compaction_margin=-0.02)


@pytest.mark.parametrize("J0, J1, t_reach, heading", [
    (0.50, 0.45, 3.0, True),    # falls 0.05 a second: reaches 0.4 at t = 2 s, within the step
    (0.50, 0.45, 1.5, False),   # the same fall, but the step ends at 1.5 s (J = 0.425)
    (1.00, 1.00, 1e3, False),   # an undrained tissue (J = 1): an iterate at J < phi0 overshot
    (0.45, 0.50, 1e3, False),   # rising J (unloading)
])
def test_closed_iterates_count_as_compaction_only_where_the_states_head(J0, J1, t_reach,
                                                                       heading):
    """The accepted states at t = 0 and 1 s, extrapolated linearly, against phi0 = 0.4."""
    assert crosses(0.0, J0, 1.0, J1, t_reach, 0.4) is heading


def test_J_below_phi0_only_at_a_node_is_caught():
    """u = (0, −0.31 y²) on the unit square: J = 1 − 0.62 y falls to 0.38 < φ0 at the top
    vertices, while every quadrature point of the degree-4 rule stays above φ0 + 0.02."""
    msh = mesh.create_unit_square(MPI.COMM_SELF, 1, 1)
    u = fem.Function(fem.functionspace(msh, ("Lagrange", 2, (2,))))
    u.interpolate(lambda x: np.vstack([0 * x[0], -0.31 * x[1] ** 2]))
    F = ufl.Identity(2) + ufl.grad(u)
    cells = np.arange(msh.topology.index_map(2).size_local, dtype=np.int32)
    at_quadrature = fem.Expression(ufl.det(F), quadrature_points(msh, 4)).eval(msh, cells)
    assert at_quadrature.min() > 0.42  # the old check saw nothing
    check = Admissibility(F, msh, 4, Compaction(cells, 0.4, 0.02, k0=1e-3))
    found = check.compacted()
    assert found is not None and found.lowest.at_node
    assert found.J == pytest.approx(0.38, rel=1e-12)
    assert found.x[1] == pytest.approx(1.0)  # a top vertex
    assert check.violation().startswith("compaction: the tissue's volume ratio J reached 0.38 "
                                         "at a node near x = (")
    assert check.compacted(nodes=False) is None


def test_failure_times_are_printed_with_the_digits_that_tell_them_apart():
    """The issue's 'from t = 36.4231 s to t = 36.4231 s': a step of 1e-5 s at t = 36.4231 s
    that Newton cannot finish (one iteration allowed, tolerances unreachable)."""
    assert distinct(36.4231, 36.4231 + 1e-5) == ("36.4231", "36.42311")
    assert distinct(0.5, 0.75) == ("0.5", "0.75")
    column = ConfinedBlock(1, 2, RAMP, tissue=mat.SUBCUTANEOUS_BIPHASIC, width=0.1,
                           drained_top=True, top_displacement=True)
    stepper = TimeStepper(
        column, StepOptions(dt_initial=1e-5, dt_min=1e-6, dt_max=1e-5, max_cuts=0),
        {"snes_max_it": 1, "snes_rtol": 1e-30, "snes_atol": 1e-30}, prefix="issue11_digits_")
    with pytest.raises(ConvergenceError) as error:
        stepper.run(RAMP, RAMP.end_time, start_time=36.4231)
    stepper.close()
    message = str(error.value)
    assert not isinstance(error.value, CompactionError)
    a, b = re.search(r"the step from t = (\S+) s to t = (\S+) s", message).groups()
    assert a != b and float(b) - float(a) == pytest.approx(1e-5, rel=1e-6), message
    loads = re.search(r"\(load (\S+) -> (\S+)\)", message).groups()
    assert loads[0] != loads[1], message


def test_the_fingertip_stops_on_compaction_and_keeps_its_results(tmp_path):
    """The one-point scene, coarse, with a tissue that is 90 % solid and drains within the
    ramp (k0 = 1e3): it compacts under the bar. The run stops with the compaction message
    (no advice of smaller steps), summary.json says not converged and why, and every accepted
    step is on disk."""
    from fingertip_dolfinx.outputs import read_csv
    from fingertip_dolfinx.runner import run_scene
    from fingertip_dolfinx.scene import load_scene

    scene = load_scene("1pt", ["section.mesh.min_size=0.2", "section.mesh.max_size=1.0",
                               "section.mesh.bone_size=2.0", "output.profile_points=121",
                               "materials.subcutaneous.phi0=0.9",
                               "materials.subcutaneous.permeability.k0=1e3"])
    with pytest.raises(ConvergenceError) as error:
        run_scene(scene, tmp_path, progress=False, comm=MPI.COMM_SELF)
    message = str(error.value)
    assert message.startswith("compaction at t = ")
    assert "phi0 = 0.9" in message and "k0 = 1000 mm^4/(N s)" in message
    assert "smaller time steps cannot help" in message and "allow smaller steps" not in message
    x, y = (float(v) for v in re.search(r"near x = \((\S+), (\S+)\) mm", message).groups())
    assert abs(x) < 2.0 and y < -4.0  # under the bar, in the palmar tissue
    saved = float(re.search(r"Results up to t = (\S+) s are saved", message).group(1))
    h = read_csv(tmp_path / "history.csv")
    assert len(h["time_s"]) >= 1 and h["time_s"][-1] == pytest.approx(saved, rel=1e-9)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["converged"] is False and summary["failure"] == message
