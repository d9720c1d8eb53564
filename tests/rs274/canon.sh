#!/usr/bin/env bash
# Runs a program through LinuxCNC's standalone interpreter and prints its canonical
# machining calls (STRAIGHT_FEED, ARC_FEED, offsets, units, ...) on standard output:
#   tests/rs274/canon.sh PROGRAM.ngc [TOOLS.tbl]
# TOOLS.tbl is a LinuxCNC tool table in millimetres, as Kerf reads it. The standalone
# rs274 takes its tool table in inches (its machine unit), so the lengths and diameters
# are divided by 25.4 for it. Without TOOLS.tbl the table is empty.
# rs274 comes from tests/rs274/fetch.sh ($KERF_RS274_DIR, else target/rs274).
# Exit status: rs274's (non-zero when it refused the program; its message is on stderr).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
dir="${KERF_RS274_DIR:-$repo/target/rs274}"
if [ ! -x "$dir/root/usr/bin/rs274" ]; then
    echo "rs274 is not in $dir: run tests/rs274/fetch.sh first" >&2
    exit 3
fi
program="$1"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
: > "$tmp/tool.tbl"
if [ $# -ge 2 ]; then
    # T P stay; X Y Z U V W D are lengths (mm to inch); A B C I J Q are angles or codes.
    awk '{
        out = "";
        for (i = 1; i <= NF; i++) {
            w = $i;
            if (substr(w, 1, 1) == ";") { break }
            l = toupper(substr(w, 1, 1));
            if (index("XYZUVWD", l) > 0) { w = sprintf("%s%.10f", l, substr(w, 2) / 25.4) }
            out = out (out == "" ? "" : " ") w;
        }
        print out;
    }' "$2" > "$tmp/tool.tbl"
fi
# rs274 reads the program's directory for subroutine files; run it from there.
cd "$(dirname "$program")"
export LD_LIBRARY_PATH="$dir/root/usr/lib:$dir/root/usr/lib/x86_64-linux-gnu"
exec timeout 60 "$dir/root/usr/bin/rs274" -g -t "$tmp/tool.tbl" "$(basename "$program")" </dev/null
