"""Mindlin's sphere in 3D (studies.problems.MindlinSphere): a rigid sphere pressed into an elastic
half block with Coulomb friction (physics/friction.py), then dragged along x; the stick radius
along the drag and across it against c = a (1 − Q/(μP))^(1/3) on a ladder of contact mesh sizes,
and gross slip Q = μP.

Run: `python benchmarks/cattaneo_mindlin_3d.py [exact] [n ...]` (serial; n: the contact mesh
size a/n, default 1.5 2; a/1.5: 92 s on the shared machine, 13 min under heavy load at
`nice -n 15`). `exact`: `MindlinSphere.exact()`, the incompressible Taylor–Hood block with
R = 10 mm, pressed in one step, the shifts scaled by 1/R (default ladder 1.5 2 3 4).
Prints one row per step: the mesh, the sphere's shift, Q/(μP), c/a along the drag
(on z = 0) and across it (on x = 0) and Mindlin's, the L1 distance of the tangential traction
q_x from Mindlin's and of the pressure from Hertz's (integrals over the contact face, relative
to the closed form's), ∫|q_z| over ∫|q_th|, the largest transverse traction |q_z| over μ p0,
the largest |f| − μp over μ p0, and the Newton iterations; then the mesh's wall time.
"""

import sys
import time

from mpi4py import MPI

import fingertip_dolfinx  # noqa: F401
from fingertip_dolfinx.studies.problems import MindlinSphere, drag_sphere

#: Shifts of the sphere (mm): Q/(μP) ≈ 0.2, 0.4, 0.57, 0.73, then gross slip (Mindlin's
#: slip distance at full slip, μδ(2 − ν)/(2(1 − ν)) = 1.8 µm, plus the block's compliance).
SHIFTS = (3e-4, 6e-4, 9e-4, 1.2e-3, 2.4e-3, 3.2e-3)


def run(problem: MindlinSphere, n: float, shifts, press_steps: int) -> None:
    start = time.perf_counter()
    rows = drag_sphere(problem, problem.a_target / n, shifts, press_steps=press_steps,
                       comm=MPI.COMM_WORLD,
                       prefix=f"bench_mindlin3d_{problem.mixed}_{n}_".replace(".", "_"))
    for r in rows:
        c_th = r["c_theory"] / r["a"]
        q = (f"{r['q_error']:.4f}  |q_z| {r['q_z_error']:.4f}" if r["shift"] > 0
             else "  -     |q_z|   -   ")
        print(f"h = a/{n:<4g} cells {r['cells']:6d}  shift {r['shift'] * 1e3:6.4f} µm"
              f"  Q/(μP) {r['ratio']:+.4f}  c/a along {r['c_along'] / r['a']:.3f}"
              f"  across {r['c_across'] / r['a']:.3f}  theory {c_th:.3f}"
              f"  L1 q {q}  L1 p {r['p_error']:.4f}"
              f"  max|q_z|/(μp0) {r['q_across']:.3f}"
              f"  (|f| − μp)/(μp0) {r['coulomb_excess']:.1e}"
              f"  its {r['newton_iterations']}", flush=True)
    print(f"  {time.perf_counter() - start:.1f} s", flush=True)


if __name__ == "__main__":
    args = sys.argv[1:]
    exact = bool(args) and args[0] == "exact"
    ladder = [float(a) for a in args[exact:]] or ((1.5, 2.0, 3.0, 4.0) if exact else (1.5, 2.0))
    for n in ladder:
        if exact:
            problem = MindlinSphere.exact()
            run(problem, n, tuple(s * problem.depth / MindlinSphere.depth for s in SHIFTS), 1)
        else:
            run(MindlinSphere(), n, SHIFTS, 2)
