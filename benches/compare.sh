#!/usr/bin/env bash
# Compares the motion time of every bundled program between two builds of `kerf`: the
# examples, the dialect test programs, the LinuxCNC golden programs and the CAM corpus
# (on benches/cam-mill.toml). Prints each program whose duration changed, marked SLOWER
# or faster, and a count; a program that only one of the two builds runs to the end (the
# other refuses it or crashes) is printed as DIFFERS and makes the exit status 1. Used to
# check "nothing slower" before a planner or motion change lands; the durations are
# motion times (periods × period), not wall-clock.
#
# Usage: benches/compare.sh OLD_KERF NEW_KERF
#   e.g. build the old commit in a worktree with its own CARGO_TARGET_DIR, then
#   benches/compare.sh /tmp/old/release/kerf target/release/kerf
set -euo pipefail
cd "$(dirname "$0")/.."
old=$1 new=$2
corpus=$(mktemp -d)
trap 'rm -rf "$corpus"' EXIT
cargo run -q --release -p kerf-benches --bin cam_table -- --write "$corpus" >/dev/null
duration() {
    local bin=$1 file=$2; shift 2
    # Programs that are refused (the error tests) print no duration.
    { "$bin" sim "$@" "$file" --out "$corpus/out.csv" 2>/dev/null || true; } | awk '/^duration/ {print $2}'
}
slower=0 faster=0 same=0 differ=0
for f in config/examples/* tests/data/programs/*/* tests/data/ngc/*/*.ngc "$corpus"/*.ngc; do
    case $f in *.csv|*.canon|*.tbl|*.md) continue ;; esac
    args=()
    case $f in
        *.nc) args=(--dialect rockwell) ;;
        "$corpus"/*) args=(--config benches/cam-mill.toml) ;;
    esac
    a=$(duration "$old" "$f" "${args[@]}")
    b=$(duration "$new" "$f" "${args[@]}")
    if [ -z "$a" ] && [ -z "$b" ]; then
        same=$((same + 1))
    elif [ -z "$a" ] || [ -z "$b" ]; then
        # One build ran the program and the other did not (a refusal or a crash on one
        # side): never counted as unchanged.
        differ=$((differ + 1)); echo "DIFFERS ${f#"$corpus"/}: ${a:-no duration} -> ${b:-no duration}"
    elif [ "$a" = "$b" ]; then
        same=$((same + 1))
    elif awk -v a="$a" -v b="$b" 'BEGIN { exit !(b > a) }'; then
        slower=$((slower + 1)); echo "SLOWER ${f#"$corpus"/} $a -> $b s"
    else
        faster=$((faster + 1)); echo "faster ${f#"$corpus"/} $a -> $b s"
    fi
done
echo "$slower slower, $faster faster, $same unchanged (or refused by both), $differ run by one build only"
[ "$differ" -eq 0 ]
