#include "services/common/calibration_source.h"

#include <chrono>
#include <filesystem>
#include <string>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>

#include "mav/v1/simulator.grpc.pb.h"

#include "mav/common/text.h"
#include "mav/dataset/euroc.h"
#include "services/common/grpc_status.h"

namespace mav::service_common {
namespace {

Result<RigCalibration> CalibrationFromEuroc(const std::string& directory) {
  const std::string field = "calibration.euroc_directory";
  if (directory.empty()) return Status::InvalidArgument(field + ": empty");
  namespace fs = std::filesystem;
  std::error_code error;
  if (!fs::is_directory(directory, error)) {
    return Status::NotFound(field + ": " + QuoteForError(directory) + " is not a directory");
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
    const Status failed =
        OutgoingCallStatus(status, field + ": GetCalibration at " + address, "a mav-simulator");
    // FAILED_PRECONDITION (nothing loaded) and INVALID_ARGUMENT pass through; for the caller
    // everything else (unreachable, timed out, not a simulator) means the source is unavailable.
    if (failed.code() == StatusCode::kFailedPrecondition ||
        failed.code() == StatusCode::kInvalidArgument) {
      return failed;
    }
    return Status::Unavailable(failed.message());
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

void CalibrationFlags::Register(FlagParser* flags, const std::string& for_flag) {
  flags->AddString("euroc", &euroc, "calibration for " + for_flag + ": an EuRoC directory");
  flags->AddString("simulator", &simulator,
                   "calibration for " + for_flag + ": a mav-simulator's host:port");
}

Result<std::optional<v1::CalibrationSource>> CalibrationFlags::Source(
    bool wanted, const std::string& for_flag) const {
  const bool given = !euroc.empty() || !simulator.empty();
  if (!wanted) {
    if (given) return Status::InvalidArgument("--euroc/--simulator only go with " + for_flag);
    return std::optional<v1::CalibrationSource>();
  }
  if (euroc.empty() == simulator.empty()) {
    return Status::InvalidArgument(for_flag + " needs exactly one of --euroc or --simulator");
  }
  v1::CalibrationSource source;
  if (!euroc.empty()) {
    source.set_euroc_directory(euroc);
  } else {
    source.set_simulator_address(simulator);
  }
  return std::optional<v1::CalibrationSource>(std::move(source));
}

}  // namespace mav::service_common
