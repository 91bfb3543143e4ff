#include "mav/mapping/delaunay_graph_cut.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <set>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "mav/mapping/collision_eval.h"
#include "mav/mapping/mesh_to_grid.h"
#include "mav/mapping/synthetic_scene.h"

namespace mav::mapping {
namespace {

using Cell = std::array<int, 4>;
using Facet = std::array<int, 3>;

// ---------------------------------------------------------------------------------------------
// Line-of-sight traversal

// Hand-made: a = origin, b, c, d on the axes at 2, e = (3,3,3). Delaunay = two tetrahedra abcd and
// bcde (e lies outside abcd's circumsphere, centre (1,1,1) radius sqrt 3; a outside bcde's).
// The camera C = (4, 3.5, 3) looks at a: the segment C + s (a - C) enters the hull through the
// facet bce at s = 3/7 (point (2.29, 2.0, 1.71), barycentric u = 1/7, v = 4/7 in bce), crosses
// bcd at (0.76, 0.67, 0.57) and ends at a. Expected cells: the infinite cell on bce, bcde, abcd.
TEST(TraversalTest, HandMadeTwoTetrahedra) {
  const std::vector<Eigen::Vector3d> pts = {{0, 0, 0}, {2, 0, 0}, {0, 2, 0}, {0, 0, 2}, {3, 3, 3}};
  auto dt = DelaunayTetrahedralization::Create(pts);
  ASSERT_TRUE(dt.ok()) << dt.status().ToString();
  ASSERT_EQ(dt->num_finite_cells(), 2);
  const auto walk = dt->TraceLineOfSight(Eigen::Vector3d(4, 3.5, 3), 0, 0.01);
  ASSERT_EQ(walk.cells.size(), 3u);
  EXPECT_EQ(walk.cells[0], (Cell{-1, 1, 2, 4}));
  EXPECT_EQ(walk.cells[1], (Cell{1, 2, 3, 4}));
  EXPECT_EQ(walk.cells[2], (Cell{0, 1, 2, 3}));
  ASSERT_EQ(walk.crossed_facets.size(), 2u);
  EXPECT_EQ(walk.crossed_facets[0], (Facet{1, 2, 4}));
  EXPECT_EQ(walk.crossed_facets[1], (Facet{1, 2, 3}));
  EXPECT_EQ(walk.degenerate_steps, 0);
  // Behind a the ray leaves the hull through the vertex: the sink cell is an infinite cell (which
  // of the three infinite cells at a is the triangulation's choice).
  EXPECT_EQ(walk.behind_cell[0], -1);
  EXPECT_FALSE(walk.perturbed);

  // From outside straight into vertex a along (1, 0.9, 0.8): the segment touches the hull only at
  // a, so it visits infinite cells only and crosses no finite facet; behind a lies abcd.
  const auto walk2 = dt->TraceLineOfSight(Eigen::Vector3d(-1, -0.9, -0.8), 0, 0.01);
  for (const Cell& c : walk2.cells) EXPECT_EQ(c[0], -1);
  for (const Facet& f : walk2.crossed_facets) EXPECT_EQ(f[0], -1);
  EXPECT_EQ(walk2.behind_cell, (Cell{0, 1, 2, 3}));
  // With sigma = 0.5 the sink cell is the one containing a + 0.5 * direction: still abcd.
  EXPECT_EQ(dt->TraceLineOfSight(Eigen::Vector3d(-1, -0.9, -0.8), 0, 0.5).behind_cell,
            (Cell{0, 1, 2, 3}));
}

// Independent check: does the open segment (p, q) cross the triangle (a, b, c)? Moller-Trumbore
// in double precision, used only on random (non-degenerate) configurations.
bool SegmentCrossesTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& q,
                            const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                            const Eigen::Vector3d& c) {
  const Eigen::Vector3d d = q - p;
  const Eigen::Vector3d e1 = b - a, e2 = c - a;
  const Eigen::Vector3d h = d.cross(e2);
  const double det = e1.dot(h);
  if (std::abs(det) < 1e-14) return false;
  const Eigen::Vector3d s = p - a;
  const double u = s.dot(h) / det;
  if (u < 0 || u > 1) return false;
  const Eigen::Vector3d qv = s.cross(e1);
  const double v = d.dot(qv) / det;
  if (v < 0 || u + v > 1) return false;
  const double t = e2.dot(qv) / det;
  return t > 0 && t < 1;
}

TEST(TraversalTest, CrossedFacetsMatchSegmentTriangleIntersections) {
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 5; ++trial) {
    std::vector<Eigen::Vector3d> pts(30);
    for (auto& p : pts) p = Eigen::Vector3d(u(rng), u(rng), u(rng));
    auto dt = DelaunayTetrahedralization::Create(pts);
    ASSERT_TRUE(dt.ok());
    const auto facets = dt->FiniteFacets();
    for (int ray = 0; ray < 40; ++ray) {
      // Cameras both inside and outside the hull.
      const double scale = ray % 2 == 0 ? 0.8 : 3.0;
      const Eigen::Vector3d cam(scale * u(rng), scale * u(rng), scale * u(rng));
      const int target = static_cast<int>(rng() % pts.size());
      const auto walk = dt->TraceLineOfSight(cam, target, 0.01);
      ASSERT_EQ(walk.degenerate_steps, 0);
      ASSERT_EQ(walk.crossed_facets.size() + 1, walk.cells.size());
      // Every consecutive pair of cells shares exactly the crossed facet.
      for (size_t i = 0; i + 1 < walk.cells.size(); ++i) {
        std::vector<int> common;
        std::set_intersection(walk.cells[i].begin(), walk.cells[i].end(), walk.cells[i + 1].begin(),
                              walk.cells[i + 1].end(), std::back_inserter(common));
        ASSERT_EQ(common.size(), 3u);
        EXPECT_TRUE(std::equal(common.begin(), common.end(), walk.crossed_facets[i].begin()));
      }
      // The last cell has the target as a vertex.
      const Cell& last = walk.cells.back();
      EXPECT_NE(std::find(last.begin(), last.end(), target), last.end());
      std::set<Facet> walked;
      for (const Facet& f : walk.crossed_facets) {
        if (f[0] >= 0) walked.insert(f);
      }
      std::set<Facet> expected;
      for (const Facet& f : facets) {
        if (f[0] == target || f[1] == target || f[2] == target) continue;
        if (SegmentCrossesTriangle(cam, pts[target], pts[f[0]], pts[f[1]], pts[f[2]])) {
          expected.insert(f);
        }
      }
      EXPECT_EQ(walked, expected) << "trial " << trial << " ray " << ray;
    }
  }
}

