"""Stability study: methods where they are known to fail, beside methods that work, measured.

`run_stability_study(out)` runs five cases and writes `out/stability.csv` (one row per
case × method × parameter), `out/stability.md` (tables with one line of interpretation per case)
and PNG figures. Each case is a function returning rows (dicts: case, method, parameter, value,
then its measures); a failure is recorded with its reason, never hidden.

1. `p1p1_vs_taylor_hood`: nearly undrained biphasic tissue (subcutaneous Holmes–Mow, k0 = 1e-3
   mm⁴/(N·s)) under a sudden strip load on a confined block, one step Δt = 1 s (k M Δt/h² ~ 1e-3):
   checkerboard of the pressure (its deviation from the mean of its neighbours) and the footing
   settlement against an undrained reference (Taylor–Hood on a finer mesh).
2. `nitsche_parameters`: plane-strain Hertz (rigid cylinder on an elastic block) for θ ∈ {−1, 0, 1}
   and γ0 over decades: penetration, Hertz half-width / peak-pressure errors, Newton iterations,
   SNES reason.
3. `principal_stretch_tangent`: the hyperfoam tangent at C = I with the exact series switch of
   `kinematics.eigen_sum`, with ε inside the sqrt, and naive: relative error against the
   linearised stiffness (λ0 = 2μ0β, μ0).
4. `poroelastic_time_step`: Terzaghi column (drained top), one step Δt over decades around the
   bound h²/(6c): pressure overshoot above the load, for Taylor–Hood and P1/P1, against the exact
   one-step (backward Euler, continuous in space) solution.
5. `compaction_and_drucker`: a column driven towards J = φ0 (what the solver reports) and an
   unstable hyperfoam set (drucker_check / check_state messages).

The block, Terzaghi's column and the Hertz problem are `problems`' (shared with the tests).
Serial: every mesh lives on MPI.COMM_SELF; under mpiexec rank 0 computes and writes.
"""

from __future__ import annotations

import csv
import math
import time
import warnings
from pathlib import Path

import dolfinx.fem.petsc  # noqa: F401  (registers the PETSc assemblers)
import numpy as np
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI

from ..errors import (
    CompactionError,
    ConvergenceError,
    FingertipError,
    MaterialInstabilityError,
    on_root,
)
from ..loading import PiecewiseLinear
from ..physics import materials as mat
from ..physics.drucker import check_state, drucker_check
from ..physics.kinematics import deformation_gradient, eigen_sum
from ..stepping.diagnosis import SNES_REASONS
from ..stepping.options import StepOptions
from ..stepping.stepper import TimeStepper
from .problems import (
    ConfinedBlock,
    Hertz,
    HertzBlock,
    Terzaghi,
    confined_modulus,
    contact_edge,
    newton_problem,
)

TIGHT = {"snes_rtol": 1e-10, "snes_atol": 1e-16, "snes_max_it": 25}

_prefix_counter = [0]


def _prefix(name: str) -> str:
    """A unique PETSc options prefix (NonlinearProblem needs one per problem)."""
    _prefix_counter[0] += 1
    return f"study_{name}_{_prefix_counter[0]}_"


def _reason(code: int) -> str:
    return SNES_REASONS.get(code, str(code))


def _one_step(block: ConfinedBlock, dt: float, prefix: str, petsc=None) -> tuple[bool, str, int]:
    """One backward-Euler step of size dt from rest; (converged, reason, Newton iterations)."""
    stepper = TimeStepper(block, StepOptions(dt_initial=dt, dt_min=dt, dt_max=dt, max_cuts=0,
                                             extrapolate=False),
                          {**TIGHT, **(petsc or {})}, prefix=_prefix(prefix))
    try:
        reports = stepper.run(lambda t: block.load(t), dt)
    except FingertipError as e:
        return False, str(e), stepper.snes.getIterationNumber()
    return True, _reason(stepper.snes.getConvergedReason()), reports[-1].newton_iterations


# ------------------------------------------------------------------------------------------
# case 1


def _checkerboard(p: fem.Function) -> tuple[np.ndarray, np.ndarray]:
    """Per node of the P1 pressure p (serial): p minus the mean of its neighbours (nodes
    sharing a cell), and the largest jump to a neighbour. A smooth field gives O(h² |∇²p|);
    a checkerboard gives the oscillation's amplitude."""
    n = len(p.x.array)
    nbrs = [set() for _ in range(n)]
    for cell in p.function_space.dofmap.list:
        for a in cell:
            nbrs[a].update(int(b) for b in cell if b != a)
    v = p.x.array
    dev = np.array([v[i] - np.mean([v[j] for j in nbrs[i]]) for i in range(n)])
    jump = np.array([max(abs(v[i] - v[j]) for j in nbrs[i]) for i in range(n)])
    return dev, jump


