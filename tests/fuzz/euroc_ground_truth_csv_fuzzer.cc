// libFuzzer target: mav0/state_groundtruth_estimate0/data.csv (dataset::ParseGroundTruthCsv).

#include <string>
#include <vector>

#include "fuzz_checks.h"
#include "mav/dataset/euroc.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace mav;
  std::vector<std::string> warnings;
  dataset::ReadOptions options;
  options.warnings = &warnings;
  const auto states = dataset::ParseGroundTruthCsv(fuzz::AsText(data, size), fuzz::kName, options);
  if (!states.ok()) {
    fuzz::CheckFailure(states.status());
    return 0;
  }
  for (size_t i = 0; i < states->size(); ++i) {
    const dataset::GroundTruthState& g = (*states)[i];
    MAV_CHECK(i == 0 || g.t_ns > (*states)[i - 1].t_ns) << "stamps strictly increase";
    MAV_CHECK(g.T_world_body.Translation().allFinite() && g.v_world.allFinite() &&
              g.gyro_bias.allFinite() && g.accel_bias.allFinite());
    MAV_CHECK(std::abs(g.T_world_body.Rotation().norm() - 1.0) < 1e-9) << "a unit quaternion";
  }
  return 0;
}
