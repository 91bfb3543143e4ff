#!/usr/bin/env bash
# Runs the whole test suite: sets up and builds what is missing (deploy/setup.sh), then ctest.
# Extra arguments go to ctest, e.g. ./test.sh -L unit   or   ./test.sh -R camera
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
"$repo/deploy/setup.sh"
cd "$repo/build"
ctest --output-on-failure --timeout 600 -j "$(nproc 2>/dev/null || echo 2)" "$@"
