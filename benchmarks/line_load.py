"""Benchmark: wall time of a scene (the paper's line load by default) and where it goes.

Prints dofs, steps, Newton iterations per step, the counts of residual and Jacobian
assemblies, LU factorisations and Krylov iterations, seconds per operation (PETSc's own log
events), the stepping time, and its ratio to the lower bound for an implicit scheme on the
same mesh: one Jacobian assembly plus one factorisation and solve per time step (each at its
cost measured in the same run). "Solving" is the stepping minus the results written after
each step (profiles, fields, and at the output times the field pictures: ~5 s of pyvista
rendering, not the solver's).

Why the ratio stays near 6 on the line load (measured, 2026-11-23; counts from PETSc's log):
- Newton iterations: the ramp's 18 steps take 4-14 iterations each (128 of the 164), in a
  slow, line-searched phase while surface points enter the penalty contact zone; the hold's
  15 take 2-3 (one to move, one that reaches snes_atol). The bound assumes 1 per step.
- A kept LU as preconditioner of GMRES on the fresh Jacobian (snes_lag_preconditioner 5 and
  20, persisting across steps) needed 8.4 and 16 Krylov iterations per solve: in 2D a MUMPS
  triangular solve costs 1/9 of a factorisation, so 36 (or 9) factorisations instead of 179
  saved nothing (stepping +2 % and +16 %); steps.factor_reuse (2026-11-27: the kept LU with
  a fresh factorisation after a slow solve, exact solves) on line-load-1pct: 29-72 instead of
  83 factorisations, stepping CPU 5.3-5.5x the bound against 4.5x (docs/benchmarks/
  solvers-3d.md). A kept Jacobian (chord steps) pays only in the
  quadratic phase: steps.jacobian_reuse = 0.02 (the scene's) -17 factorisations; looser
  thresholds lengthen the ramp (stepping.JacobianReuse).
- Line searches: basic (full steps) 37 steps, 3 cuts, 180 factorisations; l2 160
  factorisations but 3.3 residuals per iteration: no gain over bt. MUMPS with METIS
  ordering: the same cost per factorisation.
- Quadrature degree 2 (3 points instead of 6; 2k - 2 for P2 keeps the optimal rate) makes a
  Jacobian ~35 % cheaper but the force moves by 2e-4 (1.1794e-3 against 1.1796e-3 N/mm:
  not the same 4 digits) and Newton takes 206 factorisations: kept at 4.
Why the ramp's Newton converges only linearly (line-load-1pct, 2026-11-23, stepping CPU over
its own bound 4.5-4.6 in repeated runs): with the bt line search taking full steps (λ = 1,
`snes_linesearch_monitor`) the residual falls by ~0.3 per iteration (e.g. 8.8e-3, 1.0e-3,
3.7e-4, 1.3e-4, 5.8e-5, 1.1e-5, 2.0e-6 N/mm over the last ramp step), while the Jacobian is
exact: J d equals the residual's central difference to O(ε²) mid-ramp
(tests/test_line_load.py). `--newton` shows where (2026-11-26): from the second iteration on
70-99 % of the residual sits on four surface nodes at the edge of the contact zone, where the
skin lies along the wedge's flank at gaps of ±0.1 µm and almost no pressure (grazing: g ≈ 0
and p ≈ 0 at once). Newton moves them across the law's kink, or through its 0.1 µm smoothing
band, and the next iteration undoes it; iterations that leave the penetrating set unchanged
are as slow. Semismooth Newton (what newtonls with the exact Jacobian of [·]_+ is) and
primal-dual active sets are superlinear only once every point is on the right side of the
kink, which at grazing points takes gaps resolved to nanometres; an augmented Lagrangian has
the same kink there (λ = 0). The measured variants: no smoothing 4.8; γ0 = 30 4.7 (force
-0.65 %); γ0 = 10 fails at the tip; shorter ramp steps (easy_iterations 3) 4.05 with 92
instead of 83 factorisations; a damped predictor 11.3; 20 µm surface elements over 0.1 or
0.4 mm around the tip instead of 0.25: 131 and 106 Newton iterations instead of 89; the
residual's own law but the Jacobian of a wider smoothing (0.3, 1 µm): fails at first touch, of
the exact kink: 313 ramp iterations instead of 72 (docs/benchmarks/contact-newton.md has the
table). Second round (2026-11-26, LU factorisations against today's 83 in 28 steps): the
tangent predictor at the kinks (steps.tangent_start) the same 89 iterations and 83; at every
step (and steps.extrapolate = false) 85 iterations, 83; the contact's facet rule at the P2
nodes (Gauss-Lobatto) 159, 3 cuts; at degree 12 99; an augmented-Lagrangian (Uzawa) loop
around Newton (contact_uzawa.py) 127 in 30 steps, the forces 0.2 % higher (the exact
constraint's) and 0.12 µm of penetration; Nitsche (θ = 0, γ0 = 10) at 0.36 s of the ramp
after 420 s.
Tried earlier on the preset (Newton its / LU / stepping CPU over the bound): l2 and cp
line searches 87 / 79-95 / 5.4; newtontr 100 / 109 / 5.5; quasi-Newton (L-BFGS scaled by the
Jacobian) 262 its, 13 cuts, 5.3; Broyden: PETSc error 73; Anderson or NGMRES around one Newton
step: DIVERGED_INNER at the first touch; contact smoothing 1 µm instead of 0.1 µm 77 / 87 /
5.0 (and it moves the deflections); snes_atol 3e-6 / 1e-5 / 3e-5: 4.4 / 5.6 / 6.9 (looser
tolerances leave worse iterates, steps are cut); snes_stol 1e-4 4.4, 1e-3 inverted elements;
a drained pulp or an elastic skin 5.3 / 4.9; the contact's facet rule at degree 4 or 2
instead of 6 (fewer points to switch) 5.9 / 5.3. None reaches 2.5.

On a shared machine PETSc's event times (wall) include the other processes' turns: the
script also prints this process's CPU time for the stepping and, measured by itself at the
final state, for one Jacobian + LU + solve, the bound in CPU time. `--reference
accuracy.json` scores the key outputs against an accuracy study's reference.

    .venv/bin/python benchmarks/line_load.py [--scene line-load] [--set key=value ...]
        [--reference docs/results/adaptivity/check-line-load-full/accuracy.json] [--newton]
    .venv/bin/mpiexec -n 2 .venv/bin/python benchmarks/line_load.py
"""

