#!/usr/bin/env bash
# The image's own check: build docker/Dockerfile and run, inside the image with no network,
#   1. fingertip mesh                       (gmsh, DOLFINx, a Matplotlib figure)
#   2. a coarse, short 1pt run              (the solver and the figures, VTK's off-screen
#                                            field maps among them: each PNG must be a PNG)
#   3. the tests marked mpi on 2 ranks      (MPICH inside Docker's seccomp profile)
#   4. a results folder it cannot write     (exit 2 and the fix, before anything runs)
# Run from anywhere:  bash scripts/docker_check.sh
# Uses the `docker` on the PATH (or $DOCKER) and whatever engine it reaches ($DOCKER_HOST).
# Environment: IMAGE (default fingertip-dolfinx), BUILD_OPTS (extra `docker build` options,
# e.g. "--network host" on an engine without a bridge network), SKIP_BUILD=1 (check an image
# already built), LOGS (folder for the logs; default a new temporary folder).
# Exit: 0 all checks pass, 1 a check failed, 0 with "skipped: no Docker engine ..." when no
# engine is reachable (so that a machine without Docker passes), 3 instead when REQUIRE_DOCKER=1.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
DOCKER="${DOCKER:-docker}"
IMAGE="${IMAGE:-fingertip-dolfinx}"
BUILD_OPTS="${BUILD_OPTS:-}"
LOGS="${LOGS:-$(mktemp -d "${TMPDIR:-/tmp}/docker-check.XXXXXX")}"
mkdir -p "$LOGS"

skip() {
    echo "docker_check: skipped: no Docker engine ($1); nothing was built or checked."
    [ "${REQUIRE_DOCKER:-0}" = "1" ] && exit 3
    exit 0
}
command -v "$DOCKER" >/dev/null 2>&1 || skip "no '$DOCKER' command on the PATH"
"$DOCKER" info >"$LOGS/info.log" 2>&1 \
    || skip "'$DOCKER info' cannot reach one${DOCKER_HOST:+ at $DOCKER_HOST}: $(tail -n 1 "$LOGS/info.log")"

if [ "${SKIP_BUILD:-0}" != "1" ]; then
    start=$(date +%s)
    # shellcheck disable=SC2086  # BUILD_OPTS is a list of options
    if ! "$DOCKER" build $BUILD_OPTS -f "$here/docker/Dockerfile" -t "$IMAGE" "$here" \
        >"$LOGS/build.log" 2>&1; then
        tail -n 20 "$LOGS/build.log"
        echo "docker_check: FAIL: docker build (log: $LOGS/build.log)"
        exit 1
    fi
    echo "built $IMAGE in $(( $(date +%s) - start )) s"
fi
echo "image $IMAGE: $("$DOCKER" image inspect -f '{{.Size}}' "$IMAGE" | awk '{printf "%.2f GB", $1/1e9}')"

# The results folder, mounted as the README says: created first, written as the caller
# (--user), or as the image's user 1000 when the caller is root.
out="$LOGS/results"
mkdir -p "$out"
if [ "$(id -u)" = "0" ]; then
    chown 1000:1000 "$out"
    as=()
else
    as=(--user "$(id -u):$(id -g)")
fi
mount=(-v "$out:/home/fingertip/results")
R=/home/fingertip/results
fails=0
total=0
check() {  # label, then the arguments of docker run after the mount
    local label=$1 start code
    shift
    total=$((total + 1))
    start=$(date +%s)
    if "$DOCKER" run --rm --network none "${as[@]}" "${mount[@]}" "$@" >"$LOGS/$label.log" 2>&1; then
        echo "ok    $label ($(( $(date +%s) - start )) s)"
        return 0
    else
        code=$?
        echo "FAIL  $label (exit $code, $(( $(date +%s) - start )) s): $(tail -n 3 "$LOGS/$label.log" | tr '\n' ' ')"
        fails=$((fails + 1))
        return 1
    fi
}
fail() {  # label, what is wrong
    echo "FAIL  $1: $2"
    fails=$((fails + 1))
}
is_png() {  # a non-empty file that starts with the PNG signature
    [ -s "$1" ] && [ "$(head -c 8 "$1" | od -An -tx1 | tr -d ' \n')" = "89504e470d0a1a0a" ]
}

if check mesh "$IMAGE" mesh --out "$R/mesh"; then
    for f in mesh.xdmf mesh.h5 mesh_report.json; do
        [ -s "$out/mesh/$f" ] || fail mesh "no $f written"
    done
    is_png "$out/mesh/mesh.png" || fail mesh "mesh.png missing, empty or not a PNG"
fi

# 1pt on a coarse mesh, pressed 0.5 mm in 0.5 s: seconds of solving, every figure drawn.
if check run-1pt "$IMAGE" run 1pt \
    --set section.mesh.min_size=0.3 --set section.mesh.max_size=1.0 \
    --set protocol.depth=0.5 --set protocol.ramp_time=0.5 --set protocol.end_time=0.5 \
    --set "output.times=[0.5]" --out "$R/1pt"; then
    [ -s "$out/1pt/summary.json" ] || fail run-1pt "no summary.json"
    pngs=("$out"/1pt/*.png)
    fields=("$out"/1pt/field_*.png)
    [ -e "${fields[0]}" ] || fail run-1pt "no field map (field_*.png: VTK's off-screen figures)"
    [ "${#pngs[@]}" -ge 4 ] || fail run-1pt "only ${#pngs[@]} PNG figures"
    for png in "${pngs[@]}"; do
        is_png "$png" || fail run-1pt "$(basename "$png") is empty or not a PNG"
    done
    echo "      $(ls "$out/1pt" | grep -c '\.png$') figures in $out/1pt"
fi

check mpi-2-ranks --workdir /home/fingertip/fingertip-dolfinx --entrypoint mpiexec "$IMAGE" \
    -n 2 python -m pytest -q -m "mpi and not slow" || true

# A mounted folder the container's user cannot write: the entry point must refuse, plainly.
locked="$LOGS/locked"
mkdir -p "$locked"
chmod 555 "$locked"
total=$((total + 1))
if [ "$(id -u)" = "0" ]; then
    locked_as=()  # root's 555 folder is closed to the image's user 1000
else
    locked_as=("${as[@]}")
fi
code=0
"$DOCKER" run --rm --network none "${locked_as[@]}" -v "$locked:$R" "$IMAGE" mesh --out "$R/mesh" \
    >"$LOGS/locked-results.log" 2>&1 || code=$?
if [ "$code" = "2" ] && grep -q "mkdir -p results" "$LOGS/locked-results.log"; then
    echo "ok    locked-results (exit 2 with the fix)"
else
    fail locked-results "exit $code, expected 2 with the fix: $(tail -n 2 "$LOGS/locked-results.log" | tr '\n' ' ')"
fi
chmod 755 "$locked"

echo "docker_check: $((total - fails))/$total checks pass (logs and results: $LOGS)"
[ "$fails" -eq 0 ]
