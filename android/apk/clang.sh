#!/usr/bin/env bash
# rustc's linker for aarch64-linux-android without the NDK (set by android/build-apk.sh).
#
# The NDK's platform libraries are, to the linker, stubs that only list exported symbols. This
# script makes such stubs for exactly the symbols the link needs:
#   1. link once against empty stub libraries (a shared library may keep symbols undefined);
#   2. read the undefined dynamic symbols of the result and sort each into the Android library
#      that exports it (liblog: __android_log_*, libdl: dl*, libcamera2ndk: ACamera*/ACapture*,
#      libmediandk: AImage*/AMedia*, libandroid: the other A* NDK APIs, libEGL/libvulkan,
#      libm: the C maths functions, libc: the rest);
#   3. compile one stub .so per library (soname libX.so) and link again with -z defs, so every
#      symbol is resolved by a platform library or by the no-op unwinder (unwind.c).
# Which library a symbol really lives in on the device matters little (bionic's linker looks a
# symbol up in every library of the load group), but a symbol no platform library exports is
# only caught when the phone loads the library (docs/mobile.md).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
work="${PREVIZ_ANDROID_LINK_DIR:?set by android/build-apk.sh}"
api="${PREVIZ_ANDROID_API:-26}"
# 16 KiB pages: Android 15 devices may use them; the ELF segments must be aligned for both.
cc=(clang "--target=aarch64-linux-android$api" -fuse-ld=lld -nostartfiles -Wl,-z,max-page-size=16384)
libs=(c m dl log android camera2ndk mediandk EGL GLESv3 vulkan nativewindow)

out=""
prev=""
for a in "$@"; do
    [ "$prev" = "-o" ] && out="$a"
    prev="$a"
done
[ -n "$out" ] || { echo "link.sh: no -o in the link command" >&2; exit 1; }

empty="$work/empty"
stubs="$work/stubs"
rm -rf "$empty" "$stubs"
mkdir -p "$empty" "$stubs"
# The unwinder (libunwind.a, which the standard library asks for) in both passes.
"${cc[@]}" -O2 -fPIC -c -o "$work/unwind.o" "$here/unwind.c"
for d in "$empty" "$stubs"; do
    llvm-ar rcs "$d/libunwind.a" "$work/unwind.o"
done
: >"$work/empty.c"
for l in "${libs[@]}"; do
    "${cc[@]}" -shared -nostdlib "-Wl,-soname,lib$l.so" -o "$empty/lib$l.so" "$work/empty.c"
done

# Pass 1.
"${cc[@]}" "-L$empty" "$@"

# The undefined dynamic symbols (name and type), versions stripped.
llvm-readelf --dyn-syms -W "$out" | awk '$7 == "UND" && $8 != "" { sub(/@.*/, "", $8); print $8, $4 }' | sort -u >"$work/undefined.txt"
# The C maths functions: glibc's libm exports the same names as bionic's.
libm_names="$work/libm-names.txt"
llvm-nm -D --defined-only "$(clang -print-file-name=libm.so.6)" | awk '{ sub(/@.*/, "", $3); print $3 }' | sort -u >"$libm_names"

for l in "${libs[@]}"; do : >"$stubs/lib$l.c"; done
while read -r name type; do
    case "$name" in
        __android_log_*) lib=log ;;
        dlopen | dlclose | dlsym | dlvsym | dlerror | dladdr | android_dlopen_ext) lib=dl ;;
        ACamera* | ACapture*) lib=camera2ndk ;;
        AImage* | AMedia*) lib=mediandk ;;
        A[A-Z]*) lib=android ;;
        egl*) lib=EGL ;;
        gl[A-Z]*) lib=GLESv3 ;;
        vk[A-Z]*) lib=vulkan ;;
        *) if grep -qx -- "$name" "$libm_names"; then lib=m; else lib=c; fi ;;
    esac
    if [ "$type" = OBJECT ]; then
        echo "char $name[16];" >>"$stubs/lib$lib.c"
    else
        echo "void $name(void) {}" >>"$stubs/lib$lib.c"
    fi
done <"$work/undefined.txt"
needed=()
for l in "${libs[@]}"; do
    if [ -s "$stubs/lib$l.c" ]; then
        "${cc[@]}" -shared -nostdlib -fno-builtin -w "-Wl,-soname,lib$l.so" -o "$stubs/lib$l.so" "$stubs/lib$l.c"
        needed+=("-l$l")
    else
        cp "$empty/lib$l.so" "$stubs/lib$l.so"
    fi
done

# Pass 2: every symbol resolved.
"${cc[@]}" "-L$stubs" "$@" -Wl,-z,defs -Wl,--as-needed "${needed[@]}"
