#include "mav/geometry/spline.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace mav::geometry {
namespace {

using Spline3 = UniformQuinticBSpline<3>;
using Spline1 = UniformQuinticBSpline<1>;

std::vector<Eigen::Vector3d> RandomControlPoints(int n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  std::vector<Eigen::Vector3d> ctrl(n);
  for (auto& p : ctrl) p = Eigen::Vector3d(u(rng), u(rng), u(rng));
  return ctrl;
}

// Independent reference: the Cox-de Boor recursion on the uniform knot vector
// t_m = t0 + (m - 5) dt, m = 0..n+5, so that basis j is supported on [t_j, t_{j+6}].
double CoxDeBoor(int j, int degree, double t, double t0, double dt) {
  const auto knot = [&](int m) { return t0 + (m - 5) * dt; };
  if (degree == 0) return (t >= knot(j) && t < knot(j + 1)) ? 1.0 : 0.0;
  const double a = (t - knot(j)) / (knot(j + degree) - knot(j));
  const double b = (knot(j + degree + 1) - t) / (knot(j + degree + 1) - knot(j + 1));
  return a * CoxDeBoor(j, degree - 1, t, t0, dt) + b * CoxDeBoor(j + 1, degree - 1, t, t0, dt);
}

TEST(UniformQuinticBSplineTest, BlendingMatrixIsAPartitionOfUnity) {
  const auto& m = Spline3::BlendingMatrix();
  // Sum over control points: 1 for the constant power, 0 for the others.
  const Eigen::Matrix<double, 6, 1> row_sums = m.rowwise().sum();
  EXPECT_NEAR(row_sums[0], 1.0, 1e-14);
  for (int r = 1; r < 6; ++r) EXPECT_NEAR(row_sums[r], 0.0, 1e-13) << "power " << r;
  // Known first row of the quintic matrix: basis values at u = 0 are (1, 26, 66, 26, 1, 0) / 120.
  const double expected[6] = {1, 26, 66, 26, 1, 0};
  for (int j = 0; j < 6; ++j) EXPECT_NEAR(m(0, j) * 120.0, expected[j], 1e-12);
}

TEST(UniformQuinticBSplineTest, MatchesCoxDeBoorRecursion) {
  const double t0 = 1.5, dt = 0.4;
  const std::vector<Eigen::Vector3d> ctrl = RandomControlPoints(12, 7);
  const Spline3 spline(t0, dt, ctrl);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(spline.t_min(), spline.t_max());
  for (int trial = 0; trial < 200; ++trial) {
    const double t = u(rng);
    Eigen::Vector3d reference = Eigen::Vector3d::Zero();
    for (int j = 0; j < static_cast<int>(ctrl.size()); ++j) {
      reference += CoxDeBoor(j, 5, t, t0, dt) * ctrl[j];
    }
    EXPECT_LT((spline.Evaluate(t) - reference).norm(), 1e-12) << "t = " << t;
  }
}

TEST(UniformQuinticBSplineTest, DerivativesMatchFiniteDifferences) {
  const Spline3 spline(-0.3, 0.25, RandomControlPoints(15, 11));
  std::mt19937_64 rng(5);
  const double h = 1e-5;
  std::uniform_real_distribution<double> u(spline.t_min() + 2 * h, spline.t_max() - 2 * h);
  for (int trial = 0; trial < 100; ++trial) {
    const double t = u(rng);
    const auto d = spline.EvaluateUpTo<4>(t);
    for (int n = 1; n <= 4; ++n) {
      const Eigen::Vector3d numeric =
          (spline.Evaluate(t + h, n - 1) - spline.Evaluate(t - h, n - 1)) / (2 * h);
      // Central differences are O(h^2); derivatives grow by ~1/dt per order.
      const double scale = std::max(1.0, d[n].norm());
      EXPECT_LT((d[n] - numeric).norm(), 1e-5 * scale) << "derivative " << n << " at t=" << t;
      EXPECT_LT((spline.Evaluate(t, n) - d[n]).norm(), 1e-12 * scale);
    }
  }
}

TEST(UniformQuinticBSplineTest, IsC4ContinuousAcrossKnotsButNotC5) {
  const Spline3 spline(0.0, 0.5, RandomControlPoints(14, 13));
  const double eps = 1e-9;
  int fifth_jumps = 0;
  for (int k = 1; k < spline.num_segments(); ++k) {
    const double knot = spline.t0() + k * spline.dt();
    const auto left = spline.EvaluateUpTo<5>(knot - eps);
    const auto right = spline.EvaluateUpTo<5>(knot + eps);
    for (int n = 0; n <= 4; ++n) {
      // A jump in derivative n would show up as a difference of order |d^n|, a continuous one as
      // O(eps * |d^(n+1)|).
      EXPECT_LT((left[n] - right[n]).norm(), 1e-5 * std::max(1.0, left[n].norm()))
          << "derivative " << n << " jumps at knot " << k;
    }
    if ((left[5] - right[5]).norm() > 1e-3 * std::max(1.0, left[5].norm())) ++fifth_jumps;
  }
  // The 5th derivative is piecewise constant: it must jump at (almost) every knot, which also
  // shows that the continuity check above is able to see a jump.
  EXPECT_GE(fifth_jumps, spline.num_segments() - 2);
}

TEST(UniformQuinticBSplineTest, ReproducesConstantsAndLinearFunctionsExactly) {
  const double t0 = 2.0, dt = 0.3;
  const Eigen::Vector3d c(1.0, -2.0, 0.5);
  const Eigen::Vector3d slope(0.7, 0.1, -1.3);
  std::vector<Eigen::Vector3d> constant(10, c), linear(10);
  for (int j = 0; j < 10; ++j) linear[j] = c + slope * (t0 + (j - 2) * dt);
  const Spline3 sc(t0, dt, constant), sl(t0, dt, linear);
  for (double t = sc.t_min(); t <= sc.t_max(); t += 0.01) {
    EXPECT_LT((sc.Evaluate(t) - c).norm(), 1e-13);
    EXPECT_LT(sc.Evaluate(t, 1).norm(), 1e-12);
    EXPECT_LT((sl.Evaluate(t) - (c + slope * t)).norm(), 1e-12) << "t = " << t;
    EXPECT_LT((sl.Evaluate(t, 1) - slope).norm(), 1e-11);
    EXPECT_LT(sl.Evaluate(t, 2).norm(), 1e-9);
  }
  EXPECT_DOUBLE_EQ(sl.ControlPointTime(2), t0);
}

TEST(UniformQuinticBSplineTest, StaysInTheConvexHullOfItsControlPoints) {
  const std::vector<Eigen::Vector3d> ctrl = RandomControlPoints(20, 17);
  const Spline3 spline(0.0, 1.0, ctrl);
  for (double t = 0; t <= spline.t_max(); t += 0.05) {
    const Eigen::Vector3d p = spline.Evaluate(t);
    EXPECT_TRUE((p.array() >= -2.0).all() && (p.array() <= 2.0).all()) << p.transpose();
  }
}

TEST(UniformQuinticBSplineTest, SpanAndControlPointCount) {
  EXPECT_EQ(Spline1::NumControlPointsFor(10.0, 1.0), 15);
  EXPECT_EQ(Spline1::NumControlPointsFor(10.5, 1.0), 16);
  EXPECT_EQ(Spline1::NumControlPointsFor(0.0, 1.0), 6);
  const Spline1 spline(
      1.0, 0.5, std::vector<Eigen::Matrix<double, 1, 1>>(8, Eigen::Matrix<double, 1, 1>::Zero()));
  EXPECT_EQ(spline.num_segments(), 3);
  EXPECT_DOUBLE_EQ(spline.t_min(), 1.0);
  EXPECT_DOUBLE_EQ(spline.t_max(), 2.5);
}

TEST(UniformQuinticBSplineTest, BadArgumentsAreNamed) {
  const auto ctrl = RandomControlPoints(8, 1);
  auto r = Spline3::Create(0.0, 0.0, ctrl);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("dt_s"), std::string::npos) << r.status().message();

  r = Spline3::Create(0.0, 1.0, RandomControlPoints(5, 1));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("control_points"), std::string::npos);

  auto bad = ctrl;
  bad[3].x() = std::nan("");
  r = Spline3::Create(0.0, 1.0, bad);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("control_points[3]"), std::string::npos);

  r = Spline3::Create(std::nan(""), 1.0, ctrl);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("t0_s"), std::string::npos);

  EXPECT_TRUE(Spline3::Create(0.0, 1.0, ctrl).ok());
}

TEST(UniformQuinticBSplineDeathTest, EvaluationOutsideTheSpanIsABug) {
  const Spline3 spline(0.0, 1.0, RandomControlPoints(8, 1));
  EXPECT_DEATH(spline.Evaluate(3.5), "outside the spline's span");
  EXPECT_DEATH(spline.Evaluate(-0.1), "outside the spline's span");
  EXPECT_DEATH(spline.Evaluate(1.0, 6), "derivative 6");
  EXPECT_DEATH(Spline3().Evaluate(0.0), "empty spline");
}

}  // namespace
}  // namespace mav::geometry
