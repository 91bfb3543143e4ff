#include "mav/mapping/mesh_to_grid.h"

#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "mav/common/check.h"

namespace mav::mapping {
namespace {

// A meshing result of one inside-labelled tetrahedron with these corners.
MeshingResult OneInsideTetrahedron(std::vector<Eigen::Vector3d> corners) {
  MeshingResult m;
  m.points = std::move(corners);
  Tetrahedron t;
  t.vertices = {0, 1, 2, 3};
  t.inside = true;
  m.tetrahedra.push_back(t);
  return m;
}

// 20^3 voxels of 0.1 m around the unit corner of the tetrahedron tests.
GridGeometry UnitCornerGrid() {
  GridGeometry g;
  g.origin = Eigen::Vector3d(-0.5, -0.5, -0.5);
  g.resolution = 0.1;
  g.size = Eigen::Vector3i(20, 20, 20);
  return g;
}

// One inside tetrahedron spanning the unit corner: voxel centres with x + y + z <= 1 (all
// coordinates positive) are occupied; the surface triangles touch the rest of its boundary cubes.
TEST(MeshToOccupancyTest, SingleTetrahedron) {
  const MeshingResult m = OneInsideTetrahedron({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}});
  const GridGeometry g = UnitCornerGrid();
  MeshToGridOptions options;
  options.carve_lines_of_sight = false;
  const auto grid = MeshToOccupancy(m, {}, {}, g, options);
  ASSERT_TRUE(grid.ok()) << grid.status().ToString();
  int64_t expected = 0;
  for (int k = 0; k < 20; ++k)
    for (int j = 0; j < 20; ++j)
      for (int i = 0; i < 20; ++i) {
        const Eigen::Vector3d c = grid->CenterOf({i, j, k});
        const bool in = (c.array() >= 0).all() && c.sum() <= 1.0;
        expected += in;
        if (in) {
          ASSERT_EQ(grid->at({i, j, k}), VoxelState::kOccupied) << i << " " << j << " " << k;
        } else {
          ASSERT_EQ(grid->at({i, j, k}), VoxelState::kUnknown);
        }
      }
  EXPECT_EQ(grid->Count(VoxelState::kOccupied), expected);
  EXPECT_GT(expected, 100);
}

// Rule 3 off (a map of a partly seen scene): the inside cell stays unknown, its surface triangles
// still occupy the voxels they touch.
TEST(MeshToOccupancyTest, InsideCellsLeftUnknownKeepTheirSurface) {
  MeshingResult m = OneInsideTetrahedron({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}});
  m.mesh.vertices = m.points;
  m.mesh.triangles = {{1, 2, 3}};  // the slanted face x + y + z = 1
  const GridGeometry g = UnitCornerGrid();
  MeshToGridOptions options;
  options.carve_lines_of_sight = false;
  options.occupy_surface_voxels = true;
  options.occupy_inside_cells = false;
  const auto grid = MeshToOccupancy(m, {}, {}, g, options);
  ASSERT_TRUE(grid.ok()) << grid.status().ToString();
  EXPECT_EQ(grid->StateAt({0.12, 0.12, 0.12}), VoxelState::kUnknown);   // deep inside
  EXPECT_EQ(grid->StateAt({0.34, 0.34, 0.34}), VoxelState::kOccupied);  // on the face
  options.occupy_inside_cells = true;
  const auto full = MeshToOccupancy(m, {}, {}, g, options);
  ASSERT_TRUE(full.ok());
  EXPECT_EQ(full->StateAt({0.12, 0.12, 0.12}), VoxelState::kOccupied);
  EXPECT_GT(full->Count(VoxelState::kOccupied), grid->Count(VoxelState::kOccupied));
}

