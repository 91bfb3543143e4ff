// libFuzzer target: TUM trajectories (dataset::ParseTumTrajectory), lenient and strict.

#include <cmath>
#include <string_view>

#include "fuzz_checks.h"
#include "mav/dataset/trajectory_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace mav;
  fuzz::CheckLenientAndStrictReads(
      fuzz::AsText(data, size),
      [](std::string_view text, const char* name, const dataset::ReadOptions& options) {
        return dataset::ParseTumTrajectory(text, name, options);
      },
      [](const dataset::StampedPose& p) {
        MAV_CHECK(p.T_world_body.Translation().allFinite());
        MAV_CHECK(std::abs(p.T_world_body.Rotation().norm() - 1.0) < 1e-9) << "a unit quaternion";
      });
  return 0;
}
