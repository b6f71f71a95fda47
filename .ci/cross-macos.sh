#!/usr/bin/env bash
# macOS cross checks: clippy (all targets, with and without the Python bindings) for Apple
# silicon and Intel Macs, from Linux. Needs only `rustup target add`: no Apple SDK and no
# macOS Python (PyO3's abi3-py39 feature configures a cross build without an interpreter).
# Nothing is linked or run here; see docs/guides/platforms.md for what that leaves.
set -euo pipefail
cd "$(dirname "$0")/.."
# A target directory of its own, so host builds are not invalidated by the cross builds.
export CARGO_TARGET_DIR="${CROSS_TARGET_DIR:-target/cross}"
targets=(aarch64-apple-darwin x86_64-apple-darwin)
installed=$(rustup target list --installed)
for t in "${targets[@]}"; do
    grep -qx "$t" <<<"$installed" || rustup target add "$t"
done
for t in "${targets[@]}"; do
    echo "cross: clippy $t"
    cargo clippy --quiet --all-targets --target "$t" -- -D warnings
    echo "cross: clippy $t --features python"
    cargo clippy --quiet --all-targets --features python --target "$t" -- -D warnings
done
