"""The wiring the verification problems share: the quadrature degree of their volume terms,
graded cells towards a drained boundary, a Newton problem with the time stepper's SNES set-up,
the reaction of a support."""

from __future__ import annotations

import math

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem.petsc import NonlinearProblem

from ...stepping.options import DEFAULT_PETSC_OPTIONS

#: Quadrature degree of the block's volume terms: the hyperfoam stress is not polynomial.
QUADRATURE_DEGREE = 4


def graded(s: np.ndarray, ratio: float) -> np.ndarray:
    """s ∈ [0, 1] mapped so that equal cells in s shrink geometrically towards s = 1, the
    first `ratio` times the last (1: unchanged): 1 − (e^(g(1 − s)) − 1)/(e^g − 1), g = ln ratio.
    A drained boundary's layer, ~sqrt(c t) thick at first, needs the small cells."""
    if ratio == 1.0:
        return s
    g = math.log(ratio)
    return 1.0 - np.expm1(g * (1.0 - s)) / math.expm1(g)


def newton_problem(F, u, bcs, prefix: str, **options) -> NonlinearProblem:
    """A NonlinearProblem with the time stepper's SNES set-up (`stepping.DEFAULT_PETSC_OPTIONS`:
    Newton with line search, direct LU) and `options` on top, e.g. snes_rtol=1e-12.
    `prefix` must be unique per problem (PETSc options are global). F and u may be lists (a
    mixed problem): one monolithic matrix, as the time stepper's."""
    kind = "mpi" if isinstance(u, list | tuple) else None
    return NonlinearProblem(F, u, bcs=bcs, petsc_options_prefix=prefix, kind=kind,
                            petsc_options={**DEFAULT_PETSC_OPTIONS, **options})


def support_reaction(P, V, dofs) -> float:
    """The y-reaction of the supports holding `dofs` (N/mm): the elastic residual ∫ P:∇w dx
    tested with w = 1 on those y-dofs, summed over the ranks."""
    w = fem.Function(V)
    w.x.array[dofs] = 1.0
    form = fem.form(ufl.inner(P, ufl.grad(w)) * ufl.dx)
    return V.mesh.comm.allreduce(fem.assemble_scalar(form))
