#include "mav/control/autopilot.h"

#include <cmath>
#include <cstdio>

#include "mav/common/time.h"

namespace mav::control {

const char* FlightModeName(FlightMode mode) {
  switch (mode) {
    case FlightMode::kDisarmed:
      return "disarmed";
    case FlightMode::kHover:
      return "hover";
    case FlightMode::kTrajectory:
      return "trajectory";
    case FlightMode::kFailsafe:
      return "failsafe";
  }
  return "?";
}

const char* ControllerTypeName(ControllerType type) {
  return type == ControllerType::kPaper ? "paper" : "lee";
}

bool AutopilotOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  auto prefixed = [&](const std::string& prefix, bool ok) {
    if (!ok && why) *why = prefix + *why;
    return ok;
  };
  std::string inner;
  std::string* w = why ? why : &inner;
  if (!prefixed("vehicle.", vehicle.IsValid(w))) return false;
  if (!prefixed("estimator.", estimator.IsValid(w))) return false;
  if (!prefixed("paper_gains.", paper_gains.IsValid(w))) return false;
  if (!prefixed("lee_gains.", lee_gains.IsValid(w))) return false;
  if (!prefixed("allocation.", allocation.IsValid(w))) return false;
  if (!prefixed("goto_limits.", goto_limits.IsValid(w))) return false;
  if (!(max_tilt_rad > 0 && max_tilt_rad < 1.5)) return fail("max_tilt_rad: must be in (0, 1.5)");
  if (!(tilt_braking_fraction >= 0 && tilt_braking_fraction <= 1)) {
    return fail("tilt_braking_fraction: must be in [0, 1] (0 = off)");
  }
  if (!(imu_timeout_s > 0 && std::isfinite(imu_timeout_s))) {
    return fail("imu_timeout_s: must be positive");
  }
  if (!(pose_timeout_s > 0 && std::isfinite(pose_timeout_s))) {
    return fail("pose_timeout_s: must be positive");
  }
  if (!(failsafe_descent_mps >= 0 && failsafe_descent_mps <= 3)) {
    return fail("failsafe_descent_mps: must be in [0, 3]");
  }
  if (!(max_trajectory_jump_m >= 0 && std::isfinite(max_trajectory_jump_m))) {
    return fail("max_trajectory_jump_m: must be >= 0");
  }
  if (!(disturbance_observer_s >= 0 && disturbance_observer_s <= 5)) {
    return fail("disturbance_observer_s: must be in [0, 5] (0 = off)");
  }
  if (!(correction_blend_s >= 0 && correction_blend_s <= 5)) {
    return fail("correction_blend_s: must be in [0, 5] (0 = off)");
  }
  if (gust_gains && !prefixed("gust_gains.", gust_gains->IsValid(w))) return false;
  if (!(gust_threshold_mps2 > 0 && std::isfinite(gust_threshold_mps2))) {
    return fail("gust_threshold_mps2: must be positive");
  }
  if (!(gust_hold_s >= 0 && std::isfinite(gust_hold_s))) return fail("gust_hold_s: must be >= 0");
  if (rest_z_m && !std::isfinite(*rest_z_m)) return fail("rest_z_m: must be finite");
  if (!(takeover_min_height_m >= 0 && std::isfinite(takeover_min_height_m))) {
    return fail("takeover_min_height_m: must be >= 0");
  }
  if (!(takeover_settle_s >= 0 && takeover_settle_s <= 10)) {
    return fail("takeover_settle_s: must be in [0, 10]");
  }
  if (!prefixed("allocation.", allocation.FitsVehicle(vehicle, w))) return false;
  return true;
}

PaperControllerGains AutopilotOptions::GustGains() {
  PaperControllerGains g;
  g.position_omega_radps.setConstant(4.0 * std::sqrt(3.0));
  g.position_zeta.setConstant(std::sqrt(3.0) / 2.0);
  g.integral_gain.setConstant(64.0);
  g.attitude_omega_radps = 16.0;
  g.attitude_zeta = 0.8;
  return g;
}

Result<Autopilot> Autopilot::Create(const AutopilotOptions& options) {
  if (std::string why; !options.IsValid(&why)) return Status::InvalidArgument(why);
  Result<Estimator> estimator = Estimator::Create(options.estimator);
  if (!estimator.ok()) return estimator.status().WithContext("estimator");
  return Autopilot(options, std::move(estimator).value());
}

namespace {

AllocationOptions AllocationFor(const AutopilotOptions& options) {
  AllocationOptions a = options.allocation;
  if (options.controller == ControllerType::kLee) a.saturation = SaturationPolicy::kClip;
  return a;
}

}  // namespace

