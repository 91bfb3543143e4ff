#include "mav/geometry/se3.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace mav::geometry {
namespace {

// Random tangent vectors, including tiny and near-pi rotations where Exp/Log are delicate.
std::vector<Vector6d> TestTangents() {
  std::mt19937_64 rng(42);
  std::normal_distribution<double> n(0.0, 1.0);
  std::vector<Vector6d> out;
  for (int i = 0; i < 200; ++i) {
    Vector6d xi;
    for (int k = 0; k < 6; ++k) xi[k] = n(rng);
    const double scale = (i % 4 == 0) ? 1e-9 : (i % 4 == 1) ? 1e-4 : 1.0;
    xi.tail<3>() *= scale;
    // Log returns angles in [0, pi]; keep the samples inside that chart.
    if (xi.tail<3>().norm() > 3.0) xi.tail<3>() *= 3.0 / xi.tail<3>().norm();
    if (i % 10 == 0) xi.tail<3>() = xi.tail<3>().normalized() * (M_PI - 1e-6);
    out.push_back(xi);
  }
  return out;
}

TEST(SO3Test, ExpLogRoundTrip) {
  for (const Vector6d& xi : TestTangents()) {
    const Eigen::Vector3d phi = xi.tail<3>();
    EXPECT_LT((LogSO3(ExpSO3(phi)) - phi).norm(), 1e-9 * std::max(1.0, phi.norm()))
        << phi.transpose();
  }
}

TEST(SO3Test, ExpMatchesAngleAxis) {
  const Eigen::Vector3d phi(0.3, -0.2, 0.9);
  const Eigen::Matrix3d expected =
      Eigen::AngleAxisd(phi.norm(), phi.normalized()).toRotationMatrix();
  EXPECT_TRUE(ExpSO3(phi).toRotationMatrix().isApprox(expected, 1e-12));
}

TEST(SO3Test, HatVeeAndCross) {
  const Eigen::Vector3d a(1, 2, 3), b(-4, 0.5, 2);
  EXPECT_TRUE((Hat(a) * b).isApprox(a.cross(b)));
  EXPECT_TRUE(Vee(Hat(a)).isApprox(a));
}

TEST(SO3Test, LeftJacobianMatchesNumericDerivative) {
  const Eigen::Vector3d phi(0.4, -0.7, 0.2);
  const Eigen::Matrix3d j = LeftJacobianSO3(phi);
  const double h = 1e-6;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d d = Eigen::Vector3d::Unit(k) * h;
    // Exp(phi + d) Exp(phi)^-1 = Exp(J d)
    const Eigen::Vector3d numeric = LogSO3(ExpSO3(phi + d) * ExpSO3(phi).conjugate()) / h;
    EXPECT_LT((numeric - j.col(k)).norm(), 1e-5);
  }
}

TEST(SE3Test, ExpLogRoundTripAndGroupAxioms) {
  const auto tangents = TestTangents();
  for (size_t i = 0; i + 1 < tangents.size(); ++i) {
    const SE3 a = SE3::Exp(tangents[i]);
    const SE3 b = SE3::Exp(tangents[i + 1]);
    if (tangents[i].tail<3>().norm() < M_PI - 1e-3) {
      EXPECT_LT((a.Log() - tangents[i]).norm(), 1e-8) << i;
    }
    EXPECT_TRUE((a * a.Inverse()).IsApprox(SE3::Identity(), 1e-12));
    EXPECT_TRUE((a * b).Matrix().isApprox(a.Matrix() * b.Matrix(), 1e-12));
    const Eigen::Vector3d p(0.5, -1.0, 2.0);
    EXPECT_TRUE((a * p).isApprox((a.Matrix() * p.homogeneous()).head<3>(), 1e-12));
  }
}

TEST(SE3Test, FromMatrixProjectsOntoSO3) {
  Eigen::Matrix4d m = SE3::Exp((Vector6d() << 1, 2, 3, 0.1, 0.2, 0.3).finished()).Matrix();
  m(0, 0) += 1e-6;  // slightly non-orthogonal, as printed calibration matrices are
  const SE3 t = SE3::FromMatrix(m);
  EXPECT_NEAR(t.RotationMatrix().determinant(), 1.0, 1e-12);
  EXPECT_TRUE(t.Matrix().isApprox(m, 1e-5));
}

TEST(SE3Test, InterpolationEndsAndMidpoint) {
  const SE3 a(ExpSO3(Eigen::Vector3d(0, 0, 0.2)), Eigen::Vector3d(0, 0, 0));
  const SE3 b(ExpSO3(Eigen::Vector3d(0, 0, 1.0)), Eigen::Vector3d(2, 0, 0));
  EXPECT_TRUE(InterpolatePose(a, b, 0.0).IsApprox(a, 1e-12));
  EXPECT_TRUE(InterpolatePose(a, b, 1.0).IsApprox(b, 1e-12));
  const SE3 mid = InterpolatePose(a, b, 0.5);
  EXPECT_NEAR(LogSO3(mid.Rotation()).z(), 0.6, 1e-12);
  EXPECT_NEAR(mid.Translation().x(), 1.0, 1e-12);
}

TEST(SE3Test, RollPitchYawOrder) {
  const Eigen::Matrix3d r = RotationFromRollPitchYaw(0.0, 0.0, M_PI / 2);
  EXPECT_TRUE((r * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitY(), 1e-12));
  const Eigen::Matrix3d rp = RotationFromRollPitchYaw(0.1, 0.2, 0.3);
  const Eigen::Matrix3d expected =
      Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()) *
      Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitY()) *
      Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitX()).toRotationMatrix();
  EXPECT_TRUE(rp.isApprox(expected, 1e-12));
}

}  // namespace
TEST(SensorFramesTest, BodyPoseFromSensorPoseAndOdometry) {
  const SE3 T_body_sensor = SE3::Exp((Vector6d() << 0.03, -0.07, 0.1, 0.2, -0.1, 0.3).finished());
  const SE3 T_world_body0 = SE3::Exp((Vector6d() << 1, 2, 3, 0.0, 0.1, 1.0).finished());
  const SE3 T_world_body1 = SE3::Exp((Vector6d() << 1.5, 2, 2.5, 0.1, 0.1, 1.2).finished());
  // The sensor's poses of both body poses, and its odometry from the first.
  const SE3 T_world_sensor1 = T_world_body1 * T_body_sensor;
  const SE3 T_sensor0_sensor1 = (T_world_body0 * T_body_sensor).Inverse() * T_world_sensor1;
  EXPECT_TRUE(
      BodyPoseFromSensorPose(T_world_sensor1, T_body_sensor).IsApprox(T_world_body1, 1e-12));
  EXPECT_TRUE(BodyPoseFromSensorOdometry(T_world_body0, T_body_sensor, T_sensor0_sensor1)
                  .IsApprox(T_world_body1, 1e-12));
}

}  // namespace mav::geometry
