// The only translation unit that includes CGAL (it is the heaviest compile unit of the project).

#include "mav/mapping/delaunay_graph_cut.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>
#include <utility>

#include <CGAL/Delaunay_triangulation_3.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_cell_base_with_info_3.h>
#include <CGAL/Triangulation_vertex_base_with_info_3.h>

#include "mav/common/check.h"
#include "mav/common/time.h"
#include "min_cut.h"

namespace mav::mapping {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Vb = CGAL::Triangulation_vertex_base_with_info_3<int, K>;
using Cb =
    CGAL::Triangulation_cell_base_with_info_3<int, K, CGAL::Delaunay_triangulation_cell_base_3<K>>;
using Tds = CGAL::Triangulation_data_structure_3<Vb, Cb>;
using Dt = CGAL::Delaunay_triangulation_3<K, Tds>;
using Point = Dt::Point;
using CellHandle = Dt::Cell_handle;
using VertexHandle = Dt::Vertex_handle;

namespace {

Point ToPoint(const Eigen::Vector3d& p) { return Point(p.x(), p.y(), p.z()); }
Eigen::Vector3d ToEigen(const Point& p) { return Eigen::Vector3d(p.x(), p.y(), p.z()); }

bool AllFinite(const Eigen::Vector3d& p) { return p.allFinite(); }

}  // namespace

struct DelaunayTetrahedralization::Impl {
  Dt dt;
  std::vector<VertexHandle> vertex_of_point;  // per input point (duplicates share a handle)
  int num_duplicates = 0;
  int num_cells = 0;  // all cells, infinite included; cell->info() in [0, num_cells)

  int VertexIndex(VertexHandle v) const { return dt.is_infinite(v) ? -1 : v->info(); }

  std::array<int, 4> CellKey(CellHandle c) const {
    std::array<int, 4> key{};
    for (int i = 0; i < 4; ++i) key[i] = VertexIndex(c->vertex(i));
    std::sort(key.begin(), key.end());
    return key;
  }
  std::array<int, 3> FacetKey(CellHandle c, int i) const {
    std::array<int, 3> key{};
    int n = 0;
    for (int j = 0; j < 4; ++j) {
      if (j != i) key[n++] = VertexIndex(c->vertex(j));
    }
    std::sort(key.begin(), key.end());
    return key;
  }

  // One walk along a line of sight, buffered so that a failed walk leaves no weights behind.
  struct WalkBuffer {
    std::vector<CellHandle> cells;
    std::vector<std::pair<CellHandle, int>> facets;  // (cell before the facet, facet index)
    int degenerate = 0;
  };

  // Walks the segment from `camera` to the vertex `v` (point location starts at `hint`). Returns
  // false if the walk did not end in a cell incident to `v`: CGAL 5.5's traverser can stop early
  // when the segment runs along a hull edge through several vertices.
  bool WalkOnce(const Point& camera, VertexHandle v, CellHandle hint, WalkBuffer* out) const {
    out->cells.clear();
    out->facets.clear();
    out->degenerate = 0;
    CellHandle prev;
    Dt::Segment_cell_iterator it(&dt, camera, v, hint);
    const Dt::Segment_cell_iterator end = dt.segment_traverser_cells_end();
    for (; it != end; ++it) {
      const CellHandle c = it;
      out->cells.push_back(c);
      if (prev != CellHandle()) {
        int i = 0;
        if (prev->has_neighbor(c, i)) {
          out->facets.emplace_back(prev, i);
        } else {
          ++out->degenerate;  // entered through an edge or a vertex
        }
      }
      prev = c;
    }
    return prev != CellHandle() && prev->has_vertex(v);
  }

  // WalkOnce, and if it fails, again from camera positions perturbed by a deterministic tiny
  // offset (1e-7 of the ray length): a symbolic-perturbation style tie-break that turns the
  // degenerate ray into a generic one infinitesimally close to it. Returns false if all fail.
  bool Walk(const Point& camera, VertexHandle v, CellHandle hint, WalkBuffer* out,
            int* perturbed) const {
    if (WalkOnce(camera, v, hint, out)) return true;
    const Eigen::Vector3d c = ToEigen(camera);
    const double eps = 1e-7 * std::max(1e-3, (ToEigen(v->point()) - c).norm());
    static const Eigen::Vector3d kOffsets[3] = {Eigen::Vector3d(0.5773, 0.3347, 0.7445),
                                                Eigen::Vector3d(-0.3219, 0.8851, -0.3362),
                                                Eigen::Vector3d(0.6931, -0.2718, -0.6676)};
    for (const Eigen::Vector3d& offset : kOffsets) {
      ++*perturbed;
      if (WalkOnce(ToPoint(c + eps * offset), v, hint, out)) return true;
    }
    return false;
  }

