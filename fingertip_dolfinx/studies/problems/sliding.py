r"""A block dragged by Coulomb friction, with inertia: the check of friction on the dynamic route.

A linear-elastic block [−W/2, W/2] × [0, H] of density ρ (small strain, plane strain) rests on a
rigid flat plate below it, its top on rollers (u_y = 0, u_x free). The plate is pressed up by
`depth` (one static step: the block starts at rest in equilibrium), then moves along +x at a
constant speed V from t = 0, at constant depth. Nothing holds the block along x but the
friction (μ, Nitsche contact, physics/friction.py), so it is dragged after the plate.

Closed form (momentum): while the whole contact slips (the plate faster than the block's bottom
everywhere), the friction force is μ times the normal force Fn, and the block's momentum grows
at that rate: its mean velocity v̄(t) = μ Fn t/m (m = ρ W H) until it catches up with the
plate at t* = m V/(μ Fn). For a rigid block the friction dissipates ½ m V² by then, as much as
it gives the block as kinetic energy (the plate's work is m V²); an elastic one keeps a little
of the plate's work as shear waves.

The discrete energy balance over the drag: the plate's work W = Σ ½ (F_n + F_{n+1})·Δc (F the
force it puts on the block, Δc its move over a step) against Δ(kinetic energy) + Δ(strain
energy) + Δ(the penalty's stored energy ½ ∫ γ [−g]_+² ds) + the friction's dissipation
Σ D_{n+1} (D_{n+1} = −∫ f_{n+1}·Δs_{n+1} ds, what the package records per step): their
difference is the scheme's own energy error (`energy_balance`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import ufl
from dolfinx import fem, la, mesh
from mpi4py import MPI

from ...geometry.indenters import Plate
from ...physics import materials as mat
from ...physics.admissibility import Admissibility
from ...physics.contact import NitscheContact, Obstacle
from ...physics.friction import CoulombFriction
from ...physics.inertia import Inertia
from ...physics.kinematics import deformation_gradient
from ...state import SteppableState
from ...stepping.options import StepOptions
from ...stepping.stepper import TimeStepper
from .wiring import QUADRATURE_DEGREE

#: The static press: one step this long (s) makes the mass term ρ a ~ ρ u/Δt² vanish.
STATIC_STEP = 1e9


@dataclass(frozen=True)
class SlidingBlock:
    """The block's data (units mm, N, s, MPa; ρ in N s²/mm⁴ chosen so that the times are of
    order 1 s: only ratios matter) and its closed forms."""

    W: float = 2.0
    H: float = 1.0
    E: float = 1.0
    nu: float = 0.3
    density: float = 1.0
    mu: float = 0.5
    depth: float = 0.01  # mm: the plate's push into the block
    speed: float = 0.05  # mm/s: the plate's speed along x, reached at `ramp`
    #: The plate's start (s): constant acceleration to `speed` over [0, ramp] (0: a velocity
    #: step at t = 0, which the trapezoidal rule takes with a first-order error: the friction
    #: force jumps from 0 to μ Fn within the first step, and the step averages its two ends).
    ramp: float = 1.0
    #: The contact law: "penalty" (γ0 = `gamma0`), the conservative one dynamics needs
    #: (contact.py), or "nitsche" (θ = 0).
    method: str = "penalty"
    gamma0: float = 10.0
    #: With a velocity step (ramp = 0): start the drag from the acceleration the block is in
    #: just after the step (`DraggedBlock.jump`), not from rest's a = 0.
    jump_acceleration: bool = False

    @property
    def mass(self) -> float:
        """m = ρ W H (N s²/mm per mm of thickness)."""
        return self.density * self.W * self.H

    def mean_velocity(self, t, normal_force: float):
        """v̄(t) = min(μ Fn t/m, V): the block's mean velocity (mm/s), accelerated by gross slip
        until it moves with the plate."""
        return np.minimum(self.mu * normal_force * np.asarray(t) / self.mass, self.speed)

    def catch_up(self, normal_force: float) -> float:
        """t* = m V/(μ Fn) (s): when the block's mean velocity reaches the plate's."""
        return self.mass * self.speed / (self.mu * normal_force)

    def stress(self, u):
        """σ(ε(u)) = λ tr(ε) I + 2μ ε (small strain)."""
        G = self.E / (2 * (1 + self.nu))
        lmbda = self.E * self.nu / ((1 + self.nu) * (1 - 2 * self.nu))
        eps = ufl.sym(ufl.grad(u))
        return lmbda * ufl.tr(eps) * ufl.Identity(2) + 2 * G * eps

    def build(self, nx: int, ny: int, comm=MPI.COMM_SELF) -> DraggedBlock:
        """The Steppable block on an nx × ny mesh of triangles, P2."""
        return DraggedBlock(self, nx, ny, comm)


class DraggedBlock(SteppableState):
    """The `SlidingBlock` as a `stepping.Steppable` with inertia and friction (`drag_block`
    presses it, then steps it with the "generalized-alpha" scheme)."""

    keeps_u_nm1 = False  # no rate: u_{n−1} is no part of the state

    def __init__(self, data: SlidingBlock, nx: int, ny: int, comm=MPI.COMM_SELF):
        self.data = data
        self.msh = msh = mesh.create_rectangle(
            comm, [[-data.W / 2, 0.0], [data.W / 2, data.H]], [nx, ny])
        V = fem.functionspace(msh, ("Lagrange", 2, (2,)))
        self.u, self.u_n, self.u_nm1 = fem.Function(V), fem.Function(V), fem.Function(V)
        self.p, self.unknowns, self.entity_maps = None, [self.u], None
        self.dt = fem.Constant(msh, 1.0)
        dx = ufl.dx(metadata={"quadrature_degree": QUADRATURE_DEGREE})
        self.sigma = data.stress(self.u)
        v = ufl.TestFunction(V)
        self.inertia = Inertia(self.u, self.u_n, self.dt, [(data.density, dx)])
        self.obstacle = Obstacle.at(msh, Plate(), y_tip=0.0, x_tip=0.0)
        G = data.E / (2 * (1 + data.nu))
        M = mat.p_wave_modulus(data.E, data.nu)
        self.contact = NitscheContact(self.u, self.sigma, ufl.ds(subdomain_data=self._tags(),
                                                                  subdomain_id=1),
                                      [self.obstacle], modulus=M, method=data.method,
                                      gamma0=data.gamma0)
        self.friction = CoulombFriction(self.contact, data.mu, gamma_ratio=G / M)
        #: The residual without the mass term (`jump`).
        self.static = (ufl.inner(self.sigma, ufl.grad(v)) * dx + self.contact.residual(v)
                       + self.friction.residual(v))
        self.residuals = [self.static + self.inertia.residual(v)]
        top = mesh.locate_entities_boundary(msh, 1, lambda x: np.isclose(x[1], data.H))
        Vy = V.sub(1)
        self.bcs = [fem.dirichletbc(0.0, fem.locate_dofs_topological(Vy, 1, top), Vy)]
        self.admissibility = Admissibility(deformation_gradient(self.u), msh,
                                           QUADRATURE_DEGREE)
        self._energy = fem.form(0.5 * ufl.inner(self.sigma, ufl.sym(ufl.grad(self.u))) * dx)
        self._t, self._friction_now = 0.0, None
        self.mark_accepted()

    def _tags(self) -> mesh.MeshTags:
        """The bottom facets (y = 0) tagged 1: the contact face."""
        bottom = mesh.locate_entities_boundary(self.msh, 1, lambda x: np.isclose(x[1], 0.0))
        return mesh.meshtags(self.msh, 1, bottom, np.ones(len(bottom), dtype=np.int32))

    # Steppable --------------------------------------------------------------------------------
    def jump(self) -> dict[str, float]:
        """The state just after the plate's velocity step, at rest where it was pressed: every
        contact point slips (the block's velocity is continuous, the plate's jumps), so the
        friction is μ p along the plate's velocity, as the return mapping gives it for a trial
        slip that dwarfs the elastic one (the plate moved 1e6 mm for this evaluation only; it
        is flat, so nothing else changes). The Newmark history takes the acceleration of that
        state; returns the diagnostics there (the forces after the jump)."""
        self.obstacle.x_tip.value = 1e6
        self.inertia.consistent_acceleration(self.static, self.bcs)
        after = self.diagnostics()
        self.set_time(self._t)
        return after

    def plate_x(self, t: float) -> float:
        """The plate's displacement along x at time t (mm): V t²/(2 T) until T = `ramp`, then
        at the speed V."""
        V, T, t = self.data.speed, self.data.ramp, max(t, 0.0)
        return V * t * t / (2 * T) if t < T else V * (t - T / 2)

    def set_time(self, t: float) -> None:
        self._t = t
        self.obstacle.y_tip.value = self.data.depth
        self.obstacle.x_tip.value = self.plate_x(t)

    def histories(self) -> list:
        """The friction's last accepted state: its slip increments start there."""
        return [self.friction]

    def diagnostics(self) -> dict[str, float]:
        """The plate's force on the block (x, y), the step's friction dissipation and normal
        contact work, the strain energy (measured before the step is accepted)."""
        fx, fy = self.friction.forces()[0]
        previous, self._friction_now = self._friction_now, self._friction_vector()
        return {"force_x": float(fx), "force_y": float(fy), "plate_x": self.plate_x(self._t),
                "dissipated": self.friction.dissipated(),
                "dissipated_previous": self._slip_work(previous),
                "normal_work": self._sum(self._normal_work),
                "strain_energy": self._sum(self._energy),
                "contact_energy": self._sum(self._contact_energy)}

    def _friction_vector(self) -> np.ndarray:
        """r with r·w = −∫ f·w ds for every w in u's space: the friction's nodal forces on the
        block (owned entries), the traction f of the current state."""
        b = fem.assemble_vector(self._friction_form)
        b.scatter_reverse(la.InsertMode.add)
        return b.array[: self._owned].copy()

    def _slip_work(self, r: np.ndarray | None) -> float:
        """−∫ f_n·Δs_{n+1} ds = r_n·(Δu − Δc): the previous accepted traction f_n (its nodal
        forces r_n) against this step's slip (the plate is flat: Δs = Δu − Δc, tangential by
        the law's f_n)."""
        if r is None:
            return 0.0
        moved = [self.obstacle.x_tip.value - self.friction._previous[0].value[0],
                 self.obstacle.y_tip.value - self.friction._previous[0].value[1]]
        slip = (self.u.x.array - self.friction.u_prev.x.array).reshape(-1, 2) - moved
        return self.msh.comm.allreduce(float(r @ slip.reshape(-1)[: self._owned]), op=MPI.SUM)

    @cached_property
    def _friction_form(self) -> fem.Form:
        return fem.form(self.friction.residual(ufl.TestFunction(self.u.function_space)))

    @cached_property
    def _owned(self) -> int:
        V = self.u.function_space
        return V.dofmap.index_map.size_local * V.dofmap.index_map_bs

    def mean_velocity(self) -> float:
        """The block's mean x-velocity (mm/s): ∫ ρ v_x dX / m, of the accepted state."""
        return self._sum(self._momentum) / self.data.mass

    @cached_property
    def _momentum(self) -> fem.Form:
        return fem.form(self.data.density * self.inertia.v_n[0] * ufl.dx)

    def _sum(self, form: fem.Form) -> float:
        return self.msh.comm.allreduce(fem.assemble_scalar(form), op=MPI.SUM)

    @cached_property
    def _contact_energy(self) -> fem.Form:
        """½ ∫ γ [−g]_+² ds = ½ ∫ p²/γ ds: the penalty's stored energy, whose derivative is its
        force (for Nitsche's law a measure of the penetration only)."""
        return fem.form(0.5 * self.contact.pressure**2 / self.contact.gamma * self.contact.ds)

    @cached_property
    def _normal_work(self) -> fem.Form:
        """∫ p n·(Δu − Δc) ds over the step: the plate is flat (n = e_y) and holds its depth
        during the drag (Δc_y = 0), so ∫ p Δu_y ds; − p Δg, the penetration's share."""
        du = self.u - self.friction.u_prev
        return fem.form(self.contact.pressure * du[1] * self.contact.ds)


