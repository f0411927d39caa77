"""The stepping package's pure parts: the step-size policies against their closed forms, and the
option modules a scene reads without PETSc. (The stepper itself: test_solver.py,
test_timestep.py, test_compaction.py.)"""

import ast
import math
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from fingertip_dolfinx.stepping.controllers import (
    ERROR_CUT_MIN,
    ErrorControl,
    IterationControl,
    Outcome,
    PeriodLimit,
    bdf2_weights,
    controller,
    error_factor,
    lagrange,
    milne_factor,
)
from fingertip_dolfinx.stepping.options import StepOptions

PACKAGE = Path(__file__).resolve().parents[1] / "fingertip_dolfinx"
EPS = 4 * np.finfo(float).eps


def test_bdf2_weights_at_equal_steps_and_exact_for_quadratics():
    assert bdf2_weights(1.0) == (1.5, -2.0, 0.5)
    # Δt_n ẋ(t_{n+1}) = a₀ x_{n+1} + a₁ x_n + a₂ x_{n−1} for x = t², at any step ratio
    for dt_old, dt in ((1.0, 0.3), (0.2, 0.45), (1.0, 2.4)):
        t0, t1, t2 = 0.7, 0.7 + dt_old, 0.7 + dt_old + dt
        a0, a1, a2 = bdf2_weights(dt / dt_old)
        assert a0 * t2**2 + a1 * t1**2 + a2 * t0**2 == pytest.approx(dt * 2 * t2, rel=1e-13)


def test_milne_factors_at_equal_steps():
    assert milne_factor(1, (0.1, 0.1)) == pytest.approx(1 / 3, rel=EPS)
    assert milne_factor(2, (0.1, 0.1, 0.1)) == pytest.approx(2 / 11, rel=EPS)


def test_lagrange_predictor_is_exact_for_its_degree():
    points = [(0.0, [np.array([1.0])]), (0.5, [np.array([2.0])]), (1.5, [np.array([5.0])])]
    x = lambda t: 1 + 5 / 3 * t + 2 / 3 * t**2  # noqa: E731  (the quadratic through them)
    assert all(x(t) == pytest.approx(v[0][0]) for t, v in points)
    assert lagrange(points, 2.0)[0][0] == pytest.approx(x(2.0), rel=1e-14)
    assert lagrange(points[1:], 2.0)[0][0] == pytest.approx(6.5, rel=1e-14)  # the line


def test_error_factor_is_the_safety_at_the_tolerance_and_clipped():
    assert error_factor(1.0, 2, 0.9, 1.5) == 0.9
    assert error_factor(1e-12, 2, 0.9, 1.5) == 1.5  # growth clipped at the limit
    assert error_factor(1e12, 1, 0.9, 1.5) == ERROR_CUT_MIN  # shrinking clipped too
    assert error_factor(0.0, 1, 0.9, 1.5) == 1.5
    assert error_factor(8.0, 2, 0.9, 1.0) == pytest.approx(0.45, rel=EPS)  # 0.9 · 8^(−1/3)


def _error_control(**kw):
    return ErrorControl(StepOptions(**{"control": "error", "scheme": "bdf2", "dt_max": 10.0, **kw}))


def test_error_control_next_step():
    control = _error_control(growth=1.5, safety=0.9)
    at = lambda err, **kw: control.next_dt(Outcome(taken=0.2, planned=0.2, iterations=3,  # noqa: E731
                                                   cuts=0, error=err, order=2, **kw))
    assert at(1.0) == pytest.approx(0.2 * 0.9, rel=EPS)
    assert at(1e-9) == pytest.approx(0.2 * 1.5, rel=EPS)  # growth clipped at the limit
    # a doubled step (two halves of 0.2): one step Δt errs 2 err (Δt/0.2)² as much
    assert at(1.0, doubled=True) == pytest.approx(0.2 / math.sqrt(2) * 0.9, rel=EPS)
    assert at(1e-9, doubled=True) == pytest.approx(1.5 * 0.1, rel=EPS)  # the halves' ratio
    hard = control.next_dt(Outcome(0.2, 0.2, 3, cuts=1, error=1e-9, order=2))
    assert hard == 0.2  # no growth right after a cut
    # cut short by a breakpoint: the planned step is kept, but under BDF2 the step ratio wins
    short = Outcome(0.05, 0.2, 3, 0, error=0.5, order=1)
    euler = ErrorControl(StepOptions(control="error", growth=1.5))
    assert euler.next_dt(short) == 0.2
    assert control.next_dt(short) == pytest.approx(1.5 * 0.05, rel=EPS)
    assert _error_control(dt_max=0.25).next_dt(Outcome(0.2, 0.2, 3, 0, 1e-9, 2)) == 0.25


def test_error_control_rejects_shorter_and_never_lands_on_the_same_time():
    control = _error_control(safety=0.9)
    free = control.reject(8.0, 2, 1.0, 1.2, lambda dt: 1.0 + dt)
    assert free == pytest.approx(0.2 * 0.45, rel=1e-12)
    stretched = control.reject(1.01, 1, 1.0, 1.2, lambda dt: 1.2)  # a mark pulls it back
    assert stretched == pytest.approx(0.75 * 0.2, rel=1e-12)
    assert control.cut(0.2) == 0.2 * StepOptions().cut


