#!/usr/bin/env bash
# Which setting of deploy/cyclonedds.xml costs what on a stereo-sized sample (issue: DDS stereo at
# Cyclone's own latency; docs/benchmarks.md, "DDS transport"). Cyclone's own ddsperf, ping/pong
# between two processes on loopback (pinned to different cores), one 722 KiB sample at 20 Hz,
# once per configuration, alternating, each ROUNDS times:
#
#   default        no configuration (Cyclone's defaults, its own choice of interface)
#   lo             the loopback interface and unicast discovery only (as ours)
#   ours           deploy/cyclonedds.xml
#   ours-frag      ours without MaxMessageSize/FragmentSize (Cyclone's 14720 B / 1344 B)
#   ours-buffers   ours without the socket buffer sizes
#   ours-heartbeat ours without HeartbeatInterval
#   ours-whc       ours without WhcHigh
#
#   tools/dds-config-ablation.sh [--seconds S] [--rounds R] [--size 722k] [--only NAME,...]
#                                [--pongs N]
#
# --pongs N  N pong processes answer each ping (Cyclone's own floor for a stream with N
#            subscribers; each answer is a full sample back, so a round trip carries N of them).
#            With N > 1 no process is pinned: N + 1 processes share the cores, as a stream's
#            subscribers do.
#
# Prints one row per run: the round trip's median over its one-second p50s, the mean and the
# largest of its one-second p99s, and the samples (ddsperf reports per second and per pong, not
# per sample).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
seconds=15
rounds=2
size=722k
only=""
pongs=1
while [[ $# -gt 0 ]]; do
  case "$1" in
    --seconds) seconds="${2:?}"; shift 2 ;;
    --rounds) rounds="${2:?}"; shift 2 ;;
    --size) size="${2:?}"; shift 2 ;;
    --only) only="${2:?}"; shift 2 ;;
    --pongs) pongs="${2:?}"; shift 2 ;;
    -h|--help) sed -n '2,26p' "$0"; exit 0 ;;
    *) echo "dds-config-ablation.sh: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
[[ "$pongs" =~ ^[1-9][0-9]*$ ]] || { echo "dds-config-ablation.sh: --pongs: a count >= 1, got '$pongs'" >&2; exit 2; }
command -v ddsperf > /dev/null || { echo "dds-config-ablation.sh: ddsperf not found (Debian's cyclonedds-tools)" >&2; exit 1; }
work="$(mktemp -d /tmp/mav-dds-ablation.XXXXXX)"
pong_pids=()
cleanup() {
  [[ ${#pong_pids[@]} -gt 0 ]] && kill "${pong_pids[@]}" 2> /dev/null
  wait 2> /dev/null || true
  rm -rf "$work"
}
trap cleanup EXIT

ours="$repo/deploy/cyclonedds.xml"
without() {  # without NAME PATTERN...: ours minus the lines matching each pattern
  local name="$1"; shift
  cp "$ours" "$work/$name.xml"
  for p in "$@"; do sed -i "/$p/d" "$work/$name.xml"; done
}
cat > "$work/lo.xml" <<'XML'
<CycloneDDS xmlns="https://cdds.io/config"><Domain id="any"><General><Interfaces><NetworkInterface name="lo" multicast="false"/></Interfaces><AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>32</MaxAutoParticipantIndex><Peers><Peer address="127.0.0.1"/></Peers></Discovery></Domain></CycloneDDS>
XML
cp "$ours" "$work/ours.xml"
without ours-frag '<MaxMessageSize>' '<FragmentSize>'
without ours-buffers '<SocketReceiveBufferSize' '<SocketSendBufferSize'
without ours-heartbeat '<HeartbeatInterval>'
without ours-whc '<WhcHigh>' '<Watermarks>' '<\/Watermarks>'
configs=(default lo ours ours-frag ours-buffers ours-heartbeat ours-whc)
if [[ -n "$only" ]]; then IFS=, read -r -a configs <<< "$only"; fi

domain=$(( 200 + $$ % 30 ))
echo "| config | round | rtt p50 (median of 1 s) | rtt p99 (mean of 1 s) | rtt p99 (worst 1 s) | samples |"
echo "|---|---:|---:|---:|---:|---:|"
for round in $(seq "$rounds"); do
  for c in "${configs[@]}"; do
    uri=""
    [[ "$c" == default ]] || uri="file://$work/$c.xml"
    pin_pong=(taskset -c 1) pin_ping=(taskset -c 0)
    [[ "$pongs" -gt 1 ]] && pin_pong=() pin_ping=()
    for p in $(seq "$pongs"); do
      CYCLONEDDS_URI="$uri" "${pin_pong[@]}" ddsperf -i "$domain" -D $(( seconds + 3 )) pong \
        > "$work/pong-$p.log" 2>&1 &
      pong_pids+=($!)
    done
    sleep $(( pongs > 1 ? 1 : 0 )).5
    CYCLONEDDS_URI="$uri" "${pin_ping[@]}" ddsperf -i "$domain" -D "$seconds" ping 20Hz size "$size" \
      > "$work/ping-$c-$round.log" 2>&1 || true
    kill "${pong_pids[@]}" 2> /dev/null || true
    wait "${pong_pids[@]}" 2> /dev/null || true
    pong_pids=()
    # Per-second lines: "... size N mean Xus min Xus 50% Xus 90% Xus 99% Xus max Xus cnt N".
    # mawk has no sort: the p50s are sorted by sort(1) and their median taken from the list.
    p50s="$(grep -oE ' 50% [0-9.]+us' "$work/ping-$c-$round.log" | sed -E 's/ 50% ([0-9.]+)us/\1/' | sort -g | tr '\n' ' ')"
    awk -v c="$c" -v r="$round" -v p50s="$p50s" '
      / size [0-9]+ mean / {
        for (i = 1; i <= NF; ++i) { if ($i == "99%") p99 = $(i + 1) + 0; if ($i == "cnt") cnt += $(i + 1) }
        s99 += p99; if (p99 > w99) w99 = p99; ++n
      }
      END {
        if (n == 0) { printf "| %s | %d | no samples | | | 0 |\n", c, r; exit }
        m = split(p50s, v, " ")
        printf "| %s | %d | %.2f ms | %.2f ms | %.2f ms | %d |\n", c, r, v[int((m + 1) / 2)] / 1000, s99 / n / 1000, w99 / 1000, cnt
      }' "$work/ping-$c-$round.log"
  done
done
