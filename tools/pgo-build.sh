#!/usr/bin/env bash
# raygun built with profile-guided optimisation (PGO): the CPU twin's fastest binary, for a
# machine with no GPU (the twin is then the renderer) and for the peer benchmark.
#
#   bash tools/pgo-build.sh [OUT]        # default OUT: the repository's target/pgo/raygun
#   bash tools/pgo-build.sh --train BIN  # only the training runs, with BIN (a check)
#
# Three steps, each in its own folder under target/pgo/ (the ordinary target/dist is left
# alone), all in the `dist` profile (fat LTO, one codegen unit):
#   1. an instrumented build (rustc -Cprofile-generate) in target/pgo/gen;
#   2. that binary renders a training set — the CPU twin on the builtin scenes and the peer
#      suite's scenes (area light, environment, environment map, textures, glossy, glass,
#      punctual lights, the wall camera) and the guided benchmark (DGI, schedule, filter) — at
#      small sizes, about ten seconds on two cores; the counts are merged with the toolchain's
#      llvm-profdata into target/pgo/raygun.profdata;
#   3. a build that uses them (-Cprofile-use) in target/pgo/use, copied to OUT once
#      it renders what the ordinary build renders.
# The two builds take as long as two `dist` builds from scratch (README, *Building*).
#
# What PGO changes: the compiler's layout and inlining of the code the training ran most (the
# walks, the shading, the batch loop); not one floating-point operation — the binary renders
# the same pixels to the bit (checked against target/dist/raygun when it exists).
# Measured in BENCHMARKS.md, *Builds*.
#
# Needs the toolchain's llvm-tools (`rustup component add llvm-tools`; added here when missing
# and rustup is present). Settings (environment): PGO_TRAIN_THREADS (default 2).
set -euo pipefail
caller=$PWD
cd "$(dirname "$0")/.."
ROOT=$PWD

# A relative path on the command line is the caller's (the script works from the repository).
from_caller() {
  case $1 in
    /*) echo "$1" ;;
    *) echo "$caller/$1" ;;
  esac
}

peers=tests/data/peers/scenes

# The training set, run with the binary `$bin` (its counts go where LLVM_PROFILE_FILE says,
# when it is an instrumented build).
train() {
  echo "  raygun $*" >&2
  if ! "$bin" "$@" >/dev/null; then
    echo "pgo-build: the training run failed: raygun $*" >&2
    exit 1
  fi
}
trace() { # SCENE ENV [extra…]
  local scene=$1 env=$2
  shift 2
  train bench trace --backend cpu --scene "$scene" --env "$env" --size 320,180 --spp 4 \
    --max-depth 8 "$@"
}
train_all() {
  export RAYON_NUM_THREADS=${PGO_TRAIN_THREADS:-2}
  trace builtin:cornell-light 0,0,0
  trace builtin:cornell 1,1,1
  trace builtin:city-small 1,1,1
  trace "$peers/envmap.glb" "$peers/sky.exr"
  trace "$peers/glossy.glb" 1,1,1
  trace "$peers/glass.glb" 1,1,1
  trace "$peers/lights.glb" 0,0,0
  trace builtin:cornell-light 0,0,0 --camera wall --display display-models/hornet.json \
    --eye 0,0,1
  train bench guided --backend cpu --scene builtin:cornell-light --size 320,180 --fov 10,60 \
    --iterations 8 --reference-spp 16
}

case ${1:-} in
  -h | --help)
    sed -n '2,26p' "$0" | sed 's/^# \{0,1\}//'
    exit 0
    ;;
  --train)
    bin=$(from_caller "${2:-}")
    if [ $# -ne 2 ] || [ ! -x "$bin" ]; then
      echo "pgo-build: --train needs one executable raygun binary (got: ${*:2})" >&2
      exit 2
    fi
    train_all
    echo "pgo-build: every training run finished" >&2
    exit 0
    ;;
  -*)
    echo "pgo-build: unknown option $1 (bash tools/pgo-build.sh [OUT] | --train BIN | --help)" >&2
    exit 2
    ;;
esac
out=$(from_caller "${1:-$ROOT/target/pgo/raygun}")
if [ $# -gt 1 ] || [ -d "$out" ]; then
  echo "pgo-build: OUT is the binary's path, one file, not a folder (got: $*)" >&2
  exit 2
fi

host=$(rustc -vV | sed -n 's/^host: //p')
profdata="$(rustc --print sysroot)/lib/rustlib/$host/bin/llvm-profdata"
if [ ! -x "$profdata" ]; then
  if command -v rustup >/dev/null; then
    echo "pgo-build: adding the toolchain's llvm-tools (llvm-profdata)" >&2
    rustup component add llvm-tools >&2
  fi
  if [ ! -x "$profdata" ]; then
    echo "pgo-build: $profdata not found: install the toolchain's llvm-tools (rustup component add llvm-tools)" >&2
    exit 1
  fi
fi

pgo=$ROOT/target/pgo
profiles=$pgo/profiles
rm -rf "$profiles"
mkdir -p "$profiles"

# The flag is added to .cargo/config.toml's target rustflags (cargo joins the arrays of the
# same key; RUSTFLAGS would replace them, and with them the AVX2 + FMA target features).
flags() {
  printf "target.'cfg(target_arch = \"x86_64\")'.rustflags=[\"%s\"]" "$1"
}
build() { # TARGET_DIR FLAG
  local cfg=()
  case $host in
    x86_64-*) cfg=(--config "$(flags "$2")") ;;
    *) export RUSTFLAGS="$2" ;;
  esac
  cargo build --profile dist --locked --bin raygun --target-dir "$1" "${cfg[@]}"
}

echo "pgo-build: 1/3 instrumented build (target/pgo/gen)" >&2
build "$pgo/gen" "-Cprofile-generate=$profiles"

echo "pgo-build: 2/3 training runs" >&2
export LLVM_PROFILE_FILE="$profiles/raygun-%p-%m.profraw"
bin=$pgo/gen/dist/raygun
train_all
unset LLVM_PROFILE_FILE
"$profdata" merge -o "$pgo/raygun.profdata" "$profiles"

echo "pgo-build: 3/3 optimised build (target/pgo/use)" >&2
build "$pgo/use" "-Cprofile-use=$pgo/raygun.profdata"
built=$pgo/use/dist/raygun

# The same pixels as the ordinary build, where there is one to compare with, before OUT is
# written.
if [ -x target/dist/raygun ]; then
  tmp=$(mktemp -d)
  trap 'rm -rf "$tmp"' EXIT
  render() { # BIN NAME SCENE ENV
    "$1" render --backend cpu --scene "$3" --env "$4" --size 96,54 --spp 4 --quiet \
      --out "$tmp/$2.exr" >/dev/null
  }
  for case in "builtin:city-small 1,1,1" "builtin:cornell-light 0,0,0" "$peers/glossy.glb 1,1,1"; do
    read -r scene env <<<"$case"
    render target/dist/raygun dist "$scene" "$env"
    render "$built" pgo "$scene" "$env"
    if ! cmp -s "$tmp/dist.exr" "$tmp/pgo.exr"; then
      echo "pgo-build: $built renders other pixels than target/dist/raygun ($scene;" \
        "is target/dist/raygun built from these sources?)" >&2
      exit 1
    fi
  done
  echo "pgo-build: the same pixels as target/dist/raygun (three scenes, 96×54, 4 spp)" >&2
fi

mkdir -p "$(dirname "$out")"
cp "$built" "$out.tmp"
mv "$out.tmp" "$out"
echo "pgo-build: $out" >&2
