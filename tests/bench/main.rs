//! The benchmarks' commands: `bench all`, `bench schedule`, `bench filter`, `bench denoise`, and the GPU
//! benchmark script.

mod bench_all;
mod denoise_cli;
mod filter_cli;
mod gpu_bench_script;
mod motion_cli;
mod schedule_bench;

// The helpers of tests/support/ that the files above use, each compiled once here.
#[path = "../support/cli.rs"]
mod support;
#[path = "../support/walls.rs"]
mod walls;
