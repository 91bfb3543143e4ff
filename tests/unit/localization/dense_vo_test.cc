#include "mav/localization/dense_vo.h"

#include <cmath>
#include <cstdint>
#include <functional>
#include <optional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include "tests/common/numeric.h"
#include "tests/common/pose_matchers.h"
#include "tests/common/stereo_rig.h"

#include "mav/camera/stereo.h"
#include "mav/eval/trajectory_metrics.h"
#include "mav/geometry/se3.h"
#include "mav/sim/scenario.h"

namespace mav::localization {
namespace {

using geometry::SE3;

// The rig this test's thresholds were tuned with (principal point off centre).
camera::RectifiedStereo TestRig() { return test_support::EurocLikeRig(458.0, 367.0, 248.0); }

constexpr double kRadToDeg = 180.0 / M_PI;

// Smooth value noise on a lattice of the given spacing (metres), seeded.
class ValueNoise {
 public:
  ValueNoise(double spacing, uint64_t seed) : spacing_(spacing) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<float> unit(0.f, 1.f);
    values_.resize(kSize * kSize);
    for (float& v : values_) v = unit(rng);
  }
  double operator()(double s, double t) const {
    const double x = s / spacing_ + 1000.0, y = t / spacing_ + 1000.0;
    const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
    const double fx = Smooth(x - x0), fy = Smooth(y - y0);
    const double v00 = At(x0, y0), v10 = At(x0 + 1, y0), v01 = At(x0, y0 + 1),
                 v11 = At(x0 + 1, y0 + 1);
    return (1 - fy) * ((1 - fx) * v00 + fx * v10) + fy * ((1 - fx) * v01 + fx * v11);
  }

 private:
  static constexpr int kSize = 512;
  static double Smooth(double a) { return a * a * (3 - 2 * a); }
  double At(int x, int y) const { return values_[(y & (kSize - 1)) * kSize + (x & (kSize - 1))]; }
  double spacing_;
  std::vector<float> values_;
};

// A textured box room seen from inside (the world frame is a camera frame: x right, y down,
// z forward), rendered by ray casting with 2x2 supersampling, plus an optional affine brightness
// change. Noise-free.
class BoxRoom {
 public:
  BoxRoom() : fine_(0.035, 7), coarse_(0.2, 11) {}

  cv::Mat Render(const camera::RectifiedStereo& rig, const SE3& T_world_cam, double gain = 1.0,
                 double bias = 0.0) const {
    cv::Mat image(rig.height, rig.width, CV_8UC1);
    const Eigen::Matrix3d R = T_world_cam.RotationMatrix();
    const Eigen::Vector3d& o = T_world_cam.Translation();
    for (int v = 0; v < rig.height; ++v) {
      uint8_t* row = image.ptr<uint8_t>(v);
      for (int u = 0; u < rig.width; ++u) {
        double sum = 0;
        for (int k = 0; k < 4; ++k) {
          const double su = u - 0.25 + 0.5 * (k & 1), sv = v - 0.25 + 0.5 * (k >> 1);
          const Eigen::Vector3d d =
              R * Eigen::Vector3d((su - rig.cx) / rig.fx, (sv - rig.cy) / rig.fy, 1.0);
          sum += Radiance(o, d);
        }
        const double value = gain * 0.25 * sum + bias;
        row[u] = static_cast<uint8_t>(std::clamp(std::lround(value), 0L, 255L));
      }
    }
    return image;
  }

  void RenderStereo(const camera::RectifiedStereo& rig, const SE3& T_world_left, cv::Mat* left,
                    cv::Mat* right, double gain = 1.0, double bias = 0.0) const {
    *left = Render(rig, T_world_left, gain, bias);
    const SE3 T_left_right(Eigen::Quaterniond::Identity(), Eigen::Vector3d(rig.baseline, 0, 0));
    *right = Render(rig, T_world_left * T_left_right, gain, bias);
  }

