#include "mav/sim/trajectory.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <sstream>

#include "mav/common/check.h"
#include "random.h"

namespace mav::sim {
namespace {

using Spline3 = geometry::UniformQuinticBSpline<3>;

using internal::Rng;

constexpr double kDeg = M_PI / 180.0;

// How a profile moves. Speeds follow from step / knot_dt (the spline smooths the corners, so the
// mean speed is a little below the control polygon's).
struct ProfileParams {
  double knot_dt = 1.0;              // s between control points
  double step_min = 0.5;             // m, horizontal distance between successive control points
  double step_max = 0.8;             // m
  double max_turn = 30 * kDeg;       // heading change per knot
  double vertical_sigma = 0.1;       // m, std of the height change per knot
  double bob_amplitude = 0.0;        // m, vertical sine bobbing (hard)
  double bob_period_knots = 5.0;     // knots per bobbing period
  double yaw_deviation = 15 * kDeg;  // bound on the slow random offset from the look-at bearing
  double yaw_deviation_sigma = 5 * kDeg;  // per-knot innovation of that offset
  double yaw_deviation_memory = 0.8;      // AR(1) coefficient of that offset
  // A slow look-around: the yaw scans +-scan_amplitude about the bearing with a period of about
  // scan_period_knots (randomly stretched), so that the camera sweeps the structure it faces.
  double scan_amplitude = 0.0;
  double scan_period_knots = 6.0;
  double max_yaw_step = 20 * kDeg;  // per knot
  double hold_probability = 0.0;    // chance per knot to start a pure-rotation phase (hard)
  int hold_knots = 0;               // knots a pure-rotation phase lasts
  double sweep_min = 0.0;           // rad, yaw sweep amplitude during a hold
  double sweep_max = 0.0;
  double max_tilt = 5 * kDeg;  // roll/pitch bound
  double tilt_jitter = 0.0;    // rad, random roll/pitch added to the quasi-static tilt
};

ProfileParams ParamsFor(MotionProfile profile) {
  ProfileParams p;
  switch (profile) {
    case MotionProfile::kEasy:
      p.knot_dt = 1.5;
      p.step_min = 0.5;
      p.step_max = 0.8;
      p.max_turn = 30 * kDeg;
      p.vertical_sigma = 0.08;
      p.yaw_deviation = 40 * kDeg;
      p.yaw_deviation_sigma = 8 * kDeg;
      p.scan_amplitude = 35 * kDeg;
      p.scan_period_knots = 6;
      p.max_yaw_step = 40 * kDeg;
      p.max_tilt = 5 * kDeg;
      p.tilt_jitter = 0.5 * kDeg;
      break;
    case MotionProfile::kMedium:
      p.knot_dt = 1.0;
      p.step_min = 0.8;
      p.step_max = 1.1;
      p.max_turn = 45 * kDeg;
      p.vertical_sigma = 0.15;
      p.yaw_deviation = 55 * kDeg;
      p.yaw_deviation_sigma = 12 * kDeg;
      p.scan_amplitude = 40 * kDeg;
      p.scan_period_knots = 6;
      p.max_yaw_step = 60 * kDeg;
      p.max_tilt = 12 * kDeg;
      p.tilt_jitter = 2.5 * kDeg;
      break;
    case MotionProfile::kHard:
      p.knot_dt = 0.5;
      p.step_min = 0.35;
      p.step_max = 0.75;
      p.max_turn = 70 * kDeg;
      p.vertical_sigma = 0.05;
      p.bob_amplitude = 0.35;
      p.bob_period_knots = 5.0;
      p.yaw_deviation = 45 * kDeg;
      p.scan_amplitude = 30 * kDeg;
      p.scan_period_knots = 6;
      p.yaw_deviation_sigma = 12 * kDeg;
      p.max_yaw_step = 60 * kDeg;
      p.hold_probability = 0.1;
      p.hold_knots = 6;
      p.sweep_min = 50 * kDeg;
      p.sweep_max = 90 * kDeg;
      p.max_tilt = 20 * kDeg;
      p.tilt_jitter = 6 * kDeg;
      break;
    case MotionProfile::kPlant:
      p.knot_dt = 2.0;
      p.step_min = 3.0;
      p.step_max = 5.0;
      p.max_turn = 35 * kDeg;
      p.vertical_sigma = 0.8;
      p.yaw_deviation = 35 * kDeg;
      p.scan_amplitude = 20 * kDeg;
      p.scan_period_knots = 6;
      p.yaw_deviation_sigma = 8 * kDeg;
      p.max_yaw_step = 25 * kDeg;
      p.max_tilt = 15 * kDeg;
      p.tilt_jitter = 1.0 * kDeg;
      break;
  }
  return p;
}

double WrapAngle(double a) { return std::remainder(a, 2.0 * M_PI); }

// Horizontal bearing from p to target, or nullopt when p is (almost) above/below it.
std::optional<double> Bearing(const Eigen::Vector3d& p, const Eigen::Vector3d& target) {
  const Eigen::Vector2d d = (target - p).head<2>();
  if (d.norm() < 0.5) return std::nullopt;
  return std::atan2(d.y(), d.x());
}

// Samples the position control points: a random walk with momentum inside the bounds whose
// spline keeps `min_clearance` (checked densely, segment by segment, as soon as a segment's six
// control points are known; backtracks when a dead end is reached).
class PathSampler {
 public:
  PathSampler(const TrajectoryOptions& options, const ProfileParams& params, int num_ctrl)
      : options_(options), params_(params), num_ctrl_(num_ctrl), rng_(options.seed) {
    const Eigen::Vector3d extent = options.bounds.sizes();
    const double horizontal = std::min(extent.x(), extent.y());
    // Small boxes get proportionally shorter steps (and so a slower trajectory).
    step_scale_ = std::min(1.0, 0.35 * horizontal / params.step_max);
    bob_amplitude_ = std::min(params.bob_amplitude, 0.3 * extent.z());
    look_avoid_radius_ = std::min(1.0, 0.15 * horizontal);
  }