def drag_block(data: SlidingBlock, nx: int, ny: int, dt: float, end: float, *,
               rho_inf: float = 1.0, prefix: str = "sliding_") -> list[dict]:
    """Press the block statically, then drag it to `end` (s) in steps of `dt` (s) with the
    Wood–Bossak–Zienkiewicz scheme of spectral radius `rho_inf`; per step after the press:
    time, the block's mean velocity and kinetic energy (after the step) and the diagnostics
    (before it). Raises if a step fails."""
    block = data.build(nx, ny)
    stepper = TimeStepper(block, StepOptions(
        scheme="generalized-alpha", rho_inf=rho_inf, dt_initial=dt, dt_max=dt, dt_min=dt / 64),
        petsc_options={"snes_rtol": 1e-12, "snes_atol": 1e-14, "snes_linesearch_type": "basic"},
        prefix=prefix)
    try:
        _press(block, stepper)
        jumped = data.jump_acceleration and data.ramp == 0
        rows = [{"time": 0.0, "velocity": 0.0, "kinetic": 0.0,
                 **(block.jump() if jumped else block.diagnostics())}]

        def record(report) -> None:
            rows.append({"time": report.time, "velocity": block.mean_velocity(),
                         "kinetic": block.inertia.kinetic_energy(), **report.diagnostics})

        stepper.run(block.plate_x, end, on_step=record)
    finally:
        stepper.close()
    return rows


