#!/usr/bin/env bash
# Build an installable, debug-signed APK without the Android NDK or SDK:
#   target/android/previz-debug.apk
# Debian's clang/lld target aarch64-linux-android; the platform libraries are generated stubs
# (apk/clang.sh); the unwinder is a no-op (apk/unwind.c, the library is built with panic=abort);
# aapt links the manifest against Debian's android-framework-res; zipalign and apksigner finish
# it with a generated debug key. The APK carries no dex (no d8/dx here): the NativeActivity and
# JNI calls only (docs/mobile.md). It then checks the result with android/verify-apk.sh.
#
# Env: PROFILE=dev (default: everything at opt-level 1, no debug info — the quicker build, for
# CI) or release; PREVIZ_APK_NO_INSTALL=1 to skip apt-get/rustup. Cargo builds into
# target/android/cargo (its own lock, so host builds are not blocked meanwhile).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/.." && pwd)"
cd "$root"
target=aarch64-linux-android
api=26
target_sdk=34
profile="${PROFILE:-dev}"
out="$root/target/android"
work="$out/work"
framework=/usr/share/android-framework-res/framework-res.apk

if [ -z "${PREVIZ_APK_NO_INSTALL:-}" ]; then
    packages=(clang lld llvm aapt zipalign apksigner android-framework-res)
    missing=()
    for p in "${packages[@]}"; do
        dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
    done
    if [ ${#missing[@]} -gt 0 ]; then
        echo "installing ${missing[*]} (the APK toolchain)"
        export DEBIAN_FRONTEND=noninteractive
        apt-get update -qq
        apt-get install -y -qq --no-install-recommends "${missing[@]}"
    fi
    if ! rustup target list --installed | grep -qx "$target"; then
        rustup target add "$target"
    fi
fi
for tool in clang ld.lld llvm-ar llvm-readelf llvm-nm aapt zipalign apksigner keytool; do
    command -v "$tool" >/dev/null || { echo "build-apk.sh: $tool not found" >&2; exit 1; }
done
[ -f "$framework" ] || { echo "build-apk.sh: $framework not found (apt-get install android-framework-res)" >&2; exit 1; }

rm -rf "$work"
mkdir -p "$work/link" "$work/apk/lib/arm64-v8a"

# 1. libpreviz.so: the crate's library as a cdylib, exporting only ANativeActivity_onCreate.
echo "== cargo rustc --target $target --profile $profile (cdylib)"
target_env="$(echo "$target" | tr 'a-z-' 'A-Z_')"
export "CARGO_TARGET_${target_env}_LINKER=$here/apk/clang.sh"
export "CARGO_TARGET_${target_env}_RUSTFLAGS=-C panic=abort -C linker-flavor=gcc -C link-arg=-Wl,--version-script=$here/apk/exports.map"
export PREVIZ_ANDROID_LINK_DIR="$work/link" PREVIZ_ANDROID_API="$api"
# No debug info in the phone's library (the profiles keep line tables for the host).
export CARGO_PROFILE_DEV_DEBUG=false CARGO_PROFILE_DEV_STRIP=symbols CARGO_PROFILE_RELEASE_DEBUG=false CARGO_PROFILE_RELEASE_STRIP=symbols
export CARGO_TARGET_DIR="$out/cargo"
opt=()
if [ "$profile" = dev ]; then
    # The host's dev profile builds dependencies at opt-level 3 (the tests compare many images);
    # the phone's debug build takes opt-level 1 throughout (quicker to compile; not measured yet).
    opt=(--config 'profile.dev.package."*".opt-level=1')
fi
cargo rustc "${opt[@]}" --lib --crate-type cdylib --target "$target" --profile "$profile"
dir=$([ "$profile" = dev ] && echo debug || echo "$profile")
lib="$CARGO_TARGET_DIR/$target/$dir/libpreviz.so"
cp "$lib" "$work/apk/lib/arm64-v8a/libpreviz.so"

# 2. The manifest: the Gradle one with the package name, and hasCode="false" (no dex here).
sed -e 's|<manifest |<manifest package="org.previz.app" |' \
    -e 's|android:hasCode="true"|android:hasCode="false"|' \
    "$here/app/src/main/AndroidManifest.xml" >"$work/AndroidManifest.xml"

# 3. Package, align, sign.
aapt package -f -M "$work/AndroidManifest.xml" -I "$framework" \
    --min-sdk-version "$api" --target-sdk-version "$target_sdk" --version-code 1 --version-name 0.1.0 \
    -0 so -F "$work/unaligned.apk" "$work/apk"
zipalign -f -p 4 "$work/unaligned.apk" "$work/aligned.apk"
keystore="$out/debug.keystore"
if [ ! -f "$keystore" ]; then
    keytool -genkeypair -keystore "$keystore" -storepass android -keypass android -alias androiddebugkey \
        -keyalg RSA -keysize 2048 -validity 10000 -dname "CN=Previz Debug,O=Previz,C=GB" >/dev/null 2>&1
fi
apk="$out/previz-debug.apk"
apksigner sign --ks "$keystore" --ks-pass pass:android --key-pass pass:android --ks-key-alias androiddebugkey \
    --min-sdk-version "$api" --out "$apk" "$work/aligned.apk"

# 4. Check it (android/verify-apk.sh: badging, the library's exports and NEEDED entries,
# page alignment, the signature).
"$here/verify-apk.sh" "$apk"
