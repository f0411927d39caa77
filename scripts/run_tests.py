"""The default test command: the tests marked `mpi` on N ranks, then the whole suite serially.

The serial run goes last so that the final line is pytest's own summary of the full suite.
Exit code 5 (no tests collected) of the parallel part is not a failure: a suite may have
no MPI tests yet.
"""

import argparse
import os
import subprocess
import sys
from pathlib import Path

bindir = Path(sys.executable).parent


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--np", type=int, default=2, help="MPI ranks for the parallel part")
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

    serial = [sys.executable, "-m", "pytest", "-q", "--durations=8", *args.pytest_args]
    print("$", " ".join(serial), flush=True)
    return subprocess.call(serial, env=env)


if __name__ == "__main__":
    sys.exit(main())
