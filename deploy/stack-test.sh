#!/usr/bin/env bash
# The stack in containers, end to end (docs/deploy.md). One command on a fresh Debian 12 machine:
#
#   deploy/stack-test.sh [--prebuilt] [--smoke] [--no-dds-security | --dds-shm] [--load-seconds S]
#                        [--out DIR]
#
#  1. installs podman, runc, docker-compose and debootstrap when missing and writes the podman
#     settings these machines need (/etc/containers/containers.conf.d/50-mav-stack.conf);
#  2. builds the host tree (deploy/setup.sh: mavctl and mav-load run from the host, and the load
#     tests' bare processes) and makes the debian:bookworm base image with debootstrap when podman
#     has none (no registry is reachable here);
#  3. builds the image mav-stack:latest from the sources (deploy/Dockerfile), or around the host's
#     executables with --prebuilt (deploy/Dockerfile.prebuilt); checks its size and libraries;
#  4. makes the DDS Security certificates (deploy/dds-security/make-certs.sh: an identity per
#     program, ENCRYPT), docker-compose up -d with deploy/compose.security.yml (each service on
#     its own identity), then waits for every service's health check;
#  5. flies missions/room_survey.yaml from the compose mission client: it must complete; while it
#     flies, a `mavctl listen` from the host without credentials must receive no stereo frame,
#     and one with mavctl's identity must;
#  6. SIGKILLs mav-localization's process; podman's restart policy must bring it back healthy,
#     and a second mission (the host's mavctl) must complete;
#  7. load tests: mav-load against every service, in its container and as a bare process
#     (OUT/load.md, OUT/load/*.json);
#  8. three planning replicas (deploy/compose.replicas.yml) behind round_robin: the spread, and a
#     replica SIGKILLed under load;
#  9. tears everything down: no container, volume or podman socket of this run is left.
# It prints a table of the stages with their times (also in OUT/stages.txt).
#
# --prebuilt     pack the executables of build/ instead of compiling in the image (CI)
# --smoke        stages 1-6 and 9 only (implies --prebuilt): what CI runs
# --no-dds-security  the data plane without DDS Security (docker-compose.yml alone)
# --dds-shm      the data plane in shared memory (deploy/compose.shm.yml: RouDi in a container,
#                the services in its IPC namespace; implies --no-dds-security). Stage 5 then runs
#                a listener in shared memory beside the mission instead of the credential checks,
#                and stage 6 SIGKILLs RouDi too: it and every service in its memory must restart.
# --load-seconds seconds per load run (default 20)
# --out DIR      reports and logs (default out/stack-test)
# Environment: MAV_SIM_PORT, MAV_LOCALIZATION_PORT, MAV_MAPPING_PORT, MAV_PLANNING_PORT,
# MAV_CONTROL_PORT (50051-50055), MAV_PLANNING_PORT_2/_3 (50064, 50074), MAV_DDS_DOMAIN (a free
# one is drawn), DEBIAN_MIRROR (the one apt uses), CPUS (cores the services and the load run
# on, default 0,1), MAV_STACK_PROJECT (the compose project, default mavstack).
# Exit status 0 when every stage passed; 1 when one failed (named, with its service's log);
# 2 on a usage error.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$repo"

prebuilt=0
smoke=0
dds_security=1
dds_shm=0
load_seconds=20
out="$repo/out/stack-test"
while [[ $# -gt 0 ]]; do
  case "$1" in
    --prebuilt) prebuilt=1; shift ;;
    --smoke) smoke=1; prebuilt=1; shift ;;
    --load-seconds) load_seconds="${2:?--load-seconds needs a value}"; shift 2 ;;
    --out) out="${2:?--out needs a value}"; shift 2 ;;
    --no-dds-security) dds_security=0; shift ;;
    --dds-shm) dds_shm=1; dds_security=0; shift ;;
    -h|--help) sed -n '2,43p' "$0"; exit 0 ;;
    *) echo "stack-test.sh: unknown argument '$1' (try --help)" >&2; exit 2 ;;
  esac
