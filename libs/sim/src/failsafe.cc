#include "mav/sim/failsafe.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>
#include <Eigen/SVD>

namespace mav::sim {

namespace {

bool Positive(double v) { return v > 0 && std::isfinite(v); }

}  // namespace

bool FailsafeOptions::IsValid(std::string* why) const {
  auto fail = [why](const std::string& message) {
    if (why != nullptr) *why = message;
    return false;
  };
  if (!Positive(descent_mps) || descent_mps > 3) return fail("descent_mps: must be in (0, 3]");
  if (!Positive(climb_gain_per_s)) return fail("climb_gain_per_s: must be positive");
  if (!Positive(attitude_gain_per_s2)) return fail("attitude_gain_per_s2: must be positive");
  if (!Positive(rate_gain_per_s)) return fail("rate_gain_per_s: must be positive");
  return true;
}

Result<DescentFailsafe> DescentFailsafe::Create(const MulticopterParams& vehicle,
                                                const FailsafeOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument("failsafe: " + why);
  if (!vehicle.IsValid(&why)) return Status::InvalidArgument("failsafe vehicle: " + why);
  return DescentFailsafe(vehicle, options);
}

DescentFailsafe::DescentFailsafe(const MulticopterParams& vehicle, const FailsafeOptions& options)
    : vehicle_(vehicle), options_(options) {
  // The wrench of unit thrust on each rotor, as sim::Multicopter computes it: thrust along body
  // z at the rotor's position, the drag torque against its spin.
  const int n = vehicle.rotor_count;
  Eigen::Matrix<double, 4, Eigen::Dynamic, Eigen::ColMajor, 4, kMaxRotors> allocation(4, n);
  for (int i = 0; i < n; ++i) {
    const double a = vehicle.rotor_angles_deg[static_cast<size_t>(i)] * M_PI / 180.0;
    const Eigen::Vector3d r = vehicle.arm_length_m * Eigen::Vector3d(std::cos(a), std::sin(a), 0.0);
    const Eigen::Vector3d moment = r.cross(Eigen::Vector3d::UnitZ());
    allocation.col(i) << 1.0, moment.x(), moment.y(),
        -vehicle.rotor_directions[static_cast<size_t>(i)] * vehicle.moment_constant_m;
  }
  thrusts_from_wrench_ = allocation.completeOrthogonalDecomposition().pseudoInverse();
}

RotorVector DescentFailsafe::Command(const MulticopterState& state) const {
  const int n = vehicle_.rotor_count;
  if (state.on_ground) return RotorVector::Zero(n);
  const double m = vehicle_.mass_kg, g = vehicle_.gravity_mps2;
  const Eigen::Matrix3d R = state.q_world_body.normalized().toRotationMatrix();
  const Eigen::Vector3d b3 = R.col(2);
  // Thrust: the vertical speed held at -descent, the tilt's loss of lift made up.
  const double accel = options_.climb_gain_per_s * (-options_.descent_mps - state.v_world.z());
  const double thrust =
      std::clamp(m * (g + accel) / std::max(b3.z(), 0.5), 0.2 * m * g, 1.5 * m * g);
  // Torque: back to level (the axis that turns b3 onto e3, in the body frame), rates damped
  // (the yaw rate too: the heading is let go, not held).
  const Eigen::Vector3d level_error = R.transpose() * b3.cross(Eigen::Vector3d::UnitZ());
  const Eigen::Vector3d J = vehicle_.inertia_kgm2;
  const Eigen::Vector3d& w = state.omega_body;
  const Eigen::Vector3d torque =
      J.cwiseProduct(options_.attitude_gain_per_s2 * level_error - options_.rate_gain_per_s * w) +
      w.cross(J.cwiseProduct(w));
  Eigen::Vector4d wrench;
  wrench << thrust, torque;
  const double f_max =
      vehicle_.thrust_constant * vehicle_.max_rotor_speed_radps * vehicle_.max_rotor_speed_radps;
  RotorVector speeds(n);
  const Eigen::VectorXd thrusts = thrusts_from_wrench_ * wrench;
  for (int i = 0; i < n; ++i) {
    speeds[i] = std::sqrt(std::clamp(thrusts[i], 0.0, f_max) / vehicle_.thrust_constant);
  }
  return speeds;
}

}  // namespace mav::sim
