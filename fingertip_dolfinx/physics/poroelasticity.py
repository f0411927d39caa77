"""Biphasic (solid + fluid) tissue at finite strain: residual terms in pure UFL.

Unknowns u (displacement) and p (pore pressure), reference configuration, backward Euler:

    solid:  ∫ (P_e − p J F⁻ᵀ) : Grad v dX                                       = loads
    fluid:  ∫ (J − J_n) q + Δt J k(J) C⁻¹ Grad p · Grad q dX                    = −Δt ∫ Q·N q

or, with the weights (a₀, a₁, a₂) of a multistep formula for Δt·dJ/dt, the volume change
J − J_n becomes a₀ J + a₁ J_n + a₂ J_{n−1}: (1, −1, 0) is backward Euler, and variable-step
BDF2 with ω = Δt_n/Δt_{n−1} has a₀ = (1 + 2ω)/(1 + ω), a₁ = −(1 + ω), a₂ = ω²/(1 + ω)
(`volume_change`; the time stepper sets the weights, a `fem.Constant`, every step).

The fluid flux is the Piola pull-back of Darcy's law w = −k grad p, W = J F⁻¹ w =
−J k C⁻¹ Grad p, so the mass balance is exact at finite strain (the small-strain balance
div(u̇) − div(k grad p), often paired with a hyperelastic solid, is not). The pressure is the
Lagrange multiplier of the constituents' incompressibility: in the undrained limit (k Δt/L² → 0)
J stays at J_n, which needs an inf-sup stable pair (Taylor–Hood P2/P1).

The functions take the measure `dx` (e.g. `dx(SUBCUTANEOUS_TAG)`) so the solver can assemble
them on a sub-region; no boundary terms are added (impermeable by default: zero flux is the
natural condition; a drained boundary is the Dirichlet condition p = 0).
"""

from __future__ import annotations

import ufl

from .kinematics import deformation_gradient, right_cauchy_green
from .materials import Biphasic, first_piola_kirchhoff, small_strain_p_wave_modulus


def total_first_piola(u, p, material: Biphasic, P_e=None) -> ufl.core.expr.Expr:
    """P = P_e − p J F⁻ᵀ (Cauchy: σ = σ_e − p I). P_e defaults to the solid's hyperfoam stress."""
    F = deformation_gradient(u)
    if P_e is None:
        P_e = first_piola_kirchhoff(material.solid, F)
    return P_e - p * ufl.det(F) * ufl.inv(F).T


def solid_residual(u, p, v, material: Biphasic, dx, P_e=None) -> ufl.Form:
    """Momentum balance of the mixture, ∫ P : Grad v dX."""
    return ufl.inner(total_first_piola(u, p, material, P_e), ufl.grad(v)) * dx


def volume_change(u, u_n, u_nm1=None, weights=None) -> ufl.core.expr.Expr:
    """Δt·dJ/dt at t_{n+1}: J − J_n (backward Euler), or a₀ J + a₁ J_n + a₂ J_{n−1} with the
    `weights` (a₀, a₁, a₂) (a `fem.Constant` of shape (3,)) and the displacement `u_nm1` of
    t_{n−1}. With the weights (1, −1, 0) the two agree to the last bit."""
    J = ufl.det(deformation_gradient(u))
    J_n = ufl.det(deformation_gradient(u_n))
    if weights is None:
        return J - J_n
    J_nm1 = ufl.det(deformation_gradient(u_nm1))
    return weights[0] * J + weights[1] * J_n + weights[2] * J_nm1


def mass_residual(u, p, u_n, q, dt, material: Biphasic, dx, u_nm1=None,
                  weights=None) -> ufl.Form:
    """Δt × (fluid mass balance): ∫ (J − J_n) q + Δt J k(J) C⁻¹ Grad p · Grad q dX, the volume
    change J − J_n by the multistep `weights` if given (`volume_change`)."""
    change = volume_change(u, u_n, u_nm1, weights)
    return (change * q + darcy_flux(u, p, q, material, dt)) * dx


def darcy_flux(u, p, q, material: Biphasic, dt=1.0) -> ufl.core.expr.Expr:
    """Δt J k(J) C⁻¹ Grad p · Grad q = −Δt W · Grad q: the integrand of the fluid volume that
    leaves per unit reference volume over Δt (per unit time for dt = 1), W = −J k C⁻¹ Grad p
    the Piola pull-back of Darcy's w. (The product's order is the residual's of old: the
    quasi-static numbers are unchanged to the last bit.)"""
    F = deformation_gradient(u)
    J = ufl.det(F)
    k = material.permeability.permeability(J)
    Cinv = ufl.inv(right_cauchy_green(F))
    return dt * J * k * ufl.inner(Cinv * ufl.grad(p), ufl.grad(q))


def biphasic_residuals(u, p, u_n, v, q, dt, material: Biphasic, dx, P_e=None, u_nm1=None,
                       weights=None):
    """(solid, fluid) residual forms of one step on the region `dx` (backward Euler, or the
    multistep `weights` with `u_nm1`)."""
    return (solid_residual(u, p, v, material, dx, P_e),
            mass_residual(u, p, u_n, q, dt, material, dx, u_nm1, weights))


def consolidation_time(material: Biphasic, length: float, J: float = 1.0) -> float:
    """Drainage time scale L² / (H_A k) with the small-strain aggregate modulus
    H_A = K0 + 4μ0/3 (plane strain, confined): ~t for p to decay over a distance L (mm)."""
    H = small_strain_p_wave_modulus(material.solid)
    k = float(material.permeability.permeability_np(J))
    return length**2 / (H * k)
