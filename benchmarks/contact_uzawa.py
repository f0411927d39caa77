"""Benchmark: an augmented-Lagrangian (Uzawa) loop around each Newton solve of a scene (the 1 %
line load by default), against the penalty law it wraps: Newton iterations, factorisations,
stepping over its bound, forces and penetration (line_load.py's printout, plus one line per
solve: the multiplier updates and Newton iterations it took).

The law is the scene's penalty with each indenter's gap g shifted by a frozen multiplier gap
μ ≥ 0 (mm): p = [γ (μ − g)]_+ = [λ − γ g]_+ with λ = γ μ, the augmented Lagrangian's pressure
(Alart & Curnier). μ lives on the cells of the contact facets (discontinuous Lagrange of the
displacement's degree: in one cell γ is one number, so μ ← [μ − g]_+ at its nodes is exactly
Uzawa's λ ← [λ − γ g]_+). Newton solves with μ fixed (its force is then the gradient of
½ ∫ γ [μ − g]_+² ds: conservative); then μ is updated, and the solve repeated, until
the update would move μ by at most UZAWA_TOL (mm; that last update is not applied, so that the
state and its forces are those of the μ it was solved with) or after UZAWA_MAX updates
(UZAWA_MAX=0: one update per step, at the accepted state, a multiplier one step behind). μ is
kept with the accepted state and restored with it after a failed attempt (the next step starts
from the last step's μ). At convergence g ≥ 0 at the nodes (the penalty's penetration p/γ is
gone), so the force is the exact constraint's, not the penalty's.

Measured on line-load-1pct, 2026-11-26 (one rank, niced, a loaded machine: count
factorisations; docs/benchmarks/contact-newton.md has the table): with γ0 = 100 (the scene's)
and UZAWA_TOL 1e-5 mm, 2-4 updates per ramp step, 139 Newton iterations (111 in 15 ramp steps)
and 127 factorisations in 30 steps, against the penalty's 89 (72 in 14) and 83 in 28; forces
+0.21 % at 1 s, +0.23 % at 100 s (the exact constraint's answer, not the penalty's);
penetration 0.12 µm (penalty 1.35). Each update moves the zone's edge again and Newton settles
it again, at the same linear rate: the multiplier is ~0 there, so the kink inside Newton is
the penalty's. UZAWA_MAX=0 (lagged): 123 iterations, 112 factorisations, forces +0.15 % and
+0.22 %, 0.38 µm. A tolerance relative to max μ (1e-2) hit UZAWA_MAX at small loads, where μ
is small and the edge's nodes toggle: 177 iterations, a cut. With γ0 = 10 (a soft inner law,
the multiplier carrying the load) Newton fails inside the loop at 0.24 s, steps cut to 0.4 ms.

In 3D (line-load-3d's ramp to 1 s, 2 ranks, 2026-11-27): 16 steps, 151 Newton iterations and
112 factorisations against the penalty's 10, 59 and 42; force at 1 s +0.17 %, penetration
0.028 µm at most (penalty 2.38 µm).

    PYTHONPATH=.. python contact_uzawa.py --scene line-load-1pct [--set KEY=VALUE] [--newton]
    mpiexec -n 2 python contact_uzawa.py --scene line-load-3d --set protocol.end_time=1.0 \
        --set "output.times=[1.0]" --set output.pictures=false
    (environment: UZAWA_TOL=1e-5 mm, UZAWA_MAX=10)
"""

import os
import sys
from pathlib import Path

import numpy as np
import ufl
import ufl.algorithms
from mpi4py import MPI

import fingertip_dolfinx  # noqa: F401  (sets up the DOLFINx wheel)

# isort: split
from dolfinx import fem

from fingertip_dolfinx.geometry.indenters import Indenter
from fingertip_dolfinx.runner import Run

sys.path.insert(0, str(Path(__file__).resolve().parent))
import line_load  # noqa: E402

TOL = float(os.environ.get("UZAWA_TOL", "1e-5"))  # mm: 1 % of the penalty's 1.35 µm
MAX = int(os.environ.get("UZAWA_MAX", "10"))


class Multiplier:
    """The multiplier gap μ of every indenter's contact term, built while the contact forms
    are: `Indenter.signed_distance` returns g − μ in the meantime."""

    def __init__(self):
        self.mu, self.gaps = None, []

    def shifted(self, original):
        def signed_distance(indenter, x, y_tip):
            g, n = original(indenter, x, y_tip)
            if self.mu is None:
                u = next(c for c in ufl.algorithms.extract_coefficients(x)
                         if isinstance(c, fem.Function))
                k = u.function_space.ufl_element().embedded_superdegree
                self.mu = fem.Function(fem.functionspace(u.function_space.mesh, ("DG", k)))
            self.gaps.append(g)
            return g - self.mu, n
        return signed_distance

    def attach(self, contact) -> None:
        """The update's expression, on the cells of `contact`'s facets (one indenter)."""
        if len(self.gaps) != 1:
            raise SystemExit("contact_uzawa.py handles one indenter")
        points = self.mu.function_space.element.interpolation_points
        self.update = fem.Expression(ufl.max_value(self.mu - self.gaps[0], 0.0), points)
        self.cells = contact._facet_entities[:, 0]

    def step(self, apply: bool = True) -> float:
        """μ ← [μ − g]_+ (if `apply`; else μ is left as it was: the state solved with it stays
        consistent with it, and so do its forces); returns max |Δμ| (mm) over every rank."""
        old = self.mu.x.array.copy()
        self.mu.interpolate(self.update, cells0=self.cells)
        comm = self.mu.function_space.mesh.comm
        change = comm.allreduce(float(np.max(np.abs(self.mu.x.array - old), initial=0.0)),
                                op=MPI.MAX)
        if not apply:
            self.mu.x.array[:] = old
        self.mu.x.scatter_forward()
        return change


def install(job: Run, multiplier: Multiplier) -> None:
    """Wrap the stepper's Newton solve in the Uzawa loop; keep μ with the accepted state."""
    stepper, problem = job.stepper, job.problem
    multiplier.attach(problem.contact)
    accepted, newton = multiplier.mu.x.array.copy(), stepper.solve_once

    def solve_once():
        total, updates, change = 0, 0, np.nan
        while True:
            reason, its = newton()
            total += its
            if reason <= 0 or MAX == 0:
                break
            change = multiplier.step(apply=False)
            if change <= TOL or updates >= MAX:
                break
            multiplier.step()
            updates += 1
        if job.comm.rank == 0:
            print(f"  uzawa t = {problem.time:.6g} s: {updates} updates, {total} Newton "
                  f"iterations, last max|dmu| {change:.2e} mm", flush=True)
        return reason, total

    accept, restore = problem.accept, problem.restore

    def accepted_too():
        accept()
        if MAX == 0:  # lagged: the accepted state's update, for the next step
            multiplier.step()
        accepted[:] = multiplier.mu.x.array

    def restored_too():
        restore()
        multiplier.mu.x.array[:] = accepted

    stepper.solve_once, problem.accept, problem.restore = solve_once, accepted_too, restored_too


def main():
    multiplier, original = Multiplier(), Indenter.signed_distance

    class UzawaRun(Run):
        def __init__(self, *args, **kwargs):
            Indenter.signed_distance = multiplier.shifted(original)
            try:
                super().__init__(*args, **kwargs)
            finally:
                Indenter.signed_distance = original
            install(self, multiplier)

    line_load.Run = UzawaRun
    line_load.main()


if __name__ == "__main__":
    main()