TEST(MeshToOccupancyTest, SurfaceTrianglesAndCarving) {
  MeshingResult m;
  m.points = {{0.02, 0.02, 0.5}, {0.98, 0.02, 0.5}, {0.02, 0.98, 0.5}};
  m.mesh.vertices = m.points;
  m.mesh.triangles = {{0, 1, 2}};
  GridGeometry g;
  g.origin = Eigen::Vector3d(0, 0, 0);
  g.resolution = 0.1;
  g.size = Eigen::Vector3i(10, 10, 10);
  std::vector<MapPoint> points(1);
  points[0].p_world = Eigen::Vector3d(0.55, 0.55, 0.05);
  points[0].keyframes = {7};
  std::vector<KeyframeView> keyframes(1);
  keyframes[0].id = 7;
  keyframes[0].center_world = Eigen::Vector3d(0.55, 0.55, 0.95);
  MeshToGridOptions options;
  options.occupy_surface_voxels = true;
  const auto grid = MeshToOccupancy(m, points, keyframes, g, options);
  ASSERT_TRUE(grid.ok());
  // The plane z = 0.5 lies on a voxel boundary: both layers 4 and 5 touch the triangle.
  EXPECT_EQ(grid->at({1, 1, 4}), VoxelState::kOccupied);
  EXPECT_EQ(grid->at({1, 1, 5}), VoxelState::kOccupied);
  EXPECT_EQ(grid->at({9, 9, 4}), VoxelState::kUnknown);  // beyond the hypotenuse
  // The line of sight x = y = 0.55 from z = 0.95 down to 0.05 frees layers 9..1 (carving stops
  // one voxel before the point); the voxel cubes (5, 5, 4/5) touch the triangle's hypotenuse
  // x + y = 1 at their corner, so the surface rule re-occupies them.
  EXPECT_EQ(grid->at({5, 5, 4}), VoxelState::kOccupied);
  EXPECT_EQ(grid->at({5, 5, 1}), VoxelState::kFree);
  EXPECT_EQ(grid->at({5, 5, 9}), VoxelState::kFree);
  EXPECT_EQ(grid->at({5, 5, 2}), VoxelState::kFree);
  EXPECT_EQ(grid->at({5, 5, 0}), VoxelState::kUnknown);  // the point's own voxel
  EXPECT_EQ(grid->at({4, 5, 9}), VoxelState::kUnknown);
}

// A thick line of sight frees the unknown voxels next to its voxels up to thick_stop_m before the
// point, then only its own voxels; it never frees an occupied voxel.
TEST(MeshToOccupancyTest, ThickLinesOfSight) {
  // An inside tetrahedron near (0.25, 0.6, 0.6): occupied voxels next to the ray.
  const MeshingResult m = OneInsideTetrahedron(
      {{0.12, 0.62, 0.62}, {0.38, 0.62, 0.62}, {0.25, 0.72, 0.45}, {0.25, 0.52, 0.72}});
  GridGeometry g;
  g.origin = Eigen::Vector3d(0, 0, 0);
  g.resolution = 0.1;
  g.size = Eigen::Vector3i(20, 10, 10);
  std::vector<MapPoint> points(1);
  points[0].p_world = Eigen::Vector3d(1.85, 0.55, 0.55);  // voxel (18, 5, 5)
  points[0].keyframes = {3};
  std::vector<KeyframeView> keyframes(1);
  keyframes[0].id = 3;
  keyframes[0].center_world = Eigen::Vector3d(0.05, 0.55, 0.55);  // voxel (0, 5, 5)
  MeshToGridOptions options;
  options.carve_radius_voxels = 1;
  options.thick_stop_m = 0.5;
  const auto grid = MeshToOccupancy(m, points, keyframes, g, options);
  ASSERT_TRUE(grid.ok()) << grid.status().ToString();
  const int64_t occupied = grid->Count(VoxelState::kOccupied);
  ASSERT_GT(occupied, 0);
  for (int i = 0; i < 20; ++i) {
    SCOPED_TRACE("i = " + std::to_string(i));
    // Thick part: voxel i is entered at t = (0.1 i - 0.05) / 1.8 < 1 - 0.5 / 1.8 for i <= 13,
    // and the neighbourhood of voxel 13 reaches x = 14.
    const bool thick = i <= 14;
    for (int j = 3; j <= 7; ++j) {
      for (int k = 3; k <= 7; ++k) {
        const VoxelState s = grid->at({i, j, k});
        if (s == VoxelState::kOccupied) continue;  // never freed
        const bool on_ray = j == 5 && k == 5 && i <= 17;
        const bool near = std::abs(j - 5) <= 1 && std::abs(k - 5) <= 1;
        const bool expect_free = on_ray || (thick && near);
        EXPECT_EQ(s, expect_free ? VoxelState::kFree : VoxelState::kUnknown) << j << " " << k;
      }
    }
  }
  EXPECT_EQ(grid->Count(VoxelState::kOccupied), occupied);
  EXPECT_EQ(grid->at({18, 5, 5}), VoxelState::kUnknown);  // the point's own voxel
  options.carve_radius_voxels = -1;
  const auto bad = MeshToOccupancy(m, points, keyframes, g, options);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("carve_radius_voxels"), std::string::npos);
}

