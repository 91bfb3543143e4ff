#include "mav/mapping/grid_morphology.h"

#include <algorithm>

#include <gtest/gtest.h>

#include "mav/mapping/collision_eval.h"

namespace mav::mapping {
namespace {

OccupancyGrid FreeCube(int n) {
  GridGeometry g;
  g.origin = Eigen::Vector3d(0.5, -1.0, 0.0);
  g.resolution = 0.1;
  g.size = Eigen::Vector3i(n, n, n);
  return OccupancyGrid(g, VoxelState::kFree);
}

TEST(GridMorphologyTest, OneVoxelGrowsByTheNeighbourhood) {
  OccupancyGrid grid = FreeCube(7);
  grid.set({3, 3, 3}, VoxelState::kOccupied);
  MorphologyOptions faces;
  auto d6 = DilateOccupied(grid, faces);
  ASSERT_TRUE(d6.ok()) << d6.status().ToString();
  EXPECT_EQ(d6->Count(VoxelState::kOccupied), 7);
  EXPECT_EQ(d6->at({4, 3, 3}), VoxelState::kOccupied);
  EXPECT_EQ(d6->at({4, 4, 3}), VoxelState::kFree);

  MorphologyOptions all;
  all.full_neighbourhood = true;
  EXPECT_EQ(DilateOccupied(grid, all)->Count(VoxelState::kOccupied), 27);
  all.steps = 2;
  EXPECT_EQ(DilateOccupied(grid, all)->Count(VoxelState::kOccupied), 125);

  // Two face steps: the octahedron |dx| + |dy| + |dz| <= 2 (1 + 6 + 18 voxels).
  faces.steps = 2;
  EXPECT_EQ(DilateOccupied(grid, faces)->Count(VoxelState::kOccupied), 25);

  MorphologyOptions xy;
  xy.along_z = false;
  auto d_xy = DilateOccupied(grid, xy);
  EXPECT_EQ(d_xy->Count(VoxelState::kOccupied), 5);
  EXPECT_EQ(d_xy->at({3, 3, 4}), VoxelState::kFree);
  MorphologyOptions z;
  z.along_x = z.along_y = false;
  z.full_neighbourhood = true;
  EXPECT_EQ(DilateOccupied(grid, z)->Count(VoxelState::kOccupied), 3);
}

TEST(GridMorphologyTest, UnknownNeverChangesAndTheGridEdgeIsNoNeighbour) {
  OccupancyGrid grid = FreeCube(3);
  grid.set({0, 0, 0}, VoxelState::kOccupied);
  grid.set({1, 0, 0}, VoxelState::kUnknown);
  auto d = DilateOccupied(grid, MorphologyOptions{});
  ASSERT_TRUE(d.ok());
  EXPECT_EQ(d->at({1, 0, 0}), VoxelState::kUnknown);
  EXPECT_EQ(d->Count(VoxelState::kOccupied),
            3);  // itself, +y, +z (the -x/-y/-z sides are off-grid)

  // An occupied voxel touching only unknown voxels and the grid's edge is not eroded.
  OccupancyGrid walled(grid.geometry(), VoxelState::kUnknown);
  walled.set({0, 0, 0}, VoxelState::kOccupied);
  EXPECT_EQ(ErodeOccupied(walled, MorphologyOptions{})->Count(VoxelState::kOccupied), 1);
}

TEST(GridMorphologyTest, ErosionPeelsTheFreeSideOfASlab) {
  // A slab 3 voxels thick in z, free above and below: one step leaves the middle layer.
  OccupancyGrid grid = FreeCube(5);
  for (int j = 0; j < 5; ++j)
    for (int i = 0; i < 5; ++i)
      for (int k = 1; k <= 3; ++k) grid.set({i, j, k}, VoxelState::kOccupied);
  auto e = ErodeOccupied(grid, MorphologyOptions{});
  ASSERT_TRUE(e.ok());
  EXPECT_EQ(e->Count(VoxelState::kOccupied), 25);
  EXPECT_EQ(e->at({2, 2, 2}), VoxelState::kOccupied);
  EXPECT_EQ(e->at({2, 2, 1}), VoxelState::kFree);
  // Eroding along x and y only leaves the slab as it was (no free voxel beside it in xy).
  MorphologyOptions xy;
  xy.along_z = false;
  EXPECT_EQ(ErodeOccupied(grid, xy)->Count(VoxelState::kOccupied), 75);
  // steps = 0 is the identity.
  MorphologyOptions none;
  none.steps = 0;
  EXPECT_EQ(ErodeOccupied(grid, none)->states(), grid.states());
}

TEST(GridMorphologyTest, InvalidOptionsNameTheField) {
  const OccupancyGrid grid = FreeCube(3);
  MorphologyOptions bad;
  bad.steps = -1;
  auto r = DilateOccupied(grid, bad);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("steps"), std::string::npos);
  bad.steps = MorphologyOptions::kMaxSteps + 1;
  EXPECT_FALSE(ErodeOccupied(grid, bad).ok());
  MorphologyOptions no_axis;
  no_axis.along_x = no_axis.along_y = no_axis.along_z = false;
  r = ErodeOccupied(grid, no_axis);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("along_x"), std::string::npos);
}

