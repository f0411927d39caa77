"""Benchmark: Newton directions that settle the penalty contact inside the linear solve.

Each Newton iteration of a scene (the 1 % line load by default) solves, instead of J y = F,
the model in which the bulk is linearised at the iterate u and the contact is kept exact:

    M(w) = F(u) + J w + C(w) = 0,   C(w) = Fc(u + w) − Fc(u) − dFc(u)[w],   y = −w,

with Fc the penalty contact's residual (contact.NitscheContact.residual, θ = 0 penalty: it
depends on u only on the surface, so C is a surface integral). Where no surface point crosses
the law's kink between u and u + w, C is second order in w (the normal's rotation) and the
model is Newton's; where the zone grows, the points that would enter it are pushed back by
their real penalty force inside the linear solve, not one Newton iteration later. The model
is solved by a semismooth inner Newton (A_j = J + dFc(u + w_j) − dFc(u), backtracking on
|M|) whose linear systems are solved by GMRES right-preconditioned by the LU factors SNES
made of J (A_j − J lives on the contact's rows only); an inner loop that does not reach
`--rtol` × |F| in MAX_INNER iterations falls back to Newton's own direction J⁻¹F. It runs
as SNES's KSP (a python KSP), so the stepper, the line search and the step control are the
scene's.

Measured on line-load-1pct, 2026-11-27 06:00-06:15 UTC, one rank, another engineer's 2-rank
3D run beside it (load 2-4: CPU seconds and counts are the measures); the scene's baseline
(`--off`): 28 steps, 89 Newton iterations, 83 LU factorisations, no cut, stepping 4.8 CPU s;
forces 1.179254e-3 and 1.047498e-3 N/mm at 1 and 100 s:

| inner model, `--rtol`, `--gmres-rtol` | steps | Newton | cuts | LU | GMRES | CPU s | force |
| --- | ---: | ---: | ---: | ---: | ---: | ---: | --- |
| exact contact, 1e-8, 1e-10 | 25 | 66 | 0 | 61 | 3 481 | 11.5 | −0.011 %, +0.027 % |
| exact contact, 1e-4, 1e-6 | 27 | 71 | 0 | 65 | 2 330 | 9.3 | −0.005 %, +0.028 % |
| exact contact, 1e-3, 1e-4 | 26 | 68 | 0 | 61 | 1 863 | 8.1 | −0.004 %, +0.002 % |
| the same, 1e-4, tangent predictor | 30 | 71 | 2 | 96 | 2 739 | 13.0 | −0.002 %, +0.028 % |
| linearised gap, 1e-8, 1e-10 | 36 | 114 | 3 | 125 | 5 669 | 20.3 | −0.007 %, −0.006 % |

(Force: at 1 s and 100 s against the baseline's. The inner loop fell back to Newton's
direction in 10-18 of the ~70 solves. The tangent predictor at every step is
`--set steps.tangent_start=true --set steps.extrapolate=false`; its baseline, `--off` with
the same options: 26 steps, 85 Newton iterations, 83 LU, 5.0 CPU s.)

What it shows:

- The model does what it is meant to: from first touch to mid-ramp most steps converge in one
  Newton iteration (with the tangent predictor, 2 counting the predictor: 1, 2, 2, 2, 3, 2,
  2, 2, 2, 2, 2 over the first 11 ramp steps, against 3-7), and Newton's count falls by a
  quarter (66-71 against 85-89) with the answers within the 0.1 % rule. The late ramp, where
  the skin wraps the wedge's flank, still takes 4-13.
- It does not pay: each Newton iteration costs 25-50 GMRES iterations on the kept factors
  (3-4 inner iterations of 8-12), and in 2D a triangular solve with its mat-vec and the
  surface assembly costs ~1/8 of a factorisation (2.2 ms against 17 ms), so the stepping
  costs 1.7-2.4 times the baseline. In 3D (line-load-3d, 2 ranks) the first Newton
  iteration's inner systems needed more than 40 GMRES iterations each (the switching points
  are hundreds: the rank of A_j − J), and the first inner loop had not ended after 7
  minutes; stopped. A cheaper inner solver (one whose cost does not grow with the points
  that switch) is what this would need.
- Linearising the gap too (a first version of this script: the law [−g − n·w]_+ with the normal
  frozen at u) is worse than the scene: near the 25 µm tip a point that slides 10-20 µm along
  the surface (Newton's steps at residuals of 1e-6 N/mm are that long: the frictionless
  contact's soft tangential mode) sees its gap change by ~w²/2R, tens of times the 0.1 µm
  smoothing band; bt's line search then rejects the direction.

    .venv/bin/python benchmarks/contact_inner_model.py [--scene line-load-1pct] [--off]
        [--rtol 1e-4] [--gmres-rtol 1e-6] [--verbose] [--set key=value ...]
"""

