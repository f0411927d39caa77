"""The key outputs say what they hold: quantity, unit, place and time in every column name, the
largest value over the run where the name says "max over the run", the end of the run where it
says t_end, and an error (never another depth or time) when a run lacks what a key reads.

Fast: synthetic run directories (the run's own CSV columns, hand-made numbers), and a sweep
refused before its first run."""

import json

import numpy as np
import pytest

import fingertip_dolfinx as ft
from fingertip_dolfinx.cli import main
from fingertip_dolfinx.errors import InputError
from fingertip_dolfinx.keys import KEY_OUTPUTS, KEYS, TIME_COLUMNS, check_scene, key_outputs

SED = "sed_MPa_peak_at_depth0.75mm_max_over_run"
E_MAX = "e_max_peak_at_depth0.75mm_max_over_run"


def _write(path, columns, rows):
    path.write_text(",".join(columns) + "\n"
                    + "".join(",".join(f"{v:.12g}" for v in r) + "\n" for r in rows))


def fake_run(path, times=(1.0, 3.0, 5.0), depths=(0.75,), end=5.0):
    """A finished 2D run: force rising to its peak at t = 1 s between steps, a depth curve
    whose peak (at x = 0) grows as (1 + t) and a deflection w = t (1 - |x|/4) at each output
    time."""
    path.mkdir()
    steps = np.linspace(0.0, end, 11)
    force = np.minimum(steps, 1.0) * np.exp(-(np.maximum(steps, 1.0) - 1.0) / 10)
    _write(path / "history.csv", ("time_s", "force_N_per_mm"), zip(steps, force))
    x = np.linspace(-4.0, 4.0, 17)
    _write(path / "surface_profile.csv", ("x_mm", "time_s", "deflection_mm"),
           [(xi, t, t * (1 - abs(xi) / 4)) for t in times for xi in x])
    _write(path / "depth_profiles.csv", ("x_mm", "depth_mm", "time_s", "e_max", "sed_MPa"),
           [(xi, d, t, 0.1 * (1 + t) / (1 + xi**2) / d, 1e-5 * (1 + t) / (1 + xi**2) / d)
            for t in times for d in depths for xi in x])
    (path / "summary.json").write_text(json.dumps(
        {"end_time_s": end, "converged": True, "wall_time_s": 1.0, "dofs": 10}))
    return path


def test_every_column_names_its_quantity_unit_place_and_time():
    """The old names (peak_force, deflection_1mm, peak_sed_0.75mm) said neither unit nor time."""
    assert KEYS == ("force_N_per_mm_max_over_run", "force_N_per_mm_at_t_end",
                    "deflection_mm_at_x1mm_t_end", "deflection_mm_at_x2mm_t_end",
                    "deflection_mm_at_x3mm_t_end", E_MAX, SED)
    for key in KEY_OUTPUTS:
        assert key.column.endswith(("_max_over_run", "_t_end"))
        assert key.unit == "1" or key.name.split("_", 1)[1] in key.column


def test_the_peaks_are_the_largest_over_the_run(tmp_path):
    """The depth-curve peak grows with t: its max over the run is at the last output time,
    5 s, (1 + 5) 1e-5 / 0.75 MPa; the value at the first output time is a third of it."""
    values = key_outputs(fake_run(tmp_path / "run"))
    assert values[SED] == pytest.approx(6e-5 / 0.75, rel=1e-9)
    assert values[E_MAX] == pytest.approx(0.6 / 0.75, rel=1e-9)
    assert values[f"{SED}_t_s"] == 5.0
    # the force peaks at the end of the ramp, t = 1 s, on the history's every step
    assert values["force_N_per_mm_max_over_run"] == pytest.approx(1.0)
    assert values["force_N_per_mm_max_over_run_t_s"] == 1.0
    assert values["force_N_per_mm_at_t_end"] == pytest.approx(np.exp(-0.4))
    assert set(TIME_COLUMNS) <= set(values)


def test_deflections_are_read_at_the_end_and_say_so(tmp_path):
    """w = t (1 - |x|/4): at x = ±2 mm and t_end = 5 s, 2.5 mm."""
    values = key_outputs(fake_run(tmp_path / "run"))
    assert values["deflection_mm_at_x2mm_t_end"] == pytest.approx(2.5)
    assert values["deflection_mm_at_x2mm_t_end_t_s"] == 5.0


def test_a_run_without_the_end_among_its_output_times_is_refused(tmp_path):
    """Profiles at 1 and 3 s of a run that ends at 5 s: no deflection 'at the end' exists
    (the old reader returned the last written profile's, t = 3 s, under the same name)."""
    with pytest.raises(InputError, match="end of the run, t = 5 s"):
        key_outputs(fake_run(tmp_path / "run", times=(1.0, 3.0)))


def test_a_missing_depth_is_an_error_not_another_depth(tmp_path):
    """output.depths = [1.2]: the old reader put the 1.2 mm value in the 0.75 mm column."""
    with pytest.raises(InputError, match=r"no depth curve at 0.75 mm \(written: 1.2 mm\)"):
        key_outputs(fake_run(tmp_path / "run", depths=(1.2,)))


def test_scenes_that_cannot_give_the_key_outputs_are_refused_before_running():
    check_scene(ft.load_scene("line-load"), "test")
    with pytest.raises(InputError, match="output.depths"):
        check_scene(ft.load_scene("1pt", ["output.depths=[1.2]"]), "test")
    with pytest.raises(InputError, match=r"output.times=\[1, 5\]"):
        check_scene(ft.load_scene("1pt", ["protocol.end_time=5.0"]), "test")
    with pytest.raises(InputError, match="3D"):
        check_scene(ft.load_scene("probe-3d"), "test")


def test_a_sweep_at_another_depth_stops_before_its_first_run(tmp_path, capsys):
    argv = ["sweep", "1pt", "--param", "materials.subcutaneous.permeability.k0", "--values",
            "1e-3", "1", "--set", "output.depths=[1.2]", "--out", str(tmp_path), "--quiet"]
    assert main(argv) == 2
    assert "0.75" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


def test_records_with_the_old_names_are_refused(tmp_path):
    """A fidelity.csv (for --fidelity-table) or an accuracy reference written with the old
    names: one line saying to rerun, not a KeyError."""
    from fingertip_dolfinx.keys import relative_errors
    from fingertip_dolfinx.studies.fidelity import read_table

    old = tmp_path / "fidelity.csv"
    old.write_text("model,max_error,error_peak_force,peak_force,failure\nfull,0,0,1e-3,\n")
    with pytest.raises(InputError, match="study fidelity"):
        read_table(old)
    with pytest.raises(InputError, match="peak_force"):
        relative_errors(dict.fromkeys(KEYS, 1.0), {"peak_force": 1.0}, "accuracy.json")
