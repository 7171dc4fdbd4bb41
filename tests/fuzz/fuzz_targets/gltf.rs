#![no_main]
//! Fuzz target `gltf`: see previz::fuzzing::gltf for what it feeds and checks.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    previz::fuzzing::gltf(data);
});
