#!/usr/bin/env bash
# check-ddsperf.sh - try the DDS Security material of make-certs.sh for real with Cyclone's ddsperf.
#
# Usage: deploy/dds-security/check-ddsperf.sh OUT SCENARIO [LOGDIR]
#   OUT must come from   make-certs.sh OUT --extra-test perf-a --extra-test perf-b \
#                            --extra-expired old --extra-foreign intruder
#   (ddsperf's topics are DDSPerf*; only those test identities are granted them).
# Scenarios (one or two ddsperf processes under nice, at most DUR+5 s):
#   pair         perf-a answers pings (pong), perf-b pings at 20 Hz: roundtrips expected
#   plain        perf-a (pong) and a ddsperf without security (ping): no roundtrips expected
#   plain-rev    a ddsperf without security (pong) and perf-b (ping): no roundtrips expected
#   expired      ddsperf with the expired identity 'old': participant creation must fail
#   foreign      perf-a + perf-b (pong) and 'intruder' (ping; identity from another CA): no
#                roundtrips; the refusals are in the .out files (Cyclone prints them on stderr)
#   denied       ddsperf with mav-planning's identity: its DDSPerf* topics must be refused
#   latency      perf-a pong + perf-b ping of SIZE back to back for DUR s, with OUT's governance
#   latency-off  the same without security (BASE only)
# Each process logs to LOGDIR/NAME.out (stdout+stderr) and, except for the latency runs,
# LOGDIR/NAME.log (Cyclone trace, Verbosity finest). The verdict is printed last; exit 0 when
# the scenario behaved as expected, 1 when not, 2 on a usage error.
# Env: DOMAIN (default 42, away from the stack's default domain 0), DUR (8), SIZE (722k),
#      BASE (default: deploy/cyclonedds.xml next to this directory), DDSPERF (ddsperf).
set -euo pipefail

PROG=${0##*/}
HERE=$(cd -- "$(dirname -- "$0")" && pwd -P)
usage() { printf '%s: %s\n(see the header of %s)\n' "$PROG" "$1" "$0" >&2; exit 2; }
[[ $# -ge 2 ]] || usage "need OUT and SCENARIO"
OUT=$(cd -- "$1" 2>/dev/null && pwd -P) || usage "no directory $1"
SCENARIO=$2
LOGDIR=${3:-$(mktemp -d /tmp/ddssec-check.XXXXXX)}
mkdir -p "$LOGDIR"
DOMAIN=${DOMAIN:-42}
DUR=${DUR:-8}
SIZE=${SIZE:-722k}
BASE=${BASE:-$HERE/../cyclonedds.xml}
BASE=$(cd -- "$(dirname -- "$BASE")" && pwd -P)/$(basename -- "$BASE")
DDSPERF=${DDSPERF:-ddsperf}
[[ -f $BASE ]] || usage "no base config $BASE"
command -v "$DDSPERF" >/dev/null || usage "$DDSPERF not found"

trace_xml() {  # trace_xml LOGFILE: inline config fragment turning on the full Cyclone trace
  printf '<CycloneDDS><Domain id="any"><Tracing><Verbosity>finest</Verbosity><OutputFile>%s</OutputFile></Tracing></Domain></CycloneDDS>' "$1"
}
uri() {  # uri IDENTITY|- [trace]: CYCLONEDDS_URI for an identity of OUT ("-": no security)
  local u="file://$BASE"
  [[ $1 == - ]] || u+=",file://$OUT/$1/security.xml"
  [[ ${2:-} != trace ]] || u+=",$(trace_xml "$LOGDIR/${3:?}.log")"
  printf '%s' "$u"
}
case $SCENARIO in
  latency-off) NEED=();;
  pair|latency) NEED=(perf-a perf-b);;
  plain) NEED=(perf-a);;
  plain-rev) NEED=(perf-b);;
  expired) NEED=(old);;
  foreign) NEED=(perf-a perf-b intruder);;
  denied) NEED=(mav-planning);;
  *) usage "unknown scenario $SCENARIO";;
