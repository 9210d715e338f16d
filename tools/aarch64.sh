#!/usr/bin/env bash
# raygun on 64-bit ARM Linux (AArch64: NVIDIA Grace beside a Hopper GPU, AWS Graviton, Ampere),
# from this x86-64 machine: cross-built, linted, and its tests run under qemu-user, the GPU
# tests on arm64's lavapipe.
#
#   bash tools/aarch64.sh                 # clippy with warnings denied, then the tests
#   bash tools/aarch64.sh lint            # clippy only: what .ci/run does
#   bash tools/aarch64.sh test [ARGS...]  # the tests only; ARGS (cargo test's) choose them
#
# The whole run takes about an hour on two cores: the cross build 7 min, then under emulation
# the library's unit tests 4 min and the integration tests 52 min (mostly the GPU tests on an
# emulated lavapipe; tests/render/peers.rs alone 19 min). `lint` takes about 2 min.
#
# What differs on ARM: the CPU twin walks its rays one at a time (the sixteen-ray packets are
# x86-64 lanes; `RAYGUN_CPU_PACKETS` accepts only 0 there), each leaf's eight triangles in one
# test; the shading lanes and the DGI's f64x4 lanes are `wide`'s, in pairs of NEON registers.
# Every lane function is its scalar twin to the bit on both architectures, which is what the
# tests check.
#
# The tests run: the library's unit tests and every integration test that does not start the
# `raygun` binary. Those that do (the files under tests/ that use `support/cli.rs` or name
# `CARGO_BIN_EXE`) would start an ARM executable, which needs the kernel's binfmt_misc to hand
# it to qemu — containers have none. Times under emulation mean nothing: this checks
# correctness, never speed.
#
# Installs what it lacks (Debian, as root): the cross C++ compiler (Basis Universal's and
# meshoptimizer's C++ are built for the target), rustup's aarch64 standard library; for the
# tests also qemu-user and, through multiarch, arm64's libc, Vulkan loader and lavapipe.
# Builds under target/aarch64-unknown-linux-gnu/, beside the host's build.
set -euo pipefail
cd "$(dirname "$0")/.."

mode=${1:-all}
case $mode in
  all | lint | test) shift $(($# > 0)) ;;
  *)
    echo "usage: bash tools/aarch64.sh [lint | test [CARGO-TEST-ARGS...]]" >&2
    exit 2
    ;;
esac
if [ "$mode" != test ] && (($#)); then
  echo "tools/aarch64.sh: only \`test\` takes cargo test's arguments" >&2
  exit 2
fi

TARGET=aarch64-unknown-linux-gnu
log() { printf '\n== %s ==\n' "$*"; }

packages=()
command -v aarch64-linux-gnu-g++ >/dev/null 2>&1 || packages+=(g++-aarch64-linux-gnu)
if [ "$mode" != lint ]; then
  command -v qemu-aarch64 >/dev/null 2>&1 || packages+=(qemu-user)
  if ! ls /usr/share/vulkan/icd.d/lvp_icd.aarch64.json >/dev/null 2>&1 \
    || ! [ -e /usr/lib/aarch64-linux-gnu/libvulkan.so.1 ]; then
    dpkg --print-foreign-architectures | grep -qx arm64 || dpkg --add-architecture arm64
    packages+=(mesa-vulkan-drivers:arm64 libvulkan1:arm64)
  fi
fi
if ((${#packages[@]})); then
  log "installing ${packages[*]}"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq "${packages[@]}" >/dev/null
fi
rustup target list --installed | grep -qx "$TARGET" || rustup target add "$TARGET" >/dev/null

export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc
# The arm64 libraries (libc, the Vulkan loader, lavapipe) are multiarch packages in the
# system's own folders, where the emulated loader looks.
export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_RUNNER=qemu-aarch64
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp}"

if [ "$mode" != test ]; then
  log "cargo clippy --target $TARGET (warnings denied)"
  # The library with its unit tests (the SIMD lanes' twins, `--profile test`: cfg(test) on),
  # the binary, and the one integration test with ARM-only code (tests/cli); the other test
  # binaries are the same portable code on both architectures, linted on the host.
  cargo clippy --target "$TARGET" --lib --bins --test cli --profile test --locked -- -D warnings
fi
[ "$mode" = lint ] && exit 0
if (($#)); then
  log "cargo test --target $TARGET $*, under qemu"
  exec cargo test --target "$TARGET" --locked "$@"
fi

# The integration tests that run in this process: not those that start the binary. Cargo's
# test targets: tests/NAME.rs, and tests/NAME/main.rs whose folder's other files are its modules
# (one subject each); a module that starts the binary is skipped by its name (`--skip FILE::`),
# a binary all of whose tests would be skipped is left out.
starts() { grep -qE 'support/cli\.rs|crate::support\b|CARGO_BIN_EXE' "$1"; }
names=() skips=()
for f in tests/*.rs tests/*/main.rs; do
  case $f in
    */main.rs)
      name=$(basename "$(dirname "$f")") skip=() kept=0
      for m in "$(dirname "$f")"/*.rs; do
        [ "$m" = "$f" ] && continue
        if starts "$m"; then skip+=(--skip "$(basename "$m" .rs)::"); else kept=1; fi
      done
      ((kept)) || continue
      ;;
    *)
      name=$(basename "$f" .rs) skip=()
      starts "$f" && continue
      ;;
  esac
  names+=("$name") skips+=("${skip[*]}")
done
log "cargo test --target $TARGET: the library and ${#names[@]} integration tests, under qemu"
cargo test --target "$TARGET" --locked --no-run --lib "${names[@]/#/--test=}"
cargo test --target "$TARGET" --locked --lib
for i in "${!names[@]}"; do
  # shellcheck disable=SC2086 # the skips are words without spaces
  cargo test --target "$TARGET" --locked --test "${names[$i]}" -- ${skips[$i]}
done