def test_iteration_control_grows_after_easy_steps_only():
    opts = StepOptions(growth=1.5, easy_iterations=6, dt_max=0.25, cut=0.5)
    control = IterationControl(opts)
    assert control.next_dt(Outcome(taken=0.1, planned=0.1, iterations=6, cuts=0)) == \
        pytest.approx(0.15, rel=EPS)
    assert control.next_dt(Outcome(0.05, 0.1, 2, 0)) == pytest.approx(0.15, rel=EPS)
    assert control.next_dt(Outcome(0.1, 0.1, 7, 0)) == 0.1  # hard: kept
    assert control.next_dt(Outcome(0.1, 0.1, 2, 1)) == 0.1  # after a cut: kept
    assert control.next_dt(Outcome(0.2, 0.2, 2, 0)) == 0.25  # at most dt_max
    assert control.cut(0.1) == 0.05
    assert type(controller(opts)) is IterationControl
    assert type(controller(StepOptions(control="error"))) is ErrorControl


def test_period_limit_from_the_onset_on():
    limit = PeriodLimit(SimpleNamespace(period=0.004, onset=1.0), steps_per_period=40)
    assert limit(0.5, 0.1) == 0.1
    assert limit(1.0, 0.1) == pytest.approx(1e-4, rel=EPS)
    assert PeriodLimit(SimpleNamespace(), 40)(5.0, 0.1) == 0.1


def test_option_modules_load_without_petsc(repo_root):
    """What a scene needs (its step, linear-solver and harmonic options) imports no PETSc."""
    code = ("import sys, fingertip_dolfinx.stepping.options, fingertip_dolfinx.stepping."
            "controllers, fingertip_dolfinx.stepping.tolerance, fingertip_dolfinx.harmonic_options;"
            "print(sorted(m for m in ('petsc4py', 'dolfinx') if m in sys.modules))")
    env = {**os.environ, "PYTHONPATH": str(repo_root)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=env, cwd=repo_root, check=True).stdout
    assert out.strip() == "[]"


def _package_imports(path: Path) -> tuple[set[Path], set[str]]:
    """The package files `path` imports (relative imports, with the packages' __init__ that
    Python runs on the way) and the outside modules it imports (dotted names)."""
    files, outside = set(), set()
    here = path.parent
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            outside.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0:
            outside.add(node.module)
        elif isinstance(node, ast.ImportFrom):
            base = here
            for _ in range(node.level - 1):
                base = base.parent
            for part in (node.module or "").split(".") if node.module else []:
                if (base / "__init__.py").exists():
                    files.add(base / "__init__.py")
                base = base / part
            targets = [base] if node.module else [base / a.name for a in node.names]
            for target in targets:
                files.add(target / "__init__.py" if target.is_dir() else
                          target.with_suffix(".py"))
    return {f for f in files if f.exists()}, outside


def test_scene_imports_no_petsc_module():
    """scene.py is data: no module it imports, directly or through others, imports petsc4py
    or DOLFINx's PETSc layer. (DOLFINx itself loads petsc4py when it is installed, and the model
    options come with the model's UFL: so this checks the package's own import chain, not
    sys.modules.)"""
    seen, todo, offenders = set(), [PACKAGE / "scene.py"], []
    while todo:
        path = todo.pop()
        if path in seen:
            continue
        seen.add(path)
        files, outside = _package_imports(path)
        todo += files
        offenders += [f"{path.relative_to(PACKAGE)}: {m}" for m in outside
                      if m.split(".")[0] == "petsc4py" or m.startswith("dolfinx.fem.petsc")]
    assert PACKAGE / "stepping" / "options.py" in seen  # the walk follows subpackages
    assert not offenders, offenders


def test_a_failed_attempt_after_one_that_closed_the_pores_is_cut_not_a_crash():
    """Two earlier attempts of the step closed the pores (counted; the accepted states were not
    heading there, so they were cut), this one failed without closing them: the step is cut
    (no compaction: None), where the count alone once made the stepper read the limit of a
    closed iterate that does not exist (AttributeError)."""
    from fingertip_dolfinx.stepping.stepper import TimeStepper, _Step

    stepper = SimpleNamespace(problem=SimpleNamespace(), snes=None, _closed=None,
                              _heading_for=lambda *args: True)
    step = _Step(t=0.0, dt=0.1, started=0.0, linear_before=0, reason=-5, t_first=0.1,
                 closed_iterates=2)
    assert TimeStepper._compaction(stepper, SimpleNamespace(states=[]), step) is None
    assert step.closed_iterates == 2 and "Newton did not converge" in step.why


@pytest.mark.parametrize("cuts, said", [(1, "failed once, the last"), (3, "failed 3 times")])
def test_a_failed_step_says_how_often_in_words(cuts, said):
    """The stop after the step's attempts names their number ('failed 1 times' before)."""
    from fingertip_dolfinx.stepping.diagnosis import cuts_error

    text = str(cuts_error(0.81, 0.8100125, (0.81, 0.8100125), cuts, "Newton did not converge", 0))
    assert said in text and "1 times" not in text
