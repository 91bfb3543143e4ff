#!/usr/bin/env bash
# The price of DDS Security on the stereo stream (docs/benchmarks.md, "DDS Security"): the same
# room-easy stream (752 x 480 x 2 MONO8, 20 Hz) from mav-simulator to `mavctl listen` on
# loopback, separate processes, once per protection level, alternating, each ROUNDS times:
#
#   off       no DDS Security
#   NONE      authentication and access control only (make-certs.sh --protection NONE)
#   SIGN      every RTPS message, submessage and payload authenticated (AES-GCM GMAC)
#   ENCRYPT   everything encrypted and authenticated (AES-GCM): make-certs.sh's default
#   ENC-DATA  only the payload encrypted (--protection ENCRYPT --rtps-protection NONE
#             --metadata-protection NONE)
#
#   deploy/dds-security/measure-price.sh [--frames N] [--rounds R] [--cpus 0,1] [--out DIR]
#
# Prints one markdown row per run: one-way latency (the frame's publish wall clock to its
# arrival, as mavctl listen measures it: p50/p95/p99/max), frames lost, and the CPU time of the
# publisher (mav-simulator: its rendering included, the same in every run) and of the
# subscriber, per frame. Needs build/bin (mav-simulator, mavctl) and openssl.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
frames=200
rounds=2
cpus=0,1
out="$(mktemp -d /tmp/mav-dds-price.XXXXXX)"
while [[ $# -gt 0 ]]; do
  case "$1" in
    --frames) frames="${2:?}"; shift 2 ;;
    --rounds) rounds="${2:?}"; shift 2 ;;
    --cpus) cpus="${2:?}"; shift 2 ;;
    --out) out="${2:?}"; mkdir -p "$out"; shift 2 ;;
    -h|--help) sed -n '2,18p' "$0"; exit 0 ;;
    *) echo "measure-price.sh: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
bin="$repo/build/bin"
for e in mav-simulator mavctl; do
  [[ -x "$bin/$e" ]] || { echo "measure-price.sh: $bin/$e is missing: build the tree first" >&2; exit 1; }
done
port=$(( 51000 + $$ % 500 ))
domain=$(( 150 + $$ % 50 ))
sim_pid=""
cleanup() { [[ -n "$sim_pid" ]] && kill "$sim_pid" 2> /dev/null; wait 2> /dev/null || true; }
trap cleanup EXIT

declare -A certs=(
  [NONE]="--protection NONE"
  [SIGN]="--protection SIGN"
  [ENCRYPT]="--protection ENCRYPT"
  [ENC-DATA]="--protection ENCRYPT --rtps-protection NONE --metadata-protection NONE"
)
modes=(off NONE SIGN ENCRYPT ENC-DATA)
for m in "${modes[@]:1}"; do
  # shellcheck disable=SC2086  # the flags are words
  "$repo/deploy/dds-security/make-certs.sh" "$out/$m" ${certs[$m]} > "$out/make-certs-$m.log" 2>&1 ||
    { echo "measure-price.sh: make-certs.sh $m failed (log: $out/make-certs-$m.log)" >&2; exit 1; }
done

cpu_s() {  # utime + stime of PID in seconds
  awk -v hz="$(getconf CLK_TCK)" '{ sub(/.*\) /, ""); print ($12 + $13) / hz }' "/proc/$1/stat"
}

echo "| mode | round | latency p50 / p95 / p99 / max ms | frames lost | publisher CPU ms/frame | subscriber CPU ms/frame |"
echo "|---|---:|---|---:|---:|---:|"
for r in $(seq "$rounds"); do
  for m in "${modes[@]}"; do
    sim_sec=() listen_sec=()
    if [[ "$m" != off ]]; then
      sim_sec=(--dds-security "$out/$m/mav-simulator")
      listen_sec=(--dds-security "$out/$m/mavctl")
    fi
    taskset -c "$cpus" "$bin/mav-simulator" --port "$port" --dds-domain "$domain" "${sim_sec[@]}" \
      > "$out/sim-$m-$r.log" 2>&1 &
    sim_pid=$!
    for _ in $(seq 100); do "$bin/mavctl" health --port "$port" --timeout 1 > /dev/null 2>&1 && break; sleep 0.1; done
    "$bin/mavctl" sim load --port "$port" --preset room-easy --frames "$frames" > /dev/null
    taskset -c "$cpus" "$bin/mavctl" listen --topic stereo --frames "$frames" --timeout 60 \
      --dds-domain "$domain" "${listen_sec[@]}" > "$out/listen-$m-$r.log" 2>&1 &
    listen_pid=$!
    sleep 1
    sim_before=$(cpu_s "$sim_pid")
    listen_before=$(cpu_s "$listen_pid")
    "$bin/mavctl" sim start --port "$port" --rate 1.0 --wait-subscribers 1 > /dev/null
    # The subscriber's CPU just before it exits: poll until its report is written.
    listen_after="$listen_before"
    while kill -0 "$listen_pid" 2> /dev/null; do
      listen_after=$(cpu_s "$listen_pid" 2> /dev/null || echo "$listen_after")
      sleep 0.2
    done
    wait "$listen_pid" || true
    sim_after=$(cpu_s "$sim_pid")
    kill "$sim_pid"; wait "$sim_pid" 2> /dev/null || true; sim_pid=""
    python3 - "$out/listen-$m-$r.log" "$m" "$r" "$frames" "$sim_before" "$sim_after" \
      "$listen_before" "$listen_after" <<'EOF'
import re, sys
log, mode, rnd, frames = open(sys.argv[1]).read(), sys.argv[2], sys.argv[3], int(sys.argv[4])
sb, sa, lb, la = map(float, sys.argv[5:9])
lat = re.search(r"p50 ([0-9.]+) ms, p95 ([0-9.]+) ms, p99 ([0-9.]+) ms, max ([0-9.]+) ms", log)
got = re.search(r"stereo: +([0-9]+) frames", log) or re.search(r"([0-9]+) frames", log)
n = int(got.group(1)) if got else 0
cells = " / ".join(lat.groups()) if lat else "no frames"
print("| %s | %s | %s | %d | %.2f | %.2f |" % (mode, rnd, cells, frames - n,
      1e3 * (sa - sb) / max(n, 1), 1e3 * (la - lb) / max(n, 1)))
EOF
  done
done
