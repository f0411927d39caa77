"""The driver shared by the two canonical biphasic benchmarks (biphasic_confined.py,
biphasic_unconfined.py): runs, reference, errors, the table and the chart.

A benchmark is a `studies.problems.PlatenRelaxation` (a Holmes–Mow tissue compressed by a
platen ramp, then held) for ν = 0.4 and ν = 0 (the hyperfoam limit other codes call "Ogden
unconstrained"), stepped

- by fixed-step backward Euler, the baseline: Δt = t_end/N for several N (the ramp's end is
  always landed on: a step of Δt > t0 takes the whole ramp at once);
- by the error-controlled BDF2 stepper, `StepOptions(control="error", rtol=tol, atol=tol *
  ATOL_SCALE, scheme="bdf2")` at tol = 1e-2 and 1e-3. (The README's rows for the growth
  control, ×1.5 and ×1.1 after an easy step, were measured with this driver before the error
  control landed.)

Errors are those of the force and the core pressure histories as a user reads them (linearly
between a run's steps) at the reference's points (dense where the histories change fast),
relative to their peaks: the largest in the hold (t > t0), and at the ramp's end (the peak
force); the ramp's (t < t0, set by the first step: the force grows like sqrt(t)) and the
classic global error at the run's own steps are in the CSV. The reference: backward Euler on a
geometric time grid (the ramp in m equal steps, the
hold in 4m steps growing geometrically from t0/m), at m = 128 and 256, combined by
Richardson extrapolation (2 F_256 − F_128; BE is first order), interpolated between its
points (PCHIP, monotone) where needed. The reference's own error (from the ramp's end on) is
estimated from m = 64, 128 against 128, 256. Every run uses the same mesh: these are time
errors. The limits (undrained start, drained end) are homogeneous states that P2/P1 holds
exactly: their errors are in the table, against the closed forms.

`--asked TOL ...` (`tolerance_table`): per tolerance asked, the tolerance-driven time control
(`stepping.tolerance_steps` for its time share, checked by `stepping.verify_time`), its estimate and
what it delivered at the output times (`output_times`) against a tight reference of the same
mesh (`TightReference`), beside local error control alone at rtol = TOL
(docs/benchmarks/tolerance.md).
"""

from __future__ import annotations

import argparse
import csv
import math
from pathlib import Path

import numpy as np

import fingertip_dolfinx  # noqa: F401  (sets up the DOLFINx wheel)
from fingertip_dolfinx.physics import materials as mat
from fingertip_dolfinx.stepping import (
    TIME_SHARE,
    StepOptions,
    time_estimates,
    tolerance_steps,
    verify_time,
)
from fingertip_dolfinx.studies.problems import PlatenRelaxation, RelaxationRun, run_relaxation

#: atol = rtol × this (the unknowns: u in mm, ~1e-2 here; p in MPa, ~1e-4)
ATOL_SCALE = 1e-3
NUS = (0.4, 0.0)
#: Newton tolerances of every run: tight enough that the time error dominates.
PETSC = {"snes_rtol": 1e-11, "snes_atol": 1e-14}


def solid(nu: float) -> mat.Hyperfoam:
    """The paper's subcutaneous hyperfoam with Poisson ratio ν."""
    return mat.Hyperfoam(mu=mat.SUBCUTANEOUS.mu, alpha=mat.SUBCUTANEOUS.alpha, nu=nu,
                         where=f"subcutaneous, nu = {nu:g}")


def adaptive_options(level: int, problem: PlatenRelaxation) -> tuple[StepOptions, str]:
    """The error-controlled BDF2 stepper at setting `level` (0: rtol 1e-2, 1: 1e-3), a label."""
    h = problem.history
    tol = (1e-2, 1e-3)[level]
    options = StepOptions(control="error", rtol=tol, atol=tol * ATOL_SCALE, scheme="bdf2",
                          dt_initial=h.ramp_time / 16, dt_min=1e-9 * h.ramp_time,
                          dt_max=h.end_time / 4)
    return options, f"error control (BDF2), rtol {tol:g}"


