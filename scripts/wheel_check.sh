#!/usr/bin/env bash
# Installs anywhere: build this checkout's wheel, install it (not editable) into a fresh
# virtual environment, and run a scene from a directory outside the checkout.
#
# It checks that the built-in data (scenes, sections, indenters, materials) ship inside the
# wheel and are found with importlib.resources, that the `fingertip` command works, and that
# the package comes from the fresh environment's site-packages, not from the checkout.
#
# The fresh environment borrows the heavy dependencies (DOLFINx, PETSc, MPI, gmsh, ...) of
# $VENV (default: the checkout's .venv, which `make` builds) instead of installing them again:
# installing them takes minutes and downloads them, and a check of *our* package gains nothing
# from it. The borrowing is done the way site-packages are composed anyway:
#   - a .pth file names $VENV's site-packages (a plain path line: the .pth files *there* are not
#     run, so the editable install of the checkout in $VENV stays invisible);
#   - $VENV/lib's shared libraries are linked into the fresh lib/ (the mpich wheel installs
#     libmpi into <prefix>/lib, and mpi4py looks for it under sys.prefix).
# Only our wheel is installed, with --no-deps, from the file just built.
#
# Usage: bash scripts/wheel_check.sh          (KEEP=1 keeps the work directory)
# Takes ~15 s (wheel ~2 s, environment ~3 s, the coarse 1pt run ~7 s).
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${VENV:-$here/.venv}"
PY="$VENV/bin/python"
if [ ! -x "$PY" ]; then
    echo "wheel check: error: no $PY. Fix: run 'make install' first (or set VENV=...)." >&2
    exit 1
fi

work="$(mktemp -d "${TMPDIR:-/tmp}/fingertip-wheel-check.XXXXXX")"
if [ "${KEEP:-0}" = 1 ]; then
    echo "wheel check: keeping $work"
else
    trap 'rm -rf "$work"' EXIT
fi
started=$SECONDS
say() { echo "wheel check [$((SECONDS - started)) s]: $*"; }

# 1. The wheel, built from a copy of the checkout's files (tracked and untracked, not ignored):
#    setuptools writes build/ and *.egg-info next to the sources, and none of that belongs here.
mkdir -p "$work/src"
if git -C "$here" rev-parse --is-inside-work-tree >/dev/null 2>&1; then
    (cd "$here" && git ls-files -z --cached --others --exclude-standard \
        | xargs -0 cp --parents -t "$work/src" 2>/dev/null || true)
else
    (cd "$here" && tar --exclude=./.venv --exclude=./results --exclude=./.git -cf - .) \
        | tar -xf - -C "$work/src"
fi
[ -f "$work/src/pyproject.toml" ] || { echo "wheel check: error: copying the checkout failed" >&2; exit 1; }
PIP_NO_INDEX=1 "$PY" -m pip wheel --quiet --no-deps --no-build-isolation -w "$work/dist" "$work/src"
wheel="$(ls "$work"/dist/fingertip_dolfinx-*.whl)"
say "built $(basename "$wheel")"

# 2. A fresh environment on the same interpreter, borrowing $VENV's dependencies.
"$PY" -m venv --without-pip "$work/venv"
fresh_site="$("$work/venv/bin/python" -c 'import sysconfig; print(sysconfig.get_path("purelib"))')"
deps_site="$("$PY" -c 'import sysconfig; print(sysconfig.get_path("purelib"))')"
echo "$deps_site" >"$fresh_site/_fingertip_borrowed_dependencies.pth"
for lib in "$VENV"/lib/*; do
    case "$(basename "$lib")" in
        python*) ;;  # the interpreter's own tree: the fresh environment has its own
        *) ln -s "$lib" "$work/venv/lib/" ;;
    esac
done
"$PY" -m pip --python "$work/venv/bin/python" install --quiet --no-deps --no-index "$wheel"
say "installed it into a fresh environment ($work/venv)"

# 3. From a directory outside the checkout, with nothing pointing at the checkout.
mkdir -p "$work/elsewhere"
cd "$work/elsewhere"
unset PYTHONPATH VIRTUAL_ENV
export PYTHONNOUSERSITE=1 OMP_NUM_THREADS="${OMP_NUM_THREADS:-1}"
head -n 1 "$work/venv/bin/fingertip" | grep -qx "#!$work/venv/bin/python" \
    || { echo "wheel check: error: fingertip's launcher does not run the fresh python" >&2; exit 1; }
"$work/venv/bin/fingertip" run 1pt --set section.mesh.min_size=0.3 \
    --set section.mesh.max_size=1.0 --set section.mesh.bone_size=2.0 --out out --quiet
say "ran 'fingertip run 1pt' in $work/elsewhere"

"$work/venv/bin/python" - "$fresh_site" "$here" <<'PY'
import importlib.metadata
import json
import sys
from pathlib import Path

import fingertip_dolfinx as ft
from fingertip_dolfinx.scene import SCENES_DIR

fresh_site, checkout = Path(sys.argv[1]).resolve(), Path(sys.argv[2]).resolve()
package = Path(ft.__file__).resolve().parent
problems = []
if package.parent != fresh_site:
    problems.append(f"fingertip_dolfinx imported from {package}, not from {fresh_site}")
if checkout in SCENES_DIR.resolve().parents:
    problems.append(f"built-in scenes read from the checkout ({SCENES_DIR})")
dist = importlib.metadata.distribution("fingertip-dolfinx")
direct = dist.read_text("direct_url.json") or "{}"
if json.loads(direct).get("dir_info", {}).get("editable"):
    problems.append("the installed distribution is editable")
summary = json.loads(Path("out/summary.json").read_text())
if summary.get("converged") is not True:
    problems.append(f"the 1pt run did not converge: {summary.get('failure')}")
if not (summary.get("peak_force_N_per_mm") or 0) > 0:
    problems.append(f"no force in the 1pt run: {summary.get('peak_force_N_per_mm')}")
name = ft.load_scene("line-load").name
if name != "line-load":
    problems.append(f"load_scene('line-load').name is {name!r}")
if problems:
    sys.exit("wheel check: error: " + "; ".join(problems))
print(f"wheel check: fingertip_dolfinx {ft.__version__} from {package}; built-in scenes in "
      f"{SCENES_DIR}; 1pt converged in {summary['time_steps']} steps, peak force "
      f"{summary['peak_force_N_per_mm']:.4g} N/mm; load_scene('line-load').name = {name!r}")
PY
"$work/venv/bin/python" -c "import fingertip_dolfinx as ft; print(ft.load_scene('line-load').name)"
say "passed"
