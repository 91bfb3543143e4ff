#include "mav/planning/planning_map.h"

#include <octomap/OcTree.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>

#include "distance_field.h"
#include "mav/common/file.h"
#include "mav/common/hash.h"
#include "mav/common/time.h"
#include "mav/dataset/octomap_bt.h"

namespace mav::planning {
namespace {

enum CellState : uint8_t { kFreeCell = 0, kOccupiedCell = 1, kUnknownCell = 2 };

// The grid box: the planning volume padded by what the clearance needs (the saturation plus a
// cell); when unknown space is an obstacle everything outside the OctoMap is an obstacle, so one
// cell of that shell is enough and the box is clipped to the map plus one cell.
Box GridBox(const Box& planning, const Box& map_bounds, double cell, const MapOptions& options) {
  const double pad = options.max_distance_m + 2 * cell;
  const Eigen::Vector3d pad3 = Eigen::Vector3d::Constant(pad);
  Box box{planning.min - pad3, planning.max + pad3};
  if (options.unknown_space == UnknownSpace::kObstacle) {
    const Eigen::Vector3d shell = Eigen::Vector3d::Constant(cell);
    box.min = box.min.cwiseMax(map_bounds.min - shell);
    box.max = box.max.cwiseMin(map_bounds.max + shell);
  }
  return box;
}

// Cells aligned with OctoMap's voxels (boundaries at multiples of the resolution).
void AlignToCells(const Box& box, double cell, Eigen::Vector3d* origin, Eigen::Vector3i* size) {
  for (int a = 0; a < 3; ++a) {
    const double lo = std::floor(box.min[a] / cell + 1e-9);
    const double hi = std::ceil(box.max[a] / cell - 1e-9);
    (*origin)[a] = lo * cell;
    (*size)[a] = std::max(1, static_cast<int>(hi - lo));
  }
}

uint64_t BytesPerVoxel(const MapOptions& options) {
  // The state/mask byte, the distance map, the row bits.
  const uint64_t base = 1 + internal::kExactBytesPerCell + 1;
  return options.distance_method == DistanceMethod::kDynamicEdt3d
             ? base + internal::kDynamicEdt3dBytesPerCell
             : base;
}

}  // namespace

bool MapOptions::IsValid(std::string* why) const {
  std::ostringstream msg;
  if (!(robot_radius_m > 0 && robot_radius_m <= 10)) {
    msg << "robot_radius_m: must be in (0, 10] m, got " << robot_radius_m;
  } else if (!(max_distance_m > robot_radius_m && max_distance_m <= 50)) {
    msg << "max_distance_m: must be in (robot_radius_m = " << robot_radius_m << ", 50] m, got "
        << max_distance_m;
  } else if (threads < 1 || threads > 64) {
    msg << "threads: must be in [1, 64], got " << threads;
  } else if (planning_bounds && !planning_bounds->IsValid("planning_bounds", why)) {
    return false;
  }
  if (msg.str().empty()) return true;
  if (why) *why = msg.str();
  return false;
}

MemoryEstimate EstimateMapMemory(const Box& volume, double resolution_m,
                                 const MapOptions& options) {
  MemoryEstimate e;
  Eigen::Vector3d origin;
  AlignToCells(volume, resolution_m, &origin, &e.grid_size);
  e.grid_voxels = static_cast<uint64_t>(e.grid_size.x()) * e.grid_size.y() * e.grid_size.z();
  e.bytes_per_voxel = BytesPerVoxel(options);
  e.bytes = e.grid_voxels * e.bytes_per_voxel;
  return e;
}

struct PlanningMap::Impl {
  MapOptions options;
  MapInfo info;
  Box planning_bounds;
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3i size = Eigen::Vector3i::Zero();
  int64_t nx = 0, ny = 0, nz = 0;
  double cell = 0;
  int64_t words_per_row = 0;
  std::vector<uint64_t> bits;   // obstacle bit per cell, one x-row after the other
  std::vector<float> distance;  // D(c), metres
  float saturation = 0;         // the largest value `distance` holds
  bool exact_centres = true;    // D(c) exact (else only a lower bound)

