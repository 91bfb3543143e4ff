#include "mav/mapping/mesh_to_grid.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include <Eigen/Geometry>
#include <unordered_map>

#include <Eigen/Dense>

#include "mav/common/check.h"
#include "mav/common/parallel.h"
#include "voxel_traversal.h"

namespace mav::mapping {

bool MeshToGridOptions::IsValid(std::string* why) const {
  if (carve_radius_voxels < 0 || carve_radius_voxels > 8) {
    if (why) *why = "carve_radius_voxels must be in [0, 8]";
    return false;
  }
  if (!(thick_stop_m >= 0.0) || !std::isfinite(thick_stop_m)) {
    if (why) *why = "thick_stop_m must be >= 0 [m]";
    return false;
  }
  if (free_near_ray_voxels < -1 || free_near_ray_voxels > 8) {
    if (why) *why = "free_near_ray_voxels must be in [-1, 8]";
    return false;
  }
  if (occupied_margin_voxels < 0 || occupied_margin_voxels > 8) {
    if (why) *why = "occupied_margin_voxels must be in [0, 8]";
    return false;
  }
  return true;
}

GridGeometry GridGeometryAround(const std::vector<MapPoint>& points,
                                const std::vector<KeyframeView>& keyframes, double resolution,
                                double padding) {
  MAV_CHECK(resolution > 0.0) << "resolution " << resolution;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (const MapPoint& p : points) {
    if (!p.p_world.allFinite()) continue;
    lo = lo.cwiseMin(p.p_world);
    hi = hi.cwiseMax(p.p_world);
  }
  for (const KeyframeView& k : keyframes) {
    if (!k.center_world.allFinite()) continue;
    lo = lo.cwiseMin(k.center_world);
    hi = hi.cwiseMax(k.center_world);
  }
  if (!lo.allFinite()) {
    lo.setZero();
    hi.setZero();
  }
  lo.array() -= padding;
  hi.array() += padding;
  GridGeometry g;
  g.resolution = resolution;
  for (int a = 0; a < 3; ++a) {
    g.origin[a] = std::floor(lo[a] / resolution) * resolution;
    g.size[a] = std::max(1, static_cast<int>(std::ceil((hi[a] - g.origin[a]) / resolution)));
  }
  return g;
}

namespace {

// Voxel index range [lo, hi] (inclusive) whose centres lie in the world box [min, max], clamped.
bool CenterRange(const GridGeometry& g, const Eigen::Vector3d& min, const Eigen::Vector3d& max,
                 Eigen::Vector3i* lo, Eigen::Vector3i* hi) {
  for (int a = 0; a < 3; ++a) {
    (*lo)[a] =
        std::max(0, static_cast<int>(std::ceil((min[a] - g.origin[a]) / g.resolution - 0.5)));
    (*hi)[a] = std::min(g.size[a] - 1,
                        static_cast<int>(std::floor((max[a] - g.origin[a]) / g.resolution - 0.5)));
    if ((*lo)[a] > (*hi)[a]) return false;
  }
  return true;
}

// Voxel index range [lo, hi] (inclusive) of voxels whose closed cubes touch the world box,
// clamped; a box face on a voxel boundary touches the voxels on both sides.
bool CubeRange(const GridGeometry& g, const Eigen::Vector3d& min, const Eigen::Vector3d& max,
               Eigen::Vector3i* lo, Eigen::Vector3i* hi) {
  constexpr double kTol = 1e-9;
  for (int a = 0; a < 3; ++a) {
    (*lo)[a] =
        std::max(0, static_cast<int>(std::floor((min[a] - g.origin[a]) / g.resolution - kTol)));
    (*hi)[a] = std::min(g.size[a] - 1,
                        static_cast<int>(std::floor((max[a] - g.origin[a]) / g.resolution + kTol)));
    if ((*lo)[a] > (*hi)[a]) return false;
  }
  return true;
}

void RasteriseTetrahedron(const Eigen::Vector3d v[4], VoxelState state, OccupancyGrid* grid) {
  const GridGeometry& g = grid->geometry();
  Eigen::Matrix3d m;
  m << v[1] - v[0], v[2] - v[0], v[3] - v[0];
  const double det = m.determinant();
  const double scale = (v[1] - v[0]).norm() * (v[2] - v[0]).norm() * (v[3] - v[0]).norm();
  if (!(std::abs(det) > 1e-12 * scale)) return;  // flat: covers no voxel centre robustly
  const Eigen::Matrix3d inv = m.inverse();
  Eigen::Vector3d min = v[0], max = v[0];
  for (int i = 1; i < 4; ++i) {
    min = min.cwiseMin(v[i]);
    max = max.cwiseMax(v[i]);
  }
  Eigen::Vector3i lo, hi;
  if (!CenterRange(g, min, max, &lo, &hi)) return;
  constexpr double kEps = 1e-9;
  for (int k = lo.z(); k <= hi.z(); ++k) {
    for (int j = lo.y(); j <= hi.y(); ++j) {
      // Solve the x-interval of the row analytically: barycentric coordinates are affine in x.
      const Eigen::Vector3d row0 = grid->CenterOf({lo.x(), j, k}) - v[0];
      const Eigen::Vector3d b0 = inv * row0;
      const Eigen::Vector3d db = inv.col(0) * g.resolution;
      double t_lo = 0.0, t_hi = hi.x() - lo.x();
      auto clip = [&](double value, double slope) {  // keep t with value + slope * t >= -eps
        if (slope == 0.0) {
          if (value < -kEps) t_hi = -1.0;
        } else if (slope > 0.0) {
          t_lo = std::max(t_lo, (-kEps - value) / slope);
        } else {
          t_hi = std::min(t_hi, (-kEps - value) / slope);
        }
      };
      clip(b0.x(), db.x());
      clip(b0.y(), db.y());
      clip(b0.z(), db.z());
      clip(1.0 - b0.sum(), -db.sum());
      if (t_lo > t_hi) continue;
      const int i0 = lo.x() + static_cast<int>(std::ceil(t_lo));
      const int i1 = lo.x() + static_cast<int>(std::floor(t_hi));
      for (int i = i0; i <= i1; ++i) (*grid)[grid->Linear(i, j, k)] = state;
    }
  }
}

// Separating-axis test of a triangle against an axis-aligned cube (centre c, half edge h).
bool TriangleTouchesCube(const Eigen::Vector3d& c, double h, const Eigen::Vector3d& a,
                         const Eigen::Vector3d& b, const Eigen::Vector3d& d) {
  const Eigen::Vector3d v[3] = {a - c, b - c, d - c};
  auto separated = [&](const Eigen::Vector3d& axis) {
    const double p0 = axis.dot(v[0]), p1 = axis.dot(v[1]), p2 = axis.dot(v[2]);
    const double r = h * axis.cwiseAbs().sum();
    return std::min({p0, p1, p2}) > r || std::max({p0, p1, p2}) < -r;
  };
  for (int i = 0; i < 3; ++i) {
    if (separated(Eigen::Vector3d::Unit(i))) return false;
  }
  const Eigen::Vector3d e[3] = {v[1] - v[0], v[2] - v[1], v[0] - v[2]};
  if (separated(e[0].cross(e[1]))) return false;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      const Eigen::Vector3d axis = e[i].cross(Eigen::Vector3d::Unit(j));
      if (axis.squaredNorm() > 0.0 && separated(axis)) return false;
    }
  }
  return true;
}

