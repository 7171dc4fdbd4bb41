#!/usr/bin/env bash
# Check an APK built by android/build-apk.sh (or Gradle) and fail, naming what is wrong:
#   android/verify-apk.sh [target/android/previz-debug.apk]
# - `aapt dump badging`: package org.previz.app, minSdk 26, the NativeActivity launcher,
#   arm64-v8a native code, the CAMERA and location permissions;
# - the library lib/arm64-v8a/libpreviz.so (unpacked from the APK): AArch64, stored
#   uncompressed, exports ANativeActivity_onCreate (and android_main, nothing else), NEEDs only
#   Android platform libraries (readelf), every loadable segment aligned for 16 KiB pages;
# - `apksigner verify`.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
apk="${1:-$root/target/android/previz-debug.apk}"
api=26
fail() { echo "verify-apk.sh: $apk: $*" >&2; exit 1; }
[ -f "$apk" ] || fail "no such file (build it with android/build-apk.sh)"
for tool in aapt apksigner llvm-readelf unzip; do
    command -v "$tool" >/dev/null || { echo "verify-apk.sh: $tool not found" >&2; exit 1; }
done

badging="$(aapt dump badging "$apk")" || fail "aapt cannot read it"
grep -q "^package: name='org.previz.app'" <<<"$badging" || fail "aapt: wrong package: $(echo "$badging" | head -1)"
grep -q "^sdkVersion:'$api'" <<<"$badging" || fail "aapt: minSdk is not $api"
grep -q "^launchable-activity: name='android.app.NativeActivity'" <<<"$badging" || fail "aapt: no NativeActivity launcher"
grep -q "^native-code: 'arm64-v8a'" <<<"$badging" || fail "aapt: no arm64-v8a library"
for perm in CAMERA ACCESS_FINE_LOCATION ACCESS_COARSE_LOCATION; do
    grep -q "uses-permission: name='android.permission.$perm'" <<<"$badging" || fail "aapt: permission $perm missing"
done

tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
unzip -q -o "$apk" lib/arm64-v8a/libpreviz.so -d "$tmp" 2>/dev/null || fail "lib/arm64-v8a/libpreviz.so missing"
lib="$tmp/lib/arm64-v8a/libpreviz.so"
# Stored uncompressed (aapt -0 so; zipalign -p page-aligns it).
# (Outputs are read into variables before grep -q: with pipefail, grep -q closing the pipe early
# would fail the writer with SIGPIPE.)
listing="$(unzip -v "$apk" lib/arm64-v8a/libpreviz.so)"
grep -q " Stored " <<<"$listing" || fail "libpreviz.so is compressed in the APK"
header="$(llvm-readelf -h "$lib")"
grep -q "Machine:.*AArch64" <<<"$header" || fail "libpreviz.so is not AArch64"
# Defined, non-local dynamic symbols (the table's rows start "N:"). The activity's entry point
# must be there; besides it only android_main: rustc's own version script for a cdylib exports
# every #[no_mangle] function, and android-activity's glue calls android_main by that name.
exports="$(llvm-readelf --dyn-syms -W "$lib" | awk '$1 ~ /^[0-9]+:$/ && $7 != "UND" && $5 != "LOCAL" && $8 != "" { print $8 }' | sort -u | tr '\n' ' ')"
case " $exports" in *" ANativeActivity_onCreate "*) ;; *) fail "libpreviz.so does not export ANativeActivity_onCreate (exports: $exports)" ;; esac
for e in $exports; do
    case "$e" in ANativeActivity_onCreate | android_main) ;; *) fail "libpreviz.so exports $e (only ANativeActivity_onCreate and android_main expected)" ;; esac
done
platform=" libc.so libm.so libdl.so liblog.so libandroid.so libcamera2ndk.so libmediandk.so libEGL.so libGLESv3.so libvulkan.so libnativewindow.so "
needed="$(llvm-readelf -d "$lib" | sed -n 's/.*(NEEDED).*\[\(.*\)\]/\1/p' | tr '\n' ' ')"
for n in $needed; do
    case "$platform" in *" $n "*) ;; *) fail "libpreviz.so needs $n, not an Android platform library" ;; esac
done
# LOAD segments: alignment (last column) at least 0x4000 (16 KiB pages, Android 15).
while read -r align; do
    [ $((align)) -ge 16384 ] || fail "libpreviz.so has a LOAD segment aligned to $align (< 16 KiB)"
done < <(llvm-readelf -l -W "$lib" | awk '$1 == "LOAD" { print $NF }')
apksigner verify --min-sdk-version "$api" "$apk" || fail "apksigner verify failed"

echo "$badging" | grep -E "^(package|sdkVersion|targetSdkVersion|launchable-activity|native-code)"
echo "libpreviz.so: $(du -h "$lib" | cut -f1), exports: $exports, NEEDED: $needed"
echo "verified $apk ($(du -h "$apk" | cut -f1)); install with: adb install -r $apk"
