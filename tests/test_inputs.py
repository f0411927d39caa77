"""Scene input: overrides that replace a list of tables, error messages naming the source of
the bad value, paths relative to the scene file, `--check`, the help's list of scenes, the
title of a changed scene, and the message of a depth that was not written."""

import pytest

import fingertip_dolfinx as ft
from fingertip_dolfinx.cli import main
from fingertip_dolfinx.datafiles import builtin_names, find
from fingertip_dolfinx.errors import InputError
from fingertip_dolfinx.geometry.indenters import Cylinder
from fingertip_dolfinx.scene import TITLE_LENGTH, load_scene

CYLINDER = [{"file": "cylinder", "radius": 5.0}]


def _error(capsys, argv) -> str:
    assert main(argv) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1
    return lines[0]


def test_a_list_of_tables_replaces_the_list_from_python_config_and_set(tmp_path, capsys):
    """The 1pt bar becomes a 5 mm cylinder, whichever way the list is given."""
    from_python = load_scene("1pt", {"indenters": CYLINDER})
    from_set = load_scene("1pt", ['indenters=[{file = "cylinder", radius = 5.0}]'])
    assert from_python.indenters == from_set.indenters == [Cylinder(radius=5.0)]
    config = tmp_path / "c.toml"
    config.write_text('[[indenters]]\nfile = "cylinder"\nradius = 5.0\n')
    assert main(["run", "1pt", "--check", "--config", str(config)]) == 0
    assert "indenters cylinder" in capsys.readouterr().err


@pytest.mark.parametrize("overrides, source", [
    ({"protocol": {"dept": 0.5}}, 'overrides["protocol"]["dept"]: '),
    ({"materials": {"skin": {"prony": {"g": [0.5]}}}},
     'overrides["materials"]["skin"]["prony"]["g"]: materials.skin.prony'),
    ({"indenters": [{"file": "cylinder", "radius": -5.0}]}, 'overrides["indenters"]: '),
    (["output.times=[5.0]"], 'override "output.times=[5.0]": output.times'),
])
def test_a_python_override_is_named_not_the_packages_file(overrides, source):
    with pytest.raises(InputError) as error:
        load_scene("1pt", overrides)
    assert str(error.value).startswith(source)
    assert "1pt.toml" not in str(error.value) and "wu2004" not in str(error.value)


def test_set_and_config_are_named(tmp_path, capsys):
    assert _error(capsys, ["run", "1pt", "--check", "--set", "protocol.dept=0.5"]).startswith(
        "fingertip run: error: --set protocol.dept=0.5: protocol (ramp-hold).dept: unknown")
    config = tmp_path / "c.toml"
    config.write_text("[materials.skin.prony]\ng = [0.5]\n")
    assert _error(capsys, ["run", "1pt", "--check", "--config", str(config)]).startswith(
        f"fingertip run: error: --config {config}: materials.skin.prony")


def test_the_file_a_bad_value_is_in_is_named(tmp_path):
    """The scene file for its own [materials] table (not the materials set it overrides); the
    materials file and the indenter file for their own values."""
    protocol = "[protocol]\ndepth = 0.5\nramp_time = 1.0\nend_time = 1.0\n"
    scene = tmp_path / "s.toml"
    scene.write_text('[[indenters]]\nfile = "bar"\n' + protocol + "[materials.skin.prony]\n"
                     "g = [0.5]\n")
    with pytest.raises(InputError, match=rf"^{scene}: materials.skin.prony"):
        load_scene(scene)
    soft = tmp_path / "soft.toml"
    soft.write_text(find("materials", "wu2004", "").read_text().replace("E = 170.0", "E = -1.0"))
    scene.write_text('[[indenters]]\nfile = "bar"\n' + protocol
                     + '[materials]\nset = "soft.toml"\n')
    with pytest.raises(InputError, match=rf"^{soft}: nail"):
        load_scene(scene)
    (tmp_path / "sharp.toml").write_text('shape = "cylinder"\nradius = -1.0\n')
    scene.write_text('[[indenters]]\nfile = "sharp.toml"\n' + protocol)
    with pytest.raises(InputError, match=rf"^{scene}: indenters\[0\].file: {tmp_path}/sharp.toml"):
        load_scene(scene)