Autopilot::Autopilot(const AutopilotOptions& options, Estimator estimator)
    : options_(options),
      estimator_(std::move(estimator)),
      allocator_(options.vehicle, AllocationFor(options)) {
  if (options.controller == ControllerType::kPaper) {
    PaperControllerOptions o;
    o.vehicle = options.vehicle;
    o.gains = options.paper_gains;
    o.max_tilt_rad = options.max_tilt_rad;
    o.tilt_braking_fraction = options.tilt_braking_fraction;
    o.allocation = options.allocation;
    controller_ = std::make_unique<PaperController>(o);
  } else {
    LeeControllerOptions o;
    o.vehicle = options.vehicle;
    o.gains = options.lee_gains;
    controller_ = std::make_unique<LeeController>(o);
  }
  zero_ = RotorVector::Zero(options.vehicle.rotor_count);
  command_ = zero_;
  motor_model_ = zero_;
}

Autopilot::Autopilot(Autopilot&&) noexcept = default;
Autopilot& Autopilot::operator=(Autopilot&&) noexcept = default;
Autopilot::~Autopilot() = default;

geometry::TrajectoryPoint Autopilot::ReferenceAt(int64_t t_ns) {
  if (!has_trajectory_) return hold_;
  const double tau = NsToSeconds(t_ns - trajectory_start_ns_);
  if (tau >= trajectory_.duration_s()) {
    // Hover at the end (a planner's spline may end with speed; the hold stops there).
    geometry::TrajectoryPoint end = trajectory_.Evaluate(trajectory_.duration_s());
    StartHold(end.position + trajectory_offset_, end.yaw_rad);
    if (mode_ == FlightMode::kTrajectory) mode_ = FlightMode::kHover;
    return hold_;
  }
  geometry::TrajectoryPoint p = trajectory_.Evaluate(std::max(tau, 0.0));
  p.position += trajectory_offset_;
  return p;
}

void Autopilot::StartHold(const Eigen::Vector3d& position, double yaw_rad) {
  hold_ = geometry::TrajectoryPoint();
  hold_.position = position;
  hold_.yaw_rad = yaw_rad;
  has_trajectory_ = false;
}

namespace {

// exp(-dt / tau), 0 for tau = 0 (no memory).
double Decay(double dt_s, double tau_s) { return tau_s > 0 ? std::exp(-dt_s / tau_s) : 0.0; }

}  // namespace

void Autopilot::UpdateDisturbance(const EstimatorState& x, double dt_s) {
  // The thrust the rotors produce now: the commands so far through the motors' lag.
  const VehicleParameters& veh = options_.vehicle;
  double thrust = 0;
  for (int i = 0; i < veh.rotor_count; ++i) {
    const double tau = command_[i] >= motor_model_[i] ? veh.motor_time_constant_up_s
                                                      : veh.motor_time_constant_down_s;
    motor_model_[i] = command_[i] + (motor_model_[i] - command_[i]) * Decay(dt_s, tau);
    thrust += veh.thrust_constant * motor_model_[i] * motor_model_[i];
  }
  const bool airborne = armed_ && x.p_world.z() > arm_z_ + 0.15;
  if (options_.disturbance_observer_s <= 0 || !airborne) {
    disturbance_.setZero();
    disturbance_slow_.setZero();
    return;
  }
  const Eigen::Vector3d a_model = x.q_world_body * Eigen::Vector3d(0, 0, thrust / veh.mass_kg) -
                                  Eigen::Vector3d(0, 0, kGravity);
  const double f = Decay(dt_s, options_.disturbance_observer_s);
  disturbance_ = f * disturbance_ + (1 - f) * (x.a_world - a_model);
  constexpr double kMaxDisturbance = 8.0;  // m/s^2: beyond, the model is wrong, not the wind
  if (disturbance_.norm() > kMaxDisturbance) disturbance_ *= kMaxDisturbance / disturbance_.norm();
  const double f_slow = Decay(dt_s, 2.0);
  disturbance_slow_ = f_slow * disturbance_slow_ + (1 - f_slow) * disturbance_;
  if (options_.gust_gains && !has_trajectory_ && mode_ == FlightMode::kHover &&
      (disturbance_ - disturbance_slow_).norm() > options_.gust_threshold_mps2) {
    gust_until_ns_ = now_ns_ + SecondsToNs(options_.gust_hold_s);
  }
}