done
[[ "$load_seconds" =~ ^[0-9]+$ && "$load_seconds" -ge 1 ]] ||
  { echo "stack-test.sh: --load-seconds: expected a whole number of seconds >= 1" >&2; exit 2; }

export MAV_SIM_PORT="${MAV_SIM_PORT:-50051}"
export MAV_LOCALIZATION_PORT="${MAV_LOCALIZATION_PORT:-50052}"
export MAV_MAPPING_PORT="${MAV_MAPPING_PORT:-50053}"
export MAV_PLANNING_PORT="${MAV_PLANNING_PORT:-50054}"
export MAV_CONTROL_PORT="${MAV_CONTROL_PORT:-50055}"
export MAV_PLANNING_PORT_2="${MAV_PLANNING_PORT_2:-50064}"
export MAV_PLANNING_PORT_3="${MAV_PLANNING_PORT_3:-50074}"
# A DDS domain of its own keeps this run apart from anything else on the machine.
export MAV_DDS_DOMAIN="${MAV_DDS_DOMAIN:-$(( ($$ % 100) + 120 ))}"
cpus="${CPUS:-0,1}"
# The compose project: its containers, volume and teardown are this run's alone.
project="${MAV_STACK_PROJECT:-mavstack}"
[[ "$project" =~ ^[a-z0-9][a-z0-9_-]*$ ]] ||
  { echo "stack-test.sh: MAV_STACK_PROJECT: '$project' is not a compose project name ([a-z0-9_-])" >&2; exit 2; }
image=mav-stack:latest
bin="$repo/build/bin"
# The stack's files (with DDS Security unless --no-dds-security), and the replicas' on top.
base_files=(-f "$repo/docker-compose.yml")
[[ $dds_security -eq 1 ]] && base_files+=(-f "$repo/deploy/compose.security.yml")
[[ $dds_shm -eq 1 ]] && base_files+=(-f "$repo/deploy/compose.shm.yml")
compose_files=("${base_files[@]}" -f "$repo/deploy/compose.replicas.yml")
mkdir -p "$out/logs" "$out/load"
work="$(mktemp -d /tmp/mav-stack-test.XXXXXX)"

# ---------------------------------------------------------------------------------------------
# Reporting: every stage is timed and listed at the end, passed or not.
rows=()
stage_name=""
stage_start=0
bold() { printf '\n\033[1m== %s\033[0m\n' "$*"; }
begin() {
  stage_name="$1"
  stage_start=$(date +%s)
  bold "$1"
}
row() {  # row NAME RESULT START_S NOTE: a line of the table, timed from START_S
  rows+=("$(printf '%-52s %-6s %6d s  %s' "$1" "$2" "$(( $(date +%s) - $3 ))" "$4")")
}
close_stage() {  # close_stage RESULT NOTE: the open stage's line, when a stage is open
  if [[ -n "$stage_name" ]]; then row "$stage_name" "$1" "$stage_start" "$2"; fi
  stage_name=""
}
end() { close_stage ok "${1:-}"; }  # end [NOTE]
print_table() {
  {
    printf '\n%-52s %-6s %8s  %s\n' stage result time note
    printf '%s\n' "${rows[@]}"
  } | tee "$out/stages.txt"
}
fail() {  # fail MESSAGE [SERVICE]: names the failed stage, shows the service's log, exits 1
  echo "stack-test.sh: $1" >&2
  if [[ -n "${2:-}" ]]; then
    echo "--- last lines of $2's log (podman logs --tail 30 ${project}_${2}_1):" >&2
    podman logs --tail 30 "${project}_${2}_1" >&2 2>&1 || true
  fi
  close_stage FAILED "$1"
  exit 1
}

