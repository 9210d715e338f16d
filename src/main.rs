//! The `raygun` command. Arguments are parsed into each command's typed configuration before any
//! work starts; errors are printed once, with their cause chain.

use clap::{Parser, Subcommand};

use raygun::cli;

/// raygun — guided high-quality rendering on display walls.
#[derive(Parser)]
#[command(version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Write the distance-guide image for a ray-gun pose or a mouse ROI.
    Dgi(cli::dgi::DgiArgs),
    /// Benchmarks: speed and error, with the hardware they ran on.
    #[command(subcommand)]
    Bench(cli::bench::BenchCommand),
}

fn main() {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Dgi(args) => cli::dgi::run(args),
        Command::Bench(cmd) => cli::bench::run(cmd),
    };
    if let Err(e) = result {
        eprintln!("raygun: error: {e:#}");
        std::process::exit(1);
    }
}