 private:
  // Walls at x = +-2.2, y = -1.3 (ceiling), y = +1.2 (floor), z = +3.5 (front), z = -3 (back).
  double Radiance(const Eigen::Vector3d& o, const Eigen::Vector3d& d) const {
    double best = 1e9, s = 0, t = 0;
    auto hit = [&](int axis, double plane, int sa, int ta) {
      if (std::abs(d[axis]) < 1e-12) return;
      const double lambda = (plane - o[axis]) / d[axis];
      if (lambda <= 0 || lambda >= best) return;
      best = lambda;
      const Eigen::Vector3d p = o + lambda * d;
      s = p[sa] + 10.0 * axis + (plane > 0 ? 3.0 : 0.0);
      t = p[ta];
    };
    hit(0, 2.2, 2, 1);
    hit(0, -2.2, 2, 1);
    hit(1, -1.3, 0, 2);
    hit(1, 1.2, 0, 2);
    hit(2, 3.5, 0, 1);
    hit(2, -3.0, 0, 1);
    return 30.0 + 200.0 * (0.65 * fine_(s, t) + 0.35 * coarse_(s, t));
  }

  ValueNoise fine_, coarse_;
};

struct MotionErrors {
  double rotation_deg = 0;
  double translation_rel = 0;  // |t_est - t_true| / |t_true|
};

MotionErrors Compare(const SE3& estimate, const SE3& truth) {
  MotionErrors e;
  e.rotation_deg = geometry::AngleBetween(estimate.Rotation(), truth.Rotation()) * kRadToDeg;
  e.translation_rel =
      (estimate.Translation() - truth.Translation()).norm() / truth.Translation().norm();
  return e;
}

// Runs the tracker over poses[0..n) (T_world_cam), checking every frame-to-frame motion.
void RunAndCheck(const std::vector<SE3>& poses, const DenseVoOptions& options,
                 double max_rotation_deg, double max_translation_rel) {
  const camera::RectifiedStereo rig = TestRig();
  const BoxRoom room;
  auto vo = DenseVo::Create(rig, options, poses[0]);
  ASSERT_TRUE(vo.ok()) << vo.status().ToString();
  for (size_t k = 0; k < poses.size(); ++k) {
    cv::Mat left, right;
    room.RenderStereo(rig, poses[k], &left, &right);
    auto result = vo->ProcessFrame(static_cast<int64_t>(k) * 50'000'000, left, right);
    ASSERT_TRUE(result.ok()) << result.status().ToString();
    ASSERT_EQ(result->state, TrackingState::kOk) << "frame " << k << ": " << result->lost_reason;
    if (k == 0) {
      EXPECT_TRUE(result->reference_reset);
      EXPECT_THAT(result->T_world_cam, test_support::IsNearPose(poses[0], 1e-12, 1e-6));
      continue;
    }
    const SE3 truth = poses[k - 1].Inverse() * poses[k];
    const MotionErrors e = Compare(result->T_prev_cur, truth);
    EXPECT_LT(e.rotation_deg, max_rotation_deg) << "frame " << k;
    EXPECT_LT(e.translation_rel, max_translation_rel)
        << "frame " << k << " estimate " << result->T_prev_cur.Translation().transpose()
        << " truth " << truth.Translation().transpose();
    EXPECT_GT(result->num_pixels_used, 1000);
    EXPECT_TRUE(result->T_world_cam.Translation().allFinite());
  }
}

std::vector<SE3> Trajectory(int frames, const Eigen::Vector3d& step_t,
                            const Eigen::Vector3d& step_phi) {
  std::vector<SE3> poses;
  SE3 T(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.1, -0.05, 0.0));
  for (int k = 0; k < frames; ++k) {
    poses.push_back(T);
    geometry::Vector6d xi;
    xi << step_t, step_phi;
    T = T * SE3::Exp(xi);
  }
  return poses;
}

// Renders `room` from `pose` and tracks it as frame k (stamped k ns). The frame must be tracked:
// nullopt, after a test failure saying why, when it is not.
std::optional<DenseFrameResult> TrackRendered(DenseVo* vo, const BoxRoom& room,
                                              const camera::RectifiedStereo& rig, const SE3& pose,
                                              size_t k) {
  cv::Mat left, right;
  room.RenderStereo(rig, pose, &left, &right);
  auto result = vo->ProcessFrame(static_cast<int64_t>(k), left, right);
  if (!result.ok()) {
    ADD_FAILURE() << "frame " << k << ": " << result.status().ToString();
    return std::nullopt;
  }
  if (result->state != TrackingState::kOk) {
    ADD_FAILURE() << "frame " << k << " not tracked: " << result->lost_reason;
    return std::nullopt;
  }
  return std::move(*result);
}

