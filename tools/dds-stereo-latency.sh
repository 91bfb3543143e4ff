#!/usr/bin/env bash
# The stereo stream's one-way latency against Cyclone's own floor, in one run (issue 26;
# docs/benchmarks.md, "DDS stereo stream"): mav-simulator replays the room-easy preset (752 x 480
# x 2 MONO8) at 20 Hz on loopback to SUBS separate `mavctl listen` processes, once per setting,
# alternating, each ROUNDS times; then Cyclone's ddsperf ping/pong with the same payload at
# Cyclone's default settings, with as many pong processes as subscribers (the issue's yardstick:
# our one-way p99 must not exceed its round-trip p99); then the as-fast-as-subscribers replay
# (frames/s, one subscriber).
#
#   tools/dds-stereo-latency.sh [--frames N] [--rounds R] [--subscribers "1 4"]
#                               [--settings "ours,shm,waitset,normal"] [--seconds S] [--out DIR]
#
# Settings (the issue's levers, each alone off against ours):
#   ours     over UDP on loopback, rendering at SCHED_IDLE (mav-simulator --render-priority
#            idle), frames taken on DDS's receive thread (mavctl listen --wake listener)
#   shm      ours, but over Cyclone's shared-memory transport (MAV_DDS_SHM=1; the listeners
#            keep the last 16 frames, as shared memory needs); starts iceoryx's RouDi with
#            deploy/roudi.toml when none answers at /tmp/roudi, and stops it at the end
#   waitset  ours, but frames taken by a thread woken by a waitset (--wake waitset)
#   normal   ours, but rendering at normal priority (--render-priority normal)
# Prints one markdown row per run and subscriber: one-way p50/p95/p99/max (publish stamp ->
# take), the DDS hop's p50/p99 (dds_write -> take), frames lost, the transport the listener's
# reader got. Then the fast replay once per transport. Needs build/bin (mav-simulator, mavctl),
# ddsperf (Debian's cyclonedds-tools) and, for shm, iox-roudi (Debian's iceoryx).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
frames=1000
rounds=1
subscribers="1 4"
settings="ours,shm,waitset,normal"
seconds=20
out="$(mktemp -d /tmp/mav-dds-latency.XXXXXX)"
while [[ $# -gt 0 ]]; do
  case "$1" in
    --frames) frames="${2:?}"; shift 2 ;;
    --rounds) rounds="${2:?}"; shift 2 ;;
    --subscribers) subscribers="${2:?}"; shift 2 ;;
    --settings) settings="${2:?}"; shift 2 ;;
    --seconds) seconds="${2:?}"; shift 2 ;;
    --out) out="${2:?}"; mkdir -p "$out"; shift 2 ;;
    -h|--help) sed -n '2,24p' "$0"; exit 0 ;;
    *) echo "dds-stereo-latency.sh: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
bin="$repo/build/bin"
for e in mav-simulator mavctl; do
  [[ -x "$bin/$e" ]] || { echo "dds-stereo-latency.sh: $bin/$e is missing: build the tree first" >&2; exit 1; }
done
command -v ddsperf > /dev/null || { echo "dds-stereo-latency.sh: ddsperf not found (Debian's cyclonedds-tools)" >&2; exit 1; }
port=$(( 52000 + $$ % 500 ))
domain=$(( 100 + $$ % 50 ))
pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2> /dev/null || true; done; wait 2> /dev/null || true; }
trap cleanup EXIT

source "$repo/tools/roudi.sh"
if [[ ",$settings," == *,shm,* ]]; then
  start_roudi_unless_running dds-stereo-latency.sh "$out/roudi.log"
  [[ -n "$roudi_pid" ]] && pids+=("$roudi_pid")
fi

start_simulator() {  # $1: render priority, $2: MAV_DDS_SHM (0 or 1)
  MAV_DDS_SHM="$2" "$bin/mav-simulator" --port "$port" --dds-domain "$domain" --render-priority "$1" \
    > "$out/sim.log" 2>&1 &
  sim_pid=$!
  pids+=("$sim_pid")
  for _ in $(seq 100); do "$bin/mavctl" health --port "$port" --timeout 1 > /dev/null 2>&1 && return; sleep 0.1; done
  echo "dds-stereo-latency.sh: mav-simulator did not come up (log: $out/sim.log)" >&2
  exit 1
}

