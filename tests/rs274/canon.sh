#!/usr/bin/env bash
# Runs a program through LinuxCNC's standalone interpreter and prints its canonical
# machining calls (STRAIGHT_FEED, ARC_FEED, offsets, units, ...) on standard output:
#   tests/rs274/canon.sh PROGRAM.ngc [TOOLS.tbl|- [PARAMS.var]]
# TOOLS.tbl is a LinuxCNC tool table in millimetres, as Kerf reads it. The standalone
# rs274 takes its tool table in inches (its machine unit), so the lengths and diameters
# are divided by 25.4 for it. Without TOOLS.tbl (or with `-`) the table is empty.
# PARAMS.var is a LinuxCNC parameter file (`NUMBER VALUE` lines) in millimetres and
# degrees: the persistent parameters at program start (G28/G30 positions #5161-#5169 and
# #5181-#5189, G92 #5210-#5219, coordinate systems #5220-#5390). Its lengths are divided by
# 25.4 for rs274 as well.
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
if [ $# -ge 2 ] && [ "$2" != "-" ]; then
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
params=()
if [ $# -ge 3 ]; then
    # Lengths: X Y Z and U V W of G28 (5161), G30 (5181), G92 (5211) and of the nine
    # coordinate systems (5221 + 20 k); A B C and the rotation stay degrees.
    awk '{
        n = $1 + 0; v = $2 + 0; len = 0;
        if (n >= 5161 && n <= 5169) { o = n - 5161; len = (o <= 2 || o >= 6) }
        if (n >= 5181 && n <= 5189) { o = n - 5181; len = (o <= 2 || o >= 6) }
        if (n >= 5211 && n <= 5219) { o = n - 5211; len = (o <= 2 || o >= 6) }
        if (n >= 5221 && n <= 5389) { o = (n - 5221) % 20; len = (o <= 2 || (o >= 6 && o <= 8)) }
        if (NF >= 2) { printf "%d\t%.10f\n", n, (len ? v / 25.4 : v) }
    }' "$3" > "$tmp/params.var"
    params=(-v "$tmp/params.var")
fi
# A program whose first line is the comment `(kerf: block_delete on)` runs with the block
# delete switch on (rs274 -b; Kerf's harness sets Settings::block_delete for it).
flags=()
if head -n 1 "$program" | grep -qi '(kerf: block_delete on)'; then
    flags=(-b)
fi
# rs274 reads the program's directory for subroutine files; run it from there.
cd "$(dirname "$program")"
export LD_LIBRARY_PATH="$dir/root/usr/lib:$dir/root/usr/lib/x86_64-linux-gnu"
# Not exec: the trap removes the temporary files (rs274 rewrites the parameter file).
timeout 60 "$dir/root/usr/bin/rs274" -g "${flags[@]}" -t "$tmp/tool.tbl" "${params[@]}" "$(basename "$program")" </dev/null
