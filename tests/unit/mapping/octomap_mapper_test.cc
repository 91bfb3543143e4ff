#include "mav/mapping/octomap_mapper.h"

#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <octomap/OcTree.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "tests/common/stereo_rig.h"

namespace mav::mapping {
namespace {

using ::mav::test_support::CenteredEurocLikeRig;  // tests/common/stereo_rig.h

// A fronto-parallel plane with a seeded random texture, seen at integer disparity d: the right
// image is the left one shifted by d pixels, right(u) = left(u + d), so every left pixel has
// disparity exactly d and depth Z = fx * b / d.
void PlanePair(const camera::RectifiedStereo& s, int disparity, uint64_t seed, cv::Mat* left,
               cv::Mat* right) {
  cv::Mat wide(s.height, s.width + disparity, CV_8UC1);
  cv::RNG rng(seed);
  rng.fill(wide, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(wide, wide, cv::Size(3, 3), 0.8);
  *left = wide(cv::Rect(0, 0, s.width, s.height)).clone();
  *right = wide(cv::Rect(disparity, 0, s.width, s.height)).clone();
}

// The camera at (1, 2, 1.5) looking along world +x (camera x = world -y, camera y = world -z).
geometry::SE3 CameraPose() {
  Eigen::Matrix3d R_world_cam;
  R_world_cam.col(0) = -Eigen::Vector3d::UnitY();
  R_world_cam.col(1) = -Eigen::Vector3d::UnitZ();
  R_world_cam.col(2) = Eigen::Vector3d::UnitX();
  return geometry::SE3(R_world_cam, Eigen::Vector3d(1.0, 2.0, 1.5));
}

constexpr int kDisparity = 20;
// Z = 450 * 0.11 / 20 = 2.475 m: the plane lies at world x = 3.475, the middle of the voxel
// layer [3.45, 3.50).
constexpr double kPlaneX = 1.0 + 450.0 * 0.11 / kDisparity;

Eigen::AlignedBox3d Box(double x0, double y0, double z0, double x1, double y1, double z1) {
  return Eigen::AlignedBox3d(Eigen::Vector3d(x0, y0, z0), Eigen::Vector3d(x1, y1, z1));
}

// One 5 cm voxel around p.
Eigen::AlignedBox3d VoxelAt(const Eigen::Vector3d& p) {
  const Eigen::Vector3d lo = (p / 0.05).array().floor().matrix() * 0.05;
  return Eigen::AlignedBox3d(lo, lo + Eigen::Vector3d::Constant(0.05));
}

class OctomapMapperPlaneTest : public ::testing::Test {
 protected:
  void SetUp() override {
    auto mapper = OctomapMapper::Create(options_);
    ASSERT_TRUE(mapper.ok()) << mapper.status().ToString();
    mapper_ = std::make_unique<OctomapMapper>(std::move(*mapper));
    PlanePair(CenteredEurocLikeRig(), kDisparity, 7, &left_, &right_);
    const Status status =
        mapper_->InsertKeyframe(left_, right_, CenteredEurocLikeRig(), CameraPose());
    ASSERT_TRUE(status.ok()) << status.ToString();
    mapper_->Finish();
  }

  BoxOccupancy Classify(const Eigen::AlignedBox3d& box) {
    auto r = mapper_->Classify(box);
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    return r.ok() ? *r : BoxOccupancy::kFree;
  }

  OctomapMapperOptions options_;
  std::unique_ptr<OctomapMapper> mapper_;
  cv::Mat left_, right_;
};

TEST_F(OctomapMapperPlaneTest, StatsCountTheKeyframe) {
  const OctomapMapperStats& stats = mapper_->stats();
  ASSERT_EQ(mapper_->num_keyframes(), 1);
  ASSERT_EQ(stats.keyframes.size(), 1u);
  // Stride 4 on 752 x 480 gives 188 x 120 samples; only the left band without a full disparity
  // search range (u < 96) and matching borders are invalid.
  EXPECT_GT(stats.keyframes[0].points, 188 * 120 * 6 / 10);
  EXPECT_LE(stats.keyframes[0].points, 188 * 120);
  EXPECT_GT(stats.keyframes[0].disparity_ms, 0.0);
  EXPECT_GT(stats.keyframes[0].insertion_ms, 0.0);
  EXPECT_NEAR(
      stats.TotalMs(),
      stats.TotalDisparityMs() + stats.TotalPointsMs() + stats.TotalInsertionMs() + stats.finish_ms,
      1e-9);
  EXPECT_GT(mapper_->NumLeaves(), 0);
}

TEST_F(OctomapMapperPlaneTest, PlaneVoxelsAreOccupied) {
  // Sample the plane on a 5 cm lattice inside the valid field of view (camera x in
  // [-0.8, 1.5] m, y in [-1, 1] m at Z = 2.475 m).
  int occupied = 0, total = 0;
  for (double y = 0.5; y <= 2.8; y += 0.05) {
    for (double z = 0.5; z <= 2.5; z += 0.05) {
      ++total;
      occupied += Classify(VoxelAt(Eigen::Vector3d(kPlaneX, y + 0.025, z + 0.025))) ==
                  BoxOccupancy::kOccupied;
    }
  }
  EXPECT_GE(occupied, total * 97 / 100) << occupied << " of " << total;
}

TEST_F(OctomapMapperPlaneTest, SpaceBetweenCameraAndPlaneIsFree) {
  // Voxels along rays through the image centre region, from 0.8 m to 0.2 m before the plane.
  int free = 0, total = 0;
  for (double x = 1.8; x <= kPlaneX - 0.2; x += 0.1) {
    for (double y = 1.7; y <= 2.3; y += 0.1) {
      for (double z = 1.3; z <= 1.7; z += 0.1) {
        ++total;
        free += Classify(VoxelAt(Eigen::Vector3d(x, y, z))) == BoxOccupancy::kFree;
      }
    }
  }
  EXPECT_EQ(free, total);
  EXPECT_EQ(Classify(Box(1.8, 1.6, 1.2, 3.3, 2.4, 1.8)), BoxOccupancy::kFree);
}

TEST_F(OctomapMapperPlaneTest, SpaceBehindThePlaneIsUnknown) {
  EXPECT_EQ(Classify(Box(3.6, 1.6, 1.2, 4.5, 2.4, 1.8)), BoxOccupancy::kUnknown);
  EXPECT_EQ(Classify(VoxelAt(Eigen::Vector3d(kPlaneX + 0.1, 2.0, 1.5))), BoxOccupancy::kUnknown);
  // Behind the camera, and far outside the field of view.
  EXPECT_EQ(Classify(Box(0.0, 1.8, 1.3, 0.9, 2.2, 1.7)), BoxOccupancy::kUnknown);
  EXPECT_EQ(Classify(Box(2.0, -5.0, 1.3, 2.5, -4.5, 1.7)), BoxOccupancy::kUnknown);
}

TEST_F(OctomapMapperPlaneTest, MixedBoxesFollowThePriorityOccupiedUnknownFree) {
  // Free space plus the plane: occupied.
  EXPECT_EQ(Classify(Box(3.0, 1.8, 1.3, 3.5, 2.2, 1.7)), BoxOccupancy::kOccupied);
  // Free space plus the plane plus unknown space behind it: occupied.
  EXPECT_EQ(Classify(Box(3.0, 1.8, 1.3, 4.0, 2.2, 1.7)), BoxOccupancy::kOccupied);
  // Free space plus unknown space behind the camera: unknown.
  EXPECT_EQ(Classify(Box(0.5, 1.9, 1.4, 2.0, 2.1, 1.6)), BoxOccupancy::kUnknown);
  // A box whose face touches the plane's voxel layer without entering it stays free.
  EXPECT_EQ(Classify(Box(3.0, 1.8, 1.3, 3.45, 2.2, 1.7)), BoxOccupancy::kFree);
  // A flat box lying inside the plane's layer.
  EXPECT_EQ(Classify(Box(3.47, 1.8, 1.3, 3.47, 2.2, 1.7)), BoxOccupancy::kOccupied);
}

TEST_F(OctomapMapperPlaneTest, GridAtTheMapResolutionMatchesClassify) {
  GridGeometry geometry;
  geometry.origin = Eigen::Vector3d(0.5, 0.0, 0.0);
  geometry.resolution = 0.05;
  geometry.size = Eigen::Vector3i(100, 80, 60);  // x 0.5..5.5, y 0..4, z 0..3
  auto grid = mapper_->ToGrid(geometry);
  ASSERT_TRUE(grid.ok()) << grid.status().ToString();
  ASSERT_TRUE(grid->geometry().SameAs(geometry));
  ASSERT_EQ(grid->num_voxels(), 100 * 80 * 60);

  // Every occupied voxel lies in the plane's layer (index (3.475 - 0.5) / 0.05 = 59) or a
  // neighbour; free voxels lie in front of it; behind it everything is unknown.
  const int plane_i = 59;
  int64_t occupied = 0, occupied_in_layer = 0;
  for (int k = 0; k < 60; ++k) {
    for (int j = 0; j < 80; ++j) {
      for (int i = 0; i < 100; ++i) {
        const VoxelState s = grid->at(Eigen::Vector3i(i, j, k));
        if (s == VoxelState::kOccupied) {
          ++occupied;
          occupied_in_layer += i == plane_i;
          EXPECT_LE(std::abs(i - plane_i), 1) << i << " " << j << " " << k;
        }
        if (i > plane_i + 1) {
          EXPECT_EQ(s, VoxelState::kUnknown) << i << " " << j << " " << k;
        }
      }
    }
  }
  EXPECT_GT(occupied_in_layer, occupied * 95 / 100);
  EXPECT_GT(grid->Count(VoxelState::kFree), 10000);
  EXPECT_EQ(grid->StateAt(Eigen::Vector3d(kPlaneX, 2.0, 1.5)), VoxelState::kOccupied);
  EXPECT_EQ(grid->StateAt(Eigen::Vector3d(2.5, 2.0, 1.5)), VoxelState::kFree);

  // The grid applies the Classify rule per voxel (every 3rd voxel checked).
  for (int k = 0; k < 60; k += 3) {
    for (int j = 0; j < 80; j += 3) {
      for (int i = 0; i < 100; i += 3) {
        const Eigen::Vector3d lo = geometry.origin + Eigen::Vector3d(i, j, k) * 0.05;
        const BoxOccupancy c =
            Classify(Eigen::AlignedBox3d(lo, lo + Eigen::Vector3d::Constant(0.05)));
        const VoxelState expected = c == BoxOccupancy::kOccupied ? VoxelState::kOccupied
                                    : c == BoxOccupancy::kFree   ? VoxelState::kFree
                                                                 : VoxelState::kUnknown;
        ASSERT_EQ(grid->at(Eigen::Vector3i(i, j, k)), expected) << i << " " << j << " " << k;
      }
    }
  }
}

TEST_F(OctomapMapperPlaneTest, MisalignedCoarserGridIsConservative) {
  GridGeometry geometry;
  geometry.origin = Eigen::Vector3d(0.513, 0.021, 0.007);
  geometry.resolution = 0.07;
  geometry.size = Eigen::Vector3i(70, 57, 43);
  auto grid = mapper_->ToGrid(geometry);
  ASSERT_TRUE(grid.ok()) << grid.status().ToString();
  int64_t checked = 0;
  for (int k = 0; k < 43; k += 2) {
    for (int j = 0; j < 57; j += 2) {
      for (int i = 0; i < 70; i += 2) {
        const Eigen::Vector3d lo = geometry.origin + Eigen::Vector3d(i, j, k) * 0.07;
        const BoxOccupancy c =
            Classify(Eigen::AlignedBox3d(lo, lo + Eigen::Vector3d::Constant(0.07)));
        const VoxelState expected = c == BoxOccupancy::kOccupied ? VoxelState::kOccupied
                                    : c == BoxOccupancy::kFree   ? VoxelState::kFree
                                                                 : VoxelState::kUnknown;
        ASSERT_EQ(grid->at(Eigen::Vector3i(i, j, k)), expected) << i << " " << j << " " << k;
        ++checked;
      }
    }
  }
  EXPECT_GT(checked, 10000);
  EXPECT_GT(grid->Count(VoxelState::kOccupied), 500);
  EXPECT_GT(grid->Count(VoxelState::kFree), 1000);
}

TEST_F(OctomapMapperPlaneTest, BinaryFileReadsBackWithTheSameLeaves) {
  const std::string path = ::testing::TempDir() + "octomap_mapper_test_plane.bt";
  ASSERT_TRUE(mapper_->WriteBinary(path).ok());
  octomap::OcTree read(0.1);
  ASSERT_TRUE(read.readBinary(path));
  EXPECT_DOUBLE_EQ(read.getResolution(), 0.05);
  EXPECT_EQ(static_cast<int64_t>(read.getNumLeafNodes()), mapper_->NumLeaves());
  int64_t occupied_read = 0, occupied_ours = 0;
  for (auto it = read.begin_leafs(); it != read.end_leafs(); ++it) {
    occupied_read += read.isNodeOccupied(*it);
  }
  const octomap::OcTree& ours = mapper_->tree();
  for (auto it = ours.begin_leafs(); it != ours.end_leafs(); ++it) {
    occupied_ours += ours.isNodeOccupied(*it);
  }
  EXPECT_EQ(occupied_read, occupied_ours);
  EXPECT_GT(occupied_read, 500);
  std::remove(path.c_str());

  const Status bad = mapper_->WriteBinary("/nonexistent-dir/x/map.bt");
  EXPECT_EQ(bad.code(), StatusCode::kIoError);
  EXPECT_NE(bad.message().find("/nonexistent-dir/x/map.bt"), std::string::npos);
}

TEST_F(OctomapMapperPlaneTest, ResetClearsMapAndStats) {
  mapper_->Reset();
  EXPECT_EQ(mapper_->num_keyframes(), 0);
  EXPECT_EQ(mapper_->NumLeaves(), 0);
  EXPECT_EQ(Classify(Box(1.8, 1.6, 1.2, 3.3, 2.4, 1.8)), BoxOccupancy::kUnknown);
}

TEST_F(OctomapMapperPlaneTest, BadQueriesAreInvalidArgument) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  auto r = mapper_->Classify(Box(1, 1, 1, 0, 2, 2));
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("box"), std::string::npos);
  r = mapper_->Classify(Box(nan, 1, 1, 2, 2, 2));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("box"), std::string::npos);
  r = mapper_->Classify(Box(5000, 0, 0, 5001, 1, 1));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("box"), std::string::npos);

  GridGeometry geometry;
  geometry.size = Eigen::Vector3i(0, 1, 1);
  auto grid = mapper_->ToGrid(geometry);
  ASSERT_FALSE(grid.ok());
  EXPECT_EQ(grid.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(grid.status().message().find("geometry"), std::string::npos);
}

