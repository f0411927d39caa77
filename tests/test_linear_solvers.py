"""The linear solvers inside Newton (stepping/linear.py): the iterative route (FGMRES, Schur field
split, GAMG with the rigid-body near null space) against MUMPS on a coarse fingertip; its
Krylov iterations under refinement; 1 against 2 ranks; the near null space itself in 2D and 3D.
The 4x finer fingertip comparison is benchmarks/iterative_solver.py (too slow for a test)."""

from types import SimpleNamespace

import dolfinx.fem.petsc
import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI
from petsc4py import PETSc

from fingertip_dolfinx.errors import InputError
from fingertip_dolfinx.geometry.mesh import build_mesh
from fingertip_dolfinx.harmonic import press
from fingertip_dolfinx.loading import RampHold
from fingertip_dolfinx.problem import FingertipProblem
from fingertip_dolfinx.scene import load_scene, scene_record
from fingertip_dolfinx.stepping import StepOptions, TimeStepper
from fingertip_dolfinx.stepping.linear import LinearSolver, rigid_body_modes

#: A coarse 1pt fingertip (biphasic subcutaneous tissue: the (u, p) split), bone and nail rigid:
#: the iterative route's recommended model (elastic bone: see the benchmark).
COARSE = {"section.mesh.min_size": 0.4, "section.mesh.max_size": 2.0,
          "section.mesh.bone_size": 4.0, "model.rigid_bone": True}
#: Two steps of 0.05 s of the ramp (0.1 mm deep).
STEPS = StepOptions(dt_initial=0.05, dt_min=0.05, dt_max=0.05, max_cuts=0)


def _press(linear: str, comm=MPI.COMM_WORLD, h: float | None = None, **overrides):
    """The coarse fingertip pressed two steps with `linear` (scene `overrides`, e.g.
    model.rigid_bone): (problem, stepper, Newton its)."""
    sizes = dict(COARSE)
    if h is not None:
        sizes |= {"section.mesh.min_size": h, "section.mesh.max_size": 5 * h,
                  "section.mesh.bone_size": 10 * h}
    sizes |= overrides
    scene = load_scene("1pt", [f"{k}={str(v).lower()}" for k, v in sizes.items()])
    problem = FingertipProblem(build_mesh(scene.section, comm), scene.indenters, scene.history,
                               scene.materials, scene.model)
    stepper = TimeStepper(problem, STEPS, scene.petsc_options, prefix=f"lin_{linear}_",
                          linear=linear)
    newton = sum(r.newton_iterations for r in stepper.run(scene.history, 0.1))
    return problem, stepper, newton


def _last_update(stepper) -> float:
    """∞-norm of Newton's last correction: Newton's error after it is at most about this (it
    converges superlinearly: the next correction, the remaining error, is far smaller)."""
    return stepper.snes.getSolutionUpdate().norm(norm_type=3)  # NORM_INFINITY


def test_iterative_equals_direct():
    """The iterative and the direct solution lie within the sum of their last Newton
    corrections: both are Newton's answer to the same residual tolerance."""
    solutions, bounds = [], []
    for linear in ("direct", "iterative"):
        problem, stepper, _ = _press(linear)
        solutions.append(np.concatenate([f.x.array for f in problem.unknowns]))
        bounds.append(_last_update(stepper))
        stepper.close()
    assert np.max(np.abs(solutions[0])) > 1e-3  # mm: pressed
    assert np.max(np.abs(solutions[1] - solutions[0])) <= sum(bounds)


def _solution(problem) -> np.ndarray:
    return np.concatenate([f.x.array for f in problem.unknowns])


def test_inexact_newton_solves_loosely_to_the_same_answer():
    """Eisenstat-Walker linear tolerances (the default) against exact solves (ksp_rtol 1e-10):
    under half the Krylov iterations in all (the early Newton steps need no 1e-10), and the
    same answer within the sum of the last Newton corrections (Newton's tolerances decide)."""
    runs = []
    for overrides in ({}, {"solver.snes_ksp_ew": False}):
        problem, stepper, _ = _press("iterative", **overrides)
        runs.append((_solution(problem), _last_update(stepper), stepper.linear_iterations))
        stepper.close()
    (inexact, d1, k1), (exact, d2, k2) = runs
    assert k1 < 0.5 * k2, (k1, k2)
    assert np.max(np.abs(inexact - exact)) <= d1 + d2


