#!/usr/bin/env bash
# Runs the whole test suite: sets up and builds what is missing (deploy/setup.sh), then ctest.
# Extra arguments go to ctest, e.g. ./test.sh -L unit   or   ./test.sh -R camera
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
"$repo/deploy/setup.sh"
cd "$repo/build"
mkdir -p Testing
status=0
ctest --output-on-failure --timeout 600 -j "$(nproc 2>/dev/null || echo 2)" "$@" |
  tee Testing/ctest-output.log || status=$?
# The ten slowest, and any test over the per-test budget of docs/quality.md ("CI time").
"$repo/tools/ctest-slowest.sh" --over 60 Testing/ctest-output.log || true
exit "$status"
