#!/usr/bin/env bash
# The EtherCAT figures of docs/PERFORMANCE.md, on the emulated bus: a private network
# namespace with a veth pair, `kerf-ecat-sim` (3 drives, 1 I/O subdevice) on one end at
# a real-time priority, the release `kerfd` on the other with the bundled machine
# (config/kerf.toml) at the given period and with distributed clocks. Prints:
#   - bring-up: from starting kerfd to the drives enabled (the machine idle), and kerfd's
#     own line for the bus reaching OP;
#   - after HOLD_S seconds idle (the cycle exchanging every period): kerfd's exit summary,
#     the cycle's wake-up latency and compute (which includes the frame's round trip) and
#     the distributed clocks' |offset| of the cycle start from its place before SYNC0.
#
# Needs root (network namespaces, real-time priorities) and iproute2 and util-linux.
# Usage: benches/ethercat.sh [PERIOD_US [HOLD_S [DRIFT_PPM]]]   (defaults 1000 60 0)
#   DRIFT_PPM: the emulated bus clock's drift against the host's (the phase lock follows it).
set -euo pipefail
cd "$(dirname "$0")/.."
period_us=${1:-1000} hold_s=${2:-60} drift_ppm=${3:-0}
# The emulator is a process on the same two cores as the daemon: now and then it answers a
# frame milliseconds late, which a drive's ESC never does. Allow that many incomplete
# exchanges in a row, so that the figures are of the exchange and the clocks, not of a
# fault at the first burst (the lost frames are counted in the summary).
max_missed=${KERF_BENCH_MAX_MISSED:-10}
[ "$(id -u)" = 0 ] || { echo "benches/ethercat.sh: needs root (network namespace, real-time priority)" >&2; exit 1; }
cargo build -q --release -p kerfd -p kerf -p kerf-ecat-sim
bin=${CARGO_TARGET_DIR:-target}/release
ns=kerf-bench-$$ work=$(mktemp -d)
cleanup() {
    ip netns pids "$ns" 2>/dev/null | xargs -r kill 2>/dev/null || true
    sleep 0.2
    ip netns del "$ns" 2>/dev/null || true
    rm -rf "$work"
}
trap cleanup EXIT
ip netns add "$ns"
ip -n "$ns" link add ecatA type veth peer name ecatB
ip -n "$ns" link set ecatA up
ip -n "$ns" link set ecatB up
ip -n "$ns" link set lo up
machine=bench$$
sed -e "s/^machine = \"default\"/machine = \"$machine\"/" -e "s/^period_us = 1000/period_us = $period_us/" config/kerf.toml >"$work/kerf.toml"
cat >>"$work/kerf.toml" <<EOF

[ethercat]
interface = "ecatA"
dc = true
max_missed_cycles = $max_missed
[[ethercat.drives]]
axis = "x"
position = 0
vendor_id = 0x4B52
product_code = 0x402
[[ethercat.drives]]
axis = "y"
position = 1
vendor_id = 0x4B52
product_code = 0x402
[[ethercat.drives]]
axis = "z"
position = 2
vendor_id = 0x4B52
product_code = 0x402
[[ethercat.io]]
position = 3
vendor_id = 0x4B52
product_code = 0x10
EOF
sim_args=(--interface ecatB --drives 3 --io 1)
[ "$drift_ppm" = 0 ] || sim_args+=(--dc-drift-ppm "$drift_ppm")
# The emulator stands for drives, which never wait for a busy CPU: below kerfd's cycle.
ip netns exec "$ns" chrt -f 40 "$bin/kerf-ecat-sim" "${sim_args[@]}" </dev/null 2>"$work/sim.log" &
sleep 0.5
start=$(date +%s%N)
ip netns exec "$ns" "$bin/kerfd" --config "$work/kerf.toml" 2>"$work/kerfd.log" &
kerfd_pid=$!
until "$bin/kerf" status --json --config "$work/kerf.toml" 2>/dev/null | grep -q '"state": *"idle"'; do
    kill -0 $kerfd_pid 2>/dev/null || { cat "$work/kerfd.log" >&2; exit 1; }
    if "$bin/kerf" status --json --config "$work/kerf.toml" 2>/dev/null | grep -q '"state": *"fault"'; then
        "$bin/kerf" status --config "$work/kerf.toml" >&2
        echo "benches/ethercat.sh: the machine faulted before its drives were enabled (a busy machine? see docs/ETHERCAT.md)" >&2
        exit 1
    fi
    sleep 0.005
done
enabled=$(date +%s%N)
echo "period ${period_us} µs, DC drift ${drift_ppm} ppm"
echo "bring-up: $(( (enabled - start) / 1000000 )) ms from starting kerfd to the drives enabled"
grep -o 'EtherCAT: [0-9]* subdevices in OP.*' "$work/kerfd.log" || true
sleep "$hold_s"
kill -TERM $kerfd_pid
wait $kerfd_pid || true
grep -o 'cycle timing: .*' "$work/kerfd.log"
grep -o 'EtherCAT: [0-9]* cycles exchanged.*' "$work/kerfd.log"
grep -o 'EtherCAT distributed clocks: .*' "$work/kerfd.log"
