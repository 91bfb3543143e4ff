#pragma once
// What a simulated mission flies, shared by its two drivers so that they fly the very same
// vehicle: the in-process lock-step driver (lockstep_driver.h) and the simulator service's
// mission flight (services/simulator, flown through the services by mavctl mission run).
//
//   MakeMissionWorld      the preset's world (textured for the seed) and its collision world
//                         above the ground plane
//   MissionFlightTask     the vehicle, its IMU and (pose source contest / truth) pose sensor
//   MissionAutopilotOptions  the flight software's configuration for that task and pose source
//   VehicleCamera         the forward stereo camera: which frames are due after a step (a frame
//                         is rendered once the state over its shutter is known) and their images
//
// The camera rig: the preset's EuRoC rig (body = the VI sensor's IMU frame, x up, z forward)
// mounted on the vehicle (body x forward, z up) looking forward, T_vehicle_rig.

#include <cmath>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mav/camera/stereo.h"
#include "mav/common/status.h"
#include "mav/control/autopilot.h"
#include "mav/dataset/flight_task.h"
#include "mav/dataset/mission_file.h"
#include "mav/geometry/se3.h"
#include "mav/sim/presets.h"

namespace cv {
class Mat;
}
namespace mav::sim {
class CollisionWorld;
class StereoRigRenderer;
}  // namespace mav::sim

namespace mav::mission {

enum class PoseSource {
  kContest,  // the EuRoC 2014 contest's synthetic pose sensor (10 Hz, 100 ms late, noisy)
  kVo,       // stereo VO on the rendered images
  kTruth,    // the exact pose at camera rate, no delay (debugging only)
};
const char* PoseSourceName(PoseSource source);  // "contest", "vo", "truth"
std::optional<PoseSource> ParsePoseSource(std::string_view name);
// "paper" or "lee" (control::ControllerTypeName's names).
std::optional<control::ControllerType> ParseController(std::string_view name);

struct VehicleOptions {
  uint64_t seed = 1;
  PoseSource pose_source = PoseSource::kVo;
  double imu_rate_hz = 200;
  double camera_rate_hz = 20;
  // The camera looks forward, pitched down by this much (VehicleRigMount).
  double camera_pitch_rad = 0;
  // The estimator's model of the VO pose noise, and the modelled VO latency (its buffer).
  double vo_position_sigma_m = 0.01;
  double vo_orientation_sigma_rad = 0.005;
  // The VO's tilt drifts with its keyframe chain (room-hard: ~4 degrees over a survey, 0.15 m
  // of height error): the estimator takes the tilt from gravity (a loose tilt sigma,
  // PoseSourceOptions::tilt_sigma_rad) and turns the VO's frame toward it with a time constant
  // (PoseSourceOptions::align_tilt_s, 0 = off).
  double vo_tilt_sigma_rad = 3 * M_PI / 180;
  double vo_align_tilt_s = 2.0;
  double vo_latency_s = 0.05;
  // The sparse VO's gyro prior: the noise of the gyro's rotation over one frame interval
  // (SparseVoOptions::gyro_rotation_sigma_rad; 0 = vision only).
  double vo_gyro_sigma_rad = 5e-4;
  control::ControllerType controller = control::ControllerType::kPaper;
  // The estimator's gate (EstimatorOptions::pose_gate_*) on every source.
  double pose_gate_m = 0.3;
  double pose_gate_rad = 0.2;
  // The field named ("camera_pitch_rad: must be in [0, 1.2] ...").
  bool IsValid(std::string* why) const;
};

// The vehicle's camera mounting (the rig's body frame in the vehicle's body frame), looking
// forward and pitched down by `pitch_down_rad`.
geometry::SE3 VehicleRigMount(double pitch_down_rad);

// Whether the mission's world is one of the rooms (their planning and speed defaults).
bool IsRoomWorld(const std::string& world);

struct MissionWorld {
  sim::Preset preset;  // its world's textures built for the seed
  std::shared_ptr<const sim::CollisionWorld> collision;
};
// InvalidArgument "<source>: world: unknown preset ..." for a world that is not a preset.
Result<MissionWorld> MakeMissionWorld(const dataset::MissionSpec& mission, uint64_t seed);

// The vehicle, its IMU and (for `contest` / `truth`) its pose sensor; a `vo` mission's sensor
// never delivers (the VO is the pose source). Spawned at mission.start, 7200 s long.
dataset::FlightTask MissionFlightTask(const dataset::MissionSpec& mission,
                                      const VehicleOptions& options);

// The flight software for the task, its estimator fed by the mission's pose source (the VO's
// poses are T_world_rig, of the rig mounted at VehicleRigMount(camera_pitch_rad)).
control::AutopilotOptions MissionAutopilotOptions(const dataset::FlightTask& task,
                                                  const VehicleOptions& options);

// The forward stereo camera of a flying vehicle: frame k is captured at k / rate_hz of the
// vehicle's clock and rendered, with the preset's exposure, blur and noise, once the state over
// its shutter is known. Feed it every step's true pose in time order (Observe), then render the
// frames DueFrames returns.
class VehicleCamera {
 public:
  // `world` must have its textures built; `step_ns` is the simulation's step.
  VehicleCamera(const sim::Preset& preset, const VehicleOptions& options, int64_t step_ns,
                int64_t t0_ns, const geometry::SE3& T_world_body0);
  ~VehicleCamera();
  VehicleCamera(const VehicleCamera&) = delete;
  VehicleCamera& operator=(const VehicleCamera&) = delete;

  void Observe(int64_t t_ns, const geometry::SE3& T_world_body);
  // The frames whose shutter the observed states now cover (each returned once, in order).
  std::vector<int64_t> DueFrames();
  int64_t FrameTimeNs(int64_t frame) const { return frame * frame_period_ns_; }
  // Frame `frame`'s images (CV_8UC1, the EuRoC raw rig's size). Needs the states over its
  // shutter (the last ~0.3 s are kept).
  void Render(int64_t frame, cv::Mat* left, cv::Mat* right) const;
  // The true rig pose at `t_ns` (interpolated between the observed steps).
  geometry::SE3 TrueRigPose(int64_t t_ns) const;

  const geometry::SE3& T_vehicle_rig() const { return T_vehicle_rig_; }
  const camera::StereoCalibration& calibration() const;

 private:
  struct TruthAt {
    int64_t t_ns = 0;
    geometry::SE3 T_world_body;
  };
  geometry::SE3 TruthBetween(int64_t t_ns) const;

  std::unique_ptr<sim::StereoRigRenderer> renderer_;
  geometry::SE3 T_vehicle_rig_;
  int64_t frame_period_ns_ = 0;
  int64_t shutter_half_ns_ = 0;
  int64_t next_frame_ = 0;
  std::deque<TruthAt> truth_;
};

}  // namespace mav::mission
