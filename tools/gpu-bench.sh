#!/usr/bin/env bash
# Every GPU figure in one call on a GPU machine: the adapter, then the benchmarks at 3840×2160,
# most important first, each within a time budget, the whole run within 7 minutes; everything
# it wrote packed into one tarball plus one summary file under $OUT. Step by step, with the
# groups and what comes back: docs/gpu-benchmark.md.
#
#   tools/gpu-bench.sh stage          on the build machine: the stripped dist binary, built
#                                     with the kernel-lab feature (the `kernels` groups time
#                                     the trace kernel's variants), into .dev/ and the Vulkan
#                                     loader packages into .gl/
#   OUT=DIR bash tools/gpu-bench.sh run     on the GPU machine, with .dev/ and .gl/ copied there
#   OUT=DIR bash tools/gpu-bench.sh smoke   the script itself on lavapipe at tiny sizes
#                                           (tests/bench/gpu_bench_script.rs runs it)
#
# Settings (environment): RAYGUN_BIN (default .dev/raygun for run, target/dist/raygun,
# target/release/raygun or target/debug/raygun for smoke), GPU_BENCH_LIMIT_S (the whole run's budget: 420 for run, 300
# for smoke), GPU_BENCH_BUDGET_SCALE (smoke only: every budget and the limit times this whole
# number, for a machine whose cores other work shares; default 1), GPU_BENCH_GROUPS (some groups only, by name, e.g. "adapter guided all" for a
# rerun of what failed; default every group), OUT (where the results go; required).
set -uo pipefail
cd "$(dirname "$0")/.."

stage() {
  set -e
  # The kernel lab: the `kernels` and `kernels-guided` groups rank the trace kernel's variants.
  cargo build --profile dist --locked --features kernel-lab
  mkdir -p .dev
  cp target/dist/raygun .dev/raygun
  strip .dev/raygun
  # The shared libraries beyond the C and C++ runtimes (fontconfig, freetype and theirs: the
  # plots' fonts), for a GPU machine whose image lacks them; `setup_device` uses only those
  # it misses, so its own stay first.
  rm -rf .dev/lib
  mkdir -p .dev/lib
  ldd .dev/raygun | awk '$2 == "=>" && $3 ~ /^\// {print $3}' \
    | { grep -vE '/(libc|libm|libgcc_s|libstdc\+\+|libpthread|libdl|librt)\.so' || true; } \
    | xargs -r cp -L -t .dev/lib
  # The Vulkan loader, and glvnd's libraries that NVIDIA's driver library links against.
  local pkgs="libvulkan1 libglvnd0 libegl1 libgl1 libglx0 libopengl0 libgles2" p need=""
  for p in $pkgs; do ls ".gl/${p}_"*.deb >/dev/null 2>&1 || need="$need $p"; done
  if [ -n "$need" ]; then
    mkdir -p .gl /tmp/amd64/partial
    local o='-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 -oDir::State::Lists=/tmp/amd64'
    # shellcheck disable=SC2086
    apt-get $o update -qq
    # shellcheck disable=SC2086
    (cd .gl && apt-get $o download $need)
  fi
  du -ch .dev .gl | tail -1
  echo 'staged: run with carry [".dev", ".gl"] and `bash tools/gpu-bench.sh run`'
}

