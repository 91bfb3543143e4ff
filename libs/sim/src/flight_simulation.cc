#include "mav/sim/flight_simulation.h"

#include <cmath>
#include <limits>
#include <sstream>

#include "mav/common/time.h"

namespace mav::sim {

bool FlightSimulationOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  std::string inner;
  if (!vehicle.IsValid(&inner)) return fail("vehicle." + inner);
  if (!(physics_substep_s > 0 && physics_substep_s <= 0.001)) {
    return fail("physics_substep_s: must be in (0, 0.001] (>= 1 kHz)");
  }
  if (!(landing_speed_mps >= 0 && std::isfinite(landing_speed_mps))) {
    return fail("landing_speed_mps: must be >= 0");
  }
  if (!(clearance_rate_hz > 0 && clearance_rate_hz <= 1000)) {
    return fail("clearance_rate_hz: must be in (0, 1000]");
  }
  if (!(clearance_range_m > 0 && std::isfinite(clearance_range_m))) {
    return fail("clearance_range_m: must be positive");
  }
  return true;
}

Result<FlightSimulation> FlightSimulation::Create(const dataset::FlightTask& task, uint64_t seed,
                                                  const FlightSimulationOptions& options,
                                                  std::shared_ptr<const CollisionWorld> world) {
  if (std::string why; !task.IsValid(&why)) {
    return Status::InvalidArgument("task " + task.name + ": " + why);
  }
  if (std::string why; !options.IsValid(&why)) return Status::InvalidArgument(why);
  if (!world && !task.map_path.empty()) {
    MAV_ASSIGN_OR_RETURN(std::unique_ptr<CollisionWorld> loaded,
                         LoadOctomapCollisionWorld(task.map_path));
    world = std::move(loaded);
  }
  return FlightSimulation(task, seed, options, std::move(world));
}

FlightSimulation::FlightSimulation(const dataset::FlightTask& task, uint64_t seed,
                                   const FlightSimulationOptions& options,
                                   std::shared_ptr<const CollisionWorld> world)
    : task_(task),
      options_(options),
      vehicle_(options.vehicle, options.physics_substep_s),
      imu_(task.imu, seed),
      world_(std::move(world)),
      min_clearance_m_(std::numeric_limits<double>::infinity()) {
  for (size_t i = 0; i < task.pose_sensors.size(); ++i) {
    pose_sensors_.emplace_back(task.pose_sensors[i], static_cast<int>(i), seed);
  }
  step_ns_ = PeriodNs(task.imu.rate_hz);
  duration_ns_ = SecondsToNs(task.duration_s);
  clearance_period_ns_ = PeriodNs(options.clearance_rate_hz);
  // The spawn: resting on the ground with the legs' height below the body origin.
  const bool on_ground =
      task.spawn_position.z() <= task.ground_z_m + options.vehicle.rest_height_m + 1e-9;
  vehicle_.Reset(
      task.spawn_position, task.spawn_yaw_rad, on_ground,
      on_ground ? task.spawn_position.z() - options.vehicle.rest_height_m : task.ground_z_m);
  out_.poses.reserve(16);
  out_.t_ns = 0;
  Sense();
}

FlightSimulation::FlightSimulation(FlightSimulation&&) noexcept = default;
FlightSimulation& FlightSimulation::operator=(FlightSimulation&&) noexcept = default;
FlightSimulation::~FlightSimulation() = default;

bool FlightSimulation::done() const { return out_.t_ns >= duration_ns_; }

void FlightSimulation::Sense() {
  const MulticopterState& x = vehicle_.state();
  out_.truth = x;
  out_.a_world = vehicle_.AccelerationWorld();
  out_.imu = imu_.Sample(out_.t_ns, x.omega_body, vehicle_.SpecificForceBody());
  out_.poses.clear();
  const geometry::SE3 T_world_body(x.q_world_body, x.p_world);
  for (FlightPoseSensor& s : pose_sensors_) {
    s.Observe(out_.t_ns, T_world_body);
    s.Deliver(out_.t_ns, &out_.poses);
  }
  const int previous = out_.goal_index;
  out_.goal_index = -1;
  const double t_s = NsToSeconds(out_.t_ns);
  for (size_t i = 0; i < task_.goals.size(); ++i) {
    if (task_.goals[i].publish_s <= t_s + 1e-9) out_.goal_index = static_cast<int>(i);
  }
  out_.goal_published = out_.goal_index != previous;
}

void FlightSimulation::RecordCollision(Collision collision) {
  ++collision_count_;
  if (collisions_.size() < kMaxRecordedCollisions) collisions_.push_back(std::move(collision));
}

void FlightSimulation::CheckCollisions(const GroundContact& contact) {
  const MulticopterState& x = vehicle_.state();
  if (!x.on_ground) lifted_off_ = true;
  if (contact.touched_down && contact.impact_speed_mps > options_.landing_speed_mps) {
    std::ostringstream what;
    what.precision(3);
    what << "ground (impact " << contact.impact_speed_mps << " m/s)";
    RecordCollision({out_.t_ns, x.p_world, what.str()});
    out_.collision = true;
  }
  if (!world_ || !lifted_off_) return;
  const double radius = task_.vehicle_radius_m;
  const double clearance = world_->Clearance(x.p_world, 2 * radius);
  if (!checking_map_) {
    // Armed once clear of the spawn pad.
    if (clearance < radius || x.on_ground) return;
    checking_map_ = true;
    next_clearance_ns_ = out_.t_ns;
  }
  const bool contact_now = clearance < radius;
  if (contact_now && !in_contact_) {
    std::ostringstream what;
    what.precision(3);
    what << world_->Describe() << " (clearance " << clearance << " m)";
    RecordCollision({out_.t_ns, x.p_world, what.str()});
    out_.collision = true;
  }
  in_contact_ = contact_now;
  if (out_.t_ns >= next_clearance_ns_) {
    next_clearance_ns_ += clearance_period_ns_;
    min_clearance_m_ =
        std::min(min_clearance_m_, world_->Clearance(x.p_world, options_.clearance_range_m));
  }
}

const FlightStep& FlightSimulation::Step(const RotorVector& command_radps) {
  const double t_s = NsToSeconds(out_.t_ns);
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
  for (const dataset::ForceWindow& f : task_.forces) {
    if (t_s + 1e-9 >= f.start_s && t_s + 1e-9 < f.end_s) force += f.force_world_n;
  }
  vehicle_.SetExternalForce(force);
  const GroundContact contact = vehicle_.Step(command_radps, NsToSeconds(step_ns_));
  out_.t_ns += step_ns_;
  out_.force_world_n = force;
  out_.collision = false;
  Sense();
  CheckCollisions(contact);
  return out_;
}

}  // namespace mav::sim
