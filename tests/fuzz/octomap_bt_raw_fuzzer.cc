// libFuzzer target, not run in CI: octomap::OcTree::readBinary(std::istream&) on raw bytes,
// without our validation, to record what OctoMap itself does with malformed input
// (docs/quality.md). Expected to crash: that is the reason for dataset::ReadOctomapBinary.

#include <octomap/OcTree.h>

#include <sstream>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  octomap::OcTree tree(0.1);
  tree.readBinary(in);
  return 0;
}