import json
import os
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc
from timing import scene_and_out, scene_parser, tally

import fingertip_dolfinx  # noqa: F401  (sets up the DOLFINx wheel)
from fingertip_dolfinx.keys import KEYS, key_outputs, relative_errors
from fingertip_dolfinx.outputs import read_csv
from fingertip_dolfinx.runner import Run

EVENTS = {"residual": "SNESFunctionEval", "jacobian": "SNESJacobianEval",
          "factorisation": "MatLUFactorNum", "solve": "KSPSolve", "triangular": "MatSolve"}


def main():
    parser = scene_parser(__doc__, "line-load")
    parser.add_argument("--newton", action="store_true",
                        help="print each Newton iteration's residual norm and contact points "
                             "(active, and entered or left since the last iterate), then "
                             "Newton iterations and contact changes per step")
    parser.add_argument("--reference", type=Path, default=None, metavar="JSON",
                        help="an accuracy study's accuracy.json: print each key output's "
                             "relative error against its reference, e.g. docs/results/"
                             "adaptivity/check-line-load-full/accuracy.json")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    scene, out = scene_and_out(args, comm)

    PETSc.Log.begin()
    started, cpu = time.perf_counter(), time.process_time()
    job = Run(scene, out, comm, resume=False, progress=False)
    writing = tally(job, "on_step")  # the results written after each step, pictures too
    newton = NewtonLog(job) if args.newton else None
    stepping, stepping_cpu = time.perf_counter(), time.process_time()
    job.run()
    stepping, stepping_cpu = (time.perf_counter() - stepping,
                              time.process_time() - stepping_cpu)
    krylov = job.stepper.linear_iterations
    reuse = job.stepper.reuse  # None, or the counts of Jacobians assembled and kept
    perf = {k: PETSc.Log.Event(name).getPerfInfo() for k, name in EVENTS.items()}
    kept = None if reuse is None else (reuse.assembled, reuse.reused)
    per_step_cpu = _one_iteration_cpu(job.stepper)  # after the counts: it adds to them
    summary = job.finish(True, None, time.perf_counter() - started)
    wall, cpu = time.perf_counter() - started, time.process_time() - cpu
    solving = stepping - writing.wall
    if comm.rank != 0:
        return
    h = read_csv(out / "history.csv")
    steps, its = summary["time_steps"], summary["newton_iterations"]
    t = {k: p.get("time", 0.0) for k, p in perf.items()}  # rank 0's share
    n = {k: int(p.get("count", 0)) for k, p in perf.items()}
    if reuse is not None:  # SNESJacobianEval counts the calls, kept Jacobians included
        n["jacobian"] = kept[0]
    per_jac = t["jacobian"] / max(n["jacobian"], 1)
    per_factor = t["factorisation"] / max(n["factorisation"], 1)
    per_solve = t["triangular"] / max(n["triangular"], 1)  # one pair of triangular solves
    bound = steps * (per_jac + per_factor + per_solve)
    direct = krylov == n["solve"]  # preonly: one "iteration" (a triangular solve) per solve
    print(f"scene {scene.name}: {summary['dofs']} dofs, {summary['mesh']['cells']} cells, "
          f"{comm.size} rank(s)")
    print(f"steps {steps}, Newton iterations {its} ({its / max(steps, 1):.2f} per step), "
          f"step cuts {int(h['cuts'].sum())}")
    print(f"per Newton iteration: residual {t['residual'] / max(n['residual'], 1):.4f} s "
          f"(x{n['residual'] / max(its, 1):.1f}), Jacobian {per_jac:.4f} s, "
          f"LU factorisation {per_factor:.4f} s, triangular solve {per_solve:.4f} s")
    print(f"totals: residual {t['residual']:.2f} s, Jacobian {t['jacobian']:.2f} s, "
          f"factorisation {t['factorisation']:.2f} s, linear solves {t['solve']:.2f} s "
          f"(of which triangular solves {t['triangular']:.2f} s)")
    print(f"counts: residuals {n['residual']}, Jacobians {n['jacobian']}, LU factorisations "
          f"{n['factorisation']}, linear solves {n['solve']}, Krylov iterations "
          f"{'- (direct)' if direct else krylov}"
          + ("" if reuse is None else f"; Jacobians kept {kept[1]} (reuse threshold "
                                      f"{reuse.threshold:g})"))
    print(f"wall time {wall:.1f} s: stepping {stepping:.1f} s = solving {solving:.1f} s + "
          f"writing results {writing.wall:.1f} s (profiles, fields, pictures); the rest is "
          "meshing, form compilation and the summary's figures")
    # On a shared machine wall time counts the other processes' turns; CPU time of this
    # process (rank 0) is the one-core cost.
    print(f"CPU time (rank 0) {cpu:.1f} s, stepping {stepping_cpu:.1f} s; load average "
          f"{os.getloadavg()[0]:.2f} (1 min)")
    bound_cpu = steps * sum(per_step_cpu)
    print(f"one Jacobian + LU + solve at the final state, CPU (best of 5): "
          f"{' + '.join(f'{v:.4f}' for v in per_step_cpu)} s; the bound in CPU time "
          f"{bound_cpu:.2f} s, stepping CPU {stepping_cpu / bound_cpu:.2f} times it")
    print(f"lower bound (one Jacobian + LU + solve per step) {bound:.2f} s; ratio: solving "
          f"{solving / bound:.2f}, stepping {stepping / bound:.2f}")
    unit = "N" if "peak_force_N" in summary else "N_per_mm"  # 3D: a (half) model's newtons
    shown = unit.replace("_per_", "/")
    forces = summary[f"force_at_output_times_{unit}"]
    print("force at output times: " + ", ".join(f"{k} s {v:.6g} {shown}"
                                                for k, v in forces.items()))
    print(f"peak force {summary[f'peak_force_{unit}']:.6g} {shown}; max penetration "
          f"{1e3 * summary['max_penetration_mm']:.3g} µm; results in {out}")
    if newton is not None:
        newton.summary()
    if args.reference is not None:
        _score(out, args.reference)


