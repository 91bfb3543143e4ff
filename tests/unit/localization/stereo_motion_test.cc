#include "mav/localization/stereo_motion.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "tests/common/numeric.h"

#include "synthetic_stereo.h"

namespace mav::localization {
namespace {

using geometry::SE3;
using geometry::Vector6d;

constexpr double kRadToDeg = 180.0 / M_PI;

// Random points in front of the previous camera (depth 1.5 .. 8 m) that stay visible in both
// current images after `T_cur_prev`; exact observations.
void MakeCorrespondences(const camera::RectifiedStereo& rig, const SE3& T_cur_prev, int n,
                         uint64_t seed, std::vector<Eigen::Vector3d>* points,
                         std::vector<StereoObservation>* obs) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(20, rig.width - 20), v(20, rig.height - 20), z(1.5, 8.0);
  points->clear();
  obs->clear();
  while (static_cast<int>(points->size()) < n) {
    const Eigen::Vector3d p = rig.Unproject({u(rng), v(rng)}, z(rng));
    const Eigen::Vector3d q = T_cur_prev * p;
    const auto l = rig.ProjectLeft(q), r = rig.ProjectRight(q);
    if (!l || !r) continue;
    if (l->x() < 0 || l->x() >= rig.width || l->y() < 0 || l->y() >= rig.height) continue;
    if (r->x() < 0 || r->x() >= rig.width) continue;
    points->push_back(p);
    obs->emplace_back(l->x(), l->y(), r->x(), r->y());
  }
}

double RotationErrorDeg(const SE3& a, const SE3& b) {
  return geometry::AngleBetween(a.Rotation(), b.Rotation()) * kRadToDeg;
}

TEST(StereoMotionTest, JacobianMatchesNumericDerivative) {
  const camera::RectifiedStereo rig = synthetic::EurocLikeRig();
  Vector6d xi;
  xi << 0.05, -0.02, 0.1, 0.02, -0.03, 0.01;
  const SE3 T = SE3::Exp(xi);
  const StereoObservation obs(300, 200, 280, 201);
  for (const Eigen::Vector3d& p : {Eigen::Vector3d(0.3, -0.2, 2.0), Eigen::Vector3d(-1, 0.5, 5.0),
                                   Eigen::Vector3d(0.01, 0.02, 0.8)}) {
    Eigen::Vector4d r;
    Matrix46d J;
    ASSERT_TRUE(StereoReprojectionResidual(rig, T, p, obs, &r, &J));
    const Matrix46d numeric = test_support::NumericJacobian<4, 6>(
        [&](const Vector6d& d) {
          Eigen::Vector4d residual = Eigen::Vector4d::Constant(std::nan(""));
          EXPECT_TRUE(StereoReprojectionResidual(rig, SE3::Exp(d) * T, p, obs, &residual, nullptr));
          return residual;
        },
        Vector6d::Zero());
    EXPECT_LT((J - numeric).norm(), 1e-5 * (1.0 + J.norm())) << "analytic\n"
                                                             << J << "\nnumeric\n"
                                                             << numeric;
  }
}

TEST(StereoMotionTest, PointBehindCameraHasNoResidual) {
  const camera::RectifiedStereo rig = synthetic::EurocLikeRig();
  Eigen::Vector4d r(1, 2, 3, 4);
  EXPECT_FALSE(
      StereoReprojectionResidual(rig, SE3(), {0, 0, -1}, StereoObservation::Zero(), &r, nullptr));
  EXPECT_EQ(r, Eigen::Vector4d(1, 2, 3, 4));
}

struct MotionCase {
  const char* name;
  Vector6d xi;  // T_cur_prev = Exp(xi)
};

class ExactMotionTest : public ::testing::TestWithParam<MotionCase> {};

TEST_P(ExactMotionTest, RecoversMotionFromNoiseFreeProjections) {
  const camera::RectifiedStereo rig = synthetic::EurocLikeRig();
  const SE3 T_true = SE3::Exp(GetParam().xi);
  std::vector<Eigen::Vector3d> points;
  std::vector<StereoObservation> obs;
  MakeCorrespondences(rig, T_true, 150, 3, &points, &obs);
  const StereoMotionEstimate est = EstimateStereoMotion(rig, points, obs, {});
  ASSERT_TRUE(est.ok) << est.failure;
  EXPECT_EQ(est.inliers.size(), points.size());
  EXPECT_LT(RotationErrorDeg(est.T_cur_prev, T_true), 0.1);
  const double t_norm = T_true.Translation().norm();
  const double t_err = (est.T_cur_prev.Translation() - T_true.Translation()).norm();
  if (t_norm > 0) {
    EXPECT_LT(t_err / t_norm, 0.01) << "translation error " << t_err << " m of " << t_norm;
  } else {
    EXPECT_LT(t_err, 1e-4);
  }
  EXPECT_LT(est.mean_error_px, 1e-6);
}

Vector6d Xi(double tx, double ty, double tz, double rx, double ry, double rz) {
  Vector6d xi;
  xi << tx, ty, tz, rx, ry, rz;
  return xi;
}

INSTANTIATE_TEST_SUITE_P(
    Motions, ExactMotionTest,
    ::testing::Values(MotionCase{"PureTranslation", Xi(0.08, -0.03, 0.02, 0, 0, 0)},
                      MotionCase{"PureRotation", Xi(0, 0, 0, 0.01, -0.035, 0.02)},
                      MotionCase{"ForwardMotion", Xi(0, 0, -0.15, 0, 0, 0)},
                      MotionCase{"GeneralMotion", Xi(0.05, 0.02, -0.1, 0.02, 0.03, -0.01)}),
    [](const ::testing::TestParamInfo<MotionCase>& info) { return info.param.name; });

// RANSAC statistics over many seeds: 30 % gross outliers, 0.3 px noise on inliers.
TEST(StereoMotionTest, RansacWithThirtyPercentOutliersOverManySeeds) {
  const camera::RectifiedStereo rig = synthetic::EurocLikeRig();
  const int kSeeds = 100, kPoints = 150;
  int successes = 0;
  double sum_rot_deg = 0, sum_trans_rel = 0;
  for (int seed = 0; seed < kSeeds; ++seed) {
    std::mt19937_64 rng(1000 + seed);
    std::normal_distribution<double> noise(0, 0.3), motion(0, 1);
    Vector6d xi;
    xi << 0.05 * motion(rng), 0.05 * motion(rng), 0.1 * motion(rng), 0.02 * motion(rng),
        0.02 * motion(rng), 0.02 * motion(rng);
    const SE3 T_true = SE3::Exp(xi);
    std::vector<Eigen::Vector3d> points;
    std::vector<StereoObservation> obs;
    MakeCorrespondences(rig, T_true, kPoints, 2000 + seed, &points, &obs);
    std::uniform_real_distribution<double> u(0, rig.width), v(0, rig.height), d(1, 60);
    for (int i = 0; i < kPoints; ++i) {
      if (i % 10 < 3) {  // outlier: a random observation with positive disparity
        const double ul = u(rng), vl = v(rng);
        obs[i] = StereoObservation(ul, vl, ul - d(rng), vl);
      } else {
        for (int k = 0; k < 4; ++k) obs[i](k) += noise(rng);
      }
    }
    StereoMotionOptions options;
    options.seed = seed;
    const StereoMotionEstimate est = EstimateStereoMotion(rig, points, obs, options);
    if (!est.ok) continue;
    const double rot = RotationErrorDeg(est.T_cur_prev, T_true);
    const double trans =
        (est.T_cur_prev.Translation() - T_true.Translation()).norm() / T_true.Translation().norm();
    sum_rot_deg += rot;
    sum_trans_rel += trans;
    int outliers_accepted = 0;
    for (int i : est.inliers) outliers_accepted += (i % 10 < 3);
    if (rot < 0.1 && trans < 0.05 && outliers_accepted <= 2) ++successes;
  }
  EXPECT_GE(successes, 99) << "of " << kSeeds;
  EXPECT_LT(sum_rot_deg / kSeeds, 0.03);
  EXPECT_LT(sum_trans_rel / kSeeds, 0.02);
}

TEST(StereoMotionTest, DeterministicForASeed) {
  const camera::RectifiedStereo rig = synthetic::EurocLikeRig();
  const SE3 T_true = SE3::Exp(Xi(0.05, 0, 0.1, 0, 0.02, 0));
  std::vector<Eigen::Vector3d> points;
  std::vector<StereoObservation> obs;
  MakeCorrespondences(rig, T_true, 80, 5, &points, &obs);
  for (int i = 0; i < 80; i += 3) obs[i] += StereoObservation(40, -25, 33, -25);
  const StereoMotionEstimate a = EstimateStereoMotion(rig, points, obs, {});
  const StereoMotionEstimate b = EstimateStereoMotion(rig, points, obs, {});
  ASSERT_TRUE(a.ok && b.ok);
  EXPECT_EQ(a.inliers, b.inliers);
  EXPECT_EQ(a.hypotheses, b.hypotheses);
  EXPECT_TRUE(a.T_cur_prev.IsApprox(b.T_cur_prev, 0));
}

TEST(StereoMotionTest, FailsWithAReasonOnTooFewOrInconsistentCorrespondences) {
  const camera::RectifiedStereo rig = synthetic::EurocLikeRig();
  std::vector<Eigen::Vector3d> points;
  std::vector<StereoObservation> obs;
  MakeCorrespondences(rig, SE3(), 5, 1, &points, &obs);
  StereoMotionEstimate est = EstimateStereoMotion(rig, points, obs, {});
  EXPECT_FALSE(est.ok);
  EXPECT_NE(est.failure.find("too few correspondences"), std::string::npos) << est.failure;

  // Pure noise: no motion explains more than a handful of points.
  MakeCorrespondences(rig, SE3(), 60, 2, &points, &obs);
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(0, 752), v(0, 480);
  for (auto& o : obs) o = StereoObservation(u(rng), v(rng), u(rng), v(rng));
  est = EstimateStereoMotion(rig, points, obs, {});
  EXPECT_FALSE(est.ok);
  EXPECT_NE(est.failure.find("RANSAC failed"), std::string::npos) << est.failure;
  EXPECT_TRUE(est.T_cur_prev.Translation().allFinite());
}

TEST(StereoMotionTest, OptionsValidationNamesTheField) {
  StereoMotionOptions o;
  std::string why;
  EXPECT_TRUE(o.IsValid(&why));
  o.inlier_threshold_px = 0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("inlier_threshold_px"), std::string::npos);
  o = {};
  o.confidence = 1.0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("confidence"), std::string::npos);
}

}  // namespace
}  // namespace mav::localization

