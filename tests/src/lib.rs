//! Helpers for umbra's cross-crate integration tests (the tests are in `tests/tests/`); they live
//! in `tests/support` (package `test-support`), which the single-crate tests use directly.

pub use test_support::*;

pub mod fuzz;