# ---------------------------------------------------------------------------------------------
# Teardown, on every exit: the stack's containers and volume, bare processes, the podman socket
# this run started, the temporary files. Then a check that nothing is left.
bare_pids=()
service_pid=""
socket_dir=""
teardown() {
  local rc=$?
  trap - EXIT INT TERM
  close_stage FAILED interrupted
  bold "teardown"
  local t0
  t0=$(date +%s)
  for pid in "${bare_pids[@]}"; do kill "$pid" 2>/dev/null || true; done
  for pid in "${bare_pids[@]}"; do wait "$pid" 2>/dev/null || true; done
  if command -v podman > /dev/null; then
    if [[ -n "${DOCKER_HOST:-}" ]] && command -v docker-compose > /dev/null; then
      docker-compose -p "$project" "${compose_files[@]}" --profile mission down -v \
        --remove-orphans > "$out/logs/compose-down.log" 2>&1 || true
    fi
    # Whatever compose could not remove (a socket that died, say).
    podman ps -aq --filter "label=com.docker.compose.project=$project" | xargs -r podman rm -f > /dev/null 2>&1 || true
    podman volume ls -q | grep "^${project}_" | xargs -r podman volume rm -f > /dev/null 2>&1 || true
  fi
  if [[ -n "$service_pid" ]]; then
    kill "$service_pid" 2>/dev/null || true
    wait "$service_pid" 2>/dev/null || true
  fi
  [[ -n "$socket_dir" ]] && rm -rf "$socket_dir"
  rm -rf "$work"
  local left=""
  if command -v podman > /dev/null; then
    left+="$(podman ps -aq --filter "label=com.docker.compose.project=$project")"
    left+="$(podman volume ls -q | grep "^${project}_" || true)"
  fi
  [[ -n "$socket_dir" && -e "$socket_dir" ]] && left+=" $socket_dir"
  if [[ -n "$left" ]]; then
    row teardown FAILED "$t0" "left behind: $left"
    rc=1
  else
    row teardown ok "$t0" "no container, volume or socket left"
  fi
  print_table
  exit "$rc"
}
trap teardown EXIT
trap 'exit 130' INT TERM

# ---------------------------------------------------------------------------------------------
begin "1 podman, runc, docker-compose, debootstrap"
need=()
for tool in podman:podman runc:runc docker-compose:docker-compose debootstrap:debootstrap \
            ss:iproute2 python3:python3 openssl:openssl; do
  command -v "${tool%%:*}" > /dev/null || need+=("${tool#*:}")
