// libFuzzer target: KITTI odometry poses (dataset::ParseKittiMatrices / ParseKittiTrajectory).

#include "fuzz_checks.h"
#include "mav/dataset/trajectory_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace mav;
  const std::string_view text = fuzz::AsText(data, size);
  const auto matrices = dataset::ParseKittiMatrices(text, fuzz::kName);
  if (!matrices.ok()) fuzz::CheckFailure(matrices.status());
  const auto poses = dataset::ParseKittiTrajectory(text, fuzz::kName);
  if (!poses.ok()) {
    fuzz::CheckFailure(poses.status());
    return 0;
  }
  MAV_CHECK(matrices.ok() && matrices->size() == poses->size());
  for (const auto& pose : *poses) {
    MAV_CHECK(pose.Translation().allFinite());
    MAV_CHECK(std::abs(pose.Rotation().norm() - 1.0) < 1e-9) << "a unit quaternion";
  }
  return 0;
}
