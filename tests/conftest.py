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
