#include "mav/mission/vehicle.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include <opencv2/core.hpp>

#include "mav/camera/stereo.h"
#include "mav/common/time.h"
#include "mav/eval/flight_mission.h"
#include "mav/sim/collision_world.h"
#include "mav/sim/stereo_rig.h"
#include "mav/sim/world.h"

namespace mav::mission {

namespace {
constexpr size_t kTruthKept = 64;  // 0.32 s at 200 Hz: more than a shutter and a step
}  // namespace

const char* PoseSourceName(PoseSource source) {
  switch (source) {
    case PoseSource::kContest:
      return "contest";
    case PoseSource::kVo:
      return "vo";
    case PoseSource::kTruth:
      return "truth";
  }
  return "?";
}

std::optional<PoseSource> ParsePoseSource(std::string_view name) {
  for (PoseSource s : {PoseSource::kContest, PoseSource::kVo, PoseSource::kTruth}) {
    if (name == PoseSourceName(s)) return s;
  }
  return std::nullopt;
}

std::optional<control::ControllerType> ParseController(std::string_view name) {
  for (control::ControllerType c :
       {control::ControllerType::kPaper, control::ControllerType::kLee}) {
    if (name == control::ControllerTypeName(c)) return c;
  }
  return std::nullopt;
}

bool VehicleOptions::IsValid(std::string* why) const {
  std::ostringstream msg;
  auto check = [&](bool ok, const char* what) {
    if (msg.str().empty() && !ok) msg << what;
  };
  check(vo_latency_s >= 0 && vo_latency_s <= 0.5, "vo_latency_s: must be in [0, 0.5]");
  check(vo_gyro_sigma_rad >= 0 && vo_gyro_sigma_rad <= 0.1,
        "vo_gyro_sigma_rad: must be in [0, 0.1] (0 = vision only)");
  check(vo_position_sigma_m > 0 && vo_orientation_sigma_rad > 0,
        "vo_position_sigma_m / vo_orientation_sigma_rad: must be positive");
  check(vo_tilt_sigma_rad > 0, "vo_tilt_sigma_rad: must be positive");
  check(vo_align_tilt_s >= 0, "vo_align_tilt_s: must be >= 0 (0 = off)");
  check(imu_rate_hz >= 50 && imu_rate_hz <= 1000, "imu_rate_hz: must be in [50, 1000]");
  check(camera_rate_hz > 0 && camera_rate_hz <= imu_rate_hz,
        "camera_rate_hz: must be in (0, imu_rate_hz]");
  check(camera_pitch_rad >= 0 && camera_pitch_rad <= 1.2,
        "camera_pitch_rad: must be in [0, 1.2] (0 = level, looking forward)");
  check(pose_gate_m >= 0 && pose_gate_rad >= 0, "pose_gate_m / pose_gate_rad: must be >= 0");
  if (msg.str().empty()) return true;
  if (why) *why = msg.str();
  return false;
}

geometry::SE3 VehicleRigMount(double pitch_down_rad) {
  // Rig body axes in the vehicle's: x (up) = vehicle z, z (forward) = vehicle x, y = -vehicle y;
  // then pitched down about the vehicle's y axis.
  Eigen::Matrix3d R;
  R.col(0) = Eigen::Vector3d::UnitZ();
  R.col(1) = -Eigen::Vector3d::UnitY();
  R.col(2) = Eigen::Vector3d::UnitX();
  const Eigen::Matrix3d pitch(Eigen::AngleAxisd(pitch_down_rad, Eigen::Vector3d::UnitY()));
  return geometry::SE3(Eigen::Quaterniond(pitch * R), Eigen::Vector3d(0.12, 0.0, 0.02));
}

bool IsRoomWorld(const std::string& world) { return world.rfind("room-", 0) == 0; }

Result<MissionWorld> MakeMissionWorld(const dataset::MissionSpec& mission, uint64_t seed) {
  Result<sim::Preset> preset = sim::MakePreset(mission.world);
  if (!preset.ok()) {
    return Status::InvalidArgument(mission.source + ": world: " + preset.status().message());
  }
  MissionWorld out;
  out.preset = *std::move(preset);
  out.preset.world->BuildTextures(seed);
  out.collision = sim::MakePrimitiveCollisionWorldAboveGround(*out.preset.world, mission.start.z());
  return out;
}

dataset::FlightTask MissionFlightTask(const dataset::MissionSpec& mission,
                                      const VehicleOptions& options) {
  dataset::FlightTask task;
  task.name = "mission " + mission.source;
  task.kind = dataset::FlightTaskKind::kWaypoints;
  task.duration_s = 7200;
  task.spawn_position = mission.start + Eigen::Vector3d(0, 0, 0.08);
  task.ground_z_m = mission.start.z();
  task.takeoff_position = mission.start + Eigen::Vector3d(0, 0, mission.altitude_m);
  task.goals = {dataset::FlightGoal{0.0, task.takeoff_position, 0.0}};
  task.imu.rate_hz = options.imu_rate_hz;
  task.vehicle_radius_m = 0.35;
  dataset::FlightPoseSensorSpec sensor;  // the contest's by default
  if (options.pose_source == PoseSource::kTruth) {
    sensor.rate_hz = options.camera_rate_hz;
    sensor.delay_s = 0;
    sensor.position_sigma_m = 0;
    sensor.orientation_sigma_rad = 0;
    sensor.mount_xyz_m.setZero();
    sensor.mount_rpy_rad.setZero();
  } else if (options.pose_source == PoseSource::kVo) {
    sensor.active_from_s = task.duration_s - 1;  // never within a mission
  }
  task.pose_sensors = {sensor};
  return task;
}

control::AutopilotOptions MissionAutopilotOptions(const dataset::FlightTask& task,
                                                  const VehicleOptions& options) {
  control::AutopilotOptions ap = eval::AutopilotOptionsForTask(task, options.controller);
  if (options.pose_source == PoseSource::kVo) {
    control::PoseSourceOptions vo;
    vo.rate_hz = options.camera_rate_hz;
    vo.position_sigma_m = options.vo_position_sigma_m;
    vo.orientation_sigma_rad = options.vo_orientation_sigma_rad;
    vo.tilt_sigma_rad = options.vo_tilt_sigma_rad;
    vo.align_tilt_s = options.vo_align_tilt_s;
    vo.T_body_sensor = VehicleRigMount(options.camera_pitch_rad);
    ap.estimator.pose_sources = {vo};
    ap.estimator.buffer_s = std::max(1.0, 2 * options.vo_latency_s + 0.2);
  }
  ap.estimator.pose_gate_m = options.pose_gate_m;
  ap.estimator.pose_gate_rad = options.pose_gate_rad;
  // The mission's health logic holds at 1 s and lands at 3 s (at a free column, on the IMU);
  // the autopilot's own failsafe (a level descent where it is) is the last resort behind it,
  // for a mission that stopped commanding.
  ap.pose_timeout_s = 20.0;
  return ap;
}

VehicleCamera::VehicleCamera(const sim::Preset& preset, const VehicleOptions& options,
                             int64_t step_ns, int64_t t0_ns, const geometry::SE3& T_world_body0)
    : renderer_(std::make_unique<sim::StereoRigRenderer>(
          preset.world, camera::EurocStereoCalibration(), preset.effects, options.seed,
          preset.min_clearance)),
      T_vehicle_rig_(VehicleRigMount(options.camera_pitch_rad)),
      frame_period_ns_(PeriodNs(options.camera_rate_hz)),
      shutter_half_ns_(SecondsToNs(std::max(0.0, preset.effects.shutter_s) / 2) + step_ns / 2) {
  truth_.push_back({t0_ns, T_world_body0});
}

VehicleCamera::~VehicleCamera() = default;

const camera::StereoCalibration& VehicleCamera::calibration() const {
  return renderer_->calibration();
}

void VehicleCamera::Observe(int64_t t_ns, const geometry::SE3& T_world_body) {
  truth_.push_back({t_ns, T_world_body});
  while (truth_.size() > kTruthKept) truth_.pop_front();
}

std::vector<int64_t> VehicleCamera::DueFrames() {
  std::vector<int64_t> due;
  const int64_t now = truth_.back().t_ns;
  while (next_frame_ * frame_period_ns_ + shutter_half_ns_ <= now) due.push_back(next_frame_++);
  return due;
}

geometry::SE3 VehicleCamera::TruthBetween(int64_t t_ns) const {
  // The two recorded states around t_ns (the deque is in time order), interpolated.
  const TruthAt* a = &truth_.front();
  const TruthAt* b = &truth_.back();
  for (size_t i = 1; i < truth_.size(); ++i) {
    if (truth_[i].t_ns >= t_ns) {
      a = &truth_[i - 1];
      b = &truth_[i];
      break;
    }
  }
  if (t_ns <= a->t_ns || b->t_ns == a->t_ns) return a->T_world_body;
  if (t_ns >= b->t_ns) return b->T_world_body;
  const double u = static_cast<double>(t_ns - a->t_ns) / static_cast<double>(b->t_ns - a->t_ns);
  const Eigen::Vector3d p =
      (1 - u) * a->T_world_body.Translation() + u * b->T_world_body.Translation();
  const Eigen::Quaterniond q = a->T_world_body.Rotation().slerp(u, b->T_world_body.Rotation());
  return geometry::SE3(q, p);
}

geometry::SE3 VehicleCamera::TrueRigPose(int64_t t_ns) const {
  return TruthBetween(t_ns) * T_vehicle_rig_;
}

void VehicleCamera::Render(int64_t frame, cv::Mat* left, cv::Mat* right) const {
  const int64_t t_ns = FrameTimeNs(frame);
  renderer_->Render(
      frame, NsToSeconds(t_ns),
      [&](double dt_s) { return TruthBetween(t_ns + SecondsToNs(dt_s)) * T_vehicle_rig_; }, left,
      right);
}

}  // namespace mav::mission
