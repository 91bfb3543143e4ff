#include "mav/localization/sparse_vo.h"

#include <cmath>
#include <functional>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "synthetic_stereo.h"
#include "tests/common/trajectory_error.h"

namespace mav::localization {
namespace {

using geometry::SE3;
using geometry::Vector6d;

constexpr double kRadToDeg = 180.0 / M_PI;
constexpr int64_t kFrameNs = 50'000'000;

struct Pair {
  std::vector<uint8_t> left, right;
};

cv::Mat AsMat(std::vector<uint8_t>& data, const camera::RectifiedStereo& rig) {
  return cv::Mat(rig.height, rig.width, CV_8UC1, data.data());
}

struct FrameError {
  double rotation_deg = 0;
  double translation_m = 0;
  double motion_m = 0;  // true translation of the frame
};

// Runs the VO over the trajectory and compares every frame's relative motion with the truth.
std::vector<FrameError> RunSequence(const std::vector<SE3>& T_world_cam,
                                    const SparseVoOptions& options,
                                    std::vector<VoFrameResult>* results = nullptr) {
  static const synthetic::SyntheticRoom room;
  const camera::RectifiedStereo rig = synthetic::EurocLikeRig();
  auto vo = SparseVo::Create(rig, options);
  EXPECT_TRUE(vo.ok()) << vo.status().ToString();
  std::vector<FrameError> errors;
  for (size_t k = 0; k < T_world_cam.size(); ++k) {
    Pair p;
    room.Render(rig, T_world_cam[k], &p.left, &p.right);
    auto r = vo->ProcessFrame(static_cast<int64_t>(k) * kFrameNs, AsMat(p.left, rig),
                              AsMat(p.right, rig));
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    if (results) results->push_back(*r);
    EXPECT_EQ(r->state, TrackingState::kOk) << "frame " << k << ": " << r->lost_reason;
    if (k == 0) continue;
    const SE3 truth = T_world_cam[k - 1].Inverse() * T_world_cam[k];
    FrameError e;
    e.rotation_deg = geometry::AngleBetween(truth.Rotation(), r->T_prev_cur.Rotation()) * kRadToDeg;
    e.translation_m = (truth.Translation() - r->T_prev_cur.Translation()).norm();
    e.motion_m = truth.Translation().norm();
    errors.push_back(e);
  }
  return errors;
}

std::vector<SE3> Trajectory(int frames, const std::function<SE3(int)>& pose) {
  std::vector<SE3> t;
  t.reserve(frames);
  for (int k = 0; k < frames; ++k) t.push_back(pose(k));
  return t;
}

SparseVoOptions Options(SparseVoMode mode) {
  SparseVoOptions o;
  o.mode = mode;
  return o;
}

struct ImageMotionCase {
  const char* name;
  SparseVoMode mode;
  std::function<SE3(int)> pose;
  double max_rotation_deg;
  double max_translation_rel;  // of the frame's motion, or absolute metres when it is 0
};

class ImageMotionTest : public ::testing::TestWithParam<ImageMotionCase> {};

TEST_P(ImageMotionTest, RecoversPerFrameMotionFromRenderedImages) {
  const ImageMotionCase& c = GetParam();
  std::vector<VoFrameResult> results;
  // The per-frame estimator: every pair becomes the reference (with the default keyframe option
  // a frame's T_prev_cur is the difference of two estimates against the same keyframe; see
  // KeyframeReferenceReducesDriftOfSlowMotion for that mode).
  SparseVoOptions options = Options(c.mode);
  options.keep_reference_while_small = false;
  const std::vector<FrameError> errors = RunSequence(Trajectory(6, c.pose), options, &results);
  double worst_rot = 0, worst_trans = 0;
  for (const FrameError& e : errors) {
    worst_rot = std::max(worst_rot, e.rotation_deg);
    worst_trans =
        std::max(worst_trans, e.motion_m > 0 ? e.translation_m / e.motion_m : e.translation_m);
  }
  for (size_t k = 1; k < results.size(); ++k) {
    EXPECT_GT(results[k].num_inliers, 50) << "frame " << k;
    EXPECT_GE(results[k].num_matches, results[k].num_inliers);
  }
  RecordProperty("worst_rotation_deg", std::to_string(worst_rot));
  RecordProperty("worst_translation", std::to_string(worst_trans));
  std::printf(
      "[ %s ] worst rotation error %.4f deg, worst translation error %.4f %s, inliers %d/%d\n",
      c.name, worst_rot, c.max_translation_rel > 0 ? worst_trans * 100 : worst_trans * 1000,
      "% / mm", results.back().num_inliers, results.back().num_matches);
  EXPECT_LT(worst_rot, c.max_rotation_deg);
  EXPECT_LT(worst_trans, c.max_translation_rel);
}

SE3 Lateral(int k) { return SE3(Eigen::Quaterniond::Identity(), {0.05 * k, 0, 0}); }
SE3 Yaw(int k) {
  return SE3(geometry::ExpSO3(Eigen::Vector3d(0, 1.5 * k * M_PI / 180, 0)),
             Eigen::Vector3d::Zero());
}
SE3 Forward(int k) { return SE3(Eigen::Quaterniond::Identity(), {0, 0, 0.1 * k}); }

INSTANTIATE_TEST_SUITE_P(
    Motions, ImageMotionTest,
    ::testing::Values(
        // Rendered (noise-free) images: the bounds include the matching error, unlike the
        // projected-point tests in stereo_motion_test.cc, which must be exact.
        ImageMotionCase{"TranslationSubpixel", SparseVoMode::kSubpixel, Lateral, 0.05, 0.02},
        ImageMotionCase{"RotationSubpixel", SparseVoMode::kSubpixel, Yaw, 0.05, 0.002},
        ImageMotionCase{"ForwardSubpixel", SparseVoMode::kSubpixel, Forward, 0.05, 0.02},
        ImageMotionCase{"TranslationPixel", SparseVoMode::kPixel, Lateral, 0.1, 0.03},
        ImageMotionCase{"RotationPixel", SparseVoMode::kPixel, Yaw, 0.1, 0.004},
        ImageMotionCase{"ForwardPixel", SparseVoMode::kPixel, Forward, 0.1, 0.03}),
    [](const ::testing::TestParamInfo<ImageMotionCase>& info) { return info.param.name; });

// Slow motion (1 cm and 0.1 deg per frame): matching every frame against the kept reference pair
// must not accumulate the per-frame error of integer-pixel matches, so the end pose is more
// accurate than frame-to-frame odometry, and the poses stay chained by T_prev_cur.
TEST(SparseVoKeyframeTest, KeyframeReferenceReducesDriftOfSlowMotion) {
  static const synthetic::SyntheticRoom room;
  const camera::RectifiedStereo rig = synthetic::EurocLikeRig();
  auto pose = [](int k) {
    return SE3(geometry::ExpSO3(Eigen::Vector3d(0, 0.1 * k * M_PI / 180, 0)),
               Eigen::Vector3d(0.01 * k, 0.002 * k, 0.005 * k));
  };
  constexpr int kN = 25;
  std::vector<Pair> pairs(kN);
  for (int k = 0; k < kN; ++k) {
    room.Render(rig, pose(k), &pairs[k].left, &pairs[k].right, /*noise_sigma=*/1.0, k + 1);
  }
  double end_error[2] = {0, 0};
  for (int keep = 0; keep < 2; ++keep) {
    SparseVoOptions options = Options(SparseVoMode::kPixel);
    options.keep_reference_while_small = keep == 1;
    auto vo = SparseVo::Create(rig, options);
    ASSERT_TRUE(vo.ok());
    SE3 previous;
    for (int k = 0; k < kN; ++k) {
      auto r =
          vo->ProcessFrame(k * kFrameNs, AsMat(pairs[k].left, rig), AsMat(pairs[k].right, rig));
      ASSERT_TRUE(r.ok());
      ASSERT_EQ(r->state, TrackingState::kOk) << "frame " << k << ": " << r->lost_reason;
      EXPECT_TRUE((previous * r->T_prev_cur).IsApprox(r->T_world_cam, 1e-9)) << "frame " << k;
      previous = r->T_world_cam;
    }
    end_error[keep] =
        ((pose(0).Inverse() * pose(kN - 1)).Translation() - previous.Translation()).norm();
  }
  std::printf(
      "[ keyframe ] end-point error after %.2f m: frame-to-frame %.2f mm, keyframe %.2f mm\n",
      (pose(0).Inverse() * pose(kN - 1)).Translation().norm(), end_error[0] * 1e3,
      end_error[1] * 1e3);
  EXPECT_LT(end_error[1], end_error[0]);
  EXPECT_LT(end_error[1], 0.005);
}

// A smooth 6-DoF trajectory through the room (about 1.9 m in 40 frames).
SE3 Wander(int k) {
  const double a = k * 0.08;
  return SE3(
      geometry::ExpSO3(Eigen::Vector3d(0.05 * std::sin(a), 0.4 * std::sin(0.7 * a), 0.02 * a)),
      Eigen::Vector3d(0.8 * std::sin(a), 0.2 * std::sin(1.3 * a), 1.0 * std::sin(0.5 * a)));
}

class SequenceTest : public ::testing::TestWithParam<SparseVoMode> {};

TEST_P(SequenceTest, RelativeErrorOnAShortSequenceWithNoise) {
  static const synthetic::SyntheticRoom room;
  const camera::RectifiedStereo rig = synthetic::EurocLikeRig();
  SparseVoOptions options;
  options.mode = GetParam();
  auto vo = SparseVo::Create(rig, options);
  ASSERT_TRUE(vo.ok());
  std::vector<SE3> truth, est;
  for (int k = 0; k < 40; ++k) {
    truth.push_back(Wander(k));
    Pair p;
    room.Render(rig, truth.back(), &p.left, &p.right, /*noise_sigma=*/2.0, /*noise_seed=*/k + 1);
    auto r = vo->ProcessFrame(k * kFrameNs, AsMat(p.left, rig), AsMat(p.right, rig));
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(r->state, TrackingState::kOk) << r->lost_reason;
    EXPECT_TRUE(r->T_world_cam.Translation().allFinite());
    // The world frame is the first camera.
    est.push_back(truth.front() * r->T_world_cam);
  }
  const test_support::RelativeError rte =
      test_support::RelativeTranslationError(truth, est, {0.25, 0.5, 1.0});
  ASSERT_GT(rte.segments, 0);
  const double err = rte.percent;
  std::printf("[ %s ] relative translational error %.3f %%\n", SparseVoModeName(GetParam()), err);
  // Measured 0.54 % (subpixel) and 2.27 % (pixel) when written.
  EXPECT_LT(err, GetParam() == SparseVoMode::kSubpixel ? 1.0 : 3.0);
}

INSTANTIATE_TEST_SUITE_P(Modes, SequenceTest,
                         ::testing::Values(SparseVoMode::kPixel, SparseVoMode::kSubpixel),
                         [](const ::testing::TestParamInfo<SparseVoMode>& info) {
                           return std::string(SparseVoModeName(info.param));
                         });

bool PoseIsFinite(const SE3& T) {
  return T.Translation().allFinite() && T.Rotation().coeffs().allFinite();
}

TEST(SparseVoTest, BlackImagesAreLostWithAReasonAndTrackingRecovers) {
  static const synthetic::SyntheticRoom room;
  const camera::RectifiedStereo rig = synthetic::EurocLikeRig();
  auto vo = SparseVo::Create(rig);
  ASSERT_TRUE(vo.ok());
  auto process = [&](int k, bool black) {
    Pair p;
    room.Render(rig, Lateral(k), &p.left, &p.right);
    if (black) {
      std::fill(p.left.begin(), p.left.end(), 0);
      std::fill(p.right.begin(), p.right.end(), 0);
    }
    auto r = vo->ProcessFrame(k * kFrameNs, AsMat(p.left, rig), AsMat(p.right, rig));
    EXPECT_TRUE(r.ok());
    EXPECT_TRUE(PoseIsFinite(r->T_world_cam));
    EXPECT_TRUE(PoseIsFinite(r->T_prev_cur));
    return *r;
  };
  VoFrameResult r = process(0, false);
  EXPECT_EQ(r.state, TrackingState::kOk);
  EXPECT_TRUE(r.reference_reset);
  r = process(1, false);
  EXPECT_EQ(r.state, TrackingState::kOk);
  EXPECT_FALSE(r.reference_reset);
  const SE3 before = r.T_world_cam;
  EXPECT_NEAR(before.Translation().x(), 0.05, 0.002);

  r = process(2, true);  // black pair
  EXPECT_EQ(r.state, TrackingState::kLost);
  EXPECT_NE(r.lost_reason.find("too few features"), std::string::npos) << r.lost_reason;
  EXPECT_TRUE(r.T_world_cam.IsApprox(before, 1e-12));
  EXPECT_TRUE(r.T_prev_cur.IsApprox(SE3(), 1e-12));

  r = process(3, false);  // re-initialises: pose held
  EXPECT_EQ(r.state, TrackingState::kOk) << r.lost_reason;
  EXPECT_TRUE(r.reference_reset);
  EXPECT_TRUE(r.T_world_cam.IsApprox(before, 1e-12));

  r = process(4, false);  // tracking again: one frame of motion on top of the held pose
  EXPECT_EQ(r.state, TrackingState::kOk) << r.lost_reason;
  EXPECT_FALSE(r.reference_reset);
  EXPECT_NEAR(r.T_prev_cur.Translation().x(), 0.05, 0.002);
  EXPECT_NEAR(r.T_world_cam.Translation().x(), 0.10, 0.004);
}

TEST(SparseVoTest, UnrelatedPairIsLostAndPoseStaysFinite) {
  static const synthetic::SyntheticRoom room;
  static const synthetic::SyntheticRoom other(99);
  const camera::RectifiedStereo rig = synthetic::EurocLikeRig();
  auto vo = SparseVo::Create(rig);
  ASSERT_TRUE(vo.ok());
  Pair a, b;
  room.Render(rig, SE3(), &a.left, &a.right);
  other.Render(rig, SE3(), &b.left, &b.right);
  ASSERT_TRUE(vo->ProcessFrame(0, AsMat(a.left, rig), AsMat(a.right, rig)).ok());
  auto r = vo->ProcessFrame(kFrameNs, AsMat(b.left, rig), AsMat(b.right, rig));
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->state, TrackingState::kLost);
  EXPECT_FALSE(r->lost_reason.empty());
  EXPECT_TRUE(PoseIsFinite(r->T_world_cam));
  EXPECT_TRUE(r->T_world_cam.IsApprox(SE3(), 1e-12));
}

TEST(SparseVoTest, BadInputIsInvalidArgumentNamingTheImage) {
  const camera::RectifiedStereo rig = synthetic::EurocLikeRig();
  auto vo = SparseVo::Create(rig);
  ASSERT_TRUE(vo.ok());
  const cv::Mat good(rig.height, rig.width, CV_8UC1, cv::Scalar(0));
  auto r = vo->ProcessFrame(0, cv::Mat(), good);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("left: empty"), std::string::npos) << r.status().message();
  r = vo->ProcessFrame(0, good, cv::Mat(rig.height, rig.width, CV_8UC3));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("right: expected an 8-bit"), std::string::npos);
  r = vo->ProcessFrame(0, good, cv::Mat(240, 376, CV_8UC1, cv::Scalar(0)));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("right: size 376x240"), std::string::npos);
  EXPECT_EQ(vo->frames_processed(), 0);  // bad input leaves the tracker unchanged
}

