// libFuzzer target: OctoMap binary trees (.bt) as the planning service will receive them:
// dataset::ReadOctomapBinary validates the bytes (mav/dataset/octomap_bt.h) and only then calls
// octomap::OcTree::readBinary(std::istream&). Asserts that OctoMap reads every validated input
// to exactly the validated node count, so the validation and OctoMap never disagree.

#include <octomap/OcTree.h>

#include "fuzz_checks.h"
#include "mav/dataset/octomap_bt.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace mav;
  dataset::OctomapReadLimits limits;
  limits.max_nodes = 1'000'000;  // <= 112 MB of tree, within libFuzzer's 2 GB RSS limit
  const auto tree = dataset::ReadOctomapBinary(fuzz::AsText(data, size), fuzz::kName, limits);
  if (!tree.ok()) {
    // Internal would mean OctoMap refused what the validation accepted.
    fuzz::CheckFailure(tree.status());
    return 0;
  }
  // Touch the tree as a user would.
  size_t leaves = 0;
  for (auto it = (*tree)->begin_leafs(); it != (*tree)->end_leafs(); ++it) ++leaves;
  MAV_CHECK(leaves == (*tree)->getNumLeafNodes());
  return 0;
}
