"""The linear solver inside Newton: a direct LU (MUMPS) or a preconditioned Krylov method.

Every Newton step solves J δ = −R with J the Jacobian of the coupled problem: the displacement
block K (all regions) and, with a pore law, the pore pressure p on the subcutaneous submesh,

    J = [ K  −Bᵀ ]      K: elasticity + contact,  B: ∫ q J F⁻ᵀ : Grad δu (the mass balance),
        [ B   C  ]      C: Δt J k C⁻¹ Grad p · Grad q (biphasic; 0 undrained).

"direct" (the default): MUMPS LU of the whole of J; exact, robust; in 2D work ~ n^1.5, memory ~ n
log n.
"iterative": FGMRES preconditioned by a Schur-complement field split (PETSc PCFIELDSPLIT):
K by smoothed-aggregation algebraic multigrid (GAMG, told the rigid-body modes of the
displacement space: its near null space) and the pressure Schur complement
S = C + B K⁻¹ Bᵀ by GAMG on S_p = C + M/(λ + 2μ) (M the pressure mass matrix, λ + 2μ the
subcutaneous solid's P-wave modulus; C as assembled), "full" factorisation: of the Schur
approximations and factorisations tried, the one with the fewest Krylov iterations. Without a
pore law there is no split: FGMRES on K alone (CG is not safe: Nitsche's θ = 0 contact, the default,
makes K non-symmetric; the penalty's K is symmetric to round-off, benchmarks/jacobian_symmetry.py).
With bone and nail elastic, K itself is split into the stiff regions' dofs (LU) and the soft
tissues' (GAMG), block Gauss–Seidel: GAMG's coarse aggregates represent the bending of the thin,
stiff nail plate poorly (110-400 Krylov iterations per Newton step on K whole; with the split as
many as with bone and nail rigid). Newton is inexact (Eisenstat–Walker): each linear solve is as
tight as Newton's progress needs, not 1e-10. MUMPS stays the default: in 2D it is faster at these
sizes (LU fill ~ n log n); the Krylov route is for 3D. The measurements behind these choices:
docs/benchmarks/measurements.md, "Linear solvers inside Newton", and docs/benchmarks/solvers-3d.md.

Both are chosen by scene data (`[solver] linear = "direct" | "iterative"`, checked by
`options.check_linear`, which needs no PETSc); any PETSc option
given in `[solver]` overrides the configuration's (under the stepper's prefix:
`fieldsplit_u_pc_gamg_threshold = 0.02`, `snes_ksp_ew = false` with `ksp_rtol = 1e-10`, ...;
with elastic bone and nail the soft block's GAMG options are `fieldsplit_u_fieldsplit_t_...`).

The dofs of the block ("mpi" kind) matrix are, on each rank, the owned u dofs and then the
owned p dofs; the split's index sets follow from the index maps. The near null space is
composed with the u index set ("nearnullspace"), where PCFIELDSPLIT hands it to the extracted
K block. The construction is the same in 2D (3 rigid modes) and 3D (6).
"""

from __future__ import annotations

import dolfinx.fem.petsc  # noqa: F401  (the PETSc assemblers)
import numpy as np
import ufl
from dolfinx import fem, la
from mpi4py import MPI
from petsc4py import PETSc

from .options import DEFAULT_PETSC_OPTIONS, check_linear

#: LU of the whole Jacobian (MUMPS): robust for contact and for the undrained saddle point.
DIRECT_OPTIONS = {
    "ksp_type": "preonly",
    "pc_type": "lu",
    "pc_factor_mat_solver_type": "mumps",
}

#: The Krylov tolerance (relative, unpreconditioned residual) of a Newton with exact linear solves
#: (`snes_ksp_ew = false`). Newton's own tolerances (snes_rtol 1e-9, snes_atol 1e-10 N/mm) need
#: each linear solve to reduce its residual further than Newton's quadratic rate would:
#: an inexact Newton step with relative tolerance η converges linearly at rate η.
KSP_RTOL = 1e-10

