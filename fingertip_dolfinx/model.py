r"""The model of one run: its options, and the law of each region composed from the materials.

`ModelOptions` are the modelling and discretisation choices of a run (a scene's `[model]`
table). `compose_laws(tissues, options, state)` turns the materials data (`tissues.Tissues`)
and the options into one law per region, each a small object with

    stress          P, the first Piola–Kirchhoff stress at the current state, history included
    elastic_stress  P_e, the instantaneous elastic stress (Nitsche's traction estimate)
    energy          W, the region's own strain energy density (the SED output)
    history         internal variables at quadrature points (a QLV region: the skin, and the
                    subcutaneous solid if its set gives a Prony series), or None

and the pore law of the subcutaneous tissue, the pressure part of the problem (problem.py):

    biphasic   ∫ (J − J_n) q + Δt J k(J) C⁻¹ Grad p · Grad q dX = 0      Darcy flow
    undrained  ∫ (J − J_n) q dX = 0                                      no flow: J = J_n
    drained    no pressure unknown (p = 0)

(the biphasic J − J_n is backward Euler's Δt·dJ/dt; under BDF2 the time stepper's weights make
it a₀ J + a₁ J_n + a₂ J_{n−1}).

The laws per `options.tissue`:

    layered     skin: hyperfoam, with QLV if `skin_viscoelastic` and the skin has a Prony series
                subcutaneous: the hyperfoam solid's stress (+ its pore law)
                bone, nail: St Venant–Kirchhoff, or rigid
    continuum   every region: σ = λ tr ε I + 2μ ε, W = ½ σ:ε; no pore law, nothing rigid

A region is rigid when the materials say so (`model = "rigid"`) or, for bone and nail together,
when `options.rigid_bone`; a rigid region has zero stress and zero energy, and the problem
clamps its nodes.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem

from .errors import InputError
from .physics.kinematics import deformation_gradient
from .physics.materials import (
    Biphasic,
    Hyperfoam,
    LinearElastic,
    Prony,
    first_piola_kirchhoff,
    p_wave_modulus,
    second_piola_kirchhoff,
    small_strain_p_wave_modulus,
    strain_energy_density,
)
from .physics.poroelasticity import mass_residual
from .physics.tissues import REGIONS, Rigid, Tissues
from .physics.viscoelasticity import QuasiLinearViscoelasticity
from .validation import number

SUBCUTANEOUS_MODELS = ("biphasic", "undrained", "drained")
TISSUE_MODELS = ("layered", "continuum")


@dataclass(frozen=True)
class ModelOptions:
    """Discretisation and modelling choices of one run (a scene's ``[model]`` table).

    Parameters
    ----------
    displacement_degree : int, optional
        Lagrange degree of the displacement (1, 2 or 3); the pore pressure is one lower
        (Taylor–Hood).
    quadrature_degree : int, optional
        Quadrature degree of the volume integrals and the QLV internal variables.
    skin_viscoelastic : bool, optional
        The skin's QLV history; False: its instantaneous elasticity.
    tissue : str, optional
        ``"layered"`` (four regions, each its law) or ``"continuum"`` (one homogeneous
        small-strain linear-elastic section).
    continuum_E, continuum_nu : float, optional
        Young's modulus (MPa) and Poisson's ratio of the ``"continuum"`` model.
    subcutaneous : str, optional
        ``"biphasic"`` (pore pressure unknown), ``"undrained"`` (no flow) or ``"drained"``
        (the solid alone, p = 0).
    rigid_bone : bool, optional
        Bone and nail rigid and clamped instead of elastic and held at the nail centre.
    contact : str, optional
        ``"nitsche"`` (consistent) or ``"penalty"`` (robust at sharp tips, conservative).
    contact_theta : int, optional
        Nitsche variant: 0, +1 (symmetric) or −1 (skew-symmetric).
    contact_smoothing : float, optional
        Gap width (mm) over which the contact pressure's kink is smoothed (0: exact).
    contact_gamma0 : float, optional
        γ0: the contact stiffness is γ0 (λ + 2μ)/h.
    compaction_margin : float, optional
        A converged state whose subcutaneous J falls below φ0 + margin is rejected.
    inertia : bool, optional
        Add the tissues' inertia (a dynamic run, generalised-α); False: quasi-static.

    Raises
    ------
    InputError
        For an unknown choice or an inconsistent pair (e.g. P1 with a pore pressure).
    """

    #: Lagrange degree of the displacement (1, 2 or 3); the pore pressure is one degree lower
    #: (Taylor–Hood).
    displacement_degree: int = 2
    #: Quadrature degree of the volume integrals (and of the QLV internal variables).
    quadrature_degree: int = 4
    #: Skin history (QLV). False: the skin responds with its instantaneous elasticity.
    skin_viscoelastic: bool = True
    #: "layered": the four regions with their own laws. "continuum": one homogeneous
    #: small-strain linear-elastic section (continuum_E, continuum_nu), the cheapest model.
    tissue: str = "layered"
    continuum_E: float = 2 * 0.579e-3 * 1.4  # MPa: the subcutaneous tissue's small-strain E
    #: Poisson ratio of the "continuum" model.
    continuum_nu: float = 0.4
    #: "biphasic": pore pressure unknown (Taylor–Hood). "undrained": no flow at all, the
    #: tissue is incompressible (J = 1; p its Lagrange multiplier). "drained": the solid alone
    #: (p = 0), the long-time limit.
    subcutaneous: str = "biphasic"
    #: Bone and nail rigid and held (their nodes clamped) instead of elastic and held at the
    #: nail centre.
    rigid_bone: bool = False
    #: "nitsche" (consistent) or "penalty" (robust at sharp tips): see contact.CONTACT_METHODS.
    contact: str = "nitsche"
    #: Nitsche variant: 0 (the default: converges), +1 (symmetric) or −1 (skew-symmetric).
    contact_theta: int = 0
    #: Gap width (mm) over which the contact pressure's kink is smoothed (0: exact).
    contact_smoothing: float = 0.0
    #: Contact parameter γ0: the penalty (or Nitsche) stiffness is γ0 (λ + 2μ)/h.
    contact_gamma0: float = 10.0
    #: A converged state whose subcutaneous J falls below φ0 + margin is rejected.
    compaction_margin: float = 0.02
    #: Inertia ∫ ρ a·w dX in the momentum balance (inertia.py; densities from the materials):
    #: a dynamic run, stepped by the time stepper's "generalized-alpha" scheme. Off: quasi-static.
    inertia: bool = False

    def __post_init__(self):
        self._check_contact_numbers()
        if self.displacement_degree not in (1, 2, 3):
            raise InputError(
                "model.displacement_degree", f"got {self.displacement_degree}.", "use 1, 2 or 3."
            )
        # The stiffness of degree-k elements is a polynomial of degree 2(k − 1) on affine
        # cells: a lower rule under-integrates it (spurious zero-energy modes).
        lowest = max(1, 2 * (self.displacement_degree - 1))
        if not (isinstance(self.quadrature_degree, int) and self.quadrature_degree >= lowest):
            raise InputError(
                "model.quadrature_degree",
                f"got {self.quadrature_degree!r} for displacement degree "
                f"{self.displacement_degree}, whose stiffness needs degree {lowest} or more.",
                f"use an integer >= {lowest} (the 2D scenes use 4, the 3D ones 2).")
        if self.subcutaneous not in SUBCUTANEOUS_MODELS:
            raise InputError(
                "model.subcutaneous", f"unknown model {self.subcutaneous!r}.",
                f"use one of {SUBCUTANEOUS_MODELS}.",
            )
        if self.tissue not in TISSUE_MODELS:
            raise InputError("model.tissue", f"unknown model {self.tissue!r}.",
                             f"use one of {TISSUE_MODELS}.")
        if not (self.continuum_E > 0 and -1 < self.continuum_nu < 0.5):
            raise InputError("model.continuum_E/continuum_nu",
                             f"E = {self.continuum_E}, nu = {self.continuum_nu} is not a stable "
                             "elastic material.", "use E > 0 and -1 < nu < 0.5.")
        if (self.tissue == "layered" and self.subcutaneous != "drained"
                and self.displacement_degree < 2):
            raise InputError(
                "model.displacement_degree",
                f"the {self.subcutaneous} tissue needs Taylor–Hood elements (displacement degree "
                ">= 2): equal-order u/p fails the inf-sup condition in the (nearly) undrained "
                "regime.",
                "use displacement_degree = 2.",
            )

    def _check_contact_numbers(self) -> None:
        """γ0 > 0 (a zero or negative penalty pulls the skin into the indenter), a smoothing
        width >= 0 (mm) and a compaction margin in [0, 1) (J starts at 1 above φ0 + margin)."""
        for key, value, ok, fix in (
                ("contact_gamma0", self.contact_gamma0, lambda x: x > 0,
                 "use a positive γ0 (10, the default; 100 for penalty contact at a sharp tip)."),
                ("contact_smoothing", self.contact_smoothing, lambda x: x >= 0,
                 "use 0 (an exact kink) or a gap width in mm, e.g. 1e-4."),
                ("compaction_margin", self.compaction_margin, lambda x: 0 <= x < 1,
                 "use a margin in [0, 1) above φ0 (0.02, the default).")):
            x = number(f"model.{key}", value)
            if not ok(x):
                raise InputError(f"model.{key}", f"got {x}.", fix)


@dataclass(frozen=True)
class State:
    """What the laws read: the displacement u, F = I + Grad u, the time step (a Constant the
    solver sets), the quadrature degree of the volume integrals and each region's cells (where
    a history is kept)."""

    u: fem.Function
    F: ufl.core.expr.Expr
    dt: fem.Constant
    quadrature_degree: int
    cells: Mapping[str, np.ndarray]
    #: F of a Function sharing u's values that ufl.derivative leaves alone, or None: a 3D
    #: hyperfoam's stress is then built by `materials.second_piola_kirchhoff`'s expansion
    #: (the same values and derivative, a far cheaper Jacobian).
    F_state: ufl.core.expr.Expr | None = None

    @property
    def mesh(self):
        return self.u.function_space.mesh


# --- the region laws ------------------------------------------------------------------------


class Elastic:
    """A hyperelastic region: P = F S(C), S = 2 ∂W/∂C, W(C) its energy (hyperfoam, SVK)."""

    rigid = False
    history = None

    def __init__(self, material: Hyperfoam | LinearElastic, state: State):
        self.material = material
        self.stress = self.elastic_stress = first_piola_kirchhoff(material, state.F,
                                                                  state.F_state)
        self.energy = strain_energy_density(material, state.F)
        self.p_wave_modulus = small_strain_p_wave_modulus(material)


class Viscoelastic:
    """A QLV region: P = F S with S = g∞ S_e + Σ g_i h_i (viscoelasticity.py), S_e = 2 ∂W/∂C.

    `elastic_stress` is the instantaneous F S_e: the QLV history lives at cell quadrature points
    and cannot be evaluated on facets, so the contact's traction estimate uses it. This only
    shifts Nitsche's consistency term: at convergence the gap in contact is (t_n(S_e) − t_n(S))/γ,
    a fraction (strain/γ0) of h; the penetration is reported. `energy` is the elastic W(C), the
    energy the instantaneous response stores (the SED output of the paper).
    """

    rigid = False

    def __init__(self, material: Hyperfoam, prony: Prony, state: State, region: str):
        self.material = material
        S_e = second_piola_kirchhoff(material, state.F, state.F_state)
        self.history = QuasiLinearViscoelasticity(
            S_e, prony, state.mesh, state.quadrature_degree, state.dt, cells=state.cells[region],
            name=history_name(region))
        self.elastic_stress = state.F * S_e
        self.stress = state.F * self.history.stress()
        self.energy = strain_energy_density(material, state.F)
        self.p_wave_modulus = small_strain_p_wave_modulus(material)


def history_name(region: str) -> str:
    """The prefix of a region's QLV internal variables (checkpoint names): "qlv" for the skin
    (the name checkpoints have always used), "qlv_<region>" for any other region."""
    return "qlv" if region == "skin" else f"qlv_{region}"


class SmallStrain:
    """Hooke's law at small strain: σ = λ tr(ε) I + 2μ ε, ε = sym Grad u, W = ½ σ:ε.

    Not invariant under rotation (a rigid rotation strains it): the continuum model, the
    cheapest rung of the fidelity ladder. P = σ: at small strain the stress measures agree.
    """

    rigid = False
    history = None

    def __init__(self, E: float, nu: float, state: State):
        mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
        eps = ufl.sym(ufl.grad(state.u))
        sigma = lmbda * ufl.tr(eps) * ufl.Identity(len(state.u)) + 2 * mu * eps
        self.stress = self.elastic_stress = sigma
        self.energy = 0.5 * ufl.inner(sigma, eps)
        self.p_wave_modulus = p_wave_modulus(E, nu)


class RigidRegion:
    """A region held rigidly (its nodes clamped by the problem): zero stress, zero energy.

    The stress is 0·F, a zero that still depends on u: its derivative keeps the region's dofs
    in the Jacobian's sparsity pattern, where their Dirichlet rows need a diagonal entry.
    Without any integral over the region (first try) the dofs inside the bone had no entry
    and MUMPS failed in the first step (INFOG(1) = -3).
    """

    rigid = True
    history = None

    def __init__(self, state: State):
        zero = fem.Constant(state.mesh, 0.0)  # a Constant: UFL would fold a literal 0 away
        self.stress = self.elastic_stress = zero * state.F
        self.energy = zero


# --- the pore laws (the pressure part) ------------------------------------------------------


class BiphasicFlow:
    """Darcy flow through the solid: ∫ (J − J_n) q + Δt J k(J) C⁻¹ Grad p · Grad q dX, the
    volume change J − J_n by the time stepper's multistep weights (a₀ J + a₁ J_n + a₂ J_{n−1}:
    backward Euler or BDF2, poroelasticity.volume_change)."""

    #: The law has a time derivative (dJ/dt): its history is u_n and u_{n−1}.
    has_rate = True

    def __init__(self, material: Biphasic):
        self.material = material
        self.phi0 = material.phi0

    def residual(self, u, p, u_n, q, dt, dx, u_nm1=None, weights=None) -> ufl.Form:
        return mass_residual(u, p, u_n, q, dt, self.material, dx, u_nm1, weights)


class Undrained:
    """No flow at all: the volume of every piece of tissue is kept, ∫ (J − J_n) q dX = 0.

    Algebraic (J = J_n = 1): exact under any time scheme, so it takes no multistep weights."""

    has_rate = False

    def __init__(self, material: Biphasic):
        self.phi0 = material.phi0

    def residual(self, u, p, u_n, q, dt, dx, u_nm1=None, weights=None) -> ufl.Form:
        J = ufl.det(deformation_gradient(u))
        return (J - ufl.det(deformation_gradient(u_n))) * q * dx


PORE_LAWS = {"biphasic": BiphasicFlow, "undrained": Undrained, "drained": lambda material: None}


# --- composition ----------------------------------------------------------------------------


@dataclass(frozen=True)
class Laws:
    """The law of each region (skin, subcutaneous, bone, nail) and the pore law (or None)."""

    regions: Mapping[str, Elastic | Viscoelastic | SmallStrain | RigidRegion]
    pore: BiphasicFlow | Undrained | None = None

    def rigid_regions(self) -> tuple[str, ...]:
        return tuple(name for name, law in self.regions.items() if law.rigid)

    def with_history(self) -> list:
        """The distinct laws that keep a history (a law shared by regions counts once)."""
        laws = {id(law): law for law in self.regions.values() if law.history is not None}
        return list(laws.values())

    def history_arrays(self) -> dict[str, np.ndarray]:
        """The internal variables by their checkpoint names: qlv_h{i}, qlv_S_e_n (the skin),
        qlv_<region>_h{i}, qlv_<region>_S_e_n (any other region: model.history_name)."""
        arrays = {}
        for law in self.with_history():
            names = law.history.arrays()
            if set(names) & set(arrays):  # a guard: history_name gives each region its own
                raise InputError("model", f"two QLV histories share the names {sorted(names)}.",
                                 "give each viscoelastic region its own history_name.")
            arrays.update(names)
        return arrays


def compose_laws(tissues: Tissues, options: ModelOptions, state: State) -> Laws:
    """The regions' laws from the materials data and the options."""
    return COMPOSERS[options.tissue](tissues, options, state)


