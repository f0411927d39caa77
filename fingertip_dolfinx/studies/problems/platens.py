"""The canonical biphasic benchmarks: a Holmes–Mow tissue compressed by a platen in a ramp, then
held (stress relaxation), confined and unconfined (plane strain, frictionless platens), with
their exact undrained and drained limits in closed form; a run's histories and cost."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from mpi4py import MPI

from ...loading import RampHold
from ...physics import materials as mat
from ...stepping.options import StepOptions
from ...stepping.stepper import TimeStepper
from .block import ConfinedBlock, UnconfinedBlock, confined_drained_stress, confined_modulus


class PlatenState(NamedTuple):
    """A homogeneous plane-strain state under platens: stretches across (x) and along (y) the
    platens' travel, J = λx λy, the pore pressure p (MPa) and the total nominal stress P22
    (MPa: the platen force per unit reference width, negative in compression)."""

    stretch_x: float
    stretch_y: float
    J: float
    pressure: float
    P22: float


def confined_drained_state(solid, lam: float) -> PlatenState:
    """The drained end of confined compression to the stretch λ (`confined_drained_stress`):
    F = diag(1, λ), p = 0, P22 = τ2/λ."""
    return PlatenState(1.0, lam, lam, 0.0, float(confined_drained_stress(solid, lam)[1]))


def unconfined_undrained_state(solid, lam: float) -> PlatenState:
    r"""The undrained state of plane-strain unconfined compression between frictionless
    platens at the platen stretch λy = `lam`: the core of a specimen loaded faster than it
    drains.

    Frictionless platens moved uniformly leave every field independent of y (u_y = (λy − 1) y
    exactly), so the problem is one-dimensional in x: σ_xy = 0 and equilibrium ∂σ_xx/∂x = 0
    with a traction-free edge give σ_xx = 0 everywhere. The mixture's Cauchy stress is
    σ = τ(F)/J − p I, τ_a = Σ_i (2μ_i/α_i)(λ_a^α_i − J^(−α_i β_i)) the hyperfoam's principal
    Kirchhoff stresses (λ3 = 1, plane strain). Where no fluid has left, J = λx λy = 1, so

        λx = 1/λy,   p = τ1 = Σ_i (2μ_i/α_i)(λy^(−α_i) − 1)        (σ_xx = τ1 − p = 0),
        P22 = J σ_yy / λy = (τ2 − τ1)/λy,   τ2 = Σ_i (2μ_i/α_i)(λy^α_i − 1).

    At J = 1 the volume term is 1 for every β_i: the undrained response does not depend on ν.
    Displacement control makes it exact until the drainage front sqrt(c t) (c = k M) reaches
    the point: no Mandel–Cryer rise (that needs a prescribed force).
    """
    stretches = np.array([1.0 / lam, lam, 1.0])
    tau = solid.principal_kirchhoff(stretches)
    return PlatenState(1.0 / lam, lam, 1.0, float(tau[0]), float((tau[1] - tau[0]) / lam))


def unconfined_drained_state(solid, lam: float) -> PlatenState:
    r"""The drained end (p = 0) of plane-strain unconfined compression between frictionless
    platens at the platen stretch λy = `lam`.

    As in `unconfined_undrained_state` σ_xx = 0 everywhere; with p = 0 the solid alone is
    free across: τ1(λx, λy, 1) = Σ_i (2μ_i/α_i)(λx^α_i − (λx λy)^(−α_i β_i)) = 0. For λy < 1
    τ1 < 0 at λx = 1 (the volume term pushes out; λ0 ln λy at small strain) and τ1 > 0 at
    λx = 1/λy (J = 1), so Brent's method finds λx between them (to round-off). ν = 0 (every
    β_i = 0): τ1 = Σ (2μ_i/α_i)(λx^α_i − 1) vanishes at λx = 1: no lateral expansion at all,
    the foam's signature. Then J = λx λy and P22 = J σ_yy/λy = τ2/λy.
    """
    from scipy.optimize import brentq

    def tau_x(lx: float) -> float:
        return float(solid.principal_kirchhoff(np.array([lx, lam, 1.0]))[0])

    low, high = sorted((1.0, 1.0 / lam))
    if tau_x(low) == 0.0:
        lx = low
    elif tau_x(high) == 0.0:
        lx = high
    else:
        lx = brentq(tau_x, low, high, xtol=1e-15, rtol=4 * np.finfo(float).eps)
    tau = solid.principal_kirchhoff(np.array([lx, lam, 1.0]))
    return PlatenState(lx, lam, lx * lam, 0.0, float(tau[1] / lam))


@dataclass(frozen=True)
class PlatenRelaxation:
    """A Holmes–Mow tissue (the paper's κ and M, permeability `k0` at J = 1, the hyperfoam
    `solid`) compressed by a platen to `strain` (of the height) in a linear ramp, then held:
    stress relaxation. Times scale with the consolidation time t_c = L²/(k0 M), M = K0 + 4μ0/3
    the confined modulus and L the drainage length: the ramp lasts `ramp` t_c, the run `end`
    t_c. Subclasses fix the geometry (`ConfinedRelaxation`, `UnconfinedRelaxation`), their
    block and their exact limits.
    """

    solid: mat.Hyperfoam = mat.SUBCUTANEOUS
    k0: float = 1.0  # mm⁴/(N·s)
    strain: float = 0.1
    ramp: float = 0.002
    end: float = 12.0
    length: float = 1.0  # mm: the drainage length L
    height: float = 1.0  # mm: the height the platen compresses

    @property
    def tissue(self) -> mat.Biphasic:
        hm = mat.HOLMES_MOW_SUBCUTANEOUS
        return mat.Biphasic(self.solid, mat.HolmesMow(k0=self.k0, phi0=hm.phi0,
                                                      kappa=hm.kappa, M=hm.M))

    @property
    def consolidation_time(self) -> float:
        """t_c = L²/(k0 M) (s)."""
        return self.length**2 / (self.k0 * confined_modulus(self.solid))

    @property
    def history(self) -> RampHold:
        """The platen's travel (mm) against time (s)."""
        tc = self.consolidation_time
        return RampHold(self.strain * self.height, self.ramp * tc, self.end * tc)

    @property
    def stretch(self) -> float:
        return 1.0 - self.strain

    def slowest_rate(self) -> float:
        """λ1 = (π/2)² c/L² (1/s): the decay rate of the slowest consolidation mode near the
        drained end (one drained side, L the drainage length), c the end state's
        consolidation coefficient (`consolidation_coefficient`)."""
        return (math.pi / 2) ** 2 * self.consolidation_coefficient() / self.length**2

    def end_tolerance(self, excess: float, steps: np.ndarray) -> float:
        """A bound on |F/F_drained − 1| at the end of a run: the drained end state is
        homogeneous (u linear, p = 0), so P2/P1 holds it exactly and the mesh adds nothing;
        what is left is the slowest consolidation mode, at most the relative excess force
        `excess` at the ramp's end, decayed by backward Euler's Π (1 + λ1 Δt_i)⁻¹ over the
        hold's `steps` (slower than e^(−λ1 t)); twice that, for the modes' nonlinear mixing."""
        decay = float(np.prod(1.0 / (1.0 + self.slowest_rate() * np.asarray(steps))))
        return 2.0 * abs(excess) * decay