def fixed_options(dt: float, problem: PlatenRelaxation) -> StepOptions:
    """Backward Euler with the fixed step Δt (it lands on the ramp's end)."""
    t0 = problem.history.ramp_time
    # every step counts as easy: after the short step that lands on the ramp's end the step
    # returns to Δt (the growth control would keep a hard step's size)
    return StepOptions(dt_initial=dt, dt_min=min(dt, t0) * 1e-6, dt_max=dt, growth=1.0,
                       easy_iterations=10**6)


def geometric_grid(problem: PlatenRelaxation, m: int, m_base: int) -> np.ndarray:
    """The reference's time grid: the ramp in m equal steps, the hold in 4m steps of a smooth
    geometric map whose first step is t0/m at m = m_base. The map is that of m_base at every
    m, so doubling m halves every step: the grids nest and Richardson applies."""
    from scipy.optimize import brentq

    h = problem.history
    t0, hold = h.ramp_time, h.end_time - h.ramp_time
    base = 4 * m_base  # the map: hold · expm1(γ s)/expm1(γ), first step t0/m_base
    gamma = brentq(lambda g: hold * math.expm1(g / base) / math.expm1(g) - t0 / m_base,
                   1e-6, 700.0)
    n = 4 * m
    s = np.arange(1, n + 1) / n
    return np.concatenate([t0 * np.arange(1, m + 1) / m,
                           t0 + hold * np.expm1(gamma * s) / math.expm1(gamma)])


def grid_run(problem: PlatenRelaxation, n: int, grading: float, m: int, m_base: int,
             prefix: str) -> RelaxationRun:
    """Backward Euler through exactly the points of `geometric_grid(problem, m, m_base)`."""
    times = geometric_grid(problem, m, m_base)
    largest = float(np.max(np.diff(np.concatenate([[0.0], times]))))
    options = StepOptions(dt_initial=largest, dt_min=1e-12, dt_max=largest, growth=1.0)
    run = run_relaxation(problem, problem.block(n, grading), options, PETSC,
                         sample_times=times[:-1], prefix=prefix)
    assert len(run.time) == len(times) and np.allclose(run.time, times, rtol=1e-12)
    return run


