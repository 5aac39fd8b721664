#![no_main]
//! Fuzz target `scene_toml`: the body is `system_tests::fuzz_bodies::scene_toml`.
libfuzzer_sys::fuzz_target!(|data: &[u8]| system_tests::fuzz_bodies::scene_toml(data));
