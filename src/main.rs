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
    /// Where a ray meets the display, as one JSON object.
    Pick(cli::display::PickArgs),
    /// Display-model tools.
    #[command(subcommand)]
    Display(DisplayCommand),
    /// Benchmarks: speed and error, with the hardware they ran on.
    #[command(subcommand)]
    Bench(cli::bench::BenchCommand),
}

#[derive(Subcommand)]
enum DisplayCommand {
    /// Print the model's explicit form (generators expanded), as the loader sees it.
    Expand(cli::display::ExpandArgs),
}

fn main() {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Dgi(args) => cli::dgi::run(args),
        Command::Pick(args) => cli::display::pick(args).map(|v| println!("{v}")),
        Command::Display(DisplayCommand::Expand(args)) => {
            cli::display::expand(args).map(|text| println!("{text}"))
        }
        Command::Bench(cmd) => cli::bench::run(cmd),
    };
    if let Err(e) = result {
        eprintln!("raygun: error: {e:#}");
        std::process::exit(1);
    }
}
