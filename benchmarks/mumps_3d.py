"""Benchmark: MUMPS options on the Jacobian of a 3D fingertip scene (the 3D line load by default).

Builds the scene's Newton problem, assembles its Jacobian J and residual b at a smooth deformed
state (strains of a few per cent, as `fingertip_3d.py --assembly` does) and, for each MUMPS
configuration, times the analysis (ordering and symbolic factorisation: once per run, the
matrix's pattern does not change), the numerical factorisation (once per Newton iteration, after
the Jacobian is reassembled) and the solve; prints MUMPS's own figures (factor entries
INFOG(29), flops of the elimination RINFOG(3), memory per rank INFOG(21)/(22)), and the solution's
distance to the default configuration's (relative, max norm) and its residual ‖J x − b‖/‖b‖.
Wall seconds on rank 0 and CPU seconds per rank (the machine is shared: compare the CPU):

    mpiexec -n 2 .venv/bin/python benchmarks/mumps_3d.py
    mpiexec -n 2 .venv/bin/python benchmarks/mumps_3d.py --only default metis blr-1e-8

Configurations (PETSc options under the KSP's prefix): `CONFIGS`.
"""

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np
from fingertip_3d import smooth_state
from mpi4py import MPI

import fingertip_dolfinx  # noqa: F401  (sets up the DOLFINx wheel)
from fingertip_dolfinx.scene import load_scene

#: MUMPS options (without `mat_mumps_`) per configuration. ICNTL(7): the sequential ordering
#: (7 automatic, 3 SCOTCH, 4 PORD, 5 METIS); ICNTL(28) = 2 with ICNTL(29) (1 PT-SCOTCH,
#: 2 ParMETIS): parallel analysis; ICNTL(35): block low-rank factors (2: BLR factorisation and
#: solve) with CNTL(7) the dropping tolerance (relative: an approximate factorisation).
CONFIGS = {
    "default": {},
    "metis": {"icntl_7": 5},
    "scotch": {"icntl_7": 3},
    "pord": {"icntl_7": 4},
    "amf": {"icntl_7": 2},
    "ptscotch": {"icntl_28": 2, "icntl_29": 1},
    "parmetis": {"icntl_28": 2, "icntl_29": 2},
    "blr-1e-10": {"icntl_35": 2, "cntl_7": 1e-10},
    "blr-1e-8": {"icntl_35": 2, "cntl_7": 1e-8},
    "blr-1e-6": {"icntl_35": 2, "cntl_7": 1e-6},
}


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawTextHelpFormatter)
    parser.add_argument("--scene", default="line-load-3d")
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    parser.add_argument("--only", nargs="+", default=list(CONFIGS), choices=list(CONFIGS))
    parser.add_argument("--refactor", type=int, default=2,
                        help="numerical factorisations timed per configuration")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    scene = load_scene(args.scene, args.overrides)
    out = Path(comm.bcast(tempfile.mkdtemp() if comm.rank == 0 else None))
    J, b, assemble = jacobian_at_smooth_state(scene, out)
    reference = None
    if comm.rank == 0:
        print(f"{scene.name}: {J.getSize()[0]} unknowns, {comm.size} rank(s); load average "
              f"{os.getloadavg()[0]:.2f}; wall s (rank 0) / CPU s (per rank)")
    for name in ["default", *[n for n in args.only if n != "default"]]:
        x, line = factor_and_solve(name, CONFIGS[name], J, b, assemble, args.refactor)
        reference = x.copy() if reference is None else reference
        dx = x.copy()
        dx.axpy(-1.0, reference)
        line += f"; solution - default's {dx.norm(3) / reference.norm(3):.1e} (max norm)"
        if comm.rank == 0:
            print(line, flush=True)


def jacobian_at_smooth_state(scene, out: Path):
    """The scene's Jacobian and residual at a smooth deformed state, and a re-assembler."""
    nonlinear = smooth_state(scene, out, MPI.COMM_WORLD).stepper.nonlinear
    snes = nonlinear.solver
    J, P, (jacobian, args, kargs) = snes.getJacobian()
    b, (residual, rargs, rkargs) = snes.getFunction()
    residual(snes, nonlinear.x, b, *rargs, **(rkargs or {}))

    def assemble():
        jacobian(snes, nonlinear.x, J, P, *args, **(kargs or {}))

    assemble()
    return J, b, assemble


def factor_and_solve(name: str, mumps: dict, J, b, assemble, refactor: int):
    """Time one configuration: analysis + factorisation, `refactor` more factorisations after
    a reassembly, a solve; returns the solution and the line to print."""
    from petsc4py import PETSc

    comm = MPI.COMM_WORLD
    prefix = f"mumps_{name.replace('-', '_').replace('.', '_')}_"
    db = PETSc.Options()
    options = {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps",
               **{f"mat_mumps_{k}": v for k, v in mumps.items()}}
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
    solve = _timed(lambda: ksp.solve(b, x))
    r = b.duplicate()
    J.mult(x, r)
    r.axpy(-1.0, b)
    F = ksp.getPC().getFactorMatrix()
    entries, flops = F.getMumpsInfog(29), F.getMumpsRinfog(3)
    memory = (F.getMumpsInfog(21), F.getMumpsInfog(22))  # MB: max and total over ranks
    ordering = F.getMumpsInfog(7)
    num_wall = min(w for w, _ in numeric) if numeric else float("nan")
    num_cpu = np.array([c for _, c in numeric]).min(axis=0) if numeric else [float("nan")]
    line = (f"{name:10s} (INFOG(7) ordering {ordering}): analysis+factorisation "
            f"{_fmt(first)}; factorisation {num_wall:.2f} / "
            f"{', '.join(f'{c:.2f}' for c in num_cpu)}; solve {_fmt(solve)}; "
            f"factor entries {entries:.3g}, flops {flops:.3g}, memory max/total {memory[0]}/"
            f"{memory[1]} MB; residual {r.norm() / b.norm():.1e}")
    ksp.destroy()
    for k in options:
        db.delValue(prefix + k)
    return x, line


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
