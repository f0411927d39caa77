"""Benchmark: the LU factors kept for Newton's quadratic phase in every step, not only in the hold.

The 3D line load keeps the LU factors in its held steps (`steps.hold_factor_reuse`: flexible
GMRES on the factors of an older Jacobian, every solve exact), while each ramp iteration
factorises its Jacobian (42 of the whole run's 45 factorisations). Keeping them everywhere
(`steps.factor_reuse`) did not pay in the ramp: the contact set moves between iterates and
GMRES needs many iterations. This script asks whether it pays in the ramp's *last* iterations,
where Newton is quadratic and the Jacobian should barely move: a SNES monitor switches the
solver to FGMRES on the kept factors (`linear.use_kept_factors`, the hold's own switch) for
the solve that follows an iteration whose residual norm fell to at most `--theta` times the
previous iterate's, and back to a factorisation otherwise; held steps keep their factors as
the scene says. Every solve stays exact (FGMRES to 1e-10 on the true residual, or the
fallback's factorisation after 2 × the hold's limit), so Newton's iterates are the direct
route's. `steps.jacobian_reuse = 0` (set below) lets Newton reassemble in these iterations:
with the scene's 0.05 they would be chord iterations on the kept matrix, which the FGMRES
solves in one iteration.

Measured 2026-11-27, 08:36-08:49 UTC, the runs back to back, each alone on the machine (load
from its own 2 ranks; the machine then ran the scene's command in 227 s, against 194 s at
07:26 UTC the same morning: compare the counts and the rows with each other):

| line-load-3d, 2 ranks | steps | Newton | LU | kept solves (fallbacks) | triangular solves | wall |
| --- | ---: | ---: | ---: | ---: | ---: | ---: |
| the scene (`--off`) | 16 | 73 | 45 (150 s) | 6 (0) | 241 (21 s) | 227 s |
| gate 0.2, `jacobian_reuse = 0` | 16 | 69 | 36 (124 s) | 23 (5) | 585 (51 s) | 238 s |
| gate 0.05, `jacobian_reuse = 0` | 16 | 69 | 44 (158 s) | 12 (2) | 367 (35 s) | 259 s |

(Per step, the gated runs: 7 3 4 4 5 7 8 5 8 5 in the ramp, 2 2 2 3 2 2 in the hold, against
the scene's 8 3 4 4 5 7 9 6 8 5 and 2 2 2 4 2 2.) Even after a 20-fold cut of the residual
the solves on the last iteration's factors took 4-30 FGMRES iterations, and 30 (the cap:
a factorisation follows) in a third of them: between two iterates of the ramp the Jacobian
still differs in the contact rows of the points that switch. The factorisations saved are
paid for in triangular solves. The 2D line load (`--scene line-load-1pct --set
steps.hold_factor_reuse=15`, one rank) says the same: 89 Newton iterations and 72
factorisations with the hold's factors alone, 91 and 82 (gate 0.2) or 91 and 91 (gate 0.05)
with the gate. The gated 2D run is not repeatable to the count: five runs gave 91 Newton
iterations and 82-83 factorisations (541-557 triangular solves) four times and 95 and 70
(492) once, 7.4-8.0 s of stepping against the hold-only run's 6.6 s; with
`OPENBLAS_NUM_THREADS=1` two runs gave the same 91, 82 and 550. OpenBLAS's threads change the
rounding inside MUMPS, and the gate's discrete choices (a solve at the cap or one iteration
under it) carry that into the path. This script, run again after the table (θ = 0.2,
08:53-08:58 UTC, pictures off), repeated the 3D row: 69 Newton iterations, 36
factorisations, 585 triangular solves, 5 fallbacks. Not kept: no scene key.

Gated on the contact set instead (`--set-gate 0`: kept factors while no penetrating quadrature
point differs from the iterate last factorised; 2026-11-27, 10:44-10:47 UTC, idle, pictures
off): 69 Newton iterations, 48 factorisations, 215 triangular solves, stepping 199.7 s, against
the scene's 73, 45, 241 and 189.9 s (`--off`, 10:47-10:51 UTC). The gate opened 11 times, 10 of
them at the iterate Newton accepted (no solve follows): the set reaches its converged form only
at a step's last iterate or the one before. Its one gated solve took 4 FGMRES iterations.
Rerun at load 3-7: the same counts.

    mpiexec -n 2 python benchmarks/kept_factors_gate.py [--off] [--theta 0.2] [--set-gate K]
        [--out DIR]
    python benchmarks/kept_factors_gate.py --scene line-load-1pct --set steps.hold_factor_reuse=15
"""

import time

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc
from timing import scene_and_out, scene_parser

import fingertip_dolfinx  # noqa: F401  (sets up the DOLFINx wheel)

# isort: split
from fingertip_dolfinx.outputs import read_csv
from fingertip_dolfinx.runner import Run
from fingertip_dolfinx.stepping.linear import use_kept_factors


