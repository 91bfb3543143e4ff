#pragma once
// GoogleMock matchers for poses and rotations (as Ceres' IsNearQuaternion), so that a failed
// comparison prints both poses and the errors that broke the tolerance:
//   EXPECT_THAT(estimate, IsNearPose(truth, /*translation_m=*/0.004, /*rotation_rad=*/1e-3));
//   EXPECT_THAT(q, IsNearRotation(q_truth, 1e-9));

#include <cmath>
#include <ostream>

#include <gmock/gmock.h>
#include <Eigen/Geometry>

#include "mav/geometry/se3.h"

namespace mav::test_support {

// |t - t_expected| <= translation_m and the angle of R_expected^-1 R <= rotation_rad.
MATCHER_P3(IsNearPose, expected, translation_m, rotation_rad,
           "is within " + ::testing::PrintToString(translation_m) + " m and " +
               ::testing::PrintToString(rotation_rad) + " rad of the expected pose") {
  const geometry::SE3& actual = arg;
  const geometry::SE3& want = expected;
  const double dt = (actual.Translation() - want.Translation()).norm();
  const double dr = geometry::AngleBetween(want.Rotation(), actual.Rotation());
  *result_listener << "translation error " << dt << " m, rotation error " << dr
                   << " rad; actual t = " << actual.Translation().transpose()
                   << ", expected t = " << want.Translation().transpose();
  return std::isfinite(dt) && std::isfinite(dr) && dt <= translation_m && dr <= rotation_rad;
}

// The angle between the rotations is at most `rotation_rad` (q and -q are the same rotation).
MATCHER_P2(IsNearRotation, expected, rotation_rad,
           "is within " + ::testing::PrintToString(rotation_rad) +
               " rad of the expected rotation") {
  const double dr = geometry::AngleBetween(Eigen::Quaterniond(expected), Eigen::Quaterniond(arg));
  *result_listener << "rotation error " << dr << " rad";
  return std::isfinite(dr) && dr <= rotation_rad;
}

}  // namespace mav::test_support
