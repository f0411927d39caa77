"""Drucker stability of a hyperfoam parameter set (numpy), as ABAQUS checks fitted foams.

Drucker's postulate dτ : dε > 0 (Kirchhoff stress τ, logarithmic strain ε) for every
admissible strain increment. In the principal axes of an isotropic material this splits into

1. coaxial increments: D_ab = ∂τ_a/∂ε_b, ε_b = ln λ_b, must be positive definite. For the
   hyperfoam, τ_a = Σ (2μ_i/α_i)(λ_a^α_i − J^(−α_i β_i)) and ∂ ln J/∂ε_b = 1, so
   D = diag(d_a) + v 11ᵀ with d_a = Σ 2μ_i λ_a^α_i and v = Σ 2μ_i β_i J^(−α_i β_i)
   (a term with ν_i = 0 has no volume stiffness of its own: its v-part is 0).
   Plane strain admits only in-plane increments (dε3 = 0): the 2×2 block a, b ∈ {1, 2} at
   λ3 = 1. 3D: the full 3×3.
2. shear increments in each principal plane (a, b): (τ_a − τ_b)/(ε_a − ε_b) > 0 (the
   Baker–Ericksen inequality; its limit at λ_a = λ_b is D_aa − D_ab). Plane strain: (1, 2).

Numerics: at strong compression v reaches ~1e9·d (J^(−α β) with αβ ≈ 10), so a floating-point
eigen-solver on D loses the small eigenvalue to round-off (it reports false instabilities
near λ ≈ 0.3). The test here uses Sylvester's leading minors of diag(d) + v 11ᵀ written out
(d1 + v, d1 d2 + v(d1 + d2), ...), which have no cancellation unless the state really is
marginal, and the shear moduli with the J-terms cancelled analytically.

Finding for the paper's sets (Wu et al. 2004): d_a > 0 for every stretch and v > 0 for every
J (the extreme exponents carry positive μ_i), so both conditions hold everywhere: by this
definition neither set loses stability on the grid [0.2, 2]² (plane strain) or along the
ABAQUS test paths. MODEL.md's "first loss near λ1 = λ2 ≈ 0.40 / 0.45" is not reproduced
by this (or, as far as checked, any standard) definition.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError, MaterialInstabilityError
from .materials import Hyperfoam


def coaxial_tangent_parts(material: Hyperfoam, stretches) -> tuple[np.ndarray, np.ndarray]:
    """(d, v) with D = diag(d) + v 11ᵀ = ∂τ/∂(ln λ); stretches (..., 3)."""
    lam = np.asarray(stretches, dtype=float)
    mu, al, b = np.asarray(material.mu), np.asarray(material.alpha), np.asarray(material.betas)
    J = np.prod(lam, axis=-1)
    d = np.sum(2 * mu * lam[..., None] ** al, axis=-1)
    v = np.sum(2 * mu * b * J[..., None] ** (-al * b), axis=-1)
    return d, v


def principal_shear_moduli(material: Hyperfoam, stretches, pairs) -> np.ndarray:
    """(τ_a − τ_b)/(ε_a − ε_b) for each pair; the J-terms of τ cancel exactly, and
    (λ_a^α − λ_b^α)/(ε_a − ε_b) = α λ_b^α expm1(x)/x, x = α(ε_a − ε_b), has no 0/0."""
    lam = np.asarray(stretches, dtype=float)
    mu, al = np.asarray(material.mu), np.asarray(material.alpha)
    out = []
    for a, b in pairs:
        x = al * (np.log(lam[..., a]) - np.log(lam[..., b]))[..., None]
        safe = np.where(x == 0.0, 1.0, x)
        ratio = np.where(x == 0.0, 1.0, np.expm1(safe) / safe)
        out.append(np.sum(2 * mu * lam[..., b, None] ** al * ratio, axis=-1))
    return np.stack(out, axis=-1)


def is_stable(material: Hyperfoam, stretches, plane_strain: bool = True) -> np.ndarray:
    """Drucker condition at each state. stretches (..., 2) in plane strain (λ3 = 1 added)
    or (..., 3) in 3D. Returns a boolean array of the batch shape."""
    lam = np.asarray(stretches, dtype=float)
    if np.any(lam <= 0):
        raise InputError("stability check", "principal stretches must be positive.")
    if plane_strain:
        if lam.shape[-1] != 2:
            raise InputError("stability check", f"plane strain needs (λ1, λ2), got {lam.shape}.")
        lam = np.concatenate([lam, np.ones(lam.shape[:-1] + (1,))], axis=-1)
    elif lam.shape[-1] != 3:
        raise InputError("stability check", f"3D needs (λ1, λ2, λ3), got {lam.shape}.")
    d, v = coaxial_tangent_parts(material, lam)
    d1, d2, d3 = d[..., 0], d[..., 1], d[..., 2]
    ok = (d1 + v > 0) & (d1 * d2 + v * (d1 + d2) > 0)
    pairs = [(0, 1)]
    if not plane_strain:
        ok &= d1 * d2 * d3 + v * (d1 * d2 + d1 * d3 + d2 * d3) > 0
        pairs = [(0, 1), (0, 2), (1, 2)]
    ok &= np.all(principal_shear_moduli(material, lam, pairs) > 0, axis=-1)
    return ok


#: Homogeneous test paths, one letter per principal axis: 's' the stretch parameter, 't' a free
#: axis (zero stress), '1' held. Plane strain lists the in-plane axes (λ3 = 1 is added later).
PATHS_PLANE = {"equibiaxial": "ss", "uniaxial": "st"}
PATHS_3D = {"equibiaxial": "sst", "uniaxial": "stt", "planar": "s1t", "volumetric": "sss"}


def _free_stretch(material: Hyperfoam, s: np.ndarray, n_s: int, n_f: int) -> np.ndarray:
    """Stretch t of the n_f free axes where their stress τ_f = Σ(2μ_i/α_i)(t^α_i − J^(−α_iβ_i))
    vanishes, J = s^n_s t^n_f.

    One β: t = J^(−β) zeroes every term at once, i.e. t = s^(−β n_s/(1 + n_f β)). Per-term β_i:
    no closed form; Newton in ln t, continued outwards from s = 1 (t = 1) through the sorted s,
    with ∂τ_f/∂ ln t = d_f + n_f v (the coaxial tangent). Where it cannot be followed (that
    slope ≤ 0, which is itself a Drucker failure, or no convergence) t is NaN, and `is_stable`
    reports NaN states unstable."""
    betas = material.betas
    if n_f == 0:  # no free axis
        return np.ones_like(s)
    if len(set(betas)) == 1:
        return s ** (-betas[0] * n_s / (1 + n_f * betas[0]))
    mu, al, b = np.asarray(material.mu), np.asarray(material.alpha), np.asarray(betas)
    log_s = np.log(s)
    log_t = np.full(s.shape, np.nan)
    for side in (log_s < 0, log_s >= 0):
        x = 0.0
        for i in np.flatnonzero(side)[np.argsort(np.abs(log_s[side]))]:
            x = _newton_free(mu, al, b, n_s * log_s[i], n_f, x)
            if not np.isfinite(x):
                break  # lost the path: the rest of this side stays NaN
            log_t[i] = x
    return np.exp(log_t)


def _newton_free(mu, al, b, n_s_log_s: float, n_f: int, x: float) -> float:
    """Newton for τ_f(x = ln t) = 0 from x; converged when the step is below 1e-12 or the
    residual is at round-off of its largest term; NaN if the slope is not positive."""
    for _ in range(50):
        stretch = np.exp(al * x)  # t^α_i
        vol = np.exp(-al * b * (n_s_log_s + n_f * x))  # J^(−α_i β_i)
        tau = np.sum(2 * mu / al * (stretch - vol))
        slope = np.sum(2 * mu * (stretch + n_f * b * vol))
        if not slope > 0:
            return np.nan
        step = tau / slope
        x -= step
        if abs(step) < 1e-12 or abs(tau) <= 1e-14 * np.sum(np.abs(2 * mu / al) * (stretch + vol)):
            return x
    return np.nan


def loading_paths(material: Hyperfoam, plane_strain: bool) -> dict:
    """Test paths: name -> (s ↦ principal stretches), the free axes' stresses zero."""
    def path(axes: str):
        def stretches(s):
            s = np.asarray(s, dtype=float)
            t = _free_stretch(material, s, axes.count("s"), axes.count("t"))
            values = {"s": s, "t": t, "1": np.ones_like(s)}
            return np.stack([values[a] for a in axes], -1)
        return stretches

    return {name: path(axes)
            for name, axes in (PATHS_PLANE if plane_strain else PATHS_3D).items()}


