// Ground-truth occupancy: the exact voxel rule on hand-checked cases, agreement with dense point
// sampling, the room preset, and the two file formats (.mavocc and OctoMap .bt).

#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <string>

#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include "mav/common/file.h"
#include "mav/dataset/occupancy_io.h"
#include "mav/sim/occupancy.h"
#include "mav/sim/presets.h"
#include "mav/sim/world.h"
#include "tests/common/build_paths.h"

namespace mav::sim {
namespace {

using dataset::GridGeometry;
using dataset::OccupancyGrid;
using dataset::VoxelState;
using Eigen::Vector3d;
using Eigen::Vector3i;

// Seeded uniform numbers for the tests.
class TestRng {
 public:
  explicit TestRng(uint64_t seed) : engine_(seed) {}
  double Uniform(double lo, double hi) {
    return std::uniform_real_distribution<double>(lo, hi)(engine_);
  }

 private:
  std::mt19937_64 engine_;
};

std::string TempPath(const std::string& name) {
  return mav::testing::BinaryDir() + "/occupancy_test_" + name;
}

World SmallWorld() {
  World w;
  w.AddMaterial(Material());
  w.SetBounds(Eigen::AlignedBox3d(Vector3d(-0.2, -0.2, -0.2), Vector3d(0.3, 0.3, 0.3)));
  return w;
}

TEST(OccupancyTest, AlignedBoxOnVoxelFacesOccupiesExactlyItsVoxels) {
  World w = SmallWorld();
  w.AddAlignedBox(Vector3d(0, 0, 0), Vector3d(0.1, 0.1, 0.1), 0);
  const OccupancyGrid g = ComputeOccupancy(w, 0.05);
  EXPECT_TRUE(g.origin().isApprox(Vector3d(-0.2, -0.2, -0.2)));
  EXPECT_EQ(g.size(), Vector3i(10, 10, 10));
  // 2 x 2 x 2 voxels; the face-touching neighbours stay free.
  EXPECT_EQ(g.Count(VoxelState::kOccupied), 8);
  EXPECT_EQ(g.StateAt(Vector3d(0.025, 0.075, 0.025)), VoxelState::kOccupied);
  EXPECT_EQ(g.StateAt(Vector3d(-0.025, 0.05, 0.05)), VoxelState::kFree);
  EXPECT_EQ(g.StateAt(Vector3d(0.125, 0.05, 0.05)), VoxelState::kFree);
  EXPECT_EQ(g.Count(VoxelState::kFree), 1000 - 8);
  EXPECT_EQ(g.StateAt(Vector3d(0.31, 0, 0)), VoxelState::kUnknown);
}

TEST(OccupancyTest, SlightlyLargerBoxReachesTheNeighbours) {
  World w = SmallWorld();
  // Overlaps the neighbouring voxel layer in +x by 1 mm: 3 x 2 x 2 voxels.
  w.AddAlignedBox(Vector3d(0, 0, 0), Vector3d(0.101, 0.1, 0.1), 0);
  EXPECT_EQ(ComputeOccupancy(w, 0.05).Count(VoxelState::kOccupied), 12);
}

TEST(OccupancyTest, RotatedBoxFollowsTheSeparatingAxisRule) {
  World w = SmallWorld();
  // A thin bar along the xy diagonal through (0.025, 0.025, 0.025): half length 0.05 along
  // (1,1,0)/sqrt2, half width 0.01 along (-1,1,0)/sqrt2, half height 0.01.
  w.AddBox(Vector3d(0.025, 0.025, 0.025),
           Eigen::AngleAxisd(M_PI / 4, Vector3d::UnitZ()).toRotationMatrix(),
           Vector3d(0.05, 0.01, 0.01), 0);
  const OccupancyGrid g = ComputeOccupancy(w, 0.05);
  auto state = [&](int i, int j, int k) {
    return g.StateAt(Vector3d(0.025 + 0.05 * i, 0.025 + 0.05 * j, 0.025 + 0.05 * k));
  };
  // Centre voxel and the diagonal neighbours the bar reaches (its ends are at 0.025 +- 0.0354).
  EXPECT_EQ(state(0, 0, 0), VoxelState::kOccupied);
  EXPECT_EQ(state(1, 1, 0), VoxelState::kOccupied);
  EXPECT_EQ(state(-1, -1, 0), VoxelState::kOccupied);
  // The bar crosses the shared corner point (0.05, 0.05) with positive width: (1,0) and (0,1)
  // overlap it with positive volume.
  EXPECT_EQ(state(1, 0, 0), VoxelState::kOccupied);
  EXPECT_EQ(state(0, 1, 0), VoxelState::kOccupied);
  // Separated along the bar's thin axis: projection distance 0.0707 > 0.0354 + 0.01.
  EXPECT_EQ(state(1, -1, 0), VoxelState::kFree);
  EXPECT_EQ(state(-1, 1, 0), VoxelState::kFree);
  // Beyond the ends, and above/below (the bar is 2 cm thick inside one voxel layer).
  EXPECT_EQ(state(2, 2, 0), VoxelState::kFree);
  EXPECT_EQ(state(0, 0, 1), VoxelState::kFree);
  EXPECT_EQ(state(0, 0, -1), VoxelState::kFree);
  EXPECT_EQ(g.Count(VoxelState::kOccupied), 7);  // the 5 above plus (-1,0) and (0,-1)
}

// Dense sampling check: a sample point inside both the voxel and the primitive proves overlap,
// and a primitive whose SAT says "intersects" must come within a sample spacing of the voxel.
void CheckAgainstSampling(const Primitive& prim, uint64_t seed) {
  TestRng rng(seed);
  const double res = 0.05;
  constexpr int kSamples = 9;
  for (int trial = 0; trial < 300; ++trial) {
    const Vector3d lo(rng.Uniform(-0.15, 0.1), rng.Uniform(-0.15, 0.1), rng.Uniform(-0.15, 0.1));
    const Eigen::AlignedBox3d voxel(lo, lo + Vector3d::Constant(res));
    const bool sat = prim.IntersectsBox(voxel);
    double min_sdf = 1e9;
    for (int a = 0; a < kSamples; ++a) {
      for (int b = 0; b < kSamples; ++b) {
        for (int c = 0; c < kSamples; ++c) {
          const Vector3d p = lo + res * Vector3d(a + 0.5, b + 0.5, c + 0.5) / kSamples;
          min_sdf = std::min(min_sdf, prim.SignedDistance(p));
        }
      }
    }
    const double spacing = res / kSamples;
    if (min_sdf < -1e-9) {
      EXPECT_TRUE(sat) << "sample inside both, trial " << trial;
    }
    if (sat) {
      EXPECT_LT(min_sdf, spacing * std::sqrt(3.0))
          << "reported overlap too far away, trial " << trial;
    }
  }
}

TEST(OccupancyTest, ExactTestsAgreeWithDenseSampling) {
  World w = SmallWorld();
  w.AddBox(Vector3d(0.0, 0.01, -0.02),
           (Eigen::AngleAxisd(0.7, Vector3d(1, 2, 3).normalized())).toRotationMatrix(),
           Vector3d(0.08, 0.03, 0.015), 0);
  w.AddCylinder(Vector3d(-0.1, 0.003, 0.01), Vector3d(0.12, 0.003, 0.01), 0.033, 0);
  w.AddCylinder(Vector3d(0.02, -0.02, -0.12), Vector3d(0.02, -0.02, 0.07), 0.06, 0);
  for (size_t i = 0; i < w.primitives().size(); ++i) {
    SCOPED_TRACE("primitive " + std::to_string(i));
    CheckAgainstSampling(w.primitives()[i], 100 + i);
  }
}

const World& Room() {
  static const std::shared_ptr<World> world = BuildRoomWorld(RoomStyle());
  return *world;
}

const OccupancyGrid& RoomGrid() {
  static const OccupancyGrid grid = ComputeOccupancy(Room(), 0.05);
  return grid;
}

TEST(OccupancyTest, RoomSolidsAreOccupiedAndTheRoomIsFree) {
  const World& w = Room();
  const OccupancyGrid& g = RoomGrid();
  EXPECT_NEAR(g.resolution(), 0.05, 1e-15);
  EXPECT_EQ(g.size(), Vector3i(168, 168, 68));  // 8.4 x 8.4 x 3.4 m
  EXPECT_EQ(g.StateAt(Vector3d(0.5, 1.5, 2.0)), VoxelState::kFree);
  EXPECT_EQ(g.StateAt(Vector3d(4.1, 0, 1.5)), VoxelState::kOccupied);  // inside a wall
  EXPECT_EQ(g.StateAt(Vector3d(0, 0, 0.3)), VoxelState::kOccupied);    // central crate
  EXPECT_EQ(g.StateAt(Vector3d(0, 0, 3.5)), VoxelState::kUnknown);     // above the ceiling
  EXPECT_EQ(g.StateAt(Vector3d(5, 0, 1)), VoxelState::kUnknown);
  // Random points: inside a solid -> occupied; farther than a voxel diagonal -> free.
  TestRng rng(42);
  const Eigen::AlignedBox3d b = w.bounds();
  int inside = 0, clear = 0;
  for (int i = 0; i < 20000; ++i) {
    const Vector3d p(rng.Uniform(b.min().x(), b.max().x()), rng.Uniform(b.min().y(), b.max().y()),
                     rng.Uniform(b.min().z(), b.max().z()));
    const double d = w.SignedDistance(p);
    if (d < -1e-6) {
      ++inside;
      ASSERT_EQ(g.StateAt(p), VoxelState::kOccupied) << p.transpose();
    } else if (d > 0.05 * std::sqrt(3.0) + 1e-9) {
      ++clear;
      ASSERT_EQ(g.StateAt(p), VoxelState::kFree) << p.transpose();
    }
  }
  EXPECT_GT(inside, 1000);
  EXPECT_GT(clear, 10000);
  // Thin pipes (1.2-1.5 cm radius) are fine structures that still occupy their voxels.
  EXPECT_EQ(g.StateAt(Vector3d(0.0, -3.75, 2.3)), VoxelState::kOccupied);
  EXPECT_EQ(g.StateAt(Vector3d(0.0, -3.75, 2.2)), VoxelState::kFree);
}

TEST(OccupancyTest, MavoccRoundTripIsExact) {
  const OccupancyGrid& g = RoomGrid();
  const std::string path = TempPath("room.mavocc");
  ASSERT_TRUE(dataset::WriteMavocc(g, path).ok());
  Result<OccupancyGrid> r = dataset::ReadMavocc(path);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->origin(), g.origin());
  EXPECT_EQ(r->resolution(), g.resolution());
  EXPECT_EQ(r->size(), g.size());
  EXPECT_TRUE(r->states() == g.states());
  std::remove(path.c_str());
}

TEST(OccupancyTest, CorruptTruncatedOrMissingFilesAreReported) {
  const OccupancyGrid& g = RoomGrid();
  const std::string path = TempPath("bad.mavocc");
  ASSERT_TRUE(dataset::WriteMavocc(g, path).ok());
  const std::string good = *ReadFileToString(path);

  auto expect_loss = [&](const std::string& bytes, const std::string& what) {
    ASSERT_TRUE(WriteStringToFileAtomic(path, bytes).ok());
    Result<OccupancyGrid> r = dataset::ReadMavocc(path);
    ASSERT_FALSE(r.ok()) << what;
    EXPECT_EQ(r.status().code(), StatusCode::kDataLoss) << what;
    EXPECT_NE(r.status().message().find(path), std::string::npos) << r.status().message();
  };
  std::string flipped = good;
  flipped[good.size() / 2] ^= 0x10;
  expect_loss(flipped, "flipped payload byte");
  std::string bad_res = good;
  bad_res[40] ^= 0x01;  // inside the resolution field
  expect_loss(bad_res, "header change");
  expect_loss(good.substr(0, good.size() - 11), "truncated payload");
  expect_loss(good.substr(0, 30), "truncated header");
  expect_loss("not an occupancy grid at all, just some text that is long enough........",
              "bad magic");
  expect_loss("", "empty");
  std::remove(path.c_str());

  Result<OccupancyGrid> missing = dataset::ReadMavocc(TempPath("does_not_exist.mavocc"));
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), StatusCode::kNotFound);
  EXPECT_NE(missing.status().message().find("does_not_exist.mavocc"), std::string::npos);
}

