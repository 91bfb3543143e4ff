// Where the tests find the source tree (tests/data, maps/, deploy/) and the build tree (bin/,
// Testing/). Absolute paths of the tree this test was built in, so a test runs from any
// directory. They live in one object (build_paths.cc) rather than in -D flags on every test,
// which would make ccache miss on each test source in every new clone (docs/quality.md).
#pragma once

#include <string>

namespace mav::testing {

// The source root, e.g. SourceDir() + "/maps/power_plant.bt". No trailing slash.
const std::string& SourceDir();
// The build directory (CMAKE_BINARY_DIR), e.g. BinaryDir() + "/bin/mav-sim". No trailing slash.
const std::string& BinaryDir();

}  // namespace mav::testing