def _record_linear_reductions(stepper, reductions: list) -> None:
    """Append to `reductions`, per Newton iteration of `stepper`, its linear solve's residual
    reduction (last over first norm of the Krylov history; unpreconditioned: the true residual)."""
    ksp = stepper.snes.getKSP()
    ksp.setConvergenceHistory(length=1000, reset=True)

    def watch(snes, its, fnorm):
        if its > 0:
            history = ksp.getConvergenceHistory()
            reductions.append(history[-1] / history[0])

    stepper.snes.setMonitor(watch)


def test_inexact_newton_solves_each_system_tenfold_to_the_direct_answer(monkeypatch):
    """Elastic bone and nail, inexact Newton: where a Newton iteration cuts the residual little
    (the contact set changing), Eisenstat-Walker's choice 2 loosens the next solve to η ≈ 0.5
    (measured here: 0.49, one Krylov iteration); capped at 0.1, every linear solve reduces its
    true residual at least 10-fold (PETSc's test: ‖r‖ ≤ η ‖b‖), and the answer is MUMPS's within
    the sum of the last Newton corrections."""
    reductions, init = [], TimeStepper.__init__

    def init_and_watch(self, *args, **kwargs):
        init(self, *args, **kwargs)
        if self.linear.linear == "iterative":
            _record_linear_reductions(self, reductions)

    monkeypatch.setattr(TimeStepper, "__init__", init_and_watch)
    solutions, bounds = {}, {}
    for linear in ("iterative", "direct"):
        problem, stepper, _ = _press(linear, **{"model.rigid_bone": False})
        solutions[linear], bounds[linear] = _solution(problem), _last_update(stepper)
        stepper.close()
    assert reductions and max(reductions) <= 0.1, reductions
    difference = np.max(np.abs(solutions["iterative"] - solutions["direct"]))
    assert difference <= bounds["iterative"] + bounds["direct"]


def test_elastic_bone_and_nail_cost_no_more_krylov_iterations_than_rigid():
    """With bone and nail elastic the displacement block is split into the stiff regions' dofs
    (LU) and the soft tissues' (GAMG): the Krylov iterations per Newton step (exact solves, so
    the count measures the preconditioner) stay within 1.5x the rigid model's, where GAMG on the
    whole block took 5.6x (174 against 31: the nail plate's bending); the answer is MUMPS's
    within the last Newton corrections."""
    per_newton, solutions, bounds = {}, {}, {}
    for rigid, linear in ((True, "iterative"), (False, "iterative"), (False, "direct")):
        problem, stepper, newton = _press(linear, **{"model.rigid_bone": rigid,
                                                     "solver.snes_ksp_ew": False})
        per_newton[rigid, linear] = stepper.linear_iterations / newton
        solutions[linear], bounds[linear] = _solution(problem), _last_update(stepper)
        stepper.close()
    assert per_newton[False, "iterative"] <= 1.5 * per_newton[True, "iterative"], per_newton
    difference = np.max(np.abs(solutions["iterative"] - solutions["direct"]))
    assert difference <= bounds["iterative"] + bounds["direct"]


