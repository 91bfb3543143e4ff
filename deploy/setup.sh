#!/usr/bin/env bash
# Idempotent set-up: installs the Debian packages listed in deploy/packages.txt that are missing,
# then configures and builds the Release tree in build/ (incrementally; ccache makes rebuilds cheap).
#
#   deploy/setup.sh [--no-build] [--build-dir DIR] [--jobs N] [--packages FILE]
#
# --packages FILE: install the packages of FILE (same format) instead, e.g. the quality gates'
# clang toolchain (deploy/packages-quality.txt, used by tools/ci-*.sh).
# Safe to run any number of times: apt is touched only when a package is missing.
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build_dir="$repo/build"
jobs="$(nproc 2>/dev/null || echo 2)"
do_build=1
package_file="$repo/deploy/packages.txt"

while [[ $# -gt 0 ]]; do
  case "$1" in
    --no-build) do_build=0; shift ;;
    --build-dir) build_dir="$2"; shift 2 ;;
    --jobs) jobs="$2"; shift 2 ;;
    --packages) package_file="$2"; shift 2 ;;
    -h|--help) sed -n '2,11p' "$0"; exit 0 ;;
    *) echo "setup.sh: unknown argument '$1' (try --help)" >&2; exit 2 ;;
  esac
done

log() { printf '\033[1m[setup]\033[0m %s\n' "$*" >&2; }

[[ -f "$package_file" ]] || { echo "setup.sh: $package_file: no such package list" >&2; exit 2; }
mapfile -t packages < <(grep -vE '^\s*(#|$)' "$package_file")
missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [[ ${#missing[@]} -gt 0 ]]; then
  log "installing ${#missing[@]} missing Debian packages: ${missing[*]}"
  sudo_cmd=()
  if [[ $(id -u) -ne 0 ]]; then
    command -v sudo >/dev/null || { echo "setup.sh: need root or sudo to install packages" >&2; exit 1; }
    sudo_cmd=(sudo)
  fi
  "${sudo_cmd[@]}" apt-get update -q
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}"
else
  log "all ${#packages[@]} Debian packages present"
fi

[[ $do_build -eq 1 ]] || exit 0

if [[ ! -f "$build_dir/CMakeCache.txt" ]]; then
  mkdir -p "$build_dir"
  log "configuring Release build in $build_dir (the output: $build_dir/configure.log)"
  if ! cmake -S "$repo" -B "$build_dir" -DCMAKE_BUILD_TYPE=Release > "$build_dir/configure.log" 2>&1; then
    tail -40 "$build_dir/configure.log" >&2
    echo "setup.sh: configuring failed (all of it in $build_dir/configure.log)" >&2
    rm -f "$build_dir/CMakeCache.txt"
    exit 1
  fi
fi
# One progress line (rewritten in place on a terminal) instead of CMake's hundreds; the full
# output goes to build.log, named here and shown in part when the build fails.
build_log="$build_dir/build.log"
log "building with $jobs jobs (incremental; the full output: $build_log)"
tty=0
[[ -t 2 ]] && tty=1
start=$(date +%s)
set +e
cmake --build "$build_dir" -j "$jobs" 2>&1 | tee "$build_log" |
  awk -v tty="$tty" '
    match($0, /^\[ *[0-9]+%\]/) {
      pct = substr($0, RSTART + 1, RLENGTH - 2); gsub(/ /, "", pct)
      if (tty) { printf "\r\033[K[setup] building %s %.60s", pct, substr($0, RLENGTH + 2) > "/dev/stderr" }
    }
    END { if (tty) printf "\r\033[K" > "/dev/stderr" }'
status=${PIPESTATUS[0]}
set -e
if [[ $status -ne 0 ]]; then
  echo "setup.sh: the build failed (exit $status); its errors (all of it in $build_log):" >&2
  grep -E -A4 "error|Error " "$build_log" | head -60 >&2
  exit "$status"
fi
log "built in $(( $(date +%s) - start )) s: executables in $build_dir/bin"