// Degenerate: a cubic lattice (co-spherical everywhere) and rays along lattice lines that pass
// exactly through vertices and edges. The walk must terminate at the target and count the steps
// through edges/vertices instead of inventing facets.
TEST(TraversalTest, DegenerateRaysThroughVerticesAndEdges) {
  std::vector<Eigen::Vector3d> pts;
  for (int k = 0; k < 3; ++k)
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 3; ++i) pts.emplace_back(i, j, k);
  auto dt = DelaunayTetrahedralization::Create(pts);
  ASSERT_TRUE(dt.ok());
  // Along the x axis (a hull edge) through vertices 0 and 1 to (2,0,0) = index 2: CGAL's
  // traverser stops early here; the perturbation tie-break must reach the target.
  const auto w1 = dt->TraceLineOfSight(Eigen::Vector3d(-1, 0, 0), 2, 0.01);
  EXPECT_TRUE(w1.perturbed);
  EXPECT_FALSE(w1.cells.empty());
  EXPECT_NE(std::find(w1.cells.back().begin(), w1.cells.back().end(), 2), w1.cells.back().end());
  EXPECT_EQ(w1.crossed_facets.size() + w1.degenerate_steps + 1, w1.cells.size());
  // The main diagonal from outside to the far corner (2,2,2) = index 26 through vertices 0, 13.
  const auto w2 = dt->TraceLineOfSight(Eigen::Vector3d(-0.5, -0.5, -0.5), 26, 0.01);
  EXPECT_NE(std::find(w2.cells.back().begin(), w2.cells.back().end(), 26), w2.cells.back().end());
  EXPECT_EQ(w2.crossed_facets.size() + w2.degenerate_steps + 1, w2.cells.size());
  // A face diagonal inside the lattice through the edge midpoints: (0,0,1) -> (2,2,1) = 23.
  const auto w3 = dt->TraceLineOfSight(Eigen::Vector3d(0, 0, 1), 23, 0.01);
  EXPECT_NE(std::find(w3.cells.back().begin(), w3.cells.back().end(), 23), w3.cells.back().end());
}

TEST(TraversalTest, BadInput) {
  EXPECT_FALSE(DelaunayTetrahedralization::Create({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}).ok());
  const auto coplanar =
      DelaunayTetrahedralization::Create({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}, {2, 3, 0}});
  ASSERT_FALSE(coplanar.ok());
  EXPECT_NE(coplanar.status().message().find("coplanar"), std::string::npos);
  const auto nan = DelaunayTetrahedralization::Create({{0, 0, 0}, {1, NAN, 0}});
  ASSERT_FALSE(nan.ok());
  EXPECT_NE(nan.status().message().find("points[1]"), std::string::npos);
}

