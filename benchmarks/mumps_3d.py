"""Benchmark: MUMPS options on the Jacobian of a 3D fingertip scene (the 3D line load by default).

Builds the scene's Newton problem, assembles its Jacobian J and residual b at a smooth deformed
state (strains of a few per cent, as `fingertip_3d.py --assembly` does) and, for each MUMPS
configuration, times the analysis (ordering and symbolic factorisation: once per run, the
matrix's pattern does not change), the numerical factorisation (once per Newton iteration, after
the Jacobian is reassembled) and the solve; prints MUMPS's own figures (factor entries
INFOG(29), flops of the elimination RINFOG(3), memory per rank INFOG(21)/(22)), and the solution's
distance to the default configuration's (relative, max norm) and its residual ‖J x − b‖/‖b‖;
for the symmetric factorisations (`SYMMETRIC`: LDLᵀ) also the GMRES iterations around them, and
MUMPS's delayed and negative pivots INFOG(13), INFOG(12). `--pressure` sets a pore pressure
(MPa) at the state, so that the Darcy term makes the Jacobian unsymmetric as in a run.
Wall seconds on rank 0 and CPU seconds per rank (the machine is shared: compare the CPU):

    mpiexec -n 2 .venv/bin/python benchmarks/mumps_3d.py
    mpiexec -n 2 .venv/bin/python benchmarks/mumps_3d.py --only default metis blr-1e-8
    mpiexec -n 2 .venv/bin/python benchmarks/mumps_3d.py --only default ldlt --pressure 5e-4

Configurations (PETSc options under the KSP's prefix): `CONFIGS` (MUMPS) and `OTHERS`
(SuperLU_DIST, in double and in single precision).
"""

import os
import time
from pathlib import Path

import numpy as np
from fingertip_3d import smooth_state
from mpi4py import MPI
from timing import scene_and_out, scene_parser

import fingertip_dolfinx  # noqa: F401  (sets up the DOLFINx wheel)

#: MUMPS options (without `mat_mumps_`) per configuration. ICNTL(7): the sequential ordering
#: (7 automatic, 3 SCOTCH, 4 PORD, 5 METIS); ICNTL(28) = 2 with ICNTL(29) (1 PT-SCOTCH,
#: 2 ParMETIS): parallel analysis; ICNTL(35): block low-rank factors (2: BLR factorisation and
#: solve) with CNTL(7) the dropping tolerance (relative: an approximate factorisation);
#: ICNTL(13) = 1: the root front on one rank, not ScaLAPACK's; ICNTL(8) = 0: no scaling;
#: ICNTL(6) = 0: no column permutation to a zero-free diagonal.
CONFIGS = {
    "default": {},
    "root-seq": {"icntl_13": 1},
    "noscale": {"icntl_8": 0},
    "no-permutation": {"icntl_6": 0},
    "metis": {"icntl_7": 5},
    "scotch": {"icntl_7": 3},
    "pord": {"icntl_7": 4},
    "amf": {"icntl_7": 2},
    "ptscotch": {"icntl_28": 2, "icntl_29": 1},
    "parmetis": {"icntl_28": 2, "icntl_29": 2},
    "blr-1e-10": {"icntl_35": 2, "cntl_7": 1e-10},
    "blr-1e-8": {"icntl_35": 2, "cntl_7": 1e-8},
    "blr-1e-6": {"icntl_35": 2, "cntl_7": 1e-6},
    "ldlt": {},
    "ldlt-compressed": {"icntl_12": 2},
    "ldlt-nopivot": {"cntl_1": 0.0},
}
#: Configurations that factorise the Jacobian as symmetric: MUMPS LDLᵀ (PETSc's Cholesky of an
#: AIJ matrix: MUMPS SYM = 2, symmetric indefinite, from the upper triangle) of S J, the Jacobian
#: with its pressure rows negated (benchmarks/jacobian_symmetry.py: symmetric but for the Darcy
#: term's derivative), inside GMRES, which solves with S J itself to 1e-12 (right
#: preconditioning, the true residual): the answer is the system's, whatever the factors
#: approximate. ICNTL(12) = 2: the compressed ordering for saddle points; CNTL(1) = 0: no
#: pivoting (static).
SYMMETRIC = {"ldlt", "ldlt-compressed", "ldlt-nopivot"}
#: Other factorisations of the same J, for comparison (full PETSc options): SuperLU_DIST's LU
#: in double precision, and in single precision (`pc_precision single`, PETSc's only mixed
#: precision factorisation in this build: its MUMPS has no single-precision library) inside
#: flexible GMRES, which solves with J itself to 1e-10 on the true residual.
OTHERS = {
    "superlu_dist": {"pc_factor_mat_solver_type": "superlu_dist"},
    "superlu_dist-single": {"pc_factor_mat_solver_type": "superlu_dist", "pc_precision": "single",
                            "ksp_type": "fgmres", "ksp_rtol": 1e-10, "ksp_atol": 0.0,
                            "ksp_max_it": 50, "ksp_gmres_restart": 50},
}


