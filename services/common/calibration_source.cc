#include "services/common/calibration_source.h"

#include <chrono>
#include <filesystem>
#include <string>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>

#include "mav/v1/simulator.grpc.pb.h"

#include "mav/dataset/euroc.h"

namespace mav::services {
namespace {

Result<RigCalibration> CalibrationFromEuroc(const std::string& directory) {
  const std::string field = "calibration.euroc_directory";
  if (directory.empty()) return Status::InvalidArgument(field + ": empty");
  namespace fs = std::filesystem;
  std::error_code error;
  if (!fs::is_directory(directory, error)) {
    return Status::NotFound(field + ": '" + directory + "' is not a directory");
  }
  // The directory holding mav0/, or mav0/ itself.
  fs::path mav0 = fs::path(directory) / "mav0";
  if (!fs::is_directory(mav0, error)) mav0 = fs::path(directory);
  const fs::path cam0 = mav0 / "cam0" / "sensor.yaml";
  const fs::path cam1 = mav0 / "cam1" / "sensor.yaml";
  for (const fs::path& path : {cam0, cam1}) {
    if (!fs::is_regular_file(path, error)) {
      return Status::NotFound(field + ": " + path.string() + " does not exist");
    }
  }
  Result<dataset::CameraSensor> left = dataset::ReadCameraSensorYaml(cam0.string());
  if (!left.ok()) {
    return Status(left.status().code(), field + ": " + left.status().message());
  }
  Result<dataset::CameraSensor> right = dataset::ReadCameraSensorYaml(cam1.string());
  if (!right.ok()) {
    return Status(right.status().code(), field + ": " + right.status().message());
  }
  RigCalibration out;
  out.calibration.cam0 = left->intrinsics;
  out.calibration.cam1 = right->intrinsics;
  out.calibration.T_body_cam0 = left->T_body_cam;
  out.calibration.T_body_cam1 = right->T_body_cam;
  out.rectified = false;  // EuRoC images are raw; an undistorted rig rectifies to itself
  std::string why;
  if (!out.calibration.IsValid(&why)) return Status::InvalidArgument(field + ": " + why);
  return out;
}

Result<RigCalibration> CalibrationFromSimulator(const std::string& address, int64_t timeout_ms) {
  const std::string field = "calibration.simulator_address";
  if (address.empty()) return Status::InvalidArgument(field + ": empty");
  auto channel = grpc::CreateChannel(address, grpc::InsecureChannelCredentials());
  auto stub = v1::Simulator::NewStub(channel);
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(timeout_ms));
  v1::GetCalibrationResponse response;
  const grpc::Status status =
      stub->GetCalibration(&context, v1::GetCalibrationRequest(), &response);
  if (!status.ok()) {
    const std::string text =
        field + ": GetCalibration at " + address + ": " + status.error_message();
    switch (status.error_code()) {
      case grpc::StatusCode::FAILED_PRECONDITION:
        return Status::FailedPrecondition(text);
      case grpc::StatusCode::INVALID_ARGUMENT:
        return Status::InvalidArgument(text);
      default:
        // Unreachable, timed out, shutting down, or not a simulator at all.
        return Status::Unavailable(text);
    }
  }
  return CalibrationFromProto(response.stereo(), field + " (GetCalibration.stereo)");
}

}  // namespace

Result<RigCalibration> ResolveCalibration(const v1::CalibrationSource& source, int64_t timeout_ms) {
  switch (source.source_case()) {
    case v1::CalibrationSource::kCalibration:
      return CalibrationFromProto(source.calibration(), "calibration.calibration");
    case v1::CalibrationSource::kEurocDirectory:
      return CalibrationFromEuroc(source.euroc_directory());
    case v1::CalibrationSource::kSimulatorAddress:
      return CalibrationFromSimulator(source.simulator_address(), timeout_ms);
    case v1::CalibrationSource::SOURCE_NOT_SET:
      break;
  }
  return Status::InvalidArgument(
      "calibration: not set; give calibration, euroc_directory or simulator_address");
}

}  // namespace mav::services
