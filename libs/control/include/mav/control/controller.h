#pragma once
// Trajectory-tracking controllers: estimate + reference -> body wrench [T, tau].
//
// PaperController: the quasi-static feedback linearisation of Holzmann et al. 2015 (Sec. 3),
// after Fritsch, Bicker, Lohmann et al., "Quasi-static feedback linearization for the
// translational dynamics of a quadrotor helicopter", ACC 2012. With a = R e3 T/m - g e3 the
// model acceleration (T held quasi-static, i.e. dT/dt neglected in the planar part):
//  * the vertical dynamics parametrise the thrust: T = m (a_c,z + g) / (R e3)_z;
//  * the translational error e = p_r - p gets a PI-augmented pole placement,
//      a_c = a_r + 2 zeta w (v_r - v) + w^2 e + K_i int(e)        (per axis, anti-windup),
//  * the planar dynamics are linearised through the torques: the horizontal snap
//      s = (T/m) R (dw/dt x e3 + w x (w x e3))
//    is set to s_c = d2(a_c)/dt2 + 2 zeta_a w_a (d(a_c)/dt - j) + w_a^2 (a_c - a), with the model
//    jerk j = (T/m) R (w x e3) and the derivatives of a_c taken analytically from the reference
//    (feed-forward up to snap), which fixes dw_x/dt, dw_y/dt;
//  * yaw: psi'' = psi_r'' + 2 zeta_y w_y (psi_r' - psi') + w_y^2 (psi_r - psi);
//  * tau = J dw/dt + w x J w.
//  Our addition (AutopilotOptions::disturbance_observer_s): the unmodelled acceleration the
//  accelerometer sees (a_imu - a_model, low-passed; wind, the mass error) is subtracted from a_c,
//  so a gust is cancelled within ~0.2 s instead of by the integrator, and the position poles can
//  stay slow enough not to turn the pose noise into body rates.
//  Per horizontal axis the error obeys (s^2 + 2 zeta_a w_a s + w_a^2)(s^3 + 2 zeta w s^2 + w^2 s
//  + K_i) = 0, vertically s^3 + 2 zeta w s^2 + w^2 s + K_i = 0, in yaw s^2 + 2 zeta_y w_y s +
//  w_y^2 = 0: DesignedPoles() lists them.
//
// LeeController: the peer, Lee, Leok, McClamroch, "Geometric tracking control of a quadrotor UAV
// on SE(3)", CDC 2010, as RotorS' lee_position_controller flies it with the Firefly gains (no
// integral term, no feed-forward of the angular acceleration, no gyroscopic term; its gains act
// as forces and torques: the code divides them by mass and inertia and the allocation multiplies
// the inertia back):
//   F = -k_x e_x - k_v e_v + m g e3 + m a_r,  T = F . R e3,  R_d from (F/|F|, yaw_r),
//   e_R = 1/2 vee(R_d^T R - R^T R_d),  e_w = w - R^T R_d w_d,  tau = -k_R e_R - k_w e_w.
//   Linearised at hover, per horizontal axis: s^4 + (k_w/J) s^3 + (k_R/J) s^2 + (k_R k_v/(J m)) s
//   + k_R k_x/(J m) = 0.

#include <complex>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mav/control/allocation.h"
#include "mav/control/estimator.h"
#include "mav/control/vehicle.h"
#include "mav/geometry/polynomial_trajectory.h"

namespace mav::control {

// The reference of one control step: PolynomialTrajectory's point plus yaw acceleration.
using geometry::TrajectoryPoint;

class TrackingController {
 public:
  virtual ~TrackingController() = default;
  // The wrench for the estimate `x` and reference `ref`; dt_s is the time since the last call
  // (integrators). `saturated`: the last wrench could not be allocated in full (anti-windup).
  virtual Wrench Update(const EstimatorState& x, const TrajectoryPoint& ref, double dt_s,
                        bool saturated) = 0;
  // Clears the integral state (on arming).
  virtual void Reset() = 0;
  // The integral part's acceleration (m/s^2, world), zero for controllers without one.
  virtual Eigen::Vector3d integral_acceleration() const { return Eigen::Vector3d::Zero(); }
  // An estimate of the unmodelled acceleration (external force / mass, model errors; world,
  // m/s^2) to cancel by feed-forward; controllers without the feature ignore it.
  virtual void SetDisturbance(const Eigen::Vector3d& /*a_world*/) {}
};

struct PaperControllerGains {
  // Translational error dynamics per axis: s^3 + 2 zeta w s^2 + w^2 s + K_i. The defaults put
  // all three poles at -2.5 rad/s ((s + 2.5)^3: w = 2.5 sqrt(3), zeta = sqrt(3) / 2,
  // K_i = 2.5^3): the pose noise (0.01 m at 10 Hz) reaches the body rates through these gains,
  // so faster poles buy position accuracy with angular-rate noise (docs/control.md measures the
  // trade-off); wind is mostly left to the disturbance observer (autopilot.h).
  Eigen::Vector3d position_omega_radps = Eigen::Vector3d::Constant(4.330127018922193);
  Eigen::Vector3d position_zeta = Eigen::Vector3d::Constant(0.8660254037844386);
  Eigen::Vector3d integral_gain = Eigen::Vector3d::Constant(15.625);  // 1/s^3
  // Anti-windup: bound of each component of the integral acceleration K_i int(e), m/s^2 (the
  // contest's 5 N on 1.5 kg need 3.3).
  double integral_limit_mps2 = 4.0;
  // Planar (roll/pitch) error dynamics s^2 + 2 zeta_a w_a s + w_a^2: below the motors' time
  // constants (1/0.0125 s, 1/0.025 s) and the 100 Hz control rate; faster loops shake the body
  // more with the pose noise.
  double attitude_omega_radps = 12.0;
  double attitude_zeta = 0.9;
  double yaw_omega_radps = 5.0;
  double yaw_zeta = 1.0;

