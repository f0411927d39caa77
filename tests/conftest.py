"""Shared fixtures; MPI-aware: every rank runs each test, only rank 0 reports."""

import gc
from pathlib import Path

import pytest
from mpi4py import MPI

import fingertip_dolfinx  # noqa: F401  (sets up the DOLFINx wheel before dolfinx is imported)

REPO = Path(__file__).resolve().parents[1]


@pytest.hookimpl(trylast=True)  # after the terminal reporter has registered itself
def pytest_configure(config):
    if MPI.COMM_WORLD.size > 1 and MPI.COMM_WORLD.rank != 0:
        # One report is enough: silence the other ranks' terminal output.
        reporter = config.pluginmanager.get_plugin("terminalreporter")
        if reporter is not None:
            config.pluginmanager.unregister(reporter)


@pytest.fixture(scope="session")
def comm():
    return MPI.COMM_WORLD


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return REPO


@pytest.fixture
def shared_tmp_path(tmp_path_factory, comm):
    """A temporary directory that is the same on every rank (rank 0 creates it)."""
    path = tmp_path_factory.mktemp("shared") if comm.rank == 0 else None
    return Path(comm.bcast(str(path) if path else None, root=0))


@pytest.fixture
def world_and_alone(tmp_path_factory, comm):
    """Run a scene on all ranks and on each rank alone (COMM_SELF): a function of the scene
    that returns the two result directories, after checking that both solved the same
    problem (dofs) at the same times.

    On one rank the two runs are the same run, and the comparison can fail only through
    non-determinism: the test is skipped there (the default test command runs it on 2 ranks
    first)."""
    if comm.size == 1:
        pytest.skip("compares a run on several ranks with each rank alone: needs mpiexec -n 2+")
    from fingertip_dolfinx.outputs import read_csv
    from fingertip_dolfinx.runner import run_scene

    def run(scene) -> tuple[Path, Path]:
        shared = Path(comm.bcast(str(tmp_path_factory.mktemp("world")) if comm.rank == 0
                                 else None, root=0))
        alone = tmp_path_factory.mktemp(f"self{comm.rank}")
        parallel = run_scene(scene, shared, progress=False, comm=comm)
        serial = run_scene(scene, alone, progress=False, comm=MPI.COMM_SELF)
        assert parallel["dofs"] == serial["dofs"]
        times = [read_csv(d / "history.csv")["time_s"] for d in (shared, alone)]
        assert len(times[0]) == len(times[1])
        assert max(abs(a - b) for a, b in zip(*times)) <= 1e-12 * max(times[1])
        return shared, alone

    return run


@pytest.fixture(autouse=True)
def collectives_in_step(comm):
    """After each test, free PETSc objects on every rank at the same moment, then wait for all:
    their destruction is collective (MUMPS, VecScatter), and a rank that collects garbage
    later than the others would hang the next test under mpiexec."""
    yield
    gc.collect()
    comm.barrier()


@pytest.fixture
def vanishing_steps():
    """`values(problem, depths, sample, prefix)`: for each indentation depth, one vanishing time
    step (Δt = 1e-9 s, backward Euler) of the pressed `problem` to that depth and `sample()`
    after it; the problem's state is put back afterwards. The central difference of two such
    samples is the instantaneous (small-signal) derivative the frequency route must match."""
    from fingertip_dolfinx.harmonic import BACKWARD_EULER, StepOptions, TimeStepper

    def values(problem, depths, sample, prefix: str) -> list:
        saved = {k: a.copy() for k, a in problem.state_arrays().items()}
        stepper = TimeStepper(problem, StepOptions(), prefix=prefix)
        found = []
        problem.dt.value = 1e-9
        problem.rate_weights.value[:] = BACKWARD_EULER
        for d in depths:
            for o in problem.obstacles:
                o.y_tip.value = problem.y_touch + d
            assert stepper.solve_once()[0] > 0
            found.append(sample())
            problem.restore()
        stepper.close()
        problem.set_time(problem.time)
        for name, array in problem.state_arrays().items():
            array[:] = saved[name]
        return found

    return values


@pytest.fixture
def directional_error():
    """directional_error(snes, x) -> error(ε): with the residual F and Jacobian J already
    computed at x by the caller, d = J⁻¹F (the run's own linear solver) and
    error(ε) = ‖(F(x + εd) − F(x − εd))/2ε − J d‖ / ‖J d‖, O(ε²) for an exact tangent."""
    def directional(snes, x):
        (F, _), (J, P, _) = snes.getFunction(), snes.getJacobian()
        ksp, d, Jd = snes.getKSP(), x.duplicate(), x.duplicate()
        ksp.setOperators(J, P)
        ksp.solve(F, d)
        J.mult(d, Jd)

        def error(eps):
            plus, minus, fp, fm = x.copy(), x.copy(), x.duplicate(), x.duplicate()
            plus.axpy(eps, d)
            minus.axpy(-eps, d)
            snes.computeFunction(plus, fp)
            snes.computeFunction(minus, fm)
            fp.axpy(-1.0, fm)
            fp.scale(0.5 / eps)
            fp.axpy(-1.0, Jd)
            return fp.norm() / Jd.norm()

        return error

    return directional
