#!/usr/bin/env bash
# AddressSanitizer + UndefinedBehaviorSanitizer pass: configures build-asan/ (the clang tree it
# shares with the fuzz stage: tools/ci-clang-tree.sh), builds only the unit and contract test
# executables (and the tools they run), runs them under ctest, and fails on any sanitizer
# report, also one from a child process whose failure a test expected (reports go to files,
# checked at the end).
#
#   tools/ci-sanitizers.sh [--build-dir DIR] [--jobs N] [--labels REGEX] [--no-build]
#
# Lean on purpose (CI has a time budget, docs/quality.md): -O1 -g, no benchmarks, no integration
# tests; LeakSanitizer is on. Exit status: 0 clean, 1 a test failed or a sanitizer reported.
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build_dir="$repo/build-asan"
jobs=2
labels='unit|contract'
do_build=1

while [[ $# -gt 0 ]]; do
  case "$1" in
    --build-dir) build_dir="$2"; shift 2 ;;
    --jobs|-j) jobs="$2"; shift 2 ;;
    --labels|-L) labels="$2"; shift 2 ;;
    --no-build) do_build=0; shift ;;
    -h|--help) sed -n '2,11p' "$0"; exit 0 ;;
    *) echo "ci-sanitizers.sh: unknown argument '$1' (try --help)" >&2; exit 2 ;;
  esac
done

log() { printf '\033[1m[sanitizers]\033[0m %s\n' "$*" >&2; }
start=$(date +%s)

if [[ $do_build -eq 1 ]]; then
  # The one clang tree of the quality gates, shared with the fuzz stage (tools/ci-clang-tree.sh).
  "$repo/tools/ci-clang-tree.sh" "$build_dir"
  # The test executables of the chosen labels are the targets: mav_add_test names a test like its
  # executable, a shard <executable>_<shard> (the executables are not built yet, so ctest cannot
  # tell their paths).
  mapfile -t names < <(cd "$build_dir" && ctest -N -L "$labels" | sed -n 's/^ *Test *#[0-9]*: //p')
  declare -A known=()
  while read -r t; do known[$t]=1; done < <(cmake --build "$build_dir" --target help |
    sed -n 's/^\.\.\. \([^ ]*\).*/\1/p')
  declare -A chosen=()
  for name in "${names[@]}"; do
    t="$name"
    while [[ -z "${known[$t]:-}" && "$t" == *_* ]]; do t="${t%_*}"; done
    [[ -n "${known[$t]:-}" ]] || { log "no build target for test '$name'"; exit 1; }
    chosen[$t]=1
  done
  targets=("${!chosen[@]}")
  [[ ${#targets[@]} -gt 0 ]] || { log "no test matches -L '$labels'"; exit 1; }
  log "building ${#targets[@]} test targets with $jobs jobs in $build_dir"
  cmake --build "$build_dir" -j "$jobs" --target "${targets[@]}"
  log "build done in $(( $(date +%s) - start )) s"
fi

reports="$build_dir/sanitizer-reports"
rm -rf "$reports"
mkdir -p "$reports"
# log_path: every process (tests and the tools they start) writes its report to a file; the
# report still aborts the process (halt_on_error) so the test fails where it can see it.
export ASAN_OPTIONS="log_path=$reports/asan:halt_on_error=1:detect_leaks=1:strict_string_checks=1:check_initialization_order=1:detect_stack_use_after_return=1"
export UBSAN_OPTIONS="log_path=$reports/ubsan:halt_on_error=1:print_stacktrace=1"
export LSAN_OPTIONS="suppressions=$repo/tools/lsan.supp:print_suppressions=0"
run_start=$(date +%s)
status=0
(cd "$build_dir" && ctest -L "$labels" --output-on-failure -j "$jobs" --timeout 1500) |
  tee "$build_dir/ctest-output.log" || status=1
log "tests done in $(( $(date +%s) - run_start )) s"
# The ten slowest, and any test over the sanitizer pass's per-test budget (docs/quality.md,
# "CI time": a test this slow takes smaller inputs under ASan).
"$repo/tools/ctest-slowest.sh" --over 120 "$build_dir/ctest-output.log" >&2 || true

if compgen -G "$reports/*" >/dev/null; then
  log "sanitizer reports (one file per process):"
  for f in "$reports"/*; do
    echo "==== $f" >&2
    cat "$f" >&2
  done
  status=1
fi
log "$( [[ $status -eq 0 ]] && echo clean || echo FAILED ) in $(( $(date +%s) - start )) s"
exit $status
