"""Finite-strain kinematics in UFL: F, C, J, E, spectral functions of C exact at C = I.

Ogden-type energies need principal stretches, whose closed-form expressions contain
sqrt(Δ) with Δ = 0 at every isotropic state (in particular at u = 0): the value is fine but
the derivative is 0/0. Energies only ever need *symmetric* sums Σ_a f(c_a), and such a sum is
a smooth function of C. `eigen_sum` evaluates it with the closed form away from Δ = 0 and with
its Taylor series in Δ (a polynomial in C, so exact derivatives of every order) near Δ = 0.
Nothing is regularised: no epsilon is added anywhere (an epsilon inside the sqrt gives a
finite but wrong tangent at u = 0, by a factor ~2, see tests/test_kinematics.py).

Plane strain: 2×2 tensors, the out-of-plane stretch λ3 = 1 is put in by the material laws.
3D: 3×3 tensors; the 3×3 sum is exact also at a double eigenvalue (uniaxial, equibiaxial,
confined compression), see `_eigen_sum_3d`.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import ufl

#: Switch to the Taylor series when Δ < tol·m² (2D) or tr(D²) < tol·m² (3D). At 1e-4 the
#: dropped terms (Δ⁴ and beyond) and the cancellation in the closed form's second derivative
#: (~eps·(m/s)³, weighted by Δ/m²) are both ≈1e-14 relative: the tangent is continuous across
#: the switch to that level (measured in the tests).
SWITCH_TOL = 1e-4

ScalarFn = Callable[[ufl.core.expr.Expr], ufl.core.expr.Expr]


def deformation_gradient(u) -> ufl.core.expr.Expr:
    """F = I + Grad u (reference configuration; 2D fields give the in-plane 2×2 part)."""
    d = len(u.ufl_shape) and u.ufl_shape[0]
    return ufl.Identity(d) + ufl.grad(u)


def right_cauchy_green(F) -> ufl.core.expr.Expr:
    return F.T * F


def left_cauchy_green(F) -> ufl.core.expr.Expr:
    return F * F.T


def jacobian(F) -> ufl.core.expr.Expr:
    """J = det F (in plane strain λ3 = 1, so the 2×2 determinant is the volume ratio)."""
    return ufl.det(F)


def _derivatives(f: ScalarFn, m, order: int) -> list:
    """[f(m), f'(m), ..., f^(order)(m)] as UFL, by symbolic differentiation of f."""
    mv = ufl.variable(m)
    out = [f(mv)]
    for _ in range(order):
        out.append(ufl.diff(out[-1], mv))
    return out


def _split_2d(C):
    """Mean m = tr C/2 and squared half-split Δ = ((C11 − C22)/2)² + C12 C21 of a 2×2 C.

    C12·C21 rather than C12² keeps ∂Δ/∂C symmetric, so stresses from ufl.diff are symmetric.
    """
    m = 0.5 * (C[0, 0] + C[1, 1])
    delta = (0.5 * (C[0, 0] - C[1, 1])) ** 2 + C[0, 1] * C[1, 0]
    return m, delta


def _near_isotropic_2d(C, tol: float):
    m, delta = _split_2d(C)
    near = ufl.lt(delta, tol * m**2)
    # Both branches of a conditional are evaluated: give the closed form a Δ bounded away
    # from 0 so the branch not taken cannot produce inf/NaN derivatives.
    s = ufl.sqrt(ufl.conditional(near, tol * m**2, delta))
    return m, delta, s, near


def eigen_sum(C, f: ScalarFn, tol: float = SWITCH_TOL) -> ufl.core.expr.Expr:
    """Σ_a f(c_a) over the eigenvalues c_a of a symmetric 2×2 (or 3×3) C, smooth at C = I.

    2D: c± = m ± s, s = sqrt(Δ). f(m+s) + f(m−s) is even in s, i.e. a series in Δ = s²:
    2f(m) + f''(m)Δ + f⁗(m)Δ²/12 + f⁽⁶⁾(m)Δ³/360 + ..., used for Δ < tol·m².
    f must map a UFL scalar to a UFL scalar and be differentiable six times (c ↦ c^p is).
    """
    if C.ufl_shape == (3, 3):
        return _eigen_sum_3d(C, f, tol)
    if C.ufl_shape != (2, 2):
        raise ValueError(f"eigen_sum needs a 2×2 or 3×3 tensor, got shape {C.ufl_shape}")
    m, delta, s, near = _near_isotropic_2d(C, tol)
    f0, _, f2, _, f4, _, f6 = _derivatives(f, m, 6)
    series = 2 * f0 + f2 * delta + f4 * delta**2 / 12 + f6 * delta**3 / 360
    closed = f(m + s) + f(m - s)
    return ufl.conditional(near, series, closed)


def isotropic_tensor_function(C, f: ScalarFn, tol: float = SWITCH_TOL) -> ufl.core.expr.Expr:
    """f(C) = Σ_a f(c_a) n_a⊗n_a for a symmetric 2×2 C (e.g. ln C), smooth at C = I.

    Sylvester's formula: f(C) = ½(f(c+) + f(c−)) I + (f(c+) − f(c−))/(2s) (C − m I).
    Both coefficients are even in s; the second one's series is f' + f'''Δ/6 + f⁽⁵⁾Δ²/120.
    """
    if C.ufl_shape != (2, 2):
        raise ValueError(f"isotropic_tensor_function needs a 2×2 tensor, got {C.ufl_shape}")
    m, delta, s, near = _near_isotropic_2d(C, tol)
    f0, f1, f2, f3, f4, f5, f6 = _derivatives(f, m, 6)
    mean = ufl.conditional(
        near, f0 + f2 * delta / 2 + f4 * delta**2 / 24 + f6 * delta**3 / 720,
        0.5 * (f(m + s) + f(m - s)),
    )
    slope = ufl.conditional(
        near, f1 + f3 * delta / 6 + f5 * delta**2 / 120, (f(m + s) - f(m - s)) / (2 * s)
    )
    I = ufl.Identity(2)  # noqa: E741 (the identity tensor, as in the equations)
    return mean * I + slope * (C - m * I)


def principal_values_2d(C) -> tuple:
    """(c_max, c_min) of a symmetric 2×2 tensor. Values only: not for differentiation."""
    m, delta = _split_2d(C)
    s = ufl.sqrt(ufl.max_value(delta, 0.0))
    return m + s, m - s


def hencky_strain(F, spatial: bool = True) -> ufl.core.expr.Expr:
    """Logarithmic strain: ½ ln b (spatial, global x/y axes, ABAQUS 'LE') or ½ ln C.

    In plane strain the out-of-plane log strain is ln λ3 = 0; this is the in-plane 2×2 part.
    """
    B = left_cauchy_green(F) if spatial else right_cauchy_green(F)
    return 0.5 * isotropic_tensor_function(B, ufl.ln)


def principal_values_3d(C) -> tuple:
    """(c_max, c_min) of a symmetric 3×3 tensor by Cardano's formula. Values only: not for
    differentiation (r is clamped to [−1, 1] and C ∝ I gives r = 0: both exact values)."""
    m = ufl.tr(C) / 3
    D = C - m * ufl.Identity(3)
    q = ufl.inner(D, D)
    isotropic = ufl.le(q, 1e-30 * m**2)
    p = ufl.sqrt(ufl.conditional(isotropic, m**2, q) / 6)
    r = ufl.conditional(isotropic, 0.0, ufl.det(D / p) / 2)
    phi = ufl.acos(ufl.max_value(ufl.min_value(r, 1.0), -1.0)) / 3
    p = ufl.conditional(isotropic, 0.0, p)
    return m + 2 * p * ufl.cos(phi), m + 2 * p * ufl.cos(phi + 2 * math.pi / 3)


def principal_log_strains(F) -> tuple:
    """(max, min) principal logarithmic strains ½ ln c (values, for outputs): in-plane for a
    2×2 F (plane strain), over all three directions for a 3×3 F."""
    C = right_cauchy_green(F)
    c_max, c_min = principal_values_3d(C) if C.ufl_shape == (3, 3) else principal_values_2d(C)
    return 0.5 * ufl.ln(c_max), 0.5 * ufl.ln(c_min)


#: |r| above which `_eigen_sum_3d` leaves the trigonometric (Cardano) form for the pair
#: series. Below it d acos(r)/dr = −1/sqrt(1 − r²) is at most 2.3: no cancellation.
PAIR_SWITCH = 0.9
#: Terms of the series of 1 − cos(acos(1 − t)/3) in t: its radius of convergence is 2, so at
#: t ≤ 1 − PAIR_SWITCH = 0.1 the terms fall by ~20 per order and 16 leave < 1e-20.
PAIR_TERMS = 16


def _one_minus_g_coefficients(n: int) -> list:
    """Coefficients a_1..a_n of e(t) = 1 − g, g = cos(acos(1 − t)/3), as exact fractions.

    g solves the Chebyshev identity 4g³ − 3g = r = 1 − t, i.e. 9e − 12e² + 4e³ = t; the
    implicit function theorem (d/dg (4g³ − 3g) = 9 at g = 1) makes e analytic in t. The
    fixed point e = (t + 12e² − 4e³)/9 on truncated power series gains one order per pass.
    """
    from fractions import Fraction

    def mul(a, b):
        out = [Fraction(0)] * (n + 1)
        for i, ai in enumerate(a):
            if ai:
                for j in range(n + 1 - i):
                    out[i + j] += ai * b[j]
        return out

    e = [Fraction(0)] * (n + 1)
    for _ in range(n + 1):
        e2 = mul(e, e)
        e3 = mul(e2, e)
        e = [(int(k == 1) + 12 * e2[k] - 4 * e3[k]) / 9 for k in range(n + 1)]
    return [float(c) for c in e[1:]]


_E_COEFFICIENTS = _one_minus_g_coefficients(PAIR_TERMS)


def _one_minus_g(t):
    """e(t) = 1 − cos(acos(1 − t)/3) by its power series (Horner): a polynomial, so exact
    derivatives of every order at t = 0, where the acos form has 1/sqrt(0)."""
    out = 0.0
    for c in reversed(_E_COEFFICIENTS):
        out = (out + c) * t
    return out


def _pair_sum(f: ScalarFn, x, delta, tol: float):
    """f(x + s) + f(x − s), s² = Δ: the 2D even sum (series in Δ for Δ < tol·x²)."""
    near = ufl.lt(delta, tol * x**2)
    s = ufl.sqrt(ufl.conditional(near, tol * x**2, delta))
    f0, _, f2, _, f4, _, f6 = _derivatives(f, x, 6)
    series = 2 * f0 + f2 * delta + f4 * delta**2 / 12 + f6 * delta**3 / 360
    return ufl.conditional(near, series, f(x + s) + f(x - s))


def invariants_3d(C) -> tuple:
    """(m, q, d) of a symmetric 3×3 C: m = tr C/3, q = tr(D²) and d = det D of its deviator
    D = C − mI. Σ_a f(c_a) is a function of these three alone (`eigen_sum_of_invariants`)."""
    m = ufl.tr(C) / 3
    D = C - m * ufl.Identity(3)
    return m, ufl.inner(D, D), ufl.det(D)


def eigen_sum_of_invariants(m, q, d, f: ScalarFn, tol: float = SWITCH_TOL):
    """Σ_a f(c_a) as `eigen_sum` of a 3×3 C gives it, from its invariants (`invariants_3d`)
    alone: the same three regions and formulas, with tr(Dᵏ) of the traceless D from q and d
    (Cayley–Hamilton: tr D³ = 3d, tr D⁴ = q²/2, tr D⁵ = 5qd/2, tr D⁶ = q³/4 + 3d²) and
    r = det(D/p)/2 = d/(2p³). Equal to `eigen_sum` to round-off; a function of three scalars,
    whose derivatives UFL takes in three directions instead of C's nine."""
    near = ufl.lt(q, tol * m**2)
    fd = _derivatives(f, m, 6)
    powers = [None, None, q, 3 * d, q**2 / 2, 2.5 * q * d, q**3 / 4 + 3 * d**2]
    series = 3 * fd[0] + sum(fd[k] * powers[k] / math.factorial(k) for k in range(2, 7))
    p = ufl.sqrt(ufl.conditional(near, tol * m**2, q) / 6)
    r = d / (2 * p**3)
    return ufl.conditional(near, series, _off_isotropic(m, p, r, f, tol))


def _off_isotropic(m, p, r, f: ScalarFn, tol: float):
    """Σ_a f(c_a) away from C ∝ I, from m, p and r (`_eigen_sum_3d`): Cardano's form for
    |r| < PAIR_SWITCH, the pair series around a double eigenvalue beyond."""
    paired = ufl.ge(abs(r), PAIR_SWITCH)
    # Each branch gets an r inside its own range, so the branch not taken stays finite.
    r_trig = ufl.max_value(ufl.min_value(r, PAIR_SWITCH), -PAIR_SWITCH)
    phi = ufl.acos(r_trig) / 3
    closed = sum(f(m + 2 * p * ufl.cos(phi + 2 * math.pi * k / 3)) for k in range(3))

    sigma = ufl.conditional(ufl.ge(r, 0.0), 1.0, -1.0)
    # Round-off can put |r| a hair above 1: t < 0 by ~1e-16 is inside the series' range, and
    # no clamp there (a clamp would drop the t-derivatives the tangent needs).
    t = ufl.min_value(1.0 - sigma * r, 1.0 - PAIR_SWITCH)
    e = _one_minus_g(t)
    g = 1.0 - e
    pair = (f(m + 2 * sigma * p * g)
            + _pair_sum(f, m - sigma * p * g, 3 * p**2 * e * (2.0 - e), tol))
    return ufl.conditional(paired, pair, closed)


def _eigen_sum_3d(C, f: ScalarFn, tol: float):
    """3×3 version, exact (value and derivatives) at every state, in three regions.

    With m = tr C/3, D = C − mI, p = sqrt(tr(D²)/6), r = det(D/p)/2 ∈ [−1, 1] and
    φ = acos(r)/3, the eigenvalues are m + 2p cos(φ + 2πk/3) (Cardano).

    - C ∝ I (tr(D²) < tol·m², covers C = I): Σ_a f(m + d_a) = 3f(m) + Σ_k f⁽ᵏ⁾(m) tr(Dᵏ)/k!,
      a polynomial in C.
    - |r| < PAIR_SWITCH: the Cardano form (acos's derivative is bounded there).
    - |r| ≥ PAIR_SWITCH, around a double eigenvalue (r = ±1: uniaxial, equibiaxial, confined
      compression C = diag(1, λ², 1)): with σ = sign r, t = 1 − |r|, g = cos φ = 1 − e(t),
      the simple eigenvalue is m + 2σ p g and the other two are x ± s with x = m − σ p g and
      s² = 3p²(1 − g²) = 3p² e (2 − e). e(t) is a power series (`_one_minus_g`) and the pair
      enters only through the even sum f(x + s) + f(x − s) (`_pair_sum`, the 2D series near
      s = 0): no square root of a vanishing quantity anywhere, so the stress and the tangent
      are exact at the double eigenvalue too. (Clamping r to 1 − δ instead gives the right
      stress, since dr/dC = 0 at r = ±1, but drops ∂G/∂r · d²r/dC² from the tangent: an O(1)
      error there, tests/test_kinematics.py measures it.)
    """
    I = ufl.Identity(3)  # noqa: E741 (the identity tensor, as in the equations)
    m = ufl.tr(C) / 3
    D = C - m * I
    q = ufl.inner(D, D)  # tr(D²) for symmetric D
    near = ufl.lt(q, tol * m**2)
    fd = _derivatives(f, m, 6)
    D2 = D * D
    D3 = D2 * D
    powers = [None, None, q, ufl.tr(D3), ufl.inner(D2, D2), ufl.inner(D3, D2), ufl.inner(D3, D3)]
    series = 3 * fd[0] + sum(fd[k] * powers[k] / math.factorial(k) for k in range(2, 7))

    p = ufl.sqrt(ufl.conditional(near, tol * m**2, q) / 6)
    r = ufl.det(D / p) / 2
    return ufl.conditional(near, series, _off_isotropic(m, p, r, f, tol))
