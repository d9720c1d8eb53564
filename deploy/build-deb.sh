#!/usr/bin/env bash
# Builds the Debian package of kerf and kerfd with cargo-deb (metadata: crates/kerf/Cargo.toml,
# [package.metadata.deb]) and lists its contents. Needs cargo-deb (`cargo install cargo-deb
# --locked`) and dpkg-deb.
#
# The shell completions and man pages are generated from the release binaries themselves
# (`kerf completions SHELL`, `kerf man DIR` (which writes kerfd.1 too), `kerfd --completions SHELL`),
# so they describe exactly the arguments those binaries parse; they are written to
# <target>/release/kerf-assets/, where the package's assets take them from.
#
# Usage: deploy/build-deb.sh [extra cargo-deb arguments, e.g. --fast]
# Prints the path of the .deb on its last line.
set -euo pipefail

cd "$(dirname "$0")/.."

echo "== cargo build --release -p kerf -p kerfd --locked"
cargo build --release -p kerf -p kerfd --locked

# The target directory as cargo sees it (CARGO_TARGET_DIR, a config file, or ./target).
target_dir="$(cargo metadata --format-version 1 --no-deps \
    | sed -n 's/.*"target_directory":"\([^"]*\)".*/\1/p')"
release="$target_dir/release"
assets="$release/kerf-assets"
rm -rf "$assets"
mkdir -p "$assets/completions" "$assets/man"

echo "== completions and man pages into $assets"
for bin in kerf kerfd; do
    for shell in bash zsh fish; do
        if [ "$bin" = kerf ]; then
            gen=("$release/kerf" completions "$shell")
        else
            gen=("$release/kerfd" --completions "$shell")
        fi
        case "$shell" in
            bash) file="$bin.bash" ;;
            zsh) file="_$bin" ;;
            fish) file="$bin.fish" ;;
        esac
        "${gen[@]}" >"$assets/completions/$file"
    done
done
"$release/kerf" man "$assets/man"   # kerf.1, kerf-*.1 and kerfd.1
# Debian installs man pages compressed (-n: no time stamp, so the bytes are reproducible).
gzip -9 -n "$assets"/man/*.1

echo "== cargo deb -p kerf --no-build --strip"
deb="$(cargo deb -p kerf --no-build --strip "$@" | tail -n 1)"
echo "== dpkg-deb -c $deb"
dpkg-deb -c "$deb"
echo "$deb"