#: Inexact Newton (Eisenstat & Walker 1996, their choice 2: η_k = γ (‖R_k‖/‖R_{k−1}‖)^α,
#: γ 0.9, α (1+√5)/2): each linear solve only as tight as Newton's progress needs, loose far from
#: the answer, tighter as the residual falls; Newton's own tolerances are unchanged, so the answer
#: is the exact-solve one to those. The first solve's η0 = 0.1 (PETSc's 0.3 took one more Newton
#: iteration on the 1pt fingertip for 11 fewer Krylov iterations). η is capped at 0.1
#: (`snes_ksp_ew_rtolmax`, PETSc's 0.9): where the contact set changes, a Newton iteration cuts
#: the residual little, choice 2 then loosens the next solves to η ≈ 0.6-0.9 (one Krylov iteration
#: each) and Newton crawls at that rate. Measured on the 3D line load's first step, 2 ranks: 10
#: Newton iterations at 0.4 mm with the cap 0.9, 8 with 0.1 (exact solves: 9), CPU −29 %; 0.8 mm
#: unchanged (η stays below 0.1). The residual there is the soft tissue's, not the stiff
#: regions' (benchmarks/newton_forcing.py prints it by region). In 2D the bone's and nail's rows
#: can dominate it: Newton still takes more iterations than with exact solves (12 against 7 on
#: the 1pt fingertip at 0.4 mm), so the route allows 25 before a step is cut.
#: Measured: docs/benchmarks/solvers-3d.md, docs/benchmarks/3d.md.
INEXACT_NEWTON = {"snes_ksp_ew": True, "snes_ksp_ew_version": 2, "snes_ksp_ew_rtol0": 0.1,
                  "snes_ksp_ew_rtolmax": 0.1, "snes_max_it": 25}

#: Newton's iterations per step with exact linear solves.
DEFAULT_MAX_IT = DEFAULT_PETSC_OPTIONS["snes_max_it"]

_KRYLOV = {
    "ksp_type": "fgmres",  # flexible: the field split's inner solves vary between iterations
    "ksp_rtol": KSP_RTOL,
    "ksp_atol": 1e-14,
    "ksp_max_it": 400,
    "ksp_gmres_restart": 200,
    "ksp_norm_type": "unpreconditioned",  # the tolerance on the true residual
    "ksp_error_if_not_converged": False,  # a failed solve fails Newton's step: it is cut
    **INEXACT_NEWTON,
}

def kept_factor_options(limit: int) -> dict:
    """The direct route's Krylov wrapper when the LU factorisation is kept (StepOptions.
    factor_reuse = `limit`; stepper.FactorReuse): GMRES on the Jacobian as assembled,
    right-preconditioned by the LU (MUMPS) of an older one, so that its tolerance is on the
    true residual; with fresh factors it converges in one iteration. The solve is as exact as
    the iterative route's exact solves (KSP_RTOL): Newton keeps its iterates and its answer.
    At most 2 × `limit` iterations, without restart: FactorReuse then finishes the solve with
    a fresh factorisation."""
    most = 2 * limit
    return {"ksp_type": "gmres", "ksp_pc_side": "right", "ksp_norm_type": "unpreconditioned",
            "ksp_rtol": KSP_RTOL, "ksp_atol": _KRYLOV["ksp_atol"], "ksp_max_it": most,
            "ksp_gmres_restart": most, "ksp_gmres_cgs_refinement_type": "refine_ifneeded",
            "ksp_error_if_not_converged": False}


def flexible_gmres(ksp: PETSc.KSP, rtol: float, atol: float, max_it: int) -> None:
    """Make `ksp` flexible GMRES around its PC, right-preconditioned (its tolerances on the
    true residual), without restart within its `max_it` iterations: the Krylov wrapper of
    kept LU factors (`use_kept_factors`, the tangent predictor's in stepper.py)."""
    ksp.setType(PETSc.KSP.Type.FGMRES)
    ksp.setGMRESRestart(max_it)
    ksp.setPCSide(PETSc.PC.Side.RIGHT)
    ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
    ksp.setTolerances(rtol=rtol, atol=atol, max_it=max_it)


def use_kept_factors(ksp: PETSc.KSP, limit: int, kept: bool) -> None:
    """Switch the direct route's KSP between its two modes under StepOptions.
    hold_factor_reuse = `limit`: `kept`, FGMRES as `kept_factor_options` (the tolerance on the
    true residual, at most 2 × `limit` iterations, no restart) around the LU, whose factors
    stepper.FactorReuse may keep; else the plain direct solve (preonly: one application of
    the LU of the matrix solved). Flexible GMRES keeps its preconditioned vectors and builds
    the solution from them, where GMRES right-preconditioned applies the LU once more at the
    end: a pair of triangular solves fewer per solve (the same iterates in exact
    arithmetic). The LU (the PC and its factors) is the same object in both."""
    if kept:  # kept_factor_options' settings, flexible (its restart is its iteration cap)
        o = kept_factor_options(limit)
        flexible_gmres(ksp, o["ksp_rtol"], o["ksp_atol"], o["ksp_max_it"])
    else:
        ksp.setType(PETSc.KSP.Type.PREONLY)
        ksp.setPCSide(PETSc.PC.Side.LEFT)
        ksp.setNormType(PETSc.KSP.NormType.NONE)


