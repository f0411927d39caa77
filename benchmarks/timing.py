"""The benchmarks' shared helpers: a scene's command line and output folder (`scene_parser`,
`scene_and_out`), and the wall and CPU seconds and calls of a wrapped function (`tally`).

PETSc's log events (`PETSc.Log.Event(name).getPerfInfo()`) count the solver's own operations
but time them in wall seconds only; on a shared machine the wall time includes the other
processes' turns, so the benchmarks print this process's CPU seconds next to it.
"""

import argparse
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from fingertip_dolfinx.scene import Scene, load_scene


def scene_parser(doc: str, scene: str, out: bool = True) -> argparse.ArgumentParser:
    """A benchmark's command line (help: `doc`, as written) with the options of every scene
    benchmark: --scene (default `scene`), --set key=value (repeated, in `overrides`) and, with
    `out`, --out (default: a fresh temporary folder, `scene_and_out`)."""
    parser = argparse.ArgumentParser(description=doc,
                                     formatter_class=argparse.RawTextHelpFormatter)
    parser.add_argument("--scene", default=scene)
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    if out:
        parser.add_argument("--out", type=Path, default=None, help="keep the results here")
    return parser


def scene_and_out(args, comm, overrides: list[str] | None = None) -> tuple[Scene, Path]:
    """(the scene, the output folder) of parsed `scene_parser` options on `comm`: the scene
    `--scene` with `overrides` (default: the --set ones), and --out or else one temporary
    folder that rank 0 makes and every rank shares."""
    scene = load_scene(args.scene, args.overrides if overrides is None else overrides)
    out = getattr(args, "out", None)
    return scene, out or Path(comm.bcast(tempfile.mkdtemp() if comm.rank == 0 else None))


@dataclass
class Tally:
    """Totals over the calls of one wrapped function."""

    wall: float = 0.0
    cpu: float = 0.0
    calls: int = 0

    def per_call(self) -> tuple[float, float]:
        """(wall, CPU) seconds per call (0 without calls)."""
        n = max(self.calls, 1)
        return self.wall / n, self.cpu / n


def tally(owner, name: str) -> Tally:
    """Replace the attribute `name` of `owner` (a module, class or object) by a wrapper that
    adds each call's wall and CPU seconds to the returned Tally. Wrap a module's function
    before anything looks it up (DOLFINx's NonlinearProblem keeps the assemblers it finds)."""
    totals, function = Tally(), getattr(owner, name)

    def timed(*args, **kwargs):
        wall, cpu = time.perf_counter(), time.process_time()
        try:
            return function(*args, **kwargs)
        finally:
            totals.wall += time.perf_counter() - wall
            totals.cpu += time.process_time() - cpu
            totals.calls += 1

    setattr(owner, name, timed)
    return totals