// A large outside tetrahedron (free space) with a small inside one in it, and one line of sight.
struct FreeCellScene {
  MeshingResult meshing;
  GridGeometry geometry;
  std::vector<MapPoint> points;
  std::vector<KeyframeView> keyframes;

  FreeCellScene() {
    meshing.points = {{0, 0, 0},       {2, 0, 0},       {0, 2, 0},       {0, 0, 2},
                      {0.3, 0.3, 0.3}, {0.6, 0.3, 0.3}, {0.3, 0.6, 0.3}, {0.3, 0.3, 0.6}};
    Tetrahedron outside;
    outside.vertices = {0, 1, 2, 3};
    outside.inside = false;
    Tetrahedron inside;
    inside.vertices = {4, 5, 6, 7};
    inside.inside = true;
    meshing.tetrahedra = {outside, inside};
    geometry.origin = Eigen::Vector3d(-0.1, -0.1, -0.1);
    geometry.resolution = 0.1;
    geometry.size = Eigen::Vector3i(22, 22, 22);
    points.resize(1);
    points[0].p_world = Eigen::Vector3d(1.2, 0.15, 0.15);
    points[0].keyframes = {1};
    keyframes.resize(1);
    keyframes[0].id = 1;
    keyframes[0].center_world = Eigen::Vector3d(0.05, 0.15, 0.15);
  }
  OccupancyGrid Run(const MeshToGridOptions& options) const {
    auto grid = MeshToOccupancy(meshing, points, keyframes, geometry, options);
    MAV_CHECK(grid.ok()) << grid.status().ToString();
    return *std::move(grid);
  }
};

bool WithinChebyshev(const OccupancyGrid& grid, const Eigen::Vector3i& idx, int r,
                     const std::function<bool(const Eigen::Vector3i&)>& pred) {
  for (int dk = -r; dk <= r; ++dk)
    for (int dj = -r; dj <= r; ++dj)
      for (int di = -r; di <= r; ++di) {
        const Eigen::Vector3i n = idx + Eigen::Vector3i(di, dj, dk);
        if (grid.InBounds(n) && pred(n)) return true;
      }
  return false;
}

// Compares every voxel of the scene's 22^3 grid with `plain`, or with the state `changed` gives
// a voxel it changes. Returns how many voxels `changed` changed; stops at the first mismatch (a
// test failure naming the voxel).
int64_t ExpectPlainExcept(
    const OccupancyGrid& grid, const OccupancyGrid& plain,
    const std::function<std::optional<VoxelState>(const Eigen::Vector3i&)>& changed) {
  int64_t count = 0;
  for (int k = 0; k < 22; ++k)
    for (int j = 0; j < 22; ++j)
      for (int i = 0; i < 22; ++i) {
        const Eigen::Vector3i idx(i, j, k);
        const std::optional<VoxelState> change = changed(idx);
        count += change.has_value();
        const VoxelState expected = change.value_or(plain.at(idx));
        if (grid.at(idx) != expected) {
          ADD_FAILURE() << "voxel " << i << " " << j << " " << k << ": state "
                        << static_cast<int>(grid.at(idx)) << ", expected "
                        << static_cast<int>(expected);
          return count;
        }
      }
  return count;
}

