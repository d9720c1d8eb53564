#!/usr/bin/env bash
# Checks deploy/kerfd.service and deploy/kerf-serve.service with `systemd-analyze verify`.
# A unit's ExecStart names /usr/bin/kerfd or /usr/bin/kerf, which is not installed where
# this runs, so a temporary copy points ExecStart at /bin/true; every other line is
# checked as written. Fails if systemd-analyze fails or prints anything about the unit.
#
# Then, as root (CI), applies deploy/kerfd.tmpfiles with `systemd-tmpfiles --root` to a
# scratch root whose /etc/passwd has a user kerf and whose /tmp/iceoryx2 holds what a
# command run with sudo leaves (root-owned nodes/ and a node directory in it): fails
# unless the whole tree then belongs to kerf, with the modes iceoryx2 set kept, and
# systemd-tmpfiles printed nothing. As another user it says that it skipped this part.
set -euo pipefail

here="$(cd "$(dirname "$0")" && pwd)"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT

for name in kerfd kerf-serve; do
    unit="$here/$name.service"
    sed -E 's|^ExecStart=[^ ]+|ExecStart=/bin/true|' "$unit" >"$tmp/$name.service"
    if ! grep -q '^ExecStart=/bin/true ' "$tmp/$name.service"; then
        echo "verify-unit: no ExecStart= line to rewrite in $unit" >&2
        exit 1
    fi
    status=0
    output="$(systemd-analyze verify "$tmp/$name.service" 2>&1)" || status=$?
    # Lines about other units on this machine are not ours to fix; lines about ours are.
    ours="$(printf '%s\n' "$output" | grep -i "$name" || true)"
    if [ "$status" -ne 0 ] || [ -n "$ours" ]; then
        echo "verify-unit: systemd-analyze verify (exit $status) on $unit:" >&2
        printf '%s\n' "$output" >&2
        exit 1
    fi
    echo "verify-unit: $name.service OK (systemd $(systemd-analyze --version | head -n1 | awk '{print $2}'))"
done

# The tmpfiles entry: the whole iceoryx2 tree for user kerf.
tmpfiles="$here/kerfd.tmpfiles"
if [ "$(id -u)" -ne 0 ]; then
    echo "verify-unit: kerfd.tmpfiles not applied (systemd-tmpfiles needs root to chown); run as root to check it"
    exit 0
fi
root="$tmp/root"
mkdir -p "$root/etc" "$root/tmp/iceoryx2/nodes/1234"
cp /etc/passwd /etc/group "$root/etc/"
kerf_id=64999
echo "kerf:x:$kerf_id:$kerf_id:kerf:/:/usr/sbin/nologin" >>"$root/etc/passwd"
echo "kerf:x:$kerf_id:" >>"$root/etc/group"
# Left by root: nodes/ (mode 0750, as iceoryx2 makes it) and a node's file (0400).
chmod 0750 "$root/tmp/iceoryx2/nodes"
touch "$root/tmp/iceoryx2/nodes/1234/iox2_node.details"
chmod 0400 "$root/tmp/iceoryx2/nodes/1234/iox2_node.details"
output="$(systemd-tmpfiles --root="$root" --create "$tmpfiles" 2>&1)" || {
    echo "verify-unit: systemd-tmpfiles --create failed on $tmpfiles:" >&2
    printf '%s\n' "$output" >&2
    exit 1
}
if [ -n "$output" ]; then
    echo "verify-unit: systemd-tmpfiles printed something about $tmpfiles:" >&2
    printf '%s\n' "$output" >&2
    exit 1
fi
wrong="$(find "$root/tmp/iceoryx2" \( ! -uid "$kerf_id" -o ! -gid "$kerf_id" \) -printf '%p %u:%g\n')"
if [ -n "$wrong" ]; then
    echo "verify-unit: after $tmpfiles, not owned by kerf:" >&2
    printf '%s\n' "$wrong" >&2
    exit 1
fi
modes="$(cd "$root/tmp/iceoryx2" && stat -c '%n %a' . nodes services nodes/1234/iox2_node.details)"
expected=". 750
nodes 750
services 750
nodes/1234/iox2_node.details 400"
if [ "$modes" != "$expected" ]; then
    echo "verify-unit: after $tmpfiles, unexpected modes:" >&2
    printf '%s\n' "$modes" >&2
    exit 1
fi
echo "verify-unit: kerfd.tmpfiles OK (the whole /tmp/iceoryx2 tree for user kerf)"
