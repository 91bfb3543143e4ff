#include "mav/mapping/sparse_points.h"

#include <cmath>
#include <map>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "tests/common/stereo_rig.h"

namespace mav::mapping {
namespace {

using ::mav::test_support::CenteredEurocLikeRig;  // tests/common/stereo_rig.h

// Camera at `position` looking along world +x (camera x = world -y, camera y = world -z).
geometry::SE3 PoseLookingAlongX(const Eigen::Vector3d& position) {
  Eigen::Matrix3d R_world_cam;
  R_world_cam.col(0) = -Eigen::Vector3d::UnitY();
  R_world_cam.col(1) = -Eigen::Vector3d::UnitZ();
  R_world_cam.col(2) = Eigen::Vector3d::UnitX();
  return geometry::SE3(R_world_cam, position);
}

localization::ImageView View(const cv::Mat& m) {
  return {m.data, m.cols, m.rows, static_cast<int>(m.step[0])};
}

// Exact observation of a world point from a camera (nullopt if outside the image or range).
std::optional<StereoObservation> Observe(const camera::RectifiedStereo& rig,
                                         const geometry::SE3& T_world_cam,
                                         const Eigen::Vector3d& p_world, int feature_class,
                                         const localization::Descriptor& descriptor) {
  const Eigen::Vector3d p = T_world_cam.Inverse() * p_world;
  if (p.z() < 0.3 || p.z() > 6.0) return std::nullopt;
  StereoObservation o;
  o.u_left = static_cast<float>(rig.fx * p.x() / p.z() + rig.cx);
  o.v_left = static_cast<float>(rig.fy * p.y() / p.z() + rig.cy);
  if (o.u_left < 0 || o.v_left < 0 || o.u_left >= rig.width || o.v_left >= rig.height) {
    return std::nullopt;
  }
  o.disparity = static_cast<float>(rig.fx * rig.baseline / p.z());
  o.feature_class = feature_class;
  o.descriptor = descriptor;
  o.stereo_cost = 100;
  return o;
}

struct SyntheticPoints {
  std::vector<Eigen::Vector3d> p_world;
  std::vector<localization::Descriptor> descriptors;
  std::vector<int> classes;
};

// Points on a wall at world x = 4, spread over y in [-2, 2], z in [0.5, 2.5], each with a random
// descriptor and class.
SyntheticPoints MakeWallPoints(int n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> y(-2.0, 2.0), z(0.5, 2.5);
  std::uniform_int_distribution<int> byte(0, 255), cls(0, 3);
  SyntheticPoints s;
  for (int i = 0; i < n; ++i) {
    s.p_world.emplace_back(4.0, y(rng), z(rng));
    localization::Descriptor d;
    for (auto& b : d.bytes) b = static_cast<uint8_t>(byte(rng));
    s.descriptors.push_back(d);
    s.classes.push_back(cls(rng));
  }
  return s;
}

TEST(SparsePointsOptionsTest, NamesTheInvalidField) {
  std::string why;
  EXPECT_TRUE(SparsePointsOptions().IsValid(&why)) << why;
  SparsePointsOptions o;
  o.max_depth_m = 0.1;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("max_depth_m"), std::string::npos) << why;
  o = SparsePointsOptions();
  o.features.nms_radius = -1;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_EQ(why.rfind("features.", 0), 0u) << why;
  o = SparsePointsOptions();
  o.merge_radius_px = std::nan("");
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("merge_radius_px"), std::string::npos) << why;
  o = SparsePointsOptions();
  o.bucket_cols = 0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("bucket_cols"), std::string::npos) << why;

  auto cloud = SparsePointCloud::Create(CenteredEurocLikeRig(), o);
  ASSERT_FALSE(cloud.ok());
  EXPECT_NE(cloud.status().message().find("options.bucket_cols"), std::string::npos);
  camera::RectifiedStereo bad = CenteredEurocLikeRig();
  bad.baseline = -1;
  cloud = SparsePointCloud::Create(bad);
  ASSERT_FALSE(cloud.ok());
  EXPECT_EQ(cloud.status().message().rfind("rig: ", 0), 0u) << cloud.status().message();
}