TEST(GridMorphologyTest, StepsToOccupiedCountsNeighbourSteps) {
  OccupancyGrid grid = FreeCube(7);
  grid.set({3, 3, 3}, VoxelState::kOccupied);
  grid.set({3, 3, 4}, VoxelState::kUnknown);  // steps cross unknown voxels too
  MorphologyOptions full;
  full.full_neighbourhood = true;
  full.steps = 2;
  auto d = StepsToOccupied(grid, full);
  ASSERT_TRUE(d.ok()) << d.status().ToString();
  auto at = [&](int i, int j, int k) { return (*d)[static_cast<size_t>(grid.Linear(i, j, k))]; };
  EXPECT_EQ(at(3, 3, 3), 0);
  EXPECT_EQ(at(3, 3, 4), 1);
  EXPECT_EQ(at(4, 4, 4), 1);  // a corner neighbour: one step with 26 neighbours
  EXPECT_EQ(at(5, 1, 5), 2);
  EXPECT_EQ(at(6, 3, 3), 3);  // beyond steps: steps + 1
  EXPECT_EQ(at(0, 0, 0), 3);
  MorphologyOptions faces;
  faces.steps = 3;
  d = StepsToOccupied(grid, faces);
  ASSERT_TRUE(d.ok());
  EXPECT_EQ(at(4, 4, 4), 3);  // |dx| + |dy| + |dz| with the 6 face neighbours
  EXPECT_EQ(at(6, 3, 3), 3);
  EXPECT_EQ(at(5, 5, 3), 4);
  // No occupied voxel at all: everything is "far".
  d = StepsToOccupied(FreeCube(3), faces);
  ASSERT_TRUE(d.ok());
  EXPECT_EQ(*std::min_element(d->begin(), d->end()), 4);
  MorphologyOptions bad;
  bad.steps = 300;
  EXPECT_FALSE(StepsToOccupied(grid, bad).ok());
}

// The reason for the module: a truth one voxel too thick scores below 1 and misses nothing; one
// voxel too thin misses collisions.
TEST(GridMorphologyTest, ATruthOneVoxelOffLosesMccUnderTheBoxProtocol) {
  OccupancyGrid truth = FreeCube(20);
  for (int j = 0; j < 20; ++j)
    for (int i = 0; i < 20; ++i) truth.set({i, j, 0}, VoxelState::kOccupied);  // floor
  for (int k = 0; k < 20; ++k)
    for (int j = 0; j < 20; ++j)
      for (int i = 9; i <= 10; ++i) truth.set({i, j, k}, VoxelState::kOccupied);  // a wall
  CollisionEvalOptions eval;
  eval.box_size = Eigen::Vector3d(0.3, 0.3, 0.1);
  auto thick = DilateOccupied(truth, MorphologyOptions{});
  auto thin = ErodeOccupied(truth, MorphologyOptions{});
  ASSERT_TRUE(thick.ok() && thin.ok());
  auto self = EvaluateCollisions(truth, truth, eval);
  auto t = EvaluateCollisions(truth, *thick, eval);
  auto e = EvaluateCollisions(truth, *thin, eval);
  ASSERT_TRUE(self.ok() && t.ok() && e.ok());
  EXPECT_DOUBLE_EQ(self->Mcc(), 1.0);
  EXPECT_EQ(t->missed_collision, 0);
  EXPECT_GT(t->false_collision, 0);
  EXPECT_LT(t->Mcc(), 1.0);
  EXPECT_GT(e->missed_collision, 0);
  EXPECT_LT(e->Mcc(), 1.0);
}

}  // namespace
}  // namespace mav::mapping
