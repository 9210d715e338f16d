#!/usr/bin/env bash
# Runs every fuzz target for a bounded time (default 60 s each), for CI.
#
#   fuzz/run.sh [SECONDS]
#
# Needs cargo-fuzz (`cargo install cargo-fuzz`) and a C++ compiler (libFuzzer is built from
# source by libfuzzer-sys). Only stable Rust is installed here, so the nightly-only flags
# cargo-fuzz passes (-Zsanitizer, -Cpasses=sancov) are unlocked with RUSTC_BOOTSTRAP=1; the
# address sanitizer is off (-s none) because its runtime is not shipped with stable.
set -euo pipefail
secs="${1:-60}"
cd "$(dirname "$0")/.."
for target in dtrack osc replay; do
    mkdir -p "fuzz/corpus/$target"
    RUSTC_BOOTSTRAP=1 cargo fuzz run -s none "$target" "fuzz/corpus/$target" "fuzz/seeds/$target" -- \
        -max_total_time="$secs" -max_len=65536 -rss_limit_mb=2048
done
