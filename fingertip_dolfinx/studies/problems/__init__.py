"""Verification problems with exact answers, shared by the tests and the stability study.

Each problem builds its mesh, forms and boundary conditions from the package's own pieces
(poroelasticity, viscoelasticity, contact, the time stepper's SNES set-up) and knows its exact
solution, so that a test and a study of the same problem measure the same thing. Units: mm, N,
s, MPa; plane strain, so forces are per unit thickness (N/mm). One module per problem; every
public name is imported here (`from fingertip_dolfinx.studies.problems import ConfinedBlock`).

- `block`: `ConfinedBlock`, a block on rollers loaded on its top (a traction strip or a
  displacement): biphasic (consolidation, creep, undrained strip load), viscoelastic (a relaxing
  strip) or hyperelastic (or, `small_strain`, exactly linear); with a `density`, dynamic
  (inertia.py: free vibration, a harmonically driven layer). A `Steppable` for
  `stepping.TimeStepper`. `UnconfinedBlock`: plane-strain unconfined compression between
  frictionless platens.
- `platens`: the canonical biphasic benchmarks, a platen ramp then hold, confined
  (`ConfinedRelaxation`) and unconfined (`UnconfinedRelaxation`), with their exact undrained and
  drained limits (`confined_drained_state`, `unconfined_undrained_state`,
  `unconfined_drained_state`) and `run_relaxation`.
- `terzaghi`: `Terzaghi`, the drained-top consolidation column and its exact pore pressure and
  settlement, after any time t (Terzaghi's series) and after one backward-Euler step.
- `hertz`: `Hertz` and `HertzBlock`, a rigid cylinder pressed into a linear-elastic half block
  with Nitsche contact, and the plane-strain Hertz half-width and peak pressure. `HertzSphere`:
  the 3D case, a rigid sphere on a quarter block (two symmetry planes), Hertz's contact radius
  and peak pressure (forces in N).
- `mindlin`: `CattaneoMindlin`, the cylinder on a whole block [−L, L] × [0, L] with Coulomb
  friction, pressed then dragged along x (`drag`): Cattaneo–Mindlin's stick half-width
  c = a sqrt(1 − Q/(μP)) and tangential traction, gross slip at Q = μP; `stick_halfwidth`,
  `l1_distance`. `CattaneoMindlin.exact()`: incompressible (β = 0), Taylor–Hood (u, p),
  R = 10 mm, the block on which the traction and the pressure converge to the closed forms.
- `mindlin_sphere`: `MindlinSphere`, the 3D case, a rigid sphere on a half block (symmetry
  plane z = 0) dragged along x (`drag_sphere`): Mindlin's stick radius
  c = a (1 − Q/(μP))^(1/3) measured along and across the drag (`stick_radii`), the traction's
  and the pressure's L1 distances as integrals over the contact face. `MindlinSphere.exact()`:
  incompressible (β = 0), Taylor–Hood (u, p), R = 10 mm, as the cylinder's.
- `sliding`: `SlidingBlock`, a linear-elastic block with inertia on rollers, dragged along x
  by a flat plate through Coulomb friction (`drag_block`, the "generalized-alpha" scheme):
  gross slip at μ Fn, the mean velocity growing at μ Fn/m, and the discrete energy balance
  (`energy_balance`): the plate's work against the kinetic, strain and penalty energies and
  the friction's dissipation.
- `layered`: `layered_block`, a synthetic 3D `FingertipMesh`, the four tissues as horizontal
  slabs of a half block with the fingertip's tags (pulp below, nail centre strip on top,
  symmetry and proximal-cut planes): the 3D problem's wiring without the fingertip geometry.
- `vibrating`: `VibratingLayer`, a viscoelastic hyperfoam layer on a rigid base, laterally
  confined, its top shaken harmonically: the standing wave of uniaxial strain in closed form,
  the exact check of the frequency-domain route (`harmonic`: G*(ω), the mass, the real block
  form).
- Closed forms: `confined_modulus`, `confined_drained_stress`, `prony_ramp_integral` (in
  `block`); for dynamics the harmonically driven layer (`driven_layer`, `driven_layer_force`, in
  `vibrating`; the complex modulus is `harmonic.complex_modulus`).
- `wiring`: `newton_problem` (a NonlinearProblem with the solver's SNES set-up),
  `support_reaction`, `graded`; `contact_edge` is in `hertz`.
"""

from .block import (
    ConfinedBlock,
    UnconfinedBlock,
    confined_drained_stress,
    confined_modulus,
    prony_ramp_integral,
)
from .hertz import Hertz, HertzBlock, HertzSphere, HertzSphereBlock, contact_edge
from .layered import LAYERS, layered_block
from .mindlin import CattaneoMindlin, MindlinBlock, drag, l1_distance, stick_halfwidth
from .mindlin_sphere import MindlinSphere, SphereBlock, drag_sphere, stick_radii
from .platens import (
    ConfinedRelaxation,
    PlatenRelaxation,
    PlatenState,
    RelaxationRun,
    UnconfinedRelaxation,
    confined_drained_state,
    run_relaxation,
    unconfined_drained_state,
    unconfined_undrained_state,
)
from .sliding import DraggedBlock, SlidingBlock, drag_block, energy_balance
from .terzaghi import Terzaghi
from .vibrating import VibratingLayer, driven_layer, driven_layer_force
from .wiring import QUADRATURE_DEGREE, graded, newton_problem, support_reaction

__all__ = [
    "CattaneoMindlin", "ConfinedBlock", "ConfinedRelaxation", "DraggedBlock", "Hertz",
    "HertzBlock", "SlidingBlock", "drag_block", "energy_balance",
    "HertzSphere", "HertzSphereBlock", "LAYERS", "MindlinBlock", "MindlinSphere",
    "PlatenRelaxation", "PlatenState", "QUADRATURE_DEGREE", "RelaxationRun", "SphereBlock",
    "Terzaghi", "UnconfinedBlock", "UnconfinedRelaxation", "VibratingLayer",
    "confined_drained_state", "confined_drained_stress", "confined_modulus", "contact_edge",
    "drag", "drag_sphere", "driven_layer", "driven_layer_force", "graded", "l1_distance",
    "layered_block", "newton_problem", "prony_ramp_integral", "run_relaxation",
    "stick_halfwidth", "stick_radii", "support_reaction", "unconfined_drained_state",
    "unconfined_undrained_state",
]