// Known 3D points observed exactly from three keyframes: every point is triangulated where it is
// and carries exactly the keyframes that saw it.
TEST(SparsePointsTest, MergesExactObservationsWithRightVisibility) {
  const camera::RectifiedStereo rig = CenteredEurocLikeRig();
  const SyntheticPoints wall = MakeWallPoints(80, 3);
  SparsePointsOptions options;
  options.target_points_per_keyframe = 1000;  // keep everything: this test is about merging
  auto cloud = SparsePointCloud::Create(rig, options);
  ASSERT_TRUE(cloud.ok()) << cloud.status().ToString();
  const std::vector<geometry::SE3> poses = {PoseLookingAlongX({0.0, 0.0, 1.5}),
                                            PoseLookingAlongX({0.3, 0.1, 1.5}),
                                            PoseLookingAlongX({0.6, 0.2, 1.45})};
  // Keyframe 1 sees only the first half of the points, keyframes 0 and 2 see all.
  std::map<int, std::set<int>> expected_views;  // point -> keyframes
  for (int k = 0; k < 3; ++k) {
    std::vector<StereoObservation> obs;
    for (int i = 0; i < static_cast<int>(wall.p_world.size()); ++i) {
      if (k == 1 && i >= 40) continue;
      auto o = Observe(rig, poses[k], wall.p_world[i], wall.classes[i], wall.descriptors[i]);
      if (!o) continue;
      obs.push_back(*o);
      expected_views[i].insert(k);
    }
    auto id = cloud->AddKeyframeObservations(obs, poses[k]);
    ASSERT_TRUE(id.ok()) << id.status().ToString();
    EXPECT_EQ(*id, k);
  }
  const std::vector<MapPoint> points = cloud->Points();
  ASSERT_EQ(points.size(), expected_views.size());
  // Match each map point to its source by position.
  int checked = 0;
  for (const MapPoint& p : points) {
    int nearest = -1;
    double best = 1e9;
    for (int i = 0; i < static_cast<int>(wall.p_world.size()); ++i) {
      const double d = (wall.p_world[i] - p.p_world).norm();
      if (d < best) {
        best = d;
        nearest = i;
      }
    }
    EXPECT_LT(best, 1e-4);  // float pixel positions: sub-millimetre
    const std::set<int> views(p.keyframes.begin(), p.keyframes.end());
    EXPECT_EQ(views, expected_views[nearest]) << "point " << nearest;
    EXPECT_TRUE(std::is_sorted(p.keyframes.begin(), p.keyframes.end()));
    ++checked;
  }
  EXPECT_EQ(checked, 80);
  ASSERT_EQ(cloud->keyframes().size(), 3u);
  EXPECT_TRUE(cloud->keyframes()[2].center_world.isApprox(poses[2].Translation()));
  EXPECT_EQ(cloud->stats().keyframes[1].reobserved, 40);
  EXPECT_EQ(cloud->stats().keyframes[2].reobserved, 80);
  EXPECT_EQ(cloud->stats().keyframes[2].new_points, 0);
}

// Noisy disparities: the merged position is the inverse-variance mean, within the stereo noise.
TEST(SparsePointsTest, NoisyTriangulationWithinBound) {
  const camera::RectifiedStereo rig = CenteredEurocLikeRig();
  const SyntheticPoints wall = MakeWallPoints(60, 5);
  SparsePointsOptions options;
  options.target_points_per_keyframe = 1000;
  options.merge_relative_depth_tolerance = 0.1;
  auto cloud = SparsePointCloud::Create(rig, options);
  ASSERT_TRUE(cloud.ok());
  std::mt19937_64 rng(11);
  std::normal_distribution<double> noise(0.0, 0.1);  // px
  for (int k = 0; k < 5; ++k) {
    const geometry::SE3 pose = PoseLookingAlongX({0.1 * k, 0.05 * k, 1.5});
    std::vector<StereoObservation> obs;
    for (size_t i = 0; i < wall.p_world.size(); ++i) {
      auto o = Observe(rig, pose, wall.p_world[i], wall.classes[i], wall.descriptors[i]);
      if (!o) continue;
      o->disparity += static_cast<float>(noise(rng));
      o->u_left += static_cast<float>(noise(rng));
      obs.push_back(*o);
    }
    ASSERT_TRUE(cloud->AddKeyframeObservations(obs, pose).ok());
  }
  // At ~4 m, 0.1 px of disparity noise is sigma_Z = Z^2 * 0.1 / (fx b) ~ 3.2 cm per view.
  const std::vector<MapPoint> points = cloud->Points();
  EXPECT_EQ(points.size(), 60u);
  for (const MapPoint& p : points) {
    double best = 1e9;
    for (const auto& q : wall.p_world) best = std::min(best, (q - p.p_world).norm());
    EXPECT_LT(best, 0.08);
    EXPECT_EQ(p.keyframes.size(), 5u);
  }
}