import time

import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc
from timing import scene_and_out, scene_parser

import fingertip_dolfinx  # noqa: F401  (sets up the DOLFINx wheel)

# isort: split
from dolfinx import fem, la
from dolfinx.fem import petsc as fpetsc

from fingertip_dolfinx.outputs import read_csv
from fingertip_dolfinx.runner import Run
from fingertip_dolfinx.stepping.stepper import _kept_factor_gmres

#: Inner iterations before falling back to Newton's direction; GMRES's cap per inner solve.
MAX_INNER, MAX_GMRES = 8, 40


class ContactCorrection:
    """C(w) and dC(w)[d] = dFc(u + w)[d] − dFc(u)[d] as surface forms of Functions w, d."""

    def __init__(self, problem):
        u = problem.u
        V = u.function_space
        self.w, self.d, self.out = (fem.Function(V) for _ in range(3))
        self.others = [fem.Function(f.function_space) for f in problem.unknowns[1:]]
        Fc = problem.contact.residual(ufl.TestFunction(V))
        shifted = ufl.replace(Fc, {u: u + self.w})
        self.C = fem.form(shifted - Fc - ufl.derivative(Fc, u, self.w))
        self.dC = fem.form(ufl.derivative(shifted, self.w, self.d)
                           - ufl.derivative(Fc, u, self.d))

    def apply(self, form, source: PETSc.Vec, into: fem.Function, result: PETSc.Vec,
              sign: float = 1.0) -> None:
        """result ← form with `into` set to sign × source's displacement block."""
        fpetsc.assign(source, [into, *self.others])
        into.x.array[:] *= sign
        into.x.scatter_forward()
        self.out.x.array[:] = 0.0
        fem.assemble_vector(self.out.x.array, form)
        self.out.x.scatter_reverse(la.InsertMode.add)
        for o in self.others:
            o.x.array[:] = 0.0
        fpetsc.assign([self.out, *self.others], result)