TEST(DenseVoTest, PureTranslationSideways) {
  RunAndCheck(Trajectory(6, Eigen::Vector3d(0.03, 0.0, 0.0), Eigen::Vector3d::Zero()), {}, 0.1,
              0.01);
}

TEST(DenseVoTest, PureTranslationDiagonal) {
  RunAndCheck(Trajectory(6, Eigen::Vector3d(-0.02, 0.015, 0.01), Eigen::Vector3d::Zero()), {}, 0.1,
              0.01);
}

TEST(DenseVoTest, PureRotation) {
  // Rotation about the optical centre: the translation is zero, so check it in metres.
  const std::vector<SE3> poses =
      Trajectory(6, Eigen::Vector3d::Zero(), Eigen::Vector3d(0.004, 0.015, 0.003));
  const camera::RectifiedStereo rig = TestRig();
  const BoxRoom room;
  auto vo = DenseVo::Create(rig, {}, poses[0]);
  ASSERT_TRUE(vo.ok());
  for (size_t k = 0; k < poses.size(); ++k) {
    const std::optional<DenseFrameResult> result = TrackRendered(&*vo, room, rig, poses[k], k);
    ASSERT_TRUE(result.has_value());
    if (k == 0) continue;
    const SE3 truth = poses[k - 1].Inverse() * poses[k];
    const double rotation_error_deg =
        geometry::AngleBetween(result->T_prev_cur.Rotation(), truth.Rotation()) * kRadToDeg;
    EXPECT_LT(rotation_error_deg, 0.1) << "frame " << k;
    // 1 % of the rotation's arc at 1 m.
    EXPECT_LT(result->T_prev_cur.Translation().norm(), 0.01 * 0.0158) << "frame " << k;
  }
}

TEST(DenseVoTest, ForwardMotion) {
  RunAndCheck(Trajectory(6, Eigen::Vector3d(0.0, 0.0, 0.05), Eigen::Vector3d::Zero()), {}, 0.1,
              0.01);
}

TEST(DenseVoTest, ForwardMotionWithTurn) {
  RunAndCheck(Trajectory(6, Eigen::Vector3d(0.01, 0.0, 0.04), Eigen::Vector3d(0.0, 0.01, 0.0)), {},
              0.1, 0.01);
}

TEST(DenseVoTest, FullResolutionHuber) {
  DenseVoOptions options;
  options.finest_level = 0;
  options.depth_level = 0;
  options.num_disparities = 96;
  options.loss = DenseRobustLoss::kHuber;
  RunAndCheck(Trajectory(4, Eigen::Vector3d(0.02, 0.0, 0.03), Eigen::Vector3d(0.0, 0.008, 0.0)),
              options, 0.1, 0.01);
}

TEST(DenseVoTest, ExposureChangeIsAbsorbedByAffineBrightness) {
  const camera::RectifiedStereo rig = TestRig();
  const BoxRoom room;
  const std::vector<SE3> poses =
      Trajectory(3, Eigen::Vector3d(0.02, 0.0, 0.02), Eigen::Vector3d(0.0, 0.005, 0.0));
  auto vo = DenseVo::Create(rig, {}, poses[0]);
  ASSERT_TRUE(vo.ok());
  const double gains[] = {1.0, 1.15, 0.9};
  const double biases[] = {0.0, -8.0, 5.0};
  for (size_t k = 0; k < poses.size(); ++k) {
    cv::Mat left, right;
    room.RenderStereo(rig, poses[k], &left, &right, gains[k], biases[k]);
    auto result = vo->ProcessFrame(static_cast<int64_t>(k), left, right);
    ASSERT_TRUE(result.ok());
    ASSERT_EQ(result->state, TrackingState::kOk) << result->lost_reason;
    if (k == 0) continue;
    // Bilinear resampling at sub-pixel positions lowers the contrast of the high-gradient
    // pixels by ~1 % (the gain absorbs it even without an exposure change), and gain 1.15
    // saturates the brightest texture, so the gain is checked to 3.5 %.
    EXPECT_NEAR(result->brightness_gain, gains[k], 0.035) << "frame " << k;
    const MotionErrors e = Compare(result->T_prev_cur, poses[k - 1].Inverse() * poses[k]);
    EXPECT_LT(e.rotation_deg, 0.1) << "frame " << k;
    EXPECT_LT(e.translation_rel, 0.01) << "frame " << k;
  }
}

