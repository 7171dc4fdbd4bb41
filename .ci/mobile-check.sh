#!/usr/bin/env bash
# Type-check the crate for the phone targets: the Android backend (NDK sensors, JNI location)
# and the iOS backend (CoreMotion, CoreLocation via objc2) only compile there. Linking needs the
# Android NDK / Xcode, which CI does not have; see docs/mobile.md.
set -euo pipefail
cd "$(dirname "$0")/.."

# Targets: the arguments, or both phones.
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(aarch64-linux-android aarch64-apple-ios)
for target in "${targets[@]}"; do
    if ! rustup target list --installed | grep -qx "$target"; then
        echo "installing rustup target $target"
        rustup target add "$target"
    fi
    echo "== cargo check --target $target"
    cargo check --target "$target"
done
