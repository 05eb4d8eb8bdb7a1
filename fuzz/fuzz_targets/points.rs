#![no_main]
//! Fuzz target `points`: see umbra_tests::fuzz for what it asserts.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    umbra_tests::fuzz::run(umbra_tests::fuzz::Target::Points, data);
});