TEST(SparsePointsTest, GatesRejectWrongDescriptorDepthAndOldKeyframes) {
  const camera::RectifiedStereo rig = CenteredEurocLikeRig();
  const SyntheticPoints wall = MakeWallPoints(20, 7);
  SparsePointsOptions options;
  options.target_points_per_keyframe = 1000;
  options.merge_window_keyframes = 2;
  auto cloud = SparsePointCloud::Create(rig, options);
  ASSERT_TRUE(cloud.ok());
  const geometry::SE3 pose = PoseLookingAlongX({0, 0, 1.5});
  auto observe_all = [&](auto modify) {
    std::vector<StereoObservation> obs;
    for (size_t i = 0; i < wall.p_world.size(); ++i) {
      auto o = Observe(rig, pose, wall.p_world[i], wall.classes[i], wall.descriptors[i]);
      if (!o) continue;
      modify(&*o);
      obs.push_back(*o);
    }
    return obs;
  };
  ASSERT_TRUE(cloud->AddKeyframeObservations(observe_all([](StereoObservation*) {}), pose).ok());
  const int64_t n = cloud->num_points();
  ASSERT_EQ(n, 20);
  // Inverted descriptors: far beyond the SAD gate -> all new points.
  ASSERT_TRUE(cloud
                  ->AddKeyframeObservations(observe_all([](StereoObservation* o) {
                                              for (auto& b : o->descriptor.bytes) b = 255 - b;
                                            }),
                                            pose)
                  .ok());
  EXPECT_EQ(cloud->num_points(), 2 * n);
  // Depth 20% off (beyond the 5% tolerance) -> new points.
  ASSERT_TRUE(cloud
                  ->AddKeyframeObservations(
                      observe_all([](StereoObservation* o) { o->disparity *= 1.25f; }), pose)
                  .ok());
  EXPECT_EQ(cloud->num_points(), 3 * n);
  // The original points were last seen 3 keyframes ago (window 2): not candidates any more. The
  // inverted-descriptor points (2 keyframes ago) are, but fail the descriptor gate.
  ASSERT_TRUE(cloud->AddKeyframeObservations(observe_all([](StereoObservation*) {}), pose).ok());
  EXPECT_EQ(cloud->num_points(), 4 * n);
  EXPECT_EQ(cloud->stats().keyframes.back().reobserved, 0);
}

