//! `cargo run --release --example ellipse_bench [-- --worst]`: see `raygun::bench::solver_study`.

fn main() {
    let worst = std::env::args().any(|a| a == "--worst");
    print!("{}", raygun::bench::solver_study::run(worst));
}
