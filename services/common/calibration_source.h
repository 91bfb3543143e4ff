#pragma once
// Where a service gets its stereo calibration from (common.proto's CalibrationSource): inline,
// an EuRoC directory's cam0/cam1 sensor.yaml, or a running simulator's GetCalibration.

#include <cstdint>

#include "mav/v1/common.pb.h"

#include "services/common/proto_codec.h"

namespace mav::services {

// InvalidArgument naming the field for a bad inline calibration or an unset source; NotFound for
// a missing directory or sensor.yaml (InvalidArgument naming file and key when malformed);
// Unavailable when the simulator is unreachable within `timeout_ms`, FailedPrecondition when it
// has nothing loaded. Messages start with the field path "calibration...".
Result<RigCalibration> ResolveCalibration(const v1::CalibrationSource& source, int64_t timeout_ms);

}  // namespace mav::services