# One run: the preset looped at 20 Hz until every subscriber has FRAMES frames.
stream_run() {  # $1: setting, $2: round, $3: subscribers
  local setting=$1 round=$2 subs=$3 priority=idle wake=listener shm=0
  [[ "$setting" == waitset ]] && wake=waitset
  [[ "$setting" == normal ]] && priority=normal
  [[ "$setting" == shm ]] && shm=1
  start_simulator "$priority" "$shm"
  "$bin/mavctl" sim load --port "$port" --preset room-easy > /dev/null
  local listeners=()
  for i in $(seq "$subs"); do
    MAV_DDS_SHM="$shm" "$bin/mavctl" listen --topic stereo --frames "$frames" --timeout $(( frames / 10 + 60 )) \
      --quiet --wake "$wake" --dds-domain "$domain" > "$out/listen-$setting-$round-$subs-$i.log" 2>&1 &
    listeners+=($!)
  done
  "$bin/mavctl" sim start --port "$port" --rate 1.0 --loop --wait-subscribers "$subs" \
    --wait-timeout 20 > /dev/null
  for p in "${listeners[@]}"; do wait "$p" || true; done
  kill "$sim_pid"; wait "$sim_pid" 2> /dev/null || true
  for i in $(seq "$subs"); do
    python3 - "$out/listen-$setting-$round-$subs-$i.log" "$setting" "$round" "$subs" "$i" "$frames" <<'EOF'
import re, sys
log = open(sys.argv[1]).read()
setting, rnd, subs, i, frames = sys.argv[2], sys.argv[3], sys.argv[4], sys.argv[5], int(sys.argv[6])
lat = re.search(r"p50 ([0-9.]+) ms, p95 ([0-9.]+) ms, p99 ([0-9.]+) ms, max ([0-9.]+) ms", log)
hop = re.search(r"DDS \(dds_write -> take, \w+\) ([0-9.]+) / ([0-9.]+) ms", log)
res = re.search(r"RESULT frames=([0-9]+) missing=([0-9]+)", log)
shm = re.search(r" shm=([01]) ", log)
transport = ("shared memory" if shm.group(1) == "1" else "udp") if shm else "?"
got, missing = (int(res.group(1)), int(res.group(2))) if res else (0, frames)
cells = " / ".join(lat.groups()) if lat else "no frames"
hops = " / ".join(hop.groups()) if hop else ""
print("| %s | %s | %s of %s | %s | %s | %d | %s |" % (setting, rnd, i, subs, cells, hops,
      max(frames - got, 0) + missing, transport))
EOF
  done
}

echo "stereo stream: $frames frames per subscriber at 20 Hz, room-easy, $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)"
echo
echo "| setting | round | subscriber | one-way p50 / p95 / p99 / max ms | DDS hop p50 / p99 ms | lost | transport |"
echo "|---|---:|---:|---|---|---:|---|"
IFS=',' read -r -a setting_list <<< "$settings"
for r in $(seq "$rounds"); do
  for subs in $subscribers; do
    for s in "${setting_list[@]}"; do stream_run "$s" "$r" "$subs"; done
  done
done

echo
for subs in $subscribers; do
  echo "Cyclone's floor: ddsperf ping/pong, 722 KiB at 20 Hz, Cyclone's default settings, $seconds s," \
    "$subs pong process(es) (each answers with a full sample)"
  echo
  "$repo/tools/dds-config-ablation.sh" --seconds "$seconds" --rounds 1 --only default --pongs "$subs"
  echo
done

fast_replay() {  # $1: MAV_DDS_SHM (0 or 1)
  local shm=$1 transport=udp
  [[ "$shm" == 1 ]] && transport="shared memory"
  start_simulator idle "$shm"
  "$bin/mavctl" sim load --port "$port" --preset room-easy --frames 600 > /dev/null
  MAV_DDS_SHM="$shm" "$bin/mavctl" listen --topic stereo --frames 600 --timeout 120 --quiet \
    --dds-domain "$domain" > "$out/listen-fast-$shm.log" 2>&1 &
  local listener=$!
  "$bin/mavctl" sim start --port "$port" --fast --wait-subscribers 1 --wait-timeout 20 > /dev/null
  wait "$listener" || true
  kill "$sim_pid"; wait "$sim_pid" 2> /dev/null || true
  local rate
  rate=$(sed -n 's/.*rate \([0-9.]*\) Hz.*/\1/p' "$out/listen-fast-$shm.log" | head -1)
  echo "fast replay (--fast, one subscriber, 600 frames, rendering at SCHED_IDLE, $transport): ${rate:-?} frames/s"
}
echo
fast_replay 0
[[ ",$settings," == *,shm,* ]] && fast_replay 1
echo "logs: $out"
