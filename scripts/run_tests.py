"""The default test command: the tests marked `mpi` on N ranks, then the whole suite on one rank.

The one-rank run goes last so that the final line is pytest's own summary of the full suite.
It is spread over the machine's cores by pytest-xdist, one test file per worker at a time
(`--dist loadfile`, so that a module's fixtures are computed once); most of its time is the
JIT compilation of forms (FFCx and a C compiler, one process per form), which the workers do
side by side. `--workers 1` runs it in one process. Exit code 5 (no tests collected) of the
parallel part is not a failure: a suite may have no MPI tests yet.
"""

import argparse
import importlib.util
import os
import subprocess
import sys
from pathlib import Path

bindir = Path(sys.executable).parent


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--np", type=int, default=2, help="MPI ranks for the parallel part")
    parser.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1),
                        help="pytest-xdist workers for the one-rank part (default: up to 2)")
    parser.add_argument("pytest_args", nargs="*", help="extra arguments passed to pytest")
    args = parser.parse_args()

    env = dict(os.environ, PYTHONUNBUFFERED="1")
    mpiexec = bindir / "mpiexec" if (bindir / "mpiexec").exists() else "mpiexec"
    parallel = [str(mpiexec), "-n", str(args.np), sys.executable, "-m", "pytest", "-q",
                "-m", "mpi and not slow", *args.pytest_args]
    print("$", " ".join(parallel), flush=True)
    code = subprocess.call(parallel, env=env)
    if code not in (0, 5):
        print(f"parallel tests failed on {args.np} ranks (exit {code})", flush=True)
        return code

    serial = [sys.executable, "-m", "pytest", "-q", "--durations=8", *_workers(args.workers),
              *args.pytest_args]
    print("$", " ".join(serial), flush=True)
    return subprocess.call(serial, env=env)


def _workers(count: int) -> list[str]:
    """pytest-xdist's options for `count` workers, none for one (or without pytest-xdist)."""
    if count <= 1 or importlib.util.find_spec("xdist") is None:
        return []
    return ["-n", str(count), "--dist", "loadfile"]


if __name__ == "__main__":
    sys.exit(main())