// Step 6: a single-view point whose disparity is grossly wrong (the aperture problem) is not
// reproduced by the neighbouring keyframe's stereo matches and is left out of Points(); correct
// single-view points supported by the other keyframe's matches, and points the other keyframe
// cannot see (unchecked), are kept.
TEST(SparsePointsTest, VerificationRejectsSingleViewOutliers) {
  const camera::RectifiedStereo rig = CenteredEurocLikeRig();
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> y(-1.5, 1.5), z(0.5, 2.5);
  std::uniform_int_distribution<int> byte(0, 255), cls(0, 3);
  auto random_descriptor = [&] {
    localization::Descriptor d;
    for (auto& b : d.bytes) b = static_cast<uint8_t>(byte(rng));
    return d;
  };
  SyntheticPoints good, bad;
  for (int i = 0; i < 40; ++i) {
    good.p_world.emplace_back(4.0, y(rng), z(rng));
    good.descriptors.push_back(random_descriptor());
    good.classes.push_back(cls(rng));
  }
  for (int i = 0; i < 10; ++i) {
    bad.p_world.emplace_back(4.0, y(rng), z(rng));
    bad.descriptors.push_back(random_descriptor());
    bad.classes.push_back(cls(rng));
  }
  const Eigen::Vector3d unseen(4.0, -3.1, 1.5);  // in keyframe 0's view only
  const std::vector<geometry::SE3> poses = {PoseLookingAlongX({0.0, 0.0, 1.5}),
                                            PoseLookingAlongX({0.3, 0.3, 1.5})};
  for (const bool verify : {true, false}) {
    SCOPED_TRACE(verify ? "verify" : "no verification");
    SparsePointsOptions options;
    options.target_points_per_keyframe = 1000;
    options.merge_window_keyframes = 0;  // every observation is a new single-view point
    options.verify_window_keyframes = verify ? 2 : 0;
    auto cloud = SparsePointCloud::Create(rig, options);
    ASSERT_TRUE(cloud.ok());
    for (int k = 0; k < 2; ++k) {
      std::vector<StereoObservation> obs;
      for (size_t i = 0; i < good.p_world.size(); ++i) {
        auto o = Observe(rig, poses[k], good.p_world[i], good.classes[i], good.descriptors[i]);
        ASSERT_TRUE(o.has_value());
        obs.push_back(*o);
      }
      if (k == 0) {
        for (size_t i = 0; i < bad.p_world.size(); ++i) {
          auto o = Observe(rig, poses[0], bad.p_world[i], bad.classes[i], bad.descriptors[i]);
          ASSERT_TRUE(o.has_value());
          o->disparity += 6.0f;  // ~12 px true disparity: floats at ~2.7 m instead of 4 m
          obs.push_back(*o);
        }
        auto o = Observe(rig, poses[0], unseen, 0, random_descriptor());
        ASSERT_TRUE(o.has_value());
        obs.push_back(*o);
      } else {
        ASSERT_FALSE(Observe(rig, poses[1], unseen, 0, random_descriptor()).has_value());
      }
      ASSERT_TRUE(cloud->AddKeyframeObservations(obs, poses[k]).ok());
    }
    EXPECT_EQ(cloud->num_points(), 40 + 40 + 10 + 1);
    const std::vector<MapPoint> points = cloud->Points();
    EXPECT_EQ(cloud->num_accepted_points(), static_cast<int64_t>(points.size()));
    int near_good = 0, floating = 0, unseen_kept = 0;
    for (const MapPoint& p : points) {
      EXPECT_EQ(p.keyframes.size(), 1u);
      double best = 1e9;
      for (const auto& q : good.p_world) best = std::min(best, (q - p.p_world).norm());
      near_good += best < 1e-3 ? 1 : 0;
      floating += p.p_world.x() < 3.5 ? 1 : 0;
      unseen_kept += (p.p_world - unseen).norm() < 1e-3 ? 1 : 0;
    }
    EXPECT_EQ(near_good, 80);
    EXPECT_EQ(unseen_kept, 1);
    EXPECT_EQ(floating, verify ? 0 : 10);
    EXPECT_EQ(points.size(), verify ? 81u : 91u);
    EXPECT_EQ(cloud->stats().keyframes[1].supported, verify ? 40 : 0);
    // The lines of sight of the rejected points are kept for the free space.
    const std::vector<MapPoint> all = cloud->AllPoints();
    EXPECT_EQ(all.size(), 91u);
    int all_floating = 0;
    for (const MapPoint& p : all) all_floating += p.p_world.x() < 3.5 ? 1 : 0;
    EXPECT_EQ(all_floating, 10);
  }
  // With keep_unchecked_points = false only points that another keyframe could check and
  // supported remain: the point outside keyframe 1's view goes too.
  SparsePointsOptions strict;
  strict.target_points_per_keyframe = 1000;
  strict.merge_window_keyframes = 0;
  strict.keep_unchecked_points = false;
  auto cloud = SparsePointCloud::Create(rig, strict);
  ASSERT_TRUE(cloud.ok());
  for (int k = 0; k < 2; ++k) {
    std::vector<StereoObservation> obs;
    for (size_t i = 0; i < good.p_world.size(); ++i) {
      obs.push_back(*Observe(rig, poses[k], good.p_world[i], good.classes[i], good.descriptors[i]));
    }
    if (k == 0) obs.push_back(*Observe(rig, poses[0], unseen, 0, random_descriptor()));
    ASSERT_TRUE(cloud->AddKeyframeObservations(obs, poses[k]).ok());
  }
  EXPECT_EQ(cloud->num_points(), 81);
  EXPECT_EQ(cloud->Points().size(), 80u);
  // A map preference can ask for the unchecked points per call.
  EXPECT_EQ(cloud->Points(true).size(), 81u);
  EXPECT_EQ(cloud->Points(false).size(), 80u);
}

