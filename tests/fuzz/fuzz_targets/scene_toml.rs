#![no_main]
//! Fuzz target `scene_toml`: see previz::fuzzing::scene_toml for what it feeds and checks.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    previz::fuzzing::scene_toml(data);
});