def p1p1_vs_taylor_hood(coarse: bool = True, profiles: dict | None = None) -> list[dict]:
    """Sudden strip load on a confined, impermeable block of nearly undrained tissue."""
    tissue = mat.SUBCUTANEOUS_BIPHASIC
    solid = tissue.solid
    sigma0 = 0.01 * solid.mu0  # MPa: ~1 % strain, the small-strain undrained limit
    dt = 1.0  # s; the drainage time over 1 mm is ~3e5 s
    load = lambda t: sigma0  # noqa: E731
    n = 12 if coarse else 24
    reference = ConfinedBlock(2 * n, 2 * n, load, tissue=tissue, degree_u=2, load_width=0.5)
    ok, why, _ = _one_step(reference, dt, "footing_ref")
    if not ok:
        raise FingertipError(f"undrained reference did not converge: {why}")
    s_ref = reference.settlement()
    c = tissue.permeability.k0 * confined_modulus(solid)
    rows = []
    for method, degree in (("Taylor-Hood P2/P1", 2), ("P1/P1", 1)):
        block = ConfinedBlock(n, n, load, tissue=tissue, degree_u=degree, load_width=0.5)
        ok, why, its = _one_step(block, dt, f"footing_p{degree}")
        row = {"case": "1 undrained inf-sup", "method": method, "parameter": "h (mm)",
               "value": 1.0 / n, "converged": ok, "reason": why, "newton_iterations": its,
               "c_dt_over_h2": c * dt * n**2}
        if ok:
            dev, jump = _checkerboard(block.p)
            X, _ = block.pressure_nodes()
            # the footing edge (0.5, 1) is a pressure singularity for every method: a measure
            # of the checkerboard alone leaves out the nodes within 0.25 mm of it
            off_edge = np.hypot(X[:, 0] - 0.5, X[:, 1] - 1.0) > 0.25
            row.update({
                "checkerboard_max": float(np.max(np.abs(dev)) / sigma0),
                "checkerboard_max_off_edge": float(np.max(np.abs(dev[off_edge])) / sigma0),
                "checkerboard_rms": float(np.sqrt(np.mean(dev**2)) / sigma0),
                "max_neighbour_jump": float(np.max(jump) / sigma0),
                "p_min_over_load": float(block.p.x.array.min() / sigma0),
                "p_max_over_load": float(block.p.x.array.max() / sigma0),
                "settlement_error": abs(block.settlement() / s_ref - 1),
                "J_change_max": abs(block.min_jacobian()[0] - 1),
            })
            if profiles is not None:
                profiles[method] = block.pressure_nodes() + (sigma0,)
        rows.append(row)
    return rows


# ------------------------------------------------------------------------------------------
# case 2


def nitsche_parameters(coarse: bool = True, thetas=(-1, 0, 1),
                       gammas=(0.1, 1.0, 10.0, 100.0, 1000.0), steps: int = 3) -> list[dict]:
    """Rigid cylinder into an elastic half block (small strain), Nitsche θ and γ0 swept."""
    hertz = Hertz()
    domain, facet_tags = hertz.mesh(hertz.a_target / (2.5 if coarse else 5.0))
    h_min = min(domain.h(1, facet_tags.find(Hertz.BOTTOM)))
    rows = []
    for theta in thetas:
        gamma_M = fem.Constant(domain, 10.0 * hertz.modulus)  # γ0·M: γ0 changes, no recompiling
        block = hertz.block(domain, facet_tags, theta=theta, modulus=gamma_M, gamma0=1.0)
        problem = newton_problem(block.residual, block.u, block.bcs, _prefix("nitsche"),
                                 snes_rtol=1e-9, snes_atol=1e-13, snes_max_it=50)
        for gamma0 in gammas:
            gamma_M.value = gamma0 * hertz.modulus
            ok, reason, its, wall = _indent(hertz, block, problem, steps)
            row = {"case": "2 Nitsche contact", "method": f"theta={theta:+d}",
                   "parameter": "gamma0", "value": gamma0, "converged": ok, "reason": reason,
                   "newton_iterations": int(sum(its)), "max_iterations_per_step": max(its),
                   "gamma_h_over_M": gamma0, "wall_s": wall}
            if ok:
                row.update(_against_hertz(hertz, block), h_contact=h_min)
            rows.append(row)
    ref = next((r for r in rows if r["method"] == "theta=+0" and r["value"] == 10.0
                and r["converged"]), None)
    for r in rows:
        if ref is not None and r.get("force_N_per_mm") is not None:
            r["force_vs_theta0_gamma10"] = r["force_N_per_mm"] / ref["force_N_per_mm"] - 1
    return rows