def main():
    parser = scene_parser(__doc__, "line-load-3d", out=False)
    parser.add_argument("--only", nargs="+", default=list(CONFIGS),
                        choices=[*CONFIGS, *OTHERS])
    parser.add_argument("--refactor", type=int, default=2,
                        help="numerical factorisations timed per configuration")
    parser.add_argument("--solves", type=int, default=1,
                        help="solves timed per configuration (the least is printed)")
    parser.add_argument("--pressure", type=float, default=0.0,
                        help="MPa: a smooth pore pressure of this size at the state (0: none, "
                        "the Jacobian of the earlier table; with a pressure gradient the Darcy "
                        "term's derivative makes S J unsymmetric)")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    scene, out = scene_and_out(args, comm)
    J, b, assemble, signs = jacobian_at_smooth_state(scene, out, args.pressure)
    reference = None
    if comm.rank == 0:
        print(f"{scene.name}: {J.getSize()[0]} unknowns, {comm.size} rank(s); load average "
              f"{os.getloadavg()[0]:.2f}; wall s (rank 0) / CPU s (per rank)")
    for name in ["default", *[n for n in args.only if n != "default"]]:
        sign = signs if name in SYMMETRIC else None
        x, line = factor_and_solve(name, CONFIGS.get(name, {}), J, b, assemble, args.refactor,
                                   sign, args.solves)
        reference = x.copy() if reference is None else reference
        dx = x.copy()
        dx.axpy(-1.0, reference)
        line += f"; solution - default's {dx.norm(3) / reference.norm(3):.1e} (max norm)"
        if comm.rank == 0:
            print(line, flush=True)


def jacobian_at_smooth_state(scene, out: Path, pressure: float = 0.0):
    """The scene's Jacobian and residual at a smooth deformed state (a pore pressure of size
    `pressure`, MPa, varying over a few mm), a re-assembler, and the signs S (+1 on the
    displacement rows, −1 on the pressure's)."""
    import dolfinx.fem.petsc

    job = smooth_state(scene, out, MPI.COMM_WORLD)
    nonlinear, problem = job.stepper.nonlinear, job.problem
    if problem.p is not None and pressure:
        problem.p.interpolate(lambda x: pressure * np.cos(x[0]) * np.cos(0.5 * x[2]))
        dolfinx.fem.petsc.assign(problem.unknowns, nonlinear.x)
    snes = nonlinear.solver
    J, P, (jacobian, args, kargs) = snes.getJacobian()
    b, (residual, rargs, rkargs) = snes.getFunction()
    residual(snes, nonlinear.x, b, *rargs, **(rkargs or {}))

    def assemble():
        if job.stepper.reuse is not None:
            job.stepper.reuse.start()  # the scene's Jacobian reuse would keep the old one
        jacobian(snes, nonlinear.x, J, P, *args, **(kargs or {}))

    assemble()
    return J, b, assemble, pressure_signs(problem, J)


def pressure_signs(problem, J):
    """The vector S: +1 on the displacement rows of J, −1 on the pore pressure's."""
    from fingertip_dolfinx.stepping.linear import split_index_sets

    signs = J.createVecLeft()
    signs.set(1.0)
    if problem.p is not None:
        rows = split_index_sets(problem.unknowns, J)[1].getIndices()
        signs.array[rows - J.getOwnershipRange()[0]] = -1.0
    return signs


