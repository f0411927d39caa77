"""The `fingertip` command: `mesh` writes its three outputs; bad input is one line, exit 2."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from fingertip_dolfinx.cli import main

COARSE = ["--min-size", "0.5", "--max-size", "0.8"]


def test_mesh_writes_the_mesh_the_picture_and_the_report(tmp_path):
    out = tmp_path / "mesh"
    assert main(["mesh", *COARSE, "--out", str(out)]) == 0
    for name in ("mesh.xdmf", "mesh.h5", "mesh.png", "mesh_report.json"):
        assert (out / name).stat().st_size > 0, name
    report = json.loads((out / "mesh_report.json").read_text())
    assert report["section"] == "male-index" and report["options"]["min_size"] == 0.5
    assert report["mesh"]["cell_type"] == "triangle" and report["mesh"]["num_cells"] > 0
    assert report["tags"]["pulp_surface"] == 11
    assert all(abs(a["relative_error"]) < 0.02 for a in report["areas_mm2"].values())


def test_quad_option_reaches_the_mesh(tmp_path):
    assert main(["mesh", *COARSE, "--quad", "--out", str(tmp_path)]) == 0
    report = json.loads((tmp_path / "mesh_report.json").read_text())
    assert report["mesh"]["cell_type"] == "quadrilateral"


def test_bad_option_value_exits_2_with_the_message(tmp_path, capsys):
    assert main(["mesh", "--min-size", "-0.1", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.strip() == (
        "fingertip mesh: error: --min-size -0.1 (mesh.min_size): must be positive, got -0.1 mm. "
        "Fix: use a size > 0."
    )
    assert not any(tmp_path.iterdir())


def test_option_conflicting_with_the_file_names_both(tmp_path, capsys):
    assert main(["mesh", "--min-size", "0.9", "--out", str(tmp_path)]) == 2
    assert "--min-size 0.9 (mesh.max_size): 0.4 mm is smaller than" in capsys.readouterr().err


def test_unknown_section_exits_2_naming_the_builtin_ones(tmp_path, capsys):
    assert main(["mesh", "--section", "thumb", "--out", str(tmp_path)]) == 2
    assert "thumb: no such section file" in capsys.readouterr().err


def test_malformed_number_and_help(capsys):
    assert main(["mesh", "--min-size", "fine", "--out", "x"]) == 2
    assert "invalid float value: 'fine'" in capsys.readouterr().err
    assert main(["mesh", "--help"]) == 0
    help_text = capsys.readouterr().out
    for option in ("--section", "--min-size", "--max-size", "--quad", "--out"):
        assert option in help_text


def test_the_top_level_help_names_every_study(capsys):
    """`fingertip --help` lists what `study` runs: every kind it takes (it named two of four)."""
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    study = out[out.index("    study"):out.index("options:")]  # its wrapped help lines
    assert all(kind in study for kind in ("accuracy", "fidelity", "stability", "acuity"))


def test_command_line_error_has_no_traceback(tmp_path):
    bad = tmp_path / "finger.toml"
    bad.write_text("[nail]\nhalf_angle = 120.0\n")
    result = subprocess.run(
        [sys.executable, "-m", "fingertip_dolfinx.cli", "mesh", "--section", str(bad),
         "--out", str(tmp_path / "out")],
        capture_output=True, text=True,
    )
    assert result.returncode == 2
    assert "Traceback" not in result.stderr
    assert result.stderr.count("\n") == 1 and "nail.half_angle: must lie strictly" in result.stderr


def test_run_rejects_bad_scene_input_in_one_line(tmp_path, capsys):
    assert main(["run", "no-such-scene", "--out", str(tmp_path)]) == 2
    assert "built-in scene" in capsys.readouterr().err
    assert main(["run", "1pt", "--set", "model.subcutaneous=jelly", "--out", str(tmp_path)]) == 2
    assert "model.subcutaneous" in capsys.readouterr().err
    assert main(["run", "1pt", "--set", "nonsense", "--out", str(tmp_path)]) == 2
    assert "key=value" in capsys.readouterr().err
    assert main(["run", "2pt", "--spacing", "0.5", "--out", str(tmp_path)]) == 2
    assert "does not separate" in capsys.readouterr().err
    bad = tmp_path / "bad.toml"
    bad.write_text("[model]\ndisplacement_degree = 1\n")
    assert main(["run", "1pt", "--config", str(bad), "--out", str(tmp_path)]) == 2
    assert "Taylor" in capsys.readouterr().err


def test_an_output_directory_that_cannot_be_made_is_one_line(tmp_path, capsys):
    blocker = tmp_path / "a-file"
    blocker.write_text("not a directory\n")
    assert main(["run", "1pt", "--out", str(blocker / "results"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "the output directory cannot be created" in err and "Fix:" in err


def test_a_protocol_that_never_presses_is_refused(tmp_path, capsys):
    assert main(["run", "1pt", "--set", "protocol.depth=0", "--out", str(tmp_path)]) == 2
    assert "never exceeds 0 mm" in capsys.readouterr().err


def test_an_indenter_that_never_reaches_the_skin_is_named(tmp_path, capsys):
    """A second bar at x = 6.5 mm, where the pulp has curved up by 2.9 mm: a 1 mm
    indentation from the first touch (under the bar at x = 0) never reaches it."""
    scene = tmp_path / "two.toml"
    scene.write_text('[[indenters]]\nfile = "bar"\n[[indenters]]\nfile = "bar"\n'
                     'centre_x = 6.5\n[protocol]\ndepth = 1.0\nramp_time = 1.0\n'
                     'end_time = 1.0\n[section.mesh]\nmin_size = 0.5\nmax_size = 1.0\n'
                     'bone_size = 2.0\n')
    assert main(["run", str(scene), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "indenters[1] (bar at x = 6.5 mm)" in err and "never reaches the skin" in err, err
    assert main(["run", str(scene), "--set", "indenters.1.centre_x=0.5",
                 "--set", "protocol.depth=0.1", "--out", str(tmp_path / "ok"), "--quiet"]) == 0


def test_sweep_spots_without_spacings_is_refused(tmp_path, capsys):
    # the discs follow the bars of a spacing sweep; a parameter sweep has no bars to follow
    assert main(["sweep", "1pt", "--param", "materials.skin.mu", "--factors", "1", "--spots",
                 "--out", str(tmp_path)]) == 2
    assert "sweep --spots" in capsys.readouterr().err


@pytest.mark.parametrize("command", [
    ["sweep", "1pt", "--param", "materials.bone.E", "--factors", "1", "2"],
    ["run", "1pt", "--tol", "0.05"],
    ["run", "1pt", "--fidelity", "auto"],
])
def test_check_refuses_what_the_key_outputs_cannot_read(command, capsys):
    """--check of a command that compares key outputs (a parameter sweep, the adaptive loop,
    the fidelity ladder) refuses a scene they cannot read, as the command itself does before
    its first run: a passed check must not be followed by a refusal. Before, --check passed."""
    assert main([*command, "--set", "protocol.end_time=5", "--check"]) == 2
    err = capsys.readouterr().err
    assert "the key deflections are read at the end of the run (t = 5 s)" in err, err
    # the same scene as one plain run reads no key output: its check passes
    assert main(["run", "1pt", "--set", "protocol.end_time=5", "--check"]) == 0


#: Allocate, fill and free a block of 256 MiB twice with C's malloc (as MUMPS's Fortran does;
#: numpy asks for huge pages) and print the minor page faults of the second time.
_REALLOCATE = """
import ctypes, ctypes.util, resource, sys
from fingertip_dolfinx.cli import keep_freed_memory
libc = ctypes.CDLL(ctypes.util.find_library("c"))
libc.malloc.restype = ctypes.c_void_p
libc.free.argtypes = [ctypes.c_void_p]
if sys.argv[1] == "keep":
    assert keep_freed_memory()
