"""Newton's residual: DOLFINx's, without the Dirichlet lifting where the lifting adds zero.

DOLFINx's `NonlinearProblem` evaluates the residual at an iterate x as (`dolfinx.fem.petsc.
assemble_residual`, 0.11)

    b = R(x);  b ← b + J(x) (g − x)|_D  (`apply_lifting`, α = −1);  b_D = x_D − g  (`set_bc`),

with D the Dirichlet dofs and g their prescribed values. The lifting assembles the Jacobian's
forms (packing all their coefficients and running the Jacobian kernel on every cell that holds a
Dirichlet dof: in 3D the symmetry plane, the proximal cut and the nail's clamped strip) only to
multiply them by (g − x) on D. Where x already takes its prescribed values, g − x = 0 on D to
the bit, and the lifting adds exactly zero: the fingertip's supports are all homogeneous
(problem.py `_support`: the clamp and the rollers hold 0), and every Newton iterate keeps them
(the start state does, and each Newton correction is 0 on D, where the Jacobian's rows and
columns are the identity's and the residual's entries x_D − g are 0).

So `UnliftedResidual` checks, at every evaluation, what the lifting would multiply: α(g − x) on
D for every condition, as `DirichletBC.set` computes it (ghosts included, on every rank). All
zero: the residual is assembled without the lifting; anything else (a condition whose value
moves in time or is not yet met, a NaN): DOLFINx's own function, lifting and all. The decision
is the data's, per evaluation; the skipped residual equals the lifted one to the bit (up to the
sign of a zero entry: x + 0 = x). Measured on the 3D line load (a residual 40 % cheaper, about
6 s of the run): docs/benchmarks/solvers-3d.md, "The residual's Dirichlet lifting".
"""

from __future__ import annotations

from collections.abc import Sequence

import dolfinx.fem.petsc
import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc


class UnliftedResidual:
    """SNES's residual function, DOLFINx's (`assemble_residual`) without the lifting whenever
    every Dirichlet condition is met by the iterate (the lifting then adds zero).

    Installed on a `dolfinx.fem.petsc.NonlinearProblem`'s SNES in place of its residual;
    `skipped` and `lifted` count the evaluations of each kind.
    """

    def __init__(self, snes: PETSc.SNES):
        vector, (function, args, kargs) = snes.getFunction()
        self._lifted = (function, args, kargs)
        residual, u = kargs["residual"], kargs["u"]
        self._blocked = isinstance(residual, Sequence)
        self._forms = residual
        self._u = list(u) if self._blocked else [u]
        self._blocks = kargs.get("_blocks")
        spaces = fem.extract_function_spaces(residual if self._blocked else [residual])
        self._bcs = fem.bcs_by_block(spaces, kargs["bcs"])
        self._set_bcs = self._bcs if self._blocked else self._bcs[0]
        self._comm = snes.getComm().tompi4py()
        self.skipped = self.lifted = 0
        snes.setFunction(self, vector)

    def lifting_vanishes(self) -> bool:
        """Whether g − x is 0 on every Dirichlet dof of every unknown (owned and ghost), on
        every rank: the vector the lifting multiplies by the Jacobian."""
        local = True
        for u, bcs in zip(self._u, self._bcs):
            if not bcs:
                continue
            values = u.x.array
            shift = np.zeros_like(values)
            for bc in bcs:
                bc.set(shift, x0=values, alpha=1.0)  # (g − x) on its dofs, 0 elsewhere
            local = local and not np.any(shift)  # a NaN counts as non-zero
        return self._comm.allreduce(local, op=MPI.LAND)

    def __call__(self, snes: PETSc.SNES, x: PETSc.Vec, b: PETSc.Vec) -> None:
        x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        dolfinx.fem.petsc.assign(x, self._u if self._blocked else self._u[0])
        if self.lifting_vanishes():
            self.skipped += 1
            self.assemble_unlifted(x, b)
        else:
            self.lifted += 1
            self.assemble_lifted(snes, x, b)

    def assemble_lifted(self, snes: PETSc.SNES, x: PETSc.Vec, b: PETSc.Vec) -> None:
        """DOLFINx's residual at x, lifting and all."""
        function, args, kargs = self._lifted
        function(snes, x, b, *args, **kargs)

    def assemble_unlifted(self, x: PETSc.Vec, b: PETSc.Vec) -> None:
        """DOLFINx's residual at x without the lifting, its other steps as DOLFINx takes them;
        the unknowns must hold x (`__call__` assigns them)."""
        if self._blocked:  # as DOLFINx: the block layout travels with the vectors
            b.setAttr("_blocks", self._blocks)
            x.setAttr("_blocks", self._blocks)
        with b.localForm() as local:
            local.set(0.0)
        dolfinx.fem.petsc.assemble_vector(b, self._forms)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        dolfinx.fem.petsc.set_bc(b, self._set_bcs, x0=x, alpha=-1.0)
        b.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
