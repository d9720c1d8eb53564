#!/usr/bin/env bash
# The daemon keeps up with code that never repeats (issue 31): a seeded non-repeating
# dense surface (benches' gen_surface) run through `kerfd` with `kerf run --record`, and
# the same program through `kerf sim`; the two CSVs must be byte-equal (a daemon whose
# planning fell behind would have run with less lookahead, or starved, and differ).
# Prints the comparison, the daemon's overruns and the wall time. A measurement for
# docs/PERFORMANCE.md, never a test.
#
#   benches/keep_up.sh BIN_DIR SEGMENTS PERIOD_US [SEED [NOISE_MM]]
#   e.g. benches/keep_up.sh target/release 200000 250
#        benches/keep_up.sh target/release 1500 1000 1 0.02   # slow to plan: the motion
#                                                             # starts before a full queue
# The machine is benches/cam-mill.toml with the Y travel widened for long programs and
# the period given; it runs under SCHED_FIFO where allowed (as kerfd does).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
bin="$1"
segments="$2"
period_us="$3"
seed="${4:-1}"
noise_mm="${5:-}"
# A stale binary would measure another build: refuse one older than any source it is
# built from.
build="cargo build --release -p kerf -p kerfd -p kerf-benches --bins"
for b in kerf kerfd gen_surface; do
    [ -x "$bin/$b" ] || { echo "keep_up.sh: error: $bin/$b not found; build with: $build" >&2; exit 2; }
    newer="$(find "$here"/../crates/*/src "$here"/../crates/*/Cargo.toml "$here/src" "$here/Cargo.toml" "$here/../Cargo.toml" "$here/../Cargo.lock" -newer "$bin/$b" \( -name '*.rs' -o -name 'Cargo.*' \) -print -quit)"
    if [ -n "$newer" ]; then
        echo "keep_up.sh: error: $bin/$b is older than $newer; build with: $build" >&2
        exit 2
    fi
done
dir="$(mktemp -d)"
cleanup() {
    [ -n "${daemon:-}" ] && kill "$daemon" 2>/dev/null && wait "$daemon" 2>/dev/null
    rm -rf "$dir"
}
trap cleanup EXIT
machine="keep$$"
python3 - "$here/cam-mill.toml" "$dir/kerf.toml" "$machine" "$period_us" <<'PY'
import sys
src, dst, machine, period = sys.argv[1:]
s = open(src).read()
s = s.replace('machine = "cam-bench"', f'machine = "{machine}"')
s = s.replace("period_us = 1000", f"period_us = {period}")
i = s.index("[axes.y]")
j = s.index("max_mm = 1000.0", i)
s = s[:j] + "max_mm = 100000.0" + s[j + len("max_mm = 1000.0"):]
open(dst, "w").write(s)
PY
"$bin/gen_surface" --segments "$segments" --seed "$seed" ${noise_mm:+--noise-mm "$noise_mm"} > "$dir/surface.ngc"
"$bin/kerfd" --config "$dir/kerf.toml" > "$dir/kerfd.log" 2>&1 &
daemon=$!
for _ in $(seq 100); do
    "$bin/kerf" status --config "$dir/kerf.toml" >/dev/null 2>&1 && break
    sleep 0.1
done
start=$EPOCHREALTIME
"$bin/kerf" run --config "$dir/kerf.toml" --record "$dir/run.csv" "$dir/surface.ngc" >/dev/null
end=$EPOCHREALTIME
overruns="$("$bin/kerf" status --json --config "$dir/kerf.toml" | python3 -c 'import json,sys; print(json.load(sys.stdin)["overruns"])')"
kill "$daemon"
wait "$daemon" 2>/dev/null || true
daemon=""
"$bin/kerf" sim --config "$dir/kerf.toml" "$dir/surface.ngc" --out "$dir/sim.csv" >"$dir/sim.txt"
rows=$(($(wc -l < "$dir/sim.csv") - 1))
if cmp -s "$dir/sim.csv" "$dir/run.csv"; then same="byte-equal"; else same="DIFFERENT"; fi
echo "$segments segments, period $period_us us: kerf run $(python3 -c "print(round($end - $start, 1))") s wall, $rows setpoints, daemon overruns $overruns, setpoints vs kerf sim: $same; kerf sim: $(cat "$dir/sim.txt")"
