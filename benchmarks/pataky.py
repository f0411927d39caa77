"""Tangential stiffness against normal force, and the tangential force's relaxation under a held
shear, on the coarse 2D fingertip, next to Pataky, Latash & Zatsiorsky (J Biomech 38, 2005,
1441-1449): docs/benchmarks/friction.md, "Against Pataky et al. (2005)".

Per depth: the `shear` scene's plate, mesh and tissues (QLV skin, biphasic subcutaneous
tissue), pressed to the depth in 0.5 s, then moved DX along x in 0.1 s and held there (and
at the depth) until 0.6 s + HOLD, with μ = MU (large enough that the contact sticks at its
centre: the stiffness is the pad's, not the friction's). Writes OUT/pataky.csv (every step
of every depth) and the figure.

Run (serially, from the repository root; ~1-2 min per depth on the shared machine):
    PYTHONPATH=$PWD python benchmarks/pataky.py [OUT] [FIGURE.png] [depth ...]
"""

import csv
import dataclasses
import sys
import time
from pathlib import Path

import matplotlib
import numpy as np
from mpi4py import MPI

from fingertip_dolfinx.geometry.mesh import build_mesh
from fingertip_dolfinx.loading import PiecewiseLinear, RampHold, TangentialPath
from fingertip_dolfinx.problem import FingertipProblem
from fingertip_dolfinx.scene import load_scene
from fingertip_dolfinx.stepping import TimeStepper

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

DX = 0.05  # mm: the tangential displacement, small against the contact's half-width (~2 mm)
HOLD = 30.0  # s: the hold after the tangential ramp (Pataky's relaxations: 11.8 s on average)
MU = 1.0  # Coulomb's μ: sticking at the centre under DX at every depth here
DEPTHS = (0.25, 0.5, 0.75, 1.0)  # mm
PATAKY_TAU = 11.8  # s: their mean F_T relaxation duration (abstract)


def run_depth(depth: float, comm=MPI.COMM_WORLD) -> list[dict]:
    """Press to `depth`, move DX along x, hold: one row per accepted step."""
    scene = load_scene("shear")
    end = 0.6 + HOLD
    history = TangentialPath(RampHold(depth=depth, ramp_time=0.5, end_time=end),
                             PiecewiseLinear((0.0, 0.5, 0.6), (0.0, 0.0, DX)))
    problem = FingertipProblem(build_mesh(scene.section, comm), scene.indenters, history,
                               scene.materials, scene.model, friction=MU)
    steps = dataclasses.replace(scene.steps, dt_max=5.0)  # the hold's steps grow to 5 s
    prefix = f"pataky_{depth:g}_".replace(".", "_")
    stepper = TimeStepper(problem, steps, scene.petsc_options, prefix=prefix)
    try:
        reports = stepper.run(history, end)
    finally:
        stepper.close()
    return [{"depth_mm": depth, "time_s": r.time, "newton_iterations": r.newton_iterations,
             "normal_force_N_per_mm": r.diagnostics["force_N_per_mm"],
             "tangential_force_N_per_mm": r.diagnostics["tangential_force_N_per_mm"],
             "tangential_displacement_mm": history.tangential_at(r.time)} for r in reports]


def summary(rows: list[dict]) -> dict:
    """One depth's numbers: Fn and k_T = Ft/DX at the end of the tangential ramp (0.6 s) and
    at the end of the hold; the relaxed fraction; the times the hold's drop of Ft is 50 % and
    90 % complete (interpolated between steps); the slope b of Ft/Ft0 against ln t (t held
    >= 1 s) and the largest misfit of that line."""
    t = np.array([r["time_s"] for r in rows])
    ft = np.abs([r["tangential_force_N_per_mm"] for r in rows])
    fn = np.abs([r["normal_force_N_per_mm"] for r in rows])
    i0 = int(np.argmin(np.abs(t - 0.6)))
    drop = ft[i0] - ft[-1]
    th = t[i0:] - t[i0]
    left = (ft[i0:] - ft[-1]) / drop if drop > 0 else np.zeros_like(th)
    when = [float(np.interp(-f, -left, th)) for f in (0.5, 0.1)]  # left falls with time
    late = th >= 1.0  # Pataky's logarithmic law, Ft/Ft0 = a + b ln t, from 1 s held on
    slope, offset = np.polyfit(np.log(th[late]), ft[i0:][late] / ft[i0], 1)
    misfit = np.max(np.abs(ft[i0:][late] / ft[i0] - offset - slope * np.log(th[late])))
    return {"depth_mm": rows[0]["depth_mm"], "Fn_N_per_mm": fn[i0], "kT_N_per_mm2": ft[i0] / DX,
            "Fn_end": fn[-1], "kT_end": ft[-1] / DX, "Ft_end_over_Ft_0": ft[-1] / ft[i0],
            "t50_s": when[0], "t90_s": when[1], "log_slope": slope, "log_misfit": misfit,
            "ratio_max": float(np.max(ft / (MU * fn)))}


def figure(rows: list[dict], table: list[dict], out: Path) -> None:
    fig, (a, b) = plt.subplots(1, 2, figsize=(10.0, 3.8), constrained_layout=True)
    a.plot([s["Fn_N_per_mm"] * 1e3 for s in table], [s["kT_N_per_mm2"] * 1e3 for s in table],
           "o-", label="after the 0.1 s ramp")
    a.plot([s["Fn_end"] * 1e3 for s in table], [s["kT_end"] * 1e3 for s in table], "s--",
           label=f"after {HOLD:g} s held")
    a.set_xlabel("normal force $F_n$ (mN/mm)")
    a.set_ylabel("tangential stiffness $F_t/\\Delta x$ (mN/mm per mm)")
    a.set_title(f"plane strain, Δx = {DX:g} mm, per mm of finger")
    a.set_xlim(left=0)
    a.set_ylim(bottom=0)
    a.legend()
    for s in table:
        sel = [r for r in rows if r["depth_mm"] == s["depth_mm"] and r["time_s"] >= 0.6 - 1e-9]
        t = np.array([r["time_s"] for r in sel]) - 0.6
        ft = np.abs([r["tangential_force_N_per_mm"] for r in sel])
        b.plot(t[1:], ft[1:] / ft[0], "o-", ms=3, label=f"{s['depth_mm']:g} mm deep")
    b.axvline(PATAKY_TAU, color="k", ls=":", label=f"Pataky et al.: τ = {PATAKY_TAU} s")
    b.set_xscale("log")
    b.set_xlabel("time held (s)")
    b.set_ylabel("$F_t(t)/F_t$(end of ramp)")
    b.set_title("tangential force relaxation under a held shear")
    b.legend(fontsize=8)
    fig.savefig(out, dpi=120)


def main(out: Path, picture: Path, depths) -> None:
    out.mkdir(parents=True, exist_ok=True)
    rows, table = [], []
    for depth in depths:
        started = time.perf_counter()
        these = run_depth(depth)
        rows += these
        table.append(summary(these))
        print({k: round(float(v), 6) for k, v in table[-1].items()},
              f"{sum(r['newton_iterations'] for r in these)} its, "
              f"{time.perf_counter() - started:.0f} s", flush=True)
    with open(out / "pataky.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    figure(rows, table, picture)


if __name__ == "__main__":
    args = sys.argv[1:]
    main(Path(args[0]) if args else Path("results/pataky"),
         Path(args[1]) if len(args) > 1 else Path("results/pataky/pataky.png"),
         [float(a) for a in args[2:]] or DEPTHS)
