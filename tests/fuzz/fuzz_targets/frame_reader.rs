#![no_main]
//! Fuzz target `frame_reader`: the body is `system_tests::fuzz_bodies::frame_reader`.
libfuzzer_sys::fuzz_target!(|data: &[u8]| system_tests::fuzz_bodies::frame_reader(data));
