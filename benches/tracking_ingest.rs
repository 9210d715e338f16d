//! `cargo bench --bench tracking_ingest`: see `raygun::bench::tracking`.

fn main() {
    println!("{}", raygun::bench::tracking::run());
}
