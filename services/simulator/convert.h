#pragma once
// mav.v1 simulator messages <-> the simulator's domain types (player.h). Validation of request
// fields happens here, with messages that start with the field path ("real_time_factor: ...").

#include <string>

#include "mav/v1/common.pb.h"
#include "mav/v1/simulator.pb.h"
#include "services/common/proto_codec.h"

#include "mav/camera/stereo.h"
#include "mav/common/status.h"
#include "mav/dataset/types.h"
#include "mav/eval/contest_score.h"
#include "services/simulator/flight.h"
#include "services/simulator/player.h"

namespace mav::simulator_service {

// Which scenario a LoadScenarioRequest asks for.
struct LoadRequest {
  bool is_preset = false;
  sim::PresetRequest preset;
  std::string euroc_directory;
};
// InvalidArgument "source: ..." when neither preset nor euroc is set. Field values are checked
// by OpenPreset/OpenEuroc.
Result<LoadRequest> FromProto(const v1::LoadScenarioRequest& request);

// InvalidArgument "real_time_factor: ..." (none/both, <= 0, not finite),
// "as_fast_as_subscribers: ..." (set to false), "wait_timeout_s: ..." (< 0, not finite).
Result<Pacing> FromProto(const v1::SimulatorStartRequest& request);

// A LoadFlightTaskRequest: where the task comes from and the flight's options (config.task is
// left for the service to resolve). InvalidArgument "task: ..." when no source is set, "builtin:
// empty", "path: empty", "yaml: empty"; the ranges are FlightConfig::IsValid's.
struct FlightLoadRequest {
  enum class Source { kBuiltin, kYaml, kPath, kMission };
  Source source = Source::kBuiltin;
  std::string value;  // the task name, the YAML text or the file path
  // kMission: the parsed mission and its vehicle (config.task is MissionFlightTask's).
  dataset::MissionSpec mission;
  mission::VehicleOptions vehicle;
  std::string map_path;  // replaces the task's map when not empty
  FlightConfig config;
};
// InvalidArgument "mission.<field>: ..." for a bad vehicle option.
Result<mission::VehicleOptions> FromProto(const v1::MissionFlight& request, uint64_t seed);
Result<FlightLoadRequest> FromProto(const v1::LoadFlightTaskRequest& request);
// InvalidArgument "run_until_s: ..." (not finite, negative). "Not after the flight's time" is the
// Flight's check.
Result<FlightRun> FromProto(const v1::StartFlightRequest& request);

void ToProto(const FlightConfig& config, v1::FlightTaskSummary* out);
void ToProto(const eval::TaskScore& score, v1::FlightScore* out);
void ToProto(const FlightStatus& status, v1::FlightStatus* out);
v1::FlightState ToProto(FlightState state);

void ToProto(const ScenarioInfo& info, v1::ScenarioSummary* out);
void ToProto(const PlayerStatus& status, v1::SimulatorStatus* out);
using service_common::ToProto;  // vectors, poses, intrinsics, RuntimeStats
void ToProto(const camera::StereoCalibration& calibration, double rate_hz, bool rectified,
             v1::StereoCalibration* out);
void ToProto(const dataset::ImuNoise& noise, double rate_hz, v1::ImuNoise* out);
v1::SimulatorState ToProto(PlayerState state);

}  // namespace mav::simulator_service
