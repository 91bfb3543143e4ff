#!/usr/bin/env bash
# Runs clang-tidy (Debian's clang-tidy 14, config in .clang-tidy) over the tree's own .cc files
# listed in a build's compile_commands.json, in parallel, and exits non-zero on any finding.
#
#   tools/run-clang-tidy.sh [--build-dir DIR] [--jobs N] [--all] [--since REV] [PATH...]
#
# Scope (which sources are checked; headers under libs/, services/, clients/ and tests/ are
# reported through the sources that include them):
#   default     libs/ clients/mav-sim/ clients/mav-eval/ tests/unit/  (the part kept at zero)
#   --all       the default plus services/ clients/ (mavctl, mav-load, common, plot) tests/contract/
#               tests/integration/ tests/load/
#   PATH...     only these sources, or those under these directories (relative to the root)
#   --since REV of the scope, only the sources changed since commit REV (git diff REV, committed
#               and not) and those that include a header changed since then. CI runs this with
#               the commit of tools/clang-tidy-clean, where the whole tree (--all) was last
#               checked with zero findings: a full run takes ~20 min on 2 cores, more than CI's
#               budget for this stage (docs/quality.md). Without REV in the history (a shallow
#               clone): the whole scope.
# The build directory must be configured (cmake writes compile_commands.json) and, for
# services/, built far enough that the generated protobuf/IDL headers exist.
#
# Output: every finding once, one line each (a header's finding is reported for each source that
# includes it; duplicates are dropped), then a count; run clang-tidy -p BUILD FILE for the
# details of one. Exit status: 0 no finding, 1 findings, 2 usage/setup.
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build_dir="$repo/build"
jobs=2
scope=(libs clients/mav-sim clients/mav-eval tests/unit)
explicit=()
since=""

while [[ $# -gt 0 ]]; do
  case "$1" in
    --build-dir) build_dir="$(cd "$2" && pwd)"; shift 2 ;;
    --jobs|-j) jobs="$2"; shift 2 ;;
    --all) scope+=(services clients/mavctl clients/mav-load clients/common clients/plot tests/contract
                   tests/integration tests/load); shift ;;
    --since) since="$2"; shift 2 ;;
    -h|--help) sed -n '2,24p' "$0"; exit 0 ;;
    -*) echo "run-clang-tidy.sh: unknown flag '$1' (try --help)" >&2; exit 2 ;;
    *) explicit+=("${1%/}"); shift ;;
  esac
done
[[ ${#explicit[@]} -gt 0 ]] && scope=("${explicit[@]}")

command -v clang-tidy >/dev/null ||
  "$repo/deploy/setup.sh" --packages "$repo/deploy/packages-quality.txt" --no-build
tidy="$(command -v clang-tidy-14 || command -v clang-tidy || true)"
[[ -n "$tidy" ]] || { echo "run-clang-tidy.sh: clang-tidy not found (apt-get install clang-tidy)" >&2; exit 2; }
db="$build_dir/compile_commands.json"
[[ -f "$db" ]] || { echo "run-clang-tidy.sh: $db missing (configure with cmake first)" >&2; exit 2; }

# The sources of the database that lie under the scope (CMake writes one "file" per entry).
pattern="$(printf '%s|' "${scope[@]}")"
mapfile -t files < <(sed -n 's/^ *"file": "\(.*\)",*$/\1/p' "$db" | sort -u |
  grep -E "^$repo/(${pattern%|})(/|$)" | grep -E '\.cc$' || true)
if [[ ${#files[@]} -eq 0 ]]; then
  echo "run-clang-tidy.sh: no source of $db under: ${scope[*]}" >&2
  exit 2
fi

if [[ -n "$since" ]]; then
  if git -C "$repo" rev-parse -q --verify "$since^{commit}" >/dev/null; then
    mapfile -t changed < <(git -C "$repo" diff --name-only "$since" -- '*.cc' '*.h' | sort -u)
    keep=()
    for f in "${files[@]}"; do
      rel="${f#"$repo"/}"
      hit=0
      for c in "${changed[@]}"; do
        if [[ "$c" == "$rel" ]]; then hit=1; break; fi
        # A changed header: the sources that include it (by its file name).
        if [[ "$c" == *.h ]] && grep -qE "#include [\"<]([^\">]*/)?$(basename "$c")[\">]" "$f"; then
          hit=1
          break
        fi
      done
      [[ $hit -eq 1 ]] && keep+=("$f")
    done
    echo "clang-tidy: ${#changed[@]} sources/headers changed since ${since:0:12}: ${#keep[@]} of ${#files[@]} sources to check" >&2
    if [[ ${#keep[@]} -eq 0 ]]; then
      echo "clang-tidy: 0 finding(s): nothing changed in scope" >&2
      exit 0
    fi
    files=("${keep[@]}")
  else
    echo "clang-tidy: commit $since not in this clone's history: checking the whole scope" >&2
  fi
fi

out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
echo "clang-tidy: ${#files[@]} files under ${scope[*]} with $jobs jobs ($("$tidy" --version | sed -n 's/.*version \([0-9.]*\).*/\1/p' | head -1))" >&2
start=$(date +%s)
# One log per source; a crash of clang-tidy itself counts as a finding.
printf '%s\n' "${files[@]}" | xargs -P "$jobs" -I{} sh -c '
  log="$2/$(echo "$1" | tr / _).log"
  "$3" -p "$4" --quiet "$1" >"$log" 2>&1 || echo "$1: error: clang-tidy exited with status $?" >>"$log"
' _ {} "$out" "$tidy" "$build_dir"

# A finding is a "path:line:col: warning|error: ... [check]" line; keep its note lines out.
cat "$out"/*.log | grep -E '^[^ ].*:[0-9]+:[0-9]+: (warning|error): |: error: clang-tidy exited' |
  sort -u >"$out/findings" || true
count=$(wc -l <"$out/findings")
cat "$out/findings"
echo "clang-tidy: $count finding(s) in ${#files[@]} files, $(( $(date +%s) - start )) s" >&2
[[ $count -eq 0 ]]