def cycle():
    block = libc.malloc(2**28)
    ctypes.memset(block, 1, 2**28)
    libc.free(block)
cycle()
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
cycle()
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""
PAGES = 2**28 // 4096


def _thp_always() -> bool:
    path = Path("/sys/kernel/mm/transparent_hugepage/enabled")
    return path.exists() and "[always]" in path.read_text()


@pytest.mark.skipif(not sys.platform.startswith("linux") or _thp_always(),
                    reason="glibc's mallopt; with huge pages always on, few faults either way")
def test_the_command_reuses_freed_memory_without_page_faults():
    """A block of 256 MiB (65 536 pages of 4 KiB) freed and allocated again: glibc's default
    maps it afresh, each page a fault the kernel zeroes; the command's setting reuses the
    freed pages (the pattern of MUMPS's work arrays, one allocation per LU factorisation)."""
    def faults(mode):
        out = subprocess.run([sys.executable, "-c", _REALLOCATE, mode], check=True,
                             capture_output=True, text=True).stdout
        return int(out.split()[-1])

    assert faults("default") > PAGES // 2  # most pages fault again
    assert faults("keep") < PAGES // 100   # reused: no new pages


def test_study_fidelity_says_failed_for_a_rung_that_failed(monkeypatch, tmp_path, capsys):
    """A rung whose run failed (the small-strain continuum under the line load's 25 µm tip) was
    printed as "largest error inf %"; the console now says it failed, as fidelity.md does, and
    so does `--fidelity auto`'s sentence about the cheaper rungs."""
    import math

    from fingertip_dolfinx.keys import KEYS
    from fingertip_dolfinx.studies import fidelity

    def row(model, error, failure=""):
        return {"model": model, "wall_time_s": 1.0, "max_error": error, "failure": failure,
                **{f"error_{k}": error for k in KEYS}}

    rows = [row("continuum", math.inf, "inverted elements"), row("hyperfoam", 0.3),
            row("+ skin QLV", 0.2), row("+ undrained", 1e-3), row("full", 0.0)]
    monkeypatch.setattr(fidelity, "run_fidelity_study", lambda *a, **k: rows)
    assert main(["study", "fidelity", "--quiet", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().err
    assert "continuum:    1.0 s, failed" in out and "inf" not in out
    assert "largest error  30.00 %" in out
    model, why = fidelity.pick(rows, 0.01)
    assert model == "+ undrained" and "continuum (failed)" in why and "inf" not in why


def _run_raising(monkeypatch, error):
    import fingertip_dolfinx.routes as routes

    def raising(*args, **kwargs):
        raise error

    monkeypatch.setattr(routes, "run", raising)


def test_ctrl_c_before_the_first_step_is_one_line_and_exit_130(monkeypatch, tmp_path, capsys):
    # Ctrl-C while the libraries load or the scene is read (before the run's own handlers):
    # a KeyboardInterrupt, which ended the command with a traceback.
    _run_raising(monkeypatch, KeyboardInterrupt())
    try:
        code = main(["run", "1pt", "--out", str(tmp_path), "--quiet"])
    except KeyboardInterrupt:
        code = "a traceback"
    assert code == 130
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "interrupted by SIGINT outside a time step" in err


def test_a_run_stopped_in_its_first_step_says_to_start_again_not_resume(monkeypatch, tmp_path,
                                                                        capsys):
    # Stopped within the first step's Newton solve, a run has no checkpoint: the line used to
    # say "continue with: ... --resume", which --resume then refuses.
    from fingertip_dolfinx.errors import RunInterrupted

    stop = RunInterrupted(0.0, "SIGTERM", {})
    stop.route = "time"
    _run_raising(monkeypatch, stop)
    assert main(["run", "1pt", "--out", str(tmp_path), "--quiet"]) == 130
    err = capsys.readouterr().err.strip()
    assert "before the first step was done: there is nothing to resume" in err
    assert err.endswith(f"fingertip run 1pt --out {tmp_path} --quiet")


def test_sigterm_while_starting_is_one_line_not_petscs_abort(tmp_path):
    # PETSc's own SIGTERM handler (installed when petsc4py starts PETSc) printed
    # "PETSC ERROR: Caught signal number 15" and called MPI_Abort.
    code = ("import os, signal, time\n"
            "import fingertip_dolfinx.routes as routes\n"
            "from fingertip_dolfinx.cli import main\n"
            "def run(*args, **kwargs):\n"
            "    from petsc4py import PETSc\n"
            "    os.kill(os.getpid(), signal.SIGTERM)\n"
            "    time.sleep(30)\n"
            "routes.run = run\n"
            f"raise SystemExit(main(['run', '1pt', '--out', {str(tmp_path)!r}, '--quiet']))\n")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 130, result.stderr
    assert "PETSC ERROR" not in result.stderr
    assert "interrupted by SIGTERM outside a time step" in result.stderr


@pytest.mark.parametrize("command", [["run", "1pt"], ["sweep", "1pt", "--param",
                                                       "protocol.depth", "--values", "0.5"],
                                     ["mesh"]])
def test_an_empty_out_is_refused_not_the_working_folder(command, tmp_path, monkeypatch,
                                                        capsys):
    # --out "$OUT" with OUT unset was Path("") = ".": the run wrote into the working folder,
    # first removing an earlier run's files there by their names.
    monkeypatch.chdir(tmp_path)
    (tmp_path / "summary.json").write_text("{}")
    assert main([*command, "--out", "", "--quiet"] if command[0] != "mesh"
                else [*command, "--out", ""]) == 2
    assert "argument --out: is empty" in capsys.readouterr().err
    assert [p.name for p in tmp_path.iterdir()] == ["summary.json"]


def test_an_empty_out_is_refused_from_python(tmp_path, monkeypatch):
    import fingertip_dolfinx as ft
    from fingertip_dolfinx.errors import InputError

    monkeypatch.chdir(tmp_path)
    with pytest.raises(InputError, match="out '': is empty"):
        ft.run("1pt", "", progress=False)
    assert not list(tmp_path.iterdir())


def test_ctrl_c_while_starting_under_mpi_ends_every_rank(monkeypatch, tmp_path, capsys):
    # Under mpiexec a rank stopped while starting left the others waiting in a collective for
    # it (measured: a hang, or a SEGV as it finalised): it must end them all.
    import fingertip_dolfinx.cli as cli

    class World:
        size, aborted = 2, []

        def Abort(self, code):
            self.aborted.append(code)

    monkeypatch.setattr(cli, "_world", World)
    _run_raising(monkeypatch, KeyboardInterrupt("SIGTERM"))
    assert main(["run", "1pt", "--out", str(tmp_path), "--quiet"]) == 130
    assert World.aborted == [130]
    assert "interrupted by SIGTERM outside a time step" in capsys.readouterr().err
