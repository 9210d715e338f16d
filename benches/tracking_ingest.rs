//! `cargo bench --bench tracking_ingest`: see `raygun::tracking::bench`.

fn main() {
    println!("{}", raygun::tracking::bench::run());
}