class NewtonLog:
    """Newton's iterations as the contact sees them: a SNES monitor that prints the residual
    norm, the surface quadrature points in contact (`NitscheContact.active_set`), how many
    entered or left since the last iterate, and how much of the residual sits on a few nodes
    (where); `summary` gives per step the iterations and the changes (the tables of
    docs/benchmarks/contact-newton.md)."""

    def __init__(self, job: Run):
        self.problem, self.comm, self.steps = job.problem, job.comm, {}
        self._last = None
        job.stepper.snes.setMonitor(self)

    def __call__(self, snes, it: int, norm: float):
        active = self.problem.contact.active_set()
        changed = -1 if it == 0 or self._last is None else int(np.sum(active != self._last))
        self._last = active
        total = self.comm.allreduce(int(active.sum()), op=MPI.SUM)
        changed = self.comm.allreduce(changed, op=MPI.SUM) if it else 0
        t = self.problem.time
        its, changes = self.steps.get(t, (0, 0))
        self.steps[t] = (max(its, it), changes + changed)  # a cut attempt's are overwritten
        share, where = self._largest(snes.getFunction()[0], norm)
        if self.comm.rank == 0:
            print(f"  t = {t:.6g} s, iteration {it}: |F| {norm:.3e} N/mm, contact points "
                  f"{total}" + (f", {changed} entered or left" if it else "")
                  + f"; {share:.0%} of |F| on {self.NODES} nodes, the largest at "
                  f"({where[0]:.3f}, {where[1]:.3f}) mm", flush=True)

    NODES = 4  # the residual's share on this many nodes tells whether it is local

    def _largest(self, residual, norm: float) -> tuple[float, tuple]:
        """The share of the residual norm on the NODES displacement nodes with the largest
        residual force, and the reference position of the largest."""
        n, d = self.problem.V.dofmap.index_map.size_local, self.problem.gdim
        nodal = np.linalg.norm(residual.getArray(readonly=True)[: d * n].reshape(-1, d), axis=1)
        top = np.sort(np.concatenate(self.comm.allgather(np.sort(nodal)[-self.NODES:])))
        share = float(np.sqrt(np.sum(top[-self.NODES:] ** 2)) / norm) if norm > 0 else 0.0
        where = self.problem.residual_hotspot(residual)
        return share, (np.nan, np.nan) if where is None else tuple(where)

    def summary(self):
        print("time (s) | Newton iterations | contact points entered or left")
        for t, (its, changes) in sorted(self.steps.items()):
            print(f"{t:.6g} | {its} | {changes}")


