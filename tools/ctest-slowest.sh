#!/usr/bin/env bash
# Prints the N slowest tests (default 10) of a ctest run from its output, e.g.
#   ctest ... | tee ctest.log; tools/ctest-slowest.sh ctest.log
# and, with --over S, names every test that took longer than S seconds (CI's per-test budgets,
# docs/quality.md "CI time"). Reads ctest's "Test #N: name .... Passed  12.34 sec" lines.
set -euo pipefail
n=10
over=""
while [[ $# -gt 1 ]]; do
  case "$1" in
    --top) n="$2"; shift 2 ;;
    --over) over="$2"; shift 2 ;;
    *) break ;;
  esac
done
log="${1:?usage: ctest-slowest.sh [--top N] [--over S] CTEST_OUTPUT}"
[[ -f "$log" ]] || { echo "ctest-slowest.sh: $log: no such file" >&2; exit 2; }
times="$(sed -n 's/.*Test *#[0-9]*: \([^ ]*\) .*[^0-9]\([0-9][0-9]*\.[0-9]*\) sec.*/\2 \1/p' "$log" |
  sort -rn)"
[[ -n "$times" ]] || exit 0
echo "slowest tests:"
head -n "$n" <<<"$times" | awk '{printf "  %8.1f s  %s\n", $1, $2}'
if [[ -n "$over" ]]; then
  awk -v limit="$over" '$1 > limit {printf "over the %d s per-test budget: %s (%.1f s)\n", limit, $2, $1}' \
    <<<"$times"
fi