  // The cell behind vertex v on the ray with unit direction `dir`: the one containing
  // v + sigma * dir (sigma > 0; CGAL's traverser cannot start at a hull vertex and leave the
  // hull, so "the first cell after v" is taken as the cell a small distance behind it).
  CellHandle BehindCell(VertexHandle v, const Eigen::Vector3d& dir, double sigma,
                        CellHandle hint) const {
    return dt.locate(ToPoint(ToEigen(v->point()) + sigma * dir), hint);
  }
};

namespace {

Result<std::unique_ptr<DelaunayTetrahedralization::Impl>> BuildTriangulation(
    const std::vector<Eigen::Vector3d>& points) {
  for (size_t i = 0; i < points.size(); ++i) {
    if (!AllFinite(points[i])) {
      return Status::InvalidArgument("points[" + std::to_string(i) + "]: coordinate is not finite");
    }
  }
  auto impl = std::make_unique<DelaunayTetrahedralization::Impl>();
  std::vector<std::pair<Point, int>> with_info;
  with_info.reserve(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    with_info.emplace_back(ToPoint(points[i]), static_cast<int>(i));
  }
  impl->dt.insert(with_info.begin(), with_info.end());
  if (impl->dt.dimension() < 3) {
    return Status::InvalidArgument(
        "points: need at least 4 points that are not coplanar for a 3D triangulation (got " +
        std::to_string(points.size()) + " points spanning dimension " +
        std::to_string(std::max(impl->dt.dimension(), 0)) + ")");
  }
  impl->vertex_of_point.assign(points.size(), VertexHandle());
  for (auto v = impl->dt.finite_vertices_begin(); v != impl->dt.finite_vertices_end(); ++v) {
    impl->vertex_of_point[v->info()] = v;
  }
  // Exact duplicates were merged by the triangulation; map them to the surviving vertex.
  CellHandle hint;
  for (size_t i = 0; i < points.size(); ++i) {
    if (impl->vertex_of_point[i] != VertexHandle()) continue;
    Dt::Locate_type lt;
    int li = 0, lj = 0;
    const CellHandle c = impl->dt.locate(ToPoint(points[i]), lt, li, lj, hint);
    MAV_CHECK(lt == Dt::VERTEX) << "point " << i << " is neither a vertex nor a duplicate";
    impl->vertex_of_point[i] = c->vertex(li);
    ++impl->num_duplicates;
    hint = c;
  }
  int index = 0;
  for (auto c = impl->dt.all_cells_begin(); c != impl->dt.all_cells_end(); ++c) c->info() = index++;
  impl->num_cells = index;
  return impl;
}

// cos(phi) of the paper's quality term for facet i of cell c: the signed distance of c's
// circumcentre from the facet plane (positive towards c's fourth vertex) over the circumradius.
double FacetSphereCosine(const Dt& dt, CellHandle c, int i) {
  if (dt.is_infinite(c)) return 1.0;  // the "sphere" of an infinite cell is the outer half-space
  const Eigen::Vector3d opposite = ToEigen(c->vertex(i)->point());
  Eigen::Vector3d f[3];
  int n = 0;
  for (int j = 0; j < 4; ++j) {
    if (j != i) f[n++] = ToEigen(c->vertex(j)->point());
  }
  const Eigen::Vector3d center = ToEigen(CGAL::circumcenter(
      c->vertex(0)->point(), c->vertex(1)->point(), c->vertex(2)->point(), c->vertex(3)->point()));
  const double radius = (center - f[0]).norm();
  Eigen::Vector3d normal = (f[1] - f[0]).cross(f[2] - f[0]);
  const double norm = normal.norm();
  if (!(norm > 0.0) || !std::isfinite(radius) || !(radius > 0.0)) return -1.0;
  normal /= norm;
  if (normal.dot(opposite - f[0]) < 0.0) normal = -normal;
  const double cosine = normal.dot(center - f[0]) / radius;
  if (!std::isfinite(cosine)) return -1.0;
  return std::clamp(cosine, -1.0, 1.0);
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// DelaunayTetrahedralization

DelaunayTetrahedralization::DelaunayTetrahedralization(std::unique_ptr<Impl> impl)
    : impl_(std::move(impl)) {}
DelaunayTetrahedralization::DelaunayTetrahedralization(DelaunayTetrahedralization&&) noexcept =
    default;
DelaunayTetrahedralization& DelaunayTetrahedralization::operator=(
    DelaunayTetrahedralization&&) noexcept = default;
DelaunayTetrahedralization::~DelaunayTetrahedralization() = default;

Result<DelaunayTetrahedralization> DelaunayTetrahedralization::Create(
    const std::vector<Eigen::Vector3d>& points) {
  MAV_ASSIGN_OR_RETURN(std::unique_ptr<Impl> impl, BuildTriangulation(points));
  return DelaunayTetrahedralization(std::move(impl));
}

int DelaunayTetrahedralization::num_finite_cells() const {
  return static_cast<int>(impl_->dt.number_of_finite_cells());
}

std::vector<std::array<int, 3>> DelaunayTetrahedralization::FiniteFacets() const {
  std::vector<std::array<int, 3>> out;
  for (auto f = impl_->dt.finite_facets_begin(); f != impl_->dt.finite_facets_end(); ++f) {
    out.push_back(impl_->FacetKey(f->first, f->second));
  }
  return out;
}

std::vector<std::array<int, 4>> DelaunayTetrahedralization::FiniteCells() const {
  std::vector<std::array<int, 4>> out;
  for (auto c = impl_->dt.finite_cells_begin(); c != impl_->dt.finite_cells_end(); ++c) {
    out.push_back(impl_->CellKey(c));
  }
  return out;
}

DelaunayTetrahedralization::Walk DelaunayTetrahedralization::TraceLineOfSight(
    const Eigen::Vector3d& camera_world, int point_index, double sigma) const {
  MAV_CHECK(point_index >= 0 && point_index < static_cast<int>(impl_->vertex_of_point.size()))
      << "point_index " << point_index;
  const VertexHandle v = impl_->vertex_of_point[point_index];
  const Eigen::Vector3d p = ToEigen(v->point());
  MAV_CHECK((p - camera_world).norm() > 0.0) << "camera at the point";
  MAV_CHECK(sigma > 0.0) << "sigma " << sigma;
  Walk walk;
  Impl::WalkBuffer buffer;
  int perturbed = 0;
  MAV_CHECK(impl_->Walk(ToPoint(camera_world), v, CellHandle(), &buffer, &perturbed))
      << "line of sight to point " << point_index << " could not be walked";
  for (CellHandle c : buffer.cells) walk.cells.push_back(impl_->CellKey(c));
  for (const auto& [c, i] : buffer.facets) walk.crossed_facets.push_back(impl_->FacetKey(c, i));
  walk.degenerate_steps = buffer.degenerate;
  walk.perturbed = perturbed > 0;
  const Eigen::Vector3d dir = (p - camera_world).normalized();
  walk.behind_cell = impl_->CellKey(impl_->BehindCell(v, dir, sigma, v->cell()));
  return walk;
}

// ---------------------------------------------------------------------------------------------
// BuildMesh

const char* MapPreferenceName(MapPreference preference) {
  return preference == MapPreference::kSafety ? "safety" : "mcc";
}

MeshingOptions MeshingOptionsFor(MapPreference preference) {
  MeshingOptions options;
  if (preference == MapPreference::kSafety) options.weak_surface_weight = 4.0;
  return options;
}

bool MeshingOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!(alpha_vis > 0.0) || !std::isfinite(alpha_vis)) return fail("alpha_vis must be > 0");
  if (!(lambda_quality >= 0.0) || !std::isfinite(lambda_quality)) {
    return fail("lambda_quality must be >= 0");
  }
  if (!(sigma > 0.0) || !std::isfinite(sigma)) return fail("sigma must be > 0 [m]");
  if (!(max_ray_length > 0.0)) return fail("max_ray_length must be > 0 [m]");
  if (!(weak_surface_weight >= 0.0) || !std::isfinite(weak_surface_weight)) {
    return fail("weak_surface_weight must be >= 0");
  }
  if (!(weak_surface_ratio >= 0.0 && weak_surface_ratio <= 1.0)) {
    return fail("weak_surface_ratio must be in [0, 1]");
  }
  if (!(weak_surface_depth >= sigma) || !std::isfinite(weak_surface_depth)) {
    return fail("weak_surface_depth must be >= sigma [m]");
  }
  if (!(weak_surface_min_support >= 0.0) || !std::isfinite(weak_surface_min_support)) {
    return fail("weak_surface_min_support must be >= 0");
  }
  if (weak_surface_min_views < 1) return fail("weak_surface_min_views must be >= 1");
  return true;
}

Result<MeshingResult> BuildMesh(const std::vector<MapPoint>& points,
                                const std::vector<KeyframeView>& keyframes,
                                const MeshingOptions& options) {
  const int64_t t_start = MonotonicNowNs();
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument("MeshingOptions: " + why);

  std::unordered_map<int, int> keyframe_index;
  for (size_t k = 0; k < keyframes.size(); ++k) {
    if (!AllFinite(keyframes[k].center_world)) {
      return Status::InvalidArgument("keyframes[" + std::to_string(k) +
                                     "].center_world: coordinate is not finite");
    }
    if (!keyframe_index.emplace(keyframes[k].id, static_cast<int>(k)).second) {
      return Status::InvalidArgument("keyframes[" + std::to_string(k) + "].id: duplicate id " +
                                     std::to_string(keyframes[k].id));
    }
  }
  // Lines of sight grouped by keyframe: consecutive walks start in the same cell and touch nearby
  // cells, which keeps the point location cheap and the caches warm.
  std::vector<std::vector<int>> points_of_keyframe(keyframes.size());
  std::vector<Eigen::Vector3d> positions(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    positions[i] = points[i].p_world;
    for (size_t j = 0; j < points[i].keyframes.size(); ++j) {
      const auto it = keyframe_index.find(points[i].keyframes[j]);
      if (it == keyframe_index.end()) {
        return Status::InvalidArgument("points[" + std::to_string(i) + "].keyframes[" +
                                       std::to_string(j) + "]: unknown keyframe id " +
                                       std::to_string(points[i].keyframes[j]));
      }
      points_of_keyframe[it->second].push_back(static_cast<int>(i));
    }
  }

  MeshingResult result;
  MeshingStats& stats = result.stats;
  stats.num_input_points = static_cast<int>(points.size());
  int64_t t0 = MonotonicNowNs();
  MAV_ASSIGN_OR_RETURN(std::unique_ptr<DelaunayTetrahedralization::Impl> impl,
                       BuildTriangulation(positions));
  const Dt& dt = impl->dt;
  stats.triangulation_s = SecondsSince(t0);
  stats.num_duplicate_points = impl->num_duplicates;
  stats.num_vertices = static_cast<int>(dt.number_of_vertices());
  stats.num_finite_cells = static_cast<int>(dt.number_of_finite_cells());
  stats.num_infinite_cells = impl->num_cells - stats.num_finite_cells;

  // Visibility term.
  t0 = MonotonicNowNs();
  const int n = impl->num_cells;
  internal::StGraph graph;
  graph.num_nodes = n;
  graph.source_cap.assign(n, 0.0);
  graph.sink_cap.assign(n, 0.0);
  std::vector<double> facet_weight(static_cast<size_t>(n) * 4, 0.0);  // cell*4+i: cell -> neighbor
  std::vector<int> rays_per_cell(n, 0);
  const double alpha = options.alpha_vis;
  DelaunayTetrahedralization::Impl::WalkBuffer buffer;
  // Calls visit(camera_point, camera_cell, v, p, dir, length) for every line of sight kept
  // (length in (0, max_ray_length]), keyframe by keyframe.
  auto for_each_line_of_sight = [&](auto&& visit) {
    for (size_t k = 0; k < keyframes.size(); ++k) {
      if (points_of_keyframe[k].empty()) continue;
      const Eigen::Vector3d& camera = keyframes[k].center_world;
      const Point camera_point = ToPoint(camera);
      const CellHandle camera_cell = dt.locate(camera_point);
      for (int i : points_of_keyframe[k]) {
        const VertexHandle v = impl->vertex_of_point[i];
        const Eigen::Vector3d p = ToEigen(v->point());
        const double length = (p - camera).norm();
        if (!(length > 1e-9) || length > options.max_ray_length) continue;
        visit(camera_point, camera_cell, v, p, Eigen::Vector3d((p - camera) / length), length);
      }
    }
  };
  for_each_line_of_sight([&](const Point& camera_point, CellHandle camera_cell, VertexHandle v,
                             const Eigen::Vector3d&, const Eigen::Vector3d& dir, double) {
    int perturbed = 0;
    const bool walked = impl->Walk(camera_point, v, camera_cell, &buffer, &perturbed);
    stats.perturbed_walks += perturbed > 0 ? 1 : 0;
    if (!walked) {
      ++stats.failed_walks;
      return;
    }
    ++stats.num_rays;
    graph.source_cap[camera_cell->info()] += alpha;
    for (CellHandle c : buffer.cells) ++rays_per_cell[c->info()];
    for (const auto& [c, f] : buffer.facets) {
      facet_weight[static_cast<size_t>(c->info()) * 4 + f] += alpha;
    }
    stats.num_cell_steps += static_cast<int64_t>(buffer.cells.size());
    stats.degenerate_steps += buffer.degenerate;
    const CellHandle behind = impl->BehindCell(v, dir, options.sigma, buffer.cells.back());
    graph.sink_cap[behind->info()] += alpha;
  });
  if (options.weak_surface_weight > 0.0) {
    // Free-space support jumps (Jancosek and Pajdla 2011). The support of a cell is the weight of
    // the rays that crossed it (rays_per_cell); a second pass over the lines of sight compares
    // the cell `sigma` in front of each point with the cells behind it, sampled every `sigma` up
    // to weak_surface_depth. A line of sight whose point shows a jump counts
    // (1 + weak_surface_weight) times: its facets again, and its sink link; its camera cell's
    // source link is made hard below.
    const double step = options.sigma;
    const double extra = options.weak_surface_weight * alpha;
    for_each_line_of_sight([&](const Point& camera_point, CellHandle camera_cell, VertexHandle v,
                               const Eigen::Vector3d& p, const Eigen::Vector3d& dir,
                               double length) {
      if (static_cast<int>(points[v->info()].keyframes.size()) < options.weak_surface_min_views) {
        return;
      }
      const CellHandle front =
          dt.locate(ToPoint(p - std::min(step, 0.5 * length) * dir), v->cell());
      const double front_support = alpha * rays_per_cell[front->info()];
      if (front_support < options.weak_surface_min_support * alpha) return;
      CellHandle hint = v->cell();
      CellHandle behind;
      double behind_support = std::numeric_limits<double>::infinity();
      for (double d = step; d <= options.weak_surface_depth + 1e-9; d += step) {
        const CellHandle c = dt.locate(ToPoint(p + d * dir), hint);
        if (behind == CellHandle()) behind = c;
        behind_support = std::min(behind_support, alpha * rays_per_cell[c->info()]);
        hint = c;
      }
      if (behind_support > options.weak_surface_ratio * front_support) return;
      int perturbed = 0;
      if (!impl->Walk(camera_point, v, camera_cell, &buffer, &perturbed)) return;
      for (const auto& [c, f] : buffer.facets) {
        facet_weight[static_cast<size_t>(c->info()) * 4 + f] += extra;
      }
      graph.sink_cap[behind->info()] += extra;
      ++stats.weak_surface_rays;
    });
  }
  // A capacity larger than any cut through finite facets can cost makes a source link hard.
  auto hard_capacity = [&] {
    double total = 0.0;
    for (double w : facet_weight) total += w;
    total += 2.0 * options.lambda_quality * static_cast<double>(n) * 4.0;
    for (double w : graph.sink_cap) total += w;
    return total + 1.0;
  };
  if (options.force_infinite_cells_outside) {
    const double hard = hard_capacity();
    for (auto c = dt.all_cells_begin(); c != dt.all_cells_end(); ++c) {
      if (dt.is_infinite(c)) graph.source_cap[c->info()] += hard;
    }
  }
  if (options.weak_surface_weight > 0.0) {
    // The extra sink weight outweighs the cameras' alpha_vis source links: without hard links a
    // cut around the cameras can be the cheapest, labelling the rest of the room inside (seen on
    // room-hard with a sink-only extra weight). A camera centre is free space: the vehicle was
    // there.
    const double hard = hard_capacity();
    for (const KeyframeView& k : keyframes) {
      graph.source_cap[dt.locate(ToPoint(k.center_world))->info()] += hard;
    }
  }
  stats.visibility_s = SecondsSince(t0);

  // Quality term and the facet edges; each facet once, from the cell with the smaller index.
  t0 = MonotonicNowNs();
  graph.edges.reserve(static_cast<size_t>(n) * 2);
  for (auto c = dt.all_cells_begin(); c != dt.all_cells_end(); ++c) {
    for (int i = 0; i < 4; ++i) {
      const CellHandle d = c->neighbor(i);
      if (d->info() < c->info()) continue;
      const int j = d->index(c);
      double quality = 0.0;
      if (options.lambda_quality > 0.0) {
        const double cos_c = FacetSphereCosine(dt, c, i);
        const double cos_d = FacetSphereCosine(dt, d, j);
        quality = options.lambda_quality * (1.0 - std::min(cos_c, cos_d));
      }
      internal::StGraph::Edge e;
      e.u = c->info();
      e.v = d->info();
      e.cap_uv = facet_weight[static_cast<size_t>(e.u) * 4 + i] + quality;
      e.cap_vu = facet_weight[static_cast<size_t>(e.v) * 4 + j] + quality;
      graph.edges.push_back(e);
    }
  }
  const internal::MinCut cut = internal::SolveMinCut(graph);
  stats.max_flow = cut.flow;
  stats.graph_cut_s = SecondsSince(t0);

  // Labels, tetrahedra and the surface.
  t0 = MonotonicNowNs();
  result.points = std::move(positions);
  result.tetrahedra.reserve(stats.num_finite_cells);
  for (auto c = dt.finite_cells_begin(); c != dt.finite_cells_end(); ++c) {
    Tetrahedron t;
    for (int i = 0; i < 4; ++i) t.vertices[i] = c->vertex(i)->info();
    t.inside = cut.sink_side[c->info()] != 0;
    t.num_rays = rays_per_cell[c->info()];
    stats.num_inside_cells += t.inside ? 1 : 0;
    result.tetrahedra.push_back(t);
  }
  std::vector<int> mesh_vertex(result.points.size(), -1);
  auto mesh_index = [&](VertexHandle v) {
    int& m = mesh_vertex[v->info()];
    if (m < 0) {
      m = static_cast<int>(result.mesh.vertices.size());
      result.mesh.vertices.push_back(ToEigen(v->point()));
    }
    return m;
  };
  for (auto f = dt.finite_facets_begin(); f != dt.finite_facets_end(); ++f) {
    const CellHandle c = f->first;
    const int i = f->second;
    const CellHandle d = c->neighbor(i);
    const bool c_inside = cut.sink_side[c->info()] != 0;
    const bool d_inside = cut.sink_side[d->info()] != 0;
    if (c_inside == d_inside) continue;
    VertexHandle tri[3];
    int m = 0;
    for (int j = 0; j < 4; ++j) {
      if (j != i) tri[m++] = c->vertex(j);
    }
    // Outward normal: the inside cell's opposite vertex lies on the negative side, the outside
    // cell's on the positive side (exact orientation predicate; one of them is finite).
    const CellHandle inside = c_inside ? c : d;
    const CellHandle outside = c_inside ? d : c;
    const VertexHandle in_opposite = inside->vertex(inside == c ? i : d->index(c));
    CGAL::Orientation want = CGAL::NEGATIVE;
    VertexHandle probe = in_opposite;
    if (dt.is_infinite(in_opposite)) {
      probe = outside->vertex(outside == c ? i : d->index(c));
      want = CGAL::POSITIVE;
    }
    if (CGAL::orientation(tri[0]->point(), tri[1]->point(), tri[2]->point(), probe->point()) !=
        want) {
      std::swap(tri[1], tri[2]);
    }
    result.mesh.triangles.emplace_back(mesh_index(tri[0]), mesh_index(tri[1]), mesh_index(tri[2]));
  }
  stats.extraction_s = SecondsSince(t0);
  stats.total_s = SecondsSince(t_start);
  return result;
}

}  // namespace mav::mapping
