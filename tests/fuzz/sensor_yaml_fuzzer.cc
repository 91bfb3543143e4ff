// libFuzzer target: cam*/sensor.yaml and imu0/sensor.yaml (dataset::Parse*SensorYaml; yaml-cpp
// underneath, whose exceptions must all come back as Status values).

#include <cmath>

#include "fuzz_checks.h"
#include "mav/dataset/euroc.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace mav;
  const std::string_view text = fuzz::AsText(data, size);
  const auto camera = dataset::ParseCameraSensorYaml(text, fuzz::kName);
  if (!camera.ok()) {
    fuzz::CheckFailure(camera.status());
  } else {
    std::string why;
    MAV_CHECK(camera->intrinsics.IsValid(&why)) << why;
    MAV_CHECK(camera->rate_hz > 0 && std::isfinite(camera->rate_hz));
  }
  const auto imu = dataset::ParseImuSensorYaml(text, fuzz::kName);
  if (!imu.ok()) {
    fuzz::CheckFailure(imu.status());
  } else {
    MAV_CHECK(imu->rate_hz > 0 && std::isfinite(imu->rate_hz));
    MAV_CHECK(std::isfinite(imu->noise.gyroscope_noise_density));
  }
  return 0;
}
