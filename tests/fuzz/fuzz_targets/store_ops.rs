#![no_main]
//! Fuzz target `store_ops`: the body is `system_tests::fuzz_bodies::store_ops`.
libfuzzer_sys::fuzz_target!(|data: &[u8]| system_tests::fuzz_bodies::store_ops(data));