def _layered(tissues: Tissues, options: ModelOptions, state: State) -> Laws:
    if options.rigid_bone:
        tissues = dataclasses.replace(tissues, bone=Rigid("model.rigid_bone"),
                                      nail=Rigid("model.rigid_bone"))
    return Laws(
        regions={
            "skin": _skin_law(tissues, options, state),
            "subcutaneous": _subcutaneous_law(tissues, state),
            "bone": _solid_law(tissues.bone, state),
            "nail": _solid_law(tissues.nail, state),
        },
        pore=PORE_LAWS[options.subcutaneous](tissues.subcutaneous),
    )


def _continuum(tissues: Tissues, options: ModelOptions, state: State) -> Laws:
    """One law for the whole section: the materials and the pore model play no part."""
    law = SmallStrain(options.continuum_E, options.continuum_nu, state)
    return Laws(regions=dict.fromkeys(REGIONS, law))


COMPOSERS = {"layered": _layered, "continuum": _continuum}


def _skin_law(tissues: Tissues, options: ModelOptions, state: State) -> Elastic | Viscoelastic:
    if options.skin_viscoelastic and tissues.skin_prony is not None:
        return Viscoelastic(tissues.skin, tissues.skin_prony, state, "skin")
    return Elastic(tissues.skin, state)


def _subcutaneous_law(tissues: Tissues, state: State) -> Elastic | Viscoelastic:
    """The subcutaneous solid's law: QLV on its hyperfoam stress if the set gives it a Prony
    series (under every pore model: the pore pressure adds to the solid's stress)."""
    if tissues.subcutaneous_prony is not None:
        return Viscoelastic(tissues.subcutaneous.solid, tissues.subcutaneous_prony, state,
                            "subcutaneous")
    return Elastic(tissues.subcutaneous.solid, state)


def _solid_law(material: LinearElastic | Rigid, state: State) -> Elastic | RigidRegion:
    if isinstance(material, Rigid):
        return RigidRegion(state)
    return Elastic(material, state)
