"""Benchmark: what a ramp step's Newton iterations do, and what a looser tolerance would give.

Runs a scene (the 3D line load by default) and, for every Newton iterate of every accepted
step, records the residual norm (split into the displacement and pressure rows), the contact
force, the penalty gap g at each surface quadrature point of the contact's facet rule, and the
solution. When the step is accepted (its last iterate is the converged state) it prints per
iterate:

- |F| (N in 3D), its displacement and pressure parts, the points in contact, how many of
  them differ from the converged set;
- the largest gap error max |g_k − g_conv| over the points within 50 µm of contact in either
  state (µm): the scale on which the iterates still move the contact zone's edge, against
  which a smoothing width (`model.contact_smoothing`) would be set;
- the force's and the displacement's errors against the converged state (relative).

Then, for each candidate absolute tolerance τ (N), the iterate a Newton stopped at |F| < τ
would have accepted: the iterations it saves and its force and displacement errors. These
are per step (the next step would start from that state: the drift over steps is not in
this), so a looser tolerance must still be confirmed by a run.

    mpiexec -n 2 python benchmarks/newton_ramp.py [--scene line-load-3d] \
        --set protocol.end_time=1.0 --set "output.times=[1.0]" --set output.pictures=false
"""

import time

import numpy as np
from mpi4py import MPI
from timing import scene_and_out, scene_parser

import fingertip_dolfinx  # noqa: F401  (sets up the DOLFINx wheel)

# isort: split
import basix
from dolfinx import fem

from fingertip_dolfinx.runner import Run

TOLERANCES = (1e-5, 1e-6, 1e-7)  # N: candidate snes_atol (the force ~1e-2 N at 1 s)
NEAR = 0.05  # mm: points within this gap of contact count as the edge's


class IterateLog:
    """A SNES monitor that keeps every iterate of the current attempt (see the docstring)."""

    def __init__(self, job: Run):
        self.job, self.problem, self.comm = job, job.problem, job.comm
        contact = self.problem.contact
        domain = contact.u.function_space.mesh
        facet = domain.topology.entity_types[domain.topology.dim - 1][0]
        points, _ = basix.make_quadrature(basix.CellType[facet.name], contact.quadrature_degree)
        gap = fem.Expression(-contact.trial_pressure / contact.gamma, points)
        self._gap = lambda: gap.eval(domain, contact._facet_entities).ravel()
        self.n_u = self.problem.V.dofmap.index_map.size_local * self.problem.gdim
        self.iterates, self.totals = [], {t: [0, 0] for t in TOLERANCES}
        job.stepper.snes.setMonitor(self)
        step = job.on_step

        def on_step(report):
            self.report(report)
            return step(report)

        job.on_step = on_step

    def _norm(self, a: np.ndarray) -> float:
        return float(np.sqrt(self.comm.allreduce(float(a @ a), op=MPI.SUM)))

    def __call__(self, snes, it: int, norm: float):
        if it == 0:
            self.iterates = []
        r = snes.getFunction()[0].getArray(readonly=True)
        x = snes.getSolution().getArray(readonly=True).copy()
        self.iterates.append(dict(norm=norm, ru=self._norm(r[: self.n_u]),
                                  rp=self._norm(r[self.n_u:]), x=x, gap=self._gap(),
                                  force=float(self.problem.contact.forces().sum())))

    def _max(self, a: np.ndarray) -> float:
        return self.comm.allreduce(float(a.max()) if a.size else 0.0, op=MPI.MAX)

    def _sum(self, a: np.ndarray) -> int:
        return self.comm.allreduce(int(a.sum()), op=MPI.SUM)

    def report(self, report):
        """Print the accepted step's iterates against its converged state."""
        its, last = self.iterates, self.iterates[-1]
        umax = self._max(np.abs(last["x"][: self.n_u]))
        rows = []
        for k, s in enumerate(its):
            near = (s["gap"] < NEAR) | (last["gap"] < NEAR)
            gerr = self._max(np.abs(s["gap"] - last["gap"])[near]) * 1e3
            flips = self._sum((s["gap"] < 0) != (last["gap"] < 0))
            du = self._max(np.abs(s["x"][: self.n_u] - last["x"][: self.n_u])) / umax
            df = abs(s["force"] - last["force"]) / abs(last["force"])
            rows.append((k, s["norm"], s["ru"], s["rp"], self._sum(s["gap"] < 0), flips, gerr,
                         df, du))
        if self.comm.rank != 0:
            return
        print(f"step {report.step}: t = {report.time:.6g} s, dt = {report.dt:.4g} s, "
              f"{report.newton_iterations} iterations, force {last['force']:.6e} N")
        print("  k | |F| (N) | |F_u| | |F_p| | in contact | differ from converged | "
              "max gap error near contact (µm) | force error | u error (of max |u|)")
        for r in rows:
            print(f"  {r[0]} | {r[1]:.2e} | {r[2]:.2e} | {r[3]:.2e} | {r[4]} | {r[5]} | "
                  f"{r[6]:.3g} | {r[7]:.1e} | {r[8]:.1e}")
        for tol in TOLERANCES:
            k = next((r[0] for r in rows if r[1] < tol), len(rows) - 1)
            self.totals[tol][0] += len(rows) - 1 - k
            self.totals[tol][1] = max(self.totals[tol][1], rows[k][7])
            print(f"  stop at |F| < {tol:g} N: iterate {k}, saves {len(rows) - 1 - k}, force "
                  f"error {rows[k][7]:.1e}, u error {rows[k][8]:.1e}")
        print("  so far: " + "; ".join(f"τ = {t:g}: saves {s}, worst force error {e:.1e}"
                                       for t, (s, e) in self.totals.items()), flush=True)


def main():
    parser = scene_parser(__doc__, "line-load-3d")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    scene, out = scene_and_out(args, comm)
    started, cpu = time.perf_counter(), time.process_time()
    job = Run(scene, out, comm, resume=False, progress=False)
    IterateLog(job)
    job.run()
    summary = job.finish(True, None, time.perf_counter() - started)
    cpu = comm.allgather(time.process_time() - cpu)
    if comm.rank == 0:
        print(f"steps {summary['time_steps']}, Newton iterations {summary['newton_iterations']}, "
              f"wall {time.perf_counter() - started:.0f} s, CPU per rank "
              + ", ".join(f"{c:.0f}" for c in cpu) + f" s; results in {out}")


if __name__ == "__main__":
    main()
