#include "mav/camera/pinhole.h"

#include <gtest/gtest.h>

#include "tests/common/numeric.h"

#include <random>

#include "mav/camera/stereo.h"

namespace mav::camera {
namespace {

TEST(PinholeTest, EurocCalibrationIsValid) {
  std::string why;
  EXPECT_TRUE(EurocCam0().IsValid(&why)) << why;
  const StereoCalibration calib = EurocStereoCalibration();
  EXPECT_TRUE(calib.IsValid(&why)) << why;
  EXPECT_NEAR(calib.Baseline(), 0.110, 0.001);
  // cam1 lies on cam0's +x side.
  EXPECT_GT(calib.T_cam0_cam1().Translation().x(), 0.10);
}

TEST(PinholeTest, InvalidFieldsAreNamed) {
  PinholeRadTan c = EurocCam0();
  c.fx = -1;
  std::string why;
  EXPECT_FALSE(c.IsValid(&why));
  EXPECT_NE(why.find("intrinsics"), std::string::npos);
  c = EurocCam0();
  c.width = 0;
  EXPECT_FALSE(c.IsValid(&why));
  EXPECT_NE(why.find("resolution"), std::string::npos);
}

TEST(PinholeTest, ProjectUnprojectRoundTripOverTheImage) {
  const PinholeRadTan cam = EurocCam0();
  for (int v = 0; v < cam.height; v += 40) {
    for (int u = 0; u < cam.width; u += 40) {
      const Eigen::Vector2d uv(u, v);
      const auto bearing = cam.Unproject(uv);
      ASSERT_TRUE(bearing.has_value()) << uv.transpose();
      const auto back = cam.Project(*bearing * 3.0);
      ASSERT_TRUE(back.has_value());
      EXPECT_LT((*back - uv).norm(), 1e-6) << uv.transpose();
    }
  }
}

TEST(PinholeTest, ProjectJacobianMatchesNumeric) {
  const PinholeRadTan cam = EurocCam1();
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> xy(-1.5, 1.5), z(1.0, 6.0);
  for (int i = 0; i < 100; ++i) {
    const Eigen::Vector3d p(xy(rng), xy(rng), z(rng));
    Eigen::Matrix<double, 2, 3> j;
    const auto uv = cam.Project(p, &j);
    ASSERT_TRUE(uv.has_value());
    const Eigen::Matrix<double, 2, 3> numeric = test_support::NumericJacobian<2, 3>(
        [&](const Eigen::Vector3d& q) { return *cam.Project(q); }, p);
    for (int k = 0; k < 3; ++k) {
      EXPECT_LT((numeric.col(k) - j.col(k)).norm(), 1e-4 * std::max(1.0, numeric.col(k).norm()));
    }
  }
}

TEST(PinholeTest, BehindCameraDoesNotProject) {
  EXPECT_FALSE(EurocCam0().Project(Eigen::Vector3d(0, 0, -1)).has_value());
  EXPECT_FALSE(EurocCam0().Project(Eigen::Vector3d(1, 0, 0)).has_value());
}

TEST(RectifiedStereoTest, DisparityDepthAndTriangulation) {
  RectifiedStereo s;
  s.width = 752;
  s.height = 480;
  s.fx = s.fy = 450;
  s.cx = 376;
  s.cy = 240;
  s.baseline = 0.11;
  const Eigen::Vector3d p(0.4, -0.3, 2.5);
  const Eigen::Vector2d l = *s.ProjectLeft(p);
  const Eigen::Vector2d r = *s.ProjectRight(p);
  EXPECT_NEAR(l.y(), r.y(), 1e-12);
  EXPECT_NEAR(l.x() - r.x(), s.DisparityFromDepth(2.5), 1e-9);
  const auto back = s.Triangulate(l, l.x() - r.x());
  ASSERT_TRUE(back.has_value());
  EXPECT_LT((*back - p).norm(), 1e-9);
  EXPECT_FALSE(s.Triangulate(l, 0.0).has_value());
  EXPECT_FALSE(s.Triangulate(l, -1.0).has_value());
}

}  // namespace
}  // namespace mav::camera
