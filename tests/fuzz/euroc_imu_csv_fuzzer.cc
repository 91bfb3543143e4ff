// libFuzzer target: mav0/imu0/data.csv (dataset::ParseImuCsv), lenient and strict.

#include <string_view>

#include "fuzz_checks.h"
#include "mav/dataset/euroc.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace mav;
  fuzz::CheckLenientAndStrictReads(
      fuzz::AsText(data, size),
      [](std::string_view text, const char* name, const dataset::ReadOptions& options) {
        return dataset::ParseImuCsv(text, name, options);
      },
      [](const dataset::ImuSample& s) {
        MAV_CHECK(s.gyro.allFinite() && s.accel.allFinite());
        MAV_CHECK(s.gyro.cwiseAbs().maxCoeff() <= 1e9 && s.accel.cwiseAbs().maxCoeff() <= 1e9);
      });
  return 0;
}
