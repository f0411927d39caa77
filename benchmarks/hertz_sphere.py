"""Hertz's sphere in 3D (studies.problems.HertzSphere): contact radius and peak pressure against
theory on a ladder of contact mesh sizes, and the block-size check (L = 20a against 40a).

Run: `python benchmarks/hertz_sphere.py` (serial; ~2 min). Prints one row per mesh: cells,
displacement dofs, the whole sphere's force (N), the errors of a and p0, Newton iterations
of the two steps, and the solve time.
"""

import time

from mpi4py import MPI

import fingertip_dolfinx  # noqa: F401
from fingertip_dolfinx.studies.problems import HertzSphere, contact_edge, newton_problem


def run(hertz: HertzSphere, n: float) -> str:
    domain, facet_tags = hertz.mesh(hertz.a_target / n, MPI.COMM_WORLD)
    block = hertz.block(domain, facet_tags)
    problem = newton_problem(block.residual, block.u, block.bcs, f"bench_hertz3d_{n}_{hertz.L}_",
                             snes_rtol=1e-10, snes_atol=1e-13)
    start, iterations = time.perf_counter(), []
    for k in (1, 2):
        block.obstacle.y_tip.value = hertz.depth * k / 2
        problem.solve()
        iterations.append(problem.solver.getIterationNumber())
    r, p, s = block.profile()
    force = block.force()
    a, p0 = hertz.theory(force)
    return (f"h = a/{n:<4g} L = {hertz.L:g} mm  cells {domain.topology.index_map(3).size_global:6d}"
            f"  dofs {3 * block.u.function_space.dofmap.index_map.size_global:6d}"
            f"  P = {force:.5g} N"
            f"  a {contact_edge(r, s) / a - 1:+.2%}  p0 {p.max() / p0 - 1:+.2%}"
            f"  its {iterations}  {time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    hertz = HertzSphere()
    for n in (1.5, 2.0, 3.0, 5.0):
        print(run(hertz, n), flush=True)
    print(run(HertzSphere(L=2.0), 3.0), flush=True)