void Autopilot::ScheduleGains() {
  auto* paper = dynamic_cast<PaperController*>(controller_.get());
  if (!paper || !options_.gust_gains) return;
  const bool gust = now_ns_ < gust_until_ns_;
  if (gust == gust_gains_active_) return;
  gust_gains_active_ = gust;
  if (gust) ++gust_activations_;
  // The integral state is kept across the switch.
  paper->SetGains(gust ? *options_.gust_gains : options_.paper_gains);
}

const RotorVector& Autopilot::FeedImu(const ImuMeasurement& imu) {
  const int64_t start_ns = MonotonicNowNs();
  const double dt_s = last_imu_ns_ > 0 ? NsToSeconds(imu.t_ns - last_imu_ns_)
                                       : 1.0 / options_.estimator.imu_rate_hz;
  estimator_.FeedImu(imu);
  now_ns_ = imu.t_ns;
  last_imu_ns_ = imu.t_ns;
  // The controller's view: the estimate with the recent corrections still being blended in.
  const double blend = Decay(dt_s, options_.correction_blend_s);
  blend_p_ *= blend;
  blend_v_ *= blend;
  blend_q_ *= blend;
  EstimatorState x = estimator_.state();
  x.p_world += blend_p_;
  x.v_world += blend_v_;
  x.q_world_body = (x.q_world_body * geometry::ExpSO3(blend_q_)).normalized();
  UpdateDisturbance(x, dt_s);
  if (!armed_) {
    command_ = zero_;
    return command_;
  }
  if (mode_ != FlightMode::kFailsafe &&
      now_ns_ - last_pose_arrival_ns_ > SecondsToNs(options_.pose_timeout_s)) {
    mode_ = FlightMode::kFailsafe;
    ++pose_timeouts_;
    has_trajectory_ = false;
  }
  if (mode_ == FlightMode::kFailsafe) {
    // Level attitude on the IMU (the estimate dead-reckons), sinking slowly: the reference
    // follows the estimate so that only the velocity terms act.
    hold_ = geometry::TrajectoryPoint();
    hold_.position = x.p_world;
    hold_.velocity = Eigen::Vector3d(0, 0, -options_.failsafe_descent_mps);
    hold_.yaw_rad = reference_.yaw_rad;
    reference_ = hold_;
  } else {
    reference_ = ReferenceAt(now_ns_);
  }
  ScheduleGains();
  controller_->SetDisturbance(disturbance_);
  const Wrench wrench = controller_->Update(x, reference_, dt_s, saturated_);
  AllocationResult alloc;
  command_ = allocator_.Allocate(wrench, &alloc);
  saturated_ = alloc.thrust_saturated || alloc.roll_pitch_scale < 1.0;
  if (saturated_) ++saturated_steps_;
  ++commands_;
  const Eigen::Vector3d rate_ref =
      x.q_world_body.conjugate() * Eigen::Vector3d(0, 0, reference_.yaw_rate_radps);
  sum_position_sq_ += (reference_.position - x.p_world).squaredNorm();
  sum_rate_sq_ += (x.omega_body - rate_ref).squaredNorm();
  ++rms_count_;
  step_ms_.Add(MsSince(start_ns));
  return command_;
}

Status Autopilot::FeedPose(const PoseMeasurement& pose) {
  const bool was_initialized = estimator_.initialized();
  const EstimatorState before = estimator_.state();
  Status s = estimator_.FeedPose(pose);
  if (!s.ok()) {
    ++poses_dropped_;
    return s;
  }
  if (was_initialized && options_.correction_blend_s > 0) {
    // Keep the controller's view continuous: the jump is blended in over correction_blend_s.
    const EstimatorState& after = estimator_.state();
    blend_p_ -= after.p_world - before.p_world;
    blend_v_ -= after.v_world - before.v_world;
    blend_q_ -= geometry::LogSO3(before.q_world_body.conjugate() * after.q_world_body);
  }
  last_pose_arrival_ns_ = now_ns_;
  return Status::Ok();
}

bool Autopilot::CheckImuTimeout(int64_t now_ns, RotorVector* command) {
  if (!armed_ || now_ns - last_imu_ns_ <= SecondsToNs(options_.imu_timeout_s)) return false;
  if (mode_ != FlightMode::kFailsafe || options_.imu_loss_policy == ImuLossPolicy::kMotorsOff) {
    ++imu_timeouts_;
  }
  if (options_.imu_loss_policy == ImuLossPolicy::kMotorsOff) {
    Disarm();
  } else {
    mode_ = FlightMode::kFailsafe;
  }
  *command = command_;
  return true;
}