class Reference:
    """The Richardson reference of the force and core pressure histories, interpolated."""

    def __init__(self, problem: PlatenRelaxation, n: int, grading: float, m: int, prefix: str):
        from scipy.interpolate import PchipInterpolator

        runs = {k: grid_run(problem, n, grading, k, m, f"{prefix}ref{k}_")
                for k in (m // 2, m, 2 * m)}
        self.t0 = problem.history.ramp_time
        self.steps = sum(r.steps for r in runs.values())
        self.wall_time_s = sum(r.wall_time_s for r in runs.values())

        def richardson(coarse, fine):  # at the coarse run's points (every other fine point)
            F = 2 * fine.force[1::2] - coarse.force
            p = 2 * fine.core_pressure[1::2] - coarse.core_pressure
            return coarse.time, F, p

        t, F, p = richardson(runs[m], runs[2 * m])
        tc, Fc, pc = richardson(runs[m // 2], runs[m])
        self.time, self.force, self.pressure = t, F, p
        self.F_peak, self.p_peak = np.max(np.abs(F)), np.max(np.abs(p))
        ramp = t <= self.t0 * (1 + 1e-12)
        zero = np.zeros(1)
        # one interpolant on the ramp (from 0), one on the hold: the kink at t0 is kept
        self._ramp = [PchipInterpolator(np.concatenate([zero, t[ramp]]),
                                        np.concatenate([zero, v[ramp]])) for v in (F, p)]
        hold = t >= self.t0 * (1 - 1e-12)
        self._hold = [PchipInterpolator(t[hold], v[hold]) for v in (F, p)]
        # the reference's own error: the coarser Richardson pair against it, at its points
        # from the ramp's end on (in the ramp the sqrt(t) start spoils Richardson's order)
        late = tc >= self.t0 * (1 - 1e-12)
        self.error = (float(np.max(np.abs(Fc - self._at(tc, 0))[late])) / self.F_peak,
                      float(np.max(np.abs(pc - self._at(tc, 1))[late])) / self.p_peak)

    def _at(self, t: np.ndarray, which: int) -> np.ndarray:
        t = np.asarray(t)
        return np.where(t <= self.t0, self._ramp[which](np.minimum(t, self.t0)),
                        self._hold[which](np.maximum(t, self.t0)))

    def errors(self, run: RelaxationRun) -> dict[str, float]:
        """Relative errors (to the peaks) of the run's force and core pressure histories, read
        as a user reads them, linearly between the run's steps (from 0 at t = 0), at the
        reference's points: the largest in the hold (t > t0) and in the ramp (t < t0), and
        at the ramp's end (the peak force; every run lands there). In the ramp the drained
        layer, and the force, grow like sqrt(t): backward Euler's first step is off by a
        fixed fraction whatever its length, and a step longer than the ramp takes it at once;
        right after the ramp the force relaxes on the ramp's own time scale."""
        t0, t = self.t0, self.time
        hold, ramp = t > t0 * (1 + 1e-12), t < t0 * (1 - 1e-12)
        times = np.concatenate([[0.0], run.time])
        peak = run.at(t0)
        out = {}
        for key, values, which, scale in (("force", run.force, 0, self.F_peak),
                                          ("pressure", run.core_pressure, 1, self.p_peak)):
            reference = (self.force, self.pressure)[which]
            error = np.abs(np.interp(t, times, np.concatenate([[0.0], values])) - reference)
            error /= scale
            out[f"{key}_error"] = float(np.max(error[hold], initial=0.0))
            out[f"{key}_error_ramp"] = float(np.max(error[ramp], initial=0.0))
            out[f"{key}_error_peak"] = float(abs(values[peak] - self._at(t0, which)) / scale)
            # the classic global error: at the run's own steps only (the reference between
            # its points by PCHIP), in the hold
            own = run.time > t0 * (1 + 1e-12)
            at_steps = np.abs(values[own] - self._at(run.time[own], which)) / scale
            out[f"{key}_error_at_steps"] = float(np.max(at_steps, initial=0.0))
        return out


def limits(problem: PlatenRelaxation, run: RelaxationRun) -> dict[str, float]:
    """The run's limits against the closed forms: the drained end's force; at the ramp's
    end the core's pressure (undrained closed form, or F/W confined) and |J − 1| there."""
    t0 = problem.history.ramp_time
    i = run.at(t0)
    out = {"force_ramp_end_N_per_mm": run.force[i],
           "core_pressure_ramp_end_MPa": run.core_pressure[i],
           "core_J_change_first_step": run.core_J_change[0],
           "core_J_change_ramp_end": run.core_J_change[i],
           "J_min": float(np.min(run.J_min)),
           "force_end_N_per_mm": run.force[-1], "drained_force_N_per_mm": problem.drained_force(),
           "end_force_error": run.force[-1] / problem.drained_force() - 1}
    if hasattr(problem, "undrained"):
        p_u = problem.undrained().pressure
        out["undrained_pressure_MPa"] = p_u
        out["core_pressure_error"] = run.core_pressure[i] / p_u - 1
    else:  # confined: the core is undeformed, the fluid carries the whole load
        load = run.force[i] / problem.width
        out["undrained_pressure_MPa"] = load
        out["core_pressure_error"] = run.core_pressure[i] / load - 1
    return out


def benchmark(make_problem, name: str, n: int, grading: float, Ns, m_ref: int,
              out: Path) -> list[dict]:
    """Every run for ν = 0.4 and 0: rows of the table (also written to `out`/NAME.csv)."""
    rows = []
    for nu in NUS:
        problem = make_problem(solid(nu))
        tag = f"{name}_nu{nu:g}_".replace(".", "p")
        ref = Reference(problem, n, grading, m_ref, tag)
        print(f"\n{name}, nu = {nu:g}: t_c = {problem.consolidation_time:.4g} s, ramp "
              f"{problem.history.ramp_time:.4g} s, end {problem.history.end_time:.4g} s; "
              f"reference: {ref.steps} steps, its own error {ref.error[0]:.1e} (force), "
              f"{ref.error[1]:.1e} (pressure)")
        runs = []
        for N in Ns:
            dt = problem.history.end_time / N
            runs.append((f"fixed BE, dt = t_end/{N}", "fixed",
                         run_relaxation(problem, problem.block(n, grading),
                                        fixed_options(dt, problem), PETSC,
                                        prefix=f"{tag}fixed{N}_")))
        for level in (0, 1):
            options, label = adaptive_options(level, problem)
            runs.append((label, "adaptive",
                         run_relaxation(problem, problem.block(n, grading), options, PETSC,
                                        prefix=f"{tag}adaptive{level}_")))
        for label, kind, run in runs:
            errors = ref.errors(run)
            row = {"benchmark": name, "nu": nu, "method": label, "kind": kind,
                   "steps": run.steps, "newton_iterations": run.newton_iterations,
                   "cuts": run.cuts, "wall_time_s": run.wall_time_s, **errors,
                   "reference_error_force": ref.error[0],
                   "reference_error_pressure": ref.error[1], **limits(problem, run)}
            rows.append(row)
            print(f"  {label:30s} {run.steps:5d} steps {run.newton_iterations:5d} its "
                  f"{run.wall_time_s:6.2f} s | hold: F {errors['force_error']:.1e}, p "
                  f"{errors['pressure_error']:.1e} | peak F {errors['force_error_peak']:.1e} "
                  f"| ramp F {errors['force_error_ramp']:.1e} | end F "
                  f"{row['end_force_error']:+.0e}, core p {row['core_pressure_error']:+.0e}")
        adaptive = [r for r in rows if r["nu"] == nu and r["kind"] == "adaptive"][-1]
        print(f"  limits (tighter adaptive run): force at the ramp's end "
              f"{adaptive['force_ramp_end_N_per_mm']:.5e} N/mm, core p "
              f"{adaptive['core_pressure_ramp_end_MPa']:.6e} MPa vs "
              f"{adaptive['undrained_pressure_MPa']:.6e} "
              f"({adaptive['core_pressure_error']:+.1e}); "
              f"|J - 1| in the core {adaptive['core_J_change_first_step']:.1e} (first step), "
              f"{adaptive['core_J_change_ramp_end']:.1e} (ramp end); min J "
              f"{adaptive['J_min']:.4f}; end force {adaptive['force_end_N_per_mm']:.8e} vs "
              f"drained {adaptive['drained_force_N_per_mm']:.8e} "
              f"({adaptive['end_force_error']:+.1e})")
    out.mkdir(parents=True, exist_ok=True)
    with open(out / f"{name}.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    chart(rows, out / f"{name}_error_vs_wall_time.png", name)
    return rows


def chart(rows: list[dict], path: Path, title: str) -> None:
    """Error against wall time: the force and the core pressure in the hold, the peak force;
    a line per ν for fixed-step BE, a marker per adaptive run."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6), constrained_layout=True)
    colours = {0.4: "tab:blue", 0.0: "tab:red"}
    markers = ["s", "D"]
    panels = (("force_error", "force", "platen force, hold (t > t0)"),
              ("pressure_error", "pressure", "core pore pressure, hold (t > t0)"),
              ("force_error_peak", "force", "peak force (t = t0)"))
    floor = 1e-12
    for ax, (key, reference, what) in zip(axes, panels):
        for nu in NUS:
            fixed = [r for r in rows if r["nu"] == nu and r["kind"] == "fixed"]
            ax.loglog([r["wall_time_s"] for r in fixed], [max(r[key], floor) for r in fixed],
                      "o-", color=colours[nu], mfc="white", label=f"fixed-step BE, nu = {nu:g}")
            adaptive = [r for r in rows if r["nu"] == nu and r["kind"] == "adaptive"]
            for marker, r in zip(markers, adaptive):
                ax.loglog(r["wall_time_s"], max(r[key], floor), marker, color=colours[nu],
                          ms=8, label=f"{r['method']}, nu = {nu:g}")
            if fixed:
                ax.axhline(fixed[0][f"reference_error_{reference}"], color=colours[nu],
                           lw=0.7, ls=":")
        ax.set_xlabel("wall time of the stepping (s)")
        ax.set_ylabel("relative error (largest over the history)")
        ax.set_title(what)
        ax.grid(True, which="both", alpha=0.3)
    axes[2].legend(fontsize=7, loc="best")
    fig.suptitle(f"{title}: error against wall time (dotted: the reference's own error)")
    fig.savefig(path, dpi=110)
    plt.close(fig)


# --- a tolerance asked, a tolerance delivered -------------------------------------------------

#: Output times of the asked-vs-delivered mode: the ramp's middle and end, then t0 (1 + s) for s
#: spread geometrically from AFTER ("right after the ramp"; `--after`) to the end of the hold.
OUTPUTS_IN_HOLD = 14
AFTER = 0.01
#: The reference of the asked-vs-delivered mode: the error-controlled BDF2 stepper at rtol
#: 1e-7 (and 1e-6 for its own error), atol 1e-12 mm/MPa, Newton to 1e-15 N/mm. The Richardson
#: reference of the cost table is off by ~1e-3 right after the ramp (its own estimate, m = 128):
#: too coarse to tell 1e-4 asked from delivered.
TIGHT_RTOL = 1e-7
TIGHT_PETSC = {"snes_rtol": 1e-12, "snes_atol": 1e-15, "snes_max_it": 30}


def output_times(problem: PlatenRelaxation, first: float = AFTER) -> np.ndarray:
    h = problem.history
    t0 = h.ramp_time
    after = t0 * (1 + np.geomspace(first, (h.end_time - t0) / t0, OUTPUTS_IN_HOLD))
    after[-1] = h.end_time
    return np.concatenate([[0.5 * t0, t0], after])


def sampled(problem: PlatenRelaxation, n: int, grading: float, options: StepOptions,
            petsc: dict, prefix: str, first: float = AFTER
            ) -> tuple[RelaxationRun, np.ndarray, np.ndarray]:
    """A run that lands on `output_times`, and its force and core pressure there."""
    times = output_times(problem, first)
    run = run_relaxation(problem, problem.block(n, grading), options, petsc,
                         sample_times=times[:-1], prefix=prefix)
    index = [run.at(t) for t in times]
    return run, run.force[index], run.core_pressure[index]


class TightReference:
    """The force and core pressure at `output_times` from the stepper at TIGHT_RTOL, with its
    own error estimated from a run 10 times looser (`stepping.time_estimates`)."""

    def __init__(self, problem: PlatenRelaxation, n: int, grading: float, prefix: str,
                 first: float = AFTER):
        h = problem.history
        self.first = first
        runs = []
        for rtol in (10 * TIGHT_RTOL, TIGHT_RTOL):
            options = StepOptions(control="error", scheme="bdf2", rtol=rtol, atol=1e-5 * rtol,
                                  dt_initial=1e-3 * h.ramp_time, dt_min=1e-12 * h.ramp_time,
                                  dt_max=h.end_time)
            runs.append(sampled(problem, n, grading, options, TIGHT_PETSC,
                                f"{prefix}tight{len(runs)}_", first))
        (_, F1, p1), (run, self.force, self.pressure) = runs
        self.steps, self.times = run.steps, output_times(problem, first)
        self.F_peak, self.p_peak = np.max(np.abs(self.force)), np.max(np.abs(self.pressure))
        scales = {**{f"F{i}": self.F_peak for i in range(len(F1))},
                  **{f"p{i}": self.p_peak for i in range(len(p1))}}
        estimate = time_estimates(
            {**{f"F{i}": v for i, v in enumerate(F1)}, **{f"p{i}": v for i, v in enumerate(p1)}},
            {**{f"F{i}": v for i, v in enumerate(self.force)},
             **{f"p{i}": v for i, v in enumerate(self.pressure)}}, 10.0, scales)
        self.error = (max(v for k, v in estimate.items() if k[0] == "F"),
                      max(v for k, v in estimate.items() if k[0] == "p"))


def asked_vs_delivered(problem: PlatenRelaxation, ref: TightReference, n: int, grading: float,
                       tol: float, prefix: str) -> dict:
    """The tolerance-driven control (`stepping.tolerance_steps` for the time share of `tol`,
    checked and tightened by `stepping.verify_time`) on the force and core pressure at the
    output times, each relative to its history's peak; the last run against the reference."""
    h, times = problem.history, ref.times
    base = StepOptions(dt_initial=h.ramp_time / 16, dt_min=1e-9 * h.ramp_time,
                       dt_max=h.end_time / 4)
    last = {}

    def run(options: StepOptions, i: int) -> dict[str, float]:
        r, force, pressure = sampled(problem, n, grading, options, PETSC, f"{prefix}{i}_",
                                     ref.first)
        last.update(run=r, force=force, pressure=pressure)
        return {**{f"force@{t:.6g}": v for t, v in zip(times, last["force"])},
                **{f"pressure@{t:.6g}": v for t, v in zip(times, last["pressure"])}}

    def scales(values):
        peaks = {q: max(abs(v) for k, v in values.items() if k.startswith(q))
                 for q in ("force", "pressure")}
        return {k: peaks[k.split("@")[0]] for k in values}

    budget = TIME_SHARE * tol
    check = verify_time(run, tolerance_steps(budget, base), budget, scales=scales)
    after = 2  # t0 (1 + first)
    row = {"asked": tol, "time_budget": budget, "runs": len(check["runs"]),
           "rtols": [r["rtol"] for r in check["runs"]], "answer_rtol": check["options"].rtol,
           "failed": check["runs"][-1].get("failed", ""), "steps": last["run"].steps,
           "wall_time_s": last["run"].wall_time_s, "converged": check["converged"],
           "t_after_ramp": times[after]}
    for q, reference, peak in (("force", ref.force, ref.F_peak),
                               ("pressure", ref.pressure, ref.p_peak)):
        delivered = np.abs(last[q] - reference) / peak
        estimated = [check["estimates"][f"{q}@{t:.6g}"] for t in times]
        row.update({f"{q}_estimated": max(estimated), f"{q}_delivered": float(delivered.max()),
                    f"{q}_delivered_ramp_end": float(delivered[1]),
                    f"{q}_delivered_after_ramp": float(delivered[after])})
    # local error control alone at rtol = tol (the other options at their defaults)
    _, force, pressure = sampled(problem, n, grading, StepOptions(
        control="error", scheme="bdf2", rtol=tol), PETSC, f"{prefix}local_", ref.first)
    row["local_only_force"] = float(np.max(np.abs(force - ref.force)) / ref.F_peak)
    row["local_only_pressure"] = float(np.max(np.abs(pressure - ref.pressure)) / ref.p_peak)
    return row


def tolerance_table(make_problem, name: str, n: int, grading: float, asked,
                    out: Path, nus=NUS, first: float = AFTER) -> list[dict]:
    """Per ν and per tolerance asked: asked, what the control estimated, what it delivered
    against the reference, and what local error control alone at rtol = tol delivers (printed
    as a Markdown table, written to NAME_tolerance.csv)."""
    rows = []
    for nu in nus:
        problem = make_problem(solid(nu))
        tag = f"{name}_nu{nu:g}_".replace(".", "p")
        ref = TightReference(problem, n, grading, tag, first)
        print(f"\n{name}, nu = {nu:g}: reference {ref.steps} steps, its own error "
              f"{ref.error[0]:.1e} (force), {ref.error[1]:.1e} (pressure)", flush=True)
        for tol in asked:
            row = {"benchmark": name, "nu": nu, "reference_error_force": ref.error[0],
                   "reference_error_pressure": ref.error[1],
                   **asked_vs_delivered(problem, ref, n, grading, tol, f"{tag}tol{tol:g}_")}
            rows.append(row)
            print(_tolerance_line(row), flush=True)
    out.mkdir(parents=True, exist_ok=True)
    with open(out / f"{name}_tolerance.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return rows


def _tolerance_line(r: dict) -> str:
    ok = all(r[f"{q}_delivered"] <= r["asked"] for q in ("force", "pressure"))
    runs = f"{r['runs']}" + (" (the last failed)" if r["failed"] else "")
    return (f"| {r['nu']:g} | {r['asked']:.0e} | {r['time_budget']:.1e} | {runs} "
            f"({r['answer_rtol']:.1e}){'' if r['converged'] else ', not converged'} | "
            f"{r['steps']} | {r['wall_time_s']:.1f} | "
            f"{r['force_estimated']:.1e} / {r['force_delivered']:.1e} | "
            f"{r['pressure_estimated']:.1e} / {r['pressure_delivered']:.1e} | "
            f"{r['force_delivered_after_ramp']:.1e}, {r['pressure_delivered_after_ramp']:.1e} | "
            f"{'yes' if ok else 'NO'} | {r['local_only_force']:.1e}, "
            f"{r['local_only_pressure']:.1e} |")


TOLERANCE_HEADER = ("| nu | asked | time budget | runs (the answer's rtol) | steps | wall (s) | "
                    "force: "
                    "estimated / delivered | pressure: estimated / delivered | right after the "
                    "ramp: F, p | delivered <= asked | local control alone at rtol = asked: F, p |"
                    "\n| " + " | ".join(["---:"] * 11) + " |")


def main(make_problem, name: str, doc: str, issue=None) -> None:
    """The command line of both benchmarks: `--out DIR`, `--coarse` (fewer cells and steps),
    `--asked TOL [TOL ...]` (the asked-vs-delivered table of the tolerance-driven control
    instead of the error-against-cost table)."""
    parser = argparse.ArgumentParser(description=doc,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=Path("results/biphasic"))
    parser.add_argument("--coarse", action="store_true", help="a quick run: fewer cells, steps")
    parser.add_argument("--asked", type=float, nargs="+", metavar="TOL",
                        help="relative tolerances asked of the force and core pressure "
                        "histories (e.g. 1e-2 1e-3 1e-4): per tolerance, the tolerance-driven "
                        "time control and what it delivered against the reference")
    parser.add_argument("--after", type=float, default=AFTER, metavar="S",
                        help="with --asked: the first output after the ramp at t0 (1 + S) "
                        f"(default {AFTER})")
    if issue is not None:
        parser.add_argument("--issue", action="store_true", help="with --asked: the column "
                            "of the issue that asked for it instead (k0 = 10 mm^4/(N s), 20 %% "
                            "in 100 s, held to 3000 s, the paper's foam)")
    args = parser.parse_args()
    if getattr(args, "issue", False):
        make_problem, name = issue, f"{name}_issue"
    n, m_ref, Ns = (12, 16, (25, 100)) if args.coarse else (32, 128, (25, 100, 400, 1600, 6400))
    if args.asked:
        print(TOLERANCE_HEADER.split("\n")[0], flush=True)
        tolerance_table(make_problem, name, n, 10.0, args.asked, args.out,
                        nus=(mat.SUBCUTANEOUS.nu,) if getattr(args, "issue", False) else NUS,
                        first=args.after)
        return
    benchmark(make_problem, name, n, 10.0, Ns, m_ref, args.out)
