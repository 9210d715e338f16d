//! Command-line front ends: argument types (clap) and the command logic, kept in the library so
//! tests can run a command without spawning the binary. `main.rs` wires them into subcommands.

pub mod args;
pub mod bench;
pub mod demo;
pub mod dgi;
pub mod display;
pub mod ellipse_distance;
pub mod filter;
pub mod guided;
pub mod render;
pub mod scene;
pub mod tracking;
pub mod view;
