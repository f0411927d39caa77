"""Friction with inertia: the energy ledger of a block dragged by a plate through Coulomb
friction (studies.problems.SlidingBlock), over step sizes and spectral radii.

Per run: the plate's work W, the changes of the kinetic, strain and penalty energies, the
friction's recorded dissipation D (−∫ f_{n+1}·Δs ds per step) and its trapezoid D_trap
(−½ ∫ (f_n + f_{n+1})·Δs ds), and the balance's errors W − ΔE − D and W − ΔE − D_trap, as
fractions of W; the block's mean velocity at the end against the closed form μ Fn t/m.

    PYTHONPATH=. python benchmarks/friction_inertia.py [--end 6] [--ramp 1]
        [--dts 0.5 0.25 0.125 0.0625] [--rho-inf 1 0.8] [--method penalty]
        [--jump-acceleration]  (with --ramp 0: the acceleration re-solved after the step)
"""

from __future__ import annotations

import argparse
import dataclasses
import time

from fingertip_dolfinx.studies.problems.sliding import SlidingBlock, drag_block, energy_balance


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--end", type=float, default=6.0)
    parser.add_argument("--ramp", type=float, default=1.0)
    parser.add_argument("--dts", type=float, nargs="+", default=[0.5, 0.25, 0.125, 0.0625])
    parser.add_argument("--rho-inf", type=float, nargs="+", default=[1.0, 0.8])
    parser.add_argument("--method", default="penalty")
    parser.add_argument("--jump-acceleration", action="store_true",
                        help="with --ramp 0: start from the acceleration after the step")
    args = parser.parse_args()
    data = dataclasses.replace(SlidingBlock(), ramp=args.ramp, method=args.method,
                               jump_acceleration=args.jump_acceleration)
    print("rho_inf  dt  W  (W-dE-D)/W  (W-dE-Dtrap)/W  D/Dtrap-1  v/v_closed-1  D  steps  wall_s")
    for rho_inf in args.rho_inf:
        for dt in args.dts:
            start = time.perf_counter()
            rows = drag_block(data, 8, 4, dt, args.end, rho_inf=rho_inf,
                              prefix=f"bench_{rho_inf}_{dt}_".replace(".", "_"))
            b = energy_balance(rows)
            Fn, last = rows[0]["force_y"], rows[-1]
            # the plate outruns the block from the start (its acceleration V/ramp exceeds
            # μ Fn/m), so the block slips from t = 0 on
            closed = float(data.mean_velocity(last["time"], Fn))
            print(f"{rho_inf:g}  {dt:g}  {b['work']:.5e}  {b['error'] / b['work']:+.2e}  "
                  f"{b['error_trapezoidal'] / b['work']:+.2e}  "
                  f"{b['dissipated'] / b['dissipated_trapezoidal'] - 1:+.2e}  "
                  f"{last['velocity'] / closed - 1:+.2e}  {b['dissipated']:.8e}  {len(rows) - 1}  "
                  f"{time.perf_counter() - start:.1f}", flush=True)


if __name__ == "__main__":
    main()
