#!/usr/bin/env bash
# Builds the libFuzzer targets (tests/fuzz) with clang in build-asan/ (the tree of the sanitizer
# stage, tools/ci-clang-tree.sh: address + undefined sanitizers, coverage instrumentation on the
# fuzzed libraries) and runs each for a short time on a copy of its seed corpus
# (tests/fuzz/corpus/<target>/). Fails if any target crashes, leaks, times out on an input or
# trips a sanitizer; the input is kept in build-asan/fuzz-artifacts/.
#
#   tools/ci-fuzz-smoke.sh [--build-dir DIR] [--jobs N] [--seconds S] [--parallel P]
#                          [--cpu C] [--no-build] [TARGET...]
#
# Defaults: 30 s per target, 2 targets at a time (one per core, pinned with taskset when
# available; --cpu C pins every run to core C), every target of tests/fuzz/CMakeLists.txt
# except octomap_bt_raw_fuzzer (raw OctoMap, expected to crash: docs/quality.md). The 10-minute
# runs of docs/quality.md use --seconds 600 --parallel 1 --cpu 1. The repository's corpus is
# never modified; the grown corpora stay in build-asan/fuzz-work/corpus/.
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build_dir="$repo/build-asan"
jobs=2
seconds=30
parallel=2
cpu=""
do_build=1
targets=()

while [[ $# -gt 0 ]]; do
  case "$1" in
    --build-dir) build_dir="$2"; shift 2 ;;
    --jobs|-j) jobs="$2"; shift 2 ;;
    --seconds) seconds="$2"; shift 2 ;;
    --parallel) parallel="$2"; shift 2 ;;
    --cpu) cpu="$2"; shift 2 ;;
    --no-build) do_build=0; shift ;;
    -h|--help) sed -n '2,15p' "$0"; exit 0 ;;
    -*) echo "ci-fuzz-smoke.sh: unknown flag '$1' (try --help)" >&2; exit 2 ;;
    *) targets+=("$1"); shift ;;
  esac
done

log() { printf '\033[1m[fuzz]\033[0m %s\n' "$*" >&2; }
start=$(date +%s)

if [[ ${#targets[@]} -eq 0 ]]; then
  mapfile -t targets < <(sed -n 's/^ *mav_add_fuzzer(\([a-z0-9_]*\) .*/\1/p' \
    "$repo/tests/fuzz/CMakeLists.txt" | grep -v '^octomap_bt_raw_fuzzer$')
fi

if [[ $do_build -eq 1 ]]; then
  # The sanitizer stage's tree: the libraries it built are reused (tools/ci-clang-tree.sh).
  "$repo/tools/ci-clang-tree.sh" "$build_dir"
  log "building ${#targets[@]} fuzz targets with $jobs jobs in $build_dir"
  cmake --build "$build_dir" -j "$jobs" --target "${targets[@]}"
  log "build done in $(( $(date +%s) - start )) s"
fi

work="$build_dir/fuzz-work"
artifacts="$build_dir/fuzz-artifacts"
rm -rf "$work"
mkdir -p "$work" "$artifacts"
ncpu="$(nproc 2>/dev/null || echo 1)"

# Runs one target; its libFuzzer log ends up in $work/<target>.log.
run_one() {
  local target="$1" slot="$2"
  local corpus="$work/corpus/$target"
  mkdir -p "$corpus"
  cp "$repo/tests/fuzz/corpus/$target"/* "$corpus"/ 2>/dev/null || true
  local pin=()
  if command -v taskset >/dev/null; then pin=(taskset -c "${cpu:-$(( slot % ncpu ))}"); fi
  "${pin[@]}" "$build_dir/bin/fuzz/$target" -max_total_time="$seconds" -timeout=10 \
    -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix="$artifacts/$target-" \
    "$corpus" >"$work/$target.log" 2>&1
}

run_start=$(date +%s)
failed=()
pids=()
names=()
slot=0
for target in "${targets[@]}"; do
  [[ -x "$build_dir/bin/fuzz/$target" ]] || { log "$target: not built"; failed+=("$target"); continue; }
  run_one "$target" "$slot" &
  pids+=($!)
  names+=("$target")
  slot=$(( slot + 1 ))
  if [[ ${#pids[@]} -ge $parallel ]]; then
    wait "${pids[0]}" || failed+=("${names[0]}")
    pids=("${pids[@]:1}")
    names=("${names[@]:1}")
  fi
done
for i in "${!pids[@]}"; do
  wait "${pids[$i]}" || failed+=("${names[$i]}")
done

# One line per target: runs, exec/s, corpus size (libFuzzer's final stats).
printf '%-32s %10s %8s %8s %s\n' target runs exec/s corpus result >&2
for target in "${targets[@]}"; do
  f="$work/$target.log"
  [[ -f "$f" ]] || continue
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$f" | tail -1)
  speed=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$f" | tail -1)
  files=$(find "$work/corpus/$target" -type f | wc -l)
  result=ok
  [[ " ${failed[*]} " == *" $target "* ]] && result=FAILED
  printf '%-32s %10s %8s %8s %s\n' "$target" "${runs:-?}" "${speed:-?}" "$files" "$result" >&2
done
log "runs done in $(( $(date +%s) - run_start )) s, total $(( $(date +%s) - start )) s"

if [[ ${#failed[@]} -gt 0 ]]; then
  for target in "${failed[@]}"; do
    log "$target failed; the end of its log:"
    tail -60 "$work/$target.log" >&2 || true
  done
  exit 1
fi
