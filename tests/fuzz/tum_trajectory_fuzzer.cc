// libFuzzer target: TUM trajectories (dataset::ParseTumTrajectory), lenient and strict.

#include <string>
#include <vector>

#include "fuzz_checks.h"
#include "mav/dataset/trajectory_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace mav;
  const std::string_view text = fuzz::AsText(data, size);
  std::vector<std::string> warnings;
  dataset::ReadOptions options;
  options.warnings = &warnings;
  const auto poses = dataset::ParseTumTrajectory(text, fuzz::kName, options);
  if (!poses.ok()) {
    fuzz::CheckFailure(poses.status());
  } else {
    for (size_t i = 0; i < poses->size(); ++i) {
      const dataset::StampedPose& p = (*poses)[i];
      MAV_CHECK(i == 0 || p.t_ns > (*poses)[i - 1].t_ns) << "stamps strictly increase";
      MAV_CHECK(p.T_world_body.Translation().allFinite());
      MAV_CHECK(std::abs(p.T_world_body.Rotation().norm() - 1.0) < 1e-9) << "a unit quaternion";
    }
  }
  dataset::ReadOptions strict;
  strict.repeated_stamps = dataset::RepeatedStamps::kReject;
  MAV_CHECK(dataset::ParseTumTrajectory(text, fuzz::kName, strict).ok() ==
            (poses.ok() && warnings.empty()));
  return 0;
}