constexpr uint8_t kSeen = 1;       // crossed by a line of sight
constexpr uint8_t kSeenThick = 2;  // crossed by the thick part of a line of sight

// Marks the voxels crossed by the segment from `from` to `to` in `mask` (x fastest, the grid's
// layout), stopping one voxel before `to` (Amanatides-Woo traversal): kSeenThick up to
// `thick_stop_m` before `to` when `thick`, kSeen after that (or everywhere when not `thick`).
void TraceRay(const Eigen::Vector3d& from, const Eigen::Vector3d& to, bool thick,
              double thick_stop_m, const OccupancyGrid& grid, std::vector<uint8_t>* mask) {
  const GridGeometry& g = grid.geometry();
  const double length = (to - from).norm();
  if (!(length > g.resolution)) return;
  const double t_end = 1.0 - g.resolution / length;
  const double t_thick = thick ? 1.0 - thick_stop_m / length : -1.0;
  internal::TraverseVoxels(g, from, to, t_end, [&](const Eigen::Vector3i& idx, double t) {
    if (grid.InBounds(idx)) {
      (*mask)[grid.Linear(idx.x(), idx.y(), idx.z())] |= t < t_thick ? kSeenThick : kSeen;
    }
    return true;
  });
}

// Spreads the kSeenThick bit of `mask` to every voxel within `radius` voxels (Chebyshev
// distance): a box dilation, done as three separable 1D passes.
void DilateBit(const Eigen::Vector3i& size, int radius, uint8_t bit, std::vector<uint8_t>* mask) {
  const int64_t stride[3] = {1, size.x(), static_cast<int64_t>(size.x()) * size.y()};
  std::vector<uint8_t> line;
  for (int axis = 0; axis < 3; ++axis) {
    const int n = size[axis];
    const int o1 = axis == 0 ? 1 : 0, o2 = axis == 2 ? 1 : 2;  // the two other axes
    line.resize(n);
    for (int b = 0; b < size[o2]; ++b) {
      for (int a = 0; a < size[o1]; ++a) {
        const int64_t base = a * stride[o1] + b * stride[o2];
        // A voxel gets the bit if a voxel of the line within `radius` had it before this pass:
        // one sweep for the nearest one ahead, one for the nearest one behind.
        int run_end = -1;  // nearest index >= i that had the bit
        for (int i = 0; i < n; ++i) line[i] = ((*mask)[base + i * stride[axis]] & bit) != 0;
        for (int i = n - 1; i >= 0; --i) {
          if (line[i]) run_end = i;
          if (run_end >= 0 && run_end - i <= radius) (*mask)[base + i * stride[axis]] |= bit;
        }
        int run_start = -1;  // nearest index <= i that had the bit
        for (int i = 0; i < n; ++i) {
          if (line[i]) run_start = i;
          if (run_start >= 0 && i - run_start <= radius) (*mask)[base + i * stride[axis]] |= bit;
        }
      }
    }
  }
}

}  // namespace