// The scene of the sight-line tests: a wall of 60 points that two keyframes 0.42 m apart both
// see whole, with 10 points selected per keyframe and no merging, so that most stereo matches
// stay unselected.
struct TwoViewWall {
  const camera::RectifiedStereo rig = CenteredEurocLikeRig();
  const SyntheticPoints good = MakeWallPoints(60, 5);
  const geometry::SE3 poses[2] = {PoseLookingAlongX({0.0, 0.0, 1.5}),
                                  PoseLookingAlongX({0.3, 0.3, 1.5})};

  static SparsePointsOptions Options() {
    SparsePointsOptions options;
    options.target_points_per_keyframe = 10;
    options.merge_window_keyframes = 0;
    return options;
  }
  // Keyframe k's observation of every wall point (a test failure for one it does not see).
  std::vector<StereoObservation> Observations(int k) const {
    std::vector<StereoObservation> obs;
    for (size_t i = 0; i < good.p_world.size(); ++i) {
      const auto o = Observe(rig, poses[k], good.p_world[i], good.classes[i], good.descriptors[i]);
      EXPECT_TRUE(o.has_value()) << "point " << i << " outside keyframe " << k;
      if (o.has_value()) obs.push_back(*o);
    }
    return obs;
  }
};

// The stereo matches that were not selected but that a neighbouring keyframe reproduced become
// extra lines of sight (SightPoints), never the wrong-disparity ones.
TEST(SparsePointsTest, SightPointsAddVerifiedUnselectedMatches) {
  const TwoViewWall scene;
  const SyntheticPoints& good = scene.good;
  auto cloud = SparsePointCloud::Create(scene.rig, TwoViewWall::Options());
  ASSERT_TRUE(cloud.ok());
  for (int k = 0; k < 2; ++k) {
    std::vector<StereoObservation> obs = scene.Observations(k);
    ASSERT_EQ(obs.size(), good.p_world.size());
    if (k == 1) {
      for (size_t i = 0; i < 5; ++i) obs[i].disparity += 6.0f;  // wrong depth: reproduces nothing
    }
    ASSERT_TRUE(cloud->AddKeyframeObservations(obs, scene.poses[k]).ok());
  }
  EXPECT_EQ(cloud->num_points(), 20);
  const std::vector<MapPoint> all = cloud->AllPoints();
  const std::vector<MapPoint> sight = cloud->SightPoints();
  ASSERT_GE(sight.size(), all.size());
  // Keyframe 0: its 50 unselected matches except those of the 5 points keyframe 1 got wrong
  // (45-50); keyframe 1: its 55 reproduced matches minus the 10 selected (preferred) = 45.
  // Every extra lies on a true point and has one keyframe.
  const size_t extras = sight.size() - all.size();
  EXPECT_GE(extras, 90u);
  EXPECT_LE(extras, 95u);
  for (size_t i = all.size(); i < sight.size(); ++i) {
    ASSERT_EQ(sight[i].keyframes.size(), 1u);
    double best = 1e9;
    for (const auto& q : good.p_world) best = std::min(best, (q - sight[i].p_world).norm());
    EXPECT_LT(best, 1e-3) << "extra line of sight " << i << " is not on a true point";
  }
  cloud->Reset();
  EXPECT_TRUE(cloud->SightPoints().empty());
}

// The extra lines of sight are capped (memory bounded by configuration); the ones beyond are
// counted, the points themselves are unaffected.
TEST(SparsePointsTest, SightLinesAreCappedAndTheDropsCounted) {
  const TwoViewWall scene;
  SparsePointsOptions options = TwoViewWall::Options();
  options.max_sight_lines = 30;
  auto cloud = SparsePointCloud::Create(scene.rig, options);
  ASSERT_TRUE(cloud.ok());
  for (int k = 0; k < 2; ++k) {
    ASSERT_TRUE(cloud->AddKeyframeObservations(scene.Observations(k), scene.poses[k]).ok());
  }
  EXPECT_EQ(cloud->num_points(), 20);
  EXPECT_EQ(cloud->SightPoints().size() - cloud->AllPoints().size(), 30u);
  EXPECT_GE(cloud->stats().sight_lines_dropped, 60);
  options.max_sight_lines = -1;
  std::string why;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_EQ(why.rfind("max_sight_lines", 0), 0u) << why;
}

