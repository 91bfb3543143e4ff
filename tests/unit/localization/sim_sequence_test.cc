// End-to-end: the sparse VO on a short rectified room-easy sequence from the simulator, scored
// with the KITTI-style relative translational error (Geiger et al., CVPR 2012) as in the paper;
// the dense VO's per-frame consistency check on the same sequence, with the simulator's gyro.

#include <algorithm>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "mav/localization/rig_odometry.h"
#include "mav/localization/sparse_vo.h"
#include "mav/sim/scenario.h"
#include "tests/common/trajectory_error.h"

namespace mav::localization {
namespace {

using geometry::SE3;
using ::mav::test_support::RelativeError;  // tests/common/trajectory_error.h
using ::mav::test_support::RelativeTranslationError;

struct SimRun {
  std::vector<SE3> truth;  // T_world_cam (rectified left camera) from the simulator
  std::vector<cv::Mat> left, right;
  std::vector<int64_t> t_ns;
  camera::RectifiedStereo rig;
  camera::StereoCalibration calibration;
  SE3 T_world_body0;
  std::vector<dataset::ImuSample> imu;  // noisy, 200 Hz
};

const SimRun& GetRun() {
  static const SimRun* run = [] {
    auto* r = new SimRun;
    sim::ScenarioOptions options;
    options.preset = "room-easy";
    options.frames = 160;  // 8 s
    options.rectified = true;
    auto scenario = sim::Scenario::Create(options);
    MAV_CHECK(scenario.ok()) << scenario.status().ToString();
    const camera::StereoCalibration& calib = scenario->calibration();
    r->calibration = calib;
    r->T_world_body0 = scenario->StateAt(scenario->FrameTimeNs(0)).T_world_body;
    r->imu = scenario->ImuSamples();
    r->rig.width = calib.cam0.width;
    r->rig.height = calib.cam0.height;
    r->rig.fx = calib.cam0.fx;
    r->rig.fy = calib.cam0.fy;
    r->rig.cx = calib.cam0.cx;
    r->rig.cy = calib.cam0.cy;
    r->rig.baseline = calib.Baseline();
    for (int64_t k = 0; k < scenario->num_frames(); ++k) {
      cv::Mat l, rr;
      scenario->RenderStereo(k, &l, &rr);
      r->left.push_back(l);
      r->right.push_back(rr);
      r->t_ns.push_back(scenario->FrameTimeNs(k));
      r->truth.push_back(scenario->StateAt(scenario->FrameTimeNs(k)).T_world_body *
                         calib.T_body_cam0);
    }
    return r;
  }();
  return *run;
}

class SimSequenceTest : public ::testing::TestWithParam<SparseVoMode> {};

TEST_P(SimSequenceTest, RoomEasyRelativeError) {
  const SimRun& run = GetRun();
  SparseVoOptions options;
  options.mode = GetParam();
  auto vo = SparseVo::Create(run.rig, options);
  ASSERT_TRUE(vo.ok()) << vo.status().ToString();
  std::vector<SE3> est;
  std::vector<double> ms;
  int lost = 0, inliers = 0;
  for (size_t k = 0; k < run.left.size(); ++k) {
    auto r = vo->ProcessFrame(static_cast<int64_t>(k) * 50'000'000, run.left[k], run.right[k]);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    lost += r->state != TrackingState::kOk;
    inliers += r->num_inliers;
    ASSERT_TRUE(r->T_world_cam.Translation().allFinite());
    est.push_back(run.truth.front() * r->T_world_cam);
    if (k > 0) ms.push_back(r->timing.total_ms);
  }
  double path = 0;
  for (size_t k = 1; k < run.truth.size(); ++k) {
    path += (run.truth[k].Translation() - run.truth[k - 1].Translation()).norm();
  }
  const RelativeError rte = RelativeTranslationError(run.truth, est, {1, 2, 5});
  const double err = rte.percent;
  const int segments = rte.segments;
  const double end_err = (est.back().Translation() - run.truth.back().Translation()).norm();
  std::sort(ms.begin(), ms.end());
  std::printf(
      "[ sparse-%s ] room-easy %zu frames, path %.2f m: relative error %.2f %% (%d segments of "
      "1/2/5 m), end-point error %.3f m, lost %d, mean inliers %.0f, median %.1f ms/frame "
      "(wall clock)\n",
      SparseVoModeName(GetParam()), run.left.size(), path, err, segments, end_err, lost,
      static_cast<double>(inliers) / run.left.size(), ms[ms.size() / 2]);
  EXPECT_EQ(lost, 0);
  EXPECT_GT(segments, 0);
  // Measured 1.09 % (subpixel) and 4.39 % (pixel) when written; 1.39 % and 1.55 % since pixel
  // refinement and the joint motion + structure refinement. Bounds leave room for renderer
  // changes, not for regressions of the method.
  EXPECT_LT(err, GetParam() == SparseVoMode::kSubpixel ? 2.0 : 3.0);
}

INSTANTIATE_TEST_SUITE_P(Modes, SimSequenceTest,
                         ::testing::Values(SparseVoMode::kPixel, SparseVoMode::kSubpixel),
                         [](const ::testing::TestParamInfo<SparseVoMode>& info) {
                           return std::string(SparseVoModeName(info.param));
                         });

// --- Dense VO: the per-frame consistency check (dense_vo.h) ---

struct DenseRun {
  std::vector<ReportedState> states;
  std::vector<std::string> reasons;
  std::vector<double> gyro_error_deg, prediction_error_m;
  std::vector<SE3> poses;  // T_world_cam0
  int gyro_frames = 0;
};

// RigOdometry on the sequence's rectified rig, reporting the left camera in the world frame.
RigOdometryOptions SimRunOdometryOptions(Method method) {
  const SimRun& run = GetRun();
  RigOdometryOptions options;
  options.method = method;
  options.calibration = run.calibration;
  options.calibration_rectified = true;
  options.output_frame = OutputFrame::kCam0;
  options.T_world_body0 = run.T_world_body0;
  return options;
}

// The sequence through RigOdometry (the service's and mav-eval's path) with the simulator's noisy
// gyro; frames whose index is a key of `substitute` get the images of the mapped frame instead
// (a stale frame from a stuck driver or buffer), with their own stamp.
DenseRun RunDense(bool use_gyro, bool consistency_check,
                  const std::vector<std::pair<size_t, size_t>>& substitute = {},
                  int64_t gyro_gap_begin_ns = 0, int64_t gyro_gap_end_ns = 0) {
  const SimRun& run = GetRun();
  RigOdometryOptions options = SimRunOdometryOptions(Method::kDense);
  options.use_gyro = use_gyro;
  options.odometry.dense.consistency_check = consistency_check;
  auto odometry = RigOdometry::Create(options);
  MAV_CHECK(odometry.ok()) << odometry.status().ToString();
  DenseRun out;
  size_t next_imu = 0;
  for (size_t k = 0; k < run.left.size(); ++k) {
    for (; next_imu < run.imu.size() && run.imu[next_imu].t_ns <= run.t_ns[k]; ++next_imu) {
      const int64_t t = run.imu[next_imu].t_ns;
      if (t >= gyro_gap_begin_ns && t < gyro_gap_end_ns) continue;  // samples lost
      (*odometry)->AddGyro(t, run.imu[next_imu].gyro);
    }
    size_t image = k;
    for (const auto& [at, from] : substitute) {
      if (at == k) image = from;
    }
    auto pose = (*odometry)->Process(run.t_ns[k], run.left[image], run.right[image], true);
    MAV_CHECK(pose.ok()) << pose.status().ToString();
    out.states.push_back(pose->state);
    out.reasons.push_back(pose->lost_reason);
    out.gyro_error_deg.push_back(pose->gyro_rotation_error_deg);
    out.prediction_error_m.push_back(pose->prediction_error_m);
    out.poses.push_back(pose->T_world_out);
    out.gyro_frames += pose->gyro_used ? 1 : 0;
  }
  return out;
}

double PositionError(const DenseRun& r, size_t k) {
  return (r.poses[k].Translation() - GetRun().truth[k].Translation()).norm();
}

int Count(const DenseRun& r, ReportedState state) {
  return static_cast<int>(std::count(r.states.begin(), r.states.end(), state));
}

TEST(DenseConsistencyTest, CleanSequenceFlagsNoFrame) {
  for (bool gyro : {true, false}) {
    const DenseRun r = RunDense(gyro, true);
    const SimRun& run = GetRun();
    EXPECT_EQ(Count(r, ReportedState::kDegraded), 0) << "gyro " << gyro;
    // The check's margins on this sequence.
    std::printf("[ dense, gyro %d ] largest gyro disagreement %.3f deg, prediction error %.4f m\n",
                gyro, *std::max_element(r.gyro_error_deg.begin(), r.gyro_error_deg.end()),
                *std::max_element(r.prediction_error_m.begin(), r.prediction_error_m.end()));
    EXPECT_EQ(Count(r, ReportedState::kLost), 0) << "gyro " << gyro;
    EXPECT_EQ(r.gyro_frames, gyro ? static_cast<int>(run.left.size()) - 1 : 0);
    const double err = RelativeTranslationError(run.truth, r.poses, {1, 2, 5}).percent;
    std::printf("[ dense, gyro %d ] room-easy %zu frames: relative error %.2f %%\n", gyro,
                run.left.size(), err);
    EXPECT_LT(err, 2.0) << "gyro " << gyro;
  }
}

// Gyro samples missing for 0.5 s: the frames whose interval the samples no longer cover (gaps
// over 20 ms) run vision only, and nothing else changes.
TEST(DenseConsistencyTest, GyroGapFallsBackToVisionOnly) {
  const SimRun& run = GetRun();
  const DenseRun r = RunDense(true, true, {}, run.t_ns[50], run.t_ns[60]);
  // Frames 51..60 span intervals with missing samples (frame 60's starts at the gap's last
  // sample time); frame 61's interval starts at frame 60, where samples resume.
  EXPECT_EQ(r.gyro_frames, static_cast<int>(run.left.size()) - 1 - 10);
  EXPECT_EQ(Count(r, ReportedState::kDegraded), 0);
  EXPECT_EQ(Count(r, ReportedState::kLost), 0);
}

// A stale frame: the images of frame 76 arrive again as frame 80. Unchecked, the alignment
// succeeds and publishes the camera 4 frames (~8 cm) back; checked, the frame is DEGRADED, its
// pose is the prediction, and tracking goes on from the last measurement.
TEST(DenseConsistencyTest, StaleFrameIsDegradedInsteadOfAJump) {
  const std::vector<std::pair<size_t, size_t>> stale = {{80, 76}};
  const DenseRun unchecked = RunDense(true, false, stale);
  EXPECT_EQ(unchecked.states[80], ReportedState::kOk);
  EXPECT_GT(PositionError(unchecked, 80), 0.04) << "the provoked jump";
  for (bool gyro : {true, false}) {
    SCOPED_TRACE(gyro ? "with gyro" : "vision only");
    const DenseRun r = RunDense(gyro, true, stale);
    EXPECT_EQ(r.states[80], ReportedState::kDegraded);
    EXPECT_FALSE(r.reasons[80].empty());
    EXPECT_LT(PositionError(r, 80), 0.01) << r.reasons[80];
    EXPECT_EQ(Count(r, ReportedState::kDegraded), 1);
    EXPECT_EQ(Count(r, ReportedState::kLost), 0);
    // Back on the measurement right after, and no lasting damage.
    EXPECT_EQ(r.states[81], ReportedState::kOk);
    EXPECT_LT(PositionError(r, 81), PositionError(r, 79) + 0.005);
    EXPECT_LT(PositionError(r, r.poses.size() - 1), 0.05);
  }
}

// A replayed stream: from frame 80 on the images are those of 20 frames (~0.3 m) earlier, each
// consistent with the one before, so only the prediction from the last OK frame sees the jump.
// No replayed frame is published as a measurement: each is DEGRADED with the predicted pose
// until the tracker gives up (LOST, re-initialisation) after at most max_degraded_frames (5) of
// them, instead of predicting forever. (Whether the alignment itself fails first, LOST at once,
// depends on rounding: GCC -O2 gives five DEGRADED frames, clang -O1 under ASan a LOST at 81.)
TEST(DenseConsistencyTest, ReplayedStreamIsDegradedThenLost) {
  std::vector<std::pair<size_t, size_t>> replay;
  for (size_t k = 80; k < 90; ++k) replay.push_back({k, k - 20});
  for (bool gyro : {true, false}) {
    SCOPED_TRACE(gyro ? "with gyro" : "vision only");
    const DenseRun r = RunDense(gyro, true, replay);
    const size_t max_degraded = static_cast<size_t>(DenseVoOptions().max_degraded_frames);
    size_t lost_at = 0;
    for (size_t k = 80; k <= 80 + max_degraded; ++k) {
      if (r.states[k] == ReportedState::kLost) {
        lost_at = k;
        break;
      }
      EXPECT_EQ(r.states[k], ReportedState::kDegraded) << "frame " << k;
      EXPECT_LT(PositionError(r, k), 0.01) << "frame " << k;
    }
    ASSERT_NE(lost_at, 0u) << "never gave up";
    EXPECT_FALSE(r.reasons[lost_at].empty());
    EXPECT_LT(PositionError(r, lost_at), 0.03) << "the held pose, frame " << lost_at;
    if (lost_at == 80 + max_degraded) {
      EXPECT_NE(r.reasons[lost_at].find("max_degraded_frames"), std::string::npos)
          << r.reasons[lost_at];
    }
  }
}

}  // namespace
}  // namespace mav::localization