Result<OccupancyGrid> MeshToOccupancy(const MeshingResult& meshing,
                                      const std::vector<MapPoint>& points,
                                      const std::vector<KeyframeView>& keyframes,
                                      const GridGeometry& geometry,
                                      const MeshToGridOptions& options) {
  std::string why;
  if (!geometry.IsValid(&why)) return Status::InvalidArgument("GridGeometry: " + why);
  if (!options.IsValid(&why)) return Status::InvalidArgument("MeshToGridOptions: " + why);
  const int num_points = static_cast<int>(meshing.points.size());
  for (size_t t = 0; t < meshing.tetrahedra.size(); ++t) {
    for (int i : meshing.tetrahedra[t].vertices) {
      if (i < 0 || i >= num_points) {
        return Status::InvalidArgument("meshing.tetrahedra[" + std::to_string(t) +
                                       "]: vertex index " + std::to_string(i) +
                                       " outside meshing.points");
      }
    }
  }
  OccupancyGrid grid(geometry, VoxelState::kUnknown);
  Eigen::Vector3d v[4];
  for (int pass = 0; pass < (options.occupy_inside_cells ? 2 : 1); ++pass) {
    const bool inside_pass = pass == 1;
    for (const Tetrahedron& t : meshing.tetrahedra) {
      if (t.inside != inside_pass) continue;
      if (!inside_pass && options.free_requires_traversal && t.num_rays == 0) continue;
      for (int i = 0; i < 4; ++i) v[i] = meshing.points[t.vertices[i]];
      RasteriseTetrahedron(v, inside_pass ? VoxelState::kOccupied : VoxelState::kFree, &grid);
    }
  }
  if (options.carve_lines_of_sight) {
    std::unordered_map<int, Eigen::Vector3d> center_of;
    for (const KeyframeView& k : keyframes) center_of[k.id] = k.center_world;
    for (const MapPoint& p : points) {
      for (int id : p.keyframes) {
        if (center_of.count(id) == 0) {
          return Status::InvalidArgument("points: unknown keyframe id " + std::to_string(id));
        }
      }
    }
    const bool thick = options.carve_radius_voxels > 0;
    // Two workers, each tracing half of the points into its own mask; the masks are OR-ed, so the
    // result does not depend on the split.
    auto trace = [&](size_t begin, size_t end, std::vector<uint8_t>* mask) {
      for (size_t i = begin; i < end; ++i) {
        for (int id : points[i].keyframes) {
          TraceRay(center_of.at(id), points[i].p_world, thick, options.thick_stop_m, grid, mask);
        }
      }
    };
    const size_t num_voxels = static_cast<size_t>(grid.num_voxels());
    std::vector<uint8_t> seen(num_voxels, 0);
    constexpr size_t kMinPointsPerWorker = 20000;
    if (points.size() >= 2 * kMinPointsPerWorker) {
      std::vector<uint8_t> seen_other(num_voxels, 0);
      ParallelFor(2, static_cast<int64_t>(points.size()),
                  [&](int part, int64_t begin, int64_t end) {
                    trace(static_cast<size_t>(begin), static_cast<size_t>(end),
                          part == 0 ? &seen : &seen_other);
                  });
      for (size_t i = 0; i < num_voxels; ++i) seen[i] |= seen_other[i];
    } else {
      trace(0, points.size(), &seen);
    }
    if (options.free_near_ray_voxels >= 0) {
      // Free space of the outside cells only near a line of sight: a cell that spans an
      // unsampled thin structure (a pipe, a shelf board) is crossed by rays beside it, but no
      // ray passes through the structure itself.
      constexpr uint8_t kNearRay = 4;
      for (uint8_t& m : seen) {
        if (m != 0) m |= kNearRay;
      }
      DilateBit(geometry.size, options.free_near_ray_voxels, kNearRay, &seen);
      for (int64_t i = 0; i < grid.num_voxels(); ++i) {
        if (grid[i] == VoxelState::kFree && (seen[i] & kNearRay) == 0) {
          grid[i] = VoxelState::kUnknown;
        }
      }
    }
    if (thick) DilateBit(geometry.size, options.carve_radius_voxels, kSeenThick, &seen);
    for (int64_t i = 0; i < grid.num_voxels(); ++i) {
      if ((seen[i] & (kSeen | kSeenThick)) != 0 && grid[i] == VoxelState::kUnknown) {
        grid[i] = VoxelState::kFree;
      }
    }
  }
  const double h = 0.5 * geometry.resolution * (1.0 + 1e-9);
  const TriangleMesh& mesh = meshing.mesh;
  for (const Eigen::Vector3i& tri : mesh.triangles) {
    if (!options.occupy_surface_voxels) break;
    const Eigen::Vector3d& a = mesh.vertices[tri[0]];
    const Eigen::Vector3d& b = mesh.vertices[tri[1]];
    const Eigen::Vector3d& c = mesh.vertices[tri[2]];
    Eigen::Vector3i lo, hi;
    if (!CubeRange(geometry, a.cwiseMin(b).cwiseMin(c), a.cwiseMax(b).cwiseMax(c), &lo, &hi)) {
      continue;
    }
    for (int k = lo.z(); k <= hi.z(); ++k) {
      for (int j = lo.y(); j <= hi.y(); ++j) {
        for (int i = lo.x(); i <= hi.x(); ++i) {
          VoxelState& s = grid[grid.Linear(i, j, k)];
          if (s == VoxelState::kOccupied) continue;
          if (TriangleTouchesCube(grid.CenterOf({i, j, k}), h, a, b, c)) s = VoxelState::kOccupied;
        }
      }
    }
  }
  if (options.occupied_margin_voxels > 0) {
    // Safety margin: free voxels within the margin of an occupied one become occupied.
    std::vector<uint8_t> occupied(static_cast<size_t>(grid.num_voxels()), 0);
    for (int64_t i = 0; i < grid.num_voxels(); ++i) {
      if (grid[i] == VoxelState::kOccupied) occupied[i] = 1;
    }
    DilateBit(geometry.size, options.occupied_margin_voxels, 1, &occupied);
    for (int64_t i = 0; i < grid.num_voxels(); ++i) {
      if (occupied[i] != 0 && grid[i] == VoxelState::kFree) grid[i] = VoxelState::kOccupied;
    }
  }
  return grid;
}