def _indent(hertz: Hertz, block: HertzBlock, problem, steps: int):
    """Indent from rest to the full depth in `steps` steps: (converged, last reason, Newton
    iterations per step, wall time in s)."""
    block.u.x.array[:] = 0.0
    block.obstacle.y_tip.value = 0.0
    its, started = [], time.perf_counter()
    for k in range(1, steps + 1):
        block.obstacle.y_tip.value = hertz.depth * k / steps
        with np.errstate(all="ignore"):
            problem.solve()
        r = problem.solver.getConvergedReason()
        its.append(problem.solver.getIterationNumber())
        if r <= 0 or not np.all(np.isfinite(block.u.x.array)):
            return False, _reason(r), its, time.perf_counter() - started
    return True, "converged", its, time.perf_counter() - started


def _against_hertz(hertz: Hertz, block: HertzBlock) -> dict:
    """Penetration, force, and the half-width and peak-pressure errors against Hertz theory."""
    force = block.force()
    x, pc, s = block.profile()
    a, p0 = hertz.theory(force) if force > 0 else (math.nan, math.nan)
    return {
        "penetration_over_depth": block.contact.max_penetration() / hertz.depth,
        "force_N_per_mm": force,
        "halfwidth_error": abs(contact_edge(x, s) / a - 1),
        "peak_pressure_error": abs(pc.max() / p0 - 1),
    }


# ------------------------------------------------------------------------------------------
# case 3


def _closed_form_sum(eps_sqrt: float):
    """Σ f(c±) with c± = m ± sqrt(Δ + ε): the common regularisation (ε = 0: naive)."""
    def eigsum(C, f):
        m = 0.5 * (C[0, 0] + C[1, 1])
        s = ufl.sqrt((0.5 * (C[0, 0] - C[1, 1])) ** 2 + C[0, 1] * C[1, 0] + eps_sqrt)
        return f(m + s) + f(m - s)
    return eigsum


def _hyperfoam_energy(material: mat.Hyperfoam, C, eigsum):
    """Hyperfoam.strain_energy (plane strain) with the eigenvalue sum `eigsum(C, f)`."""
    b = material.beta
    terms = [(2.0 * m / a**2, a) for m, a in zip(material.mu, material.alpha)]
    W = eigsum(C, lambda c: sum(k * c ** (a / 2.0) for k, a in terms))
    detC = ufl.det(C)
    return W + sum(k * (1.0 - 3.0 + (detC ** (-a * b / 2.0) - 1.0) / b) for k, a in terms)


def principal_stretch_tangent(material: mat.Hyperfoam = mat.SUBCUTANEOUS) -> list[dict]:
    """Second derivative of W along C = I + εH at ε = 0, and the assembled P1 Jacobian on the
    unit square (two cells) at u = 0, against the linearised stiffness (λ0 = 2μ0β, μ0)."""
    msh = mesh.create_unit_square(MPI.COMM_SELF, 1, 1)
    cells = np.arange(msh.topology.index_map(2).size_local, dtype=np.int32)
    H = np.array([[0.3, 0.7], [0.7, -0.2]])
    mu0, lam0 = material.mu0, material.lame_lambda0
    exact_d2 = lam0 / 4 * np.trace(H) ** 2 + mu0 / 2 * np.sum(H * H)

    V = fem.functionspace(msh, ("Lagrange", 1, (2,)))
    du, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    e = lambda w: ufl.sym(ufl.grad(w))  # noqa: E731
    K_lin = fem.petsc.assemble_matrix(fem.form(
        (lam0 * ufl.tr(e(du)) * ufl.tr(e(v)) + 2 * mu0 * ufl.inner(e(du), e(v))) * ufl.dx))
    K_lin.assemble()
    K_ref = K_lin.convert("dense").getDenseArray().copy()

    variants = [
        ("exact series switch (kinematics.eigen_sum)", "-", "-",
         lambda C, f: eigen_sum(C, f)),
        ("epsilon in sqrt", "eps", 3e-16, _closed_form_sum(3e-16)),
        ("epsilon in sqrt", "eps", 1e-6, _closed_form_sum(1e-6)),
        ("naive closed form", "eps", 0.0, _closed_form_sum(0.0)),
    ]
    rows = []
    for method, pname, pval, eigsum in variants:
        C0 = fem.Constant(msh, np.eye(2))
        Hc = fem.Constant(msh, H)
        eps = ufl.variable(fem.Constant(msh, 0.0))
        W = _hyperfoam_energy(material, C0 + eps * Hc, eigsum)
        d1 = ufl.diff(W, eps)
        vals = fem.Expression(ufl.as_vector([d1, ufl.diff(d1, eps)]),
                              np.array([[1 / 3, 1 / 3]])).eval(msh, cells[:1]).ravel()
        # the assembled Jacobian of ∫ P(u):∇v dx at u = 0
        u = fem.Function(V)
        F = deformation_gradient(u)
        Cv = ufl.variable(F.T * F)
        S = 2 * ufl.diff(_hyperfoam_energy(material, Cv, eigsum), Cv)
        R = ufl.inner(F * S, ufl.grad(v)) * ufl.dx(metadata={"quadrature_degree": 2})
        with np.errstate(all="ignore"):
            K = fem.petsc.assemble_matrix(fem.form(ufl.derivative(R, u, du)))
            K.assemble()
            K = K.convert("dense").getDenseArray().copy()
        finite = bool(np.all(np.isfinite(K)) and np.all(np.isfinite(vals)))
        rows.append({
            "case": "3 tangent at C = I", "method": method, "parameter": pname, "value": pval,
            "finite": finite,
            "d2W_rel_error": abs(vals[1] / exact_d2 - 1) if np.isfinite(vals[1]) else math.nan,
            "stress_at_I": abs(vals[0]) if np.isfinite(vals[0]) else math.nan,
            "jacobian_rel_error": (float(np.linalg.norm(K - K_ref) / np.linalg.norm(K_ref))
                                   if finite else math.nan),
        })
    return rows


