#include "mav/planning/planning_map.h"

#include <gtest/gtest.h>

#include <random>

#include "mav/common/file.h"
#include "test_maps.h"
#include "tests/common/build_paths.h"

namespace mav::planning {
namespace {

using testing::BruteForceClearance;
using testing::LoadMap;
using testing::RoomBytes;

class PlanningMapTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { bytes_ = new std::string(RoomBytes()); }
  static void TearDownTestSuite() { delete bytes_; }
  static std::string* bytes_;
};
std::string* PlanningMapTest::bytes_ = nullptr;

TEST_F(PlanningMapTest, InfoDescribesTheMap) {
  const auto map = LoadMap(*bytes_);
  ASSERT_NE(map, nullptr);
  const MapInfo& info = map->info();
  EXPECT_DOUBLE_EQ(info.resolution_m, 0.25);
  EXPECT_TRUE(info.bounds.min.isApprox(Eigen::Vector3d(0, 0, 0)));
  EXPECT_TRUE(info.bounds.max.isApprox(Eigen::Vector3d(10, 10, 5)));
  EXPECT_TRUE(info.planning_bounds.max.isApprox(info.bounds.max));
  // Wall 8 x 28 x 20 voxels plus the single voxel.
  EXPECT_EQ(info.occupied_voxels, 8u * 28 * 20 + 1);
  EXPECT_GT(info.free_voxels, 0u);
  EXPECT_GT(info.unknown_voxels, 8u * 8 * 20);  // the corner plus the shell around the map
  EXPECT_GT(info.fingerprint, 0u);
  EXPECT_EQ(info.memory.grid_voxels, static_cast<uint64_t>(map->grid_size().prod()));
}

// Random points, points on cell faces and corners, in every region (free, next to the wall,
// near the single voxel, in and near the unknown corner, near the map's faces).
std::vector<Eigen::Vector3d> ProbePoints(uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Eigen::Vector3d> points;
  points.reserve(210);
  for (int i = 0; i < 150; ++i) {
    points.emplace_back(u(rng) * 10, u(rng) * 10, u(rng) * 5);
  }
  for (int i = 0; i < 60; ++i) {  // on the cell lattice: faces, edges, corners
    points.emplace_back(std::round(u(rng) * 40) / 4, std::round(u(rng) * 40) / 4,
                        std::round(u(rng) * 20) / 4);
  }
  for (int i = 0; i < 40; ++i) {  // around the single voxel
    points.emplace_back(2.125 + (u(rng) - 0.5) * 1.5, 2.125 + (u(rng) - 0.5) * 1.5,
                        2.125 + (u(rng) - 0.5) * 1.5);
  }
  for (int i = 0; i < 40; ++i) {  // around the wall's end and the unknown corner
    points.emplace_back(3 + u(rng) * 6, 6.5 + u(rng) * 3.5, u(rng) * 5);
  }
  return points;
}

// `approximate_error`: how far ApproximateClearance may be off (half a cell diagonal with exact
// centre distances; DynamicEDT3D's lower bound adds up to another one).
void ExpectExactClearance(const PlanningMap& map,
                          double approximate_error = 0.5 * std::sqrt(3.0) * 0.25) {
  for (const Eigen::Vector3d& p : ProbePoints(7)) {
    const double truth = BruteForceClearance(map, p);
    ASSERT_NEAR(map.Clearance(p), truth, 1e-9) << "at " << p.transpose();
    EXPECT_LE(map.ClearanceLowerBound(p), truth + 1e-9) << "at " << p.transpose();
    EXPECT_NEAR(map.ClearanceUpTo(p, 0.6), std::min(truth, 0.6), 1e-9) << "at " << p.transpose();
    EXPECT_NEAR(map.ApproximateClearance(p), truth, approximate_error + 1e-9);
    for (double required : {0.2, 0.5, 0.75, 1.3}) {
      // Exactly at the threshold either answer is right; elsewhere it must match.
      if (std::abs(truth - required) < 1e-9) continue;
      EXPECT_EQ(map.HasClearance(p, required), truth >= required)
          << "at " << p.transpose() << " required " << required << " truth " << truth;
    }
  }
}

TEST_F(PlanningMapTest, ClearanceIsTheExactDistanceToTheNearestCube) {
  const auto map = LoadMap(*bytes_);
  ASSERT_NE(map, nullptr);
  ExpectExactClearance(*map);
  // Hand-checked values: 0.5 m in front of the wall's face, between cell centres.
  EXPECT_NEAR(map->Clearance({3.5, 3.13, 2.4}), 0.5, 1e-12);
  // Diagonally off the single voxel's corner (2.25, 2.25, 2.25).
  EXPECT_NEAR(map->Clearance({2.55, 2.65, 2.25}), 0.5, 1e-12);
  // Inside an obstacle.
  EXPECT_EQ(map->Clearance({5, 3, 1}), 0.0);
}

TEST_F(PlanningMapTest, DynamicEdt3dBaselineGivesTheSameClearance) {
  MapOptions options;
  options.distance_method = DistanceMethod::kDynamicEdt3d;
  const auto map = LoadMap(*bytes_, options);
  ASSERT_NE(map, nullptr);
  ExpectExactClearance(*map, std::sqrt(3.0) * 0.25);
}

TEST_F(PlanningMapTest, UnknownSpaceFollowsThePolicy) {
  const Eigen::Vector3d in_unknown(9, 9, 2.5), near_unknown(7.6, 9, 2.5);
  const auto blocked = LoadMap(*bytes_);
  ASSERT_NE(blocked, nullptr);
  EXPECT_EQ(blocked->Clearance(in_unknown), 0.0);
  EXPECT_NEAR(blocked->Clearance(near_unknown), 0.4, 1e-12);
  EXPECT_FALSE(blocked->IsValid(near_unknown));
  // The map's faces are unknown beyond: an obstacle too.
  EXPECT_NEAR(blocked->Clearance({5, 9, 4.8}), 0.2, 1e-12);

  MapOptions options;
  options.unknown_space = UnknownSpace::kFree;
  const auto open = LoadMap(*bytes_, options);
  ASSERT_NE(open, nullptr);
  EXPECT_GT(open->Clearance(in_unknown), 1.0);
  EXPECT_TRUE(open->IsValid(near_unknown));
  EXPECT_TRUE(open->IsValid({5, 9, 4.8}));  // nothing above the map but the planning bounds
  ExpectExactClearance(*open);
  EXPECT_NE(open->fingerprint(), blocked->fingerprint());
}

TEST_F(PlanningMapTest, PlanningBoundsLimitValidity) {
  MapOptions options;
  options.planning_bounds = Box{{0.5, 0.5, 0.5}, {3.5, 9.5, 4.5}};
  const auto map = LoadMap(*bytes_, options);
  ASSERT_NE(map, nullptr);
  EXPECT_TRUE(map->bounds().max.isApprox(Eigen::Vector3d(3.5, 9.5, 4.5)));
  EXPECT_FALSE(map->IsValid({3.6, 9, 2}));  // free, but outside the volume
  EXPECT_TRUE(map->IsValid({3.0, 9, 2}));
  // The wall outside the volume still counts for the clearance.
  EXPECT_NEAR(map->Clearance({3.4, 3, 2}), 0.6, 1e-12);
}

TEST_F(PlanningMapTest, SegmentsDoNotCutCornersAtTheMapResolution) {
  const auto map = LoadMap(*bytes_);
  ASSERT_NE(map, nullptr);
  // Passing the single voxel's corner (2.25, 2.25, 2.25) on the diagonal at a closest distance d:
  // the segment's endpoints are far from the voxel (valid), its middle is not.
  const Eigen::Vector3d corner(2.25, 2.25, 2.25), dir = Eigen::Vector3d(1, -1, 0).normalized();
  const Eigen::Vector3d away = Eigen::Vector3d(1, 1, 0).normalized();
  for (double d : {0.30, 0.45, 0.49}) {
    const Eigen::Vector3d mid = corner + d * away;
    EXPECT_FALSE(map->IsSegmentValid(mid - 0.8 * dir, mid + 0.8 * dir, 0.5)) << d;
  }
  for (double d : {0.52, 0.6}) {
    const Eigen::Vector3d mid = corner + d * away;
    EXPECT_TRUE(map->IsSegmentValid(mid - 0.8 * dir, mid + 0.8 * dir, 0.5)) << d;
  }
  // A segment grazing the wall's face 1 cm closer than allowed for 4 m is invalid, 1 cm farther
  // is valid: the check steps finely where it matters.
  EXPECT_FALSE(map->IsSegmentValid({3.51, 1, 2}, {3.51, 5, 2}, 0.5));
  EXPECT_TRUE(map->IsSegmentValid({3.49, 1, 2}, {3.49, 5, 2}, 0.5));
  // ValidFraction stops before the obstacle.
  const double f = map->ValidFraction({1, 3, 2}, {5, 3, 2}, 0.5);
  EXPECT_NEAR(f * 4, 2.5, 0.011);
}

TEST(PlanningMapErrorsTest, BadInputIsAValueNamingTheProblem) {
  const std::string bytes = RoomBytes();
  MapOptions options;
  options.robot_radius_m = -1;
  auto r = PlanningMap::LoadBytes(bytes, "room", options);
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("robot_radius_m"), std::string::npos);

