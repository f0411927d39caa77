"""Coulomb friction between rigid indenters and the body's surface, on top of `contact.py`.

Per indenter, with the contact's normal n (from the indenter into the body), pressure
p = [t_n − γ g]_+ and the nominal traction t = P N, the tangential traction the indenter puts
on the body, f, obeys Coulomb's law: |f| ≤ μ p; where |f| < μ p the surface sticks to the
indenter, and where it slips f = −μ p s/|s| opposes the slip s. For any γ > 0 this is
Alart & Curnier's (CMAME 92, 1991) augmented law; in Nitsche's form Chouly (J. Math. Anal.
Appl. 411, 2014, 329–339) for Tresca friction, Mlika, Renard & Chouly (CMAME 325, 2017,
265–288) for Coulomb friction at finite strain; here in the quasi-static incremental form

    f = P_B(μ p)(t_t − γ Δs_t),

P_B(r) the projection onto the ball of radius r (the tangent plane's disc |q| ≤ r), t_t the
tangential part of t, Δs_t = (I − n⊗n)[(u − u_prev) − Δc] the slip increment: the surface
point's displacement since the last accepted step relative to the indenter's (Δc, its
translation over the step). Nitsche's method with θ = 0 (the contact's own default) adds

    − ∫ f·v ds

to the residual, next to the contact's − ∫ p n·v ds. With the penalty law (t_n = 0 in the
contact) there is no traction estimate t_t; its place is taken by the last accepted traction,
γ w_n with w_n = f_n/γ the elastic slip, kept at the nodes of u's space:
f = P_B(μ p)(γ (I − n⊗n) w_n − γ Δs_t), a tangential spring of stiffness γ while sticking (the
elastic slip f/γ accumulates over the steps), Coulomb's bound while slipping. Without w_n (as
the penalty law was first written) the spring forgot its stretch at every step: a held shear
let go of the skin, and the stick force −γ Δs_t was a dashpot of viscosity γ Δt, which vanishes
as Δt → 0 (the test: a block held sheared by a sticking plate keeps its tangential force).
w_{n+1} = f_{n+1}/γ is interpolated at the nodes: f/γ = P_B(μ p/γ)(...) holds no h (p/γ =
[−g]_+ for the penalty), so the interpolation is of a field continuous across the cells.

The slip is an increment over one step (the time-discrete law, the return mapping of an
implicit step): a step ends in `mark_accepted`, which moves u_prev, the indenters' previous
positions and (penalty) the elastic slip. Its state is the last accepted one on either time
route: the dynamic route (inertia.py, α_f = 0) evaluates the contact and the friction at
t_{n+1} exactly as a quasi-static step does, so its slip increment is the same u_{n+1} − u_n
relative to the indenter; a rejected or failed attempt leaves the state untouched. Coulomb friction
with the slip over a step is exact for a monotonic, one-directional load (the
Cattaneo–Mindlin check, benchmarks page) and first order in the step for a reversing one.

μ = 0 for every indenter: build no `CoulombFriction`; the contact's forms are untouched and the
frictionless answers unchanged to the last digit.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cached_property

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from ..errors import InputError
from .contact import NitscheContact, is_conservative

#: |q| below this (MPa) counts as 0 in the projection's division (the stick branch is then
#: taken anyway: only a zero ball r = 0, out of contact, reaches it, and gives f = 0).
_TINY = 1e-300


def friction_coefficients(mu, count: int, where: str = "indenter.friction") -> tuple[float, ...]:
    """μ per indenter: one number for all, or one per indenter; each finite and >= 0."""
    values = list(mu) if isinstance(mu, Sequence) else [mu] * count
    if len(values) != count:
        raise InputError(where, f"{len(values)} friction coefficients for {count} indenters.",
                         "give one μ for all indenters, or one per indenter.")
    for value in values:
        if isinstance(value, bool) or not isinstance(value, int | float) or not (
                np.isfinite(value) and value >= 0):
            raise InputError(where, f"a friction coefficient must be a number >= 0, got "
                             f"{value!r}.",
                             "use 0 (frictionless) or a measured value, typically 0.4-1.")
    return tuple(float(v) for v in values)


def contact_state(pressure, margin) -> np.ndarray:
    """Codes per surface point: 2 stick where the stick margin μp − |q| > 0, else 1 slip
    where the pressure p > 0, else 0 free (a margin > 0 needs p > 0)."""
    return np.where(np.asarray(margin) > 0, 2, np.where(np.asarray(pressure) > 0, 1, 0))


def check_dynamic_contact(method: str, theta: int, inertia: bool, mu, where: str = "") -> None:
    """Refuse friction with inertia on a contact law whose force derives from no potential
    (Nitsche's θ = 0: θ ≠ 0 is refused with friction anyway). Measured on the dragged block
    (studies.problems.SlidingBlock, docs/benchmarks/friction.md): the energy balance did not
    converge with Δt and its error grew at the smallest step, and with a velocity step the
    contact's normal work reached −0.13 of the plate's: it fed energy in. Frictionless
    dynamic runs keep the stepper's warning (stepping/stepper.py)."""
    if not inertia or is_conservative(method, theta) or not any(m > 0 for m in mu):
        return
    raise InputError(
        f"{where}model.contact", f"friction with inertia (model.inertia = true) needs a "
        f"conservative contact law, got {method!r} (model.contact_theta = {theta}), whose "
        "force derives from no potential: on the dragged block it fed energy into the run "
        "(docs/benchmarks/friction.md, \"Friction with inertia\").",
        'use model.contact = "penalty" (with its default model.contact_gamma0 = 10), or '
        "model.inertia = false.")


def project_on_ball(q, radius):
    """P_B(r)(q): q if |q| <= r, else r q/|q| (UFL; q a vector, r >= 0)."""
    norm = ufl.sqrt(ufl.dot(q, q))
    return ufl.conditional(ufl.le(norm, radius), q, radius / ufl.max_value(norm, _TINY) * q)


class CoulombFriction:
    """Coulomb friction for the indenters of `contact`, μ per indenter (module docstring).

    Add `residual(v)` to the contact's; call `mark_accepted()` after every accepted step (it
    runs once here, with the body and the indenters at their start). Measure a step (forces,
    traction, stick margin) before accepting it: they depend on the step's slip. An indenter
    moved along x needs an `x_tip` Constant (`Obstacle.at(..., x_tip=0.0)`), along z (3D) a
    `z_tip`.

    γ_t = `gamma_ratio` × the contact's γ. The method is consistent for any γ_t > 0; the
    contact's γ = γ0 M/h is scaled by the P-wave modulus M, which for nearly incompressible
    tissue is ~50 times the shear modulus G that sets the surface's tangential stiffness:
    G/M brings γ_t to γ0 G/h (on the Cattaneo–Mindlin block, ν = 0.49, a/2.5 elements: 15–28
    Newton iterations per tangential step; with γ_t = γ, 40–45 and a failed line search).
    """

    def __init__(self, contact: NitscheContact, mu, *, gamma_ratio: float = 1.0):
        if contact.method == "nitsche" and contact.theta != 0:
            raise InputError(
                "model.contact_theta", f"friction is written for Nitsche's θ = 0 (or the "
                f"penalty), got θ = {contact.theta}: its traction has no consistency term, and "
                "with θ ≠ 0 the contact's would act on the normal part alone.",
                'use contact_theta = 0, or contact = "penalty" (conservative: the choice with '
                "inertia).")
        self.contact = contact
        self.gamma = gamma_ratio * contact.gamma
        self.mu = friction_coefficients(mu, len(contact.obstacles))
        u = contact.u
        domain = u.function_space.mesh
        gdim = domain.geometry.dim
        self.u_prev = fem.Function(u.function_space, name="u_prev")
        #: Penalty law: the elastic slip w_n = f_n/γ (mm) at the last accepted step (None:
        #: Nitsche's law, whose traction estimate t_t carries the memory).
        self.elastic_slip = (fem.Function(u.function_space, name="elastic_slip")
                             if contact.method == "penalty" else None)
        #: Each indenter's (x, y) (3D: (x, y, z)) at the last accepted step.
        self._previous = [fem.Constant(domain, np.zeros(gdim)) for _ in contact.obstacles]
        #: Where the last accepted step started (its u_prev and the indenters' positions):
        #: its slip, for `accepted`, the state measured after `mark_accepted`.
        self.u_step = fem.Function(u.function_space, name="u_step")
        self._elastic_slip_step = (fem.Function(u.function_space, name="elastic_slip_step")
                                   if self.elastic_slip is not None else None)
        self._step_start = [fem.Constant(domain, np.zeros(gdim)) for _ in contact.obstacles]
        self._forces, self.trial, self._slips = [], [], []
        for i in range(len(contact.obstacles)):
            q, radius, slip = self._trial(i, gdim, self.u_prev, self._previous,
                                          self.elastic_slip)
            self._slips.append(slip)
            self._forces.append(project_on_ball(q, radius))
            self.trial.append(radius - ufl.sqrt(ufl.dot(q, q)))
        nearest = contact._nearest
        #: −f·Δs_t (MPa mm): the work the friction takes from the body per unit surface over
        #: the step, by the nearest indenter (Δs_t its slip increment, f opposing it).
        self.dissipation = -sum(c * ufl.dot(f, s)
                                for c, f, s in zip(nearest, self._forces, self._slips))
        #: The tangential traction f on the body (MPa, nominal), the nearest indenter's.
        self.traction = sum(c * f for c, f in zip(nearest, self._forces))
        #: μ p − |t_t − γ Δs_t| of the nearest indenter: > 0 where the surface sticks, <= 0
        #: where it slips (or is free: there p = 0); its zero level is the stick zone's edge.
        self.stick_margin = sum(c * m for c, m in zip(nearest, self.trial))
        self.mark_accepted()

    @cached_property
    def tangential_traction(self):
        """2D: f·t, the tangential traction's signed size (MPa), t = (n_y, −n_x) the nearest
        indenter's tangent that points along +x under an indenter pressing up (n ≈ e_y): > 0
        where the indenter pulls the surface towards +x."""
        normals, nearest = self.contact._normals, self.contact._nearest
        return sum(c * (f[0] * n[1] - f[1] * n[0])
                   for c, f, n in zip(nearest, self._forces, normals))

    def _trial(self, i: int, gdim: int, u_prev, previous, elastic_slip) -> tuple:
        """Indenter i's q = t_t − γ Δs_t (UFL vector), the ball's radius μ p and the slip
        Δs_t since the state `u_prev` with the indenters at `previous` (penalty: its elastic
        slip `elastic_slip`; None for Nitsche's law)."""
        contact, obstacle = self.contact, self.contact.obstacles[i]
        n = contact._normals[i]
        moved = ufl.as_vector([p - previous[i][k]
                               for k, p in enumerate(_position(obstacle, gdim))])
        tangential = ufl.Identity(gdim) - ufl.outer(n, n)
        slip = tangential * (contact.u - u_prev - moved)
        # the penalty law has no traction estimate (t_n = 0 in the contact): the traction
        # γ w of the state the step starts from in its place
        t_t = (tangential * contact.traction if elastic_slip is None
               else self.gamma * (tangential * elastic_slip))
        return t_t - self.gamma * slip, self.mu[i] * contact._pressures[i], slip

    @cached_property
    def accepted(self) -> tuple:
        """(f, the stick margin) of the last accepted step, as UFL, for measuring after
        `mark_accepted` (a run writes its outputs then): `traction` and `stick_margin` with
        the slip over that step, from where it started (`u_step`, the indenters there and,
        penalty, the elastic slip then). After `mark_accepted` the live `stick_margin` has
        no slip left: it is μp − |f| (penalty), 0 wherever the step slipped."""
        gdim = self.contact.u.function_space.mesh.geometry.dim
        nearest = self.contact._nearest
        trials = [self._trial(i, gdim, self.u_step, self._step_start, self._elastic_slip_step)
                  for i in range(len(self.contact.obstacles))]
        return (sum(c * project_on_ball(q, r) for c, (q, r, _) in zip(nearest, trials)),
                sum(c * (r - ufl.sqrt(ufl.dot(q, q))) for c, (q, r, _) in zip(nearest, trials)))

    def _term(self, i: int, v) -> ufl.Form:
        return -self.contact._nearest[i] * ufl.dot(self._forces[i], v) * self.contact.ds

    def residual(self, v) -> ufl.Form:
        """The friction contribution to the residual: add it to the contact's."""
        return sum(self._term(i, v) for i, mu in enumerate(self.mu) if mu > 0)

    def mark_accepted(self) -> None:
        """The current state becomes the start of the next slip increment (the last one's
        start is kept for `accepted`; penalty: the traction, the elastic slip f/γ, is taken
        before u_prev moves, since f depends on the step's slip)."""
        self.u_step.x.array[:] = self.u_prev.x.array
        for start, previous in zip(self._step_start, self._previous):
            start.value[:] = previous.value
        if self.elastic_slip is not None:
            self._elastic_slip_step.x.array[:] = self.elastic_slip.x.array
            self._slip_now.interpolate(self._slip_expression)
            self.elastic_slip.x.array[:] = self._slip_now.x.array
            self.elastic_slip.x.scatter_forward()
        self.u_prev.x.array[:] = self.contact.u.x.array
        for previous, obstacle in zip(self._previous, self.contact.obstacles):
            previous.value[:] = _position(obstacle, len(previous.value), _value)

    @cached_property
    def _slip_expression(self) -> fem.Expression:
        """f/γ, the elastic slip of the current state, at the nodes of u's space."""
        V = self.contact.u.function_space
        return fem.Expression(self.traction / self.gamma, V.element.interpolation_points)

    @cached_property
    def _slip_now(self) -> fem.Function:
        return fem.Function(self.contact.u.function_space)

    def advance(self) -> None:
        """The time stepper's name for `mark_accepted` (friction is one of its histories)."""
        self.mark_accepted()

    def arrays(self) -> dict[str, np.ndarray]:
        """The live arrays of the last accepted state, by checkpoint name."""
        arrays = {"friction_u_prev": self.u_prev.x.array}
        if self.elastic_slip is not None:
            arrays["friction_elastic_slip"] = self.elastic_slip.x.array
        return arrays | {f"friction_previous_{i}": c.value for i, c in enumerate(self._previous)}

    @cached_property
    def _dissipation_form(self) -> fem.Form:
        return fem.form(self.dissipation * self.contact.ds)

    def dissipated(self) -> float:
        """The energy the friction dissipated over the step (N mm/mm in plane strain, N mm in
        3D): ∫ −f·Δs_t ds over the reference surface. Measure it before `mark_accepted`.
        Where the surface slips, |f| = μp opposes the slip: −f·Δs_t = μp|Δs_t|; where it
        sticks, Δs_t is only the change of the elastic slip, of order |Δf|/γ_t."""
        comm = self.contact.u.function_space.mesh.comm
        return comm.allreduce(fem.assemble_scalar(self._dissipation_form), op=MPI.SUM)

    @cached_property
    def _area_forms(self) -> list[fem.Form]:
        def indicator(positive):
            return ufl.conditional(ufl.gt(positive, 0.0), 1.0, 0.0)
        return [fem.form(indicator(f) * self.contact.ds)
                for f in (self.contact.pressure, self.stick_margin)]

    def areas(self) -> tuple[float, float]:
        """(contact, stick) area: the reference surface where p > 0 and where the stick margin
        is > 0 (mm² in 3D; mm per mm in plane strain), each counted at the surface quadrature
        points (a measure of the active set, to about an element along its edge). Their ratio
        is the stick fraction: 1 while the contact sticks everywhere, 0 in gross slip."""
        comm = self.contact.u.function_space.mesh.comm
        return tuple(comm.allreduce(fem.assemble_scalar(f), op=MPI.SUM)
                     for f in self._area_forms)

    def _translation_forms(self, term) -> list[list[fem.Form]]:
        """[k][i]: −term(i, e_k), indenter i's residual term tested with the rigid translation
        e_k: the force it puts on the body along axis k (as contact._force_forms)."""
        V = self.contact.u.function_space
        bs = V.dofmap.index_map_bs
        forms = []
        for k in range(bs):
            e_k = fem.Function(V)
            e_k.x.array.reshape(-1, bs)[:, k] = 1.0
            forms.append([fem.form(-term(i, e_k)) for i in range(len(self.mu))])
        return forms

    @cached_property
    def _force_forms(self) -> list[list[fem.Form]]:
        # pressure and friction together
        return self._translation_forms(lambda i, e: self.contact._term(i, e) + self._term(i, e))

    def forces(self) -> np.ndarray:
        """(indenters, gdim): the force each indenter exerts on the body, pressure and
        friction (N/mm in plane strain, N in 3D); columns 0 and (3D) 2 are the tangential
        force along x and z."""
        return self._assemble(self._force_forms)

    @cached_property
    def _pressure_forms(self) -> list[list[fem.Form]]:
        return self._translation_forms(self.contact._term)

    def pressure_forces(self) -> np.ndarray:
        """(indenters, gdim): the pressure's share of `forces()`, ∫ p n ds; the rest is the
        friction's, ∫ f ds. On a curved or tilted contact the pressure has a share along x
        (ploughing: the skin heaped ahead of a sliding indenter pushes it back), so in gross
        slip it is the friction's share that is μ times the pressure's normal force, not the
        total tangential force μ times the total normal force."""
        return self._assemble(self._pressure_forms)

    def _assemble(self, forms) -> np.ndarray:
        comm = self.contact.u.function_space.mesh.comm
        local = np.array([[fem.assemble_scalar(f) for f in row] for row in forms])
        return comm.allreduce(local.T.copy(), op=MPI.SUM)


def _position(obstacle, gdim: int, value=lambda c: c) -> list:
    """The indenter's position (x, y[, z]): its tangential offset (`Obstacle.offset`: x_tip,
    z_tip, or along a tilted grating's plane) plus y_tip along y, as Constants (or what
    `value` makes of them); 0.0 along an axis it never moves along."""
    position = obstacle.offset(gdim, value)
    y = value(obstacle.y_tip)
    position[1] = y if isinstance(position[1], float) and position[1] == 0.0 else y + position[1]
    return position


def _value(constant) -> float:
    return float(constant) if isinstance(constant, float) else float(constant.value)