  int64_t Linear(int64_t i, int64_t j, int64_t k) const { return i + nx * (j + ny * k); }

  // The cell containing p (false outside the grid) and p in cell units.
  bool Locate(const Eigen::Vector3d& p, Eigen::Vector3d* q, Eigen::Vector3i* c) const {
    *q = (p - origin) / cell;
    for (int a = 0; a < 3; ++a) {
      const double f = std::floor((*q)[a]);
      if (!(f >= 0 && f < size[a])) return false;
      (*c)[a] = static_cast<int>(f);
    }
    return true;
  }

  bool Bit(int64_t i, int64_t j, int64_t k) const {
    const uint64_t* row = bits.data() + (j + ny * k) * words_per_row;
    return (row[i >> 6] >> (i & 63)) & 1u;
  }

  // Distance from p (cell units q) to the nearest obstacle cube, if one lies closer than
  // `limit_cells`: the exact squared distance in cell units, else limit_cells^2. Rows (j, k) are
  // visited outwards from p's row and pruned by their slab distance; in each row the nearest
  // obstacle on either side of p's column comes from a bit search.
  double ScanSquared(const Eigen::Vector3d& q, const Eigen::Vector3i& c, double limit_cells) const {
    double best2 = limit_cells * limit_cells;
    const auto gap = [](double coord, int64_t idx) {
      return std::max({0.0, idx - coord, coord - (idx + 1)});
    };
    for (int dir_k = 0; dir_k < 2; ++dir_k) {
      for (int64_t k = dir_k == 0 ? c.z() : c.z() - 1; k >= 0 && k < nz; k += dir_k == 0 ? 1 : -1) {
        const double gz = gap(q.z(), k);
        if (gz * gz >= best2) break;
        for (int dir_j = 0; dir_j < 2; ++dir_j) {
          for (int64_t j = dir_j == 0 ? c.y() : c.y() - 1; j >= 0 && j < ny;
               j += dir_j == 0 ? 1 : -1) {
            const double gy = gap(q.y(), j);
            const double yz2 = gy * gy + gz * gz;
            if (yz2 >= best2) break;
            const double reach = std::sqrt(best2 - yz2);
            best2 = std::min(best2, yz2 + RowGapSquared(j, k, q.x(), c.x(), reach));
          }
        }
      }
    }
    return best2;
  }

