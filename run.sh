#!/usr/bin/env bash
# The main job. Sets up and builds what is missing (deploy/setup.sh), then runs the pipeline:
#   1. mav-sim renders a short room-easy data set (EuRoC layout + exact ground truth);
#   2. mav-simulator loads it over gRPC and replays it in real time on the DDS data plane;
#   3. mavctl listen subscribes over DDS, checks every frame and prints what arrived;
#   4. mav-eval localization runs the three stereo VO methods on it and prints the paper's
#      Tables 1 and 2 beside ours;
#   5. mav-eval mapping builds both maps (sparse meshing, OctoMap + dense stereo) from the same
#      keyframes and prints the paper's Tables 3 and 4 beside ours;
#   6. mav-planning loads the contest's power_plant.bt (maps/) with a PRM* roadmap
#      (built once into OUT/power_plant.mavprm, ~15 s, then loaded in under a second) and
#      mavctl plans the t4_3 legs through it and prints the table with the paper's figures;
#   7. the closed loop through the services: mav-simulator flies the contest's t3_1 lock-stepped
#      on the rotor speeds mav-control (the paper's controller) sends over DDS and prints the
#      contest's score; then t4_3's first leg, planned by mav-planning and flown through
#      mav-control, with the vehicle's end point and collisions;
#   8. a mission through the services on the vehicle's own eyes: missions/room_survey.yaml
#      (7 goals around the room's obstacles, ~34 m) flown by mavctl mission run with
#      mav-simulator rendering the stereo camera from the flown state, mav-localization's VO
#      tracking it, mav-control's estimator on the VO's poses, mav-planning planning each leg;
#      prints the mission's table and the path of its mission.png.
# Environment: FRAMES (default 300), PRESET (room-easy), OUT (out/), MAV_SIM_PORT (50051),
# MAV_LOCALIZATION_PORT (50052), MAV_PLANNING_PORT (50054), MAV_CONTROL_PORT (50055),
# FLIGHT_SEED (1), MISSION (missions/room_survey.yaml).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
"$repo/deploy/setup.sh"

bin="$repo/build/bin"
frames="${FRAMES:-300}"
preset="${PRESET:-room-easy}"
out="${OUT:-$repo/out}"
port="${MAV_SIM_PORT:-50051}"
loc_port="${MAV_LOCALIZATION_PORT:-50052}"
plan_port="${MAV_PLANNING_PORT:-50054}"
ctl_port="${MAV_CONTROL_PORT:-50055}"
flight_seed="${FLIGHT_SEED:-1}"
data="$out/$preset-$frames"
mkdir -p "$out"
# A DDS domain of its own keeps this run apart from anything else on the machine.
export MAV_DDS_DOMAIN="${MAV_DDS_DOMAIN:-$(( ($$ % 200) + 1 ))}"

step() { printf '\n\033[1m== %s\033[0m\n' "$*"; }

step "1/8 rendering $frames frames of $preset into $data"
if [[ -f "$data/ground_truth/scenario.yaml" ]]; then
  echo "(already there; delete $data to render again)"
else
  "$bin/mav-sim" generate --preset "$preset" --frames "$frames" --out "$data" --force
fi
"$bin/mav-sim" info "$data"

step "2/8 starting mav-simulator on 127.0.0.1:$port (DDS domain $MAV_DDS_DOMAIN)"
"$bin/mav-simulator" --port "$port" > "$out/mav-simulator.log" 2>&1 &
sim_pid=$!
pids=("$sim_pid")
cleanup() {
  for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null || true; done
  for pid in "${pids[@]}"; do wait "$pid" 2>/dev/null || true; done
  pids=()
}
trap cleanup EXIT
# wait_serving PORT PID LOG [TRIES]: until the service at PORT answers its health check (every
# 0.2 s, 50 tries unless told).
wait_serving() {
  for _ in $(seq "${4:-50}"); do
    "$bin/mavctl" health --port "$1" > /dev/null 2>&1 && return 0
    kill -0 "$2" 2>/dev/null || { cat "$3"; exit 1; }
    sleep 0.2
  done
}
wait_serving "$port" "$sim_pid" "$out/mav-simulator.log"
"$bin/mavctl" health --port "$port"
"$bin/mavctl" sim load --euroc "$data" --port "$port"

step "3/8 replaying in real time over DDS; mavctl listen reports what arrived"
"$bin/mavctl" listen --topic all --frames "$frames" --timeout 60 &
listen_pid=$!
sleep 1  # let DDS discovery match the listener before the first frame
"$bin/mavctl" sim start --rate 1.0 --port "$port"
listen_status=0
wait "$listen_pid" || listen_status=$?
"$bin/mavctl" sim status --port "$port"
[[ $listen_status -eq 0 ]] || { echo "mavctl listen failed ($listen_status)" >&2; exit "$listen_status"; }

cleanup  # the simulator's work is done; free the cores for the evaluation
step "4/8 localization: sparse (pixel, subpixel) and dense stereo VO against ground truth"
"$bin/mav-eval" localization --data "$data" --json "$out/localization-$preset-$frames.json"

