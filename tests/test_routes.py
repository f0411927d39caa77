"""`ft.run` and `fingertip run` take the same route for the same scene: the frequency route for
a `[harmonic]` table, the adaptive loop for a tolerance, the model `--fidelity auto` picks; and
they write the same numbers. The heavy calls are replaced by recorders where only the route is
asserted; one coarse run is made for real by both."""

import csv
import math

import numpy as np
import pytest
from mpi4py import MPI

import fingertip_dolfinx as ft
from fingertip_dolfinx import frequency_response, runner
from fingertip_dolfinx.cli import main
from fingertip_dolfinx.errors import InputError
from fingertip_dolfinx.keys import KEYS
from fingertip_dolfinx.outputs import read_csv
from fingertip_dolfinx.studies import adaptivity
from fingertip_dolfinx.studies.fidelity import LADDER

#: A coarse one-point run in steps of 0.5 s, no pictures: ~20 s.
SETS = ["section.mesh.min_size=0.4", "section.mesh.max_size=1.5", "section.mesh.bone_size=2.0",
        "output.profile_points=21", "steps.dt_initial=0.5", "steps.dt_max=0.5",
        "output.pictures=false"]
HARMONIC = ['harmonic.state="held"']


def _cli(scene: str, out, sets, *flags) -> int:
    return main(["run", scene, *(a for s in sets for a in ("--set", s)), *flags, "--quiet",
                 "--out", str(out)])


class Called(Exception):
    """Raised by a recorder in place of a heavy computation: its arguments."""


def _recorder(name: str):
    def record(*args, **kwargs):
        raise Called(name, args, kwargs)
    return record


@pytest.fixture
def recorders(monkeypatch):
    """The three routes' computations replaced by recorders."""
    monkeypatch.setattr(runner, "run_scene", _recorder("time"))
    monkeypatch.setattr(adaptivity, "adapt", _recorder("adaptive"))
    monkeypatch.setattr(frequency_response, "run_frequency_response", _recorder("frequency"))


def _route_taken(call) -> tuple:
    with pytest.raises(Called) as called:
        call()
    return called.value.args


# --- the decision ------------------------------------------------------------------------------


@pytest.mark.parametrize("sets, kwargs, route", [
    ([], {}, "time"),
    (HARMONIC, {}, "frequency"),
    ([], {"frequencies": "10,100"}, "frequency"),
    ([], {"state": "relaxed"}, "frequency"),
    (["accuracy.tol=0.05"], {}, "adaptive"),
    ([], {"tol": 0.05}, "adaptive"),
    ([], {"max_levels": 3}, "adaptive"),
])
def test_route_of_reads_the_scene_and_the_arguments(sets, kwargs, route):
    assert ft.route_of(ft.load_scene("1pt", sets), **kwargs) == route


@pytest.mark.parametrize("sets, flags, route", [
    (HARMONIC, (), "frequency"),
    (["accuracy.tol=0.05"], (), "adaptive"),
    ([], ("--tol", "0.05", "--max-levels", "3"), "adaptive"),
    ([], (), "time"),
])
def test_api_and_command_line_take_the_same_route(recorders, tmp_path, sets, flags, route):
    """A scene with [harmonic] goes to the frequency route, one with [accuracy] tol (or --tol)
    to the adaptive loop, from Python as from the command line, with the same scene and
    options (before, ft.run ran every scene once in time)."""
    kwargs = {"--tol": "tol", "--max-levels": "max_levels"}
    given = {kwargs[f]: float(v) if f == "--tol" else int(v) for f, v in zip(flags[::2],
                                                                               flags[1::2])}
    api = _route_taken(lambda: ft.run(ft.load_scene("1pt", sets), tmp_path / "api",
                                      progress=False, **given))
    cli = _route_taken(lambda: _cli("1pt", tmp_path / "cli", sets, *flags))
    assert api[0] == cli[0] == route
    scene_api, scene_cli = api[1][0], cli[1][0]
    assert _same(scene_api, scene_cli)
    if route == "adaptive":
        assert api[1][2] == cli[1][2]  # AdaptOptions: tol and levels
        assert api[1][2].tol == pytest.approx(0.05)


def _same(a, b) -> bool:
    """Two scenes alike but for the overrides' text (the Python and --set spellings)."""
    from fingertip_dolfinx.scene import scene_record

    return scene_record(a) == scene_record(b)


