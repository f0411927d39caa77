"""errors.py: messages that name the input and the fix; failures on rank 0 stop every rank."""

import json
from pathlib import Path

import pytest

from fingertip_dolfinx.errors import InputError, RootRankError, on_root


def test_input_error_names_where_what_and_the_fix():
    error = InputError("--set protocol.depth=-1", "must be positive.", "use a depth > 0.")
    assert str(error) == "--set protocol.depth=-1: must be positive. Fix: use a depth > 0."


@pytest.mark.mpi
def test_on_root_returns_rank_zeros_value_on_every_rank(comm):
    assert on_root(comm, lambda: ("made on", comm.rank)) == ("made on", 0)


@pytest.mark.mpi
def test_a_failure_on_rank_zero_stops_every_rank(comm):
    """Without the broadcast of the failure the other ranks would wait for rank 0's value
    forever: the test would hang under mpiexec instead of passing."""
    def fail():
        raise InputError("size map", "file not found.", "give an existing file.")

    expected = InputError if comm.rank == 0 else RootRankError
    with pytest.raises(expected, match="file not found"):
        on_root(comm, fail)
    comm.barrier()  # every rank got here


@pytest.mark.mpi
def test_a_json_record_is_written_for_every_rank_or_fails_on_every_rank(comm, tmp_path_factory):
    """write_json returns on any rank only once rank 0 has written the file (a two-rank run
    read summary.json on rank 1 before rank 0 had written it), and rank 0's failure to write
    stops the others too instead of leaving them to read a file that never comes."""
    from fingertip_dolfinx.outputs import write_json

    folder = comm.bcast(str(tmp_path_factory.mktemp("json")) if comm.rank == 0 else None)
    path = Path(folder) / "summary.json"
    write_json(path, {"rank": comm.rank}, comm)
    assert json.loads(path.read_text()) == {"rank": 0}
    comm.barrier()
    if comm.rank == 0:
        path.unlink()
        path.mkdir()  # a folder in the file's place: rank 0 cannot write it
    comm.barrier()
    expected = OSError if comm.rank == 0 else RootRankError
    with pytest.raises(expected):
        write_json(path, {"rank": comm.rank}, comm)
    comm.barrier()