// The thin-structure budget: six points of a "pipe" 2 m in front of a wall at 4 m. With a budget of
// 10 spread points per keyframe few of them are taken; the foreground budget takes every verified
// one in the second keyframe (the first has nothing to verify against).
TEST(SparsePointsTest, ForegroundBudgetTakesThinStructuresInFrontOfAWall) {
  const camera::RectifiedStereo rig = CenteredEurocLikeRig();
  // A regular wall (a random one would depend on the compiler's argument evaluation order):
  // 20 x 10 points over y in [-2, 2], z in [0.5, 2.5] at x = 4, ~25 px apart in the images.
  SyntheticPoints scene;
  std::mt19937_64 rng(11);
  std::uniform_int_distribution<int> byte(0, 255);
  for (int row = 0; row < 10; ++row) {
    for (int col = 0; col < 20; ++col) {
      scene.p_world.emplace_back(4.0, -1.9 + 0.2 * col, 0.6 + 0.2 * row + 0.03);
      localization::Descriptor d;
      for (auto& b : d.bytes) b = static_cast<uint8_t>(byte(rng));
      scene.descriptors.push_back(d);
      scene.classes.push_back((row + col) % 4);
    }
  }
  std::vector<Eigen::Vector3d> pipe;
  for (int i = 0; i < 6; ++i) {
    pipe.emplace_back(2.0, -0.5 + 0.2 * i, 1.5);
    scene.p_world.push_back(pipe.back());
    localization::Descriptor d;
    for (size_t b = 0; b < d.bytes.size(); ++b) d.bytes[b] = static_cast<uint8_t>(31 * i + 7 * b);
    scene.descriptors.push_back(d);
    scene.classes.push_back(i % 4);
  }
  auto pipe_points_in_cloud = [&](int foreground) {
    SparsePointsOptions options;
    options.target_points_per_keyframe = 10;
    options.foreground_points_per_keyframe = foreground;
    auto cloud = SparsePointCloud::Create(rig, options);
    EXPECT_TRUE(cloud.ok());
    for (int k = 0; k < 2; ++k) {
      const geometry::SE3 pose = PoseLookingAlongX({0.2 * k, 0.05 * k, 1.5});
      std::vector<StereoObservation> obs;
      for (size_t i = 0; i < scene.p_world.size(); ++i) {
        if (auto o = Observe(rig, pose, scene.p_world[i], scene.classes[i], scene.descriptors[i])) {
          obs.push_back(*o);
        }
      }
      EXPECT_TRUE(cloud->AddKeyframeObservations(obs, pose).ok());
    }
    EXPECT_EQ(cloud->stats().keyframes[0].foreground, 0);
    EXPECT_LE(cloud->stats().keyframes[1].foreground, foreground);
    int found = 0;
    for (const Eigen::Vector3d& q : pipe) {
      for (const MapPoint& p : cloud->AllPoints()) {
        if ((p.p_world - q).norm() < 1e-3) {
          ++found;
          break;
        }
      }
    }
    return found;
  };
  const int without = pipe_points_in_cloud(0);
  const int with = pipe_points_in_cloud(8);
  std::printf("pipe points in the cloud: %d without the foreground budget, %d with it\n", without,
              with);
  EXPECT_LT(without, 6);
  EXPECT_EQ(with, 6);
  SparsePointsOptions o;
  o.foreground_depth_drop = 1.0;
  std::string why;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_EQ(why.rfind("foreground_depth_drop", 0), 0u) << why;
}

TEST(SparsePointsOptionsTest, NamesTheInvalidVerificationField) {
  std::string why;
  SparsePointsOptions o;
  o.verify_disparity_tolerance_px = 0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("verify_disparity_tolerance_px"), std::string::npos) << why;
  o = SparsePointsOptions();
  o.verify_window_keyframes = -1;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("verify_window_keyframes"), std::string::npos) << why;
}

