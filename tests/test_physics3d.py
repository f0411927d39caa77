"""The 3D model's exact checks: Hertz's sphere, the confined biphasic column against
the plane-strain one, and the equilibrium of a layered block through the fingertip problem.

- Hertz (`studies.problems.HertzSphere`): a rigid sphere on a linear-elastic quarter block,
  contact radius a = (3PR/(4E*))^(1/3) and peak pressure p0 = 3P/(2πa²) for the measured force.
  Measured (a/R = 0.05, L = 20a; h at the contact a/1.5, a/2, a/3, a/5): a −3.8, −1.7, −2.1,
  −0.7 %; p0 +2.8, −0.8, −0.4, −0.04 %; L = 40a at h = a/3 moved a and p0 by 0.1 %.
- The confined column: its state C = diag(1, λ², 1) has a double eigenvalue away from C ∝ I,
  where the 3D eigenvalue sum's Cardano form had NaN derivatives (kinematics._eigen_sum_3d).
  The 3D column (tetrahedra, rollers on x and z) and the 2D column (triangles, rollers on x)
  discretise the same one-dimensional problem; they differ by their discretisation errors
  only, which fall with the mesh (measured: settlement 1.2e-5 → 3.3e-6 relative, pressure
  1.2e-3 → 7e-4 of its peak, from 8 to 16 cells over the height), and both end at the drained
  closed form.
- The layered block (`studies.problems.layered_block`): FingertipProblem + TimeStepper, the
  real path, with a sphere and an "x" bar: the indenter force equals the nail-centre reaction
  at every step (the rollers of the symmetry and proximal-cut planes carry no y-force).
"""

import math

import numpy as np
import pytest
from mpi4py import MPI
from scipy.optimize import brentq

from fingertip_dolfinx.geometry.indenters import Bar, Sphere
from fingertip_dolfinx.loading import RampHold
from fingertip_dolfinx.model import ModelOptions
from fingertip_dolfinx.physics import materials as mat
from fingertip_dolfinx.problem import FingertipProblem
from fingertip_dolfinx.stepping import DEFAULT_PETSC_OPTIONS, StepOptions, TimeStepper
from fingertip_dolfinx.studies.problems import (
    ConfinedBlock,
    HertzSphere,
    confined_drained_stress,
    confined_modulus,
    contact_edge,
    layered_block,
    newton_problem,
)

HERTZ = HertzSphere()


def hertz_sphere(n: float) -> dict:
    """Indent the quarter block by HERTZ.depth in 2 steps, h = a_target/n at the contact."""
    domain, facet_tags = HERTZ.mesh(HERTZ.a_target / n, MPI.COMM_WORLD)
    block = HERTZ.block(domain, facet_tags)
    problem = newton_problem(block.residual, block.u, block.bcs, f"hertz3d_{n}_",
                             snes_rtol=1e-10, snes_atol=1e-13)
    for k in (1, 2):
        block.obstacle.y_tip.value = HERTZ.depth * k / 2
        problem.solve()
        assert problem.solver.getConvergedReason() > 0, f"step {k} did not converge"
    r, p, s = block.profile()
    force = block.force()
    a, p0 = HERTZ.theory(force)
    assert 0.5 * HERTZ.a_target < a < 2 * HERTZ.a_target, "not the small load intended"
    # Nitsche's gap at convergence is (t_n − p)/γ, γ = γ0 M/h: at most p0 h/(γ0 M) if the
    # traction estimate t_n is off by no more than p0 itself (measured: 0.15 of it at h = a/2).
    gap_bound = p0 * HERTZ.a_target / n / (10.0 * HERTZ.modulus)
    return {"force": force, "reaction": block.reaction(), "ea": abs(contact_edge(r, s) / a - 1),
            "ep": abs(p.max() / p0 - 1), "penetration": block.contact.max_penetration(),
            "gap_bound": gap_bound}


@pytest.mark.slow  # three 3D meshes; benchmarks/hertz_sphere.py prints the same table
def test_hertz_sphere_radius_and_peak_pressure_converge_to_theory():
    coarse, fine = hertz_sphere(2.0), hertz_sphere(5.0)
    print(f"Hertz 3D errors a, p0: h = a/2: {coarse['ea']:.2%}, {coarse['ep']:.2%}; "
          f"h = a/5: {fine['ea']:.2%}, {fine['ep']:.2%}")
    assert coarse["ea"] < 0.05 and coarse["ep"] < 0.05
    assert fine["ea"] < coarse["ea"] and fine["ep"] < coarse["ep"]
    for run in (coarse, fine):
        # Discrete equilibrium: the residual tested with e_y, split between contact and top.
        assert run["reaction"] == pytest.approx(-run["force"], rel=1e-7)
        assert run["penetration"] < run["gap_bound"], (run["penetration"], run["gap_bound"])


# ---- the confined biphasic column, 3D against 2D ------------------------------------------------

SOLID = mat.SUBCUTANEOUS
M = confined_modulus(SOLID)
#: k0 = 1/M: consolidation coefficient ~1 mm²/s on the 1 mm column, so the 3 s run passes from
#: the undrained response through consolidation to the drained state.
TISSUE = mat.Biphasic(SOLID, mat.HolmesMow(k0=1.0 / M, phi0=0.4, kappa=0.0848, M=4.638))
LOAD = RampHold(0.3 * M, 1.0, 3.0)  # MPa: ~11 % settlement, J down to 0.89