# The GPU machine: unpack the loader, find the driver, say what the machine is.
setup_device() {
  for f in .gl/*.deb; do dpkg -x "$f" /; done
  ldconfig
  # Libraries the image lacks, from the ones staged beside the binary, a round per level of
  # dependence (fontconfig needs freetype, which needs libpng ...).
  local libs missing changed=1
  libs="$(mktemp -d)"
  while [ "$changed" = 1 ]; do
    changed=0
    for missing in $(LD_LIBRARY_PATH="$libs" ldd "$BIN" | awk '/not found/ {print $1}'); do
      if [ -e ".dev/lib/$missing" ]; then cp ".dev/lib/$missing" "$libs/"; changed=1; fi
    done
  done
  if [ -n "$(ls -A "$libs")" ]; then
    export LD_LIBRARY_PATH="$libs${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
    echo "libraries from .dev/lib: $(ls "$libs" | tr '\n' ' ')"
  fi
  # No adapter, or only Mesa's software one: point the loader at NVIDIA's driver manifest.
  local first f
  first="$("$BIN" bench adapter 2>/dev/null | grep -m1 '^adapter:')"
  if [ -z "$first" ] || [[ "$first" == *llvmpipe* ]]; then
    for f in /usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json \
      /usr/share/vulkan/icd.d/nvidia_icd.json /etc/vulkan/icd.d/nvidia_icd.json; do
      if [ -e "$f" ]; then export VK_DRIVER_FILES="$f"; break; fi
    done
    f=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
    [ -e "$f" ] && export __EGL_VENDOR_LIBRARY_FILENAMES="$f"
    echo "VK_DRIVER_FILES=${VK_DRIVER_FILES:-unset}"
  fi
  first="$("$BIN" bench adapter 2>/dev/null | grep -m1 '^adapter:')"
  if [ -z "$first" ]; then
    # Still none: say why (the loader's own errors), so one run is enough to fix it.
    VK_LOADER_DEBUG=error,warn "$BIN" bench adapter 2>&1 | head -40
  fi
  echo "${first:-adapter: none found}"
  nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.sm,clocks.max.mem --format=csv || true
  lscpu | grep -E 'Model name|^CPU\(s\)' || true
}

# The groups, most important first: NAME BUDGET_SECONDS (the H200's; smoke mode has its own).
# The full report goes last: on an H200 it runs for minutes (its 4K convergence curves), and
# takes what the others leave.
BENCH_GROUPS=(adapter picture dgi schedule trace kernels kernels-guided guided native filter
  denoise motion all-quick wall cluster sizes readback all)
declare -A BUDGET=([adapter]=20 [picture]=40 [dgi]=60 [schedule]=30 [trace]=90 [kernels]=150
  [kernels-guided]=90 [guided]=120 [native]=60 [filter]=45 [denoise]=90 [motion]=90 [all-quick]=60
  [wall]=60 [cluster]=60 [sizes]=40 [readback]=30 [all]=300)
# Smoke: kernels' 150 s is lavapipe compiling four trace kernels with an empty shader cache
# (119 s measured on a 2-vCPU Intel Xeon with the glTF extensions' BSDF in the kernel, 2026-12-05).
declare -A SMOKE_BUDGET=([adapter]=10 [picture]=10 [dgi]=20 [schedule]=20 [trace]=20 [kernels]=150
  [kernels-guided]=40 [guided]=40 [native]=20 [filter]=30 [denoise]=30 [motion]=30 [all-quick]=60
  [wall]=20 [cluster]=20 [sizes]=20 [readback]=10 [all]=60)

# The trace kernel's variants the `kernels` group times (`raygun bench trace --help`).
KERNEL_VARIANTS=function,private,workgroup,function+unchecked,private+unchecked
KERNEL_VARIANTS+=,workgroup+unchecked,function+wg32,function+wg128,function+wg256
KERNEL_VARIANTS+=,private+unchecked+wg32,workgroup+unchecked+wg32,workgroup+unchecked+wg128
# Path regeneration in at most G workgroups: an H200 has 132 SMs, so 2 to 16 groups of 64 each.
KERNEL_VARIANTS+=,private+regen264,private+regen528,private+regen1056,private+regen2112
# The wavefront split: 2^18 paths a chunk (20 MiB of state: within the H200's 50 MB L2), 2^16,
# 2^20, and with the workgroup stack.
KERNEL_VARIANTS+=,private+split,private+split65536,private+split1048576,workgroup+unchecked+split
# Triangle tests postponed by subgroup vote (32-lane subgroups on NVIDIA): at 20 % (Ylitie et
# al.'s), 10 and 35, and with the split's traversal kernel.
KERNEL_VARIANTS+=,private+vote,private+vote10,private+vote35,private+split+vote
# ... and those the `kernels-guided` group runs guided iterations with (the default first; a
# regenerating variant regenerates the guided lists' paths too).
GUIDED_KERNEL_VARIANTS="private function private+unchecked workgroup+unchecked+wg32"
GUIDED_KERNEL_VARIANTS+=" private+regen528 private+regen2112 private+vote"

# Whether the binary has the kernel lab (the `kernel-lab` feature: the trace kernel's variants,
# `bench trace --trace-kernel` and RAYGUN_TRACE_KERNEL).
has_kernel_lab() {
  "$BIN" bench trace --help 2>/dev/null | grep -q -- '--trace-kernel'
}

# Why a group has no command line in this build (`group_command` printed none).
missing_reason() {
  case "$1" in
    kernels | kernels-guided)
      echo "not in this build: the trace kernel's variants need the kernel-lab feature ($BIN lacks it; \`tools/gpu-bench.sh stage\` builds with it, or cargo build --features kernel-lab)"
      ;;
    *) echo "not in this build" ;;
  esac
}

# One group's command line (printed, then run by `bash -c` in `run_groups`).
group_command() {
  local g="$1" d="$2"
  local s="$SIZE"
  case "$g" in
    adapter) echo "$BIN bench adapter --json --out $d/adapter.json" ;;
    dgi) echo "$BIN bench dgi --backend gpu --size $s --fov 10,30,60 --reps $REPS --cpu-reps 1 --out $d/dgi.md" ;;
    schedule) echo "$BIN bench schedule --backend gpu --size $s --fov 10,30,60 --order coherent,scattered --reps $REPS --cpu-reps 1 --out $d/schedule.md" ;;
    trace) echo "$BIN bench trace --backend gpu --size $s --scene builtin:cornell,$CITY --spp $SPP --out $d/trace.md" ;;
    kernels)
      # The trace kernel's variants side by side (frames interleaved): where the traversal
      # stack lives, wgpu's run-time checks on or off, the workgroup's size. Same pictures,
      # different code; the table's last column is each one's time over the default's.
      if has_kernel_lab; then
        # A scene a run, the city first (the H200's largest kernel miss), so that a group
        # stopped by its budget still leaves the city's table.
        echo "$BIN bench trace --backend gpu --size $s --scene $CITY --spp $SPP --trace-kernel $KERNEL_VARIANTS --out $d/kernels-city.md && $BIN bench trace --backend gpu --size $s --scene builtin:cornell --spp $SPP --trace-kernel $KERNEL_VARIANTS --out $d/kernels.md"
      fi
      ;;
    kernels-guided)
      # A few of those variants in guided iterations (small launches: 2.9 % of the pixels at
      # 10°), each a run of its own with RAYGUN_TRACE_KERNEL.
      if has_kernel_lab; then
        echo "for v in $GUIDED_KERNEL_VARIANTS; do RAYGUN_TRACE_KERNEL=\$v $BIN bench guided --backend gpu --size $s --scene builtin:cornell --fov 10,60 --iterations $ITERATIONS --reference-spp $REFERENCE_SPP --out $d/guided-\$v.md || exit; done"
      fi
      ;;
    guided) echo "$BIN bench guided --backend gpu --size $s --scene builtin:cornell --fov 10,20,30,40,50,60 --iterations $ITERATIONS --reference-spp $REFERENCE_SPP --plot $d/fig5.png --out $d/guided.md" ;;
    native)
      # A guided iteration at the canvas's own resolution (HORNET: 73.8 MP), wall camera.
      echo "$BIN bench native --backend gpu --camera wall --eye 0,0,1 --fov 10,60 --iterations $NATIVE_ITERATIONS $NATIVE_DISPLAY --out $d/native.md"
      ;;
    filter) echo "$BIN bench filter --backend gpu --size $s --fov 10,60 --time-k-max 8,16,32 --reps $REPS --out $d/filter.md" ;;
    # The denoisers' error and time (the kernel at 1080p and 4K beside OIDN where the run
    # finds its library: OIDN_DIR).
    denoise) echo "$BIN bench denoise --backend gpu $DENOISE_ARGS --json $d/denoise.json --crops $d/denoise-crops.png --out $d/denoise.md" ;;
    # A moving eye with the accumulation reused and restarted (head walk, sway, step).
    motion) echo "$BIN bench motion --backend gpu $MOTION_ARGS --json $d/motion.json --plot $d/motion.svg --out $d/motion.md" ;;
    all-quick) echo "$BIN bench all --quick --backend gpu $ALL_QUICK_SIZE --out $d" ;;
    all) echo "$BIN bench all --backend gpu $ALL_SIZE --out $d" ;;
    wall)
      # HORNET's native canvas through the wall camera, once the build has one.
      if "$BIN" bench guided --help 2>/dev/null | grep -q -- '--eye'; then
        echo "$BIN bench guided --backend gpu --camera wall --eye 0,0,1 --size $WALL_SIZE --scene builtin:cornell --fov 10,60 --iterations $ITERATIONS --reference-spp 1 --out $d/wall.md"
      fi
      ;;
    cluster)
      # One GPU rank of the cluster frame (a thread: the machine has no MPI), its trace rate
      # with the compact mode's upload and read-back, for the model at 3840×2160 and 73.8 MP.
      if "$BIN" bench guided --help 2>/dev/null | grep -q -- '--cluster-threads'; then
        echo "$BIN bench guided --cluster --cluster-threads 1 --backend gpu --size $s --fov 10,60 --iterations $CLUSTER_ITERATIONS $CLUSTER_MODEL --out $d/cluster.md"
      fi
      ;;
    sizes)
      # The full frame at smaller launches: how ms per megasample grows as a launch holds fewer
      # paths than the GPU has threads (a 10° iteration traces 2.9 % of 3840×2160).
      echo "for s in $TRACE_SIZES; do $BIN bench trace --backend gpu --size \$s --scene builtin:cornell,$CITY --spp $SPP --out $d/trace-\${s/,/x}.md || exit; done"
      ;;
    picture)
      # One shown picture per iteration three ways: read back, filter, convert on the CPU
      # (what the viewer did), filtered and converted on the GPU with the 8-bit picture read
      # back (what it does now), and written into a texture on the GPU (nothing read back);
      # with the window's upload of the bytes the first two need.
      echo "$BIN bench picture --size $s --fov 10 --k-max 32 --rounds $READBACK_ROUNDS --out $d/picture.md"
      ;;
    readback)
      # A picture's read-back through a fresh and a kept mappable buffer.
      echo "$BIN bench readback --size $s --rounds $READBACK_ROUNDS --out $d/readback.md"
      ;;
  esac
}

# Runs the groups in order within the run's budget; writes $WORK/status.tsv.
run_groups() {
  local start now left budget status rc t0 t1 cmd
  start=$(date +%s)
  : >"$WORK/status.tsv"
  for g in "${BENCH_GROUPS[@]}"; do
    local d="$WORK/$g"
    mkdir -p "$d"
    budget=${BUDGETS[$g]}
    now=$(date +%s)
    left=$((LIMIT - (now - start)))
    # The last group (the full report, on a whole run) takes all the time the others left.
    if [ "$g" = "${BENCH_GROUPS[-1]}" ] && [ "$left" -gt "$budget" ]; then budget=$left; fi
    cmd=$(group_command "$g" "$d")
    if [ -z "$cmd" ]; then
      status="$(missing_reason "$g")"
      echo "== $g: $status" | tee "$d/$g.log"
      printf '%s\t%s\t0\n' "$g" "$status" >>"$WORK/status.tsv"
      continue
    fi
    if [ "$left" -lt "$budget" ]; then
      status="skipped: ${left} s left, its budget is ${budget} s"
      echo "== $g: $status" | tee "$d/$g.log"
      printf '%s\t%s\t0\n' "$g" "$status" >>"$WORK/status.tsv"
      continue
    fi
    echo "== $g ($(date -u +%FT%TZ)), budget ${budget} s: $cmd" | tee "$d/$g.log"
    t0=$(date +%s)
    timeout --signal=TERM --kill-after=5 "$budget" bash -c "$cmd" >>"$d/$g.log" 2>&1
    rc=$?
    t1=$(date +%s)
    case "$rc" in
      0) status=ok ;;
      124 | 137) status="overran its ${budget} s budget (stopped)" ;;
      *) status="failed (exit $rc)" ;;
    esac
    echo "== $g: $status in $((t1 - t0)) s" | tee -a "$d/$g.log"
    printf '%s\t%s\t%s\n' "$g" "$status" "$((t1 - t0))" >>"$WORK/status.tsv"
  done
}

# summary.md: the machine, every group's status and time, and the tables each wrote.
write_summary() {
  local out="$1"
  {
    echo "# GPU benchmarks, $(date -u +%F) ($MODE)"
    echo
    if [ -s "$WORK/adapter/adapter.json" ]; then
      grep -E '"(name|backend|driver|driver_info|subgroup_min_size|subgroup_max_size|cpu)"' \
        "$WORK/adapter/adapter.json" | sed 's/^ */- /'
    else
      echo "- adapter: not recorded"
    fi
    [ -s "$WORK/setup.log" ] && sed 's/^/    /' "$WORK/setup.log"
    echo
    echo "| group | status | seconds |"
    echo "|---|---|---|"
    while IFS=$'\t' read -r g st secs; do echo "| $g | $st | $secs |"; done <"$WORK/status.tsv"
    for g in "${BENCH_GROUPS[@]}"; do
      for f in "$WORK/$g"/*.md; do
        [ -s "$f" ] || continue
        echo
        echo "## $g: $(basename "$f")"
        echo
        cat "$f"
      done
    done
  } >"$out/summary.md"
  tar -czf "$out/gpu-bench.tar.gz" -C "$WORK" .
}

main() {
  MODE="${1:-}"
  case "$MODE" in
    stage) stage; return ;;
    run)
      BIN="${RAYGUN_BIN:-.dev/raygun}"
      LIMIT="${GPU_BENCH_LIMIT_S:-420}"
      SIZE=3840,2160 REPS=20 SPP=4 ITERATIONS=100 REFERENCE_SPP=256 CITY=builtin:city
      ALL_QUICK_SIZE="" ALL_SIZE="" WALL_SIZE=native NATIVE_ITERATIONS=20 NATIVE_DISPLAY=""
      CLUSTER_ITERATIONS=20 CLUSTER_MODEL="" TRACE_SIZES="1920,1080 960,540 480,270"
      READBACK_ROUNDS=9 DENOISE_ARGS="--size 1920,1080 --reference-spp 1024"
      MOTION_ARGS="--size 1352,546 --fps 30 --every 60 --reference-spp 256"
      declare -gA BUDGETS
      for g in "${BENCH_GROUPS[@]}"; do BUDGETS[$g]=${BUDGET[$g]}; done
      ;;
    smoke)
      if [ -n "${RAYGUN_BIN:-}" ]; then BIN="$RAYGUN_BIN"
      elif [ -x target/dist/raygun ]; then BIN=target/dist/raygun
      elif [ -x target/release/raygun ]; then BIN=target/release/raygun
      else BIN=target/debug/raygun; fi
      local scale="${GPU_BENCH_BUDGET_SCALE:-1}"
      [[ "$scale" =~ ^[1-9][0-9]*$ ]] || { echo "GPU_BENCH_BUDGET_SCALE: expected a whole number from 1, found '$scale'" >&2; exit 2; }
      LIMIT="${GPU_BENCH_LIMIT_S:-$((300 * scale))}"
      SIZE=32,18 REPS=1 SPP=1 ITERATIONS=2 REFERENCE_SPP=2 CITY=builtin:city-small
      ALL_QUICK_SIZE="--size 16,9 --scene builtin:cornell" ALL_SIZE="--size 24,12 --scene builtin:cornell"
      WALL_SIZE=64,26 NATIVE_ITERATIONS=2 NATIVE_DISPLAY=tiny
      CLUSTER_ITERATIONS=2 CLUSTER_MODEL="--model-size 64,26 --model-ranks 3"
      TRACE_SIZES="16,9 8,4" READBACK_ROUNDS=2
      DENOISE_ARGS="--size 32,18 --iterations 1,4 --reference-spp 8 --timing-sizes none"
      MOTION_ARGS="--scene builtin:cornell --size 32,18 --fov 60 --fps 0.5 --every 5 --reference-spp 4 --max-depth 1"
      # One of each kind (one over lavapipe's workgroup memory: named, not run). Few, as
      # lavapipe compiles each new kernel in about 20 s; the regeneration's cap is not in the
      # kernel, so the guided run reuses the regenerating kernel compiled before it.
      KERNEL_VARIANTS=private,workgroup+unchecked+wg32,private+regen264,workgroup+unchecked+wg128,private+vote
      GUIDED_KERNEL_VARIANTS="private+regen4"
      declare -gA BUDGETS
      for g in "${BENCH_GROUPS[@]}"; do BUDGETS[$g]=$((SMOKE_BUDGET[$g] * scale)); done
      export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp}"
      ;;
    *)
      echo "usage: tools/gpu-bench.sh stage | run | smoke   (run and smoke need OUT)" >&2
      exit 2
      ;;
  esac
  if [ -n "${GPU_BENCH_GROUPS:-}" ]; then
    # A rerun of some groups (in the script's order), e.g. those the first run failed or skipped.
    local want g known picked=()
    for want in $GPU_BENCH_GROUPS; do
      known=0
      for g in "${BENCH_GROUPS[@]}"; do [ "$g" = "$want" ] && known=1; done
      if [ "$known" = 0 ]; then
        echo "GPU_BENCH_GROUPS: no group '$want' (groups: ${BENCH_GROUPS[*]})" >&2
        exit 2
      fi
    done
    for g in "${BENCH_GROUPS[@]}"; do
      for want in $GPU_BENCH_GROUPS; do
        if [ "$g" = "$want" ]; then picked+=("$g"); break; fi
      done
    done
    BENCH_GROUPS=("${picked[@]}")
  fi
  local out="${OUT:?set OUT to the folder for the results}"
  mkdir -p "$out"
  WORK="$(mktemp -d)/gpu-bench"
  mkdir -p "$WORK"
  # Everything worth keeping is packed into $out; the working folder goes with the script.
  trap 'rm -rf "${WORK%/gpu-bench}"' EXIT
  local dmon=""
  if [ "$MODE" = run ]; then
    setup_device >"$WORK/setup.log" 2>&1
    # The GPU's clocks, power and load each second through the run: a kernel that ran slower in
    # one group than in another is told apart from a GPU that had clocked down.
    if command -v nvidia-smi >/dev/null 2>&1; then
      nvidia-smi dmon -s pucm -d 1 -o T >"$WORK/dmon.log" 2>&1 &
      dmon=$!
    fi
  fi
  if [ "$NATIVE_DISPLAY" = tiny ]; then
    # Smoke: a 3×2 curved wall of 24×12-pixel tiles (lavapipe's 128 MiB bindings hold no
    # native HORNET).
    cat >"$WORK/tiny-wall.json" <<'JSON'
{ "name": "tiny curved wall", "generator": { "columns": 3, "rows": 2, "resolution": [24, 12],
  "active_size": [0.24, 0.12], "bezel": { "left": 0.01, "right": 0.01, "top": 0.01, "bottom": 0.01 },
  "yaw_step_deg": 10.0, "center": [0, 0, 0], "normal": [0, 0, 1], "up": [0, 1, 0] } }
JSON
    NATIVE_DISPLAY="--display $WORK/tiny-wall.json"
  fi
  run_groups
  if [ -n "$dmon" ]; then kill "$dmon" 2>/dev/null; wait "$dmon" 2>/dev/null; fi
  write_summary "$out"
  echo "wrote $out/summary.md and $out/gpu-bench.tar.gz"
  cat "$WORK/status.tsv"
}

main "$@"
