#!/usr/bin/env bash
# Checks deploy/kerfd.service with `systemd-analyze verify`. The unit's ExecStart names
# /usr/bin/kerfd, which is not installed where this runs, so a temporary copy points
# ExecStart at /bin/true; every other line is checked as written. Fails if systemd-analyze
# fails or prints anything about the unit.
set -euo pipefail

here="$(cd "$(dirname "$0")" && pwd)"
unit="$here/kerfd.service"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT

sed -E 's|^ExecStart=[^ ]+|ExecStart=/bin/true|' "$unit" >"$tmp/kerfd.service"
if ! grep -q '^ExecStart=/bin/true ' "$tmp/kerfd.service"; then
    echo "verify-unit: no ExecStart= line to rewrite in $unit" >&2
    exit 1
fi

status=0
output="$(systemd-analyze verify "$tmp/kerfd.service" 2>&1)" || status=$?
# Lines about other units on this machine are not ours to fix; lines about kerfd are.
ours="$(printf '%s\n' "$output" | grep -i 'kerfd' || true)"
if [ "$status" -ne 0 ] || [ -n "$ours" ]; then
    echo "verify-unit: systemd-analyze verify (exit $status) on $unit:" >&2
    printf '%s\n' "$output" >&2
    exit 1
fi
echo "verify-unit: kerfd.service OK (systemd $(systemd-analyze --version | head -n1 | awk '{print $2}'))"
