# Sourced by deploy/stack-test.sh (which defines begin/end/fail/compose/wait_healthy, $bin, $out,
# $work, $cpus, $load_seconds and the ports): stage 7, the load tests, and stage 8, the planning
# replicas. Not meant to be run by itself.
#
# Stage 7 runs mav-load against each service's hot call at concurrency 1, 2, 4, 8 and an
# overload run at 32 (4 x the sweep's top; twice: refused clients pausing 1 ms, then backing off
# as mav-load does by default, 10 ms doubling up to 1 s), first against the container, then a bare
# process of the same executable on the same port; servers and mav-load are pinned to $cpus
# (taskset; a container's processes are host processes). Mapping and control are run once more
# at 8 calls in flight from mav-load's asynchronous client (--client async), which costs the
# shared cores less per call than a client thread per call. Each run writes
# OUT/load/<mode>-<service>-c<C>[-backoff|-async].json; deploy/load-table.py turns them into
# OUT/load.md.

load_concurrencies=(1 2 4 8 32)

# The mav-load command line of SERVICE, without the common flags.
load_args() {
  case "$1" in
    planning) echo "planning --address 127.0.0.1:$MAV_PLANNING_PORT --queries $repo/tests/data/planning/power_plant_queries.txt" ;;
    # The service's own input queue (2 frames): beyond it, calls are refused, not queued.
    localization) echo "localization --address 127.0.0.1:$MAV_LOCALIZATION_PORT --method sparse --queue 2" ;;
    mapping) echo "mapping --address 127.0.0.1:$MAV_MAPPING_PORT" ;;
    control) echo "control --address 127.0.0.1:$MAV_CONTROL_PORT" ;;
  esac
}

# load_sweep MODE SERVICE PID: every concurrency against the server PID.
load_sweep() {
  local mode="$1" service="$2" pid="$3"
  taskset -a -p -c "$cpus" "$pid" > /dev/null
  if [[ "$service" == mapping ]]; then
    # A room map to query: 12 room-easy keyframes through the service's own session.
    taskset -c "$cpus" "$bin/mav-load" $(load_args mapping) --build-room 12 --concurrency 1 \
      --duration 1 > "$out/logs/load-$mode-mapping-build.log" 2>&1 ||
      fail "mav-load mapping --build-room against the $mode server failed (log: $out/logs/load-$mode-mapping-build.log)"
  fi
  for c in "${load_concurrencies[@]}"; do
    local name="$mode-$service-c$c"
    echo "  $name"
    # A refused client pauses 1 ms (--backoff-max-ms 0): the sweep measures the service, and the
    # overload at 32 shows what clients that do not back off do to it.
    taskset -c "$cpus" "$bin/mav-load" $(load_args "$service") --concurrency "$c" --backoff-max-ms 0 \
      --duration "$load_seconds" --cpu-pid "$pid" --json "$out/load/$name.json" \
      > "$out/logs/load-$name.log" 2>&1 ||
      fail "mav-load $service at concurrency $c against the $mode server failed (log: $out/logs/load-$name.log)"
    kill -0 "$pid" 2>/dev/null || fail "the $mode $service server died under load (log: $out/logs/load-$name.log)"
  done
  # The overload again with clients that back off when refused (as well-behaved ones do).
  local name="$mode-$service-c${load_concurrencies[-1]}-backoff"
  echo "  $name"
  taskset -c "$cpus" "$bin/mav-load" $(load_args "$service") --concurrency "${load_concurrencies[-1]}" \
    --duration "$load_seconds" --cpu-pid "$pid" --json "$out/load/$name.json" \
    > "$out/logs/load-$name.log" 2>&1 ||
    fail "mav-load $service (backoff) against the $mode server failed (log: $out/logs/load-$name.log)"
  kill -0 "$pid" 2>/dev/null || fail "the $mode $service server died under load (log: $out/logs/load-$name.log)"
  if [[ "$service" == mapping || "$service" == control ]]; then
    name="$mode-$service-c8-async"
    echo "  $name"
    taskset -c "$cpus" "$bin/mav-load" $(load_args "$service") --concurrency 8 --client async \
      --duration "$load_seconds" --cpu-pid "$pid" --json "$out/load/$name.json" \
      > "$out/logs/load-$name.log" 2>&1 ||
      fail "mav-load $service --client async against the $mode server failed (log: $out/logs/load-$name.log)"
  fi
}

container_pid() { podman inspect -f '{{.State.Pid}}' "${project}_${1}_1"; }