// ---------------------------------------------------------------------------------------------
// Meshing a box seen from rings of cameras

struct BoxScene {
  Eigen::Vector3d lo{0.01, 0.01, 0.01};
  Eigen::Vector3d hi{1.01, 0.81, 0.61};
  std::vector<MapPoint> points;
  std::vector<KeyframeView> keyframes;
};

BoxScene MakeBoxScene(int num_points, uint64_t seed) {
  BoxScene s;
  const Eigen::Vector3d center = 0.5 * (s.lo + s.hi);
  int id = 0;
  for (double z : {-0.8, 0.3, 1.4}) {
    for (int i = 0; i < 16; ++i) {
      const double a = 2.0 * M_PI * (i + 0.5 * (z > 0)) / 16.0;
      s.keyframes.push_back(
          {id++, center + Eigen::Vector3d(2.5 * std::cos(a), 2.5 * std::sin(a), z)});
    }
  }
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const Eigen::Vector3d ext = s.hi - s.lo;
  const double areas[3] = {ext.y() * ext.z(), ext.x() * ext.z(), ext.x() * ext.y()};
  const double total = 2 * (areas[0] + areas[1] + areas[2]);
  for (int n = 0; n < num_points; ++n) {
    double r = u(rng) * total;
    int face = 0;
    while (r > 2 * areas[face]) r -= 2 * areas[face++];
    const bool upper = r > areas[face];
    MapPoint p;
    for (int a = 0; a < 3; ++a) p.p_world[a] = s.lo[a] + u(rng) * ext[a];
    p.p_world[face] = upper ? s.hi[face] : s.lo[face];
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();
    normal[face] = upper ? 1.0 : -1.0;
    // Exact visibility for a convex box: the camera is in front of the point's face.
    for (const KeyframeView& k : s.keyframes) {
      const Eigen::Vector3d to = k.center_world - p.p_world;
      if (normal.dot(to) > 0.2 * to.norm()) p.keyframes.push_back(k.id);
    }
    s.points.push_back(p);
  }
  return s;
}

TEST(BuildMeshTest, BoxFromRingsOfCamerasIsClosedAndMatchesTheBox) {
  const BoxScene scene = MakeBoxScene(1500, 7);
  MeshingOptions options;
  // An object seen from all around: everything outside the hull of its points is free.
  options.force_infinite_cells_outside = true;
  const auto result = BuildMesh(scene.points, scene.keyframes, options);
  ASSERT_TRUE(result.ok()) << result.status().ToString();
  const MeshingResult& m = *result;
  EXPECT_GT(m.stats.num_rays, 1500);
  EXPECT_GT(m.mesh.triangles.size(), 500u);

  // Closed and consistently oriented: every directed edge appears once, its reverse once.
  std::map<std::pair<int, int>, int> directed;
  for (const Eigen::Vector3i& t : m.mesh.triangles) {
    for (int i = 0; i < 3; ++i) ++directed[{t[i], t[(i + 1) % 3]}];
  }
  int bad_edges = 0, non_manifold = 0, open = 0;
  for (const auto& [edge, count] : directed) {
    const auto rev = directed.find({edge.second, edge.first});
    if (count != 1 || rev == directed.end() || rev->second != 1) ++bad_edges;
    non_manifold += count > 1;
    open += rev == directed.end();
  }
  std::printf(
      "box: %zu triangles, %lld rays, %d inside cells, flow %.1f, perturbed %lld, failed %lld, "
      "bad edges %d (non-manifold %d, open %d)\n",
      m.mesh.triangles.size(), static_cast<long long>(m.stats.num_rays), m.stats.num_inside_cells,
      m.stats.max_flow, static_cast<long long>(m.stats.perturbed_walks),
      static_cast<long long>(m.stats.failed_walks), bad_edges, non_manifold, open);
  EXPECT_EQ(bad_edges, 0);
  // Outward orientation: the signed volume (divergence theorem) is the box volume, positive.
  double volume = 0.0;
  for (const Eigen::Vector3i& t : m.mesh.triangles) {
    volume += m.mesh.vertices[t[0]].dot(m.mesh.vertices[t[1]].cross(m.mesh.vertices[t[2]])) / 6.0;
  }
  const Eigen::Vector3d ext = scene.hi - scene.lo;
  const double box_volume = ext.prod();
  EXPECT_NEAR(volume, box_volume, 0.05 * box_volume);

  // Occupancy at 0.05 m against the exact box (voxel cube overlaps the box with positive volume).
  const GridGeometry g = GridGeometryAround(scene.points, scene.keyframes, 0.05, 0.2);
  MeshToGridOptions grid_options;
  grid_options.occupy_surface_voxels = true;  // the faces lie inside voxels: count them
  const auto grid = MeshToOccupancy(m, scene.points, scene.keyframes, g, grid_options);
  ASSERT_TRUE(grid.ok());
  int64_t inter = 0, uni = 0;
  for (int k = 0; k < g.size.z(); ++k)
    for (int j = 0; j < g.size.y(); ++j)
      for (int i = 0; i < g.size.x(); ++i) {
        const Eigen::Vector3d lo = g.origin + Eigen::Vector3d(i, j, k) * g.resolution;
        const Eigen::Vector3d hi = lo + Eigen::Vector3d::Constant(g.resolution);
        const bool truth =
            (lo.array() < scene.hi.array()).all() && (hi.array() > scene.lo.array()).all();
        const bool occ = grid->at({i, j, k}) == VoxelState::kOccupied;
        inter += truth && occ;
        uni += truth || occ;
      }
  const double iou = static_cast<double>(inter) / static_cast<double>(uni);
  std::printf("box: signed volume %.4f (box %.4f), IoU %.3f\n", volume, box_volume, iou);
  EXPECT_GE(iou, 0.85) << "IoU " << iou;
  // Between the cameras and the box the lines of sight carved free space.
  EXPECT_EQ(grid->StateAt(Eigen::Vector3d(-0.5, 0.4, 0.3)), VoxelState::kFree);
}

