#!/usr/bin/env bash
# Configures the one clang tree of the quality gates (default build-asan/): AddressSanitizer +
# UndefinedBehaviorSanitizer on every target, the unit and contract tests, and the libFuzzer
# targets (MAV_FUZZ=ON), so tools/ci-sanitizers.sh and tools/ci-fuzz-smoke.sh build the
# libraries once between them (docs/quality.md). Installs the clang toolchain (and the
# project's packages) when missing. Configuring again with the same settings changes nothing.
#
#   tools/ci-clang-tree.sh [BUILD_DIR]
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build_dir="${1:-$repo/build-asan}"

# A clean CI machine has only what the project's files install.
"$repo/deploy/setup.sh" --no-build
"$repo/deploy/setup.sh" --packages "$repo/deploy/packages-quality.txt" --no-build
command -v clang++ >/dev/null ||
  { echo "ci-clang-tree.sh: clang++ not found (deploy/packages-quality.txt)" >&2; exit 2; }

# clang: UBSan reports go to files like ASan's (cmake/MavSanitize.cmake says why). -O1: most of
# -O2's speed for the tests at a fraction of the compile time; line tables are enough for
# symbolised stacks; NDEBUG as in the Release build that ./test.sh runs.
mkdir -p "$build_dir"
flags="-O1 -gline-tables-only -DNDEBUG"
CC=clang CXX=clang++ cmake -S "$repo" -B "$build_dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="$flags" -DCMAKE_C_FLAGS_RELWITHDEBINFO="$flags" \
  -DMAV_SANITIZE=address,undefined -DMAV_FUZZ=ON -DMAV_BUILD_TESTS=ON \
  -DMAV_BUILD_SERVICES=ON -DMAV_BUILD_BENCHMARKS=OFF >"$build_dir/configure.log" 2>&1 ||
  { cat "$build_dir/configure.log" >&2; exit 1; }
