#!/usr/bin/env bash
# Fetches LinuxCNC's standalone interpreter `rs274` (the reference for Kerf's LinuxCNC
# dialect) from Debian's packages and unpacks it without installing anything:
#   tests/rs274/fetch.sh [DIR]      (default: $KERF_RS274_DIR, else target/rs274)
# It only runs as a separate program for comparison (tests/rs274/canon.sh); none of its
# code is part of Kerf. Needs apt-get (Debian 12 "bookworm" package lists) and dpkg.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
dir="${1:-${KERF_RS274_DIR:-$repo/target/rs274}}"
mkdir -p "$dir"
dir="$(cd "$dir" && pwd)"
if [ -x "$dir/root/usr/bin/rs274" ] && [ -f "$dir/ok" ]; then
    echo "rs274 already in $dir"
    exit 0
fi
cd "$dir"
download() {
    # apt-get download writes into the current directory; a missing package list is
    # fetched once.
    if ! apt-get download "$@" >/dev/null 2>&1; then
        apt-get update -qq
        apt-get download "$@"
    fi
}
download linuxcnc-uspace libboost-python1.74.0
for deb in ./*.deb; do
    dpkg -x "$deb" root
done
export LD_LIBRARY_PATH="$dir/root/usr/lib:$dir/root/usr/lib/x86_64-linux-gnu"
missing="$(ldd root/usr/bin/rs274 | grep 'not found' || true)"
if [ -n "$missing" ]; then
    echo "rs274 needs libraries this machine lacks:" >&2
    echo "$missing" >&2
    exit 1
fi
touch ok
echo "rs274 unpacked in $dir"