  // Fills ctrl (num_ctrl points) and hold flags; false when the attempt budget is exhausted.
  bool Sample(std::vector<Eigen::Vector3d>* ctrl, std::vector<bool>* hold) {
    if (!SampleStart()) return false;
    // A gentle start: the first control points coincide, so the body starts almost at rest.
    constexpr int kStartRepeats = 3;
    ctrl_.assign(kStartRepeats, start_);
    hold_.assign(kStartRepeats, false);
    heading_.assign(kStartRepeats, rng_.Uniform(-M_PI, M_PI));
    hold_left_.assign(kStartRepeats, 0);
    int64_t budget = 200LL * num_ctrl_ + 2000;
    int failures_here = 0;
    while (static_cast<int>(ctrl_.size()) < num_ctrl_) {
      if (--budget < 0) return false;
      if (TryExtend(failures_here)) {
        failures_here = 0;
        continue;
      }
      if (++failures_here >= 40) {
        // Dead end: drop the last two points (never the start) and try again from there.
        const size_t keep = std::max<size_t>(kStartRepeats, ctrl_.size() - 2);
        ctrl_.resize(keep);
        hold_.resize(keep);
        heading_.resize(keep);
        hold_left_.resize(keep);
        failures_here = 0;
      }
    }
    *ctrl = ctrl_;
    *hold = hold_;
    return true;
  }

 private:
  bool InsideBounds(const Eigen::Vector3d& p) const { return options_.bounds.contains(p); }

  bool PointClear(const Eigen::Vector3d& p) const {
    return !options_.clearance || options_.clearance(p) >= options_.min_clearance;
  }

  bool SampleStart() {
    for (int attempt = 0; attempt < 2000; ++attempt) {
      Eigen::Vector3d p;
      for (int k = 0; k < 3; ++k) {
        // Start in the central 60 % of the box, leaving room to move in every direction.
        const double lo = options_.bounds.min()[k], hi = options_.bounds.max()[k];
        const double mid = 0.5 * (lo + hi), half = 0.3 * (hi - lo);
        p[k] = rng_.Uniform(mid - half, mid + half);
      }
      const bool near_look = (p - options_.look_at).head<2>().norm() < look_avoid_radius_;
      if (!PointClear(p) || (near_look && attempt < 1000)) continue;
      start_ = p;
      return true;
    }
    return false;
  }