TEST(DenseVoTest, KeyframeIsRenewedAfterLargeMotion) {
  DenseVoOptions options;
  options.keyframe_max_translation_m = 0.05;
  const camera::RectifiedStereo rig = TestRig();
  const BoxRoom room;
  const std::vector<SE3> poses =
      Trajectory(8, Eigen::Vector3d(0.02, 0.0, 0.02), Eigen::Vector3d::Zero());
  auto vo = DenseVo::Create(rig, options, poses[0]);
  ASSERT_TRUE(vo.ok());
  for (size_t k = 0; k < poses.size(); ++k) {
    ASSERT_TRUE(TrackRendered(&*vo, room, rig, poses[k], k).has_value());
  }
  EXPECT_GE(vo->keyframes_created(), 3);
  // Chaining through keyframes keeps the pose accurate: 8 frames, 0.2 m path.
  EXPECT_LT((vo->T_world_cam().Translation() - poses.back().Translation()).norm(), 0.004);
  EXPECT_LT(
      geometry::AngleBetween(vo->T_world_cam().Rotation(), poses.back().Rotation()) * kRadToDeg,
      0.2);
}

// --- Jacobians ---

cv::Mat SmoothImage(int width, int height) {
  cv::Mat image(height, width, CV_32F);
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      image.at<float>(v, u) =
          static_cast<float>(128.0 + 60.0 * std::sin(0.11 * u + 0.3) * std::cos(0.07 * v) +
                             30.0 * std::sin(0.05 * (u + v)));
    }
  }
  return image;
}

TEST(DenseVoJacobianTest, ProjectionTwistJacobianMatchesNumeric) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> xy(-1.5, 1.5), z(0.5, 6.0);
  const double fx = 458.0, fy = 457.0;
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Vector3d p(xy(rng), xy(rng), z(rng));
    const Eigen::Matrix<double, 2, 6> analytic = ProjectionTwistJacobian(p, fx, fy);
    auto project = [&](const geometry::Vector6d& xi) {
      const Eigen::Vector3d q = SE3::Exp(xi) * p;
      return Eigen::Vector2d(fx * q.x() / q.z(), fy * q.y() / q.z());
    };
    const Eigen::Matrix<double, 2, 6> numeric =
        test_support::NumericJacobian<2, 6>(project, geometry::Vector6d::Zero());
    for (int k = 0; k < 6; ++k) {
      EXPECT_NEAR(numeric(0, k), analytic(0, k), 1e-4 * (1 + std::abs(numeric(0, k))))
          << "trial " << trial << " column " << k;
      EXPECT_NEAR(numeric(1, k), analytic(1, k), 1e-4 * (1 + std::abs(numeric(1, k))))
          << "trial " << trial << " column " << k;
    }
  }
}

TEST(DenseVoJacobianTest, PhotometricJacobianMatchesNumeric) {
  const cv::Mat image = SmoothImage(320, 240);
  const double fx = 300.0, fy = 300.0, cx = 160.0, cy = 120.0;
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> uu(40, 280), vv(40, 200);
  std::uniform_real_distribution<double> depth(1.0, 5.0);
  int checked = 0;
  for (int trial = 0; trial < 30; ++trial) {
    const int u = uu(rng), v = vv(rng);
    const double z = depth(rng);
    const Eigen::Vector3d p(z * (u - cx) / fx, z * (v - cy) / fy, z);
    const Eigen::Matrix<double, 1, 6> analytic = PhotometricJacobian(image, u, v, p, fx, fy);
    auto intensity = [&](const geometry::Vector6d& xi) {
      const Eigen::Vector3d q = SE3::Exp(xi) * p;
      return static_cast<double>(SampleBilinear(image, static_cast<float>(fx * q.x() / q.z() + cx),
                                                static_cast<float>(fy * q.y() / q.z() + cy)));
    };
    // Steps that move the projection by ~0.3 px, where bilinear interpolation of this smooth
    // image follows the central-difference gradient to within a few percent.
    const double h_t = 0.3 * z / fx, h_r = 0.3 / fx;
    const double scale = analytic.norm();
    geometry::Vector6d steps;
    steps << h_t, h_t, h_t, h_r, h_r, h_r;
    const Eigen::Matrix<double, 1, 6> numeric = test_support::NumericJacobian<1, 6>(
        [&](const geometry::Vector6d& d) { return Eigen::Matrix<double, 1, 1>(intensity(d)); },
        geometry::Vector6d::Zero(), steps);
    for (int k = 0; k < 6; ++k) {
      EXPECT_NEAR(numeric[k], analytic[k], 0.05 * scale + 0.05)
          << "trial " << trial << " col " << k;
    }
    ++checked;
  }
  EXPECT_EQ(checked, 30);
}