Result<std::vector<bool>> PointsSeenThroughSurfaces(const OccupancyGrid& grid,
                                                    const std::vector<MapPoint>& points,
                                                    const std::vector<KeyframeView>& keyframes,
                                                    double margin_m) {
  if (!(margin_m >= 0.0) || !std::isfinite(margin_m)) {
    return Status::InvalidArgument("margin_m: must be finite and >= 0, got " +
                                   std::to_string(margin_m));
  }
  std::unordered_map<int, Eigen::Vector3d> center_of;
  for (const KeyframeView& k : keyframes) center_of[k.id] = k.center_world;
  std::vector<bool> seen_through(points.size(), false);
  for (size_t i = 0; i < points.size(); ++i) {
    const MapPoint& p = points[i];
    for (size_t j = 0; j < p.keyframes.size(); ++j) {
      const auto it = center_of.find(p.keyframes[j]);
      if (it == center_of.end()) {
        return Status::InvalidArgument("points[" + std::to_string(i) + "].keyframes[" +
                                       std::to_string(j) + "]: unknown keyframe id " +
                                       std::to_string(p.keyframes[j]));
      }
      if (seen_through[i]) continue;
      const Eigen::Vector3d& camera = it->second;
      const double length = (p.p_world - camera).norm();
      if (!(length > margin_m)) continue;
      internal::TraverseVoxels(
          grid.geometry(), camera, p.p_world, (length - margin_m) / length,
          [&](const Eigen::Vector3i& index, double) {
            if (grid.InBounds(index) && grid.at(index) == VoxelState::kOccupied) {
              seen_through[i] = true;
              return false;
            }
            return true;
          });
    }
  }
  return seen_through;
}

}  // namespace mav::mapping
