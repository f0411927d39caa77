"""Newton's residual without DOLFINx's Dirichlet lifting where the lifting adds zero
(stepping/residual.py), on a confined Holmes–Mow column whose top displacement is prescribed:
a non-homogeneous condition that moves in the ramp and is held after it, with homogeneous
rollers and a drained top (p = 0) besides."""

import numpy as np
import pytest
from mpi4py import MPI

from fingertip_dolfinx.loading import RampHold
from fingertip_dolfinx.physics import materials as mat
from fingertip_dolfinx.stepping import StepOptions, TimeStepper
from fingertip_dolfinx.studies.problems import ConfinedBlock

TIGHT = {"snes_rtol": 1e-12, "snes_atol": 1e-14}


def _residuals(stepper):
    """The residual at the unknowns' state three ways: the stepper's (skipping the lifting or
    not, as it decides), DOLFINx's (lifted) and the unlifted one, forced; as arrays."""
    import dolfinx.fem.petsc

    residual, x = stepper.residual, stepper.nonlinear.x
    dolfinx.fem.petsc.assign(stepper.problem.unknowns, x)
    vectors = [x.duplicate() for _ in range(3)]
    residual(stepper.snes, x, vectors[0])
    residual.assemble_lifted(stepper.snes, x, vectors[1])
    residual.assemble_unlifted(x, vectors[2])
    arrays = [v.getArray().copy() for v in vectors]
    for v in vectors:
        v.destroy()
    return arrays


@pytest.mark.mpi
def test_residual_skips_the_lifting_only_where_it_adds_zero():
    """Where the iterate meets every Dirichlet condition, the residual skips the lifting and
    equals DOLFINx's lifted one to the bit; where the prescribed top displacement has moved
    past the iterate, the lifting (the Jacobian times g − x on the top dofs) is not zero, and
    the residual keeps it: it equals DOLFINx's, not the unlifted one. A run of ramp and hold
    skips it at the iterates that meet the top's value and keeps it at each ramp step's start,
    where the top has just moved."""
    history = RampHold(0.01, 0.1, 3.0)
    column = ConfinedBlock(1, 8, history, tissue=mat.SUBCUTANEOUS_BIPHASIC, width=0.1,
                           drained_top=True, top_displacement=True)
    stepper = TimeStepper(column, StepOptions(dt_initial=0.025, dt_max=1.0, growth=2.0),
                          TIGHT, prefix="lifting_")
    stepper.run(history, history.end_time)
    counts = stepper.residual.skipped, stepper.residual.lifted
    assert min(counts) > 0

    ours, lifted, unlifted = _residuals(stepper)  # the held state: the top at its value
    assert stepper.residual.lifting_vanishes()
    assert np.array_equal(ours, lifted) and np.array_equal(ours, unlifted)
    assert np.linalg.norm(ours) > 0

    column.set_time(0.05)  # the top's prescribed value moves to half the depth
    ours, lifted, unlifted = _residuals(stepper)
    assert not stepper.residual.lifting_vanishes()
    assert np.array_equal(ours, lifted)
    scale = stepper.snes.getComm().tompi4py().allreduce(np.max(np.abs(lifted)), op=MPI.MAX)
    gap = np.max(np.abs(unlifted - lifted), initial=0.0)
    assert stepper.snes.getComm().tompi4py().allreduce(gap, op=MPI.MAX) > 1e-3 * scale
    stepper.close()