struct BadInputCase {
  std::string name;
  std::function<void(cv::Mat* left, cv::Mat* right, camera::RectifiedStereo* stereo,
                     geometry::SE3* pose)>
      corrupt;
  std::string expected_field;
};

TEST(OctomapMapperTest, BadInputsNameTheFieldAndLeaveTheMapUnchanged) {
  const std::vector<BadInputCase> cases = {
      {"empty left",
       [](cv::Mat* l, cv::Mat*, camera::RectifiedStereo*, geometry::SE3*) { *l = cv::Mat(); },
       "left: empty image"},
      {"empty right",
       [](cv::Mat*, cv::Mat* r, camera::RectifiedStereo*, geometry::SE3*) { *r = cv::Mat(); },
       "right: empty image"},
      {"left wrong size",
       [](cv::Mat* l, cv::Mat*, camera::RectifiedStereo*, geometry::SE3*) {
         *l = cv::Mat(480, 640, CV_8UC1, cv::Scalar(0));
       },
       "left: size 640x480"},
      {"right wrong size",
       [](cv::Mat*, cv::Mat* r, camera::RectifiedStereo*, geometry::SE3*) {
         *r = cv::Mat(240, 752, CV_8UC1, cv::Scalar(0));
       },
       "right: size 752x240"},
      {"left 16 bit",
       [](cv::Mat* l, cv::Mat*, camera::RectifiedStereo*, geometry::SE3*) {
         l->convertTo(*l, CV_16U);
       },
       "left: expected CV_8UC1 (8-bit grey), got CV_16UC1"},
      {"right colour",
       [](cv::Mat*, cv::Mat* r, camera::RectifiedStereo*, geometry::SE3*) {
         cv::cvtColor(*r, *r, cv::COLOR_GRAY2BGR);
       },
       "right: expected CV_8UC1 (8-bit grey), got CV_8UC3"},
      {"right float",
       [](cv::Mat*, cv::Mat* r, camera::RectifiedStereo*, geometry::SE3*) {
         r->convertTo(*r, CV_32F);
       },
       "right: expected CV_8UC1 (8-bit grey), got CV_32FC1"},
      {"bad stereo",
       [](cv::Mat*, cv::Mat*, camera::RectifiedStereo* s, geometry::SE3*) { s->baseline = 0; },
       "stereo: "},
      {"nan pose",
       [](cv::Mat*, cv::Mat*, camera::RectifiedStereo*, geometry::SE3* pose) {
         *pose = geometry::SE3(Eigen::Quaterniond::Identity(),
                               Eigen::Vector3d(0, std::numeric_limits<double>::quiet_NaN(), 0));
       },
       "T_world_cam: non-finite"},
  };
  auto mapper = OctomapMapper::Create();
  ASSERT_TRUE(mapper.ok());
  for (const BadInputCase& c : cases) {
    SCOPED_TRACE(c.name);
    cv::Mat left, right;
    PlanePair(CenteredEurocLikeRig(), kDisparity, 3, &left, &right);
    camera::RectifiedStereo stereo = CenteredEurocLikeRig();
    geometry::SE3 pose = CameraPose();
    c.corrupt(&left, &right, &stereo, &pose);
    const Status status = mapper->InsertKeyframe(left, right, stereo, pose);
    EXPECT_EQ(status.code(), StatusCode::kInvalidArgument);
    EXPECT_NE(status.message().find(c.expected_field), std::string::npos) << status.message();
    EXPECT_EQ(mapper->num_keyframes(), 0);
    EXPECT_EQ(mapper->NumLeaves(), 0);
  }
}