  bool IsValid(std::string* why) const;
  // The 15 closed-loop poles of the linearised loop: x, y (5 each), z (3), yaw (2).
  std::vector<std::complex<double>> DesignedPoles() const;
};

struct PaperControllerOptions {
  VehicleParameters vehicle;
  PaperControllerGains gains;
  // The commanded horizontal acceleration is bounded to this tilt of the thrust axis.
  double max_tilt_rad = 0.9;
  // The bounded planar loop (our addition; 0 = off, the paper's linear loop). The planar loop
  // asks for the tilt rate (jerk) j_c = da_c + (w_a / 2 zeta_a) (a_c - a); beyond the linear
  // range that is shaped as sqrt(2 s_b (|e| - e_lin / 2)) (C1 at e_lin = s_b / P^2, P = w_a /
  // 2 zeta_a), the rate that can still be stopped with s_b = tilt_braking_fraction * (T/m) *
  // the angular acceleration the rotors can give beside the thrust along the needed direction.
  // Without it the linear loop asks for 144 rad/s^2 per rad of tilt error (w_a = 12 rad/s) where
  // the Firefly's rotors give about 40 rad/s^2 at hover thrust: the allocation scales the torque
  // down, and after a hard braking (t4_3) the saturated loop oscillates and flips the vehicle.
  // Validated [0, 1].
  double tilt_braking_fraction = 0.5;
  // The rotors' range the bound is computed for (the allocation the autopilot flies with).
  AllocationOptions allocation;
  bool IsValid(std::string* why) const;
};

class PaperController : public TrackingController {
 public:
  explicit PaperController(const PaperControllerOptions& options);
  Wrench Update(const EstimatorState& x, const TrajectoryPoint& ref, double dt_s,
                bool saturated) override;
  void Reset() override;
  Eigen::Vector3d integral_acceleration() const override;
  void SetDisturbance(const Eigen::Vector3d& a_world) override { disturbance_ = a_world; }
  // Replaces the gains; the integral state is kept (its acceleration re-clamped).
  void SetGains(const PaperControllerGains& gains);
  // The integral of the position error (m s), e.g. to carry it across a restart.
  const Eigen::Vector3d& integral_state() const { return integral_; }
  void SetIntegralState(const Eigen::Vector3d& integral) { integral_ = integral; }
  const PaperControllerOptions& options() const { return options_; }

 private:
  // The angular acceleration (rad/s^2) the rotors can give beside `thrust` about the body axis
  // that turns the thrust towards the body-frame horizontal acceleration error `e_body_xy`.
  double AngularAccelerationReach(double thrust, const Eigen::Vector2d& e_body_xy) const;

  PaperControllerOptions options_;
  Allocator allocator_;
  Eigen::Vector3d integral_ = Eigen::Vector3d::Zero();  // int(e) dt, m s
  Eigen::Vector3d disturbance_ = Eigen::Vector3d::Zero();
};

struct LeeControllerGains {
  // RotorS' Firefly gains (lee_controller_firefly.yaml).
  Eigen::Vector3d position_gain = Eigen::Vector3d::Constant(6.0);         // N/m
  Eigen::Vector3d velocity_gain = Eigen::Vector3d::Constant(4.7);         // N s/m
  Eigen::Vector3d attitude_gain = Eigen::Vector3d(3.0, 3.0, 0.15);        // N m/rad
  Eigen::Vector3d angular_rate_gain = Eigen::Vector3d(0.52, 0.52, 0.18);  // N m s/rad
  bool IsValid(std::string* why) const;
  // The closed-loop poles of the linearised loop at hover for `vehicle` (x, y: 4 each; z: 2;
  // yaw: 2).
  std::vector<std::complex<double>> LinearisedPoles(const VehicleParameters& vehicle) const;
};

struct LeeControllerOptions {
  VehicleParameters vehicle;
  LeeControllerGains gains;
  bool IsValid(std::string* why) const;
};

class LeeController : public TrackingController {
 public:
  explicit LeeController(const LeeControllerOptions& options);
  Wrench Update(const EstimatorState& x, const TrajectoryPoint& ref, double dt_s,
                bool saturated) override;
  void Reset() override {}
  void SetGains(const LeeControllerGains& gains) { options_.gains = gains; }
  const LeeControllerOptions& options() const { return options_; }

 private:
  LeeControllerOptions options_;
};

// Roots of a real polynomial given in descending powers (companion-matrix eigenvalues).
std::vector<std::complex<double>> PolynomialRoots(const std::vector<double>& coefficients);

}  // namespace mav::control
