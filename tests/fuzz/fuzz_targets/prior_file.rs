#![no_main]
//! Fuzz target `prior_file`: the body is `system_tests::fuzz_bodies::prior_file`.
libfuzzer_sys::fuzz_target!(|data: &[u8]| system_tests::fuzz_bodies::prior_file(data));
