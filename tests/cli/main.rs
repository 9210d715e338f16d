//! The `raygun` binary end to end: its arguments, outputs and error messages, the headless
//! demo, wall output in tiles, and the profile-guided build's training set (each file one
//! subject; one test binary, so that the crate is linked once for them).

mod cli;
mod demo;
mod pgo_script;
mod wall;

// The helpers of tests/support/ that the files above use, each compiled once here.
#[path = "../support/cli.rs"]
mod support;
