//! Command-line front ends: argument types (clap) and the command logic, kept in the library so
//! tests can run a command without spawning the binary. `main.rs` wires them into subcommands.

pub mod args;
pub mod bench;
pub mod calibrate;
pub mod cluster;
pub mod demo;
pub mod dgi;
pub mod display;
pub mod ellipse_distance;
pub mod filter;
pub mod head;
pub mod progress;
pub mod render;
pub mod scene;
pub mod tracking;
pub mod view;
pub mod wall;

/// An error and its causes as one line, "what failed: why: why that", leaving out a cause whose
/// text the message already holds (library errors often quote their source in their own text).
#[must_use]
pub fn error_chain(e: &anyhow::Error) -> String {
    crate::messages::join_causes(e.chain().map(ToString::to_string))
}