TEST(MeshToOccupancyTest, SafetyMarginOccupiesFreeVoxelsNextToOccupiedOnes) {
  const FreeCellScene scene;
  const OccupancyGrid plain = scene.Run({});
  ASSERT_GT(plain.Count(VoxelState::kOccupied), 0);
  for (int margin : {1, 2}) {
    SCOPED_TRACE("margin " + std::to_string(margin));
    MeshToGridOptions options;
    options.occupied_margin_voxels = margin;
    const int64_t grown =
        ExpectPlainExcept(scene.Run(options), plain, [&](const Eigen::Vector3i& idx) {
          const bool grows = plain.at(idx) == VoxelState::kFree &&
                             WithinChebyshev(plain, idx, margin, [&](const Eigen::Vector3i& n) {
                               return plain.at(n) == VoxelState::kOccupied;
                             });
          return grows ? std::optional(VoxelState::kOccupied) : std::nullopt;
        });
    EXPECT_GT(grown, 0);
  }
  MeshToGridOptions bad;
  bad.occupied_margin_voxels = 9;
  auto r = MeshToOccupancy(scene.meshing, scene.points, scene.keyframes, scene.geometry, bad);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("occupied_margin_voxels"), std::string::npos);
}

TEST(MeshToOccupancyTest, FreeCellsOnlyNearALineOfSight) {
  const FreeCellScene scene;
  const OccupancyGrid plain = scene.Run({});
  FreeCellScene ray_only = scene;
  ray_only.meshing.tetrahedra.clear();
  const OccupancyGrid ray = ray_only.Run({});  // free = the line of sight's voxels
  ASSERT_GT(ray.Count(VoxelState::kFree), 5);
  for (int r : {0, 1, 3}) {
    SCOPED_TRACE("radius " + std::to_string(r));
    MeshToGridOptions options;
    options.free_near_ray_voxels = r;
    const int64_t dropped =
        ExpectPlainExcept(scene.Run(options), plain, [&](const Eigen::Vector3i& idx) {
          const bool on_ray = ray.at(idx) == VoxelState::kFree;
          const bool drops = plain.at(idx) == VoxelState::kFree && !on_ray &&
                             !WithinChebyshev(plain, idx, r, [&](const Eigen::Vector3i& n) {
                               return ray.at(n) == VoxelState::kFree;
                             });
          return drops ? std::optional(VoxelState::kUnknown) : std::nullopt;
        });
    EXPECT_GT(dropped, 0);
  }
  MeshToGridOptions bad;
  bad.free_near_ray_voxels = -2;
  auto r = MeshToOccupancy(scene.meshing, scene.points, scene.keyframes, scene.geometry, bad);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("free_near_ray_voxels"), std::string::npos);
}

TEST(MeshToOccupancyTest, BadInput) {
  MeshingResult m;
  m.points = {{0, 0, 0}};
  Tetrahedron t;
  t.vertices = {0, 1, 2, 3};
  m.tetrahedra.push_back(t);
  GridGeometry g;
  g.size = Eigen::Vector3i(4, 4, 4);
  auto r = MeshToOccupancy(m, {}, {}, g);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("tetrahedra[0]"), std::string::npos);
  g.resolution = -1;
  r = MeshToOccupancy(MeshingResult{}, {}, {}, g);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("resolution"), std::string::npos);
}

