"""Benchmark: confined compression of the Holmes–Mow tissue, displacement ramp then hold.

A column 1 mm high (0.1 mm wide, one cell across) on rollers, drained on top, its top pushed
down by 1 % of its height in t0 = 0.002 t_c (t_c = H²/(k0 M) the consolidation time, k0 = 1
mm⁴/(N·s)) and held to 12 t_c; ν = 0.4 and ν = 0 (`studies.problems.ConfinedRelaxation`).
Exact limits: at the start the core cannot deform (J = 1) and its pore pressure carries the
whole load, p(bottom) = F/W; at the end the column is drained, F = −P22 W with P22 the
confined hyperfoam stress in closed form (`confined_drained_state`). The strain is small
because the ramp is fast: the drained top takes the whole travel in a layer ~sqrt(c t0)
thick, and at 2 % the ν = 0 foam's top approaches compaction.

`--asked TOL [TOL ...]`: per tolerance asked, the tolerance-driven time control
(`stepping.tolerance_steps`, `stepping.verify_time`), what it estimated and what it delivered
against a tight reference, beside local error control alone at rtol = TOL; with `--issue`, on
the column of the issue that asked for it (k0 = 10 mm⁴/(N·s), 20 % in 100 s, held to 3000 s).

Prints per run: steps, Newton iterations, wall time of the stepping, the force and pressure
histories' errors against a Richardson reference and the limits against the closed forms;
writes NAME.csv and the chart of error against wall time (PNG) into --out.

    .venv/bin/python benchmarks/biphasic_confined.py [--out DIR] [--coarse]
        [--asked TOL [TOL ...] [--issue]]
"""

import biphasic_common

from fingertip_dolfinx.studies.problems import ConfinedRelaxation


def issue_column(solid) -> ConfinedRelaxation:
    """k0 = 10 mm⁴/(N·s), 20 % in 100 s, held to 3000 s (times in units of t_c)."""
    tc = ConfinedRelaxation(solid=solid, k0=10.0, strain=0.2).consolidation_time
    return ConfinedRelaxation(solid=solid, k0=10.0, strain=0.2, ramp=100.0 / tc,
                              end=3000.0 / tc)


if __name__ == "__main__":
    biphasic_common.main(lambda solid: ConfinedRelaxation(solid=solid), "biphasic_confined",
                         __doc__, issue=issue_column)
