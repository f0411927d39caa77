"""Terzaghi's consolidation column: the drained-top column under a sudden load, its exact pore
pressure and settlement after any time t (Terzaghi's series) and after one backward-Euler step."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from ...physics import materials as mat
from .block import ConfinedBlock, confined_modulus


@dataclass(frozen=True)
class Terzaghi:
    """One-dimensional consolidation: a biphasic layer 0 ≤ y ≤ H under a sudden load σ0 on its
    top, drained there (p = 0), impermeable at the bottom, confined at the sides.

    The permeability is constant (Holmes–Mow with κ = M = 0) and set to k = c/M (M the confined
    modulus of `solid`), so the consolidation coefficient is c (mm²/s); the load is `strain` × M,
    which keeps the finite-strain code in its small-strain limit (linear Biot theory). Exact:
    p solves ∂p/∂t = c ∂²p/∂y², p(y, 0) = σ0, p(H, t) = 0, ∂p/∂y(0, t) = 0 (Terzaghi 1923;
    e.g. Verruijt, Theory and Problems of Poroelasticity, ch. 2), and the settlement is σ0 H/M
    times the degree of consolidation.
    """

    solid: mat.Hyperfoam = mat.SUBCUTANEOUS
    c: float = 1.0  # mm²/s: with H = 1 mm the time factor c t/H² is t
    H: float = 1.0  # mm
    strain: float = 1e-5

    @property
    def M(self) -> float:
        return confined_modulus(self.solid)

    @property
    def sigma0(self) -> float:
        """The load (MPa)."""
        return self.strain * self.M

    @property
    def tissue(self) -> mat.Biphasic:
        return mat.Biphasic(self.solid, mat.HolmesMow(k0=self.c / self.M, phi0=0.4, kappa=0.0,
                                                      M=0.0))

    def column(self, ny: int, *, degree_u: int = 2, comm=MPI.COMM_SELF) -> ConfinedBlock:
        """A column 0.1 mm wide (one cell across), ny cells high."""
        return ConfinedBlock(1, ny, lambda t: self.sigma0, tissue=self.tissue, degree_u=degree_u,
                             width=0.1, H=self.H, drained_top=True, comm=comm)

    def series(self, y, t: float, terms: int = 200) -> tuple[np.ndarray, float]:
        """p(y, t) (MPa) and the settlement at t (mm), from Terzaghi's Fourier series:
        p = Σ 2σ0/m_k sin(m_k (H − y)/H) exp(−m_k² T), m_k = (2k + 1)π/2, T = c t/H²."""
        m = np.arange(terms)
        Mm = np.pi * (2 * m + 1) / 2
        T = self.c * t / self.H**2
        Z = (self.H - np.asarray(y))[:, None] / self.H
        p = (2 * self.sigma0 / Mm * np.sin(Mm * Z) * np.exp(-(Mm**2) * T)).sum(axis=1)
        degree = 1 - (2 / Mm**2 * np.exp(-(Mm**2) * T)).sum()
        return p, self.sigma0 * self.H / self.M * degree

    def one_step_pressure(self, z, dt: float) -> np.ndarray:
        """Exact p (MPa) after one backward-Euler step Δt from rest, continuous in space:
        p − c Δt p'' = σ0, p(H) = 0, p'(0) = 0 ⇒ p = σ0 (1 − cosh(z/ℓ)/cosh(H/ℓ)), ℓ = sqrt(cΔt).
        Never above σ0 and monotone: any overshoot is the discretisation's."""
        ell = math.sqrt(self.c * dt)
        z = np.asarray(z, dtype=float)
        H = self.H
        ratio = np.exp((z - H) / ell) * (1 + np.exp(-2 * z / ell)) / (1 + np.exp(-2 * H / ell))
        return self.sigma0 * (1 - ratio)

    def one_step_settlement(self, dt: float) -> float:
        """The settlement (mm) after that step: ∫ (σ0 − p)/M dz = σ0 ℓ tanh(H/ℓ)/M."""
        ell = math.sqrt(self.c * dt)
        return self.sigma0 / self.M * ell * math.tanh(self.H / ell)
