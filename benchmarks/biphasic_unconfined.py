"""Benchmark: plane-strain unconfined compression between frictionless impermeable platens
with a drained free edge (Mandel-type), displacement ramp then hold.

The quarter [0, W] × [0, H] of a specimen 2W = 2 mm wide, 2H = 0.5 mm high: symmetry at
x = 0 and y = 0, the platen on top pushed down by 10 % of H in t0 = 0.002 t_c (t_c = W²/(k0
M), k0 = 1 mm⁴/(N·s)) and held to 12 t_c, the edge x = W free and drained; ν = 0.4 and ν = 0
(`studies.problems.UnconfinedRelaxation`). Every field depends on x alone. Exact limits: at
the end of the fast ramp the core is undrained, J = 1 and p = τ1(1/λ, λ, 1)
(`unconfined_undrained_state`); at long times the force is the drained closed form −P22 W
with the lateral stretch from τ1 = 0 (`unconfined_drained_state`; ν = 0: no lateral
expansion at all).

`--asked TOL [TOL ...]`: per tolerance asked, the tolerance-driven time control, what it
estimated and what it delivered against a tight reference (biphasic_confined.py).

Prints per run: steps, Newton iterations, wall time of the stepping, the force and pressure
histories' errors against a Richardson reference and the limits against the closed forms;
writes NAME.csv and the chart of error against wall time (PNG) into --out.

    .venv/bin/python benchmarks/biphasic_unconfined.py [--out DIR] [--coarse] [--asked TOL ...]
"""

import biphasic_common

from fingertip_dolfinx.studies.problems import UnconfinedRelaxation

if __name__ == "__main__":
    biphasic_common.main(lambda solid: UnconfinedRelaxation(solid=solid), "biphasic_unconfined",
                         __doc__)