  // Squared x-gap from coordinate qx (in cell `ci`) to the nearest obstacle of row (j, k) within
  // `reach` cells; infinity when there is none (so that no rounding lowers the caller's best).
  double RowGapSquared(int64_t j, int64_t k, double qx, int64_t ci, double reach) const {
    const uint64_t* row = bits.data() + (j + ny * k) * words_per_row;
    constexpr double kNone = std::numeric_limits<double>::infinity();
    double best = kNone;
    // Right: the first obstacle at index >= ci.
    {
      const int64_t last = std::min<int64_t>(nx - 1, static_cast<int64_t>(std::floor(qx + reach)));
      int64_t i = ci;
      while (i <= last) {
        const uint64_t word = row[i >> 6] >> (i & 63);
        if (word) {
          i += std::countr_zero(word);
          if (i <= last) best = i == ci ? 0.0 : i - qx;
          break;
        }
        i = ((i >> 6) + 1) << 6;
      }
    }
    // Left: the last obstacle at index < ci.
    if (best > 0) {
      const int64_t first = std::max<int64_t>(0, static_cast<int64_t>(std::floor(qx - reach)));
      int64_t i = ci - 1;
      while (i >= first) {
        const int shift = 63 - static_cast<int>(i & 63);
        const uint64_t word = row[i >> 6] << shift;
        if (word) {
          i -= std::countl_zero(word);
          if (i >= first) best = std::min(best, qx - (i + 1));
          break;
        }
        i = ((i >> 6) << 6) - 1;
      }
    }
    return best * best;
  }
};

namespace {

// Paints the leaves of `tree` that overlap the grid into `states` and counts the leaves.
Status FillStates(const octomap::OcTree& tree, const PlanningMap::Impl& m, const Termination& stop,
                  std::vector<uint8_t>* states, uint64_t* leaves) {
  const Eigen::Vector3d hi = m.origin + m.size.cast<double>() * m.cell;
  const Eigen::Vector3f lo_f = m.origin.cast<float>(), hi_f = hi.cast<float>();
  const octomap::point3d bbx_min(lo_f.x(), lo_f.y(), lo_f.z());
  const octomap::point3d bbx_max(hi_f.x(), hi_f.y(), hi_f.z());
  *leaves = 0;
  for (auto it = tree.begin_leafs_bbx(bbx_min, bbx_max), end = tree.end_leafs_bbx(); it != end;
       ++it) {
    if ((++*leaves & 0xffff) == 0) MAV_RETURN_IF_ERROR(stop.Check("map load"));
    const double half = 0.5 * it.getSize();
    const octomap::point3d c = it.getCoordinate();
    const uint8_t state = tree.isNodeOccupied(*it) ? kOccupiedCell : kFreeCell;
    Eigen::Vector3i lo, up;
    bool empty = false;
    for (int a = 0; a < 3; ++a) {
      const double centre = a == 0 ? c.x() : a == 1 ? c.y() : c.z();
      lo[a] = std::max(0, static_cast<int>(std::lround((centre - half - m.origin[a]) / m.cell)));
      up[a] = std::min(m.size[a],
                       static_cast<int>(std::lround((centre + half - m.origin[a]) / m.cell)));
      empty |= lo[a] >= up[a];
    }
    if (empty) continue;
    for (int64_t k = lo.z(); k < up.z(); ++k) {
      for (int64_t j = lo.y(); j < up.y(); ++j) {
        uint8_t* row = states->data() + m.Linear(0, j, k);
        std::fill(row + lo.x(), row + up.x(), state);
      }
    }
  }
  return Status::Ok();
}

uint64_t Fingerprint(const PlanningMap::Impl& m) {
  Fnv1a64 h;
  // Eigen's fixed-size types are not trivially copyable: their coefficients are hashed.
  auto add = [&h](const auto& v) { h.AddBytes(v.data(), sizeof(*v.data()) * v.size()); };
  add(m.origin);
  add(m.size);
  h.Add(m.cell);
  add(m.planning_bounds.min);
  add(m.planning_bounds.max);
  h.Add(m.options.robot_radius_m);
  h.AddBytes(m.bits.data(), m.bits.size() * sizeof(uint64_t));
  return h.value();
}

}  // namespace

PlanningMap::PlanningMap(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
PlanningMap::~PlanningMap() = default;

Result<std::shared_ptr<const PlanningMap>> PlanningMap::LoadFile(const std::string& path,
                                                                 const MapOptions& options,
                                                                 const Termination& stop,
                                                                 const ProgressCallback& progress) {
  if (!PathExists(path)) return Status::NotFound(path + ": no such file");
  MAV_ASSIGN_OR_RETURN(const std::string bytes, ReadFileToString(path));
  return LoadBytes(bytes, path, options, stop, progress);
}

Result<std::shared_ptr<const PlanningMap>> PlanningMap::LoadBytes(
    std::string_view bt_bytes, const std::string& source, const MapOptions& options,
    const Termination& stop, const ProgressCallback& progress) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument(why);
  MAV_RETURN_IF_ERROR(stop.Check("map load"));
  const int64_t start_ns = MonotonicNowNs();

  // OcTree::readBinary trusts its input (a deep or truncated node stream overflows the stack or
  // allocates gigabytes: mav/dataset/octomap_bt.h); the bytes are validated first. A malformed
  // file is DATA_LOSS, as every corrupt file of ours.
  Result<std::unique_ptr<octomap::OcTree>> read = dataset::ReadOctomapBinary(bt_bytes, source);
  if (!read.ok()) {
    return read.status().code() == StatusCode::kInvalidArgument
               ? Status::DataLoss(read.status().message() +
                                  " (not a readable OctoMap binary tree, .bt)")
               : read.status();
  }
  octomap::OcTree& tree = **read;
  if (tree.getNumLeafNodes() == 0) return Status::DataLoss(source + ": the OctoMap has no leaves");
  if (progress) progress("octomap", 1.0);

  auto impl = std::make_unique<Impl>();
  Impl& m = *impl;
  m.options = options;
  m.cell = tree.getResolution();
  double x0, y0, z0, x1, y1, z1;
  tree.getMetricMin(x0, y0, z0);
  tree.getMetricMax(x1, y1, z1);
  const Box map_bounds{{x0, y0, z0}, {x1, y1, z1}};
  m.planning_bounds = options.planning_bounds.value_or(map_bounds);
  if (options.unknown_space == UnknownSpace::kObstacle) {
    const bool overlap = (m.planning_bounds.min.array() < map_bounds.max.array()).all() &&
                         (m.planning_bounds.max.array() > map_bounds.min.array()).all();
    if (!overlap) {
      return Status::InvalidArgument(
          "planning_bounds: outside the map (" + source +
          ") while unknown space is an obstacle: every state would be invalid");
    }
  }
  const Box grid_box = GridBox(m.planning_bounds, map_bounds, m.cell, options);
  const MemoryEstimate memory = EstimateMapMemory(grid_box, m.cell, options);
  if (options.max_memory_bytes > 0 && memory.bytes > options.max_memory_bytes) {
    return Status::ResourceExhausted(
        source + ": the planning grid needs " + std::to_string(memory.bytes) + " bytes (" +
        std::to_string(memory.grid_voxels) + " voxels x " + std::to_string(memory.bytes_per_voxel) +
        " B), above the limit max_memory_bytes = " + std::to_string(options.max_memory_bytes));
  }
  AlignToCells(grid_box, m.cell, &m.origin, &m.size);
  m.nx = m.size.x();
  m.ny = m.size.y();
  m.nz = m.size.z();

  std::vector<uint8_t> states(memory.grid_voxels, kUnknownCell);
  uint64_t leaves = 0;
  MAV_RETURN_IF_ERROR(FillStates(tree, m, stop, &states, &leaves));
  tree.clear();  // the grid holds everything from here on
  if (progress) progress("grid", 1.0);

  MapInfo& info = m.info;
  info.source = source;
  info.resolution_m = m.cell;
  info.bounds = map_bounds;
  info.planning_bounds = m.planning_bounds;
  info.octree_leaves = leaves;
  info.memory = memory;
  const bool unknown_blocks = options.unknown_space == UnknownSpace::kObstacle;
  m.words_per_row = (m.nx + 63) / 64;
  m.bits.assign(static_cast<size_t>(m.ny * m.nz * m.words_per_row), 0);
  for (int64_t k = 0; k < m.nz; ++k) {
    for (int64_t j = 0; j < m.ny; ++j) {
      uint64_t* row = m.bits.data() + (j + m.ny * k) * m.words_per_row;
      const int64_t base = m.Linear(0, j, k);
      for (int64_t i = 0; i < m.nx; ++i) {
        const uint8_t s = states[base + i];
        info.occupied_voxels += s == kOccupiedCell;
        info.free_voxels += s == kFreeCell;
        info.unknown_voxels += s == kUnknownCell;
        const bool obstacle = s == kOccupiedCell || (s == kUnknownCell && unknown_blocks);
        states[base + i] = obstacle;
        if (obstacle) row[i >> 6] |= uint64_t{1} << (i & 63);
      }
    }
  }
  info.load_ms = MsSince(start_ns);

  const int64_t edt_start_ns = MonotonicNowNs();
  const double half_diagonal = 0.5 * std::sqrt(3.0) * m.cell;
  m.saturation = static_cast<float>(options.max_distance_m + half_diagonal);
  if (options.distance_method == DistanceMethod::kDynamicEdt3d) {
    m.exact_centres = false;
    MAV_RETURN_IF_ERROR(
        internal::DynamicEdt3dDistance(m.size, states, m.cell, m.saturation, stop, &m.distance));
  } else {
    MAV_RETURN_IF_ERROR(internal::ExactCubeDistance(m.size, states, m.cell, m.saturation,
                                                    options.threads, stop, progress, &m.distance));
  }
  info.distance_map_ms = MsSince(edt_start_ns);
  info.fingerprint = Fingerprint(m);
  return std::shared_ptr<const PlanningMap>(new PlanningMap(std::move(impl)));
}

const MapInfo& PlanningMap::info() const { return impl_->info; }
const MapOptions& PlanningMap::options() const { return impl_->options; }
const Box& PlanningMap::bounds() const { return impl_->planning_bounds; }
double PlanningMap::resolution() const { return impl_->cell; }
double PlanningMap::robot_radius() const { return impl_->options.robot_radius_m; }
double PlanningMap::max_distance() const { return impl_->options.max_distance_m; }
uint64_t PlanningMap::fingerprint() const { return impl_->info.fingerprint; }
Eigen::Vector3d PlanningMap::grid_origin() const { return impl_->origin; }
Eigen::Vector3i PlanningMap::grid_size() const { return impl_->size; }

bool PlanningMap::IsObstacleCell(const Eigen::Vector3i& c) const {
  const Impl& m = *impl_;
  if ((c.array() < 0).any() || (c.array() >= m.size.array()).any()) return false;
  return m.Bit(c.x(), c.y(), c.z());
}

double PlanningMap::CellCentreClearance(const Eigen::Vector3i& c) const {
  const Impl& m = *impl_;
  if ((c.array() < 0).any() || (c.array() >= m.size.array()).any()) return 0;
  return m.distance[m.Linear(c.x(), c.y(), c.z())];
}

double PlanningMap::ClearanceLowerBound(const Eigen::Vector3d& p) const {
  const Impl& m = *impl_;
  Eigen::Vector3d q;
  Eigen::Vector3i c;
  if (!m.Locate(p, &q, &c)) return 0;
  const double d0 = (q - (c.cast<double>().array() + 0.5).matrix()).norm() * m.cell;
  return std::clamp(m.distance[m.Linear(c.x(), c.y(), c.z())] - d0, 0.0, m.options.max_distance_m);
}

double PlanningMap::ApproximateClearance(const Eigen::Vector3d& p) const {
  const Impl& m = *impl_;
  Eigen::Vector3d q;
  Eigen::Vector3i c;
  if (!m.Locate(p, &q, &c)) return 0;
  return std::min<double>(m.distance[m.Linear(c.x(), c.y(), c.z())], m.options.max_distance_m);
}

double PlanningMap::Clearance(const Eigen::Vector3d& p) const {
  return ClearanceUpTo(p, impl_->options.max_distance_m);
}

double PlanningMap::ClearanceUpTo(const Eigen::Vector3d& p, double limit) const {
  const Impl& m = *impl_;
  Eigen::Vector3d q;
  Eigen::Vector3i c;
  if (!m.Locate(p, &q, &c)) return 0;
  if (m.Bit(c.x(), c.y(), c.z())) return 0;
  limit = std::min(limit, m.options.max_distance_m);
  const double d0 = (q - (c.cast<double>().array() + 0.5).matrix()).norm() * m.cell;
  const double centre = m.distance[m.Linear(c.x(), c.y(), c.z())];
  if (centre - d0 >= limit) return limit;
  // With exact centre distances D(c) + |p - c| bounds the answer; a slightly larger limit keeps
  // the cube at exactly that distance inside the scan despite rounding.
  double scan = limit;
  if (m.exact_centres && centre < m.saturation) scan = std::min(scan, centre + d0 + 1e-6);
  return std::min(limit, std::sqrt(m.ScanSquared(q, c, scan / m.cell)) * m.cell);
}

bool PlanningMap::HasClearance(const Eigen::Vector3d& p, double required) const {
  const Impl& m = *impl_;
  Eigen::Vector3d q;
  Eigen::Vector3i c;
  if (!m.Locate(p, &q, &c)) return false;
  const double d0 = (q - (c.cast<double>().array() + 0.5).matrix()).norm() * m.cell;
  const double centre = m.distance[m.Linear(c.x(), c.y(), c.z())];
  if (centre - d0 >= required) return true;
  if (m.exact_centres && centre < m.saturation && centre + d0 < required) return false;
  if (m.Bit(c.x(), c.y(), c.z())) return false;
  // Is an obstacle cube closer than `required`? The scan reports limit^2 when none is.
  const double limit = required / m.cell;
  return m.ScanSquared(q, c, limit) >= limit * limit;
}

}  // namespace mav::planning