def _score(out: Path, reference: Path):
    """Print the run's key outputs and their relative errors against an accuracy study's
    reference values (its accuracy.json, "reference")."""
    ref = json.loads(reference.read_text())["reference"]
    values = key_outputs(out)
    errors = relative_errors(values, ref, str(reference))
    for k in KEYS:
        print(f"  {k}: {values[k]:.6g} (reference {ref[k]:.6g}): {errors[k]:.3%}")
    worst = max(KEYS, key=errors.get)
    print(f"worst key-output error {errors[worst]:.3%} ({worst}) against {reference}")


def _one_iteration_cpu(stepper, repeats: int = 5) -> tuple[float, float, float]:
    """CPU seconds of this process for one Jacobian assembly, one LU factorisation and one
    solve at the final state, the best of `repeats`: the per-step cost of the bound, free of
    the other processes' share of a busy machine (PETSc's event times are wall times)."""
    snes = stepper.snes
    x, (F, _), (J, P, _) = snes.getSolution(), snes.getFunction(), snes.getJacobian()
    ksp, y = snes.getKSP(), x.duplicate()
    snes.computeFunction(x, F)
    best = [float("inf")] * 3
    for _ in range(repeats):
        if stepper.reuse is not None:
            stepper.reuse.start()  # assemble, do not keep
        t0 = time.process_time()
        snes.computeJacobian(x, J, P)
        t1 = time.process_time()
        ksp.setOperators(J, P)
        ksp.getPC().setUp()  # the values changed: a numerical factorisation
        t2 = time.process_time()
        ksp.solve(F, y)
        t3 = time.process_time()
        best = [min(b, v) for b, v in zip(best, (t1 - t0, t2 - t1, t3 - t2))]
    return tuple(best)


if __name__ == "__main__":
    main()
