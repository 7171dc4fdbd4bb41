#![no_main]
//! Fuzz target `obj_mtl`: see previz::fuzzing::obj_mtl for what it feeds and checks.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    previz::fuzzing::obj_mtl(data);
});