TEST(SparseVoTest, CreateRejectsInvalidRigAndOptionsNamingTheField) {
  camera::RectifiedStereo rig = synthetic::EurocLikeRig();
  SparseVoOptions options;
  options.matcher.bucket_max_matches = 0;
  auto vo = SparseVo::Create(rig, options);
  ASSERT_FALSE(vo.ok());
  EXPECT_NE(vo.status().message().find("options.matcher.bucket_max_matches"), std::string::npos)
      << vo.status().message();
  options = {};
  options.features.nms_radius = 0;
  vo = SparseVo::Create(rig, options);
  ASSERT_FALSE(vo.ok());
  EXPECT_NE(vo.status().message().find("options.features.nms_radius"), std::string::npos);
  rig.baseline = 0;
  vo = SparseVo::Create(rig);
  ASSERT_FALSE(vo.ok());
  EXPECT_NE(vo.status().message().find("rig: baseline"), std::string::npos);
}

TEST(SparseVoTest, DeterministicAcrossRuns) {
  std::vector<VoFrameResult> a, b;
  const std::vector<SE3> traj = Trajectory(4, Wander);
  RunSequence(traj, Options(SparseVoMode::kSubpixel), &a);
  RunSequence(traj, Options(SparseVoMode::kSubpixel), &b);
  ASSERT_EQ(a.size(), b.size());
  for (size_t k = 0; k < a.size(); ++k) {
    EXPECT_TRUE(a[k].T_world_cam.IsApprox(b[k].T_world_cam, 0)) << k;
    EXPECT_EQ(a[k].num_inliers, b[k].num_inliers);
  }
}

}  // namespace
}  // namespace mav::localization
