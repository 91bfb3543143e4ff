// libFuzzer target: the .mavocc ground-truth grid reader (today sim::OccupancyGrid::Read, which
// takes a path: the bytes are handed over as /proc/self/fd/N of a memfd, no file on disk).
//
// Two things the harness does that a file from a user would not need:
//  * it rewrites the trailing FNV-1a checksum to match the bytes (docs/formats.md), so the
//    fuzzer explores what lies behind the checksum instead of being stopped by it;
//  * it skips headers that announce more than kMaxVoxels voxels, because Read allocates the
//    whole grid (up to 2^34 bytes) before it has checked that the runs fill it: a 85-byte file
//    asks for 16 GiB. The reader needs a voxel limit from its caller (reported in
//    docs/quality.md); until it has one, this harness enforces 2^24 voxels (16 MiB).

#include <sys/mman.h>
#include <unistd.h>

#include <cstring>
#include <string>

#include "fuzz_checks.h"
#include "mav/sim/occupancy.h"

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

// The grid size the header announces (int32 x, y, z at byte 48), 0 if it is not positive. In
// double: the product of three int32 overflows int64.
double AnnouncedVoxels(const std::string& bytes) {
  int32_t n[3];
  std::memcpy(n, bytes.data() + 48, sizeof(n));
  if (n[0] <= 0 || n[1] <= 0 || n[2] <= 0) return 0;
  return static_cast<double>(n[0]) * n[1] * n[2];
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace mav;
  std::string bytes(reinterpret_cast<const char*>(data), size);
  if (bytes.size() >= kHeaderBytes + 8) {
    if (AnnouncedVoxels(bytes) > static_cast<double>(kMaxVoxels)) return -1;  // not kept
    const uint64_t sum = Fnv1a64(bytes.data(), bytes.size() - 8);
    std::memcpy(bytes.data() + bytes.size() - 8, &sum, 8);
  }
  static const int fd = memfd_create("mavocc-fuzz", 0);
  MAV_CHECK(fd >= 0);
  MAV_CHECK(ftruncate(fd, 0) == 0);
  MAV_CHECK(pwrite(fd, bytes.data(), bytes.size(), 0) == static_cast<ssize_t>(bytes.size()));
  const std::string path = "/proc/self/fd/" + std::to_string(fd);
  const auto grid = sim::OccupancyGrid::Read(path);
  if (!grid.ok()) {
    // The reader names its path, not our input name: check the rest of CheckFailure's promises.
    MAV_CHECK(grid.status().code() == StatusCode::kDataLoss) << grid.status().ToString();
    MAV_CHECK(grid.status().message().size() <= 1024);
    return 0;
  }
  const Eigen::Vector3i& n = grid->size();
  MAV_CHECK(grid->num_voxels() == static_cast<int64_t>(n.x()) * n.y() * n.z());
  MAV_CHECK(grid->resolution() > 0 && std::isfinite(grid->resolution()));
  MAV_CHECK(grid->origin().allFinite());
  for (sim::VoxelState s : grid->states()) MAV_CHECK(static_cast<int>(s) <= 2);
  return 0;
}
