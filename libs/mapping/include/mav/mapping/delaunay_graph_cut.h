#pragma once
// Multi-view meshing of a sparse point cloud with visibility, after
//   P. Labatut, J.-P. Pons, R. Keriven, "Efficient multi-view reconstruction of large-scale scenes
//   using interest points, Delaunay triangulation and graph cuts", ICCV 2007,
// as used for mapping by Holzmann et al., "Performance Evaluation of Vision-Based Algorithms for
// MAVs" (OAGM 2015), Section 2.2.
//
// Method (docs/mapping.md has the details and the reasons for each choice):
//  1. 3D Delaunay triangulation of the points (CGAL, exact predicates / inexact constructions).
//  2. An s-t graph whose nodes are ALL tetrahedra, the infinite ones (outside the convex hull)
//     included; source = free/outside, sink = occupied/inside. Infinite cells are ordinary nodes
//     by default: in a room the solid behind the walls lies outside the hull of the points, and
//     forcing it free would erase the walls (MeshingOptions::force_infinite_cells_outside).
//  3. Visibility term, for every line of sight (segment camera centre -> point it saw), walked
//     cell by cell with CGAL's exact segment traverser:
//       * source link alpha_vis on the cell containing the camera centre,
//       * alpha_vis on every facet crossed from the camera up to the point, on the directed edge
//         camera-side cell -> far-side cell (cutting it = "the surface occludes the point"),
//       * sink link alpha_vis on the cell containing the point moved `sigma` behind itself along
//         the ray (small sigma: the first cell the ray enters after passing the point).
//     A ray that passes exactly through an edge or a vertex enters the next cell through no facet;
//     that step gets no facet weight (counted in MeshingStats::degenerate_steps). If CGAL 5.5's
//     traverser stops short of the point (it can when the segment runs along a hull edge through
//     several vertices), the walk is redone from the camera centre moved by 1e-7 of the ray length
//     along fixed directions (a deterministic perturbation tie-break; MeshingStats counts these).
//  4. Surface quality term (the paper's): for the facet f between cells c1, c2 with circumspheres
//     (o_i, R_i), cos(phi_i) = h_i / R_i where h_i is the signed distance of o_i from the plane of
//     f, positive towards c_i's fourth vertex; w_q(f) = 1 - min(cos phi_1, cos phi_2) in [0, 2],
//     added to both directions of the facet's edge times lambda_quality. A facet between two large,
//     empty circumspheres that both lie on their own side (how a densely sampled surface looks) is
//     cheap to cut; a facet of a flat tetrahedron is expensive. For an infinite cell cos phi = 1.
//  5. Optional (MeshingOptions::weak_surface_weight > 0): weakly supported surfaces, after
//       M. Jancosek, T. Pajdla, "Multi-view reconstruction preserving weakly-supported surfaces",
//       CVPR 2011.
//     The free-space support of a cell is the weight of the lines of sight that crossed it. Where a
//     real surface is sampled by few points, the support is high in front of those points (rays to
//     everything else in the room cross the space there) and drops sharply behind them; behind a
//     floating outlier it stays high. For every line of sight whose point shows such a jump (the
//     least support over the cells up to `weak_surface_depth` behind the point is at most
//     `weak_surface_ratio` of the support just in front of it), the line of sight counts
//     (1 + weak_surface_weight) times: its crossed facets and its sink link get
//     weak_surface_weight * alpha_vis more, and the camera cells get hard source links (a camera
//     centre is free space). Rays to genuine surfaces then outweigh those to floating outliers.
//  6. Minimum s-t cut (Boost.Graph Boykov-Kolmogorov max-flow); the facets between an inside and an
//     outside cell form the mesh, oriented with the normal towards the outside cell.

#include <array>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mav/common/status.h"
#include "mav/mapping/mesh.h"
#include "mav/mapping/types.h"

namespace mav::mapping {

struct MeshingOptions {
  // Weight of one line of sight (the paper's alpha_vis); only ratios to lambda_quality matter.
  double alpha_vis = 1.0;
  // Weight of the surface quality term (the paper's lambda_qual), relative to alpha_vis.
  double lambda_quality = 1.0;
  // Distance [m] behind the point along the line of sight at which the sink (inside) cell is taken
  // (must be > 0; small values take the first cell behind the point). A few times the point noise:
  // with 1 cm noise, 0.02 m labels the thin slab of cells between noisy wall points inside and
  // 0.1 m jumps over thin obstacles; 0.05 m scored best on the synthetic room (docs/mapping.md).
  double sigma = 0.05;
  // Lines of sight longer than this [m] are ignored (guards against gross outliers).
  double max_ray_length = 100.0;
  // Force every infinite cell to outside (hard source link). Right for an object seen from
  // around it, wrong for a room seen from inside; see the header comment.
  bool force_infinite_cells_outside = false;
  // Weakly supported surfaces (Jancosek and Pajdla 2011; header comment, step 5): extra weight,
  // in units of alpha_vis, of a line of sight whose point shows a free-space-support jump (0 =
  // off, the paper's Labatut et al. method).
  double weak_surface_weight = 0.0;
  // A jump: the least support over the cells up to `weak_surface_depth` [m] behind the point is at
  // most `weak_surface_ratio` times the support of the cell `sigma` in front of it, and that front
  // support is at least `weak_surface_min_support` lines of sight.
  double weak_surface_ratio = 0.25;
  double weak_surface_depth = 0.3;
  double weak_surface_min_support = 4.0;
  // Only points with at least this many observing keyframes get the extra weight (1 = every
  // point): a floating outlier seen once can show a jump as well as a surface can.
  int weak_surface_min_views = 1;