def test_relative_paths_are_read_from_the_scene_files_folder(tmp_path, monkeypatch):
    """A scene beside its indenter file works from any working directory; a path given with
    --set (or in Python) is read from the working directory, as a shell user expects."""
    folder = tmp_path / "study"
    folder.mkdir()
    (folder / "round.toml").write_text('shape = "cylinder"\nradius = 4.0\n')
    (folder / "s.toml").write_text('[[indenters]]\nfile = "round.toml"\n[protocol]\ndepth = 0.5'
                                   "\nramp_time = 1.0\nend_time = 1.0\n")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert load_scene(folder / "s.toml").indenters == [Cylinder(radius=4.0)]
    (elsewhere / "big.toml").write_text('shape = "cylinder"\nradius = 6.0\n')
    scene = load_scene(folder / "s.toml", ['indenters.0.file="big.toml"'])
    assert scene.indenters == [Cylinder(radius=6.0)]


def test_check_validates_without_running(tmp_path, capsys):
    """exit 0 and a report for a good scene (2D: the mesh built); exit 2 and one line for a bad
    one or an output folder that cannot be written; 3D: the mesh is said to be skipped."""
    assert main(["run", "1pt", "--check", "--out", str(tmp_path / "new")]) == 0
    report = capsys.readouterr().err
    assert "triangles built" in report and "writable" in report and "check passed" in report
    assert not (tmp_path / "new").exists()  # checked, not made
    (tmp_path / "file").write_text("")
    assert "is a file" in _error(capsys, ["run", "1pt", "--check", "--out",
                                          str(tmp_path / "file")])
    lines = ft.check("probe-3d")
    assert any("not built (3D" in line for line in lines)


def test_run_help_lists_every_builtin_scene(capsys):
    assert main(["run", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    for name in builtin_names("scenes"):
        assert name in text, name
    assert len(builtin_names("scenes")) >= 8


def test_the_title_says_what_was_changed():
    scene = load_scene("1pt", {"indenters": CYLINDER, "materials": {
        "subcutaneous": {"permeability": {"k0": 1000}}}})
    assert scene.title == "1pt — indenters=[cylinder r=5], subcutaneous k0=1000"
    assert load_scene("1pt").title == "1pt"
    numerics_last = load_scene("1pt", ["section.mesh.min_size=0.2", "protocol.depth=0.5"])
    assert numerics_last.title == "1pt — depth=0.5, mesh min_size=0.2"
    long = load_scene("1pt", [f"section.mesh.min_size={0.1 + i * 1e-3}" for i in range(9)])
    assert len(long.title) == TITLE_LENGTH and long.title.endswith("…")


def test_a_depth_not_written_is_answered_with_the_written_depths(tmp_path):
    (tmp_path / "history.csv").write_text("time_s,force_N_per_mm\n1.0,0.1\n")
    (tmp_path / "depth_profiles.csv").write_text(
        "time_s,depth_mm,x_mm,sed_MPa\n1.0,0.5,0.0,1e-5\n1.0,1.0,0.0,2e-5\n")
    result = ft.load_result(tmp_path)
    assert result.depth_profile("sed_MPa", depth=1.0, t=1.0)[1][0] == pytest.approx(2e-5)
    with pytest.raises(InputError, match=r"depth 0.75 mm.*\[0.5, 1.0\] mm"):
        result.depth_profile("sed_MPa", depth=0.75, t=1.0)
    with pytest.raises(InputError, match=r"t = 2.0 s.*\[1.0\] s"):
        result.depth_profile("sed_MPa", depth=0.5, t=2.0)


def test_the_check_names_the_folder_a_new_out_is_made_in(tmp_path, monkeypatch):
    """--check says where a new --out will be made: the nearest folder that exists, by its
    full name (for results/x with no results/ yet, the working folder, not ".")."""
    from pathlib import Path

    from fingertip_dolfinx.checks import writable

    monkeypatch.chdir(tmp_path)
    assert writable(Path("results/x")) == f"results/x: writable (to be made in {tmp_path})"
    (tmp_path / "results").mkdir()
    assert writable(Path("results/x")).endswith(f"(to be made in {tmp_path / 'results'})")
    assert writable(Path("results")) == "results: writable"
