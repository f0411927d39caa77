"""Pictures of the fields at an output time, drawn off-screen with pyvista (`fieldplots`).

The whole deformed section with its region outlines and the indenters in place (cf. the
paper's Fig. 4), one picture per field: the vertical displacement u2, the principal log
strains e_max and e_min, the strain energy density and, with a biphasic or undrained tissue,
the pore pressure. Every rank calls; rank 0 draws.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from .fieldplots import plot_field

#: name -> (label with units, how to get the field from (problem, derived fields), the
#: area quantile beyond which colours may saturate or None). Strains and SED peak at an
#: indenter's edge or tip (under the 25 µm wedge tip the SED is 30 times its value 0.5 mm
#: away): on a full scale the rest of the section would be one colour. Where the colours
#: saturate, the picture marks the true extreme and gives its value (fieldplots.plot_field).
FIELDS = {
    "u2": ("vertical displacement u2 (mm)", lambda p, d: p.u.sub(1), None),
    "e_max": ("max principal log strain e_max (-)", lambda p, d: d.principal.sub(0), 0.995),
    "e_min": ("min principal log strain e_min (-)", lambda p, d: d.principal.sub(1), 0.995),
    "sed": ("strain energy density (MPa)", lambda p, d: d.sed, 0.995),
    "p": ("pore pressure p (MPa)", lambda p, d: p.p, None),
}


def field_pictures(problem, derived, out: Path, t: float, title: str) -> None:
    """field_<name>_t<t>s.png in `out` for every field the model has (derived: updated)."""
    tips = placed_indenters(problem.obstacles)
    for name, (label, get, saturate) in FIELDS.items():
        if name == "p" and problem.p is None:
            continue
        nodes = problem.submesh_nodes if name == "p" else None
        plot_field(problem.mesh, problem.fmesh.cell_tags, problem.u, get(problem, derived),
                   Path(out) / f"field_{name}_t{t:g}s.png", label=label,
                   title=f"{title}: {name} at t = {t:g} s", indenters=tips,
                   field_mesh_nodes=nodes, saturate=saturate)


def placed_indenters(obstacles) -> list[tuple]:
    """(indenter, y_tip) of each obstacle where it is now: moved along x by its x_tip (a
    tangential path), else at its own centre_x."""
    placed = []
    for o in obstacles:
        indenter = o.indenter
        if o.x_tip is not None and float(o.x_tip.value) != 0.0:
            indenter = dataclasses.replace(
                indenter, centre_x=indenter.centre_x + float(o.x_tip.value))
        placed.append((indenter, float(o.y_tip.value)))
    return placed