Status Autopilot::Arm() {
  if (armed_) return Status::FailedPrecondition("already armed");
  if (!estimator_.converged()) {
    return Status::FailedPrecondition("the estimator has not converged (no pose yet, or too few)");
  }
  if (now_ns_ - last_pose_arrival_ns_ > SecondsToNs(options_.pose_timeout_s)) {
    return Status::FailedPrecondition("no fresh pose");
  }
  const EstimatorState& x = estimator_.state();
  ArmAt(x, x.p_world.z());
  return Status::Ok();
}

bool Autopilot::ReadyForTakeover() const {
  return estimator_.initialized() &&
         now_ns_ - estimator_.initialized_t_ns() >= SecondsToNs(options_.takeover_settle_s) &&
         now_ns_ - last_pose_arrival_ns_ <= SecondsToNs(options_.pose_timeout_s);
}

Status Autopilot::ArmInAir() {
  if (armed_) return Status::FailedPrecondition("already armed");
  if (!options_.rest_z_m) {
    return Status::FailedPrecondition(
        "in the air: the configuration does not say where the ground is (rest_z_m)");
  }
  char text[160];
  if (!ReadyForTakeover()) {
    std::snprintf(text, sizeof(text),
                  "in the air: the estimator has not merged poses for %.2f s yet, or none is "
                  "fresh",
                  options_.takeover_settle_s);
    return Status::FailedPrecondition(text);
  }
  const EstimatorState& x = estimator_.state();
  const double height = x.p_world.z() - *options_.rest_z_m;
  if (height < options_.takeover_min_height_m) {
    std::snprintf(text, sizeof(text),
                  "in the air: the vehicle is %.2f m above its resting height, not airborne "
                  "(%.2f m needed): on the ground, Arm",
                  height, options_.takeover_min_height_m);
    return Status::FailedPrecondition(text);
  }
  ArmAt(x, *options_.rest_z_m);
  // The rotors are turning already (the vehicle's own failsafe holds it up): the observer's
  // motor model starts at the hover speed, not at rest, or it would read gravity as a wind.
  const VehicleParameters& veh = options_.vehicle;
  motor_model_.setConstant(
      std::sqrt(veh.mass_kg * kGravity / (veh.rotor_count * veh.thrust_constant)));
  command_ = motor_model_;
  return Status::Ok();
}

void Autopilot::ArmAt(const EstimatorState& x, double ground_z_m) {
  const Eigen::Matrix3d R = x.q_world_body.toRotationMatrix();
  controller_->Reset();
  arm_z_ = ground_z_m;  // the disturbance observer acts once 0.15 m above it
  disturbance_.setZero();
  disturbance_slow_.setZero();
  gust_until_ns_ = 0;
  ScheduleGains();
  StartHold(x.p_world, std::atan2(R(1, 0), R(0, 0)));
  reference_ = hold_;
  armed_ = true;
  mode_ = FlightMode::kHover;
  saturated_ = false;
  sum_position_sq_ = sum_rate_sq_ = 0;
  rms_count_ = 0;
}

void Autopilot::Disarm() {
  armed_ = false;
  mode_ = FlightMode::kDisarmed;
  has_trajectory_ = false;
  command_ = zero_;
}

namespace {

Status CheckFlying(bool armed) {
  return armed ? Status::Ok() : Status::FailedPrecondition("disarmed: Arm first");
}

}  // namespace

Status Autopilot::HoldPosition(const Eigen::Vector3d& position, double yaw_rad) {
  MAV_RETURN_IF_ERROR(CheckFlying(armed_));
  if (!position.allFinite()) return Status::InvalidArgument("position: must be finite");
  if (!std::isfinite(yaw_rad)) return Status::InvalidArgument("yaw_rad: must be finite");
  if (mode_ == FlightMode::kFailsafe &&
      now_ns_ - last_pose_arrival_ns_ > SecondsToNs(options_.pose_timeout_s)) {
    return Status::FailedPrecondition("failsafe: no fresh pose");
  }
  StartHold(position, yaw_rad);
  mode_ = FlightMode::kHover;
  return Status::Ok();
}

