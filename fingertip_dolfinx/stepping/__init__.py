"""Time stepping: step options, step-size policies, failure diagnosis, the linear solver inside
Newton and the stepper that drives a problem along a load history.

The modules, each using only those before it:

- `options`: `StepOptions`, `StepReport`, the PETSc defaults and the linear solvers' names, as
  data (no PETSc import: a scene validates its tables with them);
- `controllers`: the step-size policies (`IterationControl`, `ErrorControl`, `PeriodLimit`) and
  the closed forms they use (`bdf2_weights`, `milne_factor`);
- `tolerance`: a tolerance asked of the outputs turned into step options, and verified;
- `diagnosis`: why a step failed, compaction or Newton's overshoot, in messages;
- `linear`: the linear solver inside Newton (MUMPS LU, or FGMRES with a field split);
- `residual`: Newton's residual without DOLFINx's Dirichlet lifting where it adds zero;
- `stepper`: `TimeStepper`, the `Steppable` protocol a problem meets, `JacobianReuse`,
  `FactorReuse`.

The names below are imported from their module on first use, so that importing
`fingertip_dolfinx.stepping.options` (as scene.py does) loads no PETSc.
"""

from ..lazy import lazy_exports

#: Public name -> the module of this package that defines it.
_API = {
    **dict.fromkeys(("StepOptions", "StepReport", "DEFAULT_PETSC_OPTIONS", "CONTROLS",
                     "SCHEMES", "SECOND_ORDER_RATE", "BDF2_GROWTH_LIMIT", "LINEAR",
                     "check_linear"), "options"),
    **dict.fromkeys(("IterationControl", "ErrorControl", "Outcome", "PeriodLimit", "controller",
                     "bdf2_weights", "milne_factor", "lagrange", "error_factor",
                     "BACKWARD_EULER", "ERROR_CUT_MIN"), "controllers"),
    **dict.fromkeys(("TIME_SHARE", "RTOL_PER_BUDGET", "ATOL_PER_RTOL", "TIGHTEN",
                     "TOLERANCE_EXPONENT", "TIME_SAFETY", "tolerance_steps", "tightened",
                     "time_estimates", "verify_time"), "tolerance"),
    **dict.fromkeys(("SNES_REASONS", "distinct", "crosses", "compacted", "approach",
                     "overshoot_note", "newton_failure", "compaction_error", "cuts_error",
                     "dynamic_friction_note",
                     "error_stall_error"), "diagnosis"),
    **dict.fromkeys(("LinearSolver", "DIRECT_OPTIONS", "KSP_RTOL", "iterative_options",
                     "rigid_body_modes", "split_index_sets", "pressure_modulus",
                     "krylov_iterations"), "linear"),
    "UnliftedResidual": "residual",
    **dict.fromkeys(("TimeStepper", "Steppable", "JacobianReuse", "FactorReuse"), "stepper"),
}
__all__ = sorted(_API)


__getattr__, __dir__ = lazy_exports(__name__, _API)
