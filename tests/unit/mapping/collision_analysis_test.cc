#include "mav/mapping/collision_analysis.h"

#include <gtest/gtest.h>

namespace mav::mapping {
namespace {

GridGeometry Geometry(int nx, int ny, int nz) {
  GridGeometry g;
  g.origin = Eigen::Vector3d(0, 0, 0);
  g.resolution = 0.1;
  g.size = Eigen::Vector3i(nx, ny, nz);
  return g;
}

// A 12 x 12 x 8 world: unknown outside a known 10 x 10 x 6 box (indices 1..10, 1..10, 1..6)
// whose floor (k = 1) and one wall (i = 1) are occupied, the rest free.
OccupancyGrid Room() {
  OccupancyGrid g(Geometry(12, 12, 8), VoxelState::kUnknown);
  for (int k = 1; k <= 6; ++k) {
    for (int j = 1; j <= 10; ++j) {
      for (int i = 1; i <= 10; ++i) {
        g[g.Linear(i, j, k)] = (k == 1 || i == 1) ? VoxelState::kOccupied : VoxelState::kFree;
      }
    }
  }
  return g;
}

CollisionEvalOptions Eval(const OccupancyGrid& truth) {
  CollisionEvalOptions eval;
  eval.box_size = Eigen::Vector3d(0.2, 0.2, 0.2);
  EXPECT_TRUE(KnownRegion(truth, &eval.region_min, &eval.region_max));
  return eval;
}

TEST(KnownRegionTest, BoundsTheKnownVoxels) {
  const OccupancyGrid truth = Room();
  Eigen::Vector3i lo, hi;
  ASSERT_TRUE(KnownRegion(truth, &lo, &hi));
  EXPECT_EQ(lo, Eigen::Vector3i(1, 1, 1));
  EXPECT_EQ(hi, Eigen::Vector3i(11, 11, 7));
  EXPECT_FALSE(KnownRegion(OccupancyGrid(Geometry(3, 3, 3)), &lo, &hi));
}

TEST(ProtocolSensitivityTest, ThickerMissesNothingThinnerMissesSomething) {
  const OccupancyGrid truth = Room();
  const std::vector<uint8_t> all_observable(static_cast<size_t>(truth.num_voxels()), 1);
  auto rows = ProtocolSensitivity(truth, all_observable, Eval(truth));
  ASSERT_TRUE(rows.ok()) << rows.status().ToString();
  ASSERT_EQ(rows->size(), ProtocolSensitivityRows().size());
  for (const SensitivityRow& r : *rows) {
    const CollisionOutcomes& c = r.outcomes;
    EXPECT_GT(c.total(), 0) << r.name;
    if (r.change == SensitivityRow::Change::kDilate) {
      EXPECT_EQ(c.missed_collision, 0) << r.name;
      EXPECT_GT(c.false_collision, 0) << r.name;
    } else if (r.change == SensitivityRow::Change::kErode) {
      EXPECT_GT(c.missed_collision, 0) << r.name;
      EXPECT_EQ(c.false_collision, 0) << r.name;
    } else {
      // Everything observable: hiding the unobservable free space changes nothing.
      EXPECT_EQ(c.missed_collision + c.false_collision, 0) << r.name;
      EXPECT_NEAR(c.Mcc(), 1.0, 1e-12);
    }
  }
}

TEST(ProtocolSensitivityTest, UnobservableFreeSpaceBecomesUnknown) {
  const OccupancyGrid truth = Room();
  std::vector<uint8_t> observable(static_cast<size_t>(truth.num_voxels()), 0);
  const SensitivityRow hide = ProtocolSensitivityRows().back();
  ASSERT_EQ(hide.change, SensitivityRow::Change::kHideUnobservable);
  auto changed = ChangedTruth(truth, hide, observable);
  ASSERT_TRUE(changed.ok());
  EXPECT_EQ(changed->Count(VoxelState::kFree), 0);
  EXPECT_EQ(changed->Count(VoxelState::kOccupied), truth.Count(VoxelState::kOccupied));
  observable.pop_back();
  EXPECT_FALSE(ChangedTruth(truth, hide, observable).ok());
}

TEST(AttributeErrorsTest, FixingAClassRemovesExactlyItsErrors) {
  const OccupancyGrid truth = Room();
  OccupancyGrid map = truth;
  // Two false blocks next to the floor (1 step away) and one far from any surface; one miss.
  map[map.Linear(5, 5, 2)] = VoxelState::kOccupied;
  map[map.Linear(6, 5, 2)] = VoxelState::kUnknown;
  map[map.Linear(7, 8, 6)] = VoxelState::kOccupied;
  map[map.Linear(4, 4, 1)] = VoxelState::kFree;
  const CollisionEvalOptions eval = Eval(truth);
  auto rows = AttributeErrors(truth, map, eval);
  ASSERT_TRUE(rows.ok()) << rows.status().ToString();
  auto voxels = [&](const std::string& name) -> int64_t {
    for (const AttributionRow& r : *rows) {
      if (r.name == name) return r.voxels;
    }
    ADD_FAILURE() << name;
    return -1;
  };
  EXPECT_EQ(voxels("blocked_at_1"), 2);
  EXPECT_EQ(voxels("blocked_beyond_3"), 1);
  EXPECT_EQ(voxels("blocked_all"), 3);
  EXPECT_EQ(voxels("free_all"), 1);
  for (const AttributionRow& r : *rows) {
    if (r.name == "blocked_all") {
      EXPECT_EQ(r.outcomes.false_collision, 0);
    } else if (r.name == "free_all") {
      EXPECT_EQ(r.outcomes.missed_collision, 0);
    }
  }
  EXPECT_FALSE(AttributeErrors(truth, OccupancyGrid(Geometry(3, 3, 3)), eval).ok());
}

}  // namespace
}  // namespace mav::mapping