class InnerModel:
    """SNES's KSP (python type): y with J y − F − C(−y) = 0 (SNES's update is x − λ y)."""

    def __init__(self, problem, rtol: float, gmres_rtol: float, verbose: bool = False):
        self.c = ContactCorrection(problem)
        self.rtol, self.gmres_rtol, self.verbose = rtol, gmres_rtol, verbose
        self.gmres, self.J, self.work = None, None, None
        self.inner, self.gmres_its, self.fallbacks = [], 0, 0

    def setUp(self, ksp):
        pass

    def mult(self, _mat, dy: PETSc.Vec, out: PETSc.Vec) -> None:
        """The inner Jacobian A_j = J + dC(−y_j) applied to dy."""
        self.J.mult(dy, out)
        self.c.apply(self.c.dC, dy, self.c.d, self.work["tmp"])
        out.axpy(1.0, self.work["tmp"])

    def _model(self, y: PETSc.Vec, b: PETSc.Vec, r: PETSc.Vec) -> float:
        """r ← J y − b − C(−y), the model's residual; returns its norm."""
        self.c.apply(self.c.C, y, self.c.w, self.work["tmp"], sign=-1.0)
        self.J.mult(y, r)
        r.axpy(-1.0, b)
        r.axpy(-1.0, self.work["tmp"])
        return r.norm()

    def solve(self, ksp, b: PETSc.Vec, y: PETSc.Vec) -> None:
        pc = ksp.getPC()
        self.J = ksp.getOperators()[0]
        if self.work is None:
            self.work = {k: b.duplicate() for k in ("tmp", "r", "trial", "r_trial", "dy", "y0")}
        pc.apply(b, y)
        y.copy(self.work["y0"])
        done, n, log = self._inner(pc, b, y)
        if not done:
            self.work["y0"].copy(y)  # Newton's own direction
            self.fallbacks += 1
        self.inner.append(n)
        if self.verbose and MPI.COMM_WORLD.rank == 0:
            print(f"inner: |F| {b.norm():.2e}, converged {done}: {' '.join(log)}")
        ksp.setIterationNumber(1 + n)
        ksp.setConvergedReason(PETSc.KSP.ConvergedReason.CONVERGED_RTOL)

    def _inner(self, pc, b: PETSc.Vec, y: PETSc.Vec) -> tuple[bool, int, list[str]]:
        """The semismooth inner Newton on the model from y = J⁻¹F, backtracking on |M|."""
        w = self.work
        norm, target, log = self._model(y, b, w["r"]), self.rtol * b.norm(), []
        for n in range(MAX_INNER):
            log.append(f"{norm / b.norm():.1e}")
            if norm <= target:
                return True, n, log
            if not self._solve_inner(pc, w["r"], w["dy"]):
                return False, n, [*log, "gmres-failed"]
            step = 1.0
            while step > 1e-2:
                w["trial"].waxpy(-step, w["dy"], y)
                new = self._model(w["trial"], b, w["r_trial"])
                if new < norm:
                    break
                step *= 0.5
            else:
                return False, n, [*log, "no-descent"]
            w["trial"].copy(y)
            w["r_trial"].copy(w["r"])
            norm = new
        return False, MAX_INNER, log

    def _solve_inner(self, pc, r: PETSc.Vec, dy: PETSc.Vec) -> bool:
        A = PETSc.Mat().createPython(self.J.getSizes(), self, comm=self.J.getComm())
        A.setUp()
        if self.gmres is None:
            self.gmres = _kept_factor_gmres(self.J.getComm(), pc, self.gmres_rtol, MAX_GMRES)
        self.gmres.setOperators(A, A)
        pc.setReusePreconditioner(True)
        try:
            self.gmres.solve(r, dy)
        finally:
            pc.setReusePreconditioner(False)
            A.destroy()
        self.gmres_its += self.gmres.getIterationNumber()
        return self.gmres.getConvergedReason() > 0


def main():
    parser = scene_parser(__doc__, "line-load-1pct")
    parser.add_argument("--off", action="store_true", help="the scene's own Newton")
    parser.add_argument("--rtol", type=float, default=1e-4,
                        help="the inner model's residual, relative to |F|")
    parser.add_argument("--gmres-rtol", type=float, default=1e-6)
    parser.add_argument("--verbose", action="store_true", help="a line per inner solve")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    scene, out = scene_and_out(args, comm)
    PETSc.Log.begin()
    job = Run(scene, out, comm, resume=False, progress=False)
    inner = None if args.off else InnerModel(job.problem, args.rtol, args.gmres_rtol,
                                             args.verbose)
    if inner is not None:
        ksp = job.stepper.snes.getKSP()
        ksp.setType(PETSc.KSP.Type.PYTHON)
        ksp.setPythonContext(inner)
    wall, cpu = time.perf_counter(), time.process_time()
    job.run()
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    lu = int(PETSc.Log.Event("MatLUFactorNum").getPerfInfo().get("count", 0))
    summary = job.finish(True, None, wall)
    if comm.rank != 0:
        return
    h = read_csv(out / "history.csv")
    print(f"steps {summary['time_steps']}, Newton iterations {summary['newton_iterations']}, "
          f"cuts {int(h['cuts'].sum())}, LU factorisations {lu}; stepping {wall:.1f} s, "
          f"CPU {cpu:.1f} s")
    print("Newton iterations per step:", " ".join(str(int(i)) for i in h["newton_iterations"]))
    print("forces:", ", ".join(f"{k} s {v:.7g}" for k, v in
                               summary["force_at_output_times_N_per_mm"].items()))
    if inner is not None:
        print(f"inner iterations per solve (count of 0, 1, ...): {np.bincount(inner.inner)}; "
              f"GMRES iterations {inner.gmres_its}; fallbacks {inner.fallbacks}")


if __name__ == "__main__":
    main()