TEST(BuildMeshTest, BadInputNamesTheField) {
  BoxScene scene = MakeBoxScene(50, 1);
  MeshingOptions options;
  options.lambda_quality = -1;
  auto r = BuildMesh(scene.points, scene.keyframes, options);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("lambda_quality"), std::string::npos);
  auto points = scene.points;
  points[3].keyframes.push_back(999);
  r = BuildMesh(points, scene.keyframes);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("points[3]"), std::string::npos);
  points = scene.points;
  points[4].p_world.x() = NAN;
  r = BuildMesh(points, scene.keyframes);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("points[4]"), std::string::npos);
  auto keyframes = scene.keyframes;
  keyframes[1].id = keyframes[0].id;
  r = BuildMesh(scene.points, keyframes);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("keyframes[1].id"), std::string::npos);
  EXPECT_FALSE(BuildMesh({}, {}).ok());
  // Duplicates are merged, not an error.
  points = scene.points;
  points.push_back(points[0]);
  r = BuildMesh(points, scene.keyframes);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->stats.num_duplicate_points, 1);
}

// The synthetic room observed from `num_keyframes` keyframes, 100 points each, with its exact
// ground-truth grid at 5 cm.
struct RoomCase {
  std::vector<MapPoint> points;
  std::vector<KeyframeView> keyframes;
  GridGeometry g;
  OccupancyGrid truth;
};

RoomCase MakeRoomCase(int num_keyframes) {
  RoomCase r;
  const SyntheticScene scene = MakeRoomScene();
  SyntheticObservationOptions obs;
  obs.num_keyframes = num_keyframes;
  obs.points_per_keyframe = 100;
  SampleRoomObservations(scene, obs, &r.points, &r.keyframes);
  r.g.origin = Eigen::Vector3d(-0.2, -0.2, -0.2);
  r.g.resolution = 0.05;
  r.g.size = Eigen::Vector3i(168, 128, 68);
  r.truth = scene.TruthGrid(r.g);
  return r;
}

// The synthetic room end to end: mesh -> grid -> collision MCC against the exact ground truth.
TEST(BuildMeshTest, SyntheticRoomCollisionMcc) {
  const RoomCase room = MakeRoomCase(120);
  const std::vector<MapPoint>& points = room.points;
  const std::vector<KeyframeView>& keyframes = room.keyframes;
  const GridGeometry& g = room.g;
  const OccupancyGrid& truth = room.truth;
  const auto meshing = BuildMesh(points, keyframes);
  ASSERT_TRUE(meshing.ok());
  const auto grid = MeshToOccupancy(*meshing, points, keyframes, g);
  ASSERT_TRUE(grid.ok());
  const auto eval = EvaluateCollisions(truth, *grid);
  ASSERT_TRUE(eval.ok());
  std::printf(
      "room: %d points, %lld rays, %d cells, %.2f s; MCC %.3f  FC %.2f MC %.2f CC %.2f CF %.2f\n",
      static_cast<int>(points.size()), static_cast<long long>(meshing->stats.num_rays),
      meshing->stats.num_finite_cells, meshing->stats.total_s, eval->Mcc(),
      eval->Percent(eval->false_collision), eval->Percent(eval->missed_collision),
      eval->Percent(eval->correct_collision), eval->Percent(eval->correct_free));
  EXPECT_GE(eval->Mcc(), 0.85);
}

