// libFuzzer target: mav0/imu0/data.csv (dataset::ParseImuCsv), lenient and strict.

#include <cmath>
#include <string>
#include <vector>

#include "fuzz_checks.h"
#include "mav/dataset/euroc.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace mav;
  const std::string_view text = fuzz::AsText(data, size);
  std::vector<std::string> warnings;
  dataset::ReadOptions options;
  options.warnings = &warnings;
  const auto samples = dataset::ParseImuCsv(text, fuzz::kName, options);
  if (!samples.ok()) {
    fuzz::CheckFailure(samples.status());
  } else {
    for (size_t i = 0; i < samples->size(); ++i) {
      const dataset::ImuSample& s = (*samples)[i];
      MAV_CHECK(i == 0 || s.t_ns > (*samples)[i - 1].t_ns) << "stamps strictly increase";
      MAV_CHECK(s.gyro.allFinite() && s.accel.allFinite());
      MAV_CHECK(s.gyro.cwiseAbs().maxCoeff() <= 1e9 && s.accel.cwiseAbs().maxCoeff() <= 1e9);
    }
  }
  dataset::ReadOptions strict;
  strict.repeated_stamps = dataset::RepeatedStamps::kReject;
  const auto strict_samples = dataset::ParseImuCsv(text, fuzz::kName, strict);
  // Strict accepts exactly the lenient reads that dropped nothing.
  MAV_CHECK(strict_samples.ok() == (samples.ok() && warnings.empty()));
  return 0;
}