@dataclass(frozen=True)
class ConfinedRelaxation(PlatenRelaxation):
    """Confined compression (the column of `ConfinedBlock`, `length` = its height, drained on
    top, 0.1 mm wide) by a displacement ramp, then held.

    Exact limits: at the end, drained, the homogeneous state F = diag(1, λ) with p = 0 and the
    force −P22 W of `confined_drained_state`. At the start, undrained: a confined piece of
    tissue that keeps its volume cannot deform, so below the drainage front (~sqrt(c t) under
    the drained top) J = 1 and the solid is unstressed: the fluid carries the whole load,
    p(bottom) = F/W. The layer above the front takes the whole travel; the linear solution
    for a displacement ramp u = V t into a drained half-space puts its top strain at
    2 V sqrt(t/(π c)), i.e. 2ε/sqrt(π τ0) at the ramp's end (τ0 = t0/t_c): a fast ramp
    compacts the top. The defaults balance the two: τ0 = 0.002 keeps the lower
    half undrained to e^(−1/(16 τ0)) ≈ 3e-14 and a 1 % strain puts the top strain near 0.25.
    """

    strain: float = 0.01
    width: float = 0.1

    def block(self, n: int, grading: float = 1.0, comm=MPI.COMM_SELF) -> ConfinedBlock:
        return ConfinedBlock(1, n, self.history, tissue=self.tissue, width=self.width,
                             H=self.length, drained_top=True, top_displacement=True,
                             grading=grading, comm=comm)

    def drained(self) -> PlatenState:
        return confined_drained_state(self.solid, self.stretch)

    def consolidation_coefficient(self) -> float:
        """c = k(λ) P22'(λ)/λ (mm²/s) at the drained end: with J = λ and the total P22 =
        P_s(λ) − p uniform, the mass balance ∂λ/∂t = ∂/∂Y((k/λ) ∂p/∂Y) is a diffusion of λ
        with this coefficient (P_s' by central differences of the closed form)."""
        lam, h = self.stretch, 1e-6

        def P(x):
            return confined_drained_state(self.solid, x).P22

        slope = (P(lam + h) - P(lam - h)) / (2 * h)
        return float(self.tissue.permeability.permeability_np(lam)) * slope / lam

    def drained_force(self) -> float:
        """The platen force at the drained end (N/mm, compressive positive)."""
        return -self.drained().P22 * self.width


