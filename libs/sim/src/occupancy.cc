#include "mav/sim/occupancy.h"

#include <bit>
#include <cmath>
#include <cstring>
#include <sstream>

#include <octomap/OcTree.h>

#include "mav/common/check.h"
#include "mav/common/file.h"
#include "mav/sim/world.h"

namespace mav::sim {
namespace {

static_assert(std::endian::native == std::endian::little, ".mavocc I/O assumes little endian");

// .mavocc layout (docs/formats.md): all integers little endian.
constexpr char kMagic[8] = {'M', 'A', 'V', 'O', 'C', 'C', '\n', '\x1a'};
constexpr uint32_t kVersion = 1;
constexpr size_t kHeaderBytes = 8 + 4 + 4 + 3 * 8 + 8 + 3 * 4 + 4 + 8;  // = 72
constexpr size_t kRunBytes = 5;

uint64_t Fnv1a64(const char* data, size_t n) {
  uint64_t h = 0xcbf29ce484222325ULL;
  for (size_t i = 0; i < n; ++i) {
    h ^= static_cast<uint8_t>(data[i]);
    h *= 0x100000001b3ULL;
  }
  return h;
}

template <typename T>
void Put(std::string* out, T value) {
  char buf[sizeof(T)];
  std::memcpy(buf, &value, sizeof(T));
  out->append(buf, sizeof(T));
}

template <typename T>
T Get(const std::string& in, size_t* pos) {
  T value;
  std::memcpy(&value, in.data() + *pos, sizeof(T));
  *pos += sizeof(T);
  return value;
}

}  // namespace

OccupancyGrid::OccupancyGrid(const Eigen::Vector3d& origin, double resolution,
                             const Eigen::Vector3i& size)
    : origin_(origin), resolution_(resolution), size_(size) {
  MAV_CHECK(resolution > 0 && std::isfinite(resolution)) << "resolution " << resolution;
  MAV_CHECK((size.array() > 0).all()) << "size " << size.transpose();
  const int64_t n = static_cast<int64_t>(size.x()) * size.y() * size.z();
  MAV_CHECK(n < (int64_t{1} << 34)) << "grid too large: " << n << " voxels";
  states_.assign(static_cast<size_t>(n), VoxelState::kUnknown);
}

bool OccupancyGrid::InBounds(const Eigen::Vector3i& index) const {
  return (index.array() >= 0).all() && (index.array() < size_.array()).all();
}

VoxelState OccupancyGrid::at(const Eigen::Vector3i& index) const {
  MAV_CHECK(InBounds(index)) << "voxel " << index.transpose() << " outside " << size_.transpose();
  return states_[static_cast<size_t>(Linear(index))];
}

void OccupancyGrid::set(const Eigen::Vector3i& index, VoxelState state) {
  MAV_CHECK(InBounds(index)) << "voxel " << index.transpose() << " outside " << size_.transpose();
  states_[static_cast<size_t>(Linear(index))] = state;
}

Eigen::Vector3i OccupancyGrid::IndexOf(const Eigen::Vector3d& p_world) const {
  const Eigen::Vector3d f = ((p_world - origin_) / resolution_).array().floor();
  const Eigen::Vector3d clamped = f.cwiseMax(-2e9).cwiseMin(2e9);
  return clamped.cast<int>();
}

Eigen::Vector3d OccupancyGrid::CenterOf(const Eigen::Vector3i& index) const {
  return origin_ + (index.cast<double>().array() + 0.5).matrix() * resolution_;
}

VoxelState OccupancyGrid::StateAt(const Eigen::Vector3d& p_world) const {
  if (!p_world.allFinite()) return VoxelState::kUnknown;
  const Eigen::Vector3i i = IndexOf(p_world);
  return InBounds(i) ? states_[static_cast<size_t>(Linear(i))] : VoxelState::kUnknown;
}

int64_t OccupancyGrid::Count(VoxelState state) const {
  int64_t n = 0;
  for (VoxelState s : states_) n += s == state;
  return n;
}

Status OccupancyGrid::Write(const std::string& path) const {
  std::string out;
  out.append(kMagic, 8);
  Put<uint32_t>(&out, kVersion);
  Put<uint32_t>(&out, 0);  // flags, reserved
  for (int k = 0; k < 3; ++k) Put<double>(&out, origin_[k]);
  Put<double>(&out, resolution_);
  for (int k = 0; k < 3; ++k) Put<int32_t>(&out, size_[k]);
  Put<uint32_t>(&out, 0);  // padding, reserved
  const size_t runs_pos = out.size();
  Put<uint64_t>(&out, 0);  // number of runs, patched below
  MAV_CHECK(out.size() == kHeaderBytes);
  uint64_t runs = 0;
  size_t i = 0;
  while (i < states_.size()) {
    const VoxelState s = states_[i];
    size_t j = i + 1;
    while (j < states_.size() && states_[j] == s && j - i < 0xffffffffULL) ++j;
    Put<uint8_t>(&out, static_cast<uint8_t>(s));
    Put<uint32_t>(&out, static_cast<uint32_t>(j - i));
    ++runs;
    i = j;
  }
  std::memcpy(out.data() + runs_pos, &runs, sizeof(runs));
  Put<uint64_t>(&out, Fnv1a64(out.data(), out.size()));
  return WriteStringToFileAtomic(path, out);
}

Result<OccupancyGrid> OccupancyGrid::Read(const std::string& path) {
  MAV_ASSIGN_OR_RETURN(const std::string data, ReadFileToString(path));
  auto loss = [&](const std::string& what) { return Status::DataLoss(path + ": " + what); };
  if (data.size() < kHeaderBytes + 8) {
    return loss("truncated: " + std::to_string(data.size()) + " bytes, header needs " +
                std::to_string(kHeaderBytes + 8));
  }
  if (std::memcmp(data.data(), kMagic, 8) != 0) return loss("not a .mavocc file (bad magic)");
  size_t pos = 8;
  const uint32_t version = Get<uint32_t>(data, &pos);
  if (version != kVersion) {
    return loss("unsupported version " + std::to_string(version) + " (expected 1)");
  }
  Get<uint32_t>(data, &pos);
  Eigen::Vector3d origin;
  for (int k = 0; k < 3; ++k) origin[k] = Get<double>(data, &pos);
  const double resolution = Get<double>(data, &pos);
  Eigen::Vector3i size;
  for (int k = 0; k < 3; ++k) size[k] = Get<int32_t>(data, &pos);
  Get<uint32_t>(data, &pos);
  const uint64_t runs = Get<uint64_t>(data, &pos);
  const uint64_t stored_sum = [&] {
    uint64_t s;
    std::memcpy(&s, data.data() + data.size() - 8, 8);
    return s;
  }();
  if (runs > (data.size() - kHeaderBytes - 8) / kRunBytes ||
      kHeaderBytes + runs * kRunBytes + 8 != data.size()) {
    return loss("size mismatch: header announces " + std::to_string(runs) + " runs (" +
                std::to_string(kHeaderBytes + runs * kRunBytes + 8) + " bytes), file has " +
                std::to_string(data.size()) + " bytes (truncated or corrupt)");
  }
  if (Fnv1a64(data.data(), data.size() - 8) != stored_sum) return loss("checksum mismatch");
  if (!origin.allFinite()) return loss("origin is not finite");
  if (!(resolution > 0) || !std::isfinite(resolution)) {
    return loss("resolution must be positive, got " + std::to_string(resolution));
  }
  if (!(size.array() > 0).all()) return loss("grid size must be positive");
  const int64_t n = static_cast<int64_t>(size.x()) * size.y() * size.z();
  if (n >= (int64_t{1} << 34)) return loss("grid too large");
  OccupancyGrid grid(origin, resolution, size);
  int64_t filled = 0;
  for (uint64_t r = 0; r < runs; ++r) {
    const uint8_t state = Get<uint8_t>(data, &pos);
    const uint32_t length = Get<uint32_t>(data, &pos);
    if (state > 2)
      return loss("run " + std::to_string(r) + ": invalid state " + std::to_string(state));
    if (length == 0 || filled + length > n) {
      return loss("run " + std::to_string(r) + ": length " + std::to_string(length) +
                  " overflows the grid");
    }
    std::fill_n(grid.states_.begin() + filled, length, static_cast<VoxelState>(state));
    filled += length;
  }
  if (filled != n) {
    return loss("runs cover " + std::to_string(filled) + " of " + std::to_string(n) + " voxels");
  }
  return grid;
}

Status OccupancyGrid::WriteOctomap(const std::string& path) const {
  octomap::OcTree tree(resolution_);
  const float occupied = tree.getClampingThresMaxLog();
  const float free = tree.getClampingThresMinLog();
  for (int z = 0; z < size_.z(); ++z) {
    for (int y = 0; y < size_.y(); ++y) {
      for (int x = 0; x < size_.x(); ++x) {
        const VoxelState s = states_[static_cast<size_t>(Linear({x, y, z}))];
        if (s == VoxelState::kUnknown) continue;
        const Eigen::Vector3d c = CenterOf({x, y, z});
        octomap::OcTreeKey key;
        if (!tree.coordToKeyChecked(
                octomap::point3d(static_cast<float>(c.x()), static_cast<float>(c.y()),
                                 static_cast<float>(c.z())),
                key)) {
          return Status::InvalidArgument(path + ": voxel centre outside OctoMap's key range");
        }
        tree.setNodeValue(key, s == VoxelState::kOccupied ? occupied : free, /*lazy_eval=*/true);
      }
    }
  }
  tree.updateInnerOccupancy();
  tree.prune();
  std::ostringstream out;
  if (!tree.writeBinary(out)) return Status::IoError(path + ": OctoMap serialisation failed");
  return WriteStringToFileAtomic(path, out.str());
}

OccupancyGrid ComputeOccupancy(const World& world, double resolution) {
  MAV_CHECK(resolution > 0 && std::isfinite(resolution)) << "resolution " << resolution;
  const Eigen::AlignedBox3d b = world.bounds();
  MAV_CHECK(!b.isEmpty()) << "world without bounds";
  Eigen::Vector3d origin;
  Eigen::Vector3i size;
  for (int k = 0; k < 3; ++k) {
    // Tolerances keep e.g. -4.2 / 0.05 from flooring to -85 through round-off.
    const double lo = std::floor(b.min()[k] / resolution + 1e-9);
    const double hi = std::ceil(b.max()[k] / resolution - 1e-9);
    origin[k] = lo * resolution;
    size[k] = std::max(1, static_cast<int>(hi - lo));
  }
  OccupancyGrid grid(origin, resolution, size);
  // Free inside the bounds, unknown outside (only partial border voxels can be outside).
  std::vector<char> inside[3];
  for (int k = 0; k < 3; ++k) {
    inside[k].resize(size[k]);
    for (int i = 0; i < size[k]; ++i) {
      const double c = origin[k] + (i + 0.5) * resolution;
      inside[k][i] = c >= b.min()[k] && c <= b.max()[k];
    }
  }
  for (int z = 0; z < size.z(); ++z) {
    for (int y = 0; y < size.y(); ++y) {
      for (int x = 0; x < size.x(); ++x) {
        if (inside[0][x] && inside[1][y] && inside[2][z]) grid.set({x, y, z}, VoxelState::kFree);
      }
    }
  }
  for (const Primitive& p : world.primitives()) {
    if (!p.solid) continue;
    const Eigen::AlignedBox3d pb = p.Bounds();
    Eigen::Vector3i i0, i1;
    for (int k = 0; k < 3; ++k) {
      i0[k] = std::max(0, static_cast<int>(std::floor((pb.min()[k] - origin[k]) / resolution)) - 1);
      i1[k] = std::min(size[k] - 1,
                       static_cast<int>(std::floor((pb.max()[k] - origin[k]) / resolution)) + 1);
    }
    for (int z = i0.z(); z <= i1.z(); ++z) {
      for (int y = i0.y(); y <= i1.y(); ++y) {
        for (int x = i0.x(); x <= i1.x(); ++x) {
          const Eigen::Vector3d lo = origin + Eigen::Vector3d(x, y, z) * resolution;
          if (p.IntersectsBox(
                  Eigen::AlignedBox3d(lo, lo + Eigen::Vector3d::Constant(resolution)))) {
            grid.set({x, y, z}, VoxelState::kOccupied);
          }
        }
      }
    }
  }
  return grid;
}

}  // namespace mav::sim