// --- Lost tracking and bad input ---

TEST(DenseVoTest, BlackFramesAreLostWithoutNaNAndTrackingRecovers) {
  const camera::RectifiedStereo rig = TestRig();
  const BoxRoom room;
  const std::vector<SE3> poses =
      Trajectory(7, Eigen::Vector3d(0.02, 0.0, 0.0), Eigen::Vector3d::Zero());
  auto vo = DenseVo::Create(rig, {}, poses[0]);
  ASSERT_TRUE(vo.ok());
  const cv::Mat black = cv::Mat::zeros(rig.height, rig.width, CV_8UC1);
  SE3 last_good = poses[0];
  for (size_t k = 0; k < poses.size(); ++k) {
    const bool dark = (k == 0 || k == 2 || k == 3);
    cv::Mat left, right;
    if (dark) {
      left = black;
      right = black;
    } else {
      room.RenderStereo(rig, poses[k], &left, &right);
    }
    auto result = vo->ProcessFrame(static_cast<int64_t>(k), left, right);
    ASSERT_TRUE(result.ok());
    EXPECT_TRUE(result->T_world_cam.Translation().allFinite()) << "frame " << k;
    EXPECT_TRUE(result->T_world_cam.Rotation().coeffs().allFinite()) << "frame " << k;
    EXPECT_TRUE(std::isfinite(result->rms_error));
    if (dark) {
      EXPECT_EQ(result->state, TrackingState::kLost) << "frame " << k;
      EXPECT_FALSE(result->lost_reason.empty());
      EXPECT_FALSE(result->new_keyframe);
      EXPECT_THAT(result->T_world_cam, test_support::IsNearPose(last_good, 1e-12, 1e-6))
          << "pose held, frame " << k;
    } else {
      EXPECT_EQ(result->state, TrackingState::kOk) << "frame " << k << ": " << result->lost_reason;
      EXPECT_TRUE(result->lost_reason.empty());
    }
    if (k == 0) {
      EXPECT_NE(result->lost_reason.find("contrast"), std::string::npos) << result->lost_reason;
    }
    if (k == 1 || k == 4) {
      EXPECT_TRUE(result->reference_reset) << "frame " << k;
    }
    if (k == 5 || k == 6) {
      // Tracking resumed: the relative motion is right again.
      EXPECT_FALSE(result->reference_reset);
      const MotionErrors e = Compare(result->T_prev_cur, poses[k - 1].Inverse() * poses[k]);
      EXPECT_LT(e.rotation_deg, 0.1) << "frame " << k;
      EXPECT_LT(e.translation_rel, 0.01) << "frame " << k;
    }
    last_good = result->T_world_cam;
  }
}

TEST(DenseVoTest, SuddenBlackFrameWhileTrackingIsLost) {
  const camera::RectifiedStereo rig = TestRig();
  const BoxRoom room;
  auto vo = DenseVo::Create(rig);
  ASSERT_TRUE(vo.ok());
  cv::Mat left, right;
  room.RenderStereo(rig, SE3(), &left, &right);
  ASSERT_EQ(vo->ProcessFrame(0, left, right)->state, TrackingState::kOk);
  const cv::Mat black = cv::Mat::zeros(rig.height, rig.width, CV_8UC1);
  auto result = vo->ProcessFrame(1, black, black);
  ASSERT_TRUE(result.ok());
  EXPECT_EQ(result->state, TrackingState::kLost);
  EXPECT_FALSE(result->lost_reason.empty());
  EXPECT_THAT(result->T_world_cam, test_support::IsNearPose(SE3(), 1e-12, 1e-6));
  EXPECT_THAT(result->T_prev_cur, test_support::IsNearPose(SE3(), 1e-12, 1e-6));
}

