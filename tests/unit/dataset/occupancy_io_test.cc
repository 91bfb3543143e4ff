#include "mav/dataset/occupancy_io.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace mav::dataset {
namespace {

OccupancyGrid SmallGrid() {
  GridGeometry g;
  g.origin = Eigen::Vector3d(-0.5, -0.25, 0.0);
  g.resolution = 0.25;
  g.size = Eigen::Vector3i(4, 3, 2);
  OccupancyGrid grid(g, VoxelState::kFree);
  grid.set({0, 0, 0}, VoxelState::kOccupied);
  grid.set({3, 2, 1}, VoxelState::kUnknown);
  return grid;
}

TEST(GridGeometryTest, CoveringSnapsTheOriginAndCoversTheBox) {
  const GridGeometry g = GridGeometry::Covering(Eigen::Vector3d(-0.12, 0.3, 1.0),
                                                Eigen::Vector3d(1.0, 0.9, 1.01), 0.1);
  EXPECT_TRUE(g.origin.isApprox(Eigen::Vector3d(-0.2, 0.3, 1.0)));
  EXPECT_EQ(g.size, Eigen::Vector3i(12, 6, 1));
  std::string why;
  EXPECT_TRUE(g.IsValid(&why)) << why;
}

TEST(GridGeometryTest, HugeBoxesGiveInvalidGeometriesNotOverflows) {
  const GridGeometry g = GridGeometry::Covering(Eigen::Vector3d::Constant(-1e15),
                                                Eigen::Vector3d::Constant(1e15), 0.01);
  EXPECT_EQ(g.size.x(), 2'000'000'000);
  std::string why;
  EXPECT_FALSE(g.IsValid(&why));
  EXPECT_EQ(why.rfind("size: ", 0), 0u) << why;
  GridGeometry nan;
  nan.resolution = std::nan("");
  nan.size = Eigen::Vector3i::Ones();
  EXPECT_FALSE(nan.IsValid(&why));
  EXPECT_EQ(why.rfind("resolution", 0), 0u) << why;
}

TEST(OccupancyGridTest, IndexingAndStates) {
  const OccupancyGrid grid = SmallGrid();
  EXPECT_EQ(grid.StateAt(Eigen::Vector3d(-0.4, -0.2, 0.1)), VoxelState::kOccupied);
  EXPECT_EQ(grid.StateAt(Eigen::Vector3d(0.4, 0.4, 0.4)), VoxelState::kUnknown);
  EXPECT_EQ(grid.StateAt(Eigen::Vector3d(0.0, 0.0, 0.1)), VoxelState::kFree);
  EXPECT_EQ(grid.StateAt(Eigen::Vector3d(9, 9, 9)), VoxelState::kUnknown);
  EXPECT_EQ(grid.StateAt(Eigen::Vector3d(std::numeric_limits<double>::infinity(), 0, 0)),
            VoxelState::kUnknown);
  EXPECT_EQ(grid.IndexOf(Eigen::Vector3d(1e30, 0, 0)).x(), 2'000'000'000);
  EXPECT_TRUE(grid.CenterOf({0, 0, 0}).isApprox(Eigen::Vector3d(-0.375, -0.125, 0.125)));
  EXPECT_EQ(grid.Count(VoxelState::kFree), 22);
}

TEST(OccupancyIoTest, MavoccRoundTripIsExact) {
  const OccupancyGrid grid = SmallGrid();
  Result<OccupancyGrid> back = DecodeMavocc(EncodeMavocc(grid), "mem.mavocc");
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_TRUE(back->geometry().SameAs(grid.geometry()));
  EXPECT_EQ(back->states(), grid.states());
}

TEST(OccupancyIoTest, DecodeRefusesCorruptionAndHugeGridsByName) {
  std::string bytes = EncodeMavocc(SmallGrid());
  std::string flipped = bytes;
  flipped[80] ^= 1;
  Result<OccupancyGrid> r = DecodeMavocc(flipped, "map.mavocc");
  EXPECT_EQ(r.status().code(), StatusCode::kDataLoss);
  EXPECT_EQ(r.status().message(), "map.mavocc: checksum mismatch");
  EXPECT_EQ(DecodeMavocc(bytes.substr(0, 40), "map.mavocc").status().code(), StatusCode::kDataLoss);
  Result<OccupancyGrid> limited = DecodeMavocc(bytes, "map.mavocc", /*max_voxels=*/10);
  EXPECT_EQ(limited.status().code(), StatusCode::kResourceExhausted);
  EXPECT_EQ(ReadMavocc("/nonexistent/x.mavocc").status().code(), StatusCode::kNotFound);
}

TEST(OccupancyIoTest, OctomapBytesAreProduced) {
  Result<std::string> bt = EncodeOctomapBt(SmallGrid());
  ASSERT_TRUE(bt.ok()) << bt.status().ToString();
  EXPECT_EQ(bt->rfind("# Octomap OcTree binary file", 0), 0u);
}

}  // namespace
}  // namespace mav::dataset