def test_fidelity_auto_picks_the_same_model_from_both(recorders, tmp_path):
    """`--fidelity auto` with a table: the API and the command line run the model the table
    names (here the drained hyperfoam: the cheapest rung within 5 %)."""
    table = tmp_path / "fidelity.csv"
    errors = {"continuum": 0.3, "hyperfoam": 0.04, "+ skin QLV": 0.03, "+ undrained": 1e-5,
              "full": 0.0, "full, rigid bone": 0.02}
    with table.open("w", newline="") as f:
        writer = csv.DictWriter(f, ["model", "max_error", *(f"error_{k}" for k in KEYS)])
        writer.writeheader()
        for name, _ in LADDER:
            writer.writerow({"model": name, "max_error": errors[name],
                             **{f"error_{k}": errors[name] for k in KEYS}})
    said = []
    api = _route_taken(lambda: ft.run("1pt", tmp_path / "api", fidelity="auto", tol=0.05,
                                      fidelity_table=table, progress=False, say=said.append))
    cli = _route_taken(lambda: _cli("1pt", tmp_path / "cli", [], "--fidelity", "auto",
                                    "--fidelity-table", str(table)))
    assert api[0] == cli[0] == "time"
    for scene in (api[1][0], cli[1][0]):
        assert scene.model.subcutaneous == "drained" and not scene.model.skin_viscoelastic
    assert any("picked 'hyperfoam'" in line for line in said)


def test_fidelity_auto_needs_the_scene_file(tmp_path):
    with pytest.raises(InputError, match="a Scene object has no file"):
        ft.run(ft.load_scene("1pt"), tmp_path, fidelity="auto")


def test_the_frequency_route_refuses_what_it_cannot_do(recorders, monkeypatch, tmp_path):
    """Refused before anything is computed: `max_levels` was silently dropped, and
    `fidelity="auto"` ran its ladder of six runs before being refused."""
    from fingertip_dolfinx.studies import fidelity

    monkeypatch.setattr(fidelity, "run_fidelity_study", _recorder("fidelity ladder"))
    for kwargs, flag in (({"resume": True}, "--resume"), ({"tol": 0.01}, "--tol"),
                         ({"max_levels": 3}, "--max-levels"),
                         ({"fidelity": "auto"}, "--fidelity auto")):
        for route in ({"overrides": HARMONIC}, {"frequencies": "10,100"}):
            with pytest.raises(InputError, match=f"{flag}: is not available on the frequency"):
                ft.run("1pt", tmp_path, progress=False, **route, **kwargs)


# --- the same numbers --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def both(tmp_path_factory):
    """The coarse 1pt run made by `fingertip run` and by `ft.run` (a mapping of overrides)."""
    out = MPI.COMM_WORLD.bcast(tmp_path_factory.mktemp("routes"), root=0)
    assert _cli("1pt", out / "cli", SETS) == 0
    result = ft.run("1pt", out / "api", overrides=SETS, progress=False)
    return out, result


def test_api_and_command_line_write_the_same_numbers(both):
    out, result = both
    assert result.route == "time" and isinstance(result, ft.Result)
    for name in ("history.csv", "depth_profiles.csv", "surface_profile.csv"):
        cli, api = read_csv(out / "cli" / name), read_csv(out / "api" / name)
        assert set(cli) == set(api)
        for column in cli:
            if column != "wall_time_s":
                np.testing.assert_array_equal(api[column], cli[column], err_msg=column)
    with np.load(out / "cli" / "fields_t1s.npz") as cli:
        fields = result.fields(1.0)
        for name in cli.files:
            np.testing.assert_array_equal(fields[name], cli[name], err_msg=name)
    assert result.force[-1] > 0 and math.isfinite(result.force[-1])


@pytest.mark.slow
def test_a_harmonic_scene_gives_the_same_frequency_response_from_both(tmp_path_factory):
    """vibrotactile with a [harmonic] table (no --frequencies: the protocol's 250 Hz), coarse:
    ft.run takes the frequency route and writes what `fingertip run` writes, number for
    number (a minute each on a shared machine)."""
    out = MPI.COMM_WORLD.bcast(tmp_path_factory.mktemp("harmonic"), root=0)
    sets = [*SETS[:3], *HARMONIC, "harmonic.frequencies=[10.0, 100.0]"]
    assert _cli("vibrotactile", out / "cli", sets) == 0
    result = ft.run("vibrotactile", out / "api", overrides=sets, progress=False)
    assert isinstance(result, ft.FrequencyResult) and result.route == "frequency"
    for name in ("frequency_response.csv", "receptor_transfer.csv", "thresholds.csv"):
        cli, api = (list(csv.DictReader((out / d / name).open())) for d in ("cli", "api"))
        assert len(api) == len(cli) > 0
        for a, c in zip(api, cli):
            a.pop("solve_s", None), c.pop("solve_s", None)  # timings
            assert a == c, name
    np.testing.assert_array_equal(result.frequencies, [10.0, 100.0])
    omega = 2 * np.pi * result.frequencies  # Z = K/(iω), from the table's own columns
    np.testing.assert_allclose(result.impedance, result.stiffness / (1j * omega), rtol=1e-9)