# ------------------------------------------------------------------------------------------
# case 4


def poroelastic_time_step(coarse: bool = True, profiles: dict | None = None) -> list[dict]:
    """Terzaghi column drained at the top, one step Δt from rest, Δt over decades."""
    terzaghi = Terzaghi()  # c = 1 mm²/s, k = c/M constant
    c, sigma0 = terzaghi.c, terzaghi.sigma0
    ny = 16 if coarse else 32
    h = 1.0 / ny
    bound = h**2 / (6 * c)
    dts = (np.logspace(-6, 0, 7) if coarse else np.logspace(-7, 0, 15))
    rows = []
    for method, degree in (("Taylor-Hood P2/P1", 2), ("P1/P1", 1)):
        block = terzaghi.column(ny, degree_u=degree)
        stepper = TimeStepper(block, StepOptions(dt_initial=1.0, dt_min=1e-12, max_cuts=0,
                                                 extrapolate=False), TIGHT,
                              prefix=_prefix(f"terzaghi_p{degree}"))
        for dt in dts:
            for f in (block.u, block.u_n, block.p):
                f.x.array[:] = 0.0
            block.accept()
            stepper.options.dt_initial = stepper.options.dt_max = float(dt)
            try:
                stepper.run(lambda t: sigma0, float(dt))
                ok, why = True, "converged"
            except FingertipError as e:
                ok, why = False, str(e)
            X, p = block.pressure_nodes()
            order = np.argsort(X[:, 1], kind="stable")
            z, p = X[order, 1], p[order]
            exact = terzaghi.one_step_pressure(z, dt)
            rows.append({
                "case": "4 poroelastic time step", "method": method, "parameter": "dt (s)",
                "value": float(dt), "converged": ok, "reason": why,
                "dt_over_bound": dt / bound, "bound_h2_over_6c": bound, "h": h,
                "overshoot": float(p.max() / sigma0 - 1),
                "undershoot": float(max(0.0, -p.min()) / sigma0),
                "overshoot_vs_exact": float((p.max() - exact.max()) / sigma0),
                "z_of_p_max": float(z[np.argmax(p)]),
                "p_error_max": float(np.max(np.abs(p - exact)) / sigma0),
                "settlement_error_rel": abs(block.settlement()
                                            / terzaghi.one_step_settlement(dt) - 1),
            })
            if profiles is not None:
                profiles[(method, float(dt))] = (z, p / sigma0, exact / sigma0)
    return rows


# ------------------------------------------------------------------------------------------
# case 5


def compaction_and_drucker(coarse: bool = True) -> list[dict]:
    """Case 5: compaction named by the material check and by the solver, and the Drucker check
    of the paper's foams beside a deliberately unstable one."""
    unstable = mat.Hyperfoam(mu=(0.1, -0.05), alpha=(2.0, 6.0), nu=0.3,
                             where="unstable test foam")
    return [_compaction_check(), *_squeezed_columns(coarse), *_drucker_sets(unstable),
            *_state_checks(unstable)]


def _compaction_check() -> dict:
    """(a) The direct check: J below the solid volume fraction."""
    try:
        mat.check_compaction(0.39, "subcutaneous tissue at (0, -5) mm", 0.4)
        msg = "no error"
    except CompactionError as e:
        msg = str(e)
    return {"case": "5 compaction / Drucker", "method": "materials.check_compaction",
            "parameter": "J_min", "value": 0.39, "detected": "solid volume fraction" in msg,
            "message": msg}


