"""The fidelity ladder and the automatic choice of model, on a coarse one-point scene."""

import pytest
from mpi4py import MPI

from fingertip_dolfinx.cli import main
from fingertip_dolfinx.keys import KEYS
from fingertip_dolfinx.studies.fidelity import LADDER, pick, read_table, run_fidelity_study

# The ladder runs the scene once per rung: a study (minutes), run with `make test-slow`.
pytestmark = pytest.mark.slow

COARSE = ["section.mesh.min_size=0.3", "section.mesh.max_size=1.2", "section.mesh.bone_size=2.0",
          "output.profile_points=61"]


@pytest.fixture(scope="module")
def ladder(tmp_path_factory):
    out = MPI.COMM_WORLD.bcast(tmp_path_factory.mktemp("fidelity"), root=0)
    rows = run_fidelity_study("1pt", out, COARSE, progress=False)
    return out, rows


def test_ladder_is_scored_against_the_full_model(ladder):
    out, rows = ladder
    assert [r["model"] for r in rows] == [name for name, _ in LADDER]
    full = next(r for r in rows if r["model"] == "full")
    assert full["max_error"] == 0.0
    for name in ("fidelity.csv", "fidelity.md", "fidelity.png"):
        assert (out / name).exists()
    assert read_table(out / "fidelity.csv")[0]["model"] == "continuum"


def test_one_second_is_undrained_and_the_drained_solid_is_not_enough(ladder):
    """The drainage time (~1e6 s) dwarfs the 1 s ramp: the undrained model reproduces the
    biphasic one to the Newton tolerance, while dropping the pore pressure (drained) changes
    the force by tens of per cent; the linear continuum misses by more still."""
    rows = {r["model"]: r for r in ladder[1]}
    assert rows["+ undrained"]["max_error"] < 1e-4
    assert rows["hyperfoam"]["error_force_N_per_mm_max_over_run"] > 0.1
    assert rows["continuum"]["max_error"] > rows["hyperfoam"]["max_error"]
    assert set(KEYS) <= set(rows["full"])


def test_auto_picks_the_lowest_adequate_rung(ladder):
    rows = ladder[1]
    model, why = pick(rows, 0.01)
    assert model == "+ undrained" and "hyperfoam" in why
    with pytest.raises(StopIteration):
        pick([r for r in rows if r["model"] == "continuum"], 0.01)


def test_run_with_auto_fidelity_uses_the_table(ladder, tmp_path, capsys):
    table = ladder[0] / "fidelity.csv"
    args = ["run", "1pt", "--fidelity", "auto", "--tol", "0.01", "--fidelity-table", str(table),
            "--quiet", "--out", str(tmp_path)]
    for override in COARSE:
        args += ["--set", override]
    assert main(args) == 0
    assert "picked '+ undrained'" in capsys.readouterr().err