TEST(OctomapMapperTest, InvalidOptionsNameTheField) {
  struct Case {
    std::function<void(OctomapMapperOptions*)> corrupt;
    std::string field;
  };
  const std::vector<Case> cases = {
      {[](OctomapMapperOptions* o) { o->resolution = 0; }, "options.resolution"},
      {[](OctomapMapperOptions* o) { o->max_range_m = 0.1; }, "options.max_range_m"},
      {[](OctomapMapperOptions* o) { o->min_range_m = -1; }, "options.min_range_m"},
      {[](OctomapMapperOptions* o) { o->pixel_stride = 0; }, "options.pixel_stride"},
      {[](OctomapMapperOptions* o) { o->prob_hit = 0.3; }, "options.prob_hit"},
      {[](OctomapMapperOptions* o) { o->prob_miss = 0.6; }, "options.prob_miss"},
      {[](OctomapMapperOptions* o) { o->clamping_min = 0.6; }, "options.clamping_min"},
      {[](OctomapMapperOptions* o) { o->clamping_max = 1.0; }, "options.clamping_max"},
      {[](OctomapMapperOptions* o) { o->occupancy_threshold = 1.5; },
       "options.occupancy_threshold"},
      {[](OctomapMapperOptions* o) { o->num_disparities = 50; }, "options.num_disparities"},
      {[](OctomapMapperOptions* o) { o->block_size = 4; }, "options.block_size"},
      {[](OctomapMapperOptions* o) { o->block_size = 13; }, "options.block_size"},
      {[](OctomapMapperOptions* o) {
         o->matcher = StereoMatcherType::kBm;
         o->block_size = 3;
       },
       "options.block_size"},
      {[](OctomapMapperOptions* o) { o->uniqueness_ratio = -1; }, "options.uniqueness_ratio"},
      {[](OctomapMapperOptions* o) {
         o->sgbm_p1 = 100;
         o->sgbm_p2 = 50;
       },
       "options.sgbm_p2"},
  };
  std::string why;
  EXPECT_TRUE(OctomapMapperOptions().IsValid(&why)) << why;
  for (const Case& c : cases) {
    OctomapMapperOptions options;
    c.corrupt(&options);
    auto mapper = OctomapMapper::Create(options);
    ASSERT_FALSE(mapper.ok()) << c.field;
    EXPECT_EQ(mapper.status().code(), StatusCode::kInvalidArgument);
    EXPECT_EQ(mapper.status().message().rfind(c.field, 0), 0u) << mapper.status().message();
  }
}