#: GAMG on the displacement block: smoothed aggregation with the rigid-body near null space,
#: Chebyshev/Jacobi smoothing (diagonal scaling: each row sees its own stiffness, so the bone's
#: 10⁷ larger entries do not swamp the tissue's), a square graph on the finest level. The
#: threshold 0.01 drops the weak tissue-bone couplings from the aggregation graph; 0.1 failed
#: (400 iterations) at h = 0.2 mm with bone and nail rigid.
_GAMG = {
    "pc_type": "gamg",
    "pc_gamg_type": "agg",
    "pc_gamg_threshold": 0.01,
    "pc_gamg_square_graph": 1,
    "mg_levels_ksp_type": "chebyshev",
    "mg_levels_pc_type": "jacobi",
    "mg_levels_ksp_max_it": 2,
    "mg_coarse_ksp_type": "preonly",
    "mg_coarse_pc_type": "lu",
}


#: The displacement block with bone and nail elastic: a multiplicative (block Gauss–Seidel) field
#: split into the stiff dofs "s" (every dof of a bone or nail cell, the interfaces included) and
#: the soft tissues' "t": the stiff block by LU (MUMPS; few dofs: the bone and nail are meshed
#: coarsely), the soft one by GAMG. GAMG on the whole block cannot coarsen the thin nail plate's
#: bending (110-400 Krylov iterations per Newton step); the stiff block's exact solve removes it,
#: and the soft tissues' small stiffness couples the two blocks weakly, so few sweeps do.
#: Measured: docs/benchmarks/solvers-3d.md.
_STIFF_SPLIT = {
    "pc_type": "fieldsplit",
    "pc_fieldsplit_type": "multiplicative",
    "fieldsplit_s_ksp_type": "preonly",
    "fieldsplit_s_pc_type": "lu",
    "fieldsplit_s_pc_factor_mat_solver_type": "mumps",
    "fieldsplit_t_ksp_type": "preonly",
    **{f"fieldsplit_t_{k}": v for k, v in _GAMG.items()},
}


def iterative_options(pressure: bool, stiff: bool = False) -> dict:
    """The Krylov configuration (PETSc options without prefix): a Schur field split over
    (u, p) if the problem has a pressure, else the displacement block's preconditioner alone:
    GAMG, or with elastic stiff regions (`stiff`) the stiff/soft split."""
    block = _STIFF_SPLIT if stiff else _GAMG
    if not pressure:
        # Without the pore pressure, elastic stiff regions made the inexact Newton crawl (42
        # iterations against 7 on the drained 1pt fingertip, 4x the exact solves' time):
        # exact solves there.
        exact = {"snes_ksp_ew": False, "snes_max_it": DEFAULT_MAX_IT} if stiff else {}
        return {**_KRYLOV, **block, **exact}
    split = {
        "pc_type": "fieldsplit",
        "pc_fieldsplit_type": "schur",
        "pc_fieldsplit_schur_fact_type": "full",
        "fieldsplit_u_ksp_type": "preonly",
        "fieldsplit_p_ksp_type": "preonly",
        "fieldsplit_p_pc_type": "gamg",
    }
    split |= {f"fieldsplit_u_{k}": v for k, v in block.items()}
    return {**_KRYLOV, **split}


def options(linear: str, pressure: bool, stiff: bool = False) -> dict:
    """The PETSc options of the linear solver `linear` ("direct" or "iterative")."""
    check_linear(linear)
    return dict(DIRECT_OPTIONS) if linear == "direct" else iterative_options(pressure, stiff)


