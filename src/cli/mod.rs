//! The command line: one module per command, each with its clap arguments and a `run`.

pub mod args;
pub mod bench;
pub mod dgi;