TEST(OccupancyTest, OctomapFileHasTheRightLeafStates) {
  const OccupancyGrid g = ComputeOccupancy(Room(), 0.1);
  const std::string path = TempPath("room.bt");
  ASSERT_TRUE(dataset::WriteOctomapBt(g, path).ok());
  octomap::OcTree tree(0.1);
  ASSERT_TRUE(tree.readBinary(path));
  EXPECT_NEAR(tree.getResolution(), 0.1, 1e-12);
  int64_t checked[3] = {0, 0, 0};
  for (int z = 0; z < g.size().z(); z += 1) {
    for (int y = 0; y < g.size().y(); y += 3) {
      for (int x = 0; x < g.size().x(); x += 2) {
        const Vector3d c = g.CenterOf({x, y, z});
        const VoxelState s = g.at({x, y, z});
        const octomap::OcTreeNode* node = tree.search(c.x(), c.y(), c.z());
        ++checked[static_cast<int>(s)];
        if (s == VoxelState::kUnknown) {
          ASSERT_EQ(node, nullptr) << c.transpose();
        } else {
          ASSERT_NE(node, nullptr) << c.transpose();
          ASSERT_EQ(tree.isNodeOccupied(node), s == VoxelState::kOccupied) << c.transpose();
        }
      }
    }
  }
  EXPECT_GT(checked[static_cast<int>(VoxelState::kFree)], 1000);
  EXPECT_GT(checked[static_cast<int>(VoxelState::kOccupied)], 1000);
  // Outside the grid: unknown.
  EXPECT_EQ(tree.search(0.0, 0.0, 5.0), nullptr);
  // Pruning merged uniform regions: far fewer leaves than known voxels.
  EXPECT_LT(static_cast<int64_t>(tree.getNumLeafNodes()),
            (g.Count(VoxelState::kFree) + g.Count(VoxelState::kOccupied)) / 2);
  std::remove(path.c_str());
}

}  // namespace
}  // namespace mav::sim
