#![no_main]
//! Fuzz target `hdr_exr`: see previz::fuzzing::hdr_exr for what it feeds and checks.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    previz::fuzzing::hdr_exr(data);
});
