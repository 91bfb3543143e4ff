#pragma once
// Where a service gets its stereo calibration from (common.proto's CalibrationSource): inline,
// an EuRoC directory's cam0/cam1 sensor.yaml, or a running simulator's GetCalibration.

#include <cstdint>
#include <optional>
#include <string>

#include "mav/v1/common.pb.h"

#include "mav/common/flags.h"
#include "services/common/proto_codec.h"

namespace mav::service_common {

// InvalidArgument naming the field for a bad inline calibration or an unset source; NotFound for
// a missing directory or sensor.yaml (InvalidArgument naming file and key when malformed);
// Unavailable when the simulator is unreachable within `timeout_ms`, FailedPrecondition when it
// has nothing loaded. Messages start with the field path "calibration...".
Result<RigCalibration> ResolveCalibration(const v1::CalibrationSource& source, int64_t timeout_ms);

// The --euroc DIR / --simulator HOST:PORT flags of a service main: where a configuration made at
// start-up (--method, --pose-source, ...) takes its calibration from.
struct CalibrationFlags {
  std::string euroc;
  std::string simulator;

  // Registers both flags; `for_flag` names the flag they serve ("--method").
  void Register(FlagParser* flags, const std::string& for_flag);
  // The source when exactly one is given and `wanted` (the start-up flag was given); nullopt when
  // neither is given and not wanted. InvalidArgument with the flag names otherwise.
  Result<std::optional<v1::CalibrationSource>> Source(bool wanted,
                                                      const std::string& for_flag) const;
};

}  // namespace mav::service_common
