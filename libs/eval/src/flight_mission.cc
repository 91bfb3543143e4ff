#include "mav/eval/flight_mission.h"

#include <cmath>
#include <limits>

#include "mav/common/time.h"

namespace mav::eval {

control::AutopilotOptions AutopilotOptionsForTask(const dataset::FlightTask& task,
                                                  control::ControllerType controller) {
  control::AutopilotOptions o;
  o.controller = controller;
  o.estimator.imu_rate_hz = task.imu.rate_hz;
  o.estimator.accel_noise_sigma = std::max(task.imu.accel_noise_sigma, 1e-4);
  o.estimator.gyro_noise_sigma = std::max(task.imu.gyro_noise_sigma, 1e-5);
  o.estimator.accel_offset_random_walk =
      task.imu.accel_drift_sigma / std::sqrt(task.imu.drift_horizon_s);
  o.estimator.gyro_offset_random_walk =
      task.imu.gyro_drift_sigma / std::sqrt(task.imu.drift_horizon_s);
  o.estimator.pose_sources.clear();
  double max_delay = 0;
  for (const dataset::FlightPoseSensorSpec& s : task.pose_sensors) {
    control::PoseSourceOptions src;
    src.rate_hz = s.rate_hz;
    src.position_sigma_m = std::max(s.position_sigma_m, 1e-4);
    src.orientation_sigma_rad = std::max(s.orientation_sigma_rad, 1e-4);
    src.T_body_sensor = s.T_body_sensor();
    o.estimator.pose_sources.push_back(src);
    max_delay = std::max(max_delay, s.delay_s);
  }
  o.estimator.buffer_s = std::max(1.0, 2 * max_delay + 0.2);
  return o;
}

namespace {

struct Mission {
  const dataset::FlightTask& task;
  const FlightMissionOptions& options;
  control::Autopilot& ap;
  const sim::FlightSimulation& sim;
  int applied_goal = -1;
  bool took_off = false;

  Status ApplyGoal(int index) {
    const dataset::FlightGoal& goal = task.goals[index];
    switch (task.kind) {
      case dataset::FlightTaskKind::kHover:
      case dataset::FlightTaskKind::kDisturbance:
        return ap.Hover(goal.position, goal.yaw_rad, &options.takeoff_limits);
      case dataset::FlightTaskKind::kWaypoints:
        return ap.Hover(goal.position, goal.yaw_rad, &options.waypoint_limits);
      case dataset::FlightTaskKind::kPlannedLegs: {
        const Eigen::Vector3d start = ap.state().reference.position;
        Result<geometry::PolynomialTrajectory> plan =
            options.planner(start, goal.position, goal.yaw_rad, sim.world());
        if (!plan.ok()) {
          return plan.status().WithContext("leg " + std::to_string(index) + " to goal " +
                                           std::to_string(index));
        }
        return ap.SetTrajectory(*plan, 0, Eigen::Vector3d::Zero(), /*allow_jump=*/false);
      }
    }
    return Status::Internal("unknown task kind");
  }

  // Called after each step's inputs are fed.
  Status Update(const sim::FlightStep& out, FlightRecord* record) {
    if (!ap.armed()) {
      if (took_off || !ap.estimator().converged()) return Status::Ok();
      MAV_RETURN_IF_ERROR(ap.Arm());
      record->arm_t_s = NsToSeconds(out.t_ns);
      MAV_RETURN_IF_ERROR(
          ap.Hover(task.takeoff_position, task.spawn_yaw_rad, &options.takeoff_limits));
      took_off = true;
      return Status::Ok();
    }
    // Goals wait until the take-off move has ended.
    if (out.goal_index > applied_goal && !(applied_goal < 0 && ap.moving())) {
      applied_goal = out.goal_index;
      MAV_RETURN_IF_ERROR(ApplyGoal(applied_goal));
    }
    return Status::Ok();
  }
};

}  // namespace

Result<FlightRecord> FlyTask(const dataset::FlightTask& task, const FlightMissionOptions& options) {
  const int64_t start_ns = MonotonicNowNs();
  if (task.kind == dataset::FlightTaskKind::kPlannedLegs && !options.planner) {
    return Status::FailedPrecondition(
        "task " + task.name +
        ": needs a leg planner (libs/planning) to fly the power plant; none is linked yet");
  }
  MAV_ASSIGN_OR_RETURN(sim::FlightSimulation sim,
                       sim::FlightSimulation::Create(task, options.seed, options.simulation));
  control::AutopilotOptions ap_options = AutopilotOptionsForTask(task, options.controller);
  if (options.tune) options.tune(&ap_options);
  MAV_ASSIGN_OR_RETURN(control::Autopilot ap, control::Autopilot::Create(ap_options));

  FlightRecord record;
  record.task = task.name;
  record.controller = control::ControllerTypeName(options.controller);
  record.samples.reserve(static_cast<size_t>(task.duration_s * task.imu.rate_hz) + 2);
  Mission mission{task, options, ap, sim};
  const sim::FlightStep* out = &sim.Initial();
  record.min_clearance_m = std::numeric_limits<double>::infinity();
  int64_t next_clearance_ns = 0;
  while (true) {
    if (sim.world() && out->goal_index >= 0 && out->t_ns >= next_clearance_ns) {
      next_clearance_ns = out->t_ns + 100'000'000;
      record.min_clearance_m =
          std::min(record.min_clearance_m, sim.world()->Clearance(out->truth.p_world, 5.0));
    }
    for (const sim::PoseSample& p : out->poses) {
      // Stale or early poses are the estimator's business (counted, not fatal).
      (void)ap.FeedPose(control::PoseMeasurement{p.t_ns, p.sensor, p.T_world_sensor});
    }
    control::ImuMeasurement imu{out->imu.t_ns, out->imu.gyro, out->imu.accel};
    const control::RotorVector& command = ap.FeedImu(imu);
    MAV_RETURN_IF_ERROR(mission.Update(*out, &record));
    FlightRecordSample s;
    s.t_s = NsToSeconds(out->t_ns);
    s.truth = out->truth;
    const control::AutopilotState state = ap.state();
    s.reference = state.reference;
    s.estimate = state.estimate;
    s.force_world_n = out->force_world_n;
    s.goal_index = out->goal_index;
    record.samples.push_back(s);
    if (sim.done()) break;
    sim::RotorVector cmd(command.size());
    for (int i = 0; i < command.size(); ++i) cmd[i] = command[i];
    out = &sim.Step(cmd);
  }
  if (record.arm_t_s < 0) {
    return Status::FailedPrecondition("task " + task.name + ": the estimator never converged");
  }
  record.collisions = sim.collisions();
  record.autopilot = ap.status();
  record.step_ms = record.autopilot.step_ms;
  record.simulated_s = NsToSeconds(sim.t_ns());
  record.wall_s = SecondsSince(start_ns);
  return record;
}

std::vector<FlightTraceSample> FlightTrace(const FlightRecord& record) {
  std::vector<FlightTraceSample> trace;
  trace.reserve(record.samples.size());
  for (const FlightRecordSample& s : record.samples) {
    trace.push_back(
        {s.t_s, s.truth.p_world, s.truth.v_world, s.truth.omega_body, s.estimate.p_world});
  }
  return trace;
}

TaskScore ScoreFlight(const dataset::FlightTask& task, const FlightRecord& record) {
  return ScoreFlightTask(task, FlightTrace(record), static_cast<int>(record.collisions.size()));
}

}  // namespace mav::eval
