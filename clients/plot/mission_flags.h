#pragma once
// The flags mav-eval mission (in process) and mavctl mission run (through the services) share,
// and the options they give: one spelling, one default and one error message per flag for both
// drivers.

#include <cstdint>
#include <string>

#include "mav/common/flags.h"
#include "mav/common/status.h"
#include "mav/dataset/mission_file.h"
#include "mav/localization/odometry.h"
#include "mav/mission/lockstep_driver.h"
#include "mav/mission/mission.h"
#include "mav/mission/planning_setup.h"
#include "mav/mission/vehicle.h"

namespace mav::plot {

enum class MissionDriverKind { kInProcess, kServices };

struct MissionFlags {
  std::string mission_path, out_dir, json_path;
  std::string pose_source = "vo", controller = "paper", vo_method = "sparse-subpixel";
  std::string map = "truth";
  uint64_t seed = 1;
  double vo_latency_s = 0.05, max_speed = 0, timeout_s = 900, camera_pitch_deg = 0;
  double vo_tilt_sigma_deg = mission::VehicleOptions().vo_tilt_sigma_rad * 180 / M_PI;
  double vo_align_tilt_s = mission::VehicleOptions().vo_align_tilt_s;
  double vo_gyro_sigma_rad = mission::VehicleOptions().vo_gyro_sigma_rad;
  bool quiet = false, face_goals = false;
  // --camera-pitch was given (FlagParser::WasSet, set by the command after parsing): it
  // overrides the mission file's camera_pitch_deg.
  bool camera_pitch_set = false;
};

// Binds the shared flags to *f (the services' VO latency must be > 0: it is a lock-step
// latency).
void AddMissionFlags(MissionDriverKind kind, FlagParser* flags, MissionFlags* f);

// What the shared flags set.
struct MissionFlagOptions {
  mission::VehicleOptions vehicle;
  localization::Method vo_method = localization::Method::kSparseSubpixel;
  mission::MapSource map = mission::MapSource::kGroundTruth;
  mission::PlanningOverrides planning;
};

// InvalidArgument naming the flag ("--pose-source: 'x' is not one of vo, contest, truth").
Result<MissionFlagOptions> MissionOptionsFromFlags(const MissionFlags& f);

// What the mission file says of the vehicle (camera_pitch_deg) unless a flag said otherwise.
void ApplyMissionFile(const MissionFlags& f, const dataset::MissionSpec& spec,
                      mission::VehicleOptions* vehicle);

// The mission logic's options for the flags and the mission file (the plant's goals count
// within 0.5 m; an online map needs the camera to face the way).
mission::MissionOptions MissionLogicOptions(const MissionFlags& f,
                                            const dataset::MissionSpec& spec);

}  // namespace mav::plot