def _squeezed_columns(coarse: bool) -> list[dict]:
    """(b) The solver: drained columns squeezed to 70 % of their height (mean J → 0.3 < φ0)."""
    soft = mat.Hyperfoam(mu=mat.SUBCUTANEOUS.mu, alpha=mat.SUBCUTANEOUS.alpha, nu=0.05,
                         where="subcutaneous mu/alpha, nu = 0.05")
    return [_squeezed_column(solid, tolerances, label, coarse) for solid, tolerances, label in (
        (mat.SUBCUTANEOUS, {}, "subcutaneous, default SNES tolerances"),
        (mat.SUBCUTANEOUS, TIGHT, "subcutaneous, snes_atol 1e-16"),
        (soft, {}, "nu = 0.05 (soft in volume), default SNES tolerances"),
    )]


def _squeezed_column(solid, tolerances: dict, label: str, coarse: bool) -> dict:
    """One drained column of `solid` squeezed until the solver stops: does it name
    compaction, and where was the last accepted step?"""
    hm = mat.HOLMES_MOW_SUBCUTANEOUS
    M = confined_modulus(solid)
    # c = k M ~ 10 mm²/s: drains within the 1 s squeeze, so J follows it
    tissue = mat.Biphasic(solid, mat.HolmesMow(k0=10.0 / M, phi0=hm.phi0, kappa=hm.kappa,
                                               M=hm.M))
    history = PiecewiseLinear((0.0, 1.0), (0.0, 0.7))
    block = ConfinedBlock(1, 4 if coarse else 8, history, tissue=tissue, degree_u=2,
                          width=0.25, drained_top=True, top_displacement=True)
    stepper = TimeStepper(block, StepOptions(dt_initial=0.1, dt_min=1e-3, dt_max=0.1,
                                             max_cuts=6), tolerances,
                          prefix=_prefix("compaction"))
    reached = []
    try:
        stepper.run(history, 1.0, on_step=lambda r, reached=reached: reached.append(
            (r.time, r.load, r.diagnostics["J_min"])))
        msg = "no error"
    except ConvergenceError as e:
        msg = str(e)
    _, d_last, J_last = reached[-1] if reached else (0.0, 0.0, 1.0)
    return {"case": "5 compaction / Drucker", "method": "TimeStepper, column squeezed",
            "parameter": "solid", "value": label, "detected": "solid volume fraction" in msg,
            "last_accepted_settlement_over_H": d_last, "J_min_last_accepted": J_last,
            "message": msg}


def _drucker_sets(unstable) -> list[dict]:
    """(c) Drucker: the paper's sets and a deliberately unstable one."""
    rows = []
    for foam in (mat.SKIN, mat.SUBCUTANEOUS, unstable):
        res = drucker_check(foam)
        first = {k: v for k, v in res.first_unstable.items()}
        rows.append({"case": "5 compaction / Drucker", "method": "stability.drucker_check",
                     "parameter": "material", "value": foam.where,
                     "detected": not res.stable_everywhere,
                     "stable_fraction": float(res.stable.mean()),
                     "first_unstable_equibiaxial": first["equibiaxial"],
                     "first_unstable_uniaxial": first["uniaxial"],
                     "message": res.describe().replace("\n", " | ")})
    return rows


def _state_checks(unstable) -> list[dict]:
    """`check_state` on an unstable state of the unstable foam: it warns, or raises."""
    state = np.array([[1.3, 0.95], [1.0, 1.0]])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ok = check_state(unstable, state, "column quadrature points", mode="warn")
    rows = [{"case": "5 compaction / Drucker", "method": "stability.check_state (warn)",
             "parameter": "stretches", "value": "[1.3, 0.95]", "detected": not ok,
             "message": str(caught[0].message) if caught else "no warning"}]
    try:
        check_state(unstable, state, "column quadrature points", mode="error")
        msg = "no error"
    except MaterialInstabilityError as e:
        msg = str(e)
    rows.append({"case": "5 compaction / Drucker", "method": "stability.check_state (error)",
                 "parameter": "stretches", "value": "[1.3, 0.95]",
                 "detected": msg != "no error", "message": msg})
    return rows


# ------------------------------------------------------------------------------------------
# the study: csv, markdown, figures

_FIXED = ["case", "method", "parameter", "value"]

#: The columns of each case's markdown table (all measures are in the csv).
_MD_COLUMNS = {
    "1 undrained inf-sup": ["checkerboard_rms", "checkerboard_max_off_edge", "checkerboard_max",
                            "p_min_over_load", "p_max_over_load", "settlement_error",
                            "newton_iterations"],
    "2 Nitsche contact": ["converged", "reason", "newton_iterations", "max_iterations_per_step",
                          "penetration_over_depth", "halfwidth_error", "peak_pressure_error",
                          "force_vs_theta0_gamma10"],
    "3 tangent at C = I": ["finite", "d2W_rel_error", "jacobian_rel_error", "stress_at_I"],
    "4 poroelastic time step": ["dt_over_bound", "overshoot", "overshoot_vs_exact", "undershoot",
                                "p_error_max", "settlement_error_rel"],
    "5 compaction / Drucker": ["detected", "message"],
}