TEST(DenseVoTest, FrameWithoutStereoDepthCannotBeAKeyframe) {
  // Horizontal stripes: plenty of contrast and vertical gradient, but nothing for block
  // matching along the rows, so no depth.
  const camera::RectifiedStereo rig = TestRig();
  cv::Mat stripes(rig.height, rig.width, CV_8UC1);
  for (int v = 0; v < rig.height; ++v) stripes.row(v).setTo((v / 6) % 2 == 0 ? 40 : 200);
  auto vo = DenseVo::Create(rig);
  ASSERT_TRUE(vo.ok());
  auto result = vo->ProcessFrame(0, stripes, stripes);
  ASSERT_TRUE(result.ok());
  EXPECT_EQ(result->state, TrackingState::kLost);
  EXPECT_NE(result->lost_reason.find("pixels with depth and gradient"), std::string::npos)
      << result->lost_reason;
  EXPECT_FALSE(result->new_keyframe);
  EXPECT_THAT(result->T_world_cam, test_support::IsNearPose(SE3(), 1e-12, 1e-6));
}

TEST(DenseVoTest, BadImagesAreRejectedNamingTheField) {
  const camera::RectifiedStereo rig = TestRig();
  auto vo = DenseVo::Create(rig);
  ASSERT_TRUE(vo.ok());
  const cv::Mat good = cv::Mat::zeros(rig.height, rig.width, CV_8UC1);
  auto empty = vo->ProcessFrame(0, cv::Mat(), good);
  ASSERT_FALSE(empty.ok());
  EXPECT_NE(empty.status().ToString().find("left: empty"), std::string::npos);
  auto small = vo->ProcessFrame(0, good, cv::Mat::zeros(100, 100, CV_8UC1));
  ASSERT_FALSE(small.ok());
  EXPECT_NE(small.status().ToString().find("right: size 100x100"), std::string::npos);
  auto color = vo->ProcessFrame(0, cv::Mat::zeros(rig.height, rig.width, CV_8UC3), good);
  ASSERT_FALSE(color.ok());
  EXPECT_NE(color.status().ToString().find("left: expected an 8-bit"), std::string::npos);
  EXPECT_EQ(vo->frames_processed(), 0);
}

TEST(DenseVoTest, InvalidOptionsAndRigAreRejected) {
  std::string why;
  EXPECT_TRUE(DenseVoOptions().IsValid(&why)) << why;
  DenseVoOptions o;
  o.num_disparities = 40;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("num_disparities"), std::string::npos);
  o = DenseVoOptions();
  o.finest_level = 4;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("finest_level"), std::string::npos);
  // The consistency check's options.
  const std::vector<std::pair<const char*, std::function<void(DenseVoOptions*)>>> check_fields = {
      {"max_gyro_rotation_error_deg",
       [](DenseVoOptions* x) { x->max_gyro_rotation_error_deg = 0; }},
      {"max_acceleration_mps2", [](DenseVoOptions* x) { x->max_acceleration_mps2 = -1; }},
      {"motion_check_floor_m", [](DenseVoOptions* x) { x->motion_check_floor_m = 0; }},
      {"min_support_fraction", [](DenseVoOptions* x) { x->min_support_fraction = 1.5; }},
      {"max_rms_growth", [](DenseVoOptions* x) { x->max_rms_growth = 1.0; }},
      {"max_degraded_frames", [](DenseVoOptions* x) { x->max_degraded_frames = -1; }},
      {"rotation_prior_weight", [](DenseVoOptions* x) { x->rotation_prior_weight = std::nan(""); }},
  };
  for (const auto& [field, spoil] : check_fields) {
    o = DenseVoOptions();
    spoil(&o);
    EXPECT_FALSE(o.IsValid(&why)) << field;
    EXPECT_NE(why.find(field), std::string::npos) << why;
  }
  o = DenseVoOptions();
  o.block_size = 8;
  auto bad = DenseVo::Create(TestRig(), o);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().ToString().find("options.block_size"), std::string::npos);
  camera::RectifiedStereo rig = TestRig();
  rig.baseline = -1;
  auto bad_rig = DenseVo::Create(rig);
  ASSERT_FALSE(bad_rig.ok());
  EXPECT_NE(bad_rig.status().ToString().find("rig"), std::string::npos);
  rig = TestRig();
  rig.width = 64;
  rig.height = 64;
  o = DenseVoOptions();
  o.depth_level = 0;
  auto tiny = DenseVo::Create(rig, o);
  ASSERT_FALSE(tiny.ok());
  EXPECT_NE(tiny.status().ToString().find("num_levels"), std::string::npos);
}

