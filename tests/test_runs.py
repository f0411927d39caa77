"""A run a researcher can trust: a resume never mixes two experiments, Ctrl-C (SIGINT) and
SIGTERM stop a real `fingertip run` at a step boundary with a record and exit 130 (on 1 and 2
ranks), files are whole, and fields go to ParaView at the output times, one time line per
field across a resume.

The signal tests launch the command themselves (`mpiexec -n 2` for two ranks): they are
serial tests."""

import json
import os
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from fingertip_dolfinx.cli import main
from fingertip_dolfinx.errors import InputError, RunInterrupted
from fingertip_dolfinx.outputs import Checkpoint, check_resume, read_csv
from fingertip_dolfinx.runner import Run, run_scene
from fingertip_dolfinx.scene import load_scene, scene_record
from fingertip_dolfinx.stepping.stepper import TimeStepper

REPO = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
#: A coarse one-point test in ten steps of 0.1 s, fields at 0.2 and 1 s: tens of seconds.
SETS = ["section.mesh.min_size=0.2", "section.mesh.max_size=1.0", "section.mesh.bone_size=2.0",
        "output.profile_points=121", "steps.dt_initial=0.1", "steps.dt_max=0.1",
        "output.times=[0.2, 1.0]"]
ARGS = ["run", "1pt", *(a for s in SETS for a in ("--set", s)), "--quiet"]
FIELDS = ("displacement", "log_strain", "strain_energy_density", "pore_pressure")


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """An uninterrupted run (the command, in this process): its directory."""
    out = tmp_path_factory.mktemp("finished")
    handlers = [signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)]
    assert main([*ARGS, "--out", str(out)]) == 0
    # the run's own handlers are gone again: Python's Ctrl-C is Python's
    assert [signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)] == handlers
    return out


def _final_force(out: Path) -> float:
    return float(read_csv(out / "history.csv")["force_N_per_mm"][-1])