def _fmt(x) -> str:
    if isinstance(x, bool | np.bool_):
        return "yes" if x else "no"
    if isinstance(x, float | np.floating):
        if not math.isfinite(x):
            return "NaN" if math.isnan(x) else str(x)
        return f"{x:.3g}"
    if isinstance(x, tuple):
        return "(" + ", ".join("-" if v is None else _fmt(v) for v in x) + ")"
    return str(x).replace("|", "/").replace("\n", " ")


def _interpret(case: str, rows: list[dict]) -> str:
    """One line per case, from the measured numbers."""
    try:
        for number, explain in _INTERPRETERS.items():
            if case.startswith(number):
                return explain(rows)
    except (StopIteration, KeyError, ValueError, TypeError) as e:  # a case that failed outright
        return f"(no interpretation: {type(e).__name__} {e})"
    return ""


def _explain_inf_sup(rows: list[dict]) -> str:
    th = next(r for r in rows if r["method"].startswith("Taylor"))
    p1 = next(r for r in rows if r["method"] == "P1/P1")
    return (f"P1/P1's pressure checkerboard (RMS deviation from the neighbours' mean) is "
            f"{p1['checkerboard_rms'] / th['checkerboard_rms']:.1f}× Taylor–Hood's "
            f"({p1['checkerboard_max_off_edge'] / th['checkerboard_max_off_edge']:.1f}× "
            "in the max away from the footing edge, whose singularity both see); its "
            f"undrained settlement is off by {p1['settlement_error']:.1%} against "
            f"{th['settlement_error']:.2%} for Taylor–Hood (reference: Taylor–Hood, "
            "mesh halved).")


def _explain_nitsche(rows: list[dict]) -> str:
    by = {(r["method"], r["value"]): r for r in rows}
    fails = [f"θ = {r['method'][6:]}, γ0 = {r['value']:g} ({r['reason']})"
             for r in rows if not r["converged"]]
    ok10 = by.get(("theta=+0", 10.0), {})
    ok100 = by.get(("theta=+0", 100.0), {})
    bad1 = by.get(("theta=+1", 1.0), {})
    pen01 = by.get(("theta=+0", 0.1), {}).get("penetration_over_depth", math.nan)
    return (f"θ = 0, γ0 = 10: {ok10.get('newton_iterations')} Newton iterations in 3 "
            f"steps, penetration {ok10.get('penetration_over_depth', math.nan):.1e} of "
            f"the depth, Hertz half-width/peak errors "
            f"{ok10.get('halfwidth_error', math.nan):.1%}/"
            f"{ok10.get('peak_pressure_error', math.nan):.1%}; γ0 = 100 takes "
            f"{ok100.get('newton_iterations')} iterations (peak pressure error "
            f"{ok100.get('peak_pressure_error', math.nan):.1%}); γ0 = 0.1 lets θ = 0 "
            f"penetrate {pen01:.1e}"
            " of the depth; θ = +1 below its coercivity threshold (γ0 = 1) converges to "
            "a wrong pressure (peak error "
            f"{bad1.get('peak_pressure_error', math.nan):.0%}). "
            "On this small-strain problem θ = ±1 otherwise match θ = 0 (NOTES.md's "
            "θ = +1 divergence / θ = −1 inversion were finite-strain runs: not "
            "reproduced here). Failures: " + ("; ".join(fails) or "none") + ".")


def _explain_tangent(rows: list[dict]) -> str:
    ex = rows[0]
    eps = [r for r in rows if r["method"] == "epsilon in sqrt"]
    return (f"The exact series is exact to {ex['d2W_rel_error']:.0e} (Jacobian "
            f"{ex['jacobian_rel_error']:.0e}); ε in the sqrt gives finite but wrong "
            "tangents (" + ", ".join(f"ε = {r['value']:g}: {r['d2W_rel_error']:.1e}"
                                      for r in eps)
            + "); the naive closed form gives NaN.")


