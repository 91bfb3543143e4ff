#include "mav/mapping/collision_eval.h"

#include <cmath>

#include <gtest/gtest.h>

namespace mav::mapping {
namespace {

GridGeometry Geometry(int nx, int ny, int nz, double res = 0.1) {
  GridGeometry g;
  g.origin = Eigen::Vector3d(-1.0, 2.0, 0.5);
  g.resolution = res;
  g.size = Eigen::Vector3i(nx, ny, nz);
  return g;
}

TEST(MatthewsCorrelationTest, HandComputedValues) {
  // TP=54, FN=1, TN=40, FP=5: (54*40 - 5*1) / sqrt(59 * 55 * 45 * 41).
  const double expected = (54.0 * 40 - 5.0 * 1) / std::sqrt(59.0 * 55 * 45 * 41);
  EXPECT_NEAR(MatthewsCorrelation(54, 1, 40, 5), expected, 1e-12);
  EXPECT_NEAR(MatthewsCorrelation(10, 0, 10, 0), 1.0, 1e-12);
  EXPECT_NEAR(MatthewsCorrelation(0, 10, 0, 10), -1.0, 1e-12);
  EXPECT_NEAR(MatthewsCorrelation(5, 5, 5, 5), 0.0, 1e-12);
}

TEST(MatthewsCorrelationTest, UndefinedIsZero) {
  EXPECT_EQ(MatthewsCorrelation(0, 0, 10, 3), 0.0);  // truth has no collision at all
  EXPECT_EQ(MatthewsCorrelation(7, 3, 0, 0), 0.0);   // truth has no free position
  EXPECT_EQ(MatthewsCorrelation(7, 0, 3, 0) > 0.99, true);
  EXPECT_EQ(MatthewsCorrelation(0, 0, 0, 0), 0.0);
}

// The row of the two tests below: 6 voxels; truth occupied at 2; computed occupied at 4 and
// unknown at 5; a box 2 voxels long.
OccupancyGrid HandMadeRowTruth() {
  OccupancyGrid truth(Geometry(6, 1, 1), VoxelState::kFree);
  truth.set({2, 0, 0}, VoxelState::kOccupied);
  return truth;
}
OccupancyGrid HandMadeRowComputed() {
  OccupancyGrid computed(Geometry(6, 1, 1), VoxelState::kFree);
  computed.set({4, 0, 0}, VoxelState::kOccupied);
  computed.set({5, 0, 0}, VoxelState::kUnknown);
  return computed;
}
CollisionEvalOptions HandMadeRowOptions() {
  CollisionEvalOptions options;
  options.box_size = Eigen::Vector3d(0.2, 0.1, 0.1);
  return options;
}

// A 1-D row of 6 voxels, box of 2 voxels, step 1 -> 5 positions, checked by hand.
//   truth:    F F O F F F     positions: [0,1]=free [1,2]=hit [2,3]=hit [3,4]=free [4,5]=free
//   computed: F F F F O U     positions: [0,1]=free [1,2]=free [2,3]=free [3,4]=hit [4,5]=hit
// -> TP 0, FN 2 (positions 1, 2), TN 1 (position 0), FP 2 (positions 3, 4).
TEST(EvaluateCollisionsTest, HandMadeRow) {
  OccupancyGrid truth = HandMadeRowTruth(), computed = HandMadeRowComputed();
  CollisionEvalOptions options = HandMadeRowOptions();
  const auto r = EvaluateCollisions(truth, computed, options);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->correct_collision, 0);
  EXPECT_EQ(r->missed_collision, 2);
  EXPECT_EQ(r->correct_free, 1);
  EXPECT_EQ(r->false_collision, 2);
  EXPECT_EQ(r->total(), 5);
  EXPECT_NEAR(r->Percent(r->false_collision), 40.0, 1e-12);
  // TP + FP = 2, TP + FN = 2, TN + FP = 3, TN + FN = 3: (0 * 1 - 2 * 2) / sqrt(36) = -2/3.
  EXPECT_NEAR(r->Mcc(), -2.0 / 3.0, 1e-12);
}

TEST(EvaluateCollisionsTest, UnknownHandlingIsAnOption) {
  OccupancyGrid truth = HandMadeRowTruth(), computed = HandMadeRowComputed();
  CollisionEvalOptions options = HandMadeRowOptions();
  options.computed_unknown_is_occupied = false;
  const auto r = EvaluateCollisions(truth, computed, options);
  ASSERT_TRUE(r.ok());
  // Position [4,5] still hits the occupied voxel 4; nothing changes except via voxel 5 alone,
  // which no position covers without voxel 4. Same outcome as with unknown = occupied.
  EXPECT_EQ(r->false_collision, 2);
  // Now let the unknown voxel stand alone.
  computed.set({4, 0, 0}, VoxelState::kFree);
  const auto r2 = EvaluateCollisions(truth, computed, options);
  ASSERT_TRUE(r2.ok());
  EXPECT_EQ(r2->false_collision, 0);
  EXPECT_EQ(r2->correct_free, 3);
  options.computed_unknown_is_occupied = true;
  const auto r3 = EvaluateCollisions(truth, computed, options);
  ASSERT_TRUE(r3.ok());
  EXPECT_EQ(r3->false_collision, 1);
}

// 3-D: a 4x4x4 grid, box 2x2x2, step 1 -> 27 positions. Truth occupied at (0,0,0) only: the
// one position containing it is the box at the origin. Computed identical -> MCC 1.
TEST(EvaluateCollisionsTest, PerfectMatchIsOne) {
  const GridGeometry g = Geometry(4, 4, 4);
  OccupancyGrid truth(g, VoxelState::kFree);
  truth.set({0, 0, 0}, VoxelState::kOccupied);
  CollisionEvalOptions options;
  options.box_size = Eigen::Vector3d(0.2, 0.2, 0.2);
  const auto r = EvaluateCollisions(truth, truth, options);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->total(), 27);
  EXPECT_EQ(r->correct_collision, 1);
  EXPECT_EQ(r->correct_free, 26);
  EXPECT_NEAR(r->Mcc(), 1.0, 1e-12);
  // An all-occupied computed grid: TP 1, FP 26 -> MCC undefined (no computed free) -> 0.
  const OccupancyGrid all(g, VoxelState::kOccupied);
  const auto r2 = EvaluateCollisions(truth, all, options);
  ASSERT_TRUE(r2.ok());
  EXPECT_EQ(r2->false_collision, 26);
  EXPECT_EQ(r2->Mcc(), 0.0);
  // Step 2 -> positions 0 and 2 per axis -> 8.
  options.step_voxels = 2;
  EXPECT_EQ(EvaluateCollisions(truth, truth, options)->total(), 8);
}

