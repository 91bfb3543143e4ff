#include "mav/control/estimator_weights.h"

#include <gtest/gtest.h>
#include <Eigen/Dense>

#include "mav/control/vehicle.h"

namespace mav::control {
namespace {

// An independent long run of the full 15-state error-state EKF of a hovering multicopter (yaw 0,
// specific force g e3): x = [dp, dv, dtheta, db_a, db_g], Euler-discretised at the IMU period,
// poses (position + orientation) at 10 Hz. Its gains after 300 s must equal the library's
// steady-state weights, which it computes per axis.
TEST(EstimatorWeightsTest, SteadyStateMatchesALongFullEkfRun) {
  WeightModel model;
  const WeightSchedule w = *ComputeWeightSchedule(model);
  ASSERT_EQ(w.steady.size(), 1u);

  const double h = 0.01, g = kGravity;
  using Mat15 = Eigen::Matrix<double, 15, 15>;
  Mat15 A = Mat15::Zero();
  A.block<3, 3>(0, 3).setIdentity();                    // dp' = dv
  A(3, 7) = g;                                          // dv_x' = g dtheta_y
  A(4, 6) = -g;                                         // dv_y' = -g dtheta_x
  A.block<3, 3>(3, 9) = -Eigen::Matrix3d::Identity();   // - db_a
  A.block<3, 3>(6, 12) = -Eigen::Matrix3d::Identity();  // dtheta' = - db_g
  const Mat15 F = Mat15::Identity() + h * A;
  Eigen::Matrix<double, 15, 1> q = Eigen::Matrix<double, 15, 1>::Zero();
  q.segment<3>(3).setConstant(h * h * model.accel_noise_sigma * model.accel_noise_sigma);
  q.segment<3>(6).setConstant(h * h * model.gyro_noise_sigma * model.gyro_noise_sigma);
  q.segment<3>(9).setConstant(h * model.accel_offset_random_walk * model.accel_offset_random_walk);
  q.segment<3>(12).setConstant(h * model.gyro_offset_random_walk * model.gyro_offset_random_walk);
  const Mat15 Q = q.asDiagonal();
  Eigen::Matrix<double, 6, 15> H = Eigen::Matrix<double, 6, 15>::Zero();
  H.block<3, 3>(0, 0).setIdentity();
  H.block<3, 3>(3, 6).setIdentity();
  Eigen::Matrix<double, 6, 1> r;
  r << Eigen::Vector3d::Constant(1e-4), Eigen::Vector3d::Constant(0.017 * 0.017);
  Mat15 P = Mat15::Identity();
  Eigen::Matrix<double, 15, 6> K;
  for (int k = 1; k <= 30000; ++k) {
    P = F * P * F.transpose() + Q;
    if (k % 10 == 0) {
      const Eigen::Matrix<double, 6, 6> S =
          H * P * H.transpose() + Eigen::Matrix<double, 6, 6>(r.asDiagonal());
      K = P * H.transpose() * S.inverse();
      P = (Mat15::Identity() - K * H) * P;
      P = 0.5 * (P + P.transpose()).eval();
    }
  }
  const CorrectionWeights& s = w.steady[0];
  // x axis: states (p_x, v_x, b_ax, theta_y, b_gy) from residuals (p_x, theta_y).
  const int rows[5] = {0, 3, 9, 7, 13};
  for (int i = 0; i < 5; ++i) {
    EXPECT_NEAR(s.horizontal(i, 0), K(rows[i], 0), 1e-6 * std::max(1.0, std::abs(K(rows[i], 0))))
        << "row " << i;
    EXPECT_NEAR(s.horizontal(i, 1), K(rows[i], 4), 1e-6 * std::max(1.0, std::abs(K(rows[i], 4))))
        << "row " << i;
  }
  // y axis pairs with -theta_x: the same gains with the tilt's sign flipped.
  EXPECT_NEAR(s.horizontal(0, 0), K(1, 1), 1e-6);
  EXPECT_NEAR(s.horizontal(3, 0), -K(6, 1), 1e-6);
  // Vertical and heading.
  EXPECT_NEAR(s.vertical[0], K(2, 2), 1e-6);
  EXPECT_NEAR(s.vertical[1], K(5, 2), 1e-6);
  EXPECT_NEAR(s.vertical[2], K(11, 2), 1e-6);
  EXPECT_NEAR(s.heading[0], K(8, 5), 1e-6);
  EXPECT_NEAR(s.heading[1], K(14, 5), 1e-6);
  // Sanity: the weights are fractions / have the signs the model implies.
  EXPECT_GT(s.vertical[0], 0);
  EXPECT_LT(s.vertical[0], 1);
  EXPECT_LT(s.vertical[2], 0);
  EXPECT_LT(s.heading[1], 0);
}

TEST(EstimatorWeightsTest, TransientStartsHighAndDecaysToSteadyState) {
  const WeightSchedule w = *ComputeWeightSchedule(WeightModel());
  const auto& tr = w.transient[0];
  ASSERT_GT(tr.size(), 10u);
  EXPECT_GT(tr.front().vertical[0], w.steady[0].vertical[0]);
  EXPECT_GT(std::abs(tr[5].vertical[2]), std::abs(w.steady[0].vertical[2]));
}

TEST(EstimatorWeightsTest, TwoSourcesAndDecoupledModel) {
  WeightModel m;
  m.pose_sources.push_back(PoseSourceNoise{20, 0.01, 0.017});
  const WeightSchedule two = *ComputeWeightSchedule(m);
  ASSERT_EQ(two.steady.size(), 2u);
  const WeightSchedule one = *ComputeWeightSchedule(WeightModel());
  // More information: each update weighs less than with one source alone.
  EXPECT_LT(two.steady[0].vertical[0], one.steady[0].vertical[0]);
  WeightModel d;
  d.couple_tilt = false;
  const WeightSchedule dec = *ComputeWeightSchedule(d);
  EXPECT_EQ(dec.steady[0].horizontal(3, 0), 0);  // no tilt correction from position
  EXPECT_NEAR(dec.steady[0].horizontal(0, 0), dec.steady[0].vertical[0], 1e-12);
  WeightModel bad;
  bad.pose_sources[0].position_sigma_m = 0;
  const auto r = ComputeWeightSchedule(bad);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("pose_sources[0].position_sigma_m"), std::string::npos);
}

// A loose tilt (a VO's): the tilt's weight from the orientation residual drops far below the
// heading's, the tilt is then corrected from the position residuals (gravity) instead; while
// trust_tilt_s lasts, the tilt keeps the orientation's noise.
TEST(EstimatorWeightsTest, LooseTiltTakesTheTiltFromGravityAfterTheTrustedStart) {
  WeightModel m;
  m.pose_sources[0] = PoseSourceNoise{20, 0.01, 0.005, 0.17};
  m.trust_tilt_s = 4;
  const WeightSchedule w = *ComputeWeightSchedule(m);
  WeightModel tight = m;
  tight.pose_sources[0].tilt_sigma_rad = 0;
  const WeightSchedule t = *ComputeWeightSchedule(tight);
  const CorrectionWeights& loose = w.steady[0];
  EXPECT_NEAR(loose.heading[0], t.steady[0].heading[0], 1e-12) << "the heading is unchanged";
  EXPECT_LT(loose.horizontal(3, 1), 0.05 * t.steady[0].horizontal(3, 1));
  EXPECT_GT(loose.horizontal(3, 0), t.steady[0].horizontal(3, 0));
  // The first 80 updates (4 s at 20 Hz) are the tight model's, then the weight drops.
  ASSERT_GT(w.transient[0].size(), 81u);
  EXPECT_NEAR(w.transient[0][40].horizontal(3, 1), t.transient[0][40].horizontal(3, 1), 1e-12);
  EXPECT_LT(w.transient[0][81].horizontal(3, 1), 0.5 * t.transient[0][81].horizontal(3, 1));
  WeightModel bad = m;
  bad.trust_tilt_s = -1;
  const auto r = ComputeWeightSchedule(bad);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("trust_tilt_s"), std::string::npos);
}

}  // namespace
}  // namespace mav::control