TEST(GridGeometryAroundTest, CoversInputWithPadding) {
  std::vector<MapPoint> points(2);
  points[0].p_world = Eigen::Vector3d(0.03, -1.0, 2.0);
  points[1].p_world = Eigen::Vector3d(1.0, 1.0, 2.5);
  std::vector<KeyframeView> keyframes(1);
  keyframes[0].center_world = Eigen::Vector3d(0.5, 0.0, 4.0);
  const GridGeometry g = GridGeometryAround(points, keyframes, 0.05, 0.2);
  EXPECT_NEAR(g.origin.x(), -0.2, 1e-9);
  EXPECT_NEAR(g.origin.y(), -1.2, 1e-9);
  EXPECT_NEAR(g.origin.z(), 1.8, 1e-9);
  const Eigen::Vector3d top = g.origin + g.size.cast<double>() * g.resolution;
  EXPECT_GE(top.x(), 1.2 - 1e-9);
  EXPECT_GE(top.z(), 4.2 - 1e-9);
}

// A slab of occupied voxels at z in [1.0, 1.2) between a camera at the origin and points above it:
// the ones behind the slab, beyond the margin, were seen through it.
TEST(PointsSeenThroughSurfacesTest, FlagsPointsBehindAnOccupiedSlab) {
  GridGeometry g;
  g.origin = Eigen::Vector3d(-1, -1, -0.5);
  g.resolution = 0.1;
  g.size = Eigen::Vector3i(20, 20, 30);  // z up to 2.5
  OccupancyGrid grid(g, VoxelState::kFree);
  for (int k = 15; k < 17; ++k)
    for (int j = 0; j < 20; ++j)
      for (int i = 0; i < 20; ++i) grid.set(Eigen::Vector3i(i, j, k), VoxelState::kOccupied);
  const std::vector<KeyframeView> keyframes = {{7, Eigen::Vector3d(0.01, 0.02, 0.0)},
                                               {9, Eigen::Vector3d(0.01, 0.02, 1.5)}};
  std::vector<MapPoint> points = {
      {Eigen::Vector3d(0.05, 0.05, 1.8), {7}},     // behind the slab: seen through it
      {Eigen::Vector3d(0.05, 0.05, 0.9), {7}},     // in front of it
      {Eigen::Vector3d(0.05, 0.05, 1.25), {7}},    // the slab is within the margin before it
      {Eigen::Vector3d(0.05, 0.05, 1.8), {9}},     // seen from above the slab
      {Eigen::Vector3d(0.05, 0.05, 1.8), {9, 7}},  // one of its lines of sight crosses it
      {Eigen::Vector3d(5.0, 5.0, 5.0), {7}},       // outside the grid: only free voxels crossed
  };
  auto seen = PointsSeenThroughSurfaces(grid, points, keyframes, 0.3);
  ASSERT_TRUE(seen.ok()) << seen.status().ToString();
  EXPECT_EQ(*seen, (std::vector<bool>{true, false, false, false, true, false}));
  // Without a margin the third point's line of sight reaches the slab too.
  seen = PointsSeenThroughSurfaces(grid, points, keyframes, 0.0);
  ASSERT_TRUE(seen.ok());
  EXPECT_TRUE((*seen)[2]);
  EXPECT_FALSE((*seen)[1]);

  points.push_back({Eigen::Vector3d(0, 0, 1), {8}});
  seen = PointsSeenThroughSurfaces(grid, points, keyframes, 0.3);
  ASSERT_FALSE(seen.ok());
  EXPECT_EQ(seen.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(seen.status().message().find("points[6].keyframes[0]: unknown keyframe id 8"),
            std::string::npos)
      << seen.status().message();
  seen = PointsSeenThroughSurfaces(grid, {}, keyframes, -0.1);
  ASSERT_FALSE(seen.ok());
  EXPECT_NE(seen.status().message().find("margin_m"), std::string::npos);
}

}  // namespace
}  // namespace mav::mapping