done
if [[ ${#need[@]} -gt 0 ]]; then
  [[ $(id -u) -eq 0 ]] || fail "need root to install ${need[*]} (rootful podman runs the stack)"
  echo "installing ${need[*]}"
  apt-get update -q > "$out/logs/apt.log" 2>&1
  DEBIAN_FRONTEND=noninteractive apt-get install -y -q "${need[@]}" >> "$out/logs/apt.log" 2>&1 ||
    fail "apt-get install ${need[*]} failed (log: $out/logs/apt.log)"
fi
command -v podman > /dev/null || fail "podman is not installed and could not be installed"
[[ $(id -u) -eq 0 ]] || fail "run as root: the stack uses rootful podman (host networking for DDS)"
# runc: crun fails on these machines' mixed cgroup set-up. Limits: raising them is not permitted
# here, so containers get these (at or below the host's hard limits).
conf=/etc/containers/containers.conf.d/50-mav-stack.conf
if [[ ! -f "$conf" ]]; then
  mkdir -p "$(dirname "$conf")"
  cat > "$conf" <<'EOF'
# Written by deploy/stack-test.sh: the settings the MAV stack's containers need on these machines.
[containers]
default_ulimits = ["nofile=20000:20000", "nproc=32768:32768"]

[engine]
runtime = "runc"
EOF
fi
# docker-compose talks to podman's Docker-compatible socket: one of this run's own unless
# DOCKER_HOST names one.
if [[ -z "${DOCKER_HOST:-}" ]]; then
  socket_dir="$(mktemp -d /run/mav-stack-test.XXXXXX)"
  podman system service --time=0 "unix://$socket_dir/podman.sock" > "$out/logs/podman-service.log" 2>&1 &
  service_pid=$!
  export DOCKER_HOST="unix://$socket_dir/podman.sock"
  for _ in $(seq 50); do [[ -S "$socket_dir/podman.sock" ]] && break; sleep 0.1; done
  [[ -S "$socket_dir/podman.sock" ]] || fail "podman system service did not open $socket_dir/podman.sock (log: $out/logs/podman-service.log)"
fi
docker-compose version --short > /dev/null || fail "docker-compose cannot run"
end "podman $(podman version -f '{{.Client.Version}}'), docker-compose $(docker-compose version --short)"

# ---------------------------------------------------------------------------------------------
begin "2 host build and the debian:bookworm base image"
"$repo/deploy/setup.sh" > "$out/logs/setup.log" 2>&1 || fail "deploy/setup.sh failed (log: $out/logs/setup.log)"
base_note="present"
if ! podman image exists debian:bookworm; then
  # apt's first non-security mirror (deb822 .sources or the one-line sources.list; either file
  # may be missing, which must not end the script under pipefail).
  mirror="${DEBIAN_MIRROR:-}"
  if [[ -z "$mirror" ]]; then
    mirror="$(cat /etc/apt/sources.list.d/*.sources /etc/apt/sources.list 2>/dev/null |
      grep -oE '^(URIs:|deb) +https?://[^ ]+' | grep -v security | head -1 | awk '{print $2}' || true)"
  fi
  mirror="${mirror:-http://deb.debian.org/debian}"
  echo "making debian:bookworm with debootstrap --variant=minbase from $mirror"
  debootstrap --variant=minbase bookworm "$work/rootfs" "$mirror" > "$out/logs/debootstrap.log" 2>&1 ||
    fail "debootstrap failed (log: $out/logs/debootstrap.log)"
  # The package cache and lists are fetched again by the image builds; documentation goes.
  rm -rf "$work/rootfs/var/cache/apt/archives/"*.deb "$work/rootfs/var/lib/apt/lists/"* \
         "$work/rootfs/usr/share/doc/"* "$work/rootfs/usr/share/man/"* "$work/rootfs/usr/share/locale/"*
  tar -C "$work/rootfs" -c . | podman import - debian:bookworm > /dev/null
  rm -rf "$work/rootfs"
  base_note="made with debootstrap"
fi
end "base image $base_note"

# ---------------------------------------------------------------------------------------------
executables=(mav-simulator mav-localization mav-mapping mav-planning mav-control mavctl mav-load)
if [[ $prebuilt -eq 1 ]]; then
  begin "3 image from the host's executables"
  ctx="$work/context"
  mkdir -p "$ctx/bin" "$ctx/deploy"
  for e in "${executables[@]}"; do
    [[ -x "$bin/$e" ]] || fail "$bin/$e is missing: build the tree first (deploy/setup.sh)"
    cp "$bin/$e" "$ctx/bin/"
  done
  cp deploy/cyclonedds.xml deploy/roudi.toml deploy/packages-runtime.txt deploy/image-runtime.sh \
    "$ctx/deploy/"
  cp -r maps missions "$ctx/"
  podman build -f deploy/Dockerfile.prebuilt -t "$image" "$ctx" > "$out/logs/image-build.log" 2>&1 ||
    fail "podman build failed (log: $out/logs/image-build.log)"
else
  begin "3 image from the sources"
  podman build -f deploy/Dockerfile -t "$image" . > "$out/logs/image-build.log" 2>&1 ||
    fail "podman build failed (log: $out/logs/image-build.log)"
fi
size_mb=$(( $(podman image inspect -f '{{.Size}}' "$image") / 1000000 ))
missing_libs="$(podman run --rm --entrypoint sh "$image" -c 'ldd /opt/mav/bin/* | grep "not found" | sort -u' || true)"
[[ -z "$missing_libs" ]] || fail "the image lacks libraries (add their packages to deploy/packages-runtime.txt): $missing_libs"
user="$(podman run --rm "$image" id -un)"
[[ "$user" == mav ]] || fail "the image runs as '$user', not the unprivileged user mav"
(( size_mb <= 400 )) || fail "the image is $size_mb MB, over the 400 MB budget"
end "$size_mb MB, user $user, every library found"

# ---------------------------------------------------------------------------------------------
# Ports: a port in use is named with the process that holds it, before anything starts.
check_ports() {
  local busy=""
  for p in "$@"; do
    local holder
    holder="$(ss -Hltnp "sport = :$p" 2>/dev/null | head -1)"
    [[ -n "$holder" ]] && busy+=$'\n'"  port $p: $(grep -oE 'users:\(\("[^"]+",pid=[0-9]+' <<< "$holder" | sed 's/users:(("//; s/",pid=/ (pid /; s/$/)/')"
  done
  [[ -z "$busy" ]] || fail "ports already in use (set MAV_*_PORT to others, or stop their holders):$busy"
}

# wait_healthy SERVICE [TIMEOUT_S]: runs the compose file's health check of SERVICE (podman runs
# none on its own without systemd) until it passes.
wait_healthy() {
  local service="$1" timeout="${2:-60}" ctr="${project}_${1}_1"
  local deadline=$(( $(date +%s) + timeout ))
  while (( $(date +%s) < deadline )); do
    if [[ "$(podman inspect -f '{{.State.Status}}' "$ctr" 2>/dev/null)" == running ]] &&
       podman healthcheck run "$ctr" > /dev/null 2>&1; then
      return 0
    fi
    sleep 1
  done
  fail "$service did not become healthy within $timeout s (status: $(podman inspect -f '{{.State.Status}}, restarted {{.RestartCount}} times' "$ctr" 2>&1))" "$service"
}

compose() { docker-compose -p "$project" "${compose_files[@]}" "$@"; }
services=(simulator localization mapping planning control)

begin "4 docker-compose up, every service healthy"
check_ports "$MAV_SIM_PORT" "$MAV_LOCALIZATION_PORT" "$MAV_MAPPING_PORT" "$MAV_PLANNING_PORT" \
            "$MAV_CONTROL_PORT" "$MAV_PLANNING_PORT_2" "$MAV_PLANNING_PORT_3"
security_note="DDS Security off"
if [[ $dds_security -eq 1 ]]; then
  export MAV_DDS_SECURITY_DIR="$work/dds-security"
  "$repo/deploy/dds-security/make-certs.sh" "$MAV_DDS_SECURITY_DIR" > "$out/logs/make-certs.log" 2>&1 ||
    fail "deploy/dds-security/make-certs.sh failed (log: $out/logs/make-certs.log)"
  # The containers run as uid 10001 and must read their own key; the CA keys stay root's.
  chown -R 10001 "$MAV_DDS_SECURITY_DIR"/mav-* "$MAV_DDS_SECURITY_DIR"/mavctl
  security_note="DDS Security on (an identity per service, ENCRYPT)"
fi
if [[ $dds_shm -eq 1 ]]; then
  security_note="DDS Security off, samples in shared memory (RouDi in its container)"
  services=(iox-roudi "${services[@]}")
fi
docker-compose -p "$project" "${base_files[@]}" up -d --no-build "${services[@]}" \
  > "$out/logs/compose-up.log" 2>&1 || fail "docker-compose up failed (log: $out/logs/compose-up.log)"
for s in "${services[@]}"; do wait_healthy "$s" 60; done
[[ $dds_shm -eq 1 ]] && services=("${services[@]:1}")  # the later stages concern the five
end "${#services[@]} services SERVING, DDS domain $MAV_DDS_DOMAIN, $security_note"

# mission_summary JSON: the mission report's outcome, goals, ATE, collisions and speed, as one line.
mission_summary() {
  python3 - "$1" <<'EOF'
import json, sys
r = json.load(open(sys.argv[1]))
goals = r.get("goals", [])
print("%s, goals %d/%d, ATE %.3f m, collisions %d, %.0f s flown at %.2fx real time" % (
    r["outcome"], sum(1 for g in goals if g.get("reached")), len(goals), r["ate_m"],
    r["collisions"], r["sim_time_s"], r["real_time_factor"]))
EOF
}

begin "5 room mission from the compose mission client"
listen_pids=()
if [[ $dds_security -eq 1 ]]; then
  # Two listeners on the host while the mission flies: without credentials (must get nothing)
  # and with mavctl's identity (must get frames).
  listen=("$bin/mavctl" listen --topic stereo --frames 20 --timeout 60 --dds-domain "$MAV_DDS_DOMAIN")
  "${listen[@]}" > "$out/logs/listen-open.log" 2>&1 &
  listen_pids+=($!)
  "${listen[@]}" --dds-security "$MAV_DDS_SECURITY_DIR/mavctl" > "$out/logs/listen-mavctl.log" 2>&1 &
  listen_pids+=($!)
  bare_pids+=("${listen_pids[@]}")  # the teardown stops them if the mission fails
fi
if [[ $dds_shm -eq 1 ]]; then
  # A listener in a container of its own, in RouDi's shared memory, while the mission flies.
  docker-compose -p "$project" "${base_files[@]}" --profile shm-listen run --rm shm-listen \
    > "$out/logs/listen-shm.log" 2>&1 &
  listen_pids+=($!)
  bare_pids+=("${listen_pids[@]}")
fi
docker-compose -p "$project" "${base_files[@]}" run --rm mission > "$out/logs/mission-1.log" 2>&1 ||
  { tail -20 "$out/logs/mission-1.log" >&2; fail "the first mission did not complete (log: $out/logs/mission-1.log)"; }
volume_dir="$(podman volume inspect -f '{{.Mountpoint}}' "${project}_mav-data")"
cp "$volume_dir/mission.json" "$out/mission-1.json"
listen_note=""
if [[ $dds_security -eq 1 ]]; then
  wait "${listen_pids[@]}" || true
  open_frames="$(grep -oE '^stereo: +[0-9]+' "$out/logs/listen-open.log" | grep -oE '[0-9]+$' || echo "?")"
  mavctl_frames="$(grep -oE '^stereo: +[0-9]+' "$out/logs/listen-mavctl.log" | grep -oE '[0-9]+$' || echo "?")"
  [[ "$open_frames" == 0 ]] ||
    fail "a listener without DDS credentials received '$open_frames' stereo frames (log: $out/logs/listen-open.log)"
  [[ "$mavctl_frames" =~ ^[0-9]+$ && "$mavctl_frames" -gt 0 ]] ||
    fail "the listener with mavctl's identity received no stereo frame (log: $out/logs/listen-mavctl.log)"
  listen_note="; stereo frames to a listener without credentials: 0, with mavctl's identity: $mavctl_frames"
fi
if [[ $dds_shm -eq 1 ]]; then
  wait "${listen_pids[@]}" || true
  grep -qE 'RESULT frames=20 missing=0 crc_failures=0 .* shm=1 passed=1' "$out/logs/listen-shm.log" ||
    fail "the listener in shared memory did not get 20 intact frames through it (log: $out/logs/listen-shm.log)"
  "$bin/mavctl" sim status --port "$MAV_SIM_PORT" > "$out/logs/sim-status.log" 2>&1 || true
  grep -q "stereo in shared memory" "$out/logs/sim-status.log" ||
    fail "the simulator's stereo writer is not in shared memory (log: $out/logs/sim-status.log)" simulator
  listen_note="; 20 stereo frames to a listener in shared memory, intact ($(grep -oE 'p50 [0-9.]+ ms' "$out/logs/listen-shm.log" | head -1) one-way)"
fi
end "$(mission_summary "$out/mission-1.json")$listen_note"

begin "6 SIGKILL mav-localization, restart, a second mission"
ctr="${project}_localization_1"
pid="$(podman inspect -f '{{.State.Pid}}' "$ctr")"
restarts="$(podman inspect -f '{{.RestartCount}}' "$ctr")"
kill_s=$(date +%s.%N)
kill -KILL "$pid"
for _ in $(seq 300); do
  [[ "$(podman inspect -f '{{.RestartCount}}' "$ctr")" -gt "$restarts" ]] && break
  sleep 0.1
done
[[ "$(podman inspect -f '{{.RestartCount}}' "$ctr")" -gt "$restarts" ]] ||
  fail "podman did not restart localization within 30 s of the SIGKILL (restart policy)" localization
wait_healthy localization 60
recovered_s="$(awk -v a="$kill_s" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }')"
roudi_note=""
if [[ $dds_shm -eq 1 ]]; then
  # RouDi SIGKILLed: podman restarts it, and every service in the old RouDi's memory stops
  # itself (a process in the new one would get none of its samples) and is restarted into it.
  in_shm=()
  declare -A restarts_before=()
  for s in iox-roudi "${services[@]}"; do
    c="${project}_${s}_1"
    [[ $s == iox-roudi ]] || podman logs "$c" 2>&1 | grep -q "shared memory on" || continue
    in_shm+=("$s")
    restarts_before[$s]="$(podman inspect -f '{{.RestartCount}}' "$c")"
  done
  kill -KILL "$(podman inspect -f '{{.State.Pid}}' "${project}_iox-roudi_1")"
  for s in "${in_shm[@]}"; do
    c="${project}_${s}_1"
    for _ in $(seq 300); do
      [[ "$(podman inspect -f '{{.RestartCount}}' "$c")" -gt "${restarts_before[$s]}" ]] && break
      sleep 0.1
    done
    [[ "$(podman inspect -f '{{.RestartCount}}' "$c")" -gt "${restarts_before[$s]}" ]] ||
      fail "$s was not restarted within 30 s of RouDi's SIGKILL" "$s"
  done
  for s in iox-roudi "${services[@]}"; do wait_healthy "$s" 60; done
  roudi_note="; RouDi SIGKILLed: it and the services in its memory (${in_shm[*]:1}) restarted"
fi
"$bin/mavctl" mission run --mission missions/room_survey.yaml --seed 2 --pose-source vo \
  --out "$out/mission-2" --json "$out/mission-2.json" \
  --simulator "127.0.0.1:$MAV_SIM_PORT" --localization "127.0.0.1:$MAV_LOCALIZATION_PORT" \
  --planning "127.0.0.1:$MAV_PLANNING_PORT" --control "127.0.0.1:$MAV_CONTROL_PORT" \
  > "$out/logs/mission-2.log" 2>&1 ||
  { tail -20 "$out/logs/mission-2.log" >&2; fail "the mission after the restart did not complete (log: $out/logs/mission-2.log)"; }
end "restarted by podman's policy, healthy after ${recovered_s} s$roudi_note; $(mission_summary "$out/mission-2.json")"

[[ $smoke -eq 1 ]] && exit 0

# ---------------------------------------------------------------------------------------------
# Load tests: each service's hot call with mav-load at concurrency 1, 2, 4, 8 and an overload
# run, against the container, then against a bare process of the same executable on the same
# port; the server's CPU and peak memory come from its /proc (mav-load --cpu-pid).
source "$repo/deploy/stack-load.sh"
load_all

begin "8 planning replicas behind round_robin"
replicas_test
end "$replica_note"