// --- Sparse VO with the gyro's rotation prior (SparseVoOptions::gyro_rotation_sigma_rad) ---

namespace mav::localization {
namespace {

struct SparseGyroRun {
  std::vector<SE3> poses;  // T_world_cam0
  int gyro_frames = 0, lost = 0;
  Eigen::Vector3d bias_at_end = Eigen::Vector3d::Zero();
  Eigen::Vector3d bias_after_reset = Eigen::Vector3d::Zero();
};

// The sequence through RigOdometry with the simulator's gyro plus a constant offset.
SparseGyroRun RunSparseGyro(double sigma_rad, const Eigen::Vector3d& offset) {
  const SimRun& run = GetRun();
  RigOdometryOptions options = SimRunOdometryOptions(Method::kSparseSubpixel);
  options.odometry.sparse.gyro_rotation_sigma_rad = sigma_rad;
  auto odometry = RigOdometry::Create(options);
  MAV_CHECK(odometry.ok()) << odometry.status().ToString();
  SparseGyroRun out;
  size_t next_imu = 0;
  for (size_t k = 0; k < run.left.size(); ++k) {
    for (; next_imu < run.imu.size() && run.imu[next_imu].t_ns <= run.t_ns[k]; ++next_imu) {
      (*odometry)->AddGyro(run.imu[next_imu].t_ns, run.imu[next_imu].gyro + offset);
    }
    auto pose = (*odometry)->Process(run.t_ns[k], run.left[k], run.right[k], true);
    MAV_CHECK(pose.ok()) << pose.status().ToString();
    out.poses.push_back(pose->T_world_out);
    out.gyro_frames += pose->gyro_used ? 1 : 0;
    out.lost += pose->state == ReportedState::kLost;
  }
  out.bias_at_end = (*odometry)->gyro_bias();
  (*odometry)->Reset(run.T_world_body0);
  out.bias_after_reset = (*odometry)->gyro_bias();
  return out;
}

TEST(SparseGyroPriorTest, LearnsTheGyroOffsetKeepsItOverAResetAndTracksAsWell) {
  const SimRun& run = GetRun();
  const Eigen::Vector3d offset(-0.02, 0.008, -0.01);  // the contest IMU's gyro offset, rad/s
  const SparseGyroRun vision = RunSparseGyro(0, offset);
  const SparseGyroRun aided = RunSparseGyro(1e-4, offset);
  const double vision_err = RelativeTranslationError(run.truth, vision.poses, {1, 2, 5}).percent;
  const double aided_err = RelativeTranslationError(run.truth, aided.poses, {1, 2, 5}).percent;
  double vision_rot = 0, aided_rot = 0;
  for (size_t k = 0; k < run.truth.size(); ++k) {
    vision_rot = std::max(
        vision_rot, geometry::AngleBetween(vision.poses[k].Rotation(), run.truth[k].Rotation()));
    aided_rot = std::max(
        aided_rot, geometry::AngleBetween(aided.poses[k].Rotation(), run.truth[k].Rotation()));
  }
  std::printf(
      "[ sparse-subpixel ] vision only: %.2f %%, worst rotation %.3f deg; gyro-aided: %.2f %%, "
      "worst rotation %.3f deg, learnt offset error %.2e rad/s\n",
      vision_err, vision_rot * 180 / M_PI, aided_err, aided_rot * 180 / M_PI,
      (aided.bias_at_end - offset).norm());
  EXPECT_EQ(vision.gyro_frames, 0);  // the paper's VO ignores the gyro
  EXPECT_EQ(aided.gyro_frames, static_cast<int>(run.left.size()) - 1);
  EXPECT_EQ(aided.lost, 0);
  // The bias is learnt against what the matches alone say (not against the prior-led estimate,
  // which would leave most of the offset unlearnt), and a re-seed keeps it.
  EXPECT_LT((aided.bias_at_end - offset).norm(), 2e-3);
  EXPECT_EQ(aided.bias_after_reset, aided.bias_at_end);
  EXPECT_LT(aided_err, vision_err * 1.1 + 0.05);
  EXPECT_LT(aided_rot, vision_rot * 1.1 + 1e-3);
}

}  // namespace
}  // namespace mav::localization
