#![no_main]
//! Fuzz target `lut`: see umbra_tests::fuzz for what it asserts.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    umbra_tests::fuzz::run(umbra_tests::fuzz::Target::Lut, data);
});