TEST(DenseVoTest, ResetStartsAgainAtTheInitialPose) {
  const camera::RectifiedStereo rig = TestRig();
  const BoxRoom room;
  const SE3 T0(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY())),
               Eigen::Vector3d(1, 2, 3));
  auto vo = DenseVo::Create(rig, {}, T0);
  ASSERT_TRUE(vo.ok());
  cv::Mat left, right;
  room.RenderStereo(rig, SE3(), &left, &right);
  auto first = vo->ProcessFrame(0, left, right);
  ASSERT_TRUE(first.ok());
  EXPECT_THAT(first->T_world_cam, test_support::IsNearPose(T0, 1e-12, 1e-6));
  room.RenderStereo(rig, SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.03, 0, 0)), &left,
                    &right);
  auto second = vo->ProcessFrame(1, left, right);
  ASSERT_TRUE(second.ok());
  EXPECT_NEAR((second->T_world_cam.Translation() - T0.Translation()).norm(), 0.03, 3e-4);
  vo->Reset();
  EXPECT_EQ(vo->frames_processed(), 0);
  EXPECT_THAT(vo->T_world_cam(), test_support::IsNearPose(T0, 1e-12, 1e-6));
  auto again = vo->ProcessFrame(2, left, right);
  ASSERT_TRUE(again.ok());
  EXPECT_TRUE(again->reference_reset);
  EXPECT_EQ(again->frame_index, 0);
}

// End to end on the simulator: a short rectified room-easy sequence, KITTI-style relative error
// against ground truth. The bound is the paper's direct-method figure for its easy data set
// (1.5 %, Holzmann et al. 2015, Table 1); we measured ~0.1-0.3 % here.
TEST(DenseVoSimTest, RoomEasyRelativeErrorBelowPaper) {
  sim::ScenarioOptions scenario_options;
  scenario_options.preset = "room-easy";
  scenario_options.frames = 240;
  scenario_options.rectified = true;
  auto scenario = sim::Scenario::Create(scenario_options);
  ASSERT_TRUE(scenario.ok()) << scenario.status().ToString();
  const camera::StereoCalibration& calib = scenario->calibration();
  camera::RectifiedStereo rig;
  rig.width = calib.cam0.width;
  rig.height = calib.cam0.height;
  rig.fx = calib.cam0.fx;
  rig.fy = calib.cam0.fy;
  rig.cx = calib.cam0.cx;
  rig.cy = calib.cam0.cy;
  rig.baseline = calib.Baseline();
  auto T_world_cam = [&](int64_t k) {
    return scenario->StateAt(scenario->FrameTimeNs(k)).T_world_body * calib.T_body_cam0;
  };
  auto vo = DenseVo::Create(rig, {}, T_world_cam(0));
  ASSERT_TRUE(vo.ok()) << vo.status().ToString();
  std::vector<SE3> estimate, truth;
  int lost = 0;
  for (int64_t k = 0; k < scenario->num_frames(); ++k) {
    cv::Mat left, right;
    scenario->RenderStereo(k, &left, &right);
    auto result = vo->ProcessFrame(scenario->FrameTimeNs(k), left, right);
    ASSERT_TRUE(result.ok());
    lost += result->state == TrackingState::kLost ? 1 : 0;
    estimate.push_back(result->T_world_cam);
    truth.push_back(T_world_cam(k));
  }
  EXPECT_EQ(lost, 0);
  auto error = eval::ComputeRelativeError(estimate, truth, eval::RelativeErrorOptions());
  ASSERT_TRUE(error.ok()) << error.status().ToString();
  ASSERT_TRUE(error->average_pct.has_value()) << "path too short for a 2 m segment";
  EXPECT_LT(*error->average_pct, 1.5);
  auto end_point = eval::EndPointError(estimate, truth);
  ASSERT_TRUE(end_point.ok());
  EXPECT_LT(*end_point, 0.05 * eval::PathLength(truth));
}

}  // namespace
}  // namespace mav::localization
