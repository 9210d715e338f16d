//! Command-line front ends: argument types (clap) and the command logic, kept in the library so
//! tests can run a command without spawning the binary. `main.rs` wires them into subcommands.

pub mod args;
pub mod bench;
pub mod calibrate;
pub mod cluster;
pub mod demo;
pub mod denoise_bench;
pub mod dgi;
pub mod display;
pub mod ellipse_distance;
pub mod filter;
pub mod head;
pub mod motion_bench;
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

/// Says `text` on standard error (`raygun: text`) unless `quiet`: what a command did, not a
/// warning (warnings and errors are said whatever `--quiet` says).
pub fn say(quiet: bool, text: impl std::fmt::Display) {
    if !quiet {
        eprintln!("raygun: {text}");
    }
}

/// `; wrote A, B` for the files a command wrote (empty when none).
#[must_use]
pub fn wrote(files: &[&std::path::Path]) -> String {
    if files.is_empty() {
        return String::new();
    }
    let names: Vec<String> = files.iter().map(|p| p.display().to_string()).collect();
    format!("; wrote {}", names.join(", "))
}

/// Prints `text` and a newline on standard output. A closed pipe (`raygun … | head`) is an
/// error like any other here; `main` ends quietly on it ([`is_broken_pipe`]).
pub fn print_out(text: &dyn std::fmt::Display) -> anyhow::Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    writeln!(out, "{text}")?;
    out.flush()?;
    Ok(())
}

/// Whether `e` comes from writing to a pipe whose reader has gone: the reader had all it
/// wanted, so the command ends quietly, as a Unix filter does.
#[must_use]
pub fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}