  options = MapOptions{};
  options.max_distance_m = 0.2;
  r = PlanningMap::LoadBytes(bytes, "room", options);
  EXPECT_NE(r.status().message().find("max_distance_m"), std::string::npos);

  options = MapOptions{};
  options.planning_bounds = Box{{1, 1, 1}, {0, 2, 2}};
  r = PlanningMap::LoadBytes(bytes, "room", options);
  EXPECT_NE(r.status().message().find("planning_bounds.max"), std::string::npos);

  options.planning_bounds = Box{{100, 100, 100}, {101, 101, 101}};
  r = PlanningMap::LoadBytes(bytes, "room", options);
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);

  r = PlanningMap::LoadBytes(bytes.substr(0, bytes.size() / 2), "half.bt", {});
  EXPECT_EQ(r.status().code(), StatusCode::kDataLoss);
  EXPECT_NE(r.status().message().find("half.bt"), std::string::npos);
  r = PlanningMap::LoadBytes("not an octree", "junk.bt", {});
  EXPECT_EQ(r.status().code(), StatusCode::kDataLoss);

  r = PlanningMap::LoadFile("/nonexistent/map.bt", {});
  EXPECT_EQ(r.status().code(), StatusCode::kNotFound);
  EXPECT_NE(r.status().message().find("/nonexistent/map.bt"), std::string::npos);
}

