#include "clients/plot/mission_flags.h"

#include <cmath>
#include <optional>

#include "mav/common/text.h"

namespace mav::plot {

void AddMissionFlags(MissionDriverKind kind, FlagParser* flags, MissionFlags* f) {
  const bool services = kind == MissionDriverKind::kServices;
  flags->AddString("mission", &f->mission_path, "mission file (YAML, docs/formats.md)");
  flags->AddUint64("seed", &f->seed, "seed of the simulation (textures, noise, roadmap)");
  flags->AddString("pose-source", &f->pose_source,
                   "the estimator's pose: vo (stereo VO on the rendered images), contest (the "
                   "contest's 10 Hz sensor), truth (debugging)");
  flags->AddString("controller", &f->controller, "paper or lee");
  flags->AddString("vo-method", &f->vo_method, "the VO: sparse-subpixel, sparse-pixel or dense");
  flags->AddDouble("vo-latency", &f->vo_latency_s, "modelled VO latency, s (capture to estimator)",
                   services ? 0.001 : 0, 0.5);
  flags->AddDouble("vo-tilt-sigma", &f->vo_tilt_sigma_deg,
                   "the estimator's model of the VO's tilt noise, degrees (loose: the tilt comes "
                   "from gravity)",
                   0.01, 90);
  flags->AddDouble("vo-gyro-sigma", &f->vo_gyro_sigma_rad,
                   "the sparse VO's gyro prior: noise of the gyro's rotation over one frame, rad "
                   "(0 = vision only)",
                   0, 0.1);
  flags->AddDouble("vo-align-tilt", &f->vo_align_tilt_s,
                   "time constant of the VO frame's gravity alignment in the estimator, s "
                   "(0 = off)",
                   0, 600);
  flags->AddDouble("camera-pitch", &f->camera_pitch_deg,
                   "the stereo camera's downward pitch on the vehicle, degrees (default: the "
                   "mission file's camera_pitch_deg, else 0)",
                   0, 60);
  flags->AddDouble("max-speed", &f->max_speed, "planned speed limit, m/s (0 = the world's default)",
                   0, 20);
  flags->AddDouble("timeout", &f->timeout_s,
                   "abort the mission after this long in simulated time, s (outcome aborted)", 1,
                   7000);
  flags->AddString("map", &f->map,
                   "the planner's map: truth (the world's exact occupancy) or online (built "
                   "during the flight from the VO's keyframes; needs --pose-source vo)");
  flags->AddBool("face-goals", &f->face_goals,
                 "turn to face each goal before its leg (always with --map online)");
  flags->AddString("out", &f->out_dir, "write trajectory.csv, mission.png and map.bt here");
  flags->AddString("json", &f->json_path, "write the report here");
  flags->AddBool("quiet", &f->quiet, "no progress line");
}

Result<MissionFlagOptions> MissionOptionsFromFlags(const MissionFlags& f) {
  MissionFlagOptions o;
  o.vehicle.seed = f.seed;
  o.vehicle.vo_latency_s = f.vo_latency_s;
  o.vehicle.camera_pitch_rad = f.camera_pitch_deg * M_PI / 180;
  o.vehicle.vo_tilt_sigma_rad = f.vo_tilt_sigma_deg * M_PI / 180;
  o.vehicle.vo_align_tilt_s = f.vo_align_tilt_s;
  o.vehicle.vo_gyro_sigma_rad = f.vo_gyro_sigma_rad;
  const std::optional<mission::PoseSource> source = mission::ParsePoseSource(f.pose_source);
  if (!source) {
    return Status::InvalidArgument("--pose-source: " + QuoteForError(f.pose_source) +
                                   " is not one of vo, contest, truth");
  }
  o.vehicle.pose_source = *source;
  const std::optional<control::ControllerType> controller = mission::ParseController(f.controller);
  if (!controller) {
    return Status::InvalidArgument("--controller: " + QuoteForError(f.controller) +
                                   " is not one of paper, lee");
  }
  o.vehicle.controller = *controller;
  const std::optional<localization::Method> method = localization::ParseMethod(f.vo_method);
  if (!method) {
    return Status::InvalidArgument("--vo-method: " + QuoteForError(f.vo_method) +
                                   " is not one of sparse-pixel, sparse-subpixel, dense");
  }
  o.vo_method = *method;
  const std::optional<mission::MapSource> map = mission::ParseMapSource(f.map);
  if (!map) {
    return Status::InvalidArgument("--map: " + QuoteForError(f.map) +
                                   " is not one of truth, online");
  }
  o.map = *map;
  if (f.max_speed > 0) o.planning.limits = mission::SpeedLimitsForMaxSpeed(f.max_speed);
  return o;
}

void ApplyMissionFile(const MissionFlags& f, const dataset::MissionSpec& spec,
                      mission::VehicleOptions* vehicle) {
  if (!f.camera_pitch_set && spec.camera_pitch_deg.has_value()) {
    vehicle->camera_pitch_rad = *spec.camera_pitch_deg * M_PI / 180;
  }
}

mission::MissionOptions MissionLogicOptions(const MissionFlags& f,
                                            const dataset::MissionSpec& spec) {
  mission::MissionOptions o;
  o.timeout_s = f.timeout_s;
  o.face_goals = f.face_goals || mission::ParseMapSource(f.map) == mission::MapSource::kOnline;
  if (spec.world == "plant") o.goal_tolerance_m = 0.5;
  return o;
}

}  // namespace mav::plot