def test_no_pore_pressure_with_elastic_bone_keeps_newton_quadratic():
    """Without pore pressure and with elastic bone and nail, the iterative route solves exactly:
    Newton then takes MUMPS's iterations (at most one more, round-off at the tolerance), where
    the inexact Newton crawled (42 against 7: the bone's rows swamp the residual norm)."""
    newton = {}
    for linear in ("direct", "iterative"):
        _, stepper, newton[linear] = _press(linear, **{"model.rigid_bone": False,
                                                       "model.subcutaneous": "drained"})
        stepper.close()
    assert newton["iterative"] <= newton["direct"] + 1, newton


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="serial: meshes of two sizes")
def test_krylov_iterations_within_a_factor_two_at_half_the_size():
    """Krylov iterations per Newton step on the coarse mesh and on one of half the element
    size (about 3x the dofs) stay within a factor 2 (h-independent preconditioner)."""
    per_newton = []
    for h in (0.4, 0.2):
        _, stepper, newton = _press("iterative", h=h)
        per_newton.append(stepper.linear_iterations / newton)
        stepper.close()
    assert per_newton[1] <= 2 * per_newton[0]


def test_harmonic_press_takes_the_scene_linear_solver():
    """The frequency route's press (harmonic.press) solves with the linear solver it is given:
    the iterative one runs GMRES (orthogonalisations logged), the direct one none, and both
    reach the same pressed force (Newton's residual tolerance: rtol 1e-6 of the force)."""
    PETSc.Log.begin()
    orthogonalisations = PETSc.Log.Event("KSPGMRESOrthog")
    forces, krylov = {}, {}
    for linear in ("direct", "iterative"):
        scene = load_scene("1pt", [f"{k}={str(v).lower()}" for k, v in COARSE.items()])
        problem = FingertipProblem(build_mesh(scene.section), scene.indenters, scene.history,
                                   scene.materials, scene.model)
        before = orthogonalisations.getPerfInfo().get("count", 0)
        forces[linear] = press(problem, RampHold(0.1, 0.1, 0.1), "held", STEPS,
                               scene.petsc_options, linear=linear).force
        krylov[linear] = orthogonalisations.getPerfInfo().get("count", 0) - before
    assert krylov["direct"] == 0 and krylov["iterative"] > 0, krylov
    assert forces["direct"] > 0
    assert forces["iterative"] == pytest.approx(forces["direct"], rel=1e-6)


@pytest.mark.mpi
@pytest.mark.parametrize("rigid", [True, False])
def test_one_and_two_ranks_agree(rigid):
    """The iterative solve on all ranks against the same mesh solved on each rank alone
    (COMM_SELF): max |u| and the force agree within the sum of the last Newton corrections
    (max |u| moves by at most the largest change of u). Elastic bone and nail: the stiff/soft
    split's index sets across the partition."""
    results = []
    for comm in (MPI.COMM_SELF, MPI.COMM_WORLD):
        problem, stepper, _ = _press("iterative", comm, **{"model.rigid_bone": rigid})
        u = problem.u.x.array
        results.append((comm.allreduce(np.max(np.abs(u)), op=MPI.MAX), _last_update(stepper)))
        stepper.close()
    (u1, d1), (u2, d2) = results
    assert u1 > 1e-3
    assert abs(u1 - u2) <= d1 + d2


def _elastic_block(msh, clamp: bool):
    """Linear elasticity (E = 1, ν = 0.3) on `msh`, clamped on x = 0 if `clamp`, pulled by a
    body force; as a NonlinearProblem (one Newton step solves it)."""
    gdim = msh.geometry.dim
    V = fem.functionspace(msh, ("Lagrange", 1, (gdim,)))
    u, v = fem.Function(V), ufl.TestFunction(V)
    lmbda, mu = 0.3 / (1.3 * 0.4), 1 / 2.6
    eps = ufl.sym(ufl.grad(u))
    sigma = lmbda * ufl.tr(eps) * ufl.Identity(gdim) + 2 * mu * eps
    f = ufl.as_vector([0.0] * (gdim - 1) + [-1.0])
    R = ufl.inner(sigma, ufl.grad(v)) * ufl.dx - ufl.inner(f, v) * ufl.dx
    bcs = []
    if clamp:
        facets = mesh.locate_entities_boundary(msh, gdim - 1, lambda x: np.isclose(x[0], 0))
        dofs = fem.locate_dofs_topological(V, gdim - 1, facets)
        bcs = [fem.dirichletbc(np.zeros(gdim), dofs, V)]
    return u, R, bcs


