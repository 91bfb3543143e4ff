#include "mav/sim/scenario.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include <opencv2/core.hpp>

#include "mav/common/check.h"
#include "mav/common/text.h"
#include "mav/sim/occupancy.h"
#include "mav/sim/presets.h"
#include "mav/sim/stereo_rig.h"
#include "mav/sim/trajectory.h"
#include "mav/sim/world.h"
#include "random.h"

namespace mav::sim {
namespace {

// EuRoC-like epoch of the first frame (MH_01_easy starts near this time stamp).
constexpr int64_t kT0Ns = 1403636579763555584LL;
constexpr int64_t kFramePeriodNs = 50'000'000;
constexpr int64_t kMaxFrames = 200'000;  // ~2.8 hours at 20 Hz
// The trajectory outlasts the last frame so that the last shutter interval is covered.
constexpr double kTailS = 0.5;

// The ideal rectified rig: EuRoC cam0's focal length and principal point, no distortion, cam1
// displaced by +0.11 m along cam0's x axis, same orientation.
camera::StereoCalibration RectifiedRig() {
  camera::StereoCalibration raw = camera::EurocStereoCalibration();
  camera::StereoCalibration rig;
  rig.cam0 = raw.cam0;
  rig.cam0.k1 = rig.cam0.k2 = rig.cam0.p1 = rig.cam0.p2 = 0;
  rig.cam0.fy = rig.cam0.fx;
  rig.cam1 = rig.cam0;
  rig.T_body_cam0 = raw.T_body_cam0;
  rig.T_body_cam1 =
      raw.T_body_cam0 * geometry::SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.11, 0, 0));
  return rig;
}

}  // namespace

bool ScenarioOptions::IsValid(std::string* why) const {
  std::ostringstream msg;
  const auto& names = PresetNames();
  if (std::find(names.begin(), names.end(), preset) == names.end()) {
    msg << "preset: unknown preset " << QuoteForError(preset) << " (known: ";
    for (size_t i = 0; i < names.size(); ++i) msg << (i ? ", " : "") << names[i];
    msg << ")";
  } else if (frames < 0) {
    msg << "frames: must be >= 0 (0 = the preset's full length), got " << frames;
  } else if (frames > kMaxFrames) {
    msg << "frames: at most " << kMaxFrames << " frames, got " << frames;
  }
  if (msg.str().empty()) return true;
  if (why) *why = msg.str();
  return false;
}

struct Scenario::Impl {
  ScenarioOptions options;
  Preset preset;
  std::shared_ptr<const World> world;
  Trajectory trajectory;
  camera::StereoCalibration calibration;
  dataset::ImuNoise imu_noise;
  int64_t num_frames = 0;
  std::unique_ptr<StereoRigRenderer> rig;

  double TrajTime(int64_t t_ns) const { return static_cast<double>(t_ns - kT0Ns) * 1e-9; }
};

Scenario::Scenario(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Scenario::Scenario(Scenario&&) noexcept = default;
Scenario& Scenario::operator=(Scenario&&) noexcept = default;
Scenario::~Scenario() = default;

Result<Scenario> Scenario::Create(const ScenarioOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) return Status::InvalidArgument(why);
  MAV_ASSIGN_OR_RETURN(Preset preset, MakePreset(options.preset));
  auto impl = std::make_unique<Impl>();
  impl->options = options;
  impl->num_frames = options.frames > 0 ? options.frames : preset.full_frames;
  preset.world->BuildTextures(options.seed);
  impl->world = preset.world;

  TrajectoryOptions topt;
  topt.profile = preset.profile;
  topt.duration_s = static_cast<double>(impl->num_frames - 1) * kFramePeriodNs * 1e-9 + kTailS;
  topt.seed = options.seed;
  topt.bounds = preset.flight_bounds;
  std::shared_ptr<const World> world = impl->world;
  topt.clearance = [world](const Eigen::Vector3d& p) { return world->SignedDistance(p); };
  topt.min_clearance = preset.min_clearance;
  topt.look_at = preset.look_at;
  Result<Trajectory> trajectory = Trajectory::Create(topt);
  if (!trajectory.ok()) {
    return trajectory.status().WithContext("preset " + QuoteForError(options.preset) +
                                           " trajectory");
  }
  impl->trajectory = std::move(trajectory).value();
  impl->calibration = options.rectified ? RectifiedRig() : camera::EurocStereoCalibration();
  preset.effects.exact_cylinder_angles = options.exact_cylinder_angles;
  impl->rig = std::make_unique<StereoRigRenderer>(impl->world, impl->calibration, preset.effects,
                                                  options.seed, preset.min_clearance);
  impl->preset = std::move(preset);
  return Scenario(std::move(impl));
}

const ScenarioOptions& Scenario::options() const { return impl_->options; }
const World& Scenario::world() const { return *impl_->world; }
const camera::StereoCalibration& Scenario::calibration() const { return impl_->calibration; }
const dataset::ImuNoise& Scenario::imu_noise() const { return impl_->imu_noise; }
int64_t Scenario::num_frames() const { return impl_->num_frames; }
int64_t Scenario::FrameTimeNs(int64_t frame) const { return kT0Ns + frame * kFramePeriodNs; }

void Scenario::RenderStereo(int64_t frame, cv::Mat* left, cv::Mat* right) const {
  MAV_CHECK(frame >= 0 && frame < impl_->num_frames)
      << "frame " << frame << " outside [0, " << impl_->num_frames << ")";
  const Impl& s = *impl_;
  const double t_s = s.TrajTime(FrameTimeNs(frame));
  s.rig->Render(
      frame, t_s, [&](double dt_s) { return s.trajectory.Evaluate(t_s + dt_s).T_world_body; }, left,
      right);
}

dataset::GroundTruthState Scenario::StateAt(int64_t t_ns) const {
  const TrajectoryState st = impl_->trajectory.Evaluate(impl_->TrajTime(t_ns));
  dataset::GroundTruthState gt;
  gt.t_ns = t_ns;
  gt.T_world_body = st.T_world_body;
  gt.v_world = st.v_world;
  return gt;
}

std::vector<dataset::ImuSample> Scenario::ImuSamples() const {
  ImuSimulationOptions o;
  o.noise = impl_->imu_noise;
  o.rate_hz = imu_rate_hz();
  o.seed = internal::HashCombine(impl_->options.seed, 0x1a0ULL);
  return SimulateImu(impl_->trajectory, FrameTimeNs(0), FrameTimeNs(impl_->num_frames - 1), o,
                     nullptr);
}

dataset::ImuSample Scenario::IdealImuAt(int64_t t_ns) const {
  return IdealImu(impl_->trajectory.Evaluate(impl_->TrajTime(t_ns)), t_ns);
}

std::vector<dataset::GroundTruthState> Scenario::GroundTruth() const {
  ImuSimulationOptions o;
  o.noise = impl_->imu_noise;
  o.rate_hz = imu_rate_hz();
  o.seed = internal::HashCombine(impl_->options.seed, 0x1a0ULL);
  std::vector<dataset::GroundTruthState> gt;
  SimulateImu(impl_->trajectory, FrameTimeNs(0), FrameTimeNs(impl_->num_frames - 1), o, &gt);
  return gt;
}

dataset::OccupancyGrid Scenario::ComputeOccupancy(double resolution) const {
  return sim::ComputeOccupancy(*impl_->world, resolution);
}

dataset::GridGeometry Scenario::OccupancyGeometry(double resolution) const {
  return sim::OccupancyGeometry(*impl_->world, resolution);
}

}  // namespace mav::sim