  // Proposes one more control point and keeps it if the bounds and clearance hold.
  bool TryExtend(int failures_here) {
    const size_t j = ctrl_.size();
    const Eigen::Vector3d& prev = ctrl_.back();
    Eigen::Vector3d candidate;
    double heading = heading_.back();
    int hold_left = std::max(0, hold_left_.back() - 1);
    bool hold = hold_left > 0;
    if (!hold && params_.hold_probability > 0 && j > 6 &&
        rng_.Uniform() < params_.hold_probability) {
      hold = true;
      hold_left = params_.hold_knots;
    }
    if (hold && failures_here < 10) {
      // Pure rotation: the position stays put up to centimetre jitter.
      candidate = prev + 0.01 * Eigen::Vector3d(rng_.Normal(), rng_.Normal(), rng_.Normal());
    } else {
      hold = false;
      hold_left = 0;
      // Widen the turn range after repeated failures, up to any direction.
      const double turn_range = std::min(M_PI, params_.max_turn * (1.0 + 0.25 * failures_here));
      heading = WrapAngle(heading + rng_.Uniform(-turn_range, turn_range));
      const double step = step_scale_ * rng_.Uniform(params_.step_min, params_.step_max);
      candidate = prev + step * Eigen::Vector3d(std::cos(heading), std::sin(heading), 0.0);
      double z = prev.z() + params_.vertical_sigma * rng_.Normal();
      if (bob_amplitude_ > 0) {
        // Bobbing around a slowly drifting mean height.
        const double phase = 2.0 * M_PI / params_.bob_period_knots;
        const double bob_prev = bob_amplitude_ * std::sin(phase * (j - 1.0));
        const double bob_now = bob_amplitude_ * std::sin(phase * static_cast<double>(j));
        z += bob_now - bob_prev;
      }
      candidate.z() = z;
      const bool near_look = (candidate - options_.look_at).head<2>().norm() < look_avoid_radius_;
      if (near_look && failures_here < 20) return false;
    }
    if (!InsideBounds(candidate) || !PointClear(candidate)) return false;
    ctrl_.push_back(candidate);
    if (!SegmentClear()) {
      ctrl_.pop_back();
      return false;
    }
    hold_.push_back(hold);
    heading_.push_back(heading);
    hold_left_.push_back(hold_left);
    return true;
  }

  // The segment whose last control point was just added, sampled at most 5 cm apart: dp/du of a
  // uniform B-spline segment is a convex combination of the control point differences, so
  // |dp/du| <= the longest edge of the control polygon bounds the spacing of uniform u samples.
  bool SegmentClear() const {
    if (!options_.clearance || ctrl_.size() < static_cast<size_t>(Spline3::kOrder)) return true;
    const std::vector<Eigen::Vector3d> six(ctrl_.end() - Spline3::kOrder, ctrl_.end());
    double longest_edge = 0;
    for (int k = 1; k < Spline3::kOrder; ++k) {
      longest_edge = std::max(longest_edge, (six[k] - six[k - 1]).norm());
    }
    const Spline3 segment(0.0, 1.0, six);
    const int samples = std::max(4, static_cast<int>(std::ceil(longest_edge / 0.05)));
    for (int s = 0; s <= samples; ++s) {
      if (!PointClear(segment.Evaluate(static_cast<double>(s) / samples))) return false;
    }
    return true;
  }