def factor_and_solve(name: str, mumps: dict, J, b, assemble, refactor: int, signs=None,
                     solves: int = 1):
    """Time one configuration: analysis + factorisation, `refactor` more factorisations after
    a reassembly, `solves` solves (the least timed); returns the solution and the line to
    print. With `signs` (S), the system solved is S J x = S b, by GMRES preconditioned by the
    LDLᵀ factors of S J."""
    from petsc4py import PETSc

    comm = MPI.COMM_WORLD
    prefix = f"mumps_{name.replace('-', '_').replace('.', '_')}_"
    db = PETSc.Options()
    options = {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps",
               **{f"mat_mumps_{k}": v for k, v in mumps.items()}, **OTHERS.get(name, {})}
    if signs is not None:
        options |= SYMMETRIC_KSP
        rebuild = assemble

        def assemble():
            rebuild()
            J.diagonalScale(L=signs)

        b = b.copy()
        b.pointwiseMult(b, signs)
    assemble()
    for k, v in options.items():
        db[prefix + k] = v
    ksp = PETSc.KSP().create(comm)
    ksp.setOptionsPrefix(prefix)
    ksp.setFromOptions()
    ksp.setOperators(J)
    first = _timed(lambda: ksp.setUp())
    numeric = []
    for _ in range(refactor):
        assemble()  # a new Jacobian: refactorised numerically, the analysis kept
        ksp.setOperators(J)
        numeric.append(_timed(lambda: ksp.setUp()))
    x = J.createVecRight()
    solve = min((_timed(lambda: ksp.solve(b, x)) for _ in range(max(solves, 1))),
                key=lambda t: t[0])
    r = b.duplicate()
    J.mult(x, r)
    r.axpy(-1.0, b)
    krylov = signs is not None or name in OTHERS
    extra = f", {ksp.getIterationNumber()} Krylov iteration(s)" if krylov else ""
    if name not in OTHERS:
        extra = _mumps_figures(ksp.getPC().getFactorMatrix()) + extra
    num_wall = min(w for w, _ in numeric) if numeric else float("nan")
    num_cpu = np.array([c for _, c in numeric]).min(axis=0) if numeric else [float("nan")]
    line = (f"{name:10s}: analysis+factorisation {_fmt(first)}; factorisation {num_wall:.2f} / "
            f"{', '.join(f'{c:.2f}' for c in num_cpu)}; solve {_fmt(solve)}; "
            f"residual {r.norm() / b.norm():.1e}{extra}")
    ksp.destroy()
    for k in options:
        db.delValue(prefix + k)
    return x, line


def _mumps_figures(F) -> str:
    """MUMPS's own figures of a factorisation: ordering, factor entries, flops, memory (MB,
    the larger rank's and the total), delayed and negative pivots."""
    return (f"; INFOG(7) ordering {F.getMumpsInfog(7)}, factor entries {F.getMumpsInfog(29):.3g}"
            f", flops {F.getMumpsRinfog(3):.3g}, memory max/total {F.getMumpsInfog(21)}/"
            f"{F.getMumpsInfog(22)} MB; delayed pivots INFOG(13) {F.getMumpsInfog(13)}, "
            f"negative pivots INFOG(12) {F.getMumpsInfog(12)}")


#: The Krylov wrapper of a symmetric factorisation (SYMMETRIC).
SYMMETRIC_KSP = {"ksp_type": "gmres", "pc_type": "cholesky", "ksp_pc_side": "right",
                 "ksp_norm_type": "unpreconditioned", "ksp_rtol": 1e-12, "ksp_atol": 0.0,
                 "ksp_max_it": 30}


def _timed(call) -> tuple[float, list[float]]:
    comm = MPI.COMM_WORLD
    comm.barrier()
    wall, cpu = time.perf_counter(), time.process_time()
    call()
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    return wall, comm.allgather(cpu)


def _fmt(timing: tuple[float, list[float]]) -> str:
    wall, cpus = timing
    return f"{wall:.2f} / {', '.join(f'{c:.2f}' for c in cpus)}"


if __name__ == "__main__":
    main()