namespace mav::localization {
namespace {

// Noisy matches of points in a shallow depth range (2.5 .. 4 m, a room's wall) under sideways
// motion with a little yaw: previous pixels and disparity and current pixels each get Gaussian
// noise of `sigma` px. Returns the mean, over seeds, of the estimated translation projected on
// the true one (1 = unbiased) for motion-only and joint (motion + structure) refinement.
void ScaleOfNoisyEstimates(double sigma, int seeds, double* motion_only, double* joint,
                           double* joint_exact_error) {
  const camera::RectifiedStereo rig = synthetic::EurocLikeRig();
  Vector6d xi;
  xi << 0.04, 0.005, 0.01, 0.0, 0.01, 0.0;
  const SE3 T_true = SE3::Exp(xi);
  const Eigen::Vector3d t_prev_cur = T_true.Inverse().Translation();
  double sum_motion = 0, sum_joint = 0;
  *joint_exact_error = 0;
  for (int seed = 0; seed < seeds; ++seed) {
    std::mt19937_64 rng(1000 + seed);
    std::uniform_real_distribution<double> u(40, rig.width - 40), v(40, rig.height - 40),
        z(2.5, 4.0);
    std::normal_distribution<double> noise(0.0, sigma);
    std::vector<Eigen::Vector3d> exact_points, points;
    std::vector<StereoObservation> exact_obs, obs;
    while (points.size() < 400) {
      const Eigen::Vector3d p = rig.Unproject({u(rng), v(rng)}, z(rng));
      const auto l = rig.ProjectLeft(T_true * p), r = rig.ProjectRight(T_true * p);
      if (!l || !r || l->x() < 0 || l->x() >= rig.width || r->x() < 0) continue;
      const auto pl = rig.ProjectLeft(p);
      const double d = rig.DisparityFromDepth(p.z()) + noise(rng) - noise(rng);
      exact_points.push_back(p);
      exact_obs.emplace_back(l->x(), l->y(), r->x(), r->y());
      points.push_back(
          rig.Unproject({pl->x() + noise(rng), pl->y() + noise(rng)}, rig.DepthFromDisparity(d)));
      obs.emplace_back(l->x() + noise(rng), l->y() + noise(rng), r->x() + noise(rng),
                       r->y() + noise(rng));
    }
    std::vector<int> all(points.size());
    for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
    SE3 T_motion;
    ASSERT_TRUE(RefineStereoMotion(rig, points, obs, all, 30, &T_motion));
    SE3 T_joint = T_motion;
    ASSERT_TRUE(RefineStereoMotionAndStructure(rig, points, obs, all, 10, &T_joint));
    sum_motion += T_motion.Inverse().Translation().dot(t_prev_cur) / t_prev_cur.squaredNorm();
    sum_joint += T_joint.Inverse().Translation().dot(t_prev_cur) / t_prev_cur.squaredNorm();
    SE3 T_exact;
    ASSERT_TRUE(RefineStereoMotionAndStructure(rig, exact_points, exact_obs, all, 10, &T_exact));
    *joint_exact_error =
        std::max(*joint_exact_error, (T_exact.Translation() - T_true.Translation()).norm() +
                                         RotationErrorDeg(T_exact, T_true));
  }
  *motion_only = sum_motion / seeds;
  *joint = sum_joint / seeds;
}

TEST(StereoMotionTest, JointRefinementIsExactWithoutNoiseAndStaysCloseWithNoise) {
  double motion_only = 0, joint = 0, exact_error = 0;
  ScaleOfNoisyEstimates(0.3, 40, &motion_only, &joint, &exact_error);
  std::printf(
      "translation scale with 0.3 px noise (shallow scene, sideways motion): motion-only "
      "%.4f, joint %.4f\n",
      motion_only, joint);
  EXPECT_LT(exact_error, 1e-6);  // noise-free: exact (metres + degrees)
  // Not unbiased in general (both estimators carry an O(sigma^2) scale bias; on this shallow
  // synthetic scene the joint one is the larger, measured 1.014 vs 1.005); on the simulator's
  // sequences the joint one is the smaller (docs/localization.md).
  EXPECT_NEAR(joint, 1.0, 0.03);
}

TEST(StereoMotionTest, JointRefinementNeedsThreePoints) {
  const camera::RectifiedStereo rig = synthetic::EurocLikeRig();
  std::vector<Eigen::Vector3d> points = {{0, 0, 2}, {0.5, 0, 3}};
  std::vector<StereoObservation> obs(2, StereoObservation(300, 200, 280, 200));
  SE3 T = SE3::Exp((Vector6d() << 0.1, 0, 0, 0, 0, 0).finished());
  const SE3 before = T;
  EXPECT_FALSE(RefineStereoMotionAndStructure(rig, points, obs, {0, 1}, 5, &T));
  EXPECT_EQ(T.Translation(), before.Translation());
}

}  // namespace
}  // namespace mav::localization