  const TrajectoryOptions& options_;
  const ProfileParams& params_;
  const int num_ctrl_;
  Rng rng_;
  double step_scale_ = 1;
  double bob_amplitude_ = 0;
  double look_avoid_radius_ = 1;
  Eigen::Vector3d start_ = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> ctrl_;
  std::vector<bool> hold_;
  std::vector<double> heading_;
  std::vector<int> hold_left_;
};

// Yaw control points: the bearing to look_at plus a slow scan and a bounded random offset, swept
// back and forth during holds, unwrapped and rate limited. Periods of >= 6 knots survive the
// spline (a quintic B-spline passes 76 % of a six-knot period, 13 % of a two-knot one).
std::vector<double> SampleYaw(const std::vector<Eigen::Vector3d>& ctrl,
                              const std::vector<bool>& hold, const TrajectoryOptions& options,
                              const ProfileParams& params, Rng* rng) {
  std::vector<double> yaw(ctrl.size());
  double offset = 0;
  double previous = Bearing(ctrl[0], options.look_at).value_or(rng->Uniform(-M_PI, M_PI));
  int hold_index = 0;
  double sweep = 0;
  double scan_phase = rng->Uniform(0.0, 2.0 * M_PI);
  for (size_t j = 0; j < ctrl.size(); ++j) {
    offset = params.yaw_deviation_memory * offset + params.yaw_deviation_sigma * rng->Normal();
    scan_phase += 2.0 * M_PI / params.scan_period_knots * rng->Uniform(0.7, 1.3);
    const double deviation = std::clamp(offset + params.scan_amplitude * std::sin(scan_phase),
                                        -params.yaw_deviation, params.yaw_deviation);
    double sweep_offset = 0;
    if (hold[j]) {
      if (hold_index == 0) {
        sweep = rng->Uniform(params.sweep_min, params.sweep_max) * (rng->Uniform() < 0.5 ? -1 : 1);
      }
      // One sine period of kSweepKnots knots: out to one side, back, out to the other side, back.
      constexpr double kSweepKnots = 6.0;
      sweep_offset = sweep * std::sin(2.0 * M_PI * (hold_index + 1) / kSweepKnots);
      ++hold_index;
    } else {
      hold_index = 0;
    }
    const std::optional<double> bearing = Bearing(ctrl[j], options.look_at);
    const double target = bearing ? *bearing + deviation + sweep_offset : previous;
    const double step =
        std::clamp(WrapAngle(target - previous), -params.max_yaw_step, params.max_yaw_step);
    yaw[j] = (j == 0) ? target : previous + step;
    previous = yaw[j];
  }
  return yaw;
}

// Roll and pitch of a multicopter in quasi-static flight: the thrust axis (vehicle z) is aligned
// with a - g, plus a little random wobble, bounded by the profile's tilt.
Eigen::Vector2d TiltFor(const Eigen::Vector3d& a_world, double yaw, const ProfileParams& params,
                        Rng* rng) {
  const Eigen::Vector3d z_world = (a_world - kGravityWorld).normalized();
  // Express the thrust axis in the yaw-only frame: z_local = Rz(-yaw) z_world.
  const Eigen::Vector3d z_local = Eigen::AngleAxisd(-yaw, Eigen::Vector3d::UnitZ()) * z_world;
  // Ry(pitch) Rx(roll) e_z = (cos(roll) sin(pitch), -sin(roll), cos(roll) cos(pitch)).
  double roll = -std::asin(std::clamp(z_local.y(), -1.0, 1.0));
  double pitch = std::atan2(z_local.x(), z_local.z());
  roll += params.tilt_jitter * rng->Normal();
  pitch += params.tilt_jitter * rng->Normal();
  return {std::clamp(roll, -params.max_tilt, params.max_tilt),
          std::clamp(pitch, -params.max_tilt, params.max_tilt)};
}

}  // namespace

Eigen::Matrix3d RotationVehicleBody() {
  Eigen::Matrix3d r;
  // Columns: body x, y, z expressed in the vehicle frame.
  r << 0, 0, 1,  //
      0, -1, 0,  //
      1, 0, 0;
  return r;
}

bool TrajectoryOptions::IsValid(std::string* why) const {
  std::ostringstream msg;
  const int p = static_cast<int>(profile);
  if (p < static_cast<int>(MotionProfile::kEasy) || p > static_cast<int>(MotionProfile::kPlant)) {
    msg << "profile: unknown motion profile " << p;
  } else if (!std::isfinite(duration_s) || duration_s <= 0 || duration_s > 86400) {
    msg << "duration_s: must be in (0, 86400] s, got " << duration_s;
  } else if (!bounds.min().allFinite() || !bounds.max().allFinite()) {
    msg << "bounds: corners must be finite";
  } else if (!(bounds.min().array() < bounds.max().array()).all()) {
    msg << "bounds: min (" << bounds.min().transpose() << ") must be below max ("
        << bounds.max().transpose() << ") on every axis";
  } else if (!std::isfinite(min_clearance) || min_clearance < 0) {
    msg << "min_clearance: must be finite and >= 0, got " << min_clearance;
  } else if (!look_at.allFinite()) {
    msg << "look_at: must be finite";
  } else {
    return true;
  }
  if (why) *why = msg.str();
  return false;
}

Result<Trajectory> Trajectory::Create(const TrajectoryOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument(why);
  const ProfileParams params = ParamsFor(options.profile);
  const int num_ctrl = Spline3::NumControlPointsFor(options.duration_s, params.knot_dt);

  std::vector<Eigen::Vector3d> position_ctrl;
  std::vector<bool> hold;
  PathSampler sampler(options, params, num_ctrl);
  if (!sampler.Sample(&position_ctrl, &hold)) {
    std::ostringstream msg;
    msg << "could not sample a " << options.duration_s << " s path inside bounds ["
        << options.bounds.min().transpose() << "] - [" << options.bounds.max().transpose()
        << "] keeping min_clearance " << options.min_clearance
        << " m within the attempt budget; widen the bounds or lower min_clearance";
    return Status::FailedPrecondition(msg.str());
  }

  Trajectory trajectory;
  trajectory.duration_s_ = options.duration_s;
  trajectory.knot_dt_ = params.knot_dt;
  trajectory.position_ = Spline3(0.0, params.knot_dt, position_ctrl);

  // A separate stream for the attitude, so that attitude tweaks never change the path.
  Rng rng(options.seed ^ 0x9e3779b97f4a7c15ULL);
  const std::vector<double> yaw = SampleYaw(position_ctrl, hold, options, params, &rng);
  std::vector<Eigen::Vector3d> rpy_ctrl(num_ctrl);
  const Spline3& position = trajectory.position_;
  for (int j = 0; j < num_ctrl; ++j) {
    const double t = std::clamp(position.ControlPointTime(j), position.t_min(), position.t_max());
    const Eigen::Vector2d tilt = TiltFor(position.Evaluate(t, 2), yaw[j], params, &rng);
    rpy_ctrl[j] = Eigen::Vector3d(tilt.x(), tilt.y(), yaw[j]);
  }
  trajectory.rpy_ = Spline3(0.0, params.knot_dt, rpy_ctrl);
  return trajectory;
}

TrajectoryState Trajectory::Evaluate(double t_s) const {
  MAV_CHECK(position_.num_control_points() > 0) << "Evaluate() on a default-constructed Trajectory";
  const double t = std::clamp(t_s, 0.0, duration_s_);
  const auto p = position_.EvaluateUpTo<2>(t);
  const auto e = rpy_.EvaluateUpTo<2>(t);
  const double roll = e[0].x(), pitch = e[0].y(), yaw = e[0].z();
  const double sr = std::sin(roll), cr = std::cos(roll);
  const double sp = std::sin(pitch), cp = std::cos(pitch);
  const double roll_dot = e[1].x(), pitch_dot = e[1].y();

  // omega_V = E(roll, pitch) * rpy_dot, alpha_V = E * rpy_ddot + dE/dt * rpy_dot.
  Eigen::Matrix3d euler_rate;
  euler_rate << 1, 0, -sp,  //
      0, cr, sr * cp,       //
      0, -sr, cr * cp;
  Eigen::Matrix3d euler_rate_dot;
  euler_rate_dot << 0, 0, -cp * pitch_dot,                          //
      0, -sr * roll_dot, cr * cp * roll_dot - sr * sp * pitch_dot,  //
      0, -cr * roll_dot, -sr * cp * roll_dot - cr * sp * pitch_dot;
  const Eigen::Vector3d omega_vehicle = euler_rate * e[1];
  const Eigen::Vector3d alpha_vehicle = euler_rate * e[2] + euler_rate_dot * e[1];

  const Eigen::Matrix3d r_vehicle_body = RotationVehicleBody();
  TrajectoryState state;
  state.T_world_body =
      geometry::SE3(geometry::RotationFromRollPitchYaw(roll, pitch, yaw) * r_vehicle_body, p[0]);
  state.v_world = p[1];
  state.a_world = p[2];
  state.omega_body = r_vehicle_body.transpose() * omega_vehicle;
  state.alpha_body = r_vehicle_body.transpose() * alpha_vehicle;
  return state;
}

}  // namespace mav::sim