@dataclass(frozen=True)
class DruckerResult:
    """Outcome of `drucker_check`; `first_unstable[path] = (compression, tension)` gives the
    first stretch (walking away from 1) where the condition fails, or None within range."""

    material: Hyperfoam
    plane_strain: bool
    stretch_range: tuple[float, float]
    grid: np.ndarray = field(repr=False)  # 1D stretch values of each grid axis
    stable: np.ndarray = field(repr=False)  # boolean, one axis per in-plane/3D stretch
    first_unstable: dict

    @property
    def stable_everywhere(self) -> bool:
        return bool(self.stable.all())

    def describe(self) -> str:
        kind = "plane strain" if self.plane_strain else "3D"
        lo, hi = self.stretch_range
        lines = [f"Drucker check ({kind}) of {self.material.where}, stretches in [{lo}, {hi}]:",
                 f"  stable on {self.stable.mean():.1%} of the grid"]
        for path, (c, t) in self.first_unstable.items():
            def fmt(x):
                return "stable" if x is None else f"{x:.3f}"
            lines.append(f"  {path}: compression {fmt(c)}, tension {fmt(t)}")
        return "\n".join(lines)

    def check_state(self, stretches, where: str, mode: str = "warn") -> bool:
        return check_state(self.material, stretches, where, mode, self.plane_strain)


