#!/bin/sh
# The image's entry point: `fingertip` with the given arguments, after one check that a
# docker run can get wrong without the program being at fault. A host folder mounted on
# /home/fingertip/results that this container's user cannot write (the engine creates a
# missing host folder owned by root; a folder of another host user is refused to uid 1000)
# would end in a PermissionError deep in a run: say so, with the fix, before anything runs.
results=/home/fingertip/results
case "${1:-}" in
    "" | -h | --help) ;;
    *)
        if [ -d "$results" ] && ! [ -w "$results" ]; then
            echo "error: $results (the folder mounted with -v) is not writable by this container's user (uid $(id -u))." >&2
            echo "       Docker creates a missing host folder owned by root, and uid $(id -u) may not be its owner." >&2
            echo "       Fix: on the host, create the folder yourself and run as yourself:" >&2
            echo "            mkdir -p results && docker run --rm --user \"\$(id -u):\$(id -g)\" -v \"\$PWD/results:$results\" ..." >&2
            echo "       (a results/ the engine already made is owned by root: remove it with sudo first)." >&2
            exit 2
        fi
        ;;
esac
exec fingertip "$@"