class ContractionGate:
    """Kept factors for the solve after an iteration that cut the residual to ≤ θ of the
    previous iterate's, in every step; held steps as the scene (FactorReuse.hold)."""

    def __init__(self, stepper, theta: float):
        self.factor, self.theta = stepper.factor, theta
        self.held, self.previous, self.solves = False, None, []
        self.factor.hold = self.hold  # the stepper's call at each solve's start and end
        stepper.snes.setMonitor(self.monitor)
        self.ksp = stepper.snes.getKSP()
        self.ksp.setPostSolve(self.post_solve)

    def hold(self, held: bool) -> None:
        """A Newton solve starts (held or not) or ends (False): no contraction seen yet."""
        self.held, self.previous = held, None
        self._switch(held)

    def monitor(self, snes, its: int, norm: float) -> None:
        """After each iteration (and before the first): the next solve's mode."""
        fast = its >= 1 and self.previous is not None and norm <= self.theta * self.previous
        self.previous = norm
        self._switch(self.held or fast)

    def _switch(self, kept: bool) -> None:
        """FGMRES on the kept factors (`kept`) or a factorisation per solve, as the hold's."""
        if kept != self.factor._active:
            self.factor._active = kept
            use_kept_factors(self.ksp, self.factor.limit, kept)

    def post_solve(self, ksp, b, x) -> None:
        """FactorReuse's own post-solve (its fallback), and the iterations of a kept solve."""
        kept, its = self.factor._active, ksp.getIterationNumber()
        self.factor._postsolve(ksp, b, x)
        if kept:  # a held step's solve is marked "h"
            self.solves.append(f"h{its}" if self.held else its)


class SetGate(ContractionGate):
    """Kept factors for the solve at an iterate whose contact set (`NitscheContact.active_set`,
    the penetrating quadrature points) differs from the set of the iterate last factorised by
    at most `most` points over all ranks; held steps as the scene."""

    def __init__(self, stepper, contact, comm, most: int):
        super().__init__(stepper, 0.0)
        self.contact, self.comm, self.most = contact, comm, most
        self.factored_set, self.current, self.switches = None, None, []

    def monitor(self, snes, its: int, norm: float) -> None:
        """After each iteration (and before the first): this iterate's set, the next mode."""
        self.current = self.contact.active_set().copy()
        differ = (self.comm.allreduce(int(np.count_nonzero(self.current != self.factored_set)))
                  if self.factored_set is not None else None)
        fast = differ is not None and differ <= self.most
        self._switch(self.held or fast)
        if not self.factor._active:
            self.factored_set = self.current  # this iterate's Jacobian is factorised
        elif fast:
            self.switches.append(differ)

    def post_solve(self, ksp, b, x) -> None:
        fallbacks = self.factor.fallbacks
        super().post_solve(ksp, b, x)
        if self.factor.fallbacks > fallbacks:
            self.factored_set = self.current


def main():
    parser = scene_parser(__doc__, "line-load-3d")
    parser.add_argument("--theta", type=float, default=0.2,
                        help="keep the factors after a cut of the residual to <= theta")
    parser.add_argument("--off", action="store_true", help="the scene as it is")
    parser.add_argument("--set-gate", type=int, default=None, metavar="K",
                        help="gate on the contact set instead: kept factors while at most K "
                             "points differ from the set of the iterate last factorised")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    overrides = args.overrides + ([] if args.off else ["steps.jacobian_reuse=0"])
    scene, out = scene_and_out(args, comm, overrides)
    PETSc.Log.begin()
    job = Run(scene, out, comm, resume=False, progress=False)
    if job.stepper.factor is None:
        raise SystemExit("the scene keeps no factors: add --set steps.hold_factor_reuse=15")
    if args.off:
        gate = None
    elif args.set_gate is not None:
        gate = SetGate(job.stepper, job.problem.contact, comm, args.set_gate)
    else:
        gate = ContractionGate(job.stepper, args.theta)
    wall = time.perf_counter()
    job.run()
    wall = time.perf_counter() - wall
    events = {e: PETSc.Log.Event(e).getPerfInfo() for e in ("MatLUFactorNum", "MatSolve")}
    summary = job.finish(True, None, wall)
    if comm.rank != 0:
        return
    h = read_csv(out / "history.csv")
    factor = job.stepper.factor
    print(f"steps {summary['time_steps']}, Newton iterations {summary['newton_iterations']}, "
          + ", ".join(f"{e} {int(i.get('count', 0))} ({i.get('time', 0.0):.1f} s)"
                      for e, i in events.items())
          + f", kept solves {factor.kept}, fallbacks {factor.fallbacks}; stepping {wall:.1f} s")
    print("per step:", " ".join(str(int(i)) for i in h["newton_iterations"]))
    if gate is not None:
        print("FGMRES iterations of the solves on kept factors:", gate.solves)
        if isinstance(gate, SetGate):
            print("points differing where the gate opened (at the accepted iterate too, "
                  "where no solve follows):", gate.switches)


if __name__ == "__main__":
    main()
