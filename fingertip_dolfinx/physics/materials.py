"""Constitutive laws as small frozen dataclasses; energies in UFL, stresses by differentiation.

Each material validates its parameters on construction (an `InputError` names the parameter
and the fix) and provides `strain_energy(C)` for a 2×2 (plane strain, λ3 = 1) or 3×3 right
Cauchy–Green tensor. Stresses follow from the energy, never from hand-derived formulas:
S = 2 ∂W/∂C (`second_piola_kirchhoff`), P = F S, σ = F S Fᵀ / J. The numpy counterparts
(principal Kirchhoff stresses, permeability) are independent closed forms for checks.

Units: mm, N, s; stresses and moduli in MPa; permeability in mm⁴/(N·s).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import MISSING, dataclass, field, fields

import numpy as np
import ufl

from ..errors import CompactionError, InputError
from ..validation import check_keys
from .kinematics import (
    eigen_sum,
    eigen_sum_of_invariants,
    invariants_3d,
    right_cauchy_green,
)

# --------------------------------------------------------------------------------------------
# validation helpers


#: Stiffer than any solid (MPa): diamond's Young's modulus is about 1.05e6 MPa (1.05 TPa). A
#: modulus above it is a value in Pa (1 MPa = 1e6 Pa; the bone's 17 GPa in Pa is 1.7e10).
STIFFEST_SOLID = 1e6
#: Stiffer in shear than any soft tissue (MPa): tendon, the stiffest, has a Young's modulus of
#: about 1.2 GPa (Maganaris and Paul, J. Physiol. 521 (1999) 307-313), a shear modulus of
#: about 400 MPa (nearly incompressible). The paper's skin has mu0 = 1.16e-3 MPa, which in Pa
#: is 1160: a hyperfoam (a soft tissue's law) with mu0 above this was given in Pa.
STIFFEST_SOFT_TISSUE = 1e3


def _not_in_pa(where: str, what: str, value: float, limit: float, than: str) -> None:
    if value > limit:
        raise InputError(where, f"{what} = {value:.6g} MPa is stiffer than {than} ({limit:g} "
                         "MPa): a value in Pa?", "give moduli in MPa (1 MPa = 1e6 Pa).")


def _floats(where: str, name: str, value) -> tuple[float, ...]:
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence | np.ndarray):
        raise InputError(where, f"'{name}' must be a list of numbers, got {value!r}.",
                         f"write {name} = [...], one number per term.")
    try:
        out = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise InputError(where, f"'{name}' must be a list of numbers, got {value!r}.") from None
    if not out:
        raise InputError(where, f"'{name}' is empty.", "give at least one term.")
    if not all(math.isfinite(v) for v in out):
        raise InputError(where, f"'{name}' = {out} contains a non-finite value.")
    return out


def _float(where: str, name: str, value) -> float:
    if isinstance(value, bool):
        raise InputError(where, f"'{name}' must be a number, got {value!r}.")
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise InputError(where, f"'{name}' must be a number, got {value!r}.") from None
    if not math.isfinite(out):
        raise InputError(where, f"'{name}' = {value!r} is not finite.")
    return out


def _from_dict(cls, data: Mapping, where: str):
    """Build `cls` from a TOML table: unknown or missing keys are errors that list the keys
    (the package's one key checker); the values are then validated by `cls` itself."""
    params = [f for f in fields(cls) if f.init and f.name != "where"]
    check_keys(where, data, [f.name for f in params],
               required=[f.name for f in params if f.default is MISSING], what="parameter")
    return cls(**dict(data), where=where)


# --------------------------------------------------------------------------------------------
# hyperfoam (compressible Ogden, ABAQUS *HYPERFOAM)

#: Below this |β| (ν within ±0.01) the volume term (J^(−αβ) − 1)/β = (e^x − 1)/β, x = −αβ ln J,
#: is built as 2 sinh(x/2) e^(x/2)/β (see `_volume_term`). The closed form subtracts two
#: numbers ≈ 1: absolute error ~eps/|β| (times 2μ/α²), which grows without bound as β → 0;
#: at |β| ≥ 0.01 it is at most 100 eps, and the paper's β = 2 keeps its expression unchanged.
BETA_SMALL = 1e-2


def _poisson_ratios(where: str, value, n_terms: int) -> float | tuple[float, ...]:
    """ν as given: one number (every term) or a list with one value per term (ABAQUS's ν_i)."""
    if isinstance(value, Sequence | np.ndarray) and not isinstance(value, (str, bytes)):
        nu = _floats(where, "nu", value)
        if len(nu) != n_terms:
            raise InputError(where, f"'nu' has {len(nu)} values but 'mu' has {n_terms} terms.",
                             "give one nu for all terms, or one nu_i per term.")
        values = nu
    else:
        nu = _float(where, "nu", value)
        values = (nu,)
    bad = [v for v in values if not -1.0 < v < 0.5]
    if bad:
        which = f"{nu} is" if len(values) == 1 else f"{nu}: the value(s) {bad} are"
        raise InputError(where, f"'nu' = {which} outside (-1, 0.5).",
                         "use -1 < nu < 0.5 (0.5 would be incompressible).")
    return nu


def _volume_term(detC, alpha: float, beta: float) -> ufl.core.expr.Expr:
    """(J^(−αβ) − 1)/β, the volumetric part of one hyperfoam term, for a float β.

    J is taken from det C (J^p = det(C)^(p/2), ln J = ln(det C)/2) so W stays a function of C.
    β = 0 (ν = 0, ABAQUS's default and FEBio's 'Ogden unconstrained'): the limit −α ln J,
    exactly. 0 < |β| < BETA_SMALL: e^x − 1 = 2 sinh(x/2) e^(x/2) with x = −αβ ln J is exact
    and has no cancellation (sinh of a small argument is computed to full relative precision),
    so the term is accurate for any tiny β, and tends to −α ln J. (A truncated series in x
    would need |x| bounded, i.e. J bounded; this needs nothing.) Otherwise the closed form.
    The branch is on the float β when the form is built: nothing is decided (or divided by
    zero) at run time.
    """
    if beta == 0.0:
        return -alpha * (0.5 * ufl.ln(detC))
    if abs(beta) < BETA_SMALL:
        half_x = -alpha * beta / 4.0 * ufl.ln(detC)  # x/2 = −αβ ln J/2 = −αβ ln(det C)/4
        return 2.0 * ufl.sinh(half_x) * ufl.exp(half_x) / beta
    return (detC ** (-alpha * beta / 2.0) - 1.0) / beta


@dataclass(frozen=True)
class Hyperfoam:
    """The compressible Ogden foam of ABAQUS (``*HYPERFOAM``), Storåkers' form.

    W = Σ_i 2μ_i/α_i² [λ1^α_i + λ2^α_i + λ3^α_i − 3 + (J^(−α_i β_i) − 1)/β_i],
    β_i = ν_i/(1 − 2ν_i). ν_i = 0 is allowed: the volume term is then its limit −α_i ln J,
    built exactly (no 0/0). Individual μ_i may be negative (the paper's fits have one); what
    small-strain stability needs is μ0 = Σμ_i > 0 and K0 = Σ 2μ_i(1/3 + β_i) > 0, which is what
    is required here. Large-strain stability is the business of `drucker.drucker_check`.

    Parameters
    ----------
    mu : tuple of float
        The moduli μ_i (MPa).
    alpha : tuple of float
        The exponents α_i, one per μ_i.
    nu : float or tuple of float
        One Poisson ratio for every term (the paper; kept as the float given) or one per term
        (ABAQUS's ν_i; kept as a tuple); `betas` gives β_i per term either way.
    where : str, optional
        Where the values came from, for messages.

    Raises
    ------
    InputError
        If the lengths differ or μ0, K0 are not positive.
    """

    mu: tuple[float, ...]  # MPa
    alpha: tuple[float, ...]
    nu: float | tuple[float, ...]
    where: str = field(default="hyperfoam", compare=False, repr=False)

    def __post_init__(self):
        w = self.where
        mu = _floats(w, "mu", self.mu)
        alpha = _floats(w, "alpha", self.alpha)
        if len(mu) != len(alpha):
            raise InputError(
                w, f"'mu' has {len(mu)} terms but 'alpha' has {len(alpha)}.",
                "give one exponent alpha_i for each modulus mu_i.",
            )
        if any(a == 0.0 for a in alpha):
            raise InputError(w, f"'alpha' = {alpha} contains 0 (W divides by α_i²).",
                             "use nonzero exponents.")
        nu = _poisson_ratios(w, self.nu, len(mu))
        object.__setattr__(self, "mu", mu)
        object.__setattr__(self, "alpha", alpha)
        object.__setattr__(self, "nu", nu)
        if not self.mu0 > 0.0:
            raise InputError(
                w, f"initial shear modulus mu0 = sum(mu) = {self.mu0:.6g} MPa is not positive: "
                "the material is unstable at small strain.", "check the signs of 'mu'.")
        _not_in_pa(w, "initial shear modulus mu0 = sum(mu)", self.mu0, STIFFEST_SOFT_TISSUE,
                   "any soft tissue")
        # One ν: K0 = 2μ0(1 + ν)/(3(1 − 2ν)) > 0 follows from μ0 > 0. Per-term ν_i: it does
        # not (a negative μ_i with a large β_i can make it negative), so it is checked.
        if not self.K0 > 0.0:
            raise InputError(
                w, f"initial bulk modulus K0 = sum(2 mu_i (1/3 + beta_i)) = {self.K0:.6g} MPa "
                "is not positive: the material is unstable in volume at small strain.",
                "check 'mu' and 'nu' (a large nu_i on a negative mu_i lowers K0).")

    @classmethod
    def from_dict(cls, data: Mapping, where: str = "hyperfoam") -> Hyperfoam:
        return _from_dict(cls, data, where)

    @property
    def nus(self) -> tuple[float, ...]:
        """ν_i, one per term (the single ν repeated if one was given)."""
        return self.nu if isinstance(self.nu, tuple) else (self.nu,) * len(self.mu)

    @property
    def betas(self) -> tuple[float, ...]:
        """β_i = ν_i/(1 − 2ν_i), one per term."""
        return tuple(n / (1.0 - 2.0 * n) for n in self.nus)

    @property
    def beta(self) -> float:
        """The common β = ν/(1 − 2ν); an error if the terms have different ν_i (use `betas`)."""
        betas = set(self.betas)
        if len(betas) != 1:
            raise InputError(self.where, f"'nu' = {self.nu} differs per term: there is no "
                             "single beta.", "use the per-term 'betas'.")
        return betas.pop()

    @property
    def mu0(self) -> float:
        """Initial shear modulus Σμ_i (MPa)."""
        return float(sum(self.mu))

    @property
    def K0(self) -> float:
        """Initial bulk modulus Σ 2μ_i (1/3 + β_i) (MPa)."""
        return float(sum(2.0 * m * (1.0 / 3.0 + b) for m, b in zip(self.mu, self.betas)))

    @property
    def lame_lambda0(self) -> float:
        """Initial Lamé λ = K0 − 2μ0/3 = Σ 2μ_iβ_i (the plane-strain small-strain stiffness),
        summed directly: exactly 0 at ν = 0, where K0 − 2μ0/3 would leave round-off."""
        return float(sum(2.0 * m * b for m, b in zip(self.mu, self.betas)))

    @property
    def nu0(self) -> float:
        """Small-strain Poisson ratio (3K0 − 2μ0)/(2(3K0 + μ0)): ν itself if one was given."""
        if not isinstance(self.nu, tuple):
            return self.nu
        return (3 * self.K0 - 2 * self.mu0) / (2 * (3 * self.K0 + self.mu0))

    def strain_energy(self, C) -> ufl.core.expr.Expr:
        """W(C) for a 2×2 C (plane strain, λ3 = 1 inside) or a 3×3 C."""
        W = eigen_sum(C, self._stretch_part)
        lam3_alpha = 1.0 if C.ufl_shape[0] == 2 else 0.0  # plane strain: λ3^α = 1 (3D: inside)
        return W + self._volume_part(ufl.det(C), lam3_alpha)  # J from det C: W a function of C

    def invariants(self, C) -> tuple:
        """(m, q, d, det C) of a 3×3 C: W is a function of these alone
        (`energy_of_invariants`, `second_piola_kirchhoff`'s expansion)."""
        return (*invariants_3d(C), ufl.det(C))

    def energy_of_invariants(self, m, q, d, detC) -> ufl.core.expr.Expr:
        """W of a 3×3 C from its `invariants`: `strain_energy`'s sums, term for term."""
        return eigen_sum_of_invariants(m, q, d, self._stretch_part) + self._volume_part(detC)

    def _terms(self) -> list[tuple[float, float]]:
        """(k_i, α_i) with k_i = 2μ_i/α_i²."""
        return [(2.0 * m / a**2, a) for m, a in zip(self.mu, self.alpha)]

    def _stretch_part(self, c):
        """Σ_i k_i λ^α_i with λ^α = c^(α/2) at an eigenvalue c of C: one eigen_sum for all
        terms."""
        return sum(k * c ** (a / 2.0) for k, a in self._terms())

    def _volume_part(self, detC, lam3_alpha: float = 0.0) -> ufl.core.expr.Expr:
        """Σ_i k_i (λ3^α_i − 3 + the volume term of det C); λ3^α = 1 in plane strain, 0 in 3D
        (where λ3 is inside the eigen_sum)."""
        return sum(k * (lam3_alpha - 3.0 + _volume_term(detC, a, b))
                   for (k, a), b in zip(self._terms(), self.betas))

    # ---- numpy closed forms (checks, stability) --------------------------------------------
    def principal_kirchhoff(self, stretches) -> np.ndarray:
        """τ_a = Σ_i (2μ_i/α_i)(λ_a^α_i − J^(−α_i β_i)); stretches (..., 3) -> (..., 3), MPa.
        (β_i = 0: J^0 = 1 exactly)."""
        lam = np.asarray(stretches, dtype=float)
        J = np.prod(lam, axis=-1)[..., None, None]
        mu, al, b = np.asarray(self.mu), np.asarray(self.alpha), np.asarray(self.betas)
        return np.sum(2 * mu / al * (lam[..., None] ** al - J ** (-al * b)), axis=-1)

    def principal_energy(self, stretches) -> np.ndarray:
        """W from principal stretches (..., 3); the volume term as expm1(−αβ ln J)/β, or
        −α ln J where β = 0 (both exact to round-off for every β)."""
        lam = np.asarray(stretches, dtype=float)
        ln_J = np.log(np.prod(lam, axis=-1))[..., None]
        mu, al, b = np.asarray(self.mu), np.asarray(self.alpha), np.asarray(self.betas)
        s = np.sum(lam[..., None] ** al, axis=-2)
        b_safe = np.where(b == 0.0, 1.0, b)
        volume = np.where(b == 0.0, -al * ln_J, np.expm1(-al * b * ln_J) / b_safe)
        return np.sum(2 * mu / al**2 * (s - 3 + volume), -1)


# --------------------------------------------------------------------------------------------
# linear elastic (bone, nail)


@dataclass(frozen=True)
class LinearElastic:
    """Linear elastic in the St Venant–Kirchhoff form W = λ/2 (tr E)² + μ tr(E²).

    Bone and nail are ~10⁵ times stiffer than the tissue: they strain little but the nail
    region can rotate. Small-strain Hooke's law is not invariant under rotation (a rigid
    rotation would produce stress); SVK uses the Green–Lagrange strain, so it is, and it
    reduces to Hooke's law at small strain — which is all the paper's "linear elastic" asks.
    Plane strain: the 2×2 E is the in-plane part (E33 = 0).

    Parameters
    ----------
    E : float
        Young's modulus (MPa), positive.
    nu : float
        Poisson's ratio, in (−1, 0.5).
    where : str, optional
        Where the values came from, for messages.
    """

    E: float  # MPa
    nu: float
    where: str = field(default="linear elastic", compare=False, repr=False)

    def __post_init__(self):
        E, nu = _float(self.where, "E", self.E), _float(self.where, "nu", self.nu)
        if not E > 0:
            raise InputError(self.where, f"Young's modulus 'E' = {E} MPa is not positive.")
        _not_in_pa(self.where, "Young's modulus 'E'", E, STIFFEST_SOLID, "any solid")
        if not -1.0 < nu < 0.5:
            raise InputError(self.where, f"'nu' = {nu} is outside (-1, 0.5).")
        object.__setattr__(self, "E", E)
        object.__setattr__(self, "nu", nu)

    @classmethod
    def from_dict(cls, data: Mapping, where: str = "linear elastic") -> LinearElastic:
        return _from_dict(cls, data, where)

    @property
    def mu(self) -> float:
        return self.E / (2 * (1 + self.nu))

    @property
    def lmbda(self) -> float:
        return self.E * self.nu / ((1 + self.nu) * (1 - 2 * self.nu))

    def strain_energy(self, C) -> ufl.core.expr.Expr:
        E = 0.5 * (C - ufl.Identity(C.ufl_shape[0]))
        return 0.5 * self.lmbda * ufl.tr(E) ** 2 + self.mu * ufl.inner(E, E)


def p_wave_modulus(E, nu):
    """λ + 2μ = E (1 − ν) / ((1 + ν)(1 − 2ν)): the stiffness of a laterally confined push."""
    return E * (1 - nu) / ((1 + nu) * (1 - 2 * nu))


def small_strain_p_wave_modulus(material: Hyperfoam | LinearElastic) -> float:
    """λ0 + 2μ0, the stiffness of a laterally confined push at small strain (MPa): the
    contact's stiffness scale, and the aggregate modulus H_A (or M) of consolidation: with a
    permeability k, c = k H_A (mm²/s) is the consolidation coefficient and L²/c the drainage
    time of a layer L.

    Hyperfoam: K0 + 4μ0/3, which holds in plane strain as in 3D and needs no single ν. For the
    paper's skin it is 6.96e-3 MPa, 1 ulp (2.5e-16) above E(1 − ν)/((1 + ν)(1 − 2ν)) with
    E = 2μ0(1 + ν), used before; through γ that moved the 1pt scene's forces by 2e-12
    (Nitsche) and 8e-12 (penalty, γ0 = 100) relative: Newton's converged iterate, not the
    solution, carries the rounding.
    """
    if isinstance(material, LinearElastic):
        return material.lmbda + 2.0 * material.mu
    return material.K0 + 4.0 * material.mu0 / 3.0


# --------------------------------------------------------------------------------------------
# stresses from any material with strain_energy(C)


def second_piola_kirchhoff(material, F, F_state=None) -> ufl.core.expr.Expr:
    """S = 2 ∂W/∂C at C = FᵀF (symmetric: the energies use symmetric functions of C).

    `F_state`: F of a displacement Function that shares its values with F's (`fem.Function(V,
    x=u.x)`) but that ufl.derivative does not differentiate; given, a 3D hyperfoam's S is
    `_expanded_stress`'s, the same values and the same derivative at a much cheaper tangent.
    """
    if F_state is not None and F.ufl_shape == (3, 3) and hasattr(material, "invariants"):
        return _expanded_stress(material, F, F_state)
    C = ufl.variable(right_cauchy_green(F))
    return 2.0 * ufl.diff(material.strain_energy(C), C)


def _expanded_stress(material, F, F_state) -> ufl.core.expr.Expr:
    """S of a 3D hyperfoam, expanded in W's invariants about the state: same values, same
    derivative, a Jacobian kernel a fifth as long.

    W = G(a(C)) with a = (m, q, d, det C) (`Hyperfoam.invariants`). With ā = a(C̄),
    C̄ = F_stateᵀF_state, S = 2 ∂W̃/∂C of the second-order Taylor expansion

        W̃(C) = G(ā) + Σ_i G_i(ā)(a_i − ā_i) + ½ Σ_ij G_ij(ā)(a_i − ā_i)(a_j − ā_j).

    F_state has F's values, so a − ā = 0: S̃ = 2 Σ_i G_i ∂a_i/∂C = S, and its derivative in u
    (ufl.derivative sees F, not F_state) is 2 Σ_i [G_i ∂²a_i/∂C² + Σ_j G_ij ∂a_i/∂C ⊗ ∂a_j/∂C]
    : dC, the exact tangent. Why: from S = 2 ∂W/∂C UFL differentiates W (its eigenvalue sum's
    three branches, each with its series: FFCx evaluates every branch) in C's 9 directions and
    the Jacobian again in 9; here G only in the 4 invariants' directions, once and twice, and
    the argument enters through the polynomials a(C) alone. The 3D line load's Jacobian
    kernel: 74 000 → 13 500 lines of C, 55 → 21 µs per cell (docs/benchmarks/solvers-3d.md,
    "The Jacobian's assembly"). Not for a second derivative (ū would be held fixed).
    """
    C = ufl.variable(right_cauchy_green(F))
    a = material.invariants(C)
    a0 = [ufl.variable(x) for x in material.invariants(right_cauchy_green(F_state))]
    G = material.energy_of_invariants(*a0)
    G1 = [ufl.diff(G, x) for x in a0]
    da = [x - x0 for x, x0 in zip(a, a0)]
    W = sum(g * dx for g, dx in zip(G1, da))
    for i, g in enumerate(G1):
        W += sum((0.5 if j == i else 1.0) * ufl.diff(g, a0[j]) * da[i] * da[j]
                 for j in range(i, len(a0)))
    return 2.0 * ufl.diff(W, C)


def first_piola_kirchhoff(material, F, F_state=None) -> ufl.core.expr.Expr:
    return F * second_piola_kirchhoff(material, F, F_state)


def cauchy_stress(material, F) -> ufl.core.expr.Expr:
    """σ = F S Fᵀ / J; for a 2×2 F this is the in-plane part of the plane-strain stress."""
    return F * second_piola_kirchhoff(material, F) * F.T / ufl.det(F)


def strain_energy_density(material, F) -> ufl.core.expr.Expr:
    return material.strain_energy(right_cauchy_green(F))


# --------------------------------------------------------------------------------------------
# Prony series (quasi-linear viscoelasticity)


@dataclass(frozen=True)
class Prony:
    """Relaxation function g(t) = 1 − Σ g_i (1 − exp(−t/τ_i)) = g∞ + Σ g_i exp(−t/τ_i).

    g∞ = 1 − Σ g_i is the long-term ratio. Applied to the second Piola–Kirchhoff stress
    (quasi-linear viscoelasticity, `viscoelasticity.py`).

    Parameters
    ----------
    g : tuple of float
        The ratios g_i, each in (0, 1), their sum below 1.
    tau : tuple of float
        The relaxation times τ_i (s), one per ratio.
    where : str, optional
        Where the values came from, for messages.
    """

    g: tuple[float, ...]
    tau: tuple[float, ...]  # s
    where: str = field(default="prony", compare=False, repr=False)

    def __post_init__(self):
        g = _floats(self.where, "g", self.g)
        tau = _floats(self.where, "tau", self.tau)
        if len(g) != len(tau):
            raise InputError(self.where, f"'g' has {len(g)} terms but 'tau' has {len(tau)}.",
                             "give one relaxation time per ratio.")
        if any(gi <= 0 for gi in g):
            raise InputError(self.where, f"'g' = {g}: every ratio must be > 0.",
                             "drop terms with g_i = 0.")
        if not sum(g) < 1:
            raise InputError(self.where, f"sum(g) = {sum(g):.6g} is not < 1: the long-term "
                             "modulus would vanish or be negative.", "reduce the ratios g_i.")
        if any(t <= 0 for t in tau):
            raise InputError(self.where, f"'tau' = {tau}: relaxation times must be > 0 s.")
        object.__setattr__(self, "g", g)
        object.__setattr__(self, "tau", tau)

    @classmethod
    def from_dict(cls, data: Mapping, where: str = "prony") -> Prony:
        return _from_dict(cls, data, where)

    @property
    def g_inf(self) -> float:
        """Long-term ratio 1 − Σg_i."""
        return 1.0 - float(sum(self.g))

    def relaxation(self, t) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        return self.g_inf + sum(gi * np.exp(-t / ti) for gi, ti in zip(self.g, self.tau))


# --------------------------------------------------------------------------------------------
# Holmes–Mow permeability and the biphasic tissue


@dataclass(frozen=True)
class HolmesMow:
    """Holmes–Mow permeability k(J) = k0 ((J − φ0)/(1 − φ0))^κ exp(M (J² − 1)/2).

    Undefined for J ≤ φ0: the pores are closed (compaction).

    Parameters
    ----------
    k0 : float
        The permeability of the undeformed tissue (mm⁴/(N·s)).
    phi0 : float
        The solid volume fraction, in (0, 1).
    kappa : float
        The exponent of the porosity term.
    M : float
        The exponent of the exponential stiffening.
    where : str, optional
        Where the values came from, for messages.
    """

    k0: float  # mm⁴/(N·s)
    phi0: float  # solid volume fraction in the reference state
    kappa: float
    M: float
    where: str = field(default="Holmes-Mow permeability", compare=False, repr=False)

    def __post_init__(self):
        vals = {k: _float(self.where, k, getattr(self, k)) for k in ("k0", "phi0", "kappa", "M")}
        if not vals["k0"] > 0:
            raise InputError(self.where, f"'k0' = {vals['k0']} is not positive (mm^4/(N s)).")
        if not 0 < vals["phi0"] < 1:
            raise InputError(self.where, f"'phi0' = {vals['phi0']} is not in (0, 1).",
                             "phi0 is the solid volume fraction, 1/(1 + e0).")
        if vals["kappa"] < 0 or vals["M"] < 0:
            raise InputError(self.where, f"'kappa' = {vals['kappa']}, 'M' = {vals['M']}: "
                             "both must be >= 0 (permeability must fall under compression).")
        for k, v in vals.items():
            object.__setattr__(self, k, v)

    @classmethod
    def from_dict(cls, data: Mapping, where: str = "Holmes-Mow permeability") -> HolmesMow:
        return _from_dict(cls, data, where)

    def permeability(self, J) -> ufl.core.expr.Expr:
        return (self.k0 * ((J - self.phi0) / (1 - self.phi0)) ** self.kappa
                * ufl.exp(self.M * (J**2 - 1) / 2))

    def permeability_np(self, J) -> np.ndarray:
        J = np.asarray(J, dtype=float)
        base = np.clip((J - self.phi0) / (1 - self.phi0), 0.0, None)
        return self.k0 * base**self.kappa * np.exp(self.M * (J**2 - 1) / 2)


@dataclass(frozen=True)
class ConstantPermeability:
    """A deformation-independent permeability k(J) = k0 (small strains, or a reference case).

    Parameters
    ----------
    k0 : float
        The permeability (mm⁴/(N·s)).
    where : str, optional
        Where the value came from, for messages.
    """

    k0: float  # mm⁴/(N·s)
    where: str = field(default="constant permeability", compare=False, repr=False)

    def __post_init__(self):
        k0 = _float(self.where, "k0", self.k0)
        if not k0 > 0:
            raise InputError(self.where, f"'k0' = {k0} is not positive (mm^4/(N s)).")
        object.__setattr__(self, "k0", k0)

    @classmethod
    def from_dict(cls, data: Mapping, where: str = "constant permeability"):
        return _from_dict(cls, data, where)

    def permeability(self, J) -> ufl.core.expr.Expr:
        return self.k0 + 0.0 * J

    def permeability_np(self, J) -> np.ndarray:
        return np.full_like(np.asarray(J, dtype=float), self.k0)


@dataclass(frozen=True)
class Biphasic:
    """A hyperfoam solid and an inviscid fluid, with a permeability law (the subcutaneous tissue).

    J may not fall to the solid volume fraction φ0: the pores would be closed.

    Parameters
    ----------
    solid : Hyperfoam
        The solid's drained elastic law.
    permeability : HolmesMow or ConstantPermeability
        The permeability law.
    phi0 : float or None, optional
        The solid volume fraction; None: the permeability law's own (Holmes–Mow carries one). If
        both are given they must agree.
    where : str, optional
        Where the values came from, for messages.
    """

    solid: Hyperfoam
    permeability: HolmesMow | ConstantPermeability
    phi0: float | None = None
    where: str = field(default="biphasic", compare=False, repr=False)

    def __post_init__(self):
        own = getattr(self.permeability, "phi0", None)
        phi0 = own if self.phi0 is None else _float(self.where, "phi0", self.phi0)
        if phi0 is None:
            raise InputError(self.where, "the solid volume fraction 'phi0' is missing.",
                             "give phi0 = 1/(1 + e0), e.g. 0.4.")
        if not 0 < phi0 < 1:
            raise InputError(self.where, f"'phi0' = {phi0} is not in (0, 1).",
                             "phi0 is the solid volume fraction, 1/(1 + e0).")
        if own is not None and own != phi0:
            raise InputError(self.where, f"'phi0' = {phi0} differs from the permeability "
                             f"law's phi0 = {own}.", "give one value.")
        object.__setattr__(self, "phi0", phi0)


def check_compaction(J_min: float, where: str, phi0: float, margin: float = 0.0) -> None:
    """Raise CompactionError if the smallest volume ratio reached the solid fraction φ0.

    `where` names the location (region, point). At J = φ0 all pores are closed and the
    permeability (and the mixture) is undefined. A physical limit: the fix is in the load or
    the tissue, not in the time step. (The time stepper's own check, with the time and the
    place, is `admissibility.Admissibility.compacted`.)
    """
    if not J_min > phi0 + margin:
        raise CompactionError(
            f"{where}: compaction: the volume ratio J reached {J_min:.4g}, at or below the solid "
            f"volume fraction phi0 = {phi0:g}{f' (+ margin {margin:g})' if margin else ''}: the "
            "porous solid cannot be compressed beyond its solid volume. Fix: load more slowly "
            "or less deeply, or check the permeability parameters; smaller time steps cannot "
            "help.")


# --------------------------------------------------------------------------------------------
# the paper's parameter sets (Wu et al. 2004, table of material parameters)

SKIN = Hyperfoam(mu=(-7.594e-2, 1.138e-2, 6.572e-2), alpha=(4.941, 6.425, 4.712), nu=0.40,
                 where="skin")
SUBCUTANEOUS = Hyperfoam(mu=(-4.895e-2, 9.889e-3, 3.964e-2), alpha=(5.511, 6.571, 5.262),
                         nu=0.40, where="subcutaneous")
SKIN_PRONY = Prony(g=(0.148, 0.252), tau=(2.123, 9.371), where="skin prony")
HOLMES_MOW_SUBCUTANEOUS = HolmesMow(k0=1e-3, phi0=0.4, kappa=0.0848, M=4.638,
                                    where="subcutaneous permeability")
SUBCUTANEOUS_BIPHASIC = Biphasic(SUBCUTANEOUS, HOLMES_MOW_SUBCUTANEOUS)
BONE = LinearElastic(E=17000.0, nu=0.3, where="bone")
NAIL = LinearElastic(E=170.0, nu=0.3, where="nail")
