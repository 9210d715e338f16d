#!/usr/bin/env bash
# Runs every fuzz target for a bounded time (default 60 s each), for CI.
#
#   fuzz/run.sh [SECONDS]
#
# Needs cargo-fuzz (`cargo install cargo-fuzz`) and a C++ compiler (libFuzzer is built from
# source by libfuzzer-sys). Only stable Rust is installed here, so the nightly-only flags
# cargo-fuzz passes (-Cpasses=sancov, -Zsanitizer) are unlocked with RUSTC_BOOTSTRAP=1 (checked:
# this works with Rust 1.95). The sanitizer is off (-s none): the code under test is safe Rust,
# so the fuzzer looks for panics, arithmetic overflows (checked in dev builds) and broken
# invariants (the targets assert them), not memory errors. Targets are built with --dev, line
# tables only and raygun without its window (fuzz/Cargo.toml): 167 s from scratch on 2 cores
# (270 s with full debug info and the window's crates), then 1 000–9 000 runs/s, plenty for a
# bounded CI run.
set -euo pipefail
secs="${1:-60}"
cd "$(dirname "$0")/.."
for target in dtrack osc vrpn replay display_model ellipse_lines gltf calibration ktx2 tile_owners outputs; do
    mkdir -p "fuzz/corpus/$target"
    RUSTC_BOOTSTRAP=1 cargo fuzz run -s none --dev "$target" "fuzz/corpus/$target" "fuzz/seeds/$target" -- \
        -max_total_time="$secs" -max_len=65536 -rss_limit_mb=2048
done
