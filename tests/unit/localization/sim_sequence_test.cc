// End-to-end: the sparse VO on a short rectified room-easy sequence from the simulator, scored
// with the KITTI-style relative translational error (Geiger et al., CVPR 2012) as in the paper.

#include <algorithm>
#include <cstdio>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "mav/localization/sparse_vo.h"
#include "mav/sim/scenario.h"

namespace mav::localization {
namespace {

using geometry::SE3;

// Mean relative translational error (%) over all start frames (step 1) and the given segment
// lengths; a segment ends at the first frame whose ground-truth path length passes start +
// length, and both segments are aligned by their first frame. Lengths that never fit are skipped.
double RelativeTranslationErrorPercent(const std::vector<SE3>& truth, const std::vector<SE3>& est,
                                       const std::vector<double>& lengths, int* segments) {
  std::vector<double> dist(truth.size(), 0.0);
  for (size_t k = 1; k < truth.size(); ++k) {
    dist[k] = dist[k - 1] + (truth[k].Translation() - truth[k - 1].Translation()).norm();
  }
  double sum = 0;
  int count = 0;
  for (size_t s = 0; s < truth.size(); ++s) {
    for (double len : lengths) {
      size_t e = s;
      while (e < truth.size() && dist[e] < dist[s] + len) ++e;
      if (e == truth.size()) continue;
      const SE3 gt = truth[s].Inverse() * truth[e];
      const SE3 es = est[s].Inverse() * est[e];
      sum += (gt.Translation() - es.Translation()).norm() / len;
      ++count;
    }
  }
  *segments = count;
  return count ? 100.0 * sum / count : 0.0;
}

struct SimRun {
  std::vector<SE3> truth;  // T_world_cam (rectified left camera) from the simulator
  std::vector<cv::Mat> left, right;
  camera::RectifiedStereo rig;
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
  int segments = 0;
  const double err = RelativeTranslationErrorPercent(run.truth, est, {1, 2, 5}, &segments);
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

}  // namespace
}  // namespace mav::localization