esac
for id in ${NEED[@]+"${NEED[@]}"}; do
  [[ -f $OUT/$id/security.xml ]] || usage "$OUT/$id/security.xml missing (see the usage for how to make OUT)"
done

PIDS=()
start() {  # start NAME URI ARGS...: ddsperf in the background
  local name=$1 u=$2
  shift 2
  CYCLONEDDS_URI=$u nice -n 10 timeout -s INT $((DUR + 5)) "$DDSPERF" -i "$DOMAIN" -D "$DUR" "$@" \
    >"$LOGDIR/$name.out" 2>&1 &
  PIDS+=("$!")
}
wait_all() {  # wait_all: wait for the started processes; their exit codes in RCS
  RCS=()
  local p
  for p in "${PIDS[@]}"; do
    if wait "$p"; then RCS+=(0); else RCS+=($?); fi
  done
  PIDS=()
}
cleanup() { local p; for p in ${PIDS[@]+"${PIDS[@]}"}; do kill -INT "$p" 2>/dev/null || true; done; }
trap cleanup EXIT

verdict() {  # verdict OK|FAIL TEXT
  printf '%s: %s: %s (logs in %s)\n' "$SCENARIO" "$1" "$2" "$LOGDIR"
  [[ $1 == OK ]]
}
# roundtrips NAME: pongs the ping side got, summed over its per-second latency lines
#   ([pid] 1.000  host:pid size 12 mean 289us min 214us 50% 260us 90% 353us 99% 824us max 824us cnt 17)
roundtrips() {
  awk '/ size [0-9]+ mean / { for (i = 1; i < NF; i++) if ($i == "cnt") n += $(i + 1) } END { print n + 0 }' \
    "$LOGDIR/$1.out"
}

case $SCENARIO in
  pair)
    start pong "$(uri perf-a trace pong)" pong
    sleep 1
    start ping "$(uri perf-b trace ping)" ping 20Hz
    wait_all
    n=$(roundtrips ping)
    if [[ $n -gt 0 ]]; then verdict OK "perf-b (ping) got $n pongs from perf-a"
    else verdict FAIL "no roundtrips between perf-a and perf-b"; fi;;
  plain|plain-rev|foreign)
    if [[ $SCENARIO == plain ]]; then a=perf-a b=-
    elif [[ $SCENARIO == plain-rev ]]; then a=- b=perf-b
    else a=perf-a b=intruder; fi
    start pong "$(uri "$a" trace pong)" pong
    # The participant with the smaller GUID prefix (a hash of the certificate subject) starts
    # the handshake and the other one checks its certificate first: with perf-a and perf-b
    # both present, one of them gets to verify (and refuse) the intruder's certificate.
    [[ $SCENARIO != foreign ]] || start pong2 "$(uri perf-b trace pong2)" pong
    sleep 1
    start ping "$(uri "$b" trace ping)" ping 20Hz
    wait_all
    n=$(roundtrips ping)
    if [[ $n -eq 0 ]]; then verdict OK "no roundtrips between '$a' and '$b' ('-' = no security)"
    else verdict FAIL "'$a' and '$b' exchanged data ($n roundtrips)"; fi;;
  expired|denied)
    if [[ $SCENARIO == expired ]]; then id=old; else id=mav-planning; fi
    start solo "$(uri "$id" trace solo)" pong
    wait_all
    if [[ ${RCS[0]} -ne 0 ]]; then verdict OK "ddsperf with identity '$id' refused (exit ${RCS[0]}): $(grep -m1 -iE 'fail|denied|error' "$LOGDIR/solo.out" || true)"
    else verdict FAIL "ddsperf with identity '$id' ran"; fi;;
  latency|latency-off)
    if [[ $SCENARIO == latency ]]; then a=perf-a b=perf-b; else a=- b=-; fi
    start pong "$(uri "$a")" pong
    sleep 1
    start ping "$(uri "$b")" ping size "$SIZE"
    wait_all
    cat "$LOGDIR/ping.out"
    verdict OK "see the ping lines above";;
  *) usage "unknown scenario $SCENARIO";;
esac
