#!/usr/bin/env bash
# The one install recipe: used by `make` (first use), `.ci/run` and docker/Dockerfile.
#
# Finds a Python >= 3.12 (the DOLFINx wheel needs it): $PYTHON if set, then the PATH,
# then pyenv's installed versions. Creates the virtual environment $VENV (default .venv)
# and installs this package into it, editable, with the extras $EXTRAS.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${VENV:-$here/.venv}"
EXTRAS="${EXTRAS:-dolfinx,test}"

is_new_enough() { "$1" -c 'import sys; sys.exit(sys.version_info < (3, 12))' >/dev/null 2>&1; }

find_python() {
    local candidate
    for candidate in ${PYTHON:-} python3.12 python3.13 python3 python; do
        # A pyenv shim exists on the PATH even when it cannot run, so try each one.
        if command -v "$candidate" >/dev/null 2>&1 && is_new_enough "$candidate"; then
            command -v "$candidate"
            return 0
        fi
    done
    if command -v pyenv >/dev/null 2>&1; then
        local version
        for version in $(pyenv versions --bare 2>/dev/null | grep -E '^3\.(1[2-9]|[2-9][0-9])(\.|$)' | sort -rV); do
            candidate="$(pyenv root)/versions/$version/bin/python3"
            if [ -x "$candidate" ] && is_new_enough "$candidate"; then
                echo "$candidate"
                return 0
            fi
        done
    fi
    return 1
}

if [ ! -x "$VENV/bin/python" ]; then
    if ! python="$(find_python)"; then
        echo "error: no Python >= 3.12 found (DOLFINx 0.11's wheel needs it)." >&2
        echo "       Looked at \$PYTHON, python3.12, python3.13, python3, python on the PATH, and pyenv." >&2
        echo "       Fix: install Python 3.12 or newer (e.g. 'pyenv install 3.12'), or set PYTHON=/path/to/python3.12." >&2
        exit 1
    fi
    echo "fingertip-dolfinx: creating $VENV with $python ($("$python" --version))"
    "$python" -m venv "$VENV"
fi

"$VENV/bin/python" -m pip install --quiet --upgrade pip
"$VENV/bin/python" -m pip install --quiet -e "$here[$EXTRAS]"
# Check that the stack imports (and that the C compiler FFCx needs is there) before anyone relies on it.
"$VENV/bin/python" - <<'PY'
import shutil, sys
import fingertip_dolfinx  # sets up the DOLFINx wheel first
import dolfinx, gmsh
if shutil.which("cc") is None and shutil.which("gcc") is None:
    sys.exit("error: no C compiler (cc/gcc) on the PATH: DOLFINx compiles forms at run time. "
             "Fix: install gcc (Debian: apt-get install build-essential).")
print(f"fingertip-dolfinx: DOLFINx {dolfinx.__version__}, gmsh {gmsh.__version__}, Python {sys.version.split()[0]} ready")
PY