def _press(block: DraggedBlock, stepper) -> None:
    """The plate pushed in by `depth` in one step so long that the mass term vanishes: the
    static equilibrium; then v = a = 0, the block at rest there."""
    block.dt.value = STATIC_STEP
    block.set_time(0.0)
    reason, _ = stepper.solve_once()
    if reason <= 0:
        raise RuntimeError(f"the static press did not converge (SNES reason {reason})")
    block.accept()
    block.inertia.v_n.x.array[:] = 0.0
    block.inertia.a_n.x.array[:] = 0.0


def energy_balance(rows: list[dict]) -> dict[str, float]:
    """The energy ledger of a `drag_block` run from the pressed state at rest: the plate's work
    (trapezoidal, along x: the plate holds its depth), the changes of the kinetic, strain and
    contact energies, the friction's dissipation, and the error W − ΔK − ΔΨ − ΔΨ_c − D."""
    first, last = rows[0], rows[-1]
    work = sum(0.5 * (a["force_x"] + b["force_x"]) * (b["plate_x"] - a["plate_x"])
               for a, b in zip(rows[:-1], rows[1:]))
    out = {"work": work, "kinetic": last["kinetic"] - first["kinetic"],
           "strain": last["strain_energy"] - first["strain_energy"],
           "contact": last["contact_energy"] - first["contact_energy"],
           "dissipated": sum(r["dissipated"] for r in rows[1:]),
           "dissipated_trapezoidal": sum(0.5 * (r["dissipated"] + r["dissipated_previous"])
                                         for r in rows[1:])}
    stored = sum(out[k] for k in ("kinetic", "strain", "contact"))
    out["error"] = work - stored - out["dissipated"]
    out["error_trapezoidal"] = work - stored - out["dissipated_trapezoidal"]
    return out