TEST(EvaluateCollisionsTest, BadInputIsAnError) {
  const OccupancyGrid a(Geometry(4, 4, 4), VoxelState::kFree);
  const OccupancyGrid b(Geometry(4, 4, 5), VoxelState::kFree);
  auto r = EvaluateCollisions(a, b);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("computed"), std::string::npos);
  CollisionEvalOptions options;
  options.box_size = Eigen::Vector3d(1.0, 0.1, 0.1);  // 10 voxels > 4
  r = EvaluateCollisions(a, a, options);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("box_size"), std::string::npos);
  options.box_size = Eigen::Vector3d(NAN, 0.1, 0.1);
  r = EvaluateCollisions(a, a, options);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("box_size"), std::string::npos);
  options = {};
  options.step_voxels = 0;
  EXPECT_FALSE(EvaluateCollisions(a, a, options).ok());
}

TEST(BoxQueryTest, MatchesBruteForce) {
  const GridGeometry g = Geometry(7, 5, 6);
  OccupancyGrid grid(g, VoxelState::kFree);
  uint32_t state = 12345;
  for (int64_t i = 0; i < grid.num_voxels(); ++i) {
    state = state * 1664525u + 1013904223u;
    const int r = static_cast<int>((state >> 24) % 5);
    grid[i] = r == 0 ? VoxelState::kOccupied : r == 1 ? VoxelState::kUnknown : VoxelState::kFree;
  }
  const BoxQuery q(grid);
  for (int t = 0; t < 200; ++t) {
    Eigen::Vector3i lo, hi;
    for (int a = 0; a < 3; ++a) {
      state = state * 1664525u + 1013904223u;
      lo[a] = static_cast<int>((state >> 20) % g.size[a]);
      state = state * 1664525u + 1013904223u;
      hi[a] = lo[a] + 1 + static_cast<int>((state >> 20) % (g.size[a] - lo[a]));
    }
    int64_t occ = 0, unk = 0;
    for (int k = lo.z(); k < hi.z(); ++k)
      for (int j = lo.y(); j < hi.y(); ++j)
        for (int i = lo.x(); i < hi.x(); ++i) {
          occ += grid.at({i, j, k}) == VoxelState::kOccupied;
          unk += grid.at({i, j, k}) == VoxelState::kUnknown;
        }
    ASSERT_EQ(q.Occupied(lo, hi), occ);
    ASSERT_EQ(q.Unknown(lo, hi), unk);
  }
  // Outside the grid counts as unknown.
  EXPECT_EQ(q.Unknown({-1, 0, 0}, {0, 1, 1}), 1);
  const OccupancyGrid free_grid(g, VoxelState::kFree);
  const BoxQuery fq(free_grid);
  EXPECT_EQ(fq.Query(g.origin + Eigen::Vector3d::Constant(0.15),
                     g.origin + Eigen::Vector3d::Constant(0.35)),
            BoxQuery::Answer::kFree);
  EXPECT_EQ(fq.Query(g.origin - Eigen::Vector3d::Constant(0.05),
                     g.origin + Eigen::Vector3d::Constant(0.35)),
            BoxQuery::Answer::kUnknown);
}

}  // namespace
}  // namespace mav::mapping
