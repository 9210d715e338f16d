#!/usr/bin/env bash
# Every GPU benchmark on a lent GPU machine (the `device` tool), in as few device calls as the
# 10-minute-per-command limit allows.
#
# Here (the development machine), once:
#   tools/gpu-bench.sh stage
# builds the release binary, strips it into .dev/raygun (git-ignored; the device copies tracked
# files but only *carried* ignored ones, 64 MiB in all), and downloads the Vulkan loader packages
# into .gl/ (the device image has the NVIDIA driver but no loader).
#
# There, with carry [".dev", ".gl"], one group per call:
#   bash tools/gpu-bench.sh run quick     # adapter check + `bench all --quick` (~1 min)
#   bash tools/gpu-bench.sh run kernels   # dgi, trace, schedule, filter at 3840×2160
#   bash tools/gpu-bench.sh run guided    # the paper's benchmark + Figure 5
#   bash tools/gpu-bench.sh run all       # `bench all` at full size (report.md, plots)
# Each writes <group>.log plus the benchmarks' Markdown/JSON/PNG under $OUT; copy the tables
# into BENCHMARKS.md with the date and the adapter name printed at the top of the log.
#
# `bench GROUP...` runs the groups without the device setup. With RAYGUN_BIN and
# RAYGUN_BENCH_EXTRA (appended to every bench command) it smoke-tests this script here, e.g.
#   OUT=/tmp/gb RAYGUN_BIN=target/debug/raygun RAYGUN_BENCH_EXTRA='--size 32,18' \
#     tools/gpu-bench.sh bench kernels
set -euo pipefail
cd "$(dirname "$0")/.."

stage() {
  cargo build --release --locked
  mkdir -p .dev
  cp target/release/raygun .dev/raygun
  strip .dev/raygun
  if ! ls .gl/libvulkan1_*.deb >/dev/null 2>&1; then
    mkdir -p .gl /tmp/amd64/partial
    local o='-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 -oDir::State::Lists=/tmp/amd64'
    # shellcheck disable=SC2086
    apt-get $o update -qq
    # shellcheck disable=SC2086
    (cd .gl && apt-get $o download libvulkan1)
  fi
  du -ch .dev .gl | tail -1
  echo 'staged: run with carry [".dev", ".gl"] and `bash tools/gpu-bench.sh run GROUP`'
}

setup_device() {
  for f in .gl/*.deb; do dpkg -x "$f" /; done
  ldconfig
  if ! .dev/raygun bench dgi --size 64,36 --fov 10 --reps 1 --cpu-reps 1 --backend gpu >/dev/null 2>&1; then
    export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
  fi
  nvidia-smi --query-gpu=name,driver_version,clocks.max.sm,clocks.max.mem --format=csv || true
  lscpu | grep -E 'Model name|^CPU\(s\)' || true
}

run_group() {
  local out="${OUT:?set by the device tool}"
  local -a extra
  read -r -a extra <<<"${RAYGUN_BENCH_EXTRA:-}"
  rg() { "${RAYGUN_BIN:-.dev/raygun}" bench "$@" "${extra[@]}"; }
  case "$1" in
    quick)
      rg all --quick --backend gpu --out "$out/quick"
      ;;
    kernels)
      rg dgi --backend gpu --out "$out/dgi.md"
      rg trace --backend gpu --scene builtin:cornell,builtin:city --out "$out/trace.md"
      rg schedule --backend gpu --order coherent,scattered --out "$out/schedule.md"
      rg filter --backend gpu --out "$out/filter.md"
      ;;
    guided)
      rg guided --backend gpu --scene builtin:cornell,builtin:city \
        --order coherent,scattered --plot "$out/fig5.png" --out "$out/guided.md"
      ;;
    all)
      rg all --backend gpu --out "$out/all"
      ;;
    *)
      echo "unknown group '$1' (quick | kernels | guided | all)" >&2
      exit 2
      ;;
  esac
}

case "${1:-}" in
  stage) stage ;;
  run)
    shift
    [ $# -gt 0 ] || { echo "usage: tools/gpu-bench.sh run quick|kernels|guided|all ..." >&2; exit 2; }
    setup_device 2>&1 | tee "${OUT:?}/setup.log"
    for g in "$@"; do
      echo "== $g ($(date -u +%FT%TZ))"
      run_group "$g" 2>&1 | tee "$OUT/$g.log"
    done
    ;;
  bench)
    shift
    for g in "$@"; do run_group "$g" 2>&1 | tee "${OUT:?}/$g.log"; done
    ;;
  *)
    echo "usage: tools/gpu-bench.sh stage | run GROUP... | bench GROUP..." >&2
    exit 2
    ;;
esac
