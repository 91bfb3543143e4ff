#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

#include "mav/common/check.h"
#include "mav/control/controller.h"

namespace mav::control {

namespace {

bool Fail(std::string* why, const std::string& m) {
  if (why) *why = m;
  return false;
}

bool PositiveFinite(double x) { return x > 0 && std::isfinite(x); }

// Wraps an angle into (-pi, pi].
double WrapAngle(double a) { return std::remainder(a, 2.0 * M_PI); }

}  // namespace

std::vector<std::complex<double>> PolynomialRoots(const std::vector<double>& c) {
  MAV_CHECK(c.size() >= 2 && c[0] != 0) << "polynomial needs a leading coefficient";
  const int n = static_cast<int>(c.size()) - 1;
  Eigen::MatrixXd companion = Eigen::MatrixXd::Zero(n, n);
  for (int i = 0; i < n; ++i) companion(0, i) = -c[i + 1] / c[0];
  for (int i = 1; i < n; ++i) companion(i, i - 1) = 1;
  const Eigen::VectorXcd roots = companion.eigenvalues();
  return std::vector<std::complex<double>>(roots.data(), roots.data() + n);
}

bool PaperControllerGains::IsValid(std::string* why) const {
  for (int a = 0; a < 3; ++a) {
    static const char* const kAxis[3] = {".x", ".y", ".z"};  // the world axes
    const std::string axis = kAxis[a];
    if (!PositiveFinite(position_omega_radps[a])) {
      return Fail(why, "position_omega_radps" + axis + ": must be positive");
    }
    if (!(position_zeta[a] > 0 && position_zeta[a] <= 3)) {
      return Fail(why, "position_zeta" + axis + ": must be in (0, 3]");
    }
    if (!(integral_gain[a] >= 0 && std::isfinite(integral_gain[a]))) {
      return Fail(why, "integral_gain" + axis + ": must be >= 0");
    }
    // Routh-Hurwitz for s^3 + 2 zeta w s^2 + w^2 s + K_i.
    const double w = position_omega_radps[a];
    if (integral_gain[a] >= 2 * position_zeta[a] * w * w * w) {
      return Fail(why, "integral_gain" + axis + ": must be below 2 zeta w^3 (stability)");
    }
  }
  if (!(integral_limit_mps2 >= 0 && std::isfinite(integral_limit_mps2))) {
    return Fail(why, "integral_limit_mps2: must be >= 0");
  }
  if (!PositiveFinite(attitude_omega_radps)) {
    return Fail(why, "attitude_omega_radps: must be positive");
  }
  if (!(attitude_zeta > 0 && attitude_zeta <= 3)) return Fail(why, "attitude_zeta: (0, 3]");
  if (!PositiveFinite(yaw_omega_radps)) return Fail(why, "yaw_omega_radps: must be positive");
  if (!(yaw_zeta > 0 && yaw_zeta <= 3)) return Fail(why, "yaw_zeta: must be in (0, 3]");
  return true;
}

std::vector<std::complex<double>> PaperControllerGains::DesignedPoles() const {
  std::vector<std::complex<double>> poles;
  auto add = [&](const std::vector<double>& c) {
    for (const auto& r : PolynomialRoots(c)) poles.push_back(r);
  };
  for (int a = 0; a < 3; ++a) {
    const double w = position_omega_radps[a], z = position_zeta[a];
    add({1, 2 * z * w, w * w, integral_gain[a]});
    if (a < 2) {
      add({1, 2 * attitude_zeta * attitude_omega_radps,
           attitude_omega_radps * attitude_omega_radps});
    }
  }
  add({1, 2 * yaw_zeta * yaw_omega_radps, yaw_omega_radps * yaw_omega_radps});
  return poles;
}

bool PaperControllerOptions::IsValid(std::string* why) const {
  if (!vehicle.IsValid(why)) return false;
  if (!gains.IsValid(why)) return false;
  if (!(max_tilt_rad > 0 && max_tilt_rad < 1.5)) return Fail(why, "max_tilt_rad: (0, 1.5)");
  if (!(tilt_braking_fraction >= 0 && tilt_braking_fraction <= 1)) {
    return Fail(why, "tilt_braking_fraction: must be in [0, 1] (0 = off)");
  }
  if (!allocation.IsValid(why)) return false;
  if (allocation.min_rotor_speed_radps >= vehicle.max_rotor_speed_radps) {
    return Fail(why,
                "allocation.min_rotor_speed_radps: must be below vehicle.max_rotor_speed_radps");
  }
  return true;
}

namespace {

const PaperControllerOptions& Checked(const PaperControllerOptions& options) {
  std::string why;
  MAV_CHECK(options.IsValid(&why)) << why;
  return options;
}

}  // namespace

PaperController::PaperController(const PaperControllerOptions& options)
    : options_(Checked(options)), allocator_(options.vehicle, options.allocation) {}

double PaperController::AngularAccelerationReach(double thrust,
                                                 const Eigen::Vector2d& e_body_xy) const {
  // The planar map below: dw_y ~ e_x, dw_x ~ -e_y.
  const Eigen::Vector3d& J = options_.vehicle.inertia_kgm2;
  Eigen::Vector2d dw(-e_body_xy.y(), e_body_xy.x());
  if (!(dw.norm() > 1e-12)) dw = Eigen::Vector2d(0, 1);
  dw.normalize();
  const Eigen::Vector2d torque = J.head<2>().cwiseProduct(dw);
  return allocator_.MaxRollPitchTorque(thrust, torque) / torque.norm();
}

void PaperController::Reset() {
  integral_.setZero();
  disturbance_.setZero();
}

Eigen::Vector3d PaperController::integral_acceleration() const {
  return options_.gains.integral_gain.cwiseProduct(integral_);
}

void PaperController::SetGains(const PaperControllerGains& gains) {
  std::string why;
  MAV_CHECK(gains.IsValid(&why)) << why;
  options_.gains = gains;
  // Keep the integral acceleration inside the (possibly new) bound.
  for (int a = 0; a < 3; ++a) {
    if (gains.integral_gain[a] <= 0) continue;
    const double lim = gains.integral_limit_mps2 / gains.integral_gain[a];
    integral_[a] = std::clamp(integral_[a], -lim, lim);
  }
}

Wrench PaperController::Update(const EstimatorState& x, const TrajectoryPoint& ref, double dt_s,
                               bool saturated) {
  const PaperControllerGains& g = options_.gains;
  const VehicleParameters& veh = options_.vehicle;
  const double m = veh.mass_kg;
  const Eigen::Matrix3d R = x.q_world_body.toRotationMatrix();
  const Eigen::Vector3d e3b = R.col(2);
  const Eigen::Vector3d& w = x.omega_body;
  const Eigen::Vector3d gvec(0, 0, -kGravity);

  const Eigen::Vector3d e = ref.position - x.p_world;
  const Eigen::Vector3d de = ref.velocity - x.v_world;
  const Eigen::Vector3d k1 = 2.0 * g.position_zeta.cwiseProduct(g.position_omega_radps);
  const Eigen::Vector3d k0 = g.position_omega_radps.cwiseAbs2();
  const Eigen::Vector3d& ki = g.integral_gain;

  // Integral with anti-windup: clamped, and frozen while the rotors saturate.
  if (!saturated && dt_s > 0) integral_ += dt_s * e;
  for (int a = 0; a < 3; ++a) {
    if (ki[a] <= 0) {
      integral_[a] = 0;
      continue;
    }
    const double lim = g.integral_limit_mps2 / ki[a];
    integral_[a] = std::clamp(integral_[a], -lim, lim);
  }
  Eigen::Vector3d a_c = ref.acceleration + k1.cwiseProduct(de) + k0.cwiseProduct(e) +
                        ki.cwiseProduct(integral_) - disturbance_;
  // Bound the tilt the command implies (and never ask for less than 20 % of gravity upward).
  a_c.z() = std::max(a_c.z(), -0.8 * kGravity);
  const double horizontal = a_c.head<2>().norm();
  const double max_horizontal = (a_c.z() + kGravity) * std::tan(options_.max_tilt_rad);
  if (horizontal > max_horizontal) a_c.head<2>() *= max_horizontal / horizontal;

  // Vertical dynamics -> thrust (the tilt's cosine bounded away from zero).
  const double cos_tilt = std::max(e3b.z(), 0.3);
  const double thrust = std::clamp(m * (a_c.z() + kGravity) / cos_tilt, 0.0, veh.MaxThrust());

  // Model acceleration and jerk at the quasi-static thrust.
  const double t_m = thrust / m;
  const Eigen::Vector3d a = t_m * e3b + gvec;
  const Eigen::Vector3d w_x_e3 = w.cross(Eigen::Vector3d::UnitZ());
  const Eigen::Vector3d j = t_m * (R * w_x_e3);

  // First and second derivatives of a_c along the closed loop (feed-forward to snap).
  const Eigen::Vector3d da_c =
      ref.jerk + k1.cwiseProduct(ref.acceleration - a) + k0.cwiseProduct(de) + ki.cwiseProduct(e);
  const Eigen::Vector3d dda_c = ref.snap + k1.cwiseProduct(ref.jerk - j) +
                                k0.cwiseProduct(ref.acceleration - a) + ki.cwiseProduct(de);
  const double ka1 = 2.0 * g.attitude_zeta * g.attitude_omega_radps;
  const double ka0 = g.attitude_omega_radps * g.attitude_omega_radps;
  // The planar loop in nested form: the jerk (tilt rate) it asks for, j_c = ref.jerk + j_fb with
  // the feedback j_fb = da_c - ref.jerk + P (a_c - a), P = ka0 / ka1, then s_c = dda_c + ka1 (j_c
  // - j): exactly the linear loop above. j_fb acts on the acceleration error with the gain
  // K = k1 + P (the translational loop's k1 (ref.acceleration - a) inside da_c adds to the
  // planar P), so |j_fb| / K is the acceleration error it closes; beyond the linear range that is
  // shaped to the rate that can still be stopped (PaperControllerOptions::tilt_braking_fraction).
  // Only the part across the thrust axis tilts the vehicle (the body-z part of s_c is unused).
  const double p_gain = ka0 / ka1;
  Eigen::Vector3d j_fb = da_c - ref.jerk + p_gain * (a_c - a);
  if (options_.tilt_braking_fraction > 0 && t_m > 0.1) {
    const double k = std::max(k1.x(), k1.y()) + p_gain;
    Eigen::Vector3d j_body = R.transpose() * j_fb;
    const double n = j_body.head<2>().norm();
    const double s_brake =
        options_.tilt_braking_fraction * t_m * AngularAccelerationReach(thrust, j_body.head<2>());
    const double e_lin = s_brake / (k * k);
    if (n > k * e_lin) {
      j_body.head<2>() *= std::sqrt(2.0 * s_brake * (n / k - 0.5 * e_lin)) / n;
      j_fb = R * j_body;
    }
  }
  const Eigen::Vector3d j_c = ref.jerk + j_fb;
  const Eigen::Vector3d s_c = dda_c + ka1 * (j_c - j);

  // Planar part through the torques: (dw/dt x e3 + w x (w x e3))_xy = (R^T s_c / t_m)_xy.
  Eigen::Vector3d dw = Eigen::Vector3d::Zero();
  if (t_m > 0.1) {
    const Eigen::Vector3d b = R.transpose() * s_c / t_m;
    const Eigen::Vector3d c = w.cross(w_x_e3);
    dw.y() = b.x() - c.x();
    dw.x() = -(b.y() - c.y());
  }
  // Yaw: heading of the body x axis in the world, rate = world z rate.
  const double yaw = std::atan2(R(1, 0), R(0, 0));
  const double yaw_rate = R.row(2).dot(w);
  const double yaw_acc_c = 2.0 * g.yaw_zeta * g.yaw_omega_radps * (ref.yaw_rate_radps - yaw_rate) +
                           g.yaw_omega_radps * g.yaw_omega_radps * WrapAngle(ref.yaw_rad - yaw);
  dw.z() = (yaw_acc_c - R(2, 0) * dw.x() - R(2, 1) * dw.y()) / std::max(R(2, 2), 0.3);

  const Eigen::Vector3d J = veh.inertia_kgm2;
  const Eigen::Vector3d torque = J.cwiseProduct(dw) + w.cross(J.cwiseProduct(w));
  Wrench out;
  out << thrust, torque;
  return out;
}

}  // namespace mav::control