namespace mav::localization {
namespace {

// `n` noisy (0.5 px) matches of far points (12 .. 30 m) under a sideways step with a little
// yaw: over a narrow field of view a turn and a sideways shift look alike, so few matches leave
// the rotation loose.
void FarNoisyCorrespondences(const camera::RectifiedStereo& rig, const SE3& T_true, int n,
                             uint64_t seed, std::vector<Eigen::Vector3d>* points,
                             std::vector<StereoObservation>* obs) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(40, rig.width - 40), v(40, rig.height - 40),
      z(12.0, 30.0);
  std::normal_distribution<double> noise(0.0, 0.5);
  points->clear();
  obs->clear();
  while (static_cast<int>(points->size()) < n) {
    const Eigen::Vector3d p = rig.Unproject({u(rng), v(rng)}, z(rng));
    const auto l = rig.ProjectLeft(T_true * p), r = rig.ProjectRight(T_true * p);
    if (!l || !r || l->x() < 0 || l->x() >= rig.width || r->x() < 0) continue;
    points->push_back(p);
    obs->emplace_back(l->x() + noise(rng), l->y() + noise(rng), r->x() + noise(rng),
                      r->y() + noise(rng));
  }
}

TEST(StereoMotionTest, GyroPriorSettlesTheRotationFewFarMatchesLeaveLoose) {
  const camera::RectifiedStereo rig = synthetic::EurocLikeRig();
  Vector6d xi;
  xi << 0.08, 0.0, 0.02, 0.0, 0.01, 0.0;
  const SE3 T_true = SE3::Exp(xi);
  const int kSeeds = 40;
  double without = 0, with = 0, vision = 0;
  for (int seed = 0; seed < kSeeds; ++seed) {
    std::vector<Eigen::Vector3d> points;
    std::vector<StereoObservation> obs;
    FarNoisyCorrespondences(rig, T_true, 15, 3000 + seed, &points, &obs);
    StereoMotionOptions options;
    options.seed = seed;
    options.min_inliers = 8;
    const StereoMotionEstimate plain = EstimateStereoMotion(rig, points, obs, options);
    // The gyro's rotation: the truth within 1e-4 rad, weighted as such (0.5 px / 1e-4 rad).
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> gyro_noise(0.0, 1e-4);
    const RotationPrior prior{
        geometry::ExpSO3(Eigen::Vector3d(gyro_noise(rng), gyro_noise(rng), gyro_noise(rng))) *
            T_true.Rotation(),
        5000, 0.02};
    const StereoMotionEstimate aided = EstimateStereoMotion(rig, points, obs, options, &prior);
    ASSERT_TRUE(plain.ok) << plain.failure;
    ASSERT_TRUE(aided.ok) << aided.failure;
    without += RotationErrorDeg(plain.T_cur_prev, T_true);
    with += RotationErrorDeg(aided.T_cur_prev, T_true);
    // The matches' own rotation: where a motion-only refinement without the prior converges.
    SE3 matches_only = aided.T_cur_prev;
    ASSERT_TRUE(RefineStereoMotion(rig, points, obs, aided.inliers, 30, &matches_only));
    vision += geometry::AngleBetween(aided.vision_R_cur_prev, matches_only.Rotation()) * kRadToDeg;
  }
  std::printf("mean rotation error over %d seeds: vision only %.4f deg, gyro-aided %.4f deg\n",
              kSeeds, without / kSeeds, with / kSeeds);
  EXPECT_LT(with, 0.25 * without);
  EXPECT_LT(with / kSeeds, 0.02);
  EXPECT_LT(vision / kSeeds, 0.05 * without / kSeeds);
}

TEST(StereoMotionTest, GyroPriorYieldsWhereManyMatchesAgreeAndGatesHypotheses) {
  const camera::RectifiedStereo rig = synthetic::EurocLikeRig();
  Vector6d xi;
  xi << 0.05, 0.01, 0.08, 0.01, 0.02, -0.01;
  const SE3 T_true = SE3::Exp(xi);
  std::vector<Eigen::Vector3d> points;
  std::vector<StereoObservation> obs;
  MakeCorrespondences(rig, T_true, 300, 77, &points, &obs);
  std::mt19937_64 rng(5);
  std::normal_distribution<double> noise(0.0, 0.3);
  for (StereoObservation& o : obs) {
    for (int k = 0; k < 4; ++k) o(k) += noise(rng);
  }
  // A prior 0.02 degrees (3.5 sigma) off the truth about the optical axis, which 300 matches
  // all over the image pin down about as well as the prior (~1e-4 rad): the estimate is their
  // weighted mean, nearer the truth than the prior, and the matches' own rotation is the truth.
  const double off_deg = 0.02;
  const Eigen::Quaterniond off =
      geometry::ExpSO3(Eigen::Vector3d(0, 0, off_deg / kRadToDeg)) * T_true.Rotation();
  const RotationPrior prior{off, 5000, 0.02};
  const StereoMotionEstimate est = EstimateStereoMotion(rig, points, obs, {}, &prior);
  ASSERT_TRUE(est.ok) << est.failure;
  const double est_deg = RotationErrorDeg(est.T_cur_prev, T_true);
  const double vision_deg =
      geometry::AngleBetween(est.vision_R_cur_prev, T_true.Rotation()) * kRadToDeg;
  std::printf("prior %.3f deg off: estimate %.4f deg, matches alone %.4f deg\n", off_deg, est_deg,
              vision_deg);
  EXPECT_LT(est_deg, 0.8 * off_deg);
  EXPECT_LT(vision_deg, 0.25 * off_deg);
  // A gate no hypothesis passes (the prior 5 degrees off, the gate 0.5): RANSAC finds nothing.
  const RotationPrior wrong{
      geometry::ExpSO3(Eigen::Vector3d(0, 0, 5 / kRadToDeg)) * T_true.Rotation(), 1.0,
      0.5 / kRadToDeg};
  const StereoMotionEstimate gated = EstimateStereoMotion(rig, points, obs, {}, &wrong);
  EXPECT_FALSE(gated.ok);
  EXPECT_NE(gated.failure.find("RANSAC failed"), std::string::npos) << gated.failure;
}

}  // namespace
}  // namespace mav::localization