def _explain_time_step(rows: list[dict]) -> str:
    parts = []
    for method in ("Taylor-Hood P2/P1", "P1/P1"):
        rs = sorted((r for r in rows if r["method"] == method), key=lambda r: r["value"])
        clean = [r["dt_over_bound"] for r in rs if r["overshoot"] <= 1e-3]
        worst = max(r["overshoot"] for r in rs)
        parts.append(f"{method}: overshoot up to {worst:.0%} of the load, none "
                     f"(≤ 0.1 %) from Δt = {min(clean):.3g}× the bound" if clean else
                     f"{method}: overshoot at every Δt")
    return (f"Bound h²/(6c) = {rows[0]['bound_h2_over_6c']:.3g} s "
            f"(h = {rows[0]['h']:.4g} mm, c = 1 mm²/s); " + "; ".join(parts)
            + ". The overshoot sits at the node next to the drained top (negative "
            "values: the column has drained, p_max < load, "
            "as in the exact one-step solution; compare overshoot_vs_exact).")


def _explain_compaction(rows: list[dict]) -> str:
    runs = [r for r in rows if r["method"].startswith("TimeStepper")]
    named = [r["value"] for r in runs if r["detected"]]
    other = [f"{r['value']}: stopped at J = {r['J_min_last_accepted']:.2f} without "
             "naming compaction" for r in runs if not r["detected"]]
    foams = [r for r in rows if r["method"] == "stability.drucker_check"]
    return ("The solver stops at once on compaction (J within the margin of phi0 at a "
            "quadrature point or a node -> CompactionError naming the time, the place "
            "and the permeability) for: " + "; ".join(named) + ". "
            + ("; ".join(other) + " (Newton stalls on round-off of the stiff volumetric "
               "term J^(-αβ) first). " if other else "")
            + "Drucker: " + "; ".join(
                f"{r['value']} {'UNSTABLE, first at equibiaxial (compression, tension) '
                + _fmt(r['first_unstable_equibiaxial']) if r['detected'] else 'stable on '
                'the whole grid'}" for r in foams)
            + " (MODEL.md's loss near 0.40/0.45 is not reproduced); check_state warns "
            "or raises on an unstable state.")


#: Each case's sentence, by the case's number (the first character of its name).
_INTERPRETERS = {"1": _explain_inf_sup, "2": _explain_nitsche, "3": _explain_tangent,
                 "4": _explain_time_step, "5": _explain_compaction}


def write_csv(rows: list[dict], path: Path) -> None:
    keys = list(_FIXED)
    for r in rows:
        keys += [k for k in r if k not in keys]
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        for r in rows:
            w.writerow({k: (_fmt(v) if isinstance(v, tuple) else v) for k, v in r.items()})


def write_markdown(rows: list[dict], path: Path, runtimes: dict | None = None) -> str:
    lines = ["# Stability study: where methods fail, measured", ""]
    for case, columns in _MD_COLUMNS.items():
        rs = [r for r in rows if r["case"] == case]
        if not rs:
            continue
        lines += [f"## Case {case}", ""]
        cols = ["method", "parameter", "value"] + [c for c in columns if any(c in r for r in rs)]
        lines.append("| " + " | ".join(cols) + " |")
        lines.append("|" + "---|" * len(cols))
        for r in rs:
            lines.append("| " + " | ".join(_fmt(r.get(c, "")) for c in cols) + " |")
        lines += ["", _interpret(case, rs), ""]
    if runtimes:
        lines += ["Run time: " + ", ".join(f"case {k} {v:.1f} s" for k, v in runtimes.items()),
                  ""]
    text = "\n".join(lines)
    path.write_text(text)
    return text


def _figures(out: Path, rows: list[dict], profiles1: dict, profiles4: dict) -> list[Path]:
    """The study's figures (cases 1, 2 and 4, those it has rows or profiles of), written to
    `out`; returns their paths."""
    r2 = [r for r in rows if r["case"].startswith("2")]
    r4 = [r for r in rows if r["case"].startswith("4")]
    drawn = [_figure_inf_sup(out, profiles1) if profiles1 else None,
             _figure_nitsche(out, r2) if r2 else None,
             _figure_time_step(out, r4, profiles4) if r4 else None]
    return [path for path in drawn if path is not None]


