#pragma once
// Conversion of the labelled tetrahedralization (delaunay_graph_cut.h) into an occupancy grid, the
// representation the paper evaluates (Holzmann et al. 2015, Section 2.2).
//
// Rules, applied in this order (later rules override earlier ones):
//  1. every voxel starts kUnknown;
//  2. a voxel whose centre lies in an outside-labelled finite tetrahedron is kFree (with
//     `free_requires_traversal`, only if a line of sight crossed that tetrahedron; else kUnknown);
//  3. a voxel whose centre lies in an inside-labelled finite tetrahedron is kOccupied (with
//     `occupy_inside_cells` off it stays as it is: a map of a partly seen scene, where the graph
//     cut labels unexplored space inside, keeps only its surfaces, rule 5);
//  4. with `carve_lines_of_sight`, voxels still kUnknown that a line of sight crosses (camera to
//     one voxel short of the point, 3D DDA) become kFree: this is the observed free space outside
//     the convex hull of the points, e.g. between the cameras and an object seen from around it.
//     With `carve_radius_voxels` = r > 0 the ray is thick: the kUnknown voxels within r voxels
//     (Chebyshev distance) of the ray's voxel become kFree too, up to `thick_stop_m` before the
//     point (the last part of the ray stays thin so the surface behind the point is not eaten).
//     A line of sight samples a thin cone, not a line: the small outside cells just in front of a
//     surface that no ray's centre line crossed are free space the cameras saw;
//  5. with `occupy_surface_voxels`, every voxel whose cube touches a surface triangle is kOccupied
//     (exact triangle/box overlap), so thin structures survive whatever the centre sampling missed.
// Space outside the convex hull of the points that no line of sight crossed stays kUnknown: the
// graph cut's label of an infinite cell is not a bounded volume. The collision evaluation decides
// how unknown counts (collision_eval.h; mav-eval counts it as occupied, as the paper does for
// OctoMap).

#include <string>
#include <vector>

#include "mav/common/status.h"
#include "mav/mapping/delaunay_graph_cut.h"
#include "mav/mapping/types.h"

namespace mav::mapping {

struct MeshToGridOptions {
  bool free_requires_traversal = false;
  bool occupy_inside_cells = true;  // rule 3
  bool carve_lines_of_sight = true;
  // Rule 5 on/off. Off by default: it keeps structures thinner than a voxel but thickens every
  // surface by up to one voxel, which cost 0.04-0.06 MCC on the synthetic room (docs/mapping.md).
  bool occupy_surface_voxels = false;
  // Rule 4's ray radius [voxels, >= 0] and where its thick part ends [m before the point, >= 0].
  int carve_radius_voxels = 0;
  double thick_stop_m = 0.2;
  // Voxels of outside cells are free only within this many voxels of a line of sight's centre
  // line (-1: every voxel of a free cell, as rule 2 says; 0..8 otherwise). Needs
  // carve_lines_of_sight.
  int free_near_ray_voxels = -1;
  // Rule 6, a safety margin [voxels, 0..8]: free voxels within this Chebyshev distance of an
  // occupied voxel become occupied (a planner's clearance built into the map).
  int occupied_margin_voxels = 0;

  bool IsValid(std::string* why) const;
};

// An axis-aligned grid at `resolution` [m] covering all points and camera centres plus `padding`
// [m] on every side, its origin snapped to a multiple of the resolution. MAV_CHECKs resolution > 0.
GridGeometry GridGeometryAround(const std::vector<MapPoint>& points,
                                const std::vector<KeyframeView>& keyframes,
                                double resolution = 0.05, double padding = 0.2);

// Rasterises `meshing` into a grid of the given geometry (pass the ground-truth grid's geometry to
// compare voxel by voxel). `points` and `keyframes` give the lines of sight of rule 4: the points
// given to BuildMesh, or a superset (e.g. SparsePointCloud::SightPoints(): also the lines of sight
// of the single-view points the verification left out of the mesh and of the verified stereo
// matches that were not selected as points).
// With 40 000 or more points the lines of sight are traced on two threads (same result).
// INVALID_ARGUMENT for an invalid geometry/options or tetrahedra that index outside `points`.
Result<OccupancyGrid> MeshToOccupancy(const MeshingResult& meshing,
                                      const std::vector<MapPoint>& points,
                                      const std::vector<KeyframeView>& keyframes,
                                      const GridGeometry& geometry,
                                      const MeshToGridOptions& options = {});

// The points seen through a surface of `grid`: true for a point one of whose lines of sight
// (keyframe centre to point, 3D DDA) crosses an occupied voxel more than `margin_m` before the
// point. Such a point cannot have been seen where it is: a stereo mismatch triangulated behind the
// surface, e.g. on a textureless ceiling (the pipeline's occlusion check, pipeline.h). Voxels
// outside the grid count as not occupied. INVALID_ARGUMENT for a margin that is negative or not
// finite, or an unknown keyframe id ("points[i].keyframes[j]: ...").
Result<std::vector<bool>> PointsSeenThroughSurfaces(const OccupancyGrid& grid,
                                                    const std::vector<MapPoint>& points,
                                                    const std::vector<KeyframeView>& keyframes,
                                                    double margin_m);

}  // namespace mav::mapping
