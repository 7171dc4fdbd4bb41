#!/usr/bin/env sh
# Build the Rust library as libpreviz.so for arm64 Android into app/src/main/jniLibs.
# Needs the Android NDK (ANDROID_NDK_HOME) and cargo-ndk (`cargo install cargo-ndk`);
# neither exists on the project's build machines, see docs/mobile.md.
set -eu
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/.." && pwd)"
profile="${PROFILE:-release}"
cd "$root"
# The crate's [lib] is an rlib for the host; build it as a cdylib only here.
cargo ndk -t arm64-v8a --platform 26 -- rustc --lib --crate-type cdylib --profile "$profile"
mkdir -p "$here/app/src/main/jniLibs/arm64-v8a"
cp "target/aarch64-linux-android/$profile/libpreviz.so" "$here/app/src/main/jniLibs/arm64-v8a/libpreviz.so"
echo "built $here/app/src/main/jniLibs/arm64-v8a/libpreviz.so"