def drucker_check(material: Hyperfoam, plane_strain: bool = True,
                  stretch_range: tuple[float, float] = (0.2, 2.0),
                  grid_points: int | None = None, path_step: float = 1e-3) -> DruckerResult:
    """Check a parameter set on a grid of principal stretches and along the test paths.

    grid_points per axis defaults to 181 (plane strain) or 41 (3D, a 41³ grid); the path
    thresholds are found to `path_step` independently of the grid."""
    if grid_points is None:
        grid_points = 181 if plane_strain else 41
    lo, hi = map(float, stretch_range)
    if not 0 < lo < 1 < hi:
        raise InputError("stability check", f"stretch_range {stretch_range} must satisfy "
                         "0 < low < 1 < high.")
    axis = np.linspace(lo, hi, grid_points)
    mesh = np.meshgrid(*([axis] * (2 if plane_strain else 3)), indexing="ij")
    stable = is_stable(material, np.stack(mesh, -1), plane_strain)

    first = {}
    down = np.arange(1.0, lo - 1e-12, -path_step)[1:]
    up = np.arange(1.0, hi + 1e-12, path_step)[1:]
    for name, path in loading_paths(material, plane_strain).items():
        found = []
        for s in (down, up):
            ok = is_stable(material, path(s), plane_strain)
            found.append(float(s[np.argmin(ok)]) if not ok.all() else None)
        first[name] = tuple(found)
    return DruckerResult(material, plane_strain, (lo, hi), axis, stable, first)


def check_state(material: Hyperfoam, stretches, where: str, mode: str = "warn",
                plane_strain: bool = True) -> bool:
    """Check computed states (e.g. principal stretches at quadrature points of a region).

    Returns True if all are stable; otherwise warns (mode="warn") or raises
    MaterialInstabilityError (mode="error") naming the worst offending stretches.
    """
    if mode not in ("warn", "error"):
        raise InputError("stability check", f"mode = {mode!r}.", "use 'warn' or 'error'.")
    lam = np.asarray(stretches, dtype=float)
    ok = is_stable(material, lam, plane_strain)
    if ok.all():
        return True
    bad = lam[~ok]
    worst = bad[np.argmax(np.abs(np.log(bad)).sum(-1))]
    message = (f"{where}: {bad.shape[0]} of {ok.size} states of {material.where} violate the "
               f"Drucker condition (most strained: stretches {np.round(worst, 4).tolist()}); "
               "the hyperfoam fit is not valid there and the solution may not be unique. "
               "Fix: reduce the indentation or use a parameter set stable over this range.")
    if mode == "error":
        raise MaterialInstabilityError(message)
    warnings.warn(message, RuntimeWarning, stacklevel=2)
    return False
