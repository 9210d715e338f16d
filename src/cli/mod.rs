//! Command logic behind the `raygun` subcommands: each takes its input and output streams, so
//! tests drive it without a process; `main.rs` only parses arguments and wires the streams.

pub mod ellipse_distance;