@pytest.mark.parametrize("gdim", [2, 3])
def test_rigid_body_modes_are_the_kernel_of_elasticity(gdim):
    """The near null space (3 modes in 2D, 6 in 3D) is orthonormal and the unclamped stiffness
    maps each mode to zero (round-off: 1e-12 of ‖K‖)."""
    comm = MPI.COMM_WORLD
    msh = (mesh.create_unit_square(comm, 4, 4) if gdim == 2
           else mesh.create_unit_cube(comm, 3, 3, 3))
    u, R, _ = _elastic_block(msh, clamp=False)
    K = dolfinx.fem.petsc.assemble_matrix(fem.form(ufl.derivative(R, u)))
    K.assemble()
    space = rigid_body_modes(u.function_space)
    modes = space.getVecs()
    assert len(modes) == 3 * (gdim - 1)
    gram = np.array([[a.dot(b) for b in modes] for a in modes])
    np.testing.assert_allclose(gram, np.eye(len(modes)), atol=1e-12)
    assert space.test(K)  # PETSc's own check: ‖K z‖ small for every z
    Kz = K.createVecLeft()
    for z in modes:
        K.mult(z, Kz)
        assert Kz.norm() <= 1e-12 * K.norm()


def _gamg_iterations(n: int) -> int:
    msh = mesh.create_box(MPI.COMM_WORLD, [[0, 0, 0], [4, 1, 1]], [4 * n, n, n])
    u, R, bcs = _elastic_block(msh, clamp=True)
    linear = LinearSolver("iterative", SimpleNamespace(unknowns=[u]))
    problem = dolfinx.fem.petsc.NonlinearProblem(
        R, u, bcs=bcs, petsc_options_prefix=f"box{n}_",
        petsc_options={"snes_type": "ksponly", **linear.options})
    linear.attach(problem, f"box{n}_", linear.options)
    problem.solve()
    assert problem.solver.getConvergedReason() > 0
    its = problem.solver.getLinearSolveIterations()
    linear.release()
    return its


def test_gamg_iterations_bounded_on_a_3d_box():
    """GAMG with the 6 rigid-body modes on a clamped 3D elastic bar: the Krylov iterations of
    the mesh of twice the cells per direction (8x the dofs) are within 2x those of the coarse."""
    coarse, fine = _gamg_iterations(2), _gamg_iterations(4)
    assert fine <= 2 * coarse


def test_scene_chooses_the_linear_solver():
    scene = load_scene("1pt")
    assert scene.linear == "direct"
    assert scene_record(scene)["solver"]["linear"] == "direct"
    scene = load_scene("line-load", ["solver.linear=iterative",
                                     "solver.petsc_options.ksp_rtol=1e-9"])
    assert scene.linear == "iterative"
    assert scene.petsc_options == {"snes_atol": 1e-9, "ksp_rtol": 1e-9}
    with pytest.raises(InputError) as error:
        load_scene("1pt", ["solver.linear=cg"])
    assert "solver.linear" in error.value.where and "'iterative'" in error.value.fix


@pytest.mark.parametrize("option", ["pc_type=cholesky", "petsc_options.pc_type=icc"])
def test_a_scene_cannot_ask_for_a_symmetric_factorisation(option):
    """The Jacobian is unsymmetric (pressure coupling, contact, friction): a Cholesky or ICC
    factor of one triangle would be a wrong Newton direction, refused with the key named."""
    with pytest.raises(InputError) as error:
        load_scene("line-load", [f"solver.{option}"])
    assert error.value.where.endswith("pc_type") and "lu" in error.value.fix


def test_the_stepper_refuses_a_symmetric_factorisation_from_the_api():
    from fingertip_dolfinx.stepping.options import check_petsc_options

    assert check_petsc_options({"pc_type": "lu"}) == {"pc_type": "lu"}
    with pytest.raises(InputError, match="symmetric"):
        check_petsc_options({"fieldsplit_u_pc_type": "cholesky"}, "petsc_options")
