#![no_main]
//! Fuzz target `frame_decode`: the body is `system_tests::fuzz_bodies::frame_decode`.
libfuzzer_sys::fuzz_target!(|data: &[u8]| system_tests::fuzz_bodies::frame_decode(data));
