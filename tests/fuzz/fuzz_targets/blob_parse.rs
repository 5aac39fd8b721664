#![no_main]
//! Fuzz target `blob_parse`: the body is `system_tests::fuzz_bodies::blob_parse`.
libfuzzer_sys::fuzz_target!(|data: &[u8]| system_tests::fuzz_bodies::blob_parse(data));
