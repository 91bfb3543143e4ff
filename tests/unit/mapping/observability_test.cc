#include "mav/mapping/observability.h"

#include <cmath>
#include <cstdint>
#include <vector>

#include <gtest/gtest.h>

#include "mav/mapping/collision_eval.h"

namespace mav::mapping {
namespace {

using geometry::SE3;

// A 2 x 1 x 1 m box of 5 cm voxels: free, with a solid wall at x in [1.5, 1.6).
OccupancyGrid WallWorld() {
  GridGeometry g;
  g.origin = Eigen::Vector3d(0.0, 0.0, 0.0);
  g.resolution = 0.05;
  g.size = Eigen::Vector3i(40, 20, 20);
  OccupancyGrid grid(g, VoxelState::kFree);
  for (int k = 0; k < 20; ++k) {
    for (int j = 0; j < 20; ++j) {
      for (int i = 30; i < 32; ++i) grid.set({i, j, k}, VoxelState::kOccupied);
    }
  }
  return grid;
}

camera::RectifiedStereo Rig() {
  camera::RectifiedStereo rig;
  rig.width = 160;
  rig.height = 120;
  rig.fx = rig.fy = 80.0;  // ~90 x 74 deg field of view
  rig.cx = 80.0;
  rig.cy = 60.0;
  rig.baseline = 0.1;
  return rig;
}

// A camera at (0.5, 0.5, 0.5) looking along +x (camera z = world x, camera x = world -y,
// camera y = world -z).
SE3 LookingAlongX() {
  Eigen::Matrix3d R;
  R.col(0) = Eigen::Vector3d(0, -1, 0);
  R.col(1) = Eigen::Vector3d(0, 0, -1);
  R.col(2) = Eigen::Vector3d(1, 0, 0);
  return SE3(Eigen::Quaterniond(R), Eigen::Vector3d(0.5, 0.5, 0.5));
}

TEST(ObservableVoxelsTest, FieldOfViewAndOcclusion) {
  const OccupancyGrid world = WallWorld();
  const auto seen = ObservableVoxels(world, {LookingAlongX()}, Rig());
  ASSERT_TRUE(seen.ok()) << seen.status().ToString();
  auto at = [&](int i, int j, int k) { return (*seen)[world.Linear(i, j, k)]; };
  EXPECT_EQ(at(15, 10, 10), 1) << "in front of the camera";
  EXPECT_EQ(at(25, 10, 10), 1) << "just before the wall";
  EXPECT_EQ(at(30, 10, 10), 1) << "the wall's face is where the rays end";
  EXPECT_EQ(at(35, 10, 10), 0) << "behind the wall";
  EXPECT_EQ(at(5, 10, 10), 0) << "behind the camera";
  EXPECT_EQ(at(12, 0, 10), 0) << "outside the field of view (45 deg off the axis at 0.3 m)";
  // More cameras see more: one behind the wall looking back (-x) sees its side of the room.
  SE3 back = LookingAlongX();
  back =
      SE3(back.Rotation() * Eigen::Quaterniond(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY())),
          Eigen::Vector3d(1.9, 0.5, 0.5));
  const auto both = ObservableVoxels(world, {LookingAlongX(), back}, Rig());
  ASSERT_TRUE(both.ok());
  EXPECT_EQ((*both)[world.Linear(35, 10, 10)], 1);
  EXPECT_EQ((*both)[world.Linear(15, 10, 10)], 1);
}

TEST(ObservableVoxelsTest, BadInputNamesTheField) {
  const OccupancyGrid world = WallWorld();
  ObservabilityOptions options;
  options.pixel_step = 0;
  auto r = ObservableVoxels(world, {LookingAlongX()}, Rig(), options);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("options.pixel_step"), std::string::npos);
  options = ObservabilityOptions();
  options.max_range_m = std::nan("");
  r = ObservableVoxels(world, {LookingAlongX()}, Rig(), options);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("options.max_range_m"), std::string::npos);
  SE3 bad(Eigen::Quaterniond::Identity(), Eigen::Vector3d(std::nan(""), 0, 0));
  r = ObservableVoxels(world, {LookingAlongX(), bad}, Rig());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("T_world_cams[1]"), std::string::npos);
}

// The evaluation over the observable volume leaves out exactly the positions that cover a
// truth-free voxel no camera saw; a map wrong only there scores perfectly over it.
TEST(ObservableVoxelsTest, EvaluationOverTheObservableVolume) {
  const OccupancyGrid world = WallWorld();
  const auto seen = ObservableVoxels(world, {LookingAlongX()}, Rig());
  ASSERT_TRUE(seen.ok());
  // The map: the truth, but the unseen free space behind the wall is unknown.
  OccupancyGrid map = world;
  for (int64_t i = 0; i < map.num_voxels(); ++i) {
    if ((*seen)[static_cast<size_t>(i)] == 0 && world[i] == VoxelState::kFree) {
      map[i] = VoxelState::kUnknown;
    }
  }
  CollisionEvalOptions options;
  options.box_size = Eigen::Vector3d(0.2, 0.2, 0.1);
  const auto all = EvaluateCollisions(world, map, options);
  ASSERT_TRUE(all.ok());
  EXPECT_GT(all->false_collision, 0) << "unknown counts as occupied";
  options.observable = &*seen;
  const auto observable = EvaluateCollisions(world, map, options);
  ASSERT_TRUE(observable.ok()) << observable.status().ToString();
  EXPECT_LT(observable->total(), all->total());
  EXPECT_GT(observable->total(), 0);
  EXPECT_EQ(observable->false_collision, 0);
  EXPECT_EQ(observable->missed_collision, 0);
  EXPECT_NEAR(observable->Mcc(), 1.0, 1e-12);
  // A mask of the wrong size is refused, naming the field.
  const std::vector<uint8_t> short_mask(10, 1);
  options.observable = &short_mask;
  const auto bad = EvaluateCollisions(world, map, options);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("observable"), std::string::npos);
}

}  // namespace
}  // namespace mav::mapping
