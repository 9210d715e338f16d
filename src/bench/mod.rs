//! Benchmarks (`raygun bench …`): speed and error, measured in the repository, reported with
//! the hardware they ran on. Never timed tests.

pub mod all;
pub mod dgi;
pub mod filter;
pub mod guided;
pub mod schedule;
pub mod trace;
