#pragma once
// mav.v1 control messages <-> the control service's domain types (control_core.h, libs/control).
// Validation of request fields happens here, with messages that start with the field path as the
// request spells it ("estimator.pose_sources[1].rate_hz: ...", "trajectory.segments[2].x: ...").
// Option fields: 0 (or unset) = the library's default, as control.proto documents.

#include <string>

#include "mav/v1/common.pb.h"
#include "mav/v1/control.pb.h"
#include "mav/v1/planning.pb.h"
#include "services/common/proto_codec.h"

#include "mav/common/status.h"
#include "mav/control/autopilot.h"
#include "mav/dataset/flight_task.h"
#include "mav/geometry/polynomial_trajectory.h"
#include "services/control/control_core.h"

namespace mav::control_service {

using service_common::PoseFromProto;
using service_common::ToProto;  // geometry::SE3 -> v1::Pose, RuntimeStats

// The whole configuration; InvalidArgument naming the field (the library's checks included, with
// its field names translated to the proto's).
Result<ControlConfig> ConfigFromProto(const v1::ControlConfigureRequest& request);
// The effective configuration (every default filled in).
void ToProto(const ControlConfig& config, v1::ControlConfigureRequest* out);

// `field` prefixes the messages ("gains", "lee_gains", "limits"); 0 components = defaults.
Result<control::PaperControllerGains> PaperGainsFromProto(const v1::ControllerGains& gains,
                                                          const std::string& field);
Result<control::LeeControllerGains> LeeGainsFromProto(const v1::LeeGains& gains,
                                                      const std::string& field);
Result<control::GoToLimits> LimitsFromProto(const v1::GoToLimits& limits, const std::string& field);
// The shared messages (vectors, trajectories) go through the one codec.
using service_common::ToProto;
using service_common::TrajectoryFromProto;
using service_common::VectorFromProto;

v1::ControlMode ToProto(control::FlightMode mode);
void ToProto(const ControlCoreStatus& status, bool dds_input, v1::ControlStatus* out);
void ToProto(const ControlCoreState& state, v1::ControlState* out);

// The enums of control.proto (tests/contract/shared_messages_test.cc checks each table).
// UNSPECIFIED means PAPER.
inline constexpr auto kControllerCodec =
    service_common::MakeEnumCodec<v1::ControllerType, control::ControllerType>(
        v1::ControllerType_descriptor,
        {{v1::CONTROLLER_TYPE_PAPER, control::ControllerType::kPaper},
         {v1::CONTROLLER_TYPE_LEE, control::ControllerType::kLee}},
        control::ControllerType::kPaper);

// UNSPECIFIED means MOTORS_OFF.
inline constexpr auto kImuLossPolicyCodec =
    service_common::MakeEnumCodec<v1::ImuLossPolicy, control::ImuLossPolicy>(
        v1::ImuLossPolicy_descriptor,
        {{v1::IMU_LOSS_POLICY_MOTORS_OFF, control::ImuLossPolicy::kMotorsOff},
         {v1::IMU_LOSS_POLICY_HOLD_LAST_COMMAND, control::ImuLossPolicy::kHoldLastCommand}},
        control::ImuLossPolicy::kMotorsOff);

}  // namespace mav::control_service
