"""Cattaneo–Mindlin in plane strain (studies.problems.CattaneoMindlin): a rigid cylinder pressed
into an elastic block with Coulomb friction (physics/friction.py), then dragged along it; the
stick half-width c against c = a sqrt(1 − Q/(μP)) on a ladder of contact mesh sizes, the
tangential traction against Cattaneo–Mindlin's q(x) and the pressure against Hertz's, and gross
slip Q = μP.

Run: `python benchmarks/cattaneo_mindlin.py` (serial; ~1.5 min on the shared machine): the
default block (ν = 0.49, P2 displacement, R = 1 mm) on a/2.5, a/5, a/10.
`python benchmarks/cattaneo_mindlin.py exact [OUT.png]` (~5 min): `CattaneoMindlin.exact()`, the
block on which the closed form is exact (ν = 1/2, Taylor–Hood P2/P1, R = 10 mm), on a/2.5 to
a/20; with OUT.png, the figure of docs/benchmarks/friction.md (q on the finest mesh, the L1
distances against h).

Prints one row per step: the mesh (h = a/n at the contact), the cylinder's shift, Q/(μP), c/a
measured and in theory, their difference over a, the L1 distance ∫|q − q_th| dx / ∫|q_th| dx
of the tangential traction from Cattaneo–Mindlin's over the contact face (`mindlin.l1_distance`),
the same for the pressure against Hertz's p0 sqrt(1 − x²/a²), and the Newton iterations.
"""

import sys
import time

from mpi4py import MPI

import fingertip_dolfinx  # noqa: F401
from fingertip_dolfinx.studies.problems import CattaneoMindlin, drag

#: Shifts of the cylinder (mm) on R = 1 mm: Q/(μP) ≈ 0.22, 0.44, 0.66, 0.86, then gross slip.
#: At the same a the tangential compliance is the same and Q ∝ P ∝ 1/R: on R the shifts for
#: the same Q/(μP) are these over R.
SHIFTS = (2e-4, 4e-4, 6e-4, 8e-4, 1.2e-3)


def run(problem: CattaneoMindlin, n: float, name: str) -> list[dict]:
    start = time.perf_counter()
    shifts = tuple(s / problem.R for s in SHIFTS)
    rows = drag(problem, problem.a_target / n, shifts, prefix=f"bench_{name}_{n}_".replace(
        ".", "_"), comm=MPI.COMM_WORLD)
    for r in rows:
        # pressed (shift 0) the closed form's q is 0: no relative distance
        q = f"{r['q_error']:.4f}" if r["shift"] > 0 else "  -   "
        print(f"h = a/{n:<4g} cells {r['cells']:5d}  shift {r['shift'] * 1e3:6.4f} µm"
              f"  Q/(μP) {r['ratio']:.4f}  c/a {r['c'] / r['a']:.4f}"
              f"  theory {r['c_theory'] / r['a']:.4f}"
              f"  (c − c_th)/a {(r['c'] - r['c_theory']) / r['a']:+.4f}"
              f"  L1 q {q}  L1 p {r['p_error']:.4f}"
              f"  its {r['newton_iterations']}", flush=True)
    print(f"  {time.perf_counter() - start:.1f} s", flush=True)
    return rows


def figure(problem: CattaneoMindlin, ladder: dict[float, list[dict]], out: str) -> None:
    """Left: q(x) on the finest mesh at each partial-stick step, against Cattaneo–Mindlin's;
    right: the L1 distances of q (each step) and of p (gross slip) against h/a."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    fig, (left, right) = plt.subplots(1, 2, figsize=(10.0, 3.8), constrained_layout=True)
    finest = max(ladder)
    _, p0 = problem.theory(ladder[finest][-1]["P"])
    for r in ladder[finest][2:]:
        x = r["x_axis"] / r["a"]
        line, = left.plot(x, r["q"] / (problem.mu * p0), ".", ms=2)
        left.plot(x, problem.traction_theory(r["x_axis"], r["P"], r["Q"]) / (problem.mu * p0),
                  "-", lw=0.8, color="k")
        line.set_label(f"Q/(μP) = {r['ratio']:.2f}")
    left.set(xlim=(-1.2, 1.2), ylim=(0, 1.3), xlabel="x/a (about the cylinder's axis)",
             ylabel="q/(μ p0)", title=f"h = a/{finest:g}: measured (dots), closed form (lines)")
    left.legend(fontsize=7, loc="upper center", ncol=3, markerscale=3)
    h = np.array([1 / n for n in sorted(ladder)])
    for k in range(2, len(ladder[finest]) - 1):
        errors = [ladder[n][k]["q_error"] for n in sorted(ladder)]
        right.loglog(h, errors, "o-", ms=3, label=f"q, Q/(μP) = {ladder[finest][k]['ratio']:.2f}")
    right.loglog(h, [ladder[n][-1]["p_error"] for n in sorted(ladder)], "s--k", ms=3,
                 label="p against Hertz (gross slip)")
    right.loglog(h, 0.5 * h, ":", color="gray", label="∝ h")
    right.set(xlabel="h at the contact", ylabel="L1 distance (relative)",
              title="L1 distances: ν = 1/2, Taylor–Hood, R = 10 mm")
    right.set_xticks(h, [f"a/{n:g}" for n in sorted(ladder)])
    right.minorticks_off()
    right.legend(fontsize=7)
    fig.savefig(out, dpi=120)


if __name__ == "__main__":
    if sys.argv[1:2] == ["exact"]:
        exact = CattaneoMindlin.exact()
        ladder = {n: run(exact, n, "exact") for n in (2.5, 5.0, 10.0, 20.0)}
        if len(sys.argv) > 2:
            figure(exact, ladder, sys.argv[2])
    else:
        for n in (2.5, 5.0, 10.0):
            run(CattaneoMindlin(), n, "mindlin")
