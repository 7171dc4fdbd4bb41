#![no_main]
//! Fuzz target `trace_csv`: see previz::fuzzing::trace_csv for what it feeds and checks.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    previz::fuzzing::trace_csv(data);
});
