#include "mav/control/controller.h"

#include <algorithm>
#include <complex>
#include <functional>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>

#include "mav/geometry/se3.h"

namespace mav::control {
namespace {

using State = Eigen::Matrix<double, 15, 1>;  // p, v, phi (R = Exp(phi)), w, integral

// The closed loop of a rigid body (ideal actuators) with `controller` holding the origin:
// d/dt of the state. The integral state (if any) is the last three entries.
State Dynamics(TrackingController* controller, PaperController* paper, const State& z,
               const VehicleParameters& v) {
  EstimatorState x;
  x.p_world = z.segment<3>(0);
  x.v_world = z.segment<3>(3);
  x.q_world_body = geometry::ExpSO3(z.segment<3>(6));
  x.omega_body = z.segment<3>(9);
  if (paper) paper->SetIntegralState(z.segment<3>(12));
  const Wrench w = controller->Update(x, geometry::TrajectoryPoint(), /*dt_s=*/0, false);
  State dz;
  dz.segment<3>(0) = x.v_world;
  dz.segment<3>(3) =
      x.q_world_body * Eigen::Vector3d(0, 0, w[0] / v.mass_kg) - Eigen::Vector3d(0, 0, kGravity);
  dz.segment<3>(6) = x.omega_body;  // d phi/dt = w to first order at phi = 0
  const Eigen::Vector3d& J = v.inertia_kgm2;
  dz.segment<3>(9) =
      (w.tail<3>() - x.omega_body.cross(J.cwiseProduct(x.omega_body))).cwiseQuotient(J);
  dz.segment<3>(12) = -x.p_world;  // d/dt int(p_ref - p)
  return dz;
}

std::vector<std::complex<double>> ClosedLoopEigenvalues(TrackingController* c,
                                                        PaperController* paper,
                                                        const VehicleParameters& v, int n) {
  Eigen::MatrixXd A(n, n);
  const double eps = 1e-6;
  for (int j = 0; j < n; ++j) {
    State zp = State::Zero(), zm = State::Zero();
    zp[j] += eps;
    zm[j] -= eps;
    A.col(j) = ((Dynamics(c, paper, zp, v) - Dynamics(c, paper, zm, v)) / (2 * eps)).head(n);
  }
  const Eigen::VectorXcd ev = A.eigenvalues();
  return std::vector<std::complex<double>>(ev.data(), ev.data() + n);
}

// Every expected pole has its own computed eigenvalue within tol (relative).
void ExpectSamePoles(std::vector<std::complex<double>> computed,
                     const std::vector<std::complex<double>>& expected, double tol) {
  ASSERT_EQ(computed.size(), expected.size());
  for (const auto& e : expected) {
    auto best = std::min_element(computed.begin(), computed.end(),
                                 [&](auto a, auto b) { return std::abs(a - e) < std::abs(b - e); });
    EXPECT_LT(std::abs(*best - e), tol * std::max(1.0, std::abs(e))) << "pole " << e;
    computed.erase(best);
  }
}

TEST(PaperControllerTest, LinearisedClosedLoopHasTheDesignedPoles) {
  PaperControllerOptions o;
  o.gains.position_omega_radps = Eigen::Vector3d(3.0, 3.5, 4.0);
  o.gains.position_zeta = Eigen::Vector3d(0.9, 0.8, 1.0);
  o.gains.integral_gain = Eigen::Vector3d(5, 6, 7);
  o.gains.attitude_omega_radps = 12;
  o.gains.attitude_zeta = 0.9;
  o.gains.yaw_omega_radps = 5;
  o.gains.yaw_zeta = 0.9;
  PaperController c(o);
  const auto poles = o.gains.DesignedPoles();
  ASSERT_EQ(poles.size(), 15u);
  for (const auto& p : poles) EXPECT_LT(p.real(), 0);
  ExpectSamePoles(ClosedLoopEigenvalues(&c, &c, o.vehicle, 15), poles, 1e-4);
}

TEST(PaperControllerTest, DefaultGainsAreStableAndValid) {
  const PaperControllerGains g;
  std::string why;
  EXPECT_TRUE(g.IsValid(&why)) << why;
  for (const auto& p : g.DesignedPoles()) EXPECT_LT(p.real(), 0);
  PaperControllerGains bad;
  bad.integral_gain[1] = 1000;  // beyond Routh-Hurwitz
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_NE(why.find("integral_gain.y"), std::string::npos);
}

TEST(PaperControllerTest, SetGainsKeepsTheIntegralState) {
  PaperController c{PaperControllerOptions()};
  EstimatorState x;
  geometry::TrajectoryPoint ref;
  ref.position = Eigen::Vector3d(0.05, -0.02, 0.01);
  for (int k = 0; k < 100; ++k) c.Update(x, ref, 0.01, false);
  const Eigen::Vector3d before = c.integral_state();
  EXPECT_GT(before.norm(), 0);
  PaperControllerGains g;
  g.attitude_omega_radps = 10;
  c.SetGains(g);
  EXPECT_EQ(c.integral_state(), before);
  // Anti-windup: frozen while saturated, bounded otherwise.
  c.Update(x, ref, 0.01, /*saturated=*/true);
  EXPECT_EQ(c.integral_state(), before);
  ref.position = Eigen::Vector3d(100, 0, 0);
  for (int k = 0; k < 10000; ++k) c.Update(x, ref, 0.01, false);
  EXPECT_NEAR(c.integral_acceleration().x(), g.integral_limit_mps2, 1e-9);
}

TEST(LeeControllerTest, LinearisedClosedLoopHasRotorSPoles) {
  LeeControllerOptions o;  // the Firefly gains of RotorS
  LeeController c(o);
  const auto poles = o.gains.LinearisedPoles(o.vehicle);
  ASSERT_EQ(poles.size(), 12u);
  for (const auto& p : poles) EXPECT_LT(p.real(), 0);
  ExpectSamePoles(ClosedLoopEigenvalues(&c, nullptr, o.vehicle, 12), poles, 1e-4);
}

TEST(PolynomialRootsTest, FindsKnownRoots) {
  const auto r = PolynomialRoots({1, -6, 11, -6});  // (s-1)(s-2)(s-3)
  std::vector<double> re;
  re.reserve(r.size());
  for (const auto& x : r) re.push_back(x.real());
  std::sort(re.begin(), re.end());
  EXPECT_NEAR(re[0], 1, 1e-9);
  EXPECT_NEAR(re[1], 2, 1e-9);
  EXPECT_NEAR(re[2], 3, 1e-9);
}

}  // namespace
}  // namespace mav::control
