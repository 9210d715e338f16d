#!/usr/bin/env bash
# Intel Open Image Denoise 2.5 for `--denoise oidn`, from its prebuilt libraries.
#
#   bash tools/oidn.sh install [DIR]   # install into DIR (default: the folder raygun looks in)
#   bash tools/oidn.sh where           # print the folder raygun looks in
#
# Intel's release of OIDN 2.5.1 for x86-64 Linux (the core library, its CPU and CUDA devices,
# TBB, and Intel's own `oidnDenoise` command) is carried by PyPI's `pyoidn` wheel; this
# downloads that one wheel with pip, checks its SHA-256 and unpacks the library's folder (`lib/`,
# `bin/`) into DIR. raygun loads `DIR/lib/libOpenImageDenoise.so.2` when `--denoise oidn` asks for
# it (src/filter/oidn.rs); nothing is built or linked, and raygun runs as before without it.
#
# Where raygun looks: `$OIDN_DIR/lib` when OIDN_DIR is set (any OIDN 2.x installation, such as
# Intel's release archive unpacked), otherwise `$XDG_DATA_HOME/raygun/oidn/lib` (by default
# `~/.local/share/raygun/oidn/lib`), then the dynamic linker's own search path.
#
# The CUDA device runs where an NVIDIA driver with CUDA is present; the wheel holds no ARM
# build, so on AArch64 install OIDN from Intel's release instead and set OIDN_DIR.
set -euo pipefail

version=2.5.1.0
wheel="pyoidn-${version}-py3-none-manylinux2014_x86_64.whl"
sha256=32ad13368f8de1ef63001942ad05b02a00cd732d1206d97f352d3a3f606d823e

default_dir() {
  if [ -n "${OIDN_DIR:-}" ]; then
    printf '%s\n' "$OIDN_DIR"
  else
    printf '%s\n' "${XDG_DATA_HOME:-$HOME/.local/share}/raygun/oidn"
  fi
}

install() {
  local dir="${1:-$(default_dir)}"
  if [ "$(uname -m)" != x86_64 ]; then
    echo "oidn.sh: the pyoidn wheel holds x86-64 libraries only; on $(uname -m) unpack Intel's OIDN 2.x release and set OIDN_DIR to it" >&2
    exit 1
  fi
  if [ -e "$dir/lib/libOpenImageDenoise.so.2" ] && [ -e "$dir/.pyoidn-$version" ]; then
    echo "OIDN $version is already in $dir"
    return
  fi
  command -v python3 >/dev/null 2>&1 || { echo "oidn.sh: python3 (with pip) is needed to download the wheel" >&2; exit 1; }
  tmp="$(mktemp -d)"
  trap 'rm -rf "$tmp"' EXIT
  python3 -m pip download --quiet --no-deps --only-binary :all: "pyoidn==$version" -d "$tmp"
  echo "$sha256  $tmp/$wheel" | sha256sum --check --quiet -
  python3 - "$tmp/$wheel" "$tmp/unpacked" <<'EOF'
import sys, zipfile
wheel, out = sys.argv[1], sys.argv[2]
with zipfile.ZipFile(wheel) as z:
    for info in z.infolist():
        if info.filename.startswith("pyoidn/oidn/") and not info.is_dir():
            z.extract(info, out)
EOF
  chmod +x "$tmp/unpacked/pyoidn/oidn/bin/"*
  mkdir -p "$(dirname "$dir")"
  # Into place in one rename, so that an interrupted install leaves no half a library.
  rm -rf "$dir.partial"
  mv "$tmp/unpacked/pyoidn/oidn" "$dir.partial"
  touch "$dir.partial/.pyoidn-$version"
  rm -rf "$dir"
  mv "$dir.partial" "$dir"
  echo "installed OIDN $version into $dir"
}

case "${1:-}" in
  install) shift; install "$@" ;;
  where) default_dir ;;
  *) sed -n '2,6p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2 ;;
esac