TEST(OctomapMapperTest, UntexturedPairInsertsNothing) {
  auto mapper = OctomapMapper::Create();
  ASSERT_TRUE(mapper.ok());
  const cv::Mat flat(480, 752, CV_8UC1, cv::Scalar(128));
  ASSERT_TRUE(mapper->InsertKeyframe(flat, flat, CenteredEurocLikeRig(), CameraPose()).ok());
  EXPECT_EQ(mapper->num_keyframes(), 1);
  EXPECT_EQ(mapper->stats().keyframes[0].points, 0);
  EXPECT_EQ(mapper->NumLeaves(), 0);
}

// The plane is recovered with block matching, without discretized insertion, and when it lies
// beyond max_range (then only free space up to max_range is inserted).
TEST(OctomapMapperTest, VariantsRecoverThePlane) {
  for (int variant = 0; variant < 3; ++variant) {
    SCOPED_TRACE(variant);
    OctomapMapperOptions options;
    if (variant == 0) options.matcher = StereoMatcherType::kBm;
    if (variant == 1) options.discretize = false;
    if (variant == 2) options.max_range_m = 2.0;
    auto mapper = OctomapMapper::Create(options);
    ASSERT_TRUE(mapper.ok());
    cv::Mat left, right;
    PlanePair(CenteredEurocLikeRig(), kDisparity, 11, &left, &right);
    ASSERT_TRUE(mapper->InsertKeyframe(left, right, CenteredEurocLikeRig(), CameraPose()).ok());
    auto plane = mapper->Classify(Box(3.46, 1.8, 1.3, 3.49, 2.2, 1.7));
    auto front = mapper->Classify(Box(1.8, 1.8, 1.3, 2.9, 2.2, 1.7));
    ASSERT_TRUE(plane.ok() && front.ok());
    if (variant == 2) {
      // Rays are cut at 2 m (x = 3.0): free before, nothing known at the plane.
      EXPECT_EQ(*plane, BoxOccupancy::kUnknown);
      EXPECT_EQ(*mapper->Classify(Box(1.8, 1.8, 1.3, 2.9, 2.2, 1.7)), BoxOccupancy::kFree);
      EXPECT_EQ(*mapper->Classify(Box(3.1, 1.8, 1.3, 3.4, 2.2, 1.7)), BoxOccupancy::kUnknown);
    } else {
      EXPECT_EQ(*plane, BoxOccupancy::kOccupied);
      EXPECT_EQ(*front, BoxOccupancy::kFree);
    }
  }
}

