#include <cmath>

#include "mav/common/check.h"
#include "mav/control/controller.h"
#include "mav/geometry/se3.h"

namespace mav::control {

bool LeeControllerGains::IsValid(std::string* why) const {
  auto check = [&](const Eigen::Vector3d& v, const char* name) {
    if ((v.array() > 0).all() && v.allFinite()) return true;
    if (why) *why = std::string(name) + ": every component must be positive";
    return false;
  };
  return check(position_gain, "position_gain") && check(velocity_gain, "velocity_gain") &&
         check(attitude_gain, "attitude_gain") && check(angular_rate_gain, "angular_rate_gain");
}

std::vector<std::complex<double>> LeeControllerGains::LinearisedPoles(
    const VehicleParameters& vehicle) const {
  const double m = vehicle.mass_kg;
  const Eigen::Vector3d& J = vehicle.inertia_kgm2;
  std::vector<std::complex<double>> poles;
  auto add = [&](const std::vector<double>& c) {
    for (const auto& r : PolynomialRoots(c)) poles.push_back(r);
  };
  // x is driven through pitch (body y torque), y through roll (body x torque).
  for (int a = 0; a < 2; ++a) {
    const int b = 1 - a;
    const double kr = attitude_gain[b] / J[b], kw = angular_rate_gain[b] / J[b];
    add({1, kw, kr, kr * velocity_gain[a] / m, kr * position_gain[a] / m});
  }
  add({1, velocity_gain[2] / m, position_gain[2] / m});
  add({1, angular_rate_gain[2] / J[2], attitude_gain[2] / J[2]});
  return poles;
}

bool LeeControllerOptions::IsValid(std::string* why) const {
  return vehicle.IsValid(why) && gains.IsValid(why);
}

LeeController::LeeController(const LeeControllerOptions& options) : options_(options) {
  std::string why;
  MAV_CHECK(options.IsValid(&why)) << why;
}

Wrench LeeController::Update(const EstimatorState& x, const TrajectoryPoint& ref, double /*dt_s*/,
                             bool /*saturated*/) {
  const LeeControllerGains& g = options_.gains;
  const double m = options_.vehicle.mass_kg;
  const Eigen::Matrix3d R = x.q_world_body.toRotationMatrix();
  const Eigen::Vector3d e_x = x.p_world - ref.position;
  const Eigen::Vector3d e_v = x.v_world - ref.velocity;
  // Desired force (world): -k_x e_x - k_v e_v + m g e3 + m a_r.
  const Eigen::Vector3d force = -g.position_gain.cwiseProduct(e_x) -
                                g.velocity_gain.cwiseProduct(e_v) +
                                m * (Eigen::Vector3d(0, 0, kGravity) + ref.acceleration);
  const double thrust = std::max(0.0, force.dot(R.col(2)));

  // Desired attitude: thrust axis along the force, heading from the reference yaw.
  Eigen::Vector3d b3 = force.norm() > 1e-6 ? force.normalized() : Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d b1_ref(std::cos(ref.yaw_rad), std::sin(ref.yaw_rad), 0);
  Eigen::Vector3d b2 = b3.cross(b1_ref);
  if (b2.norm() < 1e-6) b2 = b3.unitOrthogonal();
  b2.normalize();
  Eigen::Matrix3d R_d;
  R_d.col(0) = b2.cross(b3);
  R_d.col(1) = b2;
  R_d.col(2) = b3;
  const Eigen::Vector3d e_R = 0.5 * geometry::Vee(R_d.transpose() * R - R.transpose() * R_d);
  const Eigen::Vector3d w_d(0, 0, ref.yaw_rate_radps);
  const Eigen::Vector3d e_w = x.omega_body - R.transpose() * R_d * w_d;
  const Eigen::Vector3d torque =
      -g.attitude_gain.cwiseProduct(e_R) - g.angular_rate_gain.cwiseProduct(e_w);
  Wrench out;
  out << thrust, torque;
  return out;
}

}  // namespace mav::control