# start_bare SERVICE ARGS...: the executable of SERVICE on its port, pinned, in $started_pid
# (and in $bare_pids, which the teardown stops).
started_pid=""
start_bare() {
  local service="$1"
  shift
  local port_var
  case "$service" in
    planning) port_var=MAV_PLANNING_PORT ;;
    localization) port_var=MAV_LOCALIZATION_PORT ;;
    mapping) port_var=MAV_MAPPING_PORT ;;
    control) port_var=MAV_CONTROL_PORT ;;
  esac
  taskset -c "$cpus" "$bin/mav-$service" --port "${!port_var}" "$@" \
    > "$out/logs/bare-$service.log" 2>&1 &
  local pid=$!
  bare_pids+=("$pid")
  for _ in $(seq 600); do
    "$bin/mavctl" health --port "${!port_var}" --timeout 1 > /dev/null 2>&1 && { started_pid="$pid"; return 0; }
    kill -0 "$pid" 2>/dev/null || fail "bare mav-$service exited (log: $out/logs/bare-$service.log)"
    sleep 0.2
  done
  fail "bare mav-$service did not answer within 120 s (log: $out/logs/bare-$service.log)"
}

load_all() {
  local services_under_load=(planning localization mapping control)
  begin "7a load tests against the containers"
  # Planning on the contest's map with its roadmap in the data volume (built on the first start,
  # ~1 min on 2 cores; loaded in about a second afterwards).
  compose up -d --no-build planning > "$out/logs/compose-planning.log" 2>&1 ||
    fail "docker-compose up planning (replicas file) failed (log: $out/logs/compose-planning.log)"
  wait_healthy planning 300
  for s in "${services_under_load[@]}"; do load_sweep container "$s" "$(container_pid "$s")"; done
  end "${#services_under_load[@]} services x $(( ${#load_concurrencies[@]} + 1 )) runs of $load_seconds s, + 1 async for mapping and control"

  begin "7b load tests against bare processes"
  docker-compose -p "$project" -f "$repo/docker-compose.yml" stop > "$out/logs/compose-stop.log" 2>&1 ||
    fail "docker-compose stop failed (log: $out/logs/compose-stop.log)"
  cp "$(podman volume inspect -f '{{.Mountpoint}}' "${project}_mav-data")/power_plant.mavprm" "$work/"
  for s in "${services_under_load[@]}"; do
    if [[ "$s" == planning ]]; then
      start_bare planning --map "$repo/maps/power_plant.bt" --roadmap "$work/power_plant.mavprm"
    else
      start_bare "$s"
    fi
    load_sweep bare "$s" "$started_pid"
    kill "$started_pid"
    wait "$started_pid" 2>/dev/null || true
  done
  python3 "$repo/deploy/load-table.py" "$out/load" > "$out/load.md" ||
    fail "deploy/load-table.py could not read $out/load"
  cat "$out/load.md"
  end "table: $out/load.md"
}

# Stage 8: planning, planning-2 and planning-3 on one roadmap file; mav-load through one
# round_robin target; then the same with one replica SIGKILLed a third into the run.
replica_note=""
replicas_test() {
  local target="127.0.0.1:$MAV_PLANNING_PORT,127.0.0.1:$MAV_PLANNING_PORT_2,127.0.0.1:$MAV_PLANNING_PORT_3"
  compose up -d --no-build planning planning-2 planning-3 > "$out/logs/compose-replicas.log" 2>&1 ||
    fail "docker-compose up of the replicas failed (log: $out/logs/compose-replicas.log)"
  for s in planning planning-2 planning-3; do wait_healthy "$s" 120; done
  local args=(planning --address "$target" --queries "$repo/tests/data/planning/power_plant_queries.txt"
              --concurrency 4 --duration "$load_seconds")
  taskset -c "$cpus" "$bin/mav-load" "${args[@]}" --json "$out/load/replicas-spread.json" \
    > "$out/logs/load-replicas-spread.log" 2>&1 ||
    fail "mav-load through the three replicas failed (log: $out/logs/load-replicas-spread.log)"
  # A replica killed under load: podman's policy restarts it; the client must lose no call but
  # those in flight on it (the retry policy usually saves those too).
  local victim="${project}_planning-2_1" restarts
  restarts="$(podman inspect -f '{{.RestartCount}}' "$victim")"
  taskset -c "$cpus" "$bin/mav-load" "${args[@]}" --json "$out/load/replicas-kill.json" \
    > "$out/logs/load-replicas-kill.log" 2>&1 &
  local load_pid=$!
  sleep "$(( load_seconds / 3 + 1 ))"
  kill -KILL "$(podman inspect -f '{{.State.Pid}}' "$victim")"
  wait "$load_pid" || true
  [[ "$(podman inspect -f '{{.RestartCount}}' "$victim")" -gt "$restarts" ]] ||
    fail "podman did not restart planning-2 after the SIGKILL" planning-2
  replica_note="$(python3 "$repo/deploy/load-table.py" --replicas "$out/load/replicas-spread.json" \
    "$out/load/replicas-kill.json")" || fail "the replicas' figures are out of bounds: $replica_note"
  echo "$replica_note" | tee "$out/replicas.md"
}