  bool IsValid(std::string* why) const;
};

// What a map built for a planner should favour when the two errors trade (docs/mapping.md,
// "Missed-collision budget"):
//  * kSafety (the stack's default): fewer missed collisions, i.e. fewer occupied voxels that the
//    map calls free. Here: weakly supported surfaces on (weak_surface_weight = 4); the pipeline
//    adds the conservative grid, meshes only checked points and drops far single-view points
//    seen through a surface (MeshToGridOptionsFor, KeepUncheckedPointsFor, OcclusionCheckFor in
//    pipeline.h). On the full rendered rooms the misses go from 2.3-4.1 % to 0.12-0.47 % (a fifth
//    or less), at 0.07-0.11 lower MCC;
//  * kMcc: the paper's Labatut et al. weights alone, the best collision-check MCC.
enum class MapPreference { kSafety, kMcc };
const char* MapPreferenceName(MapPreference preference);  // "safety", "mcc"
// MeshingOptions defaults with the preference applied (MeshingOptions{} itself is the paper's
// method, i.e. kMcc).
MeshingOptions MeshingOptionsFor(MapPreference preference);

// A finite tetrahedron of the triangulation after labelling.
struct Tetrahedron {
  std::array<int, 4> vertices{};  // indices into the input point vector
  bool inside = false;            // graph-cut label: true = occupied (sink side)
  int num_rays = 0;               // lines of sight that crossed this cell
};

struct MeshingStats {
  int num_input_points = 0;
  int num_duplicate_points = 0;  // exact duplicates, merged into their first occurrence
  int num_vertices = 0;
  int num_finite_cells = 0;
  int num_infinite_cells = 0;
  int64_t num_rays = 0;           // lines of sight walked
  int64_t num_cell_steps = 0;     // cells visited by all walks
  int64_t degenerate_steps = 0;   // steps through an edge or vertex (no facet weight)
  int64_t perturbed_walks = 0;    // walks redone from a perturbed camera centre
  int64_t failed_walks = 0;       // lines of sight dropped (no walk reached the point)
  int64_t weak_surface_rays = 0;  // lines of sight whose point showed a free-space-support jump
  int num_inside_cells = 0;       // finite cells labelled inside
  double max_flow = 0.0;
  double triangulation_s = 0.0;
  double visibility_s = 0.0;
  double graph_cut_s = 0.0;
  double extraction_s = 0.0;
  double total_s = 0.0;
};

struct MeshingResult {
  TriangleMesh mesh;                    // the surface (only vertices used by triangles)
  std::vector<Tetrahedron> tetrahedra;  // every finite cell with its label
  std::vector<Eigen::Vector3d> points;  // copy of the input positions (tetrahedra index these)
  MeshingStats stats;
};

// Runs the whole pipeline. INVALID_ARGUMENT (naming the field / index) for: invalid options,
// non-finite coordinates, a point referencing an unknown keyframe id, duplicate keyframe ids, fewer
// than 4 affinely independent points. Points without observers still shape the triangulation.
Result<MeshingResult> BuildMesh(const std::vector<MapPoint>& points,
                                const std::vector<KeyframeView>& keyframes,
                                const MeshingOptions& options = {});

// The triangulation and its line-of-sight walk, exposed for tests and diagnostics. Vertex indices
// are input point indices (duplicates map to the first occurrence); -1 is the infinite vertex.
class DelaunayTetrahedralization {
 public:
  // INVALID_ARGUMENT for non-finite coordinates or a triangulation of dimension < 3.
  static Result<DelaunayTetrahedralization> Create(const std::vector<Eigen::Vector3d>& points);

  DelaunayTetrahedralization(DelaunayTetrahedralization&&) noexcept;
  DelaunayTetrahedralization& operator=(DelaunayTetrahedralization&&) noexcept;
  ~DelaunayTetrahedralization();

  int num_finite_cells() const;
  // Every finite facet as an ascending vertex-index triple.
  std::vector<std::array<int, 3>> FiniteFacets() const;
  // Every finite cell as ascending vertex indices.
  std::vector<std::array<int, 4>> FiniteCells() const;

  struct Walk {
    // Cells visited from the camera to the point, as ascending vertex indices (-1 = infinite vertex
    // comes first).
    std::vector<std::array<int, 4>> cells;
    // Facets entered through, in order (ascending triples); one fewer than `cells` minus the
    // degenerate steps.
    std::vector<std::array<int, 3>> crossed_facets;
    int degenerate_steps = 0;
    std::array<int, 4> behind_cell{};  // the sink cell: contains point + sigma * direction
    bool perturbed = false;            // the walk needed the perturbation tie-break
  };
  // Walks the segment from `camera_world` to the vertex `point_index` (MAV_CHECKs the index is
  // valid, the camera is not at the point and sigma > 0).
  Walk TraceLineOfSight(const Eigen::Vector3d& camera_world, int point_index, double sigma) const;

  struct Impl;

 private:
  explicit DelaunayTetrahedralization(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace mav::mapping
