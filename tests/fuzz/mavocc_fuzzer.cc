// libFuzzer target: the .mavocc ground-truth grid decoder (dataset::DecodeMavocc, which
// ReadMavocc runs on a file's bytes).
//
// The harness rewrites the trailing FNV-1a checksum to match the bytes (docs/formats.md), so
// that the fuzzer explores what lies behind the checksum instead of being stopped by it. A grid
// is decoded with a limit of 2^24 voxels, as a service passes its own: larger headers must be
// refused with ResourceExhausted before anything is allocated.

#include <cstring>
#include <string>

#include "fuzz_checks.h"
#include "mav/dataset/occupancy_io.h"

namespace {

constexpr size_t kHeaderBytes = 72;
constexpr int64_t kMaxVoxels = int64_t{1} << 24;

uint64_t Fnv1a64(const char* data, size_t n) {
  uint64_t h = 0xcbf29ce484222325ULL;
  for (size_t i = 0; i < n; ++i) {
    h ^= static_cast<uint8_t>(data[i]);
    h *= 0x100000001b3ULL;
  }
  return h;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace mav;
  std::string bytes(reinterpret_cast<const char*>(data), size);
  if (bytes.size() >= kHeaderBytes + 8) {
    const uint64_t sum = Fnv1a64(bytes.data(), bytes.size() - 8);
    std::memcpy(bytes.data() + bytes.size() - 8, &sum, 8);
  }
  const Result<dataset::OccupancyGrid> grid = dataset::DecodeMavocc(bytes, fuzz::kName, kMaxVoxels);
  if (!grid.ok()) {
    if (grid.status().code() == StatusCode::kResourceExhausted) {
      MAV_CHECK(grid.status().message().size() <= 1024);
      return 0;
    }
    fuzz::CheckFailure(grid.status());
    return 0;
  }
  const Eigen::Vector3i& n = grid->size();
  MAV_CHECK(grid->num_voxels() == static_cast<int64_t>(n.x()) * n.y() * n.z());
  MAV_CHECK(grid->num_voxels() <= kMaxVoxels);
  MAV_CHECK(grid->resolution() > 0 && std::isfinite(grid->resolution()));
  MAV_CHECK(grid->origin().allFinite());
  const int64_t total = grid->Count(dataset::VoxelState::kFree) +
                        grid->Count(dataset::VoxelState::kOccupied) +
                        grid->Count(dataset::VoxelState::kUnknown);
  MAV_CHECK(total == grid->num_voxels());
  return 0;
}
