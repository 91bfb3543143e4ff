#!/usr/bin/env bash
# What one vehicle costs (issue 26, docs/benchmarks.md "Load at scale"): the services on this
# machine fly a mission with vision in the loop (mavctl mission run, lock-stepped through the
# services, 20 Hz stereo, 200 Hz IMU), and each service's CPU time (utime + stime from /proc) is
# divided by the mission's simulated time: CPU seconds per second of flight at 20 Hz.
#
#   tools/vehicle-cost.sh [--mission missions/room_hover.yaml] [--map truth|online] [--seed 1]
#                         [--dds-shm] [--out DIR]
#
# --dds-shm  the services' data plane in shared memory (MAV_DDS_SHM=1; docs/services.md): starts
#            iceoryx's RouDi with deploy/roudi.toml when none answers at /tmp/roudi, and stops
#            it at the end.
#
# Prints one markdown row per service and the mission's own report line. Needs build/bin.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
mission="$repo/missions/room_hover.yaml"
map=truth
seed=1
out="$(mktemp -d /tmp/mav-vehicle-cost.XXXXXX)"
while [[ $# -gt 0 ]]; do
  case "$1" in
    --mission) mission="${2:?}"; shift 2 ;;
    --map) map="${2:?}"; shift 2 ;;
    --seed) seed="${2:?}"; shift 2 ;;
    --dds-shm) export MAV_DDS_SHM=1; shift ;;
    --out) out="${2:?}"; mkdir -p "$out"; shift 2 ;;
    -h|--help) sed -n '2,14p' "$0"; exit 0 ;;
    *) echo "vehicle-cost.sh: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
bin="$repo/build/bin"
services=(mav-simulator mav-localization mav-planning mav-control)
[[ "$map" == online ]] && services+=(mav-mapping)
for e in "${services[@]}" mavctl; do
  [[ -x "$bin/$e" ]] || { echo "vehicle-cost.sh: $bin/$e is missing: build the tree first" >&2; exit 1; }
done
domain=$(( 160 + $$ % 40 ))
base=$(( 53000 + ($$ % 100) * 10 ))
declare -A port=([mav-simulator]=$base [mav-localization]=$((base + 1)) [mav-mapping]=$((base + 2))
                 [mav-planning]=$((base + 3)) [mav-control]=$((base + 4)))
declare -A pid=()
cleanup() { for p in "${pid[@]}"; do kill "$p" 2> /dev/null || true; done; wait 2> /dev/null || true; }
trap cleanup EXIT
source "$repo/tools/roudi.sh"
if [[ "${MAV_DDS_SHM:-0}" == 1 ]]; then
  start_roudi_unless_running vehicle-cost.sh "$out/iox-roudi.log"
  [[ -n "$roudi_pid" ]] && pid[iox-roudi]=$roudi_pid
fi
for s in "${services[@]}"; do
  "$bin/$s" --port "${port[$s]}" --dds-domain "$domain" > "$out/$s.log" 2>&1 &
  pid[$s]=$!
done
for s in "${services[@]}"; do
  for _ in $(seq 150); do "$bin/mavctl" health --port "${port[$s]}" --timeout 1 > /dev/null 2>&1 && break; sleep 0.1; done
done
cpu_s() { awk -v hz="$(getconf CLK_TCK)" '{ sub(/.*\) /, ""); print ($12 + $13) / hz }' "/proc/$1/stat"; }
declare -A before=()
for s in "${services[@]}"; do before[$s]=$(cpu_s "${pid[$s]}"); done
args=(--mission "$mission" --seed "$seed" --pose-source vo --map "$map" --quiet --json "$out/report.json"
      --simulator "127.0.0.1:${port[mav-simulator]}" --localization "127.0.0.1:${port[mav-localization]}"
      --planning "127.0.0.1:${port[mav-planning]}" --control "127.0.0.1:${port[mav-control]}")
[[ "$map" == online ]] && args+=(--mapping "127.0.0.1:${port[mav-mapping]}")
start=$(date +%s.%N)
"$bin/mavctl" mission run "${args[@]}" > "$out/mission.txt" 2>&1 || echo "(the mission failed: $out/mission.txt)"
wall=$(awk -v a="$(date +%s.%N)" -v b="$start" 'BEGIN { printf "%.1f", a - b }')
# The mapping service's own timings (per keyframe, per rebuild), before it is stopped.
[[ "$map" == online ]] && "$bin/mavctl" map status --port "${port[mav-mapping]}" > "$out/map-status.txt" 2>&1
sim_s=$(python3 -c "import json,sys; print(json.load(open('$out/report.json'))['sim_time_s'])" 2> /dev/null ||
        sed -n 's/.*in \([0-9.]*\) s simulated.*/\1/p' "$out/mission.txt" | head -1)
echo "mission $(basename "$mission"), map $map, seed $seed, data plane $([[ "${MAV_DDS_SHM:-0}" == 1 ]] && echo "in shared memory" || echo "over UDP"): ${sim_s} s simulated in ${wall} s wall ($(nproc) cores)"
echo
echo "| service | CPU s | CPU s per flight s (20 Hz) | ms per frame |"
echo "|---|---:|---:|---:|"
total=0
for s in "${services[@]}"; do
  used=$(awk -v a="$(cpu_s "${pid[$s]}")" -v b="${before[$s]}" 'BEGIN { print a - b }')
  total=$(awk -v a="$total" -v b="$used" 'BEGIN { print a + b }')
  awk -v s="$s" -v u="$used" -v t="$sim_s" 'BEGIN { printf "| %s | %.2f | %.3f | %.2f |\n", s, u, u / t, 1000 * u / (t * 20) }'
done
awk -v u="$total" -v t="$sim_s" 'BEGIN { printf "| all | %.2f | %.3f | %.2f |\n", u, u / t, 1000 * u / (t * 20) }'
grep -E "vision latency|localization  |online map" "$out/mission.txt" || true
echo "logs: $out"
