#!/usr/bin/env bash
# Build Previz.app for an iPhone (arm64). Needs macOS with Xcode (the iOS SDK, its linker and
# codesign); the project's build machines have neither, see docs/mobile.md. On iOS the `previz`
# binary is the app (live::ios: the live window, the AVFoundation camera, CoreMotion).
#   ios/build.sh                 # release build, unsigned bundle in target/ios/Previz.app
#   IDENTITY="Apple Development: ..." ios/build.sh   # also sign it
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/.." && pwd)"
cd "$root"
rustup target add aarch64-apple-ios >/dev/null
cargo build --release --target aarch64-apple-ios --bin previz
app="$root/target/ios/Previz.app"
rm -rf "$app"
mkdir -p "$app"
cp "target/aarch64-apple-ios/release/previz" "$app/previz"
cp "$here/Info.plist" "$app/Info.plist"
if [ -n "${IDENTITY:-}" ]; then
    codesign --force --sign "$IDENTITY" --timestamp=none "$app"
fi
echo "built $app (install with: xcrun devicectl device install app --device <id> $app)"