def rigid_body_modes(V: fem.FunctionSpace) -> PETSc.NullSpace:
    """The rigid-body motions of the vector space V as an orthonormal PETSc near null space:
    gdim translations and gdim(gdim − 1)/2 rotations (3 in 2D, 6 in 3D), on the owned dofs
    (interleaved, block size gdim), as GAMG needs them to build its coarse spaces."""
    gdim = V.mesh.geometry.dim
    bs = V.dofmap.index_map_bs
    n = V.dofmap.index_map.size_local
    x = V.tabulate_dof_coordinates()[:n, :gdim]
    x = x - V.mesh.comm.allreduce(x.sum(axis=0), op=MPI.SUM) / max(
        V.dofmap.index_map.size_global, 1)  # about the centroid: better conditioned
    modes = []
    for i in range(gdim):
        m = np.zeros((n, bs))
        m[:, i] = 1.0
        modes.append(m)
    for i, j in ((0, 1), (1, 2), (2, 0))[: 1 if gdim == 2 else 3]:
        m = np.zeros((n, bs))  # rotation in the (i, j) plane: (−x_j, x_i)
        m[:, i], m[:, j] = -x[:, j], x[:, i]
        modes.append(m)
    vectors = []
    for m in modes:
        v = PETSc.Vec().createMPI((n * bs, PETSc.DECIDE), bsize=bs, comm=V.mesh.comm)
        v.array[:] = m.ravel()
        vectors.append(v)
    _gram_schmidt(vectors)
    return PETSc.NullSpace().create(vectors=vectors, comm=V.mesh.comm)


def _gram_schmidt(vectors: list) -> None:
    for i, v in enumerate(vectors):
        for w in vectors[:i]:
            v.axpy(-v.dot(w), w)
        v.normalize()


def split_index_sets(unknowns: list[fem.Function], A: PETSc.Mat) -> list[PETSc.IS]:
    """The global index sets of each unknown's rows in the block ("mpi" kind) matrix A: on each
    rank its owned dofs of u, then of p, from the start of the rank's rows."""
    start = A.getOwnershipRange()[0]
    sets = []
    for f in unknowns:
        index_map, bs = f.function_space.dofmap.index_map, f.function_space.dofmap.index_map_bs
        size = index_map.size_local * bs
        iset = PETSc.IS().createStride(size, first=start, step=1, comm=A.comm)
        iset.setBlockSize(bs)
        sets.append(iset)
        start += size
    return sets


def stiff_soft_sets(V: fem.FunctionSpace, cells: np.ndarray, modes: PETSc.NullSpace
                    ) -> list[PETSc.IS]:
    """The global index sets, within V's own numbering (the displacement block's rows), of
    the owned dofs of the `cells` (any rank's: a dof on a partition boundary is stiff if a cell
    of either rank is) and of the others; the latter carries the rigid-body `modes` restricted
    to it, as its near null space."""
    bs, n = V.dofmap.index_map_bs, V.dofmap.index_map.size_local * V.dofmap.index_map_bs
    marks = fem.Function(V)
    marks.x.array.reshape(-1, bs)[np.unique(V.dofmap.list[cells]), :] = 1.0
    marks.x.scatter_reverse(la.InsertMode.add)
    start, comm = V.dofmap.index_map.local_range[0] * bs, V.mesh.comm
    stiff = marks.x.array[:n] > 0
    sets = [PETSc.IS().createGeneral((start + np.flatnonzero(m)).astype(PETSc.IntType),
                                     comm=comm) for m in (stiff, ~stiff)]
    vectors = []
    for mode in modes.getVecs():
        v = PETSc.Vec().createMPI((int((~stiff).sum()), PETSc.DECIDE), bsize=bs, comm=comm)
        v.array[:] = mode.getArray(readonly=True)[~stiff]
        vectors.append(v)
    _gram_schmidt(vectors)
    sets[1].compose("nearnullspace", PETSc.NullSpace().create(vectors=vectors, comm=comm))
    for iset in sets:
        iset.setBlockSize(bs)
    return sets