// Two keyframes of the same plane from different positions: the map holds one plane, and the
// second keyframe's free space does not erase it.
TEST(OctomapMapperTest, TwoKeyframesAccumulate) {
  auto mapper = OctomapMapper::Create();
  ASSERT_TRUE(mapper.ok());
  cv::Mat left, right;
  PlanePair(CenteredEurocLikeRig(), kDisparity, 5, &left, &right);
  ASSERT_TRUE(mapper->InsertKeyframe(left, right, CenteredEurocLikeRig(), CameraPose()).ok());
  // 0.5 m to the side (world -y): the plane is at the same depth.
  const geometry::SE3 moved(CameraPose().Rotation(), Eigen::Vector3d(1.0, 1.5, 1.5));
  PlanePair(CenteredEurocLikeRig(), kDisparity, 6, &left, &right);
  ASSERT_TRUE(mapper->InsertKeyframe(left, right, CenteredEurocLikeRig(), moved).ok());
  mapper->Finish();
  EXPECT_EQ(mapper->num_keyframes(), 2);
  EXPECT_EQ(*mapper->Classify(Box(3.46, 1.0, 1.3, 3.49, 2.4, 1.7)), BoxOccupancy::kOccupied);
  EXPECT_EQ(*mapper->Classify(Box(1.8, 1.3, 1.3, 2.9, 2.2, 1.7)), BoxOccupancy::kFree);
  // Each plane voxel seen twice: still occupied one by one.
  int occupied = 0, total = 0;
  for (double y = 1.3; y <= 2.2; y += 0.05) {
    ++total;
    occupied += *mapper->Classify(VoxelAt(Eigen::Vector3d(kPlaneX, y + 0.025, 1.525))) ==
                BoxOccupancy::kOccupied;
  }
  EXPECT_EQ(occupied, total);
}

}  // namespace
}  // namespace mav::mapping