step "5/8 mapping: sparse multi-view meshing vs OctoMap + dense stereo, collision-check MCC"
"$bin/mav-eval" mapping --data "$data" --json "$out/mapping-$preset-$frames.json"

step "6/8 planning: the t4_3 legs on power_plant.bt through mav-planning"
plant="$repo/maps/power_plant.bt"
if [[ -f "$plant" ]]; then
  [[ -f "$out/power_plant.mavprm" ]] ||
    echo "(building the roadmap once into $out/power_plant.mavprm, ~15 s)"
  "$bin/mav-planning" --port "$plan_port" --map "$plant" --roadmap "$out/power_plant.mavprm" \
    > "$out/mav-planning.log" 2>&1 &
  pids+=("$!")
  wait_serving "$plan_port" "$!" "$out/mav-planning.log" 600
  "$bin/mavctl" plan status --port "$plan_port"
  "$bin/mavctl" plan legs --port "$plan_port" --points "2,-27,15;20,-15,15;25,0,5;0,0,1"
else
  echo "(no $plant here: skipped)"
fi

step "7/8 closed loop: t3_1 and a t4_3 leg flown by mav-control (paper controller) on mav-simulator, lock-stepped over DDS"
"$bin/mav-simulator" --port "$port" > "$out/mav-simulator-flight.log" 2>&1 &
pids+=("$!")
wait_serving "$port" "$!" "$out/mav-simulator-flight.log"
"$bin/mav-control" --port "$ctl_port" > "$out/mav-control.log" 2>&1 &
pids+=("$!")
wait_serving "$ctl_port" "$!" "$out/mav-control.log"
sim() { "$bin/mavctl" sim flight "$@" --port "$port"; }
ctl() { "$bin/mavctl" ctl "$@" --port "$ctl_port"; }
sim load --task t3_1 --lockstep --seed "$flight_seed" > /dev/null
ctl configure --task t3_1 --controller paper --lockstep > /dev/null
# The contest server's part: arm once the estimator has converged (4 s after the first pose),
# take off to the set point, hover there when it is published (10 s), to the end (30 s).
sim run --until 5 --wait > /dev/null
ctl arm > /dev/null
ctl hover --position 0,0,1 --max-speed 1.5 --max-accel 2 > /dev/null
sim run --pause-on-goal --wait > /dev/null
ctl hover --position 0,0,1 --max-speed 1.5 --max-accel 2 > /dev/null
sim run --wait
ctl status
if [[ -f "$plant" ]]; then
  printf '\n-- t4_3, first leg: planned by mav-planning, fetched by mav-control (Planning.GetPlan), flown\n'
  ctl disarm > /dev/null  # t3_1 is over; Configure wants the motors off
  sim load --task t4_3 --lockstep --seed "$flight_seed" > /dev/null
  ctl configure --task t4_3 --controller paper --lockstep > /dev/null
  sim run --until 5 --wait > /dev/null
  ctl arm > /dev/null
  ctl hover --position 0,0,2 --max-speed 1.5 --max-accel 2 > /dev/null  # the take-off point
  sim run --pause-on-goal --wait > /dev/null                              # goal 0 at 10 s
  "$bin/mavctl" plan path --port "$plan_port" --start 0,0,2 --goal 2,-27,15 | tee "$out/t4_3-leg1.txt"
  plan_id="$(awk '/^plan_id:/ {print $2}' "$out/t4_3-leg1.txt")"
  ctl trajectory --plan "$plan_id" --planning "127.0.0.1:$plan_port" > /dev/null
  sim run --until 25 --wait     # the leg (~6 s) and the hover at the goal (2, -27, 15)
fi
cleanup

step "8/8 a mission through the services: $(basename "${MISSION:-room_survey.yaml}") on the vehicle's own eyes (stereo VO)"
"$bin/mav-simulator" --port "$port" > "$out/mav-simulator-mission.log" 2>&1 &
pids+=("$!")
wait_serving "$port" "$!" "$out/mav-simulator-mission.log"
"$bin/mav-localization" --port "$loc_port" > "$out/mav-localization.log" 2>&1 &
pids+=("$!")
wait_serving "$loc_port" "$!" "$out/mav-localization.log"
"$bin/mav-planning" --port "$plan_port" > "$out/mav-planning-mission.log" 2>&1 &
pids+=("$!")
wait_serving "$plan_port" "$!" "$out/mav-planning-mission.log"
"$bin/mav-control" --port "$ctl_port" > "$out/mav-control-mission.log" 2>&1 &
pids+=("$!")
wait_serving "$ctl_port" "$!" "$out/mav-control-mission.log"
"$bin/mavctl" mission run --mission "${MISSION:-$repo/missions/room_survey.yaml}" \
  --seed "$flight_seed" --pose-source vo --out "$out/mission" --json "$out/mission.json" \
  --simulator "127.0.0.1:$port" --localization "127.0.0.1:$loc_port" \
  --planning "127.0.0.1:$plan_port" --control "127.0.0.1:$ctl_port"
cleanup
echo
echo "mission.png: $out/mission/mission.png (the report: $out/mission.json)"
