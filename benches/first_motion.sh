#!/usr/bin/env bash
# Time from starting `kerf run` to the machine's first motion (issue 31): starts `kerfd` on
# CONFIG, waits until it answers, starts `kerf run PROGRAM` and polls `kerf status --json`
# every 10 ms until the position leaves where it was; prints the seconds to the first
# acknowledged move (the check before motion is over) and to the first motion, each as a
# range (from the start of the last status that did not show it to the end of the first
# that did: a status call takes tens of milliseconds on a busy 2-core machine), then
# aborts the program and stops the daemon. Wall-clock figures for docs/PERFORMANCE.md,
# never a test.
#
#   benches/first_motion.sh BIN_DIR PROGRAM [CONFIG]
#   e.g. target/release/gen_surface --segments 3000000 --seed 5 > /tmp/s3m.ngc
#        benches/first_motion.sh target/release /tmp/s3m.ngc
# CONFIG defaults to benches/cam-mill.toml (no homing: the machine is ready at start). The
# run uses a copy of it in a scratch directory, named `first_motion_PID`, so that it meets
# no other daemon of the same configuration (a CONFIG whose keys name files relative to
# it needs absolute paths there).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
bin="$1"
program="$2"
source_config="${3:-$here/cam-mill.toml}"
scratch="$(mktemp -d)"
log="$scratch/kerfd.log"
config="$scratch/kerf.toml"
python3 - "$source_config" "$config" "first_motion_$$" <<'PY'
import re, sys
src, dst, machine = sys.argv[1:]
text = open(src).read()
named = re.sub(r'(?m)^machine\s*=\s*"[^"]*"', f'machine = "{machine}"', text, count=1)
if named == text:
    named = f'machine = "{machine}"\n' + text
open(dst, "w").write(named)
PY
"$bin/kerfd" --config "$config" >"$log" 2>&1 &
daemon=$!
cleanup() {
    kill "$daemon" 2>/dev/null || true
    wait "$daemon" 2>/dev/null || true
    rm -rf "$scratch"
}
trap cleanup EXIT
for _ in $(seq 100); do
    "$bin/kerf" status --config "$config" >/dev/null 2>&1 && break
    sleep 0.1
done
# A daemon of the last run still stopping answers too: this one must be the one running.
if ! kill -0 "$daemon" 2>/dev/null; then
    echo "first_motion: kerfd did not start:" >&2
    cat "$log" >&2
    exit 1
fi
field() { # the status's JSON, one field
    "$bin/kerf" status --json --config "$config" | python3 -c "import json,sys; s=json.load(sys.stdin); print($1)"
}
from="$(field 's["position"]')"
start=$EPOCHREALTIME
"$bin/kerf" run --config "$config" "$program" >/dev/null 2>&1 &
run=$!
acked=""
last_before=$start
while :; do
    # A status call competes with the check and the planner for the two cores and can
    # take tens of milliseconds: each event is bracketed by the start of the last status
    # that did not show it and the end of the first that did.
    before=$EPOCHREALTIME
    line="$(field '(s["moves_received"], s["position"])')"
    after=$EPOCHREALTIME
    if [ -z "$acked" ] && [ "${line%%,*}" != "(0" ]; then
        acked=$(python3 -c "print(f'{$last_before - $start:.2f}-{$after - $start:.2f}')")
    fi
    if [ "${line#*, }" != "$from)" ]; then
        moved=$(python3 -c "print(f'{$last_before - $start:.2f}-{$after - $start:.2f}')")
        break
    fi
    last_before=$before
    if ! kill -0 "$run" 2>/dev/null; then
        echo "first_motion: kerf run ended before any motion" >&2
        exit 1
    fi
    sleep 0.01
done
"$bin/kerf" abort --config "$config" >/dev/null 2>&1 || true
wait "$run" 2>/dev/null || true
echo "$(basename "$program"): first move acknowledged after ${acked:-?} s, first motion after $moved s"