class LinearSolver:
    """Configures a dolfinx NonlinearProblem's KSP for `linear` ("direct" or "iterative"):
    the options (`options`, to merge under the user's), then `attach` the split's index sets
    and the near null space once the problem exists."""

    def __init__(self, linear: str, problem):
        self.linear = check_linear(linear)
        self.problem = problem
        self.unknowns = list(problem.unknowns)
        self.pressure = len(self.unknowns) > 1
        #: The elastic stiff regions' cells (bone, nail), if the problem tells them.
        self.stiff = getattr(problem, "stiff_cells", lambda: np.zeros(0, np.int32))()
        comm = self.unknowns[0].function_space.mesh.comm
        self.split_stiff = comm.allreduce(len(self.stiff), op=MPI.SUM) > 0
        self.options = options(linear, self.pressure, self.split_stiff)
        self._objects: list = []

    def attach(self, nonlinear, prefix: str, petsc_options: dict) -> None:
        """Give the Krylov solver what it cannot read from options: the fields' index sets and
        the rigid-body modes. PCFIELDSPLIT reads its sub-solvers' options when it first sets up
        (at the first Newton step, after NonlinearProblem has cleared its options), so those
        stay in the options database under `prefix` until `release`."""
        if self.linear == "direct":
            return
        self._prefix = prefix
        self._keys = [k for k in petsc_options if k.startswith("fieldsplit_")
                      or k.startswith("mg_")]
        db = PETSc.Options()
        for k in self._keys:
            db[prefix + k] = petsc_options[k]
        A = nonlinear.A
        modes = rigid_body_modes(self.unknowns[0].function_space)
        self._objects.append(modes)
        pc = nonlinear.solver.getKSP().getPC()
        V = self.unknowns[0].function_space
        stiff = stiff_soft_sets(V, self.stiff, modes) if self.split_stiff else None
        self._objects += stiff or []
        if self.pressure:
            sets = split_index_sets(self.unknowns, A)
            sets[0].compose("nearnullspace", modes)
            pc.setFieldSplitIS(("u", sets[0]), ("p", sets[1]))
            self._objects += sets
            self._schur_preconditioner(nonlinear, pc, sets[1])
            if stiff:
                self._split_u_block(nonlinear.solver, stiff)
        elif stiff:
            pc.setFieldSplitIS(("s", stiff[0]), ("t", stiff[1]))
        else:
            A.setBlockSize(V.dofmap.index_map_bs)
            A.setNearNullSpace(modes)

    def _split_u_block(self, snes: PETSc.SNES, stiff: list[PETSc.IS]) -> None:
        """Give the displacement block's own field split (stiff/soft) its index sets. That
        block's preconditioner exists once the Schur split is set up, which needs the first
        Jacobian: so at the first assembly, set the split up and hand them on (unless the
        scene chose another preconditioner for the block: `fieldsplit_u_pc_type`)."""
        J, P, (jacobian, args, kargs) = snes.getJacobian()
        done = []

        def first(snes, x, J_, P_):
            jacobian(snes, x, J_, P_, *args, **(kargs or {}))
            if done:
                return
            ksp = snes.getKSP()
            ksp.setOperators(J_, P_)
            ksp.getPC().setUp()
            block = ksp.getPC().getFieldSplitSubKSP()[0].getPC()
            if block.getType() == PETSc.PC.Type.FIELDSPLIT:
                block.setFieldSplitIS(("s", stiff[0]), ("t", stiff[1]))
            done.append(True)

        snes.setJacobian(first, J, P)

    def _schur_preconditioner(self, nonlinear, pc, is_p: PETSc.IS) -> None:
        """S_p = J_pp + M/m for the pressure Schur complement S = J_pp + B K⁻¹ Bᵀ: B K⁻¹ Bᵀ of
        a solid of P-wave modulus m = λ + 2μ is close to M/m (M the pressure mass matrix:
        exact for the divergence of a periodic elastic field), J_pp the Darcy block as
        assembled (Δt J k C⁻¹ Grad p·Grad q; none undrained). Refreshed with each Jacobian."""
        Q = self.unknowns[1].function_space
        p, q = ufl.TrialFunction(Q), ufl.TestFunction(Q)
        modulus = pressure_modulus(self.problem)
        M = fem.petsc.assemble_matrix(fem.form(ufl.inner(p, q) / modulus * ufl.dx(Q.mesh)))
        M.assemble()
        self._M, self._Sp, self._App = M, M.duplicate(copy=True), None
        self._objects += [M, self._Sp]
        pc.setFieldSplitSchurPreType(PETSc.PC.FieldSplitSchurPreType.USER, self._Sp)
        snes = nonlinear.solver
        J, P, (jacobian, args, kargs) = snes.getJacobian()

        def refresh(snes, x, J_, P_):
            jacobian(snes, x, J_, P_, *args, **(kargs or {}))
            self._App = P_.createSubMatrix(is_p, is_p, self._App)
            self._M.copy(self._Sp, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
            self._Sp.axpy(1.0, self._App, structure=PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)

        snes.setJacobian(refresh, J, P)

    def release(self) -> None:
        """Remove the options this solver left in the database, destroy its PETSc objects."""
        db = PETSc.Options()
        for k in getattr(self, "_keys", []):
            db.delValue(self._prefix + k)
        for obj in self._objects:
            obj.destroy()
        self._objects = []


def pressure_modulus(problem) -> float:
    """The P-wave modulus λ + 2μ (MPa) of the subcutaneous solid at rest (the region that carries
    the pore pressure), from the problem's laws."""
    return float(problem.laws.regions["subcutaneous"].p_wave_modulus)


def krylov_iterations(snes: PETSc.SNES) -> int:
    """The Krylov iterations of the last SNES solve (all Newton steps)."""
    return snes.getLinearSolveIterations()

