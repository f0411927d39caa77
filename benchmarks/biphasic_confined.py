"""Benchmark: confined compression of the Holmes–Mow tissue, displacement ramp then hold.

A column 1 mm high (0.1 mm wide, one cell across) on rollers, drained on top, its top pushed
down by 1 % of its height in t0 = 0.002 t_c (t_c = H²/(k0 M) the consolidation time, k0 = 1
mm⁴/(N·s)) and held to 12 t_c; ν = 0.4 and ν = 0 (`studies.problems.ConfinedRelaxation`).
Exact limits: at the start the core cannot deform (J = 1) and its pore pressure carries the
whole load, p(bottom) = F/W; at the end the column is drained, F = −P22 W with P22 the
confined hyperfoam stress in closed form (`confined_drained_state`). The strain is small
because the ramp is fast: the drained top takes the whole travel in a layer ~sqrt(c t0)
thick, and at 2 % the ν = 0 foam's top approaches compaction (issue 11).

Prints per run: steps, Newton iterations, wall time of the stepping, the force and pressure
histories' errors against a Richardson reference and the limits against the closed forms;
writes NAME.csv and the chart of error against wall time (PNG) into --out.

    .venv/bin/python benchmarks/biphasic_confined.py [--out DIR] [--coarse]
"""

import biphasic_common

from fingertip_dolfinx.studies.problems import ConfinedRelaxation

if __name__ == "__main__":
    biphasic_common.main(lambda solid: ConfinedRelaxation(solid=solid), "biphasic_confined",
                         __doc__)