def _figure_inf_sup(out: Path, profiles1: dict) -> Path:
    """Case 1: the pressure along the mid-height row."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6, 3.5))
    ax = fig.subplots()
    for method, (X, p, sigma0) in profiles1.items():
        row = np.isclose(X[:, 1], 0.5)
        order = np.argsort(X[row, 0])
        ax.plot(X[row, 0][order], p[row][order] / sigma0, "o-", ms=3, label=method)
    ax.set(xlabel="x (mm), at y = 0.5 mm", ylabel="p / load",
           title="Undrained strip load, one step Δt = 1 s")
    ax.legend()
    fig.tight_layout()
    path = out / "stability_p1p1_vs_taylor_hood.png"
    fig.savefig(path, dpi=120)
    return path


def _figure_nitsche(out: Path, r2: list[dict]) -> Path:
    """Case 2: penetration and Newton iterations against γ0."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 3.5))
    (a1, a2) = fig.subplots(1, 2)
    for method in dict.fromkeys(r["method"] for r in r2):
        rs = [r for r in r2 if r["method"] == method]
        g = [r["value"] for r in rs]
        # a penetration of 0 (the constraint met exactly) has no place on a log axis: floored
        pen = [max(r.get("penetration_over_depth", np.nan), 1e-6) for r in rs]
        line, = a1.loglog(g, pen, "o-", label=method.replace("theta", "θ"))
        a2.semilogx(g, [r["newton_iterations"] for r in rs], "o-", color=line.get_color(),
                    label=method.replace("theta", "θ"))
        for r in rs:
            if not r["converged"]:
                a2.plot(r["value"], r["newton_iterations"], "x", ms=12,
                        color=line.get_color())
    a1.set(xlabel="γ0", ylabel="max penetration / indentation (floor 1e-6)")
    a2.set(xlabel="γ0", ylabel="Newton iterations (3 steps; × = failed)")
    a1.legend()
    fig.suptitle("Nitsche contact, rigid cylinder on an elastic block")
    fig.tight_layout()
    path = out / "stability_nitsche.png"
    fig.savefig(path, dpi=120)
    return path


def _figure_time_step(out: Path, r4: list[dict], profiles4: dict) -> Path:
    """Case 4: the overshoot against Δt with the bound marked; profiles near 0.1 and 10
    times the bound."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 3.8))
    (a1, a2) = fig.subplots(1, 2)
    for method in dict.fromkeys(r["method"] for r in r4):
        rs = [r for r in r4 if r["method"] == method]
        a1.loglog([r["value"] for r in rs], [max(r["overshoot_vs_exact"], 1e-6) for r in rs],
                  "o-", label=method)
    bound = r4[0]["bound_h2_over_6c"]
    a1.axvline(bound, color="k", ls="--", label="h²/(6c)")
    a1.set(xlabel="Δt (s)", ylabel="(p_max − exact p_max) / load (floor 1e-6)",
           title="Terzaghi column, first step")
    a1.legend()
    for (method, dt), (z, p, exact) in profiles4.items():
        if abs(math.log10(dt / bound) + 1) < 0.6 or abs(math.log10(dt / bound) - 1) < 0.6:
            a2.plot(p, z, "o-", ms=3, label=f"{method}, Δt = {dt / bound:.2g}× bound")
            a2.plot(exact, z, "k:", lw=1)
    a2.set(xlabel="p / load (dotted: exact one-step)", ylabel="z (mm)", ylim=(0.5, 1.0))
    a2.legend(fontsize=7, loc="lower left")  # where no profile runs
    fig.tight_layout()
    path = out / "stability_time_step.png"
    fig.savefig(path, dpi=120)
    return path


def _run_cases(out: Path, coarse: bool) -> list[dict]:
    """The five cases, one after the other, and their files (on one rank)."""
    rows: list[dict] = []
    out.mkdir(parents=True, exist_ok=True)
    profiles1, profiles4, runtimes = {}, {}, {}
    cases = [
        ("1", lambda: p1p1_vs_taylor_hood(coarse, profiles1)),
        ("2", lambda: nitsche_parameters(coarse)),
        ("3", lambda: principal_stretch_tangent()),
        ("4", lambda: poroelastic_time_step(coarse, profiles4)),
        ("5", lambda: compaction_and_drucker(coarse)),
    ]
    for name, run in cases:
        started = time.perf_counter()
        try:
            rows += run()
        except Exception as e:  # record, don't hide: the other cases still run
            rows.append({"case": name, "method": "(case failed)", "parameter": "",
                         "value": "", "reason": f"{type(e).__name__}: {e}"})
        runtimes[name] = time.perf_counter() - started
    write_csv(rows, out / "stability.csv")
    write_markdown(rows, out / "stability.md", runtimes)
    _figures(out, rows, profiles1, profiles4)
    return rows


def run_stability_study(out: Path, *, coarse: bool = True, comm=MPI.COMM_WORLD) -> list[dict]:
    """Run the five cases (serially, on rank 0 of `comm`), write DIR/stability.csv,
    DIR/stability.md and PNG figures; return the rows (on every rank)."""
    out = Path(out)
    return on_root(comm, lambda: _run_cases(out, coarse))  # a failure stops every rank


def main(argv: list[str] | None = None) -> int:
    """`python -m fingertip_dolfinx.studies.stability --out DIR [--full]`."""
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True, metavar="DIR")
    parser.add_argument("--full", action="store_true", help="finer meshes and sweeps")
    args = parser.parse_args(argv)
    run_stability_study(args.out, coarse=not args.full)
    if MPI.COMM_WORLD.rank == 0:
        print((args.out / "stability.md").read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
