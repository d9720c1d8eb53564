#!/usr/bin/env bash
# Writes the golden files of LinuxCNC programs from LinuxCNC's standalone interpreter:
#   tests/rs274/golden.sh tests/data/ngc/AREA/NAME.ngc [...]
# For each NAME.ngc: NAME.canon = rs274's standard output (tests/rs274/canon.sh, with
# NAME.tbl as the tool table and NAME.var as the parameters when they exist); when rs274 refuses the program, NAME.err =
# `exit N` and rs274's standard error (otherwise a stale NAME.err is removed). Never edit
# these files by hand. rs274 comes from tests/rs274/fetch.sh ($KERF_RS274_DIR).
set -uo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
status=0
for program in "$@"; do
    base="${program%.ngc}"
    extra=(-)
    [ -f "$base.tbl" ] && extra=("$(cd "$(dirname "$base.tbl")" && pwd)/$(basename "$base.tbl")")
    [ -f "$base.var" ] && extra+=("$(cd "$(dirname "$base.var")" && pwd)/$(basename "$base.var")")
    abs="$(cd "$(dirname "$program")" && pwd)/$(basename "$program")"
    errtmp="$(mktemp)"
    bash "$here/canon.sh" "$abs" "${extra[@]}" > "$base.canon" 2> "$errtmp"
    code=$?
    if [ "$code" -eq 3 ]; then
        cat "$errtmp" >&2
        rm -f "$errtmp" "$base.canon"
        exit 3
    fi
    if [ "$code" -ne 0 ]; then
        { echo "exit $code"; cat "$errtmp"; } > "$base.err"
        echo "$program: rs274 refuses it (exit $code): $(tail -n 2 "$errtmp" | head -n 1)"
    else
        rm -f "$base.err"
        echo "$program: $(grep -c -E 'STRAIGHT_|ARC_FEED' "$base.canon") moves"
    fi
    rm -f "$errtmp"
done
exit $status
