//! Command-line front ends; `main.rs` parses and dispatches.

pub mod tracking;
