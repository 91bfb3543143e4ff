#include "mav/dataset/occupancy_io.h"

#include <algorithm>
#include <bit>
#include <cstring>
#include <sstream>

#include <octomap/OcTree.h>

#include "mav/common/check.h"
#include "mav/common/file.h"
#include "mav/common/hash.h"

namespace mav::dataset {
namespace {

static_assert(std::endian::native == std::endian::little, ".mavocc I/O assumes little endian");

// .mavocc layout (docs/formats.md): all integers little endian.
constexpr char kMagic[8] = {'M', 'A', 'V', 'O', 'C', 'C', '\n', '\x1a'};
constexpr uint32_t kVersion = 1;
constexpr size_t kHeaderBytes = 8 + 4 + 4 + 3 * 8 + 8 + 3 * 4 + 4 + 8;  // = 72
constexpr size_t kRunBytes = 5;

template <typename T>
void Put(std::string* out, T value) {
  char buf[sizeof(T)];
  std::memcpy(buf, &value, sizeof(T));
  out->append(buf, sizeof(T));
}

template <typename T>
T Get(std::string_view in, size_t* pos) {
  T value;
  std::memcpy(&value, in.data() + *pos, sizeof(T));
  *pos += sizeof(T);
  return value;
}

}  // namespace

std::string EncodeMavocc(const OccupancyGrid& grid) {
  const GridGeometry& g = grid.geometry();
  const std::vector<VoxelState>& states = grid.states();
  std::string out;
  out.append(kMagic, 8);
  Put<uint32_t>(&out, kVersion);
  Put<uint32_t>(&out, 0);  // flags, reserved
  for (int k = 0; k < 3; ++k) Put<double>(&out, g.origin[k]);
  Put<double>(&out, g.resolution);
  for (int k = 0; k < 3; ++k) Put<int32_t>(&out, g.size[k]);
  Put<uint32_t>(&out, 0);  // padding, reserved
  const size_t runs_pos = out.size();
  Put<uint64_t>(&out, 0);  // number of runs, patched below
  MAV_CHECK(out.size() == kHeaderBytes);
  uint64_t runs = 0;
  size_t i = 0;
  while (i < states.size()) {
    const VoxelState s = states[i];
    size_t j = i + 1;
    while (j < states.size() && states[j] == s && j - i < 0xffffffffULL) ++j;
    Put<uint8_t>(&out, static_cast<uint8_t>(s));
    Put<uint32_t>(&out, static_cast<uint32_t>(j - i));
    ++runs;
    i = j;
  }
  std::memcpy(out.data() + runs_pos, &runs, sizeof(runs));
  Put<uint64_t>(&out, Fnv1a64::Of(out.data(), out.size()));
  return out;
}

Status WriteMavocc(const OccupancyGrid& grid, const std::string& path) {
  return WriteStringToFileAtomic(path, EncodeMavocc(grid));
}

Result<OccupancyGrid> DecodeMavocc(std::string_view data, const std::string& name,
                                   int64_t max_voxels) {
  auto loss = [&](const std::string& what) { return Status::DataLoss(name + ": " + what); };
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
  GridGeometry geometry;
  for (int k = 0; k < 3; ++k) geometry.origin[k] = Get<double>(data, &pos);
  geometry.resolution = Get<double>(data, &pos);
  for (int k = 0; k < 3; ++k) geometry.size[k] = Get<int32_t>(data, &pos);
  Get<uint32_t>(data, &pos);
  const uint64_t runs = Get<uint64_t>(data, &pos);
  uint64_t stored_sum;
  std::memcpy(&stored_sum, data.data() + data.size() - 8, 8);
  if (runs > (data.size() - kHeaderBytes - 8) / kRunBytes ||
      kHeaderBytes + runs * kRunBytes + 8 != data.size()) {
    return loss("size mismatch: header announces " + std::to_string(runs) + " runs (" +
                std::to_string(kHeaderBytes + runs * kRunBytes + 8) + " bytes), file has " +
                std::to_string(data.size()) + " bytes (truncated or corrupt)");
  }
  if (Fnv1a64::Of(data.data(), data.size() - 8) != stored_sum) return loss("checksum mismatch");
  std::string why;
  if (!geometry.IsValid(&why)) return loss(why);
  if (geometry.num_voxels() > max_voxels) {
    return Status::ResourceExhausted(name + ": " + std::to_string(geometry.num_voxels()) +
                                     " voxels exceed the limit of " + std::to_string(max_voxels));
  }
  const int64_t n = geometry.num_voxels();
  std::vector<VoxelState> states(static_cast<size_t>(n), VoxelState::kUnknown);
  int64_t filled = 0;
  for (uint64_t r = 0; r < runs; ++r) {
    const uint8_t state = Get<uint8_t>(data, &pos);
    const uint32_t length = Get<uint32_t>(data, &pos);
    if (state > 2) {
      return loss("run " + std::to_string(r) + ": invalid state " + std::to_string(state));
    }
    if (length == 0 || filled + length > n) {
      return loss("run " + std::to_string(r) + ": length " + std::to_string(length) +
                  " overflows the grid");
    }
    std::fill_n(states.begin() + filled, length, static_cast<VoxelState>(state));
    filled += length;
  }
  if (filled != n) {
    return loss("runs cover " + std::to_string(filled) + " of " + std::to_string(n) + " voxels");
  }
  return OccupancyGrid(geometry, std::move(states));
}

Result<OccupancyGrid> ReadMavocc(const std::string& path, int64_t max_voxels) {
  MAV_ASSIGN_OR_RETURN(const std::string data, ReadFileToString(path));
  return DecodeMavocc(data, path, max_voxels);
}

Result<std::string> EncodeOctomapBt(const OccupancyGrid& grid) {
  octomap::OcTree tree(grid.resolution());
  const float occupied = tree.getClampingThresMaxLog();
  const float free = tree.getClampingThresMinLog();
  const Eigen::Vector3i& n = grid.size();
  for (int k = 0; k < n.z(); ++k) {
    for (int j = 0; j < n.y(); ++j) {
      for (int i = 0; i < n.x(); ++i) {
        const VoxelState s = grid[grid.Linear(i, j, k)];
        if (s == VoxelState::kUnknown) continue;
        const Eigen::Vector3d c = grid.CenterOf({i, j, k});
        octomap::OcTreeKey key;
        if (!tree.coordToKeyChecked(
                octomap::point3d(static_cast<float>(c.x()), static_cast<float>(c.y()),
                                 static_cast<float>(c.z())),
                key)) {
          return Status::InvalidArgument("voxel centre outside OctoMap's key range");
        }
        tree.setNodeValue(key, s == VoxelState::kOccupied ? occupied : free, /*lazy_eval=*/true);
      }
    }
  }
  tree.updateInnerOccupancy();
  tree.prune();
  std::ostringstream out;
  if (!tree.writeBinary(out)) return Status::Internal("OctoMap serialisation failed");
  return out.str();
}

Status WriteOctomapBt(const OccupancyGrid& grid, const std::string& path) {
  Result<std::string> bytes = EncodeOctomapBt(grid);
  if (!bytes.ok()) return bytes.status().WithContext(path);
  return WriteStringToFileAtomic(path, *bytes);
}

}  // namespace mav::dataset
