"""The step options as data: what a scene's `[steps]` table and `[solver] linear` accept.

Data only, with no PETSc or DOLFINx import, so that a scene (scene.py) validates its tables
without loading the solvers. `StepOptions` chooses the integrator of the biphasic rate
(`scheme`: backward Euler, variable-step BDF2, or generalised-α for dynamics) and how the steps
are sized (`control`: by Newton's effort or by the local error estimate; controllers.py);
`StepReport` is what the stepper (stepper.py) says of each accepted step.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from dataclasses import asdict, dataclass, field

from ..errors import InputError
from ..validation import count

#: Newton with a backtracking line search and a direct solve (MUMPS): robust for contact and
#: for the saddle-point structure of the undrained tissue. Users override any of these.
DEFAULT_PETSC_OPTIONS = {
    "snes_type": "newtonls",
    "snes_linesearch_type": "bt",
    "snes_rtol": 1e-9,
    "snes_atol": 1e-10,  # N/mm: the bone (17 GPa) puts round-off near 1e-12
    "snes_stol": 0.0,
    "snes_max_it": 15,  # a failing attempt should fail fast: the step is cut and retried
    "ksp_type": "preonly",
    "pc_type": "lu",
    "pc_factor_mat_solver_type": "mumps",
}

CONTROLS = ("iterations", "error")
SCHEMES = ("backward-euler", "bdf2", "generalized-alpha")
#: Schemes whose biphasic rate is BDF2 (generalised-α keeps the mass balance second order).
SECOND_ORDER_RATE = ("bdf2", "generalized-alpha")
#: Variable-step BDF2 is zero-stable for step ratios ω = Δt_n/Δt_{n−1} < 1 + √2.
BDF2_GROWTH_LIMIT = 1 + math.sqrt(2)
#: The linear solvers inside Newton (linear.py): MUMPS LU, or Krylov with a field split.
LINEAR = ("direct", "iterative")


def check_linear(linear, where: str = "solver.linear") -> str:
    """`linear` if it names a linear solver (LINEAR), else an InputError naming `where`."""
    if linear not in LINEAR:
        raise InputError(where, f"{linear!r} is not a linear solver.",
                         f"use one of {', '.join(repr(k) for k in LINEAR)}.")
    return linear


#: Factorisations that read one triangle of the matrix and assume the other.
SYMMETRIC_FACTORISATIONS = ("cholesky", "icc")


def check_petsc_options(options, where: str = "solver") -> dict:
    """`options` if no preconditioner in them assumes a symmetric Jacobian, else an InputError.

    The Jacobian is not symmetric: the biphasic coupling enters the pressure rows with the
    opposite sign (symmetric only with them negated), Nitsche's θ = 0 contact and friction are
    unsymmetric, and the Darcy term's derivative in u is unsymmetric in any sign. A Cholesky
    or ICC factor would be built from one triangle of it: a wrong Newton direction that shows
    only as failing steps (benchmarks/jacobian_symmetry.py measures the asymmetry).
    """
    for key, value in options.items():
        if key.endswith("pc_type") and str(value).lower() in SYMMETRIC_FACTORISATIONS:
            raise InputError(f"{where}.{key}", f"{value!r} assumes a symmetric Jacobian; "
                             "this model's is not (the pressure coupling, contact, friction).",
                             'use pc_type = "lu" (the default), or the iterative route '
                             '(linear = "iterative").')
    return options


@dataclass
class StepOptions:
    """Adaptive time-step control, a scene's `[steps]` table (times in s).

    Each field is a key of that table; its meaning, unit and default are in the comment next
    to it and in the key reference (docs/reference/keys.md).
    """

    dt_initial: float = 0.1  # s: the first step
    dt_min: float = 1e-5  # s: a step cut below this stops the run
    dt_max: float = 10.0  # s: the largest step
    growth: float = 1.5  # factor after an easy step
    #: The factor after an easy step taken while the load is held (the same load at the
    #: step's start, middle and end; `control = "iterations"`), 0: `growth`. In a hold only
    #: the tissues' relaxation changes the state, its rate falling as it goes, so the steps
    #: may grow faster than in a ramp, whose contact zone must be followed. Measured on the 3D
    #: line load: docs/benchmarks/3d.md, "Speed of the 3D line load".
    hold_growth: float = 0.0
    cut: float = 0.5  # factor after a failed attempt
    max_cuts: int = 8  # failed attempts in a row before giving up
    easy_iterations: int = 6  # a step with at most this many Newton iterations is easy
    #: Start Newton from the linear extrapolation of the last two states (not across a kink
    #: of the load history): in a ramp this removes most of the iterations. Measured on the
    #: line load: without it, 81 steps of ~2 ms (7 iterations each) reached only 0.22 mm of
    #: the 1 mm ramp; a quadratic extrapolation through three states overshoots the growing
    #: contact zone: 41 steps, 209 iterations against the linear one's 33 and 164.
    extrapolate: bool = True
    #: Start the first step after a kink of the load from the tangent predictor
    #: (stepper.TangentPredictor: the accepted state's linearisation, its contact and stick
    #: sets), and extrapolate across output times, which are no kinks. Off: those steps start
    #: from the accepted state, also after an output time. With friction, a plate that starts
    #: to move along the skin from rest: the shear scene's plain start failed 6 times there.
    tangent_start: bool = False
    #: Solve the tangent predictor's system (the accepted state's Jacobian, assembled) by
    #: GMRES to 1e-8 on the LU factors the last step's Newton solve ended with, instead of
    #: factorising it: a few triangular solves instead of a factorisation per step (the 3D
    #: line load: 15 factorisations fewer, the same steps and answers). The first step of a
    #: run (a resume too) and a retry after a cut factorise as before. Needs `tangent_start`.
    #: The direct route's (`[solver] linear`): on the iterative route, which has no factors,
    #: the predictor is solved as without it. docs/benchmarks/contact-newton.md, "The tangent
    #: predictor from the last factorisation".
    tangent_reuse: bool = False
    #: Keep the Jacobian, and so its LU factorisation, for the next Newton iteration of a step
    #: when the last one cut the residual norm by at least this factor (0: never keep it; a
    #: chord step is then nearly as good as Newton's: the iterate is in the quadratic phase).
    #: Measured on the line load (benchmarks/line_load.py): see JacobianReuse.
    jacobian_reuse: float = 0.0
    #: Start a step under a held load with the Jacobian, and its factorisation, that the
    #: previous step ended with, when that step was held too, was not cut and took at most
    #: this many Newton iterations (0: every step starts with a fresh Jacobian). In a hold
    #: only the tissues' relaxation moves the state, so the kept tangent may still contract.
    #: Needs `jacobian_reuse`, whose threshold judges the kept Jacobian like any other: a
    #: first iteration that cuts the residual less reassembles, and a solve that fails with it
    #: is redone from the same start with a fresh one (no cut). The Darcy and viscoelastic
    #: terms make the Jacobian depend on Δt: it pays in a hold of steady steps (a confined
    #: column at a fixed Δt: 9 Jacobians instead of 124), not in one whose steps grow x3
    #: (`hold_growth`; the 3D line load: 81 factorisations instead of 78, off there).
    #: docs/benchmarks/solvers-3d.md, "Keeping the factorisation across steps".
    jacobian_carry: int = 0
    #: Keep the LU factorisation of an older Jacobian as the preconditioner of GMRES, which
    #: solves each Newton iteration's system (to 1e-10) with the Jacobian assembled fresh, so
    #: Newton keeps its exact-Jacobian iterates; a solve of more than this many iterations has
    #: the next Jacobian factorised, one not converged in twice as many is finished with a
    #: fresh factorisation (0: off, a factorisation per Jacobian). Direct route only (`[solver]
    #: linear`), without `snes_ksp_ew`. Pays where Newton's Jacobians change little between
    #: factorisations (a steady hold: 4 factorisations for 31 iterations on a relaxing column);
    #: not on the line loads, whose Jacobians change enough between Newton iterations that a
    #: one-iteration-old factor needs 14-30 GMRES iterations: line-load-3d 42 factorisations
    #: instead of 78 for 1 359 GMRES iterations, the same cost; 2D slower (a triangular solve
    #: is 1/4 of a factorisation there). stepping.FactorReuse; docs/benchmarks/solvers-3d.md.
    factor_reuse: int = 0
    #: `factor_reuse` in held steps only (the load the same at the step's start, middle and
    #: end, as for `hold_growth`): there Newton's systems are solved by flexible GMRES (to
    #: 1e-10) on the LU factors the solver holds, the next Jacobian factorised after a solve
    #: of more than this many iterations, one not converged in twice as many finished by a
    #: fresh factorisation; every other solve (the ramp's, the predictor's own) is the direct
    #: route's (0: off). Under a held load only the tissues' relaxation moves the state, and
    #: the factors that solved the last step still nearly solve the next one: on the 3D line
    #: load (15), the hold's 6 steps take 3 factorisations instead of 8, the same Newton
    #: iterations and answers (docs/benchmarks/solvers-3d.md, "The hold's Newton solves on the
    #: kept factors"), where `factor_reuse` everywhere did not pay (the ramp's Jacobians
    #: change too much). Direct route only (the iterative route, which has no factors, solves
    #: as without it), without `snes_ksp_ew`, and not with `factor_reuse` (which keeps the
    #: factors everywhere already).
    hold_factor_reuse: int = 0
    #: "iterations": grow by `growth` after easy steps. "error": steps chosen by their
    #: estimated local time-integration error (rtol, atol); `growth` is then the largest
    #: factor from one step to the next.
    control: str = "iterations"
    #: "backward-euler" (first order) or "bdf2" (variable-step BDF2, second order) for the
    #: biphasic mass balance; "generalized-alpha" for dynamics (a model with inertia): the
    #: Wood–Bossak–Zienkiewicz method for the inertia (inertia.py), BDF2 for the mass balance.
    scheme: str = "backward-euler"
    #: "generalized-alpha" (dynamics): the spectral radius ρ∞ ∈ [0, 1] at Δt → ∞ of the
    #: Wood–Bossak–Zienkiewicz method (1: trapezoidal rule, no numerical dissipation; 0.8
    #: damps the unresolved mesh modes that contact and kinks of the load excite while
    #: keeping the resolved ones: a relative period error and damping ~(ωΔt)²).
    rho_inf: float = 0.8
    #: Steps per shortest period of a periodic load (a history with `period`, after its
    #: `onset`): the largest step there is period/steps_per_period.
    steps_per_period: int = 40
    #: Error control: per unknown field, max |local error| <= atol + rtol * (largest |value|
    #: the field has reached). atol in the unknowns' units, mm (displacement) and MPa
    #: (pressure): the floor that keeps the first steps from rest, where every field is still
    #: tiny, from asking more than Newton's own accuracy (its residual tolerance, snes_atol).
    rtol: float = 1e-3
    atol: float = 1e-6  # error control: the absolute floor (mm, MPa), see rtol
    safety: float = 0.9  # the next step aims at safety × the tolerance

    def __post_init__(self):
        self._check_types()
        if not 0 < self.dt_min <= self.dt_initial <= self.dt_max:
            raise ValueError("need 0 < dt_min <= dt_initial <= dt_max")
        if not (self.growth >= 1 and 0 < self.cut < 1 and self.max_cuts >= 0):
            raise ValueError("need growth >= 1, 0 < cut < 1, max_cuts >= 0")
        if not (self.hold_growth == 0 or self.hold_growth >= 1):
            raise ValueError(f"need hold_growth = 0 (as growth) or >= 1, got {self.hold_growth}")
        if self.control not in CONTROLS:
            raise ValueError(f"control must be one of {CONTROLS}, got {self.control!r}")
        if self.scheme not in SCHEMES:
            raise ValueError(f"scheme must be one of {SCHEMES}, got {self.scheme!r}")
        if not (self.rtol >= 0 and self.atol >= 0 and self.rtol + self.atol > 0
                and 0 < self.safety <= 1):
            raise ValueError("need rtol >= 0, atol >= 0, rtol + atol > 0, 0 < safety <= 1")
        if not 0.0 <= self.jacobian_reuse < 1.0:
            raise ValueError(f"need 0 <= jacobian_reuse < 1, got {self.jacobian_reuse}")
        self._check_carry()
        self._check_tangent()
        count("factor_reuse", self.factor_reuse, "Krylov iterations", "factor_reuse = 15")
        self._check_hold_factors()
        if not 0.0 <= self.rho_inf <= 1.0:
            raise ValueError(f"need 0 <= rho_inf <= 1, got {self.rho_inf}")
        if isinstance(self.steps_per_period, bool) or not (
                isinstance(self.steps_per_period, int) and self.steps_per_period >= 4):
            raise ValueError(f"steps_per_period must be an integer >= 4 (a step per quarter "
                             f"period at least), got {self.steps_per_period!r}")
        if self.scheme == "generalized-alpha" and self.control == "error":
            raise InputError("control", "'error' has no error estimate for the "
                             "generalized-alpha scheme.", "use control = 'iterations' "
                             "(steps_per_period sets the accuracy).")
        if self.scheme in SECOND_ORDER_RATE and not max(self.growth, self.hold_growth) < \
                BDF2_GROWTH_LIMIT:
            raise ValueError(f"BDF2 is unstable for step ratios above 1 + √2: need growth and "
                             f"hold_growth < {BDF2_GROWTH_LIMIT:.4f}, got {self.growth} and "
                             f"{self.hold_growth}")

    def _check_types(self) -> None:
        """Each key a finite number, a whole number or a switch, as its default is: a text
        fails the comparisons below with Python's words, a fraction of a count or a NaN
        passes them."""
        for f in dataclasses.fields(self):
            value, default = getattr(self, f.name), f.default
            if isinstance(default, bool):
                ok, what = isinstance(value, bool), "true or false"
            elif isinstance(default, int):
                ok = isinstance(value, numbers.Integral) and not isinstance(value, bool)
                what = "a whole number"
            elif isinstance(default, float):
                ok = (isinstance(value, numbers.Real) and not isinstance(value, bool)
                      and math.isfinite(value))
                what = "a finite number"
            else:
                continue
            if not ok:
                raise InputError(f"steps.{f.name}", f"must be {what}, got {value!r}.",
                                 f"write e.g. {f.name} = {str(default).lower()}.")

    def _check_carry(self) -> None:
        """`jacobian_carry`: a count of Newton iterations, and only with `jacobian_reuse`,
        whose threshold is the carried Jacobian's fallback."""
        carry = count("jacobian_carry", self.jacobian_carry, "Newton iterations",
                      "jacobian_carry = 4")
        if carry > 0 and not self.jacobian_reuse > 0:
            raise InputError("jacobian_carry", f"a carry ({carry}) needs jacobian_reuse > 0, "
                             "whose threshold judges the kept Jacobian (without it, one that "
                             "stops contracting would never be reassembled).",
                             "set jacobian_reuse too (e.g. 0.05), or jacobian_carry = 0.")

    def _check_hold_factors(self) -> None:
        """`hold_factor_reuse`: a count of Krylov iterations, and not with `factor_reuse`."""
        held = count("hold_factor_reuse", self.hold_factor_reuse, "Krylov iterations",
                     "hold_factor_reuse = 10")
        if held > 0 and self.factor_reuse > 0:
            raise InputError("hold_factor_reuse", f"keeps the LU factors in held steps, but "
                             f"factor_reuse = {self.factor_reuse} keeps them in every step.",
                             "set one of them (the other 0).")

    def _check_tangent(self) -> None:
        """`tangent_reuse` serves the tangent predictor: only with `tangent_start`."""
        if self.tangent_reuse and not self.tangent_start:
            raise InputError("tangent_reuse", "reuses a factorisation for the tangent "
                             "predictor, which is off (tangent_start = false).",
                             "set tangent_start = true too, or tangent_reuse = false.")


