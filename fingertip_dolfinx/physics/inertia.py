r"""Inertia for time-domain dynamics: the mass term of the momentum balance and the history of
the Wood–Bossak–Zienkiewicz integrator (generalised-α with α_f = 0).

The momentum balance with inertia, tested with w,

    ∫ ρ a·w dX + ∫ P : Grad w dX − (loads) = 0,

is integrated in time by the Chung–Hulbert generalised-α family with α_f = 0, which is the
Wood–Bossak–Zienkiewicz α-method (Wood, Bossak & Zienkiewicz, IJNME 15, 1980; Chung & Hulbert,
J. Appl. Mech. 60, 1993, eqs. 25 and 17 with α_f = 0): only the inertia is evaluated at the
intermediate point,

    M [(1 − α_m) a_{n+1} + α_m a_n] + f_int(u_{n+1}, history) = f_ext(t_{n+1}),

with Newmark's updates

    a_{n+1} = (u_{n+1} − u_n − Δt v_n)/(β Δt²) − (1/(2β) − 1) a_n,
    v_{n+1} = v_n + Δt [(1 − γ) a_n + γ a_{n+1}],

and, for a user dissipation ρ∞ ∈ [0, 1] (the spectral radius at Δt → ∞),

    α_m = (ρ∞ − 1)/(ρ∞ + 1),   γ = 1/2 − α_m,   β = (1 − α_m)²/4.

Second order for every ρ∞; unconditionally stable for linear problems; ρ∞ = 1 is the
trapezoidal rule (α_m = 0, β = 1/4, γ = 1/2), which conserves ½ vᵀMv + ½ uᵀKu exactly for a
linear system. Since α_f = 0, the internal forces, the QLV recursion, the biphasic mass balance
and the contact all stay at t_{n+1}, exactly as in a quasi-static step: only this term is new.

The state is (u_n, v_n, a_n) at the nodes; v_n and a_n live in u's space, and `advance`
updates them (before u_n takes u_{n+1}) from the nodal Newmark formulas above, which are
linear and so exact on the coefficient arrays. Initial conditions: v = a = 0 (at rest). That is
the consistent initial acceleration when the run starts from rest in equilibrium with no load
(M a_0 = f_ext − f_int(u_0) = 0), as every fingertip run does (the indenter touches at d = 0).
The coefficients (α_m, γ, β) are one `fem.Constant`, the step Δt the problem's: changing either
never recompiles a form.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from ..errors import InputError


def wbz_parameters(rho_inf: float) -> tuple[float, float, float]:
    """(α_m, γ, β) of the Wood–Bossak–Zienkiewicz method with spectral radius ρ∞ at
    Δt → ∞ (Chung & Hulbert 1993 with α_f = 0): (0, 1/2, 1/4) at ρ∞ = 1, the trapezoidal rule;
    (−1, 3/2, 1) at ρ∞ = 0, which annihilates the highest modes in one step."""
    if not 0.0 <= rho_inf <= 1.0:
        raise InputError("steps.rho_inf", f"the spectral radius {rho_inf} is outside [0, 1].",
                         "use 1 (no numerical dissipation) down to 0 (the most).")
    alpha_m = (rho_inf - 1.0) / (rho_inf + 1.0)
    return alpha_m, 0.5 - alpha_m, 0.25 * (1.0 - alpha_m) ** 2


class Inertia:
    """The mass term Σ_r ∫_r ρ_r [(1 − α_m) a_{n+1} + α_m a_n]·w dX and the state v_n, a_n.

    `u`, `u_n`: the displacement now and at the last accepted step; `dt`: the step (the
    problem's Constant); `masses`: (ρ, dx) pairs, a density (N·s²/mm⁴) and the measure of its
    region (a region of zero density, e.g. a rigid one, is left out).
    """

    def __init__(self, u: fem.Function, u_n: fem.Function, dt: fem.Constant,
                 masses: Sequence[tuple[float, ufl.Measure]]):
        V = u.function_space
        self.u, self.u_n, self.dt = u, u_n, dt
        self.masses = [(float(rho), dx) for rho, dx in masses if rho > 0]
        self.v_n = fem.Function(V, name="velocity")
        self.a_n = fem.Function(V, name="acceleration")
        #: (α_m, γ, β); the trapezoidal rule until the time stepper sets its ρ∞.
        self.parameters = fem.Constant(V.mesh, np.array(wbz_parameters(1.0)))
        self._kinetic = None

    def set_dissipation(self, rho_inf: float) -> None:
        """Take the method's coefficients for the spectral radius ρ∞ (no recompilation)."""
        self.parameters.value[:] = wbz_parameters(rho_inf)

    @property
    def rho_inf(self) -> float:
        alpha_m = float(self.parameters.value[0])
        return (1.0 + alpha_m) / (1.0 - alpha_m)

    def acceleration(self) -> ufl.core.expr.Expr:
        """a_{n+1} as UFL, from Newmark's update: it depends on the unknown u."""
        beta, dt = self.parameters[2], self.dt
        return ((self.u - self.u_n - dt * self.v_n) / (beta * dt**2)
                - (1.0 / (2.0 * beta) - 1.0) * self.a_n)

    def residual(self, w) -> ufl.Form:
        """Σ_r ∫_r ρ_r [(1 − α_m) a_{n+1} + α_m a_n]·w dX."""
        alpha_m = self.parameters[0]
        a = (1.0 - alpha_m) * self.acceleration() + alpha_m * self.a_n
        return sum(rho * ufl.inner(a, w) * dx for rho, dx in self.masses)

    def advance(self) -> None:
        """After a converged step, before u_n takes u_{n+1}: a_n ← a_{n+1}, v_n ← v_{n+1}."""
        alpha_m, gamma, beta = (float(x) for x in self.parameters.value)
        dt = float(self.dt.value)
        u, u_n = self.u.x.array, self.u_n.x.array
        v, a = self.v_n.x.array, self.a_n.x.array
        a_new = (u - u_n - dt * v) / (beta * dt**2) - (1.0 / (2.0 * beta) - 1.0) * a
        v[:] = v + dt * ((1.0 - gamma) * a + gamma * a_new)
        a[:] = a_new

    def consistent_acceleration(self, static: ufl.Form, bcs: Sequence) -> None:
        """a_n ← the acceleration the state u_n is in: M a_n = −R_s(u_n), with R_s the residual
        without the mass term (its loads as they are now) and a_n = 0 on the Dirichlet dofs.
        A run starting from rest in equilibrium has a_n = 0 already; after a jump of a force
        (a plate's velocity step makes the friction jump to μ p, slipping everywhere: the
        surface's velocity is continuous, the plate's is not) the a_n the Newmark history
        holds is the one before the jump, and the step that follows averages the two ends
        (first order); with this one it is second order again (docs/benchmarks/friction.md).
        """
        from dolfinx.fem import petsc
        from petsc4py import PETSc

        V = self.u.function_space
        w, da = ufl.TestFunction(V), ufl.TrialFunction(V)
        M = petsc.assemble_matrix(fem.form(sum(rho * ufl.inner(da, w) * dx
                                              for rho, dx in self.masses)), bcs=list(bcs))
        M.assemble()
        b = petsc.assemble_vector(fem.form(-static))
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        petsc.set_bc(b, list(bcs), alpha=0.0)
        ksp = PETSc.KSP().create(V.mesh.comm)
        ksp.setOperators(M)
        ksp.setType("preonly")
        ksp.getPC().setType("lu")
        ksp.getPC().setFactorSolverType("mumps")  # the package's direct solver, any ranks
        ksp.solve(b, self.a_n.x.petsc_vec)
        self.a_n.x.scatter_forward()
        for obj in (ksp, M, b):
            obj.destroy()

    def arrays(self) -> dict[str, np.ndarray]:
        """The live arrays of the integrator's state, by checkpoint name."""
        return {"v_n": self.v_n.x.array, "a_n": self.a_n.x.array}

    def kinetic_energy(self) -> float:
        """½ Σ_r ∫_r ρ_r v_n·v_n dX (N·mm/mm: plane strain), over every rank."""
        if self._kinetic is None:
            self._kinetic = fem.form(sum(0.5 * rho * ufl.inner(self.v_n, self.v_n) * dx
                                         for rho, dx in self.masses))
        comm = self.u.function_space.mesh.comm
        return comm.allreduce(fem.assemble_scalar(self._kinetic), op=MPI.SUM)