Status Autopilot::Hover(const Eigen::Vector3d& position, double yaw_rad, const GoToLimits* limits) {
  MAV_RETURN_IF_ERROR(CheckFlying(armed_));
  if (!position.allFinite()) return Status::InvalidArgument("position: must be finite");
  if (!std::isfinite(yaw_rad)) return Status::InvalidArgument("yaw_rad: must be finite");
  if (mode_ == FlightMode::kFailsafe) {
    if (now_ns_ - last_pose_arrival_ns_ > SecondsToNs(options_.pose_timeout_s)) {
      return Status::FailedPrecondition("failsafe: no fresh pose");
    }
    // Start the move from where the vehicle is, at rest.
    reference_ = geometry::TrajectoryPoint();
    reference_.position = estimator_.state().p_world;
    reference_.yaw_rad = hold_.yaw_rad;
  }
  MAV_ASSIGN_OR_RETURN(
      geometry::PolynomialTrajectory move,
      MakeGoToTrajectory(reference_, position, yaw_rad, limits ? *limits : options_.goto_limits));
  trajectory_ = std::move(move);
  trajectory_start_ns_ = now_ns_;
  trajectory_offset_.setZero();
  has_trajectory_ = true;
  mode_ = FlightMode::kHover;
  return Status::Ok();
}

Status Autopilot::SetTrajectory(const geometry::PolynomialTrajectory& trajectory,
                                int64_t start_t_ns, const Eigen::Vector3d& offset,
                                bool allow_jump) {
  MAV_RETURN_IF_ERROR(CheckFlying(armed_));
  if (trajectory.empty()) return Status::InvalidArgument("trajectory: no segments");
  if (!offset.allFinite()) return Status::InvalidArgument("offset: must be finite");
  if (mode_ == FlightMode::kFailsafe &&
      now_ns_ - last_pose_arrival_ns_ > SecondsToNs(options_.pose_timeout_s)) {
    return Status::FailedPrecondition("failsafe: no fresh pose");
  }
  const Eigen::Vector3d start = trajectory.Evaluate(0).position + offset;
  const double jump = (start - reference_.position).norm();
  if (!allow_jump && jump > options_.max_trajectory_jump_m) {
    return Status::InvalidArgument("trajectory: starts " + std::to_string(jump) +
                                   " m from the current reference (allow_jump to accept)");
  }
  trajectory_ = trajectory;
  trajectory_start_ns_ = start_t_ns == 0 ? now_ns_ : start_t_ns;
  trajectory_offset_ = offset;
  has_trajectory_ = true;
  mode_ = FlightMode::kTrajectory;
  return Status::Ok();
}

Status Autopilot::SetPaperGains(const PaperControllerGains& gains) {
  if (std::string why; !gains.IsValid(&why)) return Status::InvalidArgument(why);
  options_.paper_gains = gains;
  if (auto* c = dynamic_cast<PaperController*>(controller_.get()); c && !gust_gains_active_) {
    c->SetGains(gains);
  }
  return Status::Ok();
}

Status Autopilot::SetLeeGains(const LeeControllerGains& gains) {
  if (std::string why; !gains.IsValid(&why)) return Status::InvalidArgument(why);
  options_.lee_gains = gains;
  if (auto* c = dynamic_cast<LeeController*>(controller_.get())) c->SetGains(gains);
  return Status::Ok();
}

AutopilotStatus Autopilot::status() const {
  AutopilotStatus s;
  s.mode = mode_;
  s.armed = armed_;
  s.estimator_converged = estimator_.converged();
  const EstimatorCounters& c = estimator_.counters();
  s.imu_samples = c.imu_samples;
  s.poses = c.poses_merged;
  s.poses_dropped = poses_dropped_;
  s.commands = commands_;
  s.saturated_steps = saturated_steps_;
  s.imu_timeouts = imu_timeouts_;
  s.pose_timeouts = pose_timeouts_;
  s.gust_activations = gust_activations_;
  if (rms_count_ > 0) {
    s.position_rms_m = std::sqrt(sum_position_sq_ / rms_count_);
    s.angular_rate_rms_radps = std::sqrt(sum_rate_sq_ / rms_count_);
  }
  s.step_ms = step_ms_.Summary();
  return s;
}

AutopilotState Autopilot::state() const {
  AutopilotState s;
  s.mode = mode_;
  s.estimate = estimator_.state();
  s.estimator_converged = estimator_.converged();
  s.reference = reference_;
  s.position_error = reference_.position - s.estimate.p_world;
  s.velocity_error = reference_.velocity - s.estimate.v_world;
  s.integral = controller_->integral_acceleration();
  s.disturbance = disturbance_;
  s.rotor_speeds = command_;
  if (has_trajectory_) {
    s.trajectory_t_s = NsToSeconds(now_ns_ - trajectory_start_ns_);
    s.trajectory_duration_s = trajectory_.duration_s();
  }
  return s;
}

}  // namespace mav::control