def bp_times(path: Path) -> list[float]:
    """The times of a VTX series, read from its ADIOS2 BP4 metadata: md.idx holds one
    64-byte record per step (after a 64-byte header) with the step's span in md.0, where the
    variable `step` (DOLFINx's time) carries its value as the first characteristic."""
    index, meta = (path / "md.idx").read_bytes(), (path / "md.0").read_bytes()
    times = []
    for i in range(1, len(index) // 64):
        record = struct.unpack("<8Q", index[64 * i:64 * i + 64])
        step = meta[record[2]:record[5]]
        at = step.find(b"\x04\x00step")
        assert at >= 0, f"no time in step {i} of {path}"
        times.append(struct.unpack("<d", step[at + 37:at + 45])[0])
    return times


# --- resume: never two experiments in one directory ---------------------------------------


def test_a_resume_that_changes_the_physics_is_refused_and_the_record_left_alone(
        finished, capsys):
    """The issue's reproduction on a finished run: k0 changed on --resume is refused with exit
    2, the key, both values and the fix; the same scene computes nothing, says so, and
    rewrites nothing (summary.json byte for byte and its time)."""
    summary = finished / "summary.json"
    before, stamp = summary.read_bytes(), summary.stat().st_mtime_ns
    key = "materials.subcutaneous.permeability.k0"
    code = main([*ARGS, "--set", f"{key}=1000", "--resume", "--out", str(finished)])
    err = capsys.readouterr().err
    assert code == 2, err
    assert f"{key}: the run there was computed to t = 1 s with {key} = 0.001; this scene has " \
           "1000.0" in err and "start a new --out, or resume without --set" in err
    assert main([*ARGS, "--resume", "--out", str(finished)]) == 0
    assert "already complete" in capsys.readouterr().err
    assert summary.read_bytes() == before and summary.stat().st_mtime_ns == stamp
    assert json.loads(before)["status"] == "completed"


class _RankZeroOfTwo:
    """Rank 0 of two ranks, the other of which holds checkpoints of the times `other`."""

    rank, size = 0, 2

    def __init__(self, other: list[float]):
        self.other = other

    def allgather(self, mine):
        return [mine, self.other]

    def bcast(self, value, root=0):
        return value


def test_a_kill_between_the_ranks_checkpoints_resumes_from_the_step_all_hold(tmp_path):
    """A kill (SIGKILL, a second Ctrl-C) while the ranks replace their checkpoints: rank 0
    holds step 2, the other rank still step 1. The resume continues every rank from step 1
    (rank 0's step before, kept), never from two states (measured: the ranks then wait on
    each other for ever); with no step in common it is refused."""
    comm = _RankZeroOfTwo(other=[0.1])
    checkpoint = Checkpoint(tmp_path, comm)
    checkpoint.folder.mkdir()
    (checkpoint.folder / "scene.json").write_text("{}")
    for step, t in ((1, 0.1), (2, 0.2)):
        checkpoint.save(t, 0.1, step, {"u": np.full(3, t)}, (t - 0.1, [np.full(3, t - 0.1)]))
    assert checkpoint.stored() == ({}, 0.1)
    u = np.zeros(3)
    state = checkpoint.load({"u": u}, 1)
    assert (state.time, state.steps, state.previous[0]) == (0.1, 1, 0.0)
    np.testing.assert_array_equal(u, 0.1)
    checkpoint.path.unlink()  # killed between its two renames: the step before is whole
    assert checkpoint.stored() == ({}, 0.1)
    comm.other = [0.3]
    with pytest.raises(InputError, match="no step in common"):
        checkpoint.stored()
    comm.other = []  # a run of one rank resumed on two
    with pytest.raises(InputError, match="resume with mpiexec -n 1"):
        checkpoint.stored()


def test_a_checkpoint_of_another_model_or_rank_count_is_refused_and_left_closed(tmp_path):
    """Loading refuses arrays of another shape or name (another scene's model) and a run made
    on another number of ranks, naming the fix, and leaves no descriptor of the file open
    behind a refusal (whose traceback the caller may keep); a fitting load fills the state."""
    comm = _RankZeroOfTwo(other=[0.1])
    checkpoint = Checkpoint(tmp_path, comm)
    checkpoint.folder.mkdir()
    checkpoint.save(0.1, 0.1, 1, {"u": np.full(3, 0.1)}, (0.0, [np.zeros(3)]))
    refusals = []
    for state, match in (({"u": np.zeros(4)}, r"does not fit this scene's model \(u\)"),
                         ({"p": np.zeros(3)}, r"does not fit this scene's model \(p\)")):
        with pytest.raises(InputError, match=match) as refused:
            checkpoint.load(state, 1)
        refusals.append(refused)  # the tracebacks kept, as a caller reporting them would
    comm.size = 3
    with pytest.raises(InputError, match="resume with mpiexec -n 2") as refused:
        checkpoint.load({"u": np.zeros(3)}, 1)
    refusals.append(refused)
    assert not _open_descriptors(checkpoint.path)
    comm.size = 2
    checkpoint.save(0.1, 0.1, 1, {"u": np.full(3, 0.1)}, (0.0, [np.zeros(3)]))
    u = np.zeros(3)
    assert checkpoint.load({"u": u}, 1).steps == 1
    np.testing.assert_array_equal(u, 0.1)


def _open_descriptors(path: Path) -> list[str]:
    """This process's open file descriptors on `path` (Linux: /proc/self/fd)."""
    fds = Path("/proc/self/fd")
    if not fds.is_dir():
        pytest.skip("needs /proc/self/fd")
    found = []
    for fd in fds.iterdir():
        try:
            if os.readlink(fd) == str(path.resolve()):
                found.append(fd.name)
        except OSError:  # closed while listed
            continue
    return found


def test_what_a_resume_may_change():
    """Later end times, more cycles, output times after the checkpoint, pictures: allowed.
    Anything that changes d(t) before the checkpoint, the materials, the mesh, the steps, or
    drops an output time already written: refused, naming the key."""
    base = scene_record(load_scene("1pt", SETS))

    def resumed(*sets, t=0.5):
        check_resume(base, scene_record(load_scene("1pt", [*SETS, *sets])), t, Path("D"))

    resumed("protocol.end_time=3.0", "output.times=[0.2, 1.0, 2.5]", "output.pictures=false",
            'output.fields="every-step"')
    resumed("protocol.end_time=3.0", "output.times=[0.2, 2.0]", t=0.6)  # 1.0 not yet written
    for sets, key in ((["protocol.ramp_time=2.0", "protocol.end_time=2.0"], "protocol.ramp_time"),
                      (["protocol.depth=0.9"], "protocol.depth"),
                      (["materials.nail.E=200.0"], "materials.nail.E"),
                      (["model.skin_viscoelastic=false"], "model.skin_viscoelastic"),
                      (["section.mesh.min_size=0.1"], "section.mesh.min_size"),
                      (["steps.dt_max=0.2"], "steps.dt_max"),
                      (["output.times=[1.0]"], "output.times"),
                      (["output.depths=[0.5]"], "output.depths")):
        with pytest.raises(InputError, match=key):
            resumed(*sets)
    with pytest.raises(InputError, match=r"keep the output times up to 0.5 s as they were, "
                       r"\[0.2\] \(the run is past them: \[0.3\] cannot be written now, "
                       r"\[0.2\] are written already\)"):
        resumed("output.times=[0.3, 1.0]")


def test_a_resume_may_run_on_past_the_end(finished, tmp_path):
    """A finished run continued to a later end time: the steps after 1 s are added to the same
    files, one time line per field, and the record is the longer scene's."""
    import shutil

    out = tmp_path / "longer"
    shutil.copytree(finished, out)
    assert main([*ARGS, "--set", "protocol.end_time=1.2", "--set", "output.times=[0.2, 1.0, 1.2]",
                 "--resume", "--out", str(out)]) == 0
    h = read_csv(out / "history.csv")
    assert np.all(np.diff(h["time_s"]) > 0) and h["time_s"][-1] == pytest.approx(1.2)
    assert bp_times(out / "displacement.bp") == pytest.approx([0.2, 1.0, 1.2], abs=1e-12)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "completed" and summary["scene_data"]["protocol"]["end_time"] == 1.2


def test_a_fresh_run_into_an_earlier_runs_folder_leaves_none_of_its_files(finished, tmp_path):
    """A fresh run (no --resume) into a folder with an earlier run's files: the earlier run's
    pictures and arrays at a time this run does not reach are gone, so every file in the
    folder is this run's; a file that is not a run's stays."""
    import shutil

    out = tmp_path / "again"
    shutil.copytree(finished, out)
    assert sorted(p.name for p in out.glob("*_t0.2s.*"))  # the earlier run's 0.2 s files
    (out / "notes.txt").write_text("mine")
    assert main([*ARGS, "--set", "output.times=[0.5, 1.0]", "--out", str(out)]) == 0
    assert not list(out.glob("*_t0.2s.*")) and list(out.glob("*_t0.5s.*"))
    assert (out / "notes.txt").read_text() == "mine"
    assert bp_times(out / "displacement.bp") == pytest.approx([0.5, 1.0], abs=1e-12)


# --- fields at the output times ------------------------------------------------------------


def test_fields_go_to_paraview_at_the_output_times(finished):
    """Ten steps, two output times: each field's series holds the two times only (every step
    was the default: 11 VTX steps, 5x the bytes)."""
    for name in FIELDS:
        assert bp_times(finished / f"{name}.bp") == pytest.approx([0.2, 1.0], abs=1e-12), name
    assert len(read_csv(finished / "history.csv")["time_s"]) >= 10


def test_the_fields_key_is_checked():
    assert load_scene("1pt").outputs.fields == "output-times"
    assert load_scene("1pt", ["output.field_every=5"]).outputs.fields == "every-step"
    with pytest.raises(InputError, match='output.fields: got .every-time.. Fix: use "output-'):
        load_scene("1pt", ['output.fields="every-time"'])
    with pytest.raises(InputError, match="output.field_every: 5 is the stride of fields"):
        load_scene("1pt", ['output.fields="output-times"', "output.field_every=5"])


# --- interrupting ---------------------------------------------------------------------------


def test_the_api_raises_a_keyboard_interrupt_after_writing_the_record(tmp_path, monkeypatch):
    """A SIGINT during a step of `run_scene`: the step ends, the files and summary.json are
    written, and RunInterrupted (a KeyboardInterrupt) reaches the caller; the handler that was
    there before the run is back (Python's own, or whatever an earlier gmsh call left)."""
    # A process started in the background by a shell without job control inherits SIGINT
    # ignored, and a run leaves an ignored signal ignored (Interrupts): start from Python's own
    # handler, as in a terminal.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        _interrupted_in_step_two(tmp_path, monkeypatch)
    finally:
        signal.signal(signal.SIGINT, previous)


def _interrupted_in_step_two(tmp_path, monkeypatch):
    before = signal.getsignal(signal.SIGINT)
    on_step = Run.on_step

    def signal_in_step_two(self, report):
        if self.step_count == 1:  # the second step: the signal comes while it is written
            os.kill(os.getpid(), signal.SIGINT)
        on_step(self, report)

    monkeypatch.setattr(Run, "on_step", signal_in_step_two)
    with pytest.raises(KeyboardInterrupt) as caught:
        run_scene(load_scene("1pt", SETS), tmp_path, progress=False, comm=MPI.COMM_SELF)
    assert isinstance(caught.value, RunInterrupted) and caught.value.signal == "SIGINT"
    assert caught.value.time == pytest.approx(0.2)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["end_time_s"] == pytest.approx(0.2)
    assert not summary["converged"]
    assert signal.getsignal(signal.SIGINT) is before


def test_a_signal_within_a_step_stops_its_newton_solve_and_resume_finishes_it(
        finished, tmp_path, monkeypatch):
    """A SIGINT during the third step's Newton solve (a step of a fine mesh may take an hour):
    the solve ends after the iteration under way, the step is not taken, the run stops at
    the second step's state with its record, and `--resume` ends where the uninterrupted run
    ends (the final force to the Newton tolerance: the state put back is the accepted one)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    check, solves, seen = TimeStepper._check_stop, [], []

    def signal_in_step_three(self, snes, its, fnorm):
        solves.extend([its] if its == 0 else [])  # the steps are 0.1 s each, none cut
        if len(solves) == 3:
            seen.append(its)
            if its == 1:
                os.kill(os.getpid(), signal.SIGINT)
        check(self, snes, its, fnorm)

    monkeypatch.setattr(TimeStepper, "_check_stop", signal_in_step_three)
    try:
        with pytest.raises(RunInterrupted) as caught:
            run_scene(load_scene("1pt", SETS), tmp_path, progress=False, comm=MPI.COMM_SELF)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert seen == [0, 1]  # no iteration after the one the signal came in
    assert caught.value.time == pytest.approx(0.2)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["end_time_s"] == pytest.approx(0.2)
    assert read_csv(tmp_path / "history.csv")["time_s"][-1] == pytest.approx(0.2)
    monkeypatch.undo()
    run_scene(load_scene("1pt", SETS), tmp_path, progress=False, comm=MPI.COMM_SELF,
              resume=True)
    assert _final_force(tmp_path) == pytest.approx(_final_force(finished), rel=1e-7)


def _interrupt(out: Path, ranks: int, sig: signal.Signals) -> subprocess.CompletedProcess:
    """`fingertip run` (under mpiexec with ranks > 1) into `out`, sent `sig` once its
    history.csv has two rows: to mpiexec for SIGINT (it passes Ctrl-C on to the ranks), to
    the process group for SIGTERM (Hydra's mpiexec is alone in it, the ranks have sessions of
    their own: it passes SIGTERM on to them too; docs/guide/mpi.md)."""
    launch = [str(BIN / "mpiexec"), "-n", str(ranks)] if ranks > 1 else []
    command = [*launch, sys.executable, "-m", "fingertip_dolfinx.cli", *ARGS, "--out", str(out)]
    env = dict(os.environ, PYTHONPATH=str(REPO))
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True, env=env, start_new_session=True)
    history, waited = out / "history.csv", time.monotonic()
    while not (history.exists() and len(history.read_text().splitlines()) >= 3):
        assert process.poll() is None, process.communicate()
        assert time.monotonic() - waited < 300, "no two steps in 300 s"
        time.sleep(0.1)
    if sig == signal.SIGINT:
        process.send_signal(sig)
    else:
        os.killpg(process.pid, sig)
    stdout, stderr = process.communicate(timeout=300)
    return subprocess.CompletedProcess(command, process.returncode, stdout, stderr)


def _resume(out: Path, ranks: int) -> None:
    launch = [str(BIN / "mpiexec"), "-n", str(ranks)] if ranks > 1 else []
    subprocess.run([*launch, sys.executable, "-m", "fingertip_dolfinx.cli", *ARGS, "--out",
                    str(out), "--resume"], check=True, env=dict(os.environ, PYTHONPATH=str(REPO)),
                   capture_output=True, timeout=600)


@pytest.mark.slow
@pytest.mark.parametrize("ranks, sig", [(1, signal.SIGINT), (2, signal.SIGINT),
                                        (2, signal.SIGTERM)])
def test_a_signal_stops_a_real_run_and_resume_finishes_it(finished, tmp_path, ranks, sig):
    """A real signal to a real `fingertip run`: exit 130, one line saying where it stopped and
    the command that continues it, no traceback, summary.json "interrupted" at the last row of
    history.csv, no half file; `--resume` then ends where the uninterrupted run ends (the
    final force to the Newton tolerance: both solve the same steps) with one time line per
    field."""
    out = tmp_path / "run"
    result = _interrupt(out, ranks, sig)
    key = "materials.subcutaneous.permeability.k0"  # the mixed experiment: refused
    assert main([*ARGS, "--set", f"{key}=1000", "--resume", "--out", str(out)]) == 2
    assert result.returncode == 130, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    h = read_csv(out / "history.csv")
    launch = f"mpiexec -n {ranks} " if ranks > 1 else ""
    assert lines[0].startswith(f"interrupted at t = {h['time_s'][-1]:.6g} s; continue with: "
                               f"{launch}fingertip run 1pt --set ")
    assert lines[0].endswith(f"--out {out} --resume")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["end_time_s"] == h["time_s"][-1]
    assert summary["failure"] == f"interrupted by {sig.name} at t = {h['time_s'][-1]:.6g} s"
    assert 0.2 - 1e-12 <= h["time_s"][-1] < 1.0  # the first output time's fields are written
    assert not [p for p in out.rglob("*") if ".tmp" in p.name]
    _resume(out, ranks)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "completed" and summary["end_time_s"] == pytest.approx(1.0)
    assert _final_force(out) == pytest.approx(_final_force(finished), rel=1e-7)
    for name in FIELDS:
        assert bp_times(out / f"{name}.bp") == pytest.approx([0.2, 1.0], abs=1e-12), name
    assert not list(out.glob("*-from-*"))


def test_a_side_by_side_run_that_fails_says_so_at_once_then_raises(monkeypatch, capsys,
                                                                    tmp_path):
    # Side by side under MPI, a group whose run fails waits in a collective until the other
    # groups' runs end (hours, for the 3D acuity study) before raising: its error must be
    # printed when it happens, naming the run.
    import fingertip_dolfinx.runner as runner

    def fails(scene, out, **_):
        raise TimeoutError("JIT compilation timed out")

    monkeypatch.setattr(runner, "run_scene", fails)
    scene = load_scene("1pt")
    with pytest.raises(TimeoutError):
        runner.run_side_by_side([(scene, tmp_path / "a")], progress=False)
    said = capsys.readouterr().err
    assert "1pt" in said and str(tmp_path / "a") in said and "timed out" in said


def test_a_stopped_sweep_leaves_no_earlier_table_and_resumes_its_runs(tmp_path, monkeypatch,
                                                                       capsys):
    # A sweep stopped part-way into the folder of an earlier one left the earlier sweep.csv,
    # summary.json and sweep.png beside runs of another experiment; and a sweep had no way to
    # continue its runs (run again, it started every one afresh).
    import fingertip_dolfinx.runner as runner
    from fingertip_dolfinx.errors import RunInterrupted

    for name in ("sweep.csv", "summary.json", "sweep.png", "notes.txt"):
        (tmp_path / name).write_text("an earlier sweep's\n")
    (tmp_path / "k0-x1" / "checkpoint").mkdir(parents=True)
    (tmp_path / "k0-x1" / "checkpoint" / "rank0.npz").write_bytes(b"")
    calls = []

    def stopped(scene, out, *, resume=False, **kwargs):
        calls.append((out.name, resume))
        if out.name == "k0-x10":
            raise RunInterrupted(0.3, "SIGINT", {})

    monkeypatch.setattr(runner, "run_scene", stopped)
    argv = ["sweep", "1pt", "--param", "materials.subcutaneous.permeability.k0", "--factors",
            "1", "10", "--out", str(tmp_path), "--quiet"]
    assert main([*argv, "--resume"]) == 130
    assert calls == [("k0-x1", True), ("k0-x10", False)]  # k0-x10 has no checkpoint: afresh
    assert sorted(p.name for p in tmp_path.iterdir()) == ["k0-x1", "notes.txt"]
    err = capsys.readouterr().err.strip()
    assert err.endswith(f"continue with: fingertip {' '.join(argv)} --resume")


@pytest.mark.parametrize("study, report", [("fidelity", "fidelity.md"),
                                           ("accuracy", "accuracy.md")])
def test_a_stopped_study_leaves_no_earlier_report(study, report, tmp_path, monkeypatch):
    # A study stopped part-way into the folder of an earlier one left the earlier report
    # (accuracy.md, fidelity.md, their tables and charts) beside runs of this one.
    import fingertip_dolfinx.runner as runner

    def stopped(scene, out, **kwargs):
        raise RunInterrupted(0.3, "SIGTERM", {})

    monkeypatch.setattr(runner, "run_scene", stopped)
    (tmp_path / report).write_text("an earlier study's\n")
    (tmp_path / "notes.txt").write_text("mine\n")
    assert main(["study", study, "--scene", "1pt", "--out", str(tmp_path)]) == 130
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]


def test_a_value_changed_in_a_file_is_named_as_such_on_resume():
    # A materials file edited between the run and its --resume: refused, but the fix said
    # "resume without --set materials.bone.E=...", which no --set had given.
    base = scene_record(load_scene("1pt", SETS))
    edited = scene_record(load_scene("1pt", [*SETS, "materials.bone.E=18000"]))
    with pytest.raises(InputError, match=r"put materials.bone.E = 17000.0 back where this "
                       r"scene takes it from \(the scene file, or the materials"):
        check_resume(base, edited, 0.5, Path("D"))
    with pytest.raises(InputError, match=r"resume without --set materials.bone.E=\.\.\."):
        check_resume(base, edited, 0.5, Path("D"), ["materials.bone.E=18000"])
    with pytest.raises(InputError, match=r"resume without --set indenters.0.width"):
        check_resume(base, scene_record(load_scene("1pt", [*SETS, "indenters.0.width=0.8"])),
                     0.5, Path("D"), ['indenters=[{file = "bar", width = 0.8}]'])


def test_a_sweep_table_cut_short_leaves_no_half_file(tmp_path, monkeypatch):
    # sweep.csv was written in place: a kill (or an error) part-way left half a table.
    import fingertip_dolfinx.studies.parameters as parameters

    class Cut(Exception):
        pass

    class Writer:
        def __init__(self, f, **kwargs):
            self.f = f

        def writeheader(self):
            self.f.write("label,value\n")

        def writerow(self, row):
            raise Cut

    monkeypatch.setattr(parameters.csv, "DictWriter", Writer)
    with pytest.raises(Cut):
        parameters._write([{"label": "k0-x1", "value": 1.0}], tmp_path)
    assert not list(tmp_path.iterdir())
