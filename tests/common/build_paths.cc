#include "tests/common/build_paths.h"

namespace mav::testing {

const std::string& SourceDir() {
  static const std::string dir = MAV_SOURCE_DIR;
  return dir;
}

const std::string& BinaryDir() {
  static const std::string dir = MAV_BINARY_DIR;
  return dir;
}

}  // namespace mav::testing