// The per-keyframe budget bounds the selection; with apply_all_reobservations every
// re-observation of an existing point is applied on top of it.
TEST(SparsePointsTest, BudgetAndApplyAllReobservations) {
  const camera::RectifiedStereo rig = CenteredEurocLikeRig();
  const SyntheticPoints wall = MakeWallPoints(80, 9);
  for (const bool apply_all : {false, true}) {
    SparsePointsOptions options;
    options.target_points_per_keyframe = 30;
    options.apply_all_reobservations = apply_all;
    auto cloud = SparsePointCloud::Create(rig, options);
    ASSERT_TRUE(cloud.ok());
    for (int k = 0; k < 2; ++k) {
      const geometry::SE3 pose = PoseLookingAlongX({0.2 * k, 0.0, 1.5});
      std::vector<StereoObservation> obs;
      for (size_t i = 0; i < wall.p_world.size(); ++i) {
        if (auto o = Observe(rig, pose, wall.p_world[i], wall.classes[i], wall.descriptors[i])) {
          obs.push_back(*o);
        }
      }
      ASSERT_EQ(obs.size(), 80u);
      ASSERT_TRUE(cloud->AddKeyframeObservations(obs, pose).ok());
    }
    const SparseKeyframeStats& first = cloud->stats().keyframes[0];
    const SparseKeyframeStats& second = cloud->stats().keyframes[1];
    EXPECT_EQ(first.selected, 30);
    EXPECT_EQ(first.new_points, 30);
    EXPECT_EQ(second.reobservable, 30);  // exactly the 30 points of the first keyframe
    if (apply_all) {
      EXPECT_EQ(second.reobserved, 30);
      EXPECT_EQ(second.selected, 30 + second.new_points);
    } else {
      EXPECT_EQ(second.selected, 30);
      EXPECT_LE(second.reobserved, 30);
      EXPECT_EQ(second.reobserved + second.new_points, 30);
    }
    EXPECT_EQ(cloud->num_points(), 30 + second.new_points);
  }
}

TEST(SparsePointsTest, BadInputNamesTheFieldAndLeavesTheCloudUnchanged) {
  const camera::RectifiedStereo rig = CenteredEurocLikeRig();
  auto cloud = SparsePointCloud::Create(rig);
  ASSERT_TRUE(cloud.ok());
  StereoObservation o;
  o.u_left = 100;
  o.v_left = 100;
  o.disparity = -3;
  auto r = cloud->AddKeyframeObservations({o, o}, geometry::SE3());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("observations[0].disparity"), std::string::npos)
      << r.status().message();
  o.disparity = 10;
  o.feature_class = 7;
  r = cloud->AddKeyframeObservations({o}, geometry::SE3());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("feature_class"), std::string::npos);
  geometry::SE3 nan_pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(std::nan(""), 0, 0));
  o.feature_class = 0;
  r = cloud->AddKeyframeObservations({o}, nan_pose);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("T_world_cam"), std::string::npos);

  cv::Mat small(100, 100, CV_8UC1, cv::Scalar(0));
  cv::Mat good(rig.height, rig.width, CV_8UC1, cv::Scalar(0));
  r = cloud->AddKeyframe(View(small), View(good), geometry::SE3());
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message().rfind("left: size", 0), 0u) << r.status().message();
  r = cloud->AddKeyframe(View(good), localization::ImageView{}, geometry::SE3());
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message().rfind("right: empty", 0), 0u) << r.status().message();
  EXPECT_EQ(cloud->num_points(), 0);
  EXPECT_TRUE(cloud->keyframes().empty());
  EXPECT_TRUE(cloud->stats().keyframes.empty());
}

// A fronto-parallel textured plane at integer disparity d (right(u) = left(u + d)): every stereo
// match triangulates at depth fx b / d. Moving the camera sideways by s pixels' worth re-observes
// the same features.
class PlaneImagesTest : public ::testing::Test {
 protected:
  static constexpr int kDisparity = 20;  // Z = 49.5 / 20 = 2.475 m
  static constexpr int kShift = 12;      // px between the two keyframes