@dataclass(frozen=True)
class UnconfinedRelaxation(PlatenRelaxation):
    """Plane-strain unconfined compression between frictionless impermeable platens with a
    drained free edge (`UnconfinedBlock`: `length` = the half-width W, `height` = the half
    height), by a displacement ramp, then held.

    Exact limits: at the end of a fast ramp the core (x < W/2) is undrained: p equals
    `unconfined_undrained_state`'s (the front sqrt(c t0) = sqrt(τ0) W leaves the centre
    undrained to e^(−1/(16 τ0))); at long times the force equals
    `unconfined_drained_state`'s −P22 W. The free edge is drained from the start, at the
    drained lateral stretch: J there is the drained J, no compaction however fast the ramp.
    """

    height: float = 0.25

    def block(self, n: int, grading: float = 1.0, comm=MPI.COMM_SELF) -> UnconfinedBlock:
        return UnconfinedBlock(n, 1, self.history, tissue=self.tissue, width=self.length,
                               H=self.height, grading=grading, comm=comm)

    def undrained(self) -> PlatenState:
        return unconfined_undrained_state(self.solid, self.stretch)

    def drained(self) -> PlatenState:
        return unconfined_drained_state(self.solid, self.stretch)

    def consolidation_coefficient(self) -> float:
        """c = k(J) P11'(λx)/J (mm²/s) at the drained end: with λy fixed, J = λx λy and the
        total P11 = P_s(λx) − p λy = 0, the mass balance λy ∂λx/∂t = ∂/∂X((J k/λx²) ∂p/∂X)
        is a diffusion of λx with this coefficient (P_s = τ1/λx, by central differences)."""
        end = self.drained()
        lx, ly, h = end.stretch_x, end.stretch_y, 1e-6

        def P(x):
            return float(self.solid.principal_kirchhoff(np.array([x, ly, 1.0]))[0]) / x

        slope = (P(lx + h) - P(lx - h)) / (2 * h)
        return float(self.tissue.permeability.permeability_np(end.J)) * slope / end.J

    def drained_force(self) -> float:
        """The platen force at the drained end (N/mm over the half-width, compressive > 0)."""
        return -self.drained().P22 * self.length


@dataclass
class RelaxationRun:
    """One run's histories (one entry per accepted step, after t = 0): time (s), platen force
    (N/mm, compressive positive), core pressure (MPa), max |J − 1| in the core, min J; and its
    cost: steps, Newton iterations, step cuts, wall time of the stepping (s)."""

    time: np.ndarray
    force: np.ndarray
    core_pressure: np.ndarray
    core_J_change: np.ndarray
    J_min: np.ndarray
    steps: int
    newton_iterations: int
    cuts: int
    wall_time_s: float

    def at(self, t: float) -> int:
        """The index of the step that ended at t (the stepper lands on breakpoints)."""
        i = int(np.argmin(np.abs(self.time - t)))
        if not abs(self.time[i] - t) <= 1e-9 * max(1.0, abs(t)):
            raise ValueError(f"no step ended at t = {t} s")
        return i


def run_relaxation(problem: PlatenRelaxation, block: ConfinedBlock, options: StepOptions,
                   petsc_options: dict | None = None, sample_times=(), prefix: str = "relax_"
                   ) -> RelaxationRun:
    """Step `block` along `problem`'s history with `options`, landing on `sample_times` (and
    the ramp's end); returns the histories and the cost."""
    import time as wallclock

    history = problem.history
    stepper = TimeStepper(block, options, petsc_options, prefix=prefix)
    rows = []

    def record(report):
        d = report.diagnostics
        rows.append((report.time, -d["reaction"], d["core_pressure"], block.core_J_change(),
                     d["J_min"], report.newton_iterations, report.cuts))

    started = wallclock.perf_counter()
    try:
        stepper.run(history, history.end_time, breakpoints=sorted(sample_times),
                    on_step=record)
    finally:
        wall = wallclock.perf_counter() - started
        stepper.close()
    a = np.array(rows)
    return RelaxationRun(a[:, 0], a[:, 1], a[:, 2], a[:, 3], a[:, 4], len(rows),
                         int(a[:, 5].sum()), int(a[:, 6].sum()), wall)