// Weakly supported surfaces (Jancosek and Pajdla 2011): the support-jump test finds the points in
// front of the room's walls (no line of sight crosses the space behind them); the extra sink
// weight thickens what the cut labels inside, so missed collisions drop and false ones rise (the
// trade measured on the rendered rooms, docs/mapping.md); the options are validated.
TEST(BuildMeshTest, WeakSurfaceSupportJumps) {
  const RoomCase room = MakeRoomCase(60);
  const std::vector<MapPoint>& points = room.points;
  const std::vector<KeyframeView>& keyframes = room.keyframes;
  const GridGeometry& g = room.g;
  const OccupancyGrid& truth = room.truth;
  double mcc[2] = {0, 0}, missed[2] = {0, 0}, false_coll[2] = {0, 0};
  int64_t jumps[2] = {0, 0}, rays = 0;
  int inside[2] = {0, 0};
  for (int on = 0; on < 2; ++on) {
    const MeshingOptions options =
        MeshingOptionsFor(on ? MapPreference::kSafety : MapPreference::kMcc);
    const auto meshing = BuildMesh(points, keyframes, options);
    ASSERT_TRUE(meshing.ok()) << meshing.status().ToString();
    const auto grid = MeshToOccupancy(*meshing, points, keyframes, g);
    ASSERT_TRUE(grid.ok());
    const auto eval = EvaluateCollisions(truth, *grid);
    ASSERT_TRUE(eval.ok());
    mcc[on] = eval->Mcc();
    missed[on] = eval->Percent(eval->missed_collision);
    false_coll[on] = eval->Percent(eval->false_collision);
    jumps[on] = meshing->stats.weak_surface_rays;
    inside[on] = meshing->stats.num_inside_cells;
    rays = meshing->stats.num_rays;
  }
  std::printf(
      "weak surfaces: %lld of %lld lines of sight at a support jump; inside cells %d -> %d, MCC "
      "%.3f -> %.3f, missed %.2f -> %.2f %%, false %.2f -> %.2f %%\n",
      static_cast<long long>(jumps[1]), static_cast<long long>(rays), inside[0], inside[1], mcc[0],
      mcc[1], missed[0], missed[1], false_coll[0], false_coll[1]);
  EXPECT_EQ(jumps[0], 0);
  EXPECT_GT(jumps[1], rays / 4);
  EXPECT_LT(jumps[1], rays);
  EXPECT_GT(inside[1], inside[0]);
  EXPECT_LT(missed[1], missed[0]);
  EXPECT_GT(mcc[1], 0.5);  // a trade, not a collapse: the camera cells stay free

  // Only points seen by enough keyframes get the extra weight.
  int max_views = 0;
  for (const MapPoint& p : points)
    max_views = std::max(max_views, static_cast<int>(p.keyframes.size()));
  MeshingOptions options = MeshingOptionsFor(MapPreference::kSafety);
  int64_t few_view_jumps[2] = {0, 0};
  for (int i = 0; i < 2; ++i) {
    options.weak_surface_min_views = i == 0 ? 2 : max_views + 1;
    const auto meshing = BuildMesh(points, keyframes, options);
    ASSERT_TRUE(meshing.ok()) << meshing.status().ToString();
    few_view_jumps[i] = meshing->stats.weak_surface_rays;
  }
  EXPECT_GT(few_view_jumps[0], 0);
  EXPECT_LT(few_view_jumps[0], jumps[1]);
  EXPECT_EQ(few_view_jumps[1], 0);

  MeshingOptions bad;
  bad.weak_surface_min_views = 0;
  auto r0 = BuildMesh(points, keyframes, bad);
  ASSERT_FALSE(r0.ok());
  EXPECT_NE(r0.status().message().find("weak_surface_min_views"), std::string::npos);
  bad = MeshingOptions();
  bad.weak_surface_ratio = 1.5;
  auto r = BuildMesh(points, keyframes, bad);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("weak_surface_ratio"), std::string::npos);
  bad = MeshingOptions();
  bad.weak_surface_depth = 0.5 * bad.sigma;
  r = BuildMesh(points, keyframes, bad);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("weak_surface_depth"), std::string::npos);
}

}  // namespace
}  // namespace mav::mapping