def column_history(gdim: int, ny: int) -> np.ndarray:
    column = ConfinedBlock(1, ny, LOAD, tissue=TISSUE, width=0.1, drained_top=True, gdim=gdim)
    stepper = TimeStepper(column, StepOptions(dt_initial=0.25, dt_max=0.25, growth=1.0),
                          prefix=f"confined{gdim}d_{ny}_")
    try:
        reports = stepper.run(LOAD, LOAD.end_time)
    finally:
        stepper.close()
    return np.array([[r.time, r.diagnostics["settlement"], r.diagnostics["core_pressure"]]
                     for r in reports])


def drained_settlement(sigma: float) -> float:
    """H (1 − λ) with the drained confined stress σ_yy(λ) = −σ (closed form)."""
    lam = brentq(lambda s: confined_drained_stress(SOLID, s)[1] + sigma, 0.5, 1.0, xtol=1e-15)
    return 1.0 - lam


def test_confined_column_in_3d_follows_the_2d_column():
    differences = []
    for ny in (4, 8):
        h2, h3 = column_history(2, ny), column_history(3, ny)
        np.testing.assert_array_equal(h2[:, 0], h3[:, 0])
        differences.append((np.abs(h3[:, 1] / h2[:, 1] - 1).max(),
                            np.abs(h3[:, 2] - h2[:, 2]).max() / np.abs(h2[:, 2]).max()))
    print(f"3D vs 2D (settlement rel., pressure / peak): ny = 4: {differences[0]}, "
          f"ny = 8: {differences[1]}")
    # Both discretise one 1D problem: their difference is discretisation error, which falls.
    assert differences[1][0] < differences[0][0] and differences[1][1] < differences[0][1]
    assert differences[1][0] < 1e-4 and differences[1][1] < 5e-3
    # The end (t = 3 s, ~e^(−π² c t/4) ≈ 1e-3 of the load left in the pores... measured
    # p_core/σ = 2e-6) is the drained closed form, in 3D as in 2D.
    assert h3[-1, 2] < 1e-4 * LOAD.depth
    assert h3[-1, 1] == pytest.approx(drained_settlement(LOAD.depth), rel=1e-3)


# ---- the layered block through the fingertip problem -------------------------------------------

@pytest.fixture(scope="module")
def block():
    return layered_block(MPI.COMM_WORLD)


#: The 3D scenes' quadrature degree (data/scenes/*-3d.toml), so that the sphere's forms are
#: test_run3d.py's probe's.
THREE_D = ModelOptions(quadrature_degree=2)


# The bar's forms compile for ~4 min on a cold cache (the sphere's are shared with
# test_run3d.py's): it runs with the slow studies.
@pytest.mark.parametrize("indenter", [Sphere(radius=2.0, centre_z=3.0),
                                      pytest.param(Bar(width=1.0, axis="x", centre_z=3.0),
                                                   marks=pytest.mark.slow)],
                         ids=["sphere", "bar-x"])
def test_layered_block_indenter_force_equals_support_reaction(block, indenter):
    history = RampHold(0.3, 1.0, 1.5)
    problem = FingertipProblem(block, [indenter], history, options=THREE_D)
    assert problem.p is not None  # the biphasic subcutaneous tissue: P2/P1 on the submesh
    assert problem.force_keys == ("force_N", "reaction_N") and problem.mirror_factor == 2
    stepper = TimeStepper(problem, StepOptions(dt_initial=0.25, dt_max=0.5),
                          prefix=f"layered_{indenter.shape}_")
    try:
        reports = stepper.run(history, history.end_time)
    finally:
        stepper.close()
    force = np.array([r.diagnostics["force_N"] for r in reports])
    reaction = np.array([r.diagnostics["reaction_N"] for r in reports])
    assert reports[-1].time == pytest.approx(history.end_time)
    assert force[-1] > 0 and np.all(np.diff(force[: np.searchsorted(
        [r.time for r in reports], 1.0) + 1]) > 0)  # rising along the ramp
    np.testing.assert_allclose(reaction, force, rtol=1e-8, atol=DEFAULT_PETSC_OPTIONS["snes_atol"])
    assert np.max(np.abs(problem.p.x.array)) > 0
    assert max(r.diagnostics["max_penetration_mm"] for r in reports) < 0.01 * history.depth


# ---- derived fields in 3D ------------------------------------------------------------------------

@pytest.mark.parametrize("stretches", [(1.2, 0.8, 0.8), (1.3, 0.9, 0.7), (1.0, 1.0, 1.0)])
def test_derived_fields_in_3d_are_the_spectral_log_strain(stretches):
    """A homogeneous F = V R: ½ ln b = Q diag(ln λ) Qᵀ, principal (ln λ_max, ln λ_min), also at
    a double eigenvalue (uniaxial) and at F = I, where they are exactly 0."""
    from dolfinx import fem, mesh

    from fingertip_dolfinx.post import DerivedFields

    msh = mesh.create_unit_cube(MPI.COMM_SELF, 1, 1, 1)
    Q = np.linalg.qr(np.random.default_rng(3).normal(size=(3, 3)))[0]
    c, s = math.cos(0.4), math.sin(0.4)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    F = Q @ np.diag(stretches) @ Q.T @ R
    u = fem.Function(fem.functionspace(msh, ("Lagrange", 1, (3,))))
    u.interpolate(lambda x: (F - np.eye(3)) @ x)
    tags = mesh.meshtags(msh, 3, np.arange(6, dtype=np.int32), np.ones(6, dtype=np.int32))
    derived = DerivedFields(u, tags, {1: fem.Constant(msh, 0.0)})
    derived.update()
    expected = Q @ np.diag(np.log(stretches)) @ Q.T
    got = derived.log_strain.x.array.reshape(-1, 3, 3)
    assert np.abs(got - expected).max() < 1e-13
    principal = derived.principal.x.array.reshape(-1, 2)
    assert np.allclose(principal, np.log([max(stretches), min(stretches)]), rtol=0, atol=1e-13)
