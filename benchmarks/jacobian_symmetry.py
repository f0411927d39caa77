"""Benchmark: how far a scene's Newton Jacobian is from symmetric, at a deformed, contacting state.

Runs the scene (shorten it with `--set`), then assembles the Jacobian J at the last accepted
state and prints ‖A − Aᵀ‖/‖A‖ (Frobenius and ∞ norms) for A = J and for A = S J, J with the
pore pressure's rows negated (S = diag(1, −1)), and S J's asymmetry per block (u, p). With the
pressure p the momentum balance has −∫ p J F⁻ᵀ : Grad v and the mass balance its derivative
∫ q J F⁻ᵀ : Grad δu with a + sign: J = [K −Bᵀ; B + D C], so S J = [K −Bᵀ; −B − D −C] is
symmetric but for D, the derivative of the Darcy term Δt J k(J) C⁻¹ Grad p·Grad q with respect
to u (zero where Grad p = 0). Negating rows changes no Newton iterate. K is symmetric where
every term of the momentum balance derives from an energy: hyperelastic and QLV stresses, the
penalty contact (and Nitsche's with θ = 1); not with Nitsche's θ = 0 or with friction.

    mpiexec -n 2 python benchmarks/jacobian_symmetry.py --scene line-load-3d \\
        --set section.mesh.min_size=0.8 --set protocol.depth=0.3 --set protocol.ramp_time=0.3 \\
        --set protocol.end_time=3 --set "output.times=[3]" --set output.pictures=false
"""

from mpi4py import MPI
from mumps_3d import pressure_signs
from timing import scene_and_out, scene_parser

import fingertip_dolfinx  # noqa: F401  (sets up the DOLFINx wheel)
from fingertip_dolfinx.runner import Run


def main():
    import dolfinx.fem.petsc

    parser = scene_parser(__doc__, "line-load", out=False)
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    scene, out = scene_and_out(args, comm)
    job = Run(scene, out, comm, resume=False, progress=False)
    job.run()
    problem, nonlinear = job.problem, job.stepper.nonlinear
    dolfinx.fem.petsc.assign(problem.unknowns, nonlinear.x)
    snes = nonlinear.solver
    if job.stepper.reuse is not None:
        job.stepper.reuse.start()  # assemble, do not keep the last iteration's Jacobian
    J, P, _ = snes.getJacobian()
    snes.computeJacobian(nonlinear.x, J, P)
    _print(f"{scene.name}: t = {job.time:g} s, Δt = {float(problem.dt.value):.3g} s, "
           f"indenter force {problem.contact.forces()[0]:.4e}, {J.getSize()[0]} unknowns")
    asymmetry(J, "J")
    if problem.p is not None:
        report_pressure_blocks(problem, J)


def report_pressure_blocks(problem, J) -> None:
    """S J's asymmetry in all and per block (S: the pressure rows negated)."""
    from petsc4py import PETSc

    from fingertip_dolfinx.stepping.linear import split_index_sets

    sets = split_index_sets(problem.unknowns, J)
    p = problem.p.x.array
    comm = MPI.COMM_WORLD
    _print(f"pore pressure {comm.allreduce(p.min(), MPI.MIN):.3e} .. "
           f"{comm.allreduce(p.max(), MPI.MAX):.3e} MPa")
    SJ = J.copy()
    SJ.diagonalScale(L=pressure_signs(problem, J))
    D = asymmetry(SJ, "S J (pressure rows negated)")
    fro = PETSc.NormType.FROBENIUS
    for (a, b), label in zip(((0, 0), (0, 1), (1, 0), (1, 1)), ("uu", "up", "pu", "pp")):
        block, diff = (M.createSubMatrix(sets[a], sets[b]) for M in (SJ, D))
        _print(f"  block {label}: ‖S J − (S J)ᵀ‖_F {diff.norm(fro):.3e}, ‖S J‖_F "
               f"{block.norm(fro):.3e}")


def asymmetry(A, label: str):
    """Print ‖A − Aᵀ‖/‖A‖ in the Frobenius and ∞ norms; return A − Aᵀ."""
    from petsc4py import PETSc

    D = A.copy()
    D.axpy(-1.0, A.transpose(PETSc.Mat()))  # transpose(Mat()): a new matrix, not in place
    ratios = [D.norm(n) / A.norm(n) for n in (PETSc.NormType.FROBENIUS, PETSc.NormType.INFINITY)]
    _print(f"{label}: ‖A − Aᵀ‖/‖A‖ {ratios[0]:.2e} (Frobenius), {ratios[1]:.2e} (∞)")
    return D


def _print(line: str) -> None:
    if MPI.COMM_WORLD.rank == 0:
        print(line, flush=True)


if __name__ == "__main__":
    main()
