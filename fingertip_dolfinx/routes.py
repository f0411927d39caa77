"""The route a scene takes, the same from Python (`ft.run`) and from `fingertip run`.

`run(scene, out, ...)` sends a scene

- with a `[harmonic]` table, or given `frequencies` or `state`, to the **frequency route**
  (frequency_response.py: the small-signal response about the pressed state); it returns a
  `FrequencyResult` (result.py: K(ω), Z(ω), the receptor transfer functions, the thresholds);
- with a tolerance (`tol`, else the scene's `[accuracy] tol`) or `max_levels`, to the
  **adaptive loop** (studies.adaptivity: meshes refined until every key output's estimated error
  is below `tol`); it returns the `Result` of the answer, the finest level, whose files are
  copied into `out` (the loop's record: out/adapt.json, `adaptivity.read_adapt(out)`);
- otherwise to **one time run** (runner.py); it returns its `Result`.

`fidelity="auto"` first picks the cheapest model of the fidelity ladder whose key outputs stay
within `tol` of the full model (studies/fidelity.py), then routes the scene with that model.
The returned object's `route` says which route was taken ("time", "adaptive", "frequency").
`fingertip run` parses its command line into these arguments and prints what comes back; an
error names an argument as the command line spells it (`--tol` for `tol=`).

The heavy modules (DOLFINx) are imported by the functions that need them, so that the command
line's `--help`, which reads the defaults below, stays instant.
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from .errors import InputError, RunInterrupted

if TYPE_CHECKING:
    from mpi4py import MPI

    from .result import FrequencyResult, Result
    from .scene import Scene

#: The routes, in the order they are tried.
ROUTES = ("frequency", "adaptive", "time")
#: `fidelity="auto"`: the model's tolerance when no `tol` is given.
AUTO_FIDELITY_TOL = 0.05
#: The coarse settings the fidelity ladder runs at (and the studies, unless --full): a mesh
#: 2x coarser than the scenes'.
FIDELITY_COARSE = ("section.mesh.min_size=0.2", "section.mesh.max_size=1.0",
                   "section.mesh.bone_size=2.0")


def run(scene: Scene | str | Path, out: str | Path, *,
        overrides: Mapping | Sequence[str] = (), spacing: float | None = None,
        tol: float | None = None, max_levels: int | None = None, fidelity: str = "scene",
        fidelity_table: str | Path | None = None, frequencies=None, state: str | None = None,
        resume: bool = False, progress: bool = True, comm: MPI.Comm | None = None,
        say: Callable[[str], None] | None = None) -> Result | FrequencyResult:
    """Run `scene` into `out` by its route (the module's docstring) and return its results.

    Parameters
    ----------
    scene : a `Scene`, or a built-in scene's name or a scene file (loaded with `overrides`
        and `spacing`, as `load_scene` does; `fidelity="auto"` needs this form).
    out : the output directory.
    overrides, spacing : applied to the scene file (`key=value` strings or nested tables;
        a 2pt scene's bar spacing, mm), as `fingertip run`'s --set, --config and --spacing.
    tol : relative error asked of every key output: the adaptive loop (with
        `fidelity="auto"`: the model's tolerance instead, default `AUTO_FIDELITY_TOL`).
    max_levels : most mesh levels of the adaptive loop (default: the scene's `[accuracy]`).
    fidelity : "scene" (the scene's own model) or "auto".
    fidelity_table : a fidelity.csv for `fidelity="auto"`; without it the ladder is run on
        a coarse mesh into out/fidelity/ first.
    frequencies, state : the frequency route's frequencies (Hz: "START:STOP:COUNT" or a
        list) and pressed state ("held" or "relaxed"), over the scene's `[harmonic]`.
    resume : continue an interrupted time run in `out`.
    progress : show progress bars (and `say` prints its sentences).
    comm : the ranks that run it (default: all of MPI.COMM_WORLD).
    say : where the route's sentences go (which model `fidelity="auto"` picked, the
        adaptive loop's verdict); default: printed by rank 0 to stderr when `progress`.

    Returns
    -------
    `Result` (time and adaptive routes) or `FrequencyResult`, with `route` set.

    Raises
    ------
    InputError for arguments that do not fit the route; `ConvergenceError` (files written up
    to the last good step); `RunInterrupted` on SIGINT/SIGTERM (its `route` set too).
    """
    say, out = say or _printer(progress), _out_folder(out)
    source, scene = scene, _scene_of(scene, overrides, spacing, fidelity)
    kind = check_route(scene, tol=tol, max_levels=max_levels, frequencies=frequencies,
                       state=state, fidelity=fidelity, fidelity_table=fidelity_table,
                       resume=resume)
    mesh_tol = None if fidelity == "auto" else tol  # auto: the mesh by [accuracy] tol
    if fidelity == "auto":
        scene = _with_picked_model(source, out, overrides, spacing, tol, fidelity_table,
                                   progress, say)
    try:
        result = (_frequency(scene, out, frequencies, state, progress, comm)
                  if kind == "frequency" else
                  _adaptive(scene, out, mesh_tol, max_levels, resume, progress, comm, say)
                  if kind == "adaptive" else _time(scene, out, resume, progress, comm, say))
    except RunInterrupted as stop:
        stop.route = kind  # only a time run can be resumed
        raise
    result.route = kind
    return result


def route_of(scene: Scene, *, tol: float | None = None, max_levels: int | None = None,
             frequencies=None, state: str | None = None) -> str:
    """The route `run` takes for `scene` with these arguments, nothing computed.

    Parameters
    ----------
    scene : Scene
        The experiment.
    tol, max_levels, frequencies, state
        As for `run`.

    Returns
    -------
    str
        "frequency" (a `[harmonic]` table, `frequencies` or `state`), "adaptive" (`tol`, the
        scene's `[accuracy] tol`, or `max_levels`) or "time".
    """
    if frequencies is not None or state is not None or scene.harmonic is not None:
        return "frequency"
    if tol is None:
        tol = scene.accuracy.tol
    if tol is not None or max_levels is not None:
        return "adaptive"
    return "time"


def check_route(scene: Scene, *, tol: float | None = None, max_levels: int | None = None,
                frequencies=None, state: str | None = None, fidelity: str = "scene",
                fidelity_table=None, resume: bool = False) -> str:
    """The route `run` takes for `scene` (`route_of`), refused before anything is computed if
    it cannot be taken: an option off the route (`_refuse_off_route`), or a scene whose key
    outputs the route compares but cannot read (`keys.check_scene`: the adaptive loop's levels,
    the fidelity ladder of `fidelity="auto"`). `run` and `fingertip run --check` ask the same.
    The route is the scene's as given: the model "auto" picks changes the physics, not the
    route (with "auto", `tol` is the model's tolerance and the mesh follows `[accuracy] tol`)."""
    from .keys import check_scene

    auto = fidelity == "auto"
    kind = route_of(scene, tol=None if auto else tol, max_levels=max_levels,
                    frequencies=frequencies, state=state)
    _refuse_off_route(kind, {"resume": resume, "tol": tol, "max_levels": max_levels,
                             "fidelity": fidelity})
    if auto and fidelity_table is None:  # the ladder is run first: a fidelity study
        check_scene(scene, f"{scene.name}: --fidelity auto")
    if kind == "adaptive":
        check_scene(scene, f"{scene.name}: the adaptive loop (--tol)")
    return kind


def _out_folder(out: str | Path) -> Path:
    """`out` as a Path; an empty string (an unset shell variable) is refused: Path("") is the
    working folder, where a fresh run would remove an earlier run's files by name."""
    if isinstance(out, str) and not out.strip():
        raise InputError(f"out {out!r}", "is empty: it would be the working folder.",
                         'give the folder the results go to, e.g. "results/1pt".')
    return Path(out)


def _scene_of(scene, overrides, spacing, fidelity: str) -> Scene:
    """The scene as given: a `Scene`, or loaded from its name or file with the overrides."""
    from .scene import Scene

    if fidelity not in ("scene", "auto"):
        raise InputError(f"fidelity {fidelity!r}", "is not a fidelity.", 'use "scene" or "auto".')
    if isinstance(scene, Scene):
        if overrides or spacing is not None:
            raise InputError("overrides/spacing", "apply to a scene read from its file.",
                             "give the scene's name or file, or load_scene(..., overrides).")
        if fidelity == "auto":
            raise InputError("--fidelity auto", "runs the scene file again with each model of "
                             "the ladder, and a Scene object has no file.",
                             "give the scene's name or file (with overrides=) instead.")
        return scene
    return _load(scene, _as_list(overrides), spacing)


def _with_picked_model(source, out: Path, overrides, spacing, tol, table, progress,
                       say) -> Scene:
    """The scene with the model `auto_fidelity` picks within `tol` (default
    `AUTO_FIDELITY_TOL`)."""
    overrides = _as_list(overrides)
    model_tol = AUTO_FIDELITY_TOL if tol is None else tol
    overrides += auto_fidelity(source, out, overrides, model_tol, table, progress, say)
    return _load(source, overrides, spacing)


def _load(source, overrides: list, spacing) -> Scene:
    from .scene import load_scene

    return load_scene(source, overrides, spacing=spacing)


def _refuse_off_route(kind: str, given: Mapping) -> None:
    """InputError for an option the route cannot use, named as the command line spells it
    (the frequency route has no mesh loop, no model picking and no checkpoint to resume)."""
    if kind != "frequency":
        return
    for flag, used in (("--resume", given["resume"]), ("--tol", given["tol"] is not None),
                       ("--max-levels", given["max_levels"] is not None),
                       ("--fidelity auto", given["fidelity"] == "auto")):
        if used:
            raise InputError(flag, "is not available on the frequency route.",
                             f"drop {flag} (or --frequencies).")


def _as_list(overrides) -> list:
    """Overrides as a list of `key=value` texts (a nested mapping flattened)."""
    from .scene import overrides_as_text

    return list(overrides_as_text(overrides))


def auto_fidelity(source: str | Path, out: Path, overrides: list, tol: float,
                  table: str | Path | None = None, progress: bool = True,
                  say: Callable[[str], None] = print) -> list[str]:
    """The overrides of the cheapest model of the fidelity ladder within `tol` of the full
    one, from `table` (a fidelity.csv) or from the ladder run on a coarse mesh into
    out/fidelity/; `say` is told which model was picked and why."""
    from .studies.fidelity import pick, read_table, run_fidelity_study, settings_of

    if not tol > 0:
        raise InputError("--tol", f"must be positive, got {tol}.")
    if table is not None:
        if not Path(table).is_file():
            raise InputError(f"--fidelity-table {table}", "no such file.",
                             "run `fingertip study fidelity` first, or leave it out.")
        rows, where = read_table(Path(table)), str(table)
    else:
        say("--fidelity auto: running the fidelity ladder on a coarse mesh first")
        rows = run_fidelity_study(source, out / "fidelity", list(FIDELITY_COARSE) + overrides,
                                  progress=progress)
        where = f"{out}/fidelity/fidelity.csv"
    try:
        model, why = pick(rows, tol)
    except StopIteration:
        raise InputError("--tol", f"no model of the ladder is within {tol:.2%} of the full "
                         "model (not even the full one with rigid bone).",
                         "raise --tol or use --fidelity scene.") from None
    say(f"--fidelity auto picked '{model}': {why} (from {where})")
    return settings_of(model)


def _time(scene: Scene, out: Path, resume: bool, progress: bool, comm, say) -> Result:
    """One run (runner.py); resuming a completed run computes nothing."""
    from mpi4py import MPI

    from .result import Result
    from .runner import completed_summary, run_scene

    if resume and completed_summary(scene, out, comm or MPI.COMM_WORLD) is not None:
        say(f"{scene.name}: the run in {out} is already complete (to t = "
            f"{scene.history.end_time:g} s); nothing computed, nothing rewritten.")
    else:
        run_scene(scene, out, resume=resume, progress=progress, comm=comm)
    return Result(out)


def _adaptive(scene: Scene, out: Path, tol, max_levels, resume, progress, comm, say) -> Result:
    """The adaptive mesh loop (studies.adaptivity) to `tol`, else the scene's [accuracy] tol; the
    answer's files are in `out`."""
    from .result import Result
    from .studies.adaptivity import AdaptOptions, adapt

    if tol is None:
        tol = scene.accuracy.tol
    if tol is None:
        raise InputError("--max-levels", "is for the adaptive loop.",
                         "give --tol too (or [accuracy] tol in the scene).")
    if not 0 < tol < 1:
        raise InputError(f"--tol {tol}", "must be a relative error in (0, 1).",
                         "give e.g. --tol 0.01 for 1 %.")
    if max_levels is not None and max_levels < 2:
        raise InputError(f"--max-levels {max_levels}", "an error estimate needs two "
                         "levels.", "give 2 or more.")
    if resume:
        raise InputError("--resume", "cannot continue the adaptive loop (--tol or the scene's "
                         "[accuracy] tol).", "run it again into a new directory.")
    levels = scene.accuracy.max_levels if max_levels is None else max_levels
    scene = dataclasses.replace(scene, accuracy=dataclasses.replace(
        scene.accuracy, tol=tol, max_levels=levels))
    report = adapt(scene, out, AdaptOptions(tol=tol, max_levels=levels), progress=progress,
                   comm=comm)
    say(report["message"])
    return Result(out)


def _frequency(scene: Scene, out: Path, frequencies, state, progress, comm) -> FrequencyResult:
    """The frequency route (frequency_response.py)."""
    from mpi4py import MPI

    from .frequency_response import run_frequency_response
    from .harmonic_options import parse_frequencies
    from .result import FrequencyResult

    if frequencies is not None:  # named as given (the scene's [harmonic] names its own key)
        frequencies = parse_frequencies(frequencies, f"--frequencies {frequencies}")
    run_frequency_response(scene, out, frequencies=frequencies, state=state, progress=progress,
                           comm=comm or MPI.COMM_WORLD)
    return FrequencyResult(out)


def _printer(progress: bool) -> Callable[[str], None]:
    """Rank 0 prints to stderr when `progress`; otherwise nothing is said."""
    def say(text: str) -> None:
        from mpi4py import MPI

        if progress and MPI.COMM_WORLD.rank == 0:
            print(text, file=sys.stderr)
    return say
