#pragma once
// Reading OctoMap binary trees (.bt, Hornung et al., "OctoMap: an efficient probabilistic 3D
// mapping framework based on octrees", Autonomous Robots 2013) from bytes that nobody vouches
// for, e.g. a map uploaded to the planning service.
//
// octomap::OcTree::readBinary trusts its input. Found by reading OctoMap 1.9.7's source and
// checked with tests/fuzz/octomap_bt_raw_fuzzer (ASan + UBSan; docs/quality.md):
//  * the node recursion has no depth limit: every "has children" bit pair recurses again, so
//    2 MB of 0xff bytes after a valid header overflow the stack (ASan stack-overflow in
//    OccupancyOcTreeBase::readBinaryNode);
//  * at the end of the stream read() fails and readBinaryNode goes on with the uninitialised
//    bytes of its locals: 4 KB of 0xff bytes made it allocate more than 2 GB (libFuzzer
//    out-of-memory) before the size check could refuse the file;
//  * the header's "res" is only checked for <= 0 (1e-320 passes), and the header-less pre-2010
//    format reads it as raw bytes, so NaN passes too;
//  * memory is up to 8 nodes per 2 bytes of input, with no limit (the power plant's 97 KB file
//    holds 377,475 nodes), and the header's "size" is compared only after the whole tree is built.
// So the bytes are validated here first, by walking the same bit structure iteratively with a
// depth limit of 16 and a node budget, and only then given to OctoMap.
//
// This header does not include OctoMap; callers that use the tree include <octomap/OcTree.h>.

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "mav/common/status.h"

namespace octomap {
class OcTree;
}

namespace mav::dataset {

struct OctomapReadLimits {
  // Most tree nodes accepted (inner nodes and leaves, as OcTree::size() counts them). OctoMap
  // needs 44 bytes of heap per node for the EuRoC power plant (maps/power_plant.bt,
  // 0.25 m: 377,475 nodes in 16.6 MB) and at most ~112 (a node, plus an 8-pointer child array
  // when it is an inner node), so the default means ~440 MB, at worst 1.1 GB. A service sets
  // its own limit.
  int64_t max_nodes = 10'000'000;
  // Accepted voxel edge [m]: finer than 1 mm or coarser than 100 m is no map of a MAV's world.
  double min_resolution_m = 0.001;
  double max_resolution_m = 100.0;

  bool IsValid(std::string* why) const;
};

// What the header and the node walk found.
struct OctomapBinaryInfo {
  std::string id;           // the header's tree type ("OcTree", "ColorOcTree", ...)
  double resolution_m = 0;  // "res"
  int64_t num_nodes = 0;    // nodes the data describes (== the header's "size")
  int64_t data_bytes = 0;   // bytes of node data after the header
};

// Checks that `bytes` is a complete, well-formed OctoMap binary file within `limits`, without
// building the tree: first line "# Octomap OcTree binary file", then "id", "size", "res" and
// "data" lines ('#' comments allowed), then exactly the node data the bit structure announces,
// at most 16 levels deep, holding `size` nodes. InvalidArgument naming `name` and what is wrong
// ("name: header: res: ...", "name: node data ends after 123 of 124 bytes", "name: size says 9
// nodes, the data has 17"), including a violated limit; the legacy header-less format is refused.
Status ValidateOctomapBinary(std::string_view bytes, const std::string& name,
                             const OctomapReadLimits& limits = {},
                             OctomapBinaryInfo* info = nullptr);

// ValidateOctomapBinary, then octomap::OcTree::readBinary on the bytes. Internal if OctoMap still
// refuses what the validation accepted (a bug in the validation).
Result<std::unique_ptr<octomap::OcTree>> ReadOctomapBinary(std::string_view bytes,
                                                           const std::string& name,
                                                           const OctomapReadLimits& limits = {});

}  // namespace mav::dataset
