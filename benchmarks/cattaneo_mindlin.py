"""Cattaneo–Mindlin in plane strain (studies.problems.CattaneoMindlin): a rigid cylinder pressed
into an elastic block with Coulomb friction (physics/friction.py), then dragged along it; the
stick half-width c against c = a sqrt(1 − Q/(μP)) on a ladder of contact mesh sizes, and gross
slip Q = μP.

Run: `python benchmarks/cattaneo_mindlin.py` (serial; ~1.5 min on the shared machine). Prints
one row per step: the mesh (h = a/n at the contact), the cylinder's shift, Q/(μP), c/a measured
and in theory, their difference over a, the mean |q − q_th| of the tangential traction
from Cattaneo–Mindlin's q(x) over the contact (|x| < a, the sample points) relative to the mean
|q_th| (an L1 distance), and the Newton iterations.
"""

import time

from mpi4py import MPI

import fingertip_dolfinx  # noqa: F401
from fingertip_dolfinx.studies.problems import CattaneoMindlin, drag

#: Shifts of the cylinder (mm): Q/(μP) ≈ 0.22, 0.44, 0.66, 0.86, then gross slip.
SHIFTS = (2e-4, 4e-4, 6e-4, 8e-4, 1.2e-3)


def run(problem: CattaneoMindlin, n: float) -> None:
    start = time.perf_counter()
    rows = drag(problem, problem.a_target / n, SHIFTS, prefix=f"bench_mindlin_{n}_".replace(
        ".", "_"), comm=MPI.COMM_WORLD)
    for r in rows:
        print(f"h = a/{n:<4g} cells {r['cells']:5d}  shift {r['shift'] * 1e3:4.2f} µm"
              f"  Q/(μP) {r['ratio']:.4f}  c/a {r['c'] / r['a']:.4f}"
              f"  theory {r['c_theory'] / r['a']:.4f}"
              f"  (c − c_th)/a {(r['c'] - r['c_theory']) / r['a']:+.4f}"
              f"  |q − q_th|/|q_th| {r['q_error']:.4f}"
              f"  its {r['newton_iterations']}", flush=True)
    print(f"  {time.perf_counter() - start:.1f} s", flush=True)


if __name__ == "__main__":
    problem = CattaneoMindlin()
    for n in (2.5, 5.0, 10.0):
        run(problem, n)