def check_factor_reuse(limit: int, linear: str, petsc_options: dict | None = None,
                       where: str = "steps.factor_reuse") -> None:
    """A kept factorisation is the direct route's LU: the iterative route has its own
    preconditioner (and its own reuse options). Its solves are exact: Eisenstat–Walker's
    inexact Newton (`snes_ksp_ew`) sets the Krylov tolerance in the KSP's pre-solve hook,
    which the kept factorisation's hook replaces; and inexact solves cost this contact Newton
    iterations and cuts (2D line load, ksp_rtol 1e-6: 98 iterations and a cut against 89;
    docs/benchmarks/solvers-3d.md)."""
    key = where.rsplit(".", 1)[-1]  # factor_reuse or hold_factor_reuse: the fix names it
    if limit > 0 and linear != "direct":
        raise InputError(where, f"keeps the direct route's LU factorisation, but the linear "
                         f"solver is {linear!r}.",
                         f'use {key} = 0 with linear = "iterative", or linear = "direct".')
    ew = (petsc_options or {}).get("snes_ksp_ew", False)
    if limit > 0 and str(ew).lower() not in ("false", "0", "no"):
        raise InputError(where, "solves every Newton iteration to 1e-10, which inexact "
                         "Newton (solver.snes_ksp_ew) would loosen.",
                         f"drop solver.snes_ksp_ew, or set {key} = 0.")


@dataclass
class StepReport:
    step: int
    time: float
    dt: float
    load: float
    newton_iterations: int
    cuts: int
    wall_time_s: float
    #: Krylov iterations of the Newton iterations counted in `newton_iterations` (one per
    #: Newton iteration with the direct solver; attempts that were cut count in neither).
    linear_iterations: int = 0
    diagnostics: dict[str, float] = field(default_factory=dict)
    next_dt: float = math.nan  # the step size planned next (a checkpoint stores it)
    #: Error control: the accepted step's error estimate over the tolerance (<= 1), and the
    #: attempts redone because it was above.
    error: float = math.nan
    rejected: int = 0

    def row(self) -> dict[str, float]:
        row = asdict(self)
        row.update(row.pop("diagnostics"))
        return row