  void SetUp() override {
    const camera::RectifiedStereo rig = CenteredEurocLikeRig();
    wide_.create(rig.height, rig.width + kDisparity + kShift);
    cv::RNG rng(21);
    cv::Mat noise(wide_.size(), CV_8UC1);
    rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
    cv::GaussianBlur(noise, wide_, cv::Size(7, 7), 1.6);
    cv::normalize(wide_, wide_, 0, 255, cv::NORM_MINMAX);
  }
  // Left/right images of a camera moved `shift` px to the right.
  void Pair(int shift, cv::Mat* left, cv::Mat* right) const {
    const camera::RectifiedStereo rig = CenteredEurocLikeRig();
    *left = wide_(cv::Rect(shift, 0, rig.width, rig.height)).clone();
    *right = wide_(cv::Rect(shift + kDisparity, 0, rig.width, rig.height)).clone();
  }
  cv::Mat1b wide_;
};

TEST_F(PlaneImagesTest, TriangulatesAboutOneHundredSpreadPointsAtTheRightDepth) {
  const camera::RectifiedStereo rig = CenteredEurocLikeRig();
  auto cloud = SparsePointCloud::Create(rig);
  ASSERT_TRUE(cloud.ok());
  cv::Mat left, right;
  Pair(0, &left, &right);
  SparseKeyframeStats stats;
  auto matches = cloud->MatchStereo(View(left), View(right), &stats);
  ASSERT_TRUE(matches.ok()) << matches.status().ToString();
  EXPECT_GT(stats.left_features, 300);
  EXPECT_GT(stats.stereo_matches, 200);
  int exact = 0;
  for (const auto& m : *matches) exact += std::abs(m.disparity - kDisparity) < 0.25 ? 1 : 0;
  EXPECT_GT(exact, 0.9 * matches->size());

  const geometry::SE3 pose = PoseLookingAlongX({1.0, 2.0, 1.5});
  auto id = cloud->AddKeyframe(View(left), View(right), pose);
  ASSERT_TRUE(id.ok()) << id.status().ToString();
  const std::vector<MapPoint> points = cloud->Points();
  EXPECT_EQ(points.size(), 100u);
  const double plane_x = 1.0 + rig.fx * rig.baseline / kDisparity;
  std::set<int> buckets;
  int on_plane = 0;
  for (const MapPoint& p : points) {
    on_plane += std::abs(p.p_world.x() - plane_x) < 0.03 ? 1 : 0;  // 0.25 px of disparity
    const Eigen::Vector3d pc = pose.Inverse() * p.p_world;
    const int u = static_cast<int>(rig.fx * pc.x() / pc.z() + rig.cx);
    const int v = static_cast<int>(rig.fy * pc.y() / pc.z() + rig.cy);
    buckets.insert((v * 6 / rig.height) * 10 + u * 10 / rig.width);
  }
  EXPECT_GT(on_plane, 95);
  EXPECT_GE(buckets.size(), 50u);  // spread over most of the 60 buckets
  EXPECT_GT(cloud->stats().keyframes[0].extraction_ms, 0.0);
}

TEST_F(PlaneImagesTest, SecondKeyframeReobservesTheSamePoints) {
  const camera::RectifiedStereo rig = CenteredEurocLikeRig();
  auto cloud = SparsePointCloud::Create(rig);
  ASSERT_TRUE(cloud.ok());
  const Eigen::Vector3d c0(1.0, 2.0, 1.5);
  const double depth = rig.fx * rig.baseline / kDisparity;
  // Camera x is world -y: moving the camera right by kShift px at the plane's depth.
  const Eigen::Vector3d c1 = c0 - Eigen::Vector3d::UnitY() * (kShift * depth / rig.fx);
  cv::Mat left, right;
  Pair(0, &left, &right);
  ASSERT_TRUE(cloud->AddKeyframe(View(left), View(right), PoseLookingAlongX(c0)).ok());
  Pair(kShift, &left, &right);
  ASSERT_TRUE(cloud->AddKeyframe(View(left), View(right), PoseLookingAlongX(c1)).ok());
  const SparseKeyframeStats& s = cloud->stats().keyframes[1];
  EXPECT_EQ(s.selected, 100);
  EXPECT_GT(s.reobserved, 60);  // most of the first keyframe's points are still in view
  int two_views = 0;
  for (const MapPoint& p : cloud->Points()) {
    if (p.keyframes == std::vector<int>{0, 1}) ++two_views;
  }
  EXPECT_EQ(two_views, s.reobserved);
  EXPECT_EQ(cloud->num_points(), 200 - s.reobserved);
}

}  // namespace
}  // namespace mav::mapping
