"""Biphasic tissue: Holmes–Mow permeability, compaction guard, drained equilibrium."""

import dolfinx.fem.petsc  # noqa: F401
import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI

from fingertip_dolfinx.errors import CompactionError
from fingertip_dolfinx.physics import materials as mat
from fingertip_dolfinx.physics import poroelasticity as poro
from fingertip_dolfinx.stepping import StepOptions, TimeStepper
from fingertip_dolfinx.studies.problems import ConfinedBlock, confined_drained_stress

HM = mat.HOLMES_MOW_SUBCUTANEOUS
TISSUE = mat.SUBCUTANEOUS_BIPHASIC


def test_permeability_formula_ufl_and_numpy():
    msh = mesh.create_unit_square(MPI.COMM_SELF, 1, 1)
    Jc = fem.Constant(msh, 1.0)
    expr = fem.Expression(HM.permeability(Jc), np.array([[1 / 3, 1 / 3]]))
    for J in (0.45, 0.8, 1.0, 1.3):
        Jc.value = J
        exact = 1e-3 * ((J - 0.4) / 0.6) ** 0.0848 * np.exp(4.638 * (J**2 - 1) / 2)
        assert expr.eval(msh, np.array([0], dtype=np.int32)).item() == pytest.approx(exact, 1e-14)
        assert HM.permeability_np(J) == pytest.approx(exact, rel=1e-14)
    assert HM.permeability_np(1.0) == pytest.approx(1e-3)


def test_permeability_vanishes_at_compaction():
    """k → 0 as J → φ0, monotonically but slowly: ((J − φ0)/(1 − φ0))^κ with κ = 0.0848
    is still 0.056 at J − φ0 = 1e-15, so the solver must guard J itself (check_compaction)."""
    J = 0.4 + np.logspace(-1, -15, 29)
    k = HM.permeability_np(J)
    assert np.all(np.diff(k) < 0)
    assert k[-1] / HM.k0 < 0.06
    assert HM.permeability_np(0.4) == 0.0


def test_check_compaction_message():
    mat.check_compaction(0.41, "subcutaneous", HM.phi0)
    with pytest.raises(CompactionError) as err:
        mat.check_compaction(0.39, "subcutaneous at (1.0, -5.2) mm", HM.phi0)
    text = str(err.value)
    assert "subcutaneous at (1.0, -5.2) mm" in text and "0.39" in text and "phi0 = 0.4" in text
    assert "less deeply" in text and "smaller time steps cannot help" in text


def test_consolidation_time_scale_is_long():
    """MODEL.md: drainage over millimetres takes ~1e6 s with these parameters."""
    assert 1e5 < poro.consolidation_time(TISSUE, 3.0) < 1e7


def test_confined_compression_equilibrium_is_drained_hyperfoam():
    """Column, sides and bottom on rollers, top compressed by 20 % and drained (p = 0).
    One backward-Euler step with Δt ≫ drainage time reaches equilibrium: p ≈ 0 and the
    total stress equals the drained hyperfoam stress of F = diag(1, 0.8) in closed form."""
    column = ConfinedBlock(1, 2, lambda t: 0.2, tissue=TISSUE, width=0.5, drained_top=True,
                           top_displacement=True)
    stepper = TimeStepper(column, StepOptions(dt_initial=1e16, dt_min=1e16, dt_max=1e16,
                                              max_cuts=0, extrapolate=False),
                          {"snes_linesearch_type": "basic", "snes_rtol": 1e-12,
                           "snes_atol": 1e-16, "snes_max_it": 30}, prefix="test_confined_")
    stepper.run(column.load, 1e16)
    assert stepper.snes.getConvergedReason() > 0
    msh, u, p = column.msh, column.u, column.p

    P11, P22 = confined_drained_stress(TISSUE.solid, 0.8)
    points = np.array([[0.2, 0.3], [0.7, 0.1]])
    P = poro.total_first_piola(u, p, TISSUE)
    J = ufl.det(ufl.Identity(2) + ufl.grad(u))
    vals = fem.Expression(ufl.as_vector([P[0, 0], P[1, 1], P[0, 1], p, J]), points)
    out = vals.eval(msh, np.arange(msh.topology.index_map(2).size_local, dtype=np.int32))
    out = out.reshape(-1, 5)
    print(f"drained P22 = {P22:.6e} MPa; computed {out[:, 1]}; "
          f"max |p| = {np.abs(out[:, 3]).max():.1e}")
    assert np.allclose(out[:, 1], P22, rtol=1e-8, atol=0)
    assert np.allclose(out[:, 0], P11, rtol=1e-8, atol=0)
    assert np.abs(out[:, 3]).max() < 1e-8 * abs(P22)
    assert np.allclose(out[:, 4], 0.8, rtol=1e-12)
    mat.check_compaction(out[:, 4].min(), "confined column", TISSUE.phi0)  # 0.8 > φ0: passes