TEST(PlanningMapErrorsTest, MemoryIsEstimatedAndLimitedBeforeAllocating) {
  const std::string bytes = RoomBytes();
  MapOptions options;
  const MemoryEstimate estimate = EstimateMapMemory(Box{{0, 0, 0}, {10, 10, 5}}, 0.25, options);
  EXPECT_EQ(estimate.grid_voxels, 40u * 40 * 20);
  EXPECT_EQ(estimate.bytes, estimate.grid_voxels * estimate.bytes_per_voxel);
  options.max_memory_bytes = 1000;
  auto r = PlanningMap::LoadBytes(bytes, "room", options);
  EXPECT_EQ(r.status().code(), StatusCode::kResourceExhausted);
  EXPECT_NE(r.status().message().find("max_memory_bytes"), std::string::npos);
  options.max_memory_bytes = 1ull << 30;
  EXPECT_TRUE(PlanningMap::LoadBytes(bytes, "room", options).ok());
}

TEST(PlanningMapErrorsTest, TerminationStopsTheLoad) {
  CancelFlag cancel;
  cancel.Cancel();
  auto r = PlanningMap::LoadBytes(RoomBytes(), "room", {}, Termination().WithCancel(cancel));
  EXPECT_EQ(r.status().code(), StatusCode::kCancelled);
  r = PlanningMap::LoadBytes(RoomBytes(), "room", {}, Termination::AfterMs(0));
  EXPECT_EQ(r.status().code(), StatusCode::kDeadlineExceeded);
}

TEST(PlanningMapErrorsTest, FileAndBytesGiveTheSameMap) {
  const std::string bytes = RoomBytes();
  const std::string path = mav::testing::BinaryDir() + "/planning_map_test_room.bt";
  ASSERT_TRUE(WriteStringToFileAtomic(path, bytes).ok());
  auto from_file = PlanningMap::LoadFile(path, {});
  auto from_bytes = PlanningMap::LoadBytes(bytes, "room", {});
  ASSERT_TRUE(from_file.ok()) << from_file.status().ToString();
  ASSERT_TRUE(from_bytes.ok());
  EXPECT_EQ((*from_file)->fingerprint(), (*from_bytes)->fingerprint());
  EXPECT_EQ((*from_file)->info().source, path);
}

}  // namespace
}  // namespace mav::planning
