/* The unwinder for an APK linked without the NDK (android/build-apk.sh).
 *
 * The NDK links its static libunwind.a into every library; Debian has no unwinder for Android.
 * libpreviz.so is built with `-C panic=abort`, so nothing ever unwinds: the Rust standard library
 * (built with panic=unwind) still references these functions from its landing pads and its
 * backtrace printer, and they only need to exist. Raising an exception reports failure
 * (std then aborts, which panic=abort does anyway), a backtrace is empty, and resuming an unwind
 * aborts. */
typedef unsigned long uintptr_t; /* aarch64: 64 bits; no libc headers for Android here */

typedef int _Unwind_Reason_Code;
enum { URC_FATAL_PHASE1_ERROR = 3, URC_END_OF_STACK = 5 };
struct _Unwind_Context;
struct _Unwind_Exception;
typedef _Unwind_Reason_Code (*_Unwind_Trace_Fn)(struct _Unwind_Context *, void *);

void abort(void);

_Unwind_Reason_Code _Unwind_Backtrace(_Unwind_Trace_Fn f, void *arg) { (void)f; (void)arg; return URC_END_OF_STACK; }
_Unwind_Reason_Code _Unwind_RaiseException(struct _Unwind_Exception *e) { (void)e; return URC_FATAL_PHASE1_ERROR; }
void _Unwind_Resume(struct _Unwind_Exception *e) { (void)e; abort(); }
void _Unwind_DeleteException(struct _Unwind_Exception *e) { (void)e; }
uintptr_t _Unwind_GetIP(struct _Unwind_Context *c) { (void)c; return 0; }
uintptr_t _Unwind_GetIPInfo(struct _Unwind_Context *c, int *before) { (void)c; if (before) *before = 0; return 0; }
uintptr_t _Unwind_GetCFA(struct _Unwind_Context *c) { (void)c; return 0; }
uintptr_t _Unwind_GetGR(struct _Unwind_Context *c, int i) { (void)c; (void)i; return 0; }
void _Unwind_SetGR(struct _Unwind_Context *c, int i, uintptr_t v) { (void)c; (void)i; (void)v; }
void _Unwind_SetIP(struct _Unwind_Context *c, uintptr_t v) { (void)c; (void)v; }
uintptr_t _Unwind_GetLanguageSpecificData(struct _Unwind_Context *c) { (void)c; return 0; }
uintptr_t _Unwind_GetRegionStart(struct _Unwind_Context *c) { (void)c; return 0; }
uintptr_t _Unwind_GetDataRelBase(struct _Unwind_Context *c) { (void)c; return 0; }
uintptr_t _Unwind_GetTextRelBase(struct _Unwind_Context *c) { (void)c; return 0; }
void *_Unwind_FindEnclosingFunction(void *pc) { (void)pc; return 0; }
