// libFuzzer target: mission files (dataset::ParseMissionYaml, what `mav-eval mission` and
// `mavctl mission run` read). A refusal must be an InvalidArgument naming the input with a
// bounded message; what parses must keep MissionSpec's limits.

#include <string>

#include "fuzz_checks.h"
#include "mav/dataset/mission_file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace mav;
  const std::string text(fuzz::AsText(data, size));
  const Result<dataset::MissionSpec> mission = dataset::ParseMissionYaml(text, fuzz::kName);
  if (!mission.ok()) {
    fuzz::CheckFailure(mission.status());
    return 0;
  }
  std::string why;
  MAV_CHECK(mission->IsValid(&why)) << why.substr(0, 300);
  for (const dataset::MissionGoal& g : mission->goals) MAV_CHECK(g.line >= 1);
  return 0;
}
