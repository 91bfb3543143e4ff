#include "mav/sim/scenario_source.h"

#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <optional>

#include "mav/common/check.h"
#include "mav/common/log.h"
#include "mav/common/time.h"
#include "mav/dataset/euroc.h"
#include "mav/dataset/occupancy_io.h"
#include "mav/sim/occupancy.h"
#include "mav/sim/presets.h"
#include "mav/sim/scenario.h"
#include "mav/sim/world.h"

namespace mav::sim {

namespace {

std::string JoinNames(const std::vector<std::string>& names) {
  std::string out;
  for (const std::string& name : names) out += (out.empty() ? "" : ", ") + name;
  return out;
}

Status CheckResolution(double resolution_m) {
  if (!std::isfinite(resolution_m) || !(resolution_m > 0)) {
    return Status::InvalidArgument("resolution_m: must be positive and finite, got " +
                                   std::to_string(resolution_m));
  }
  return Status::Ok();
}

class PresetScenarioSource : public ScenarioSource {
 public:
  PresetScenarioSource(Scenario scenario, const PresetRequest& request)
      : scenario_(std::move(scenario)) {
    imu_ = scenario_.ImuSamples();
    ground_truth_ = scenario_.GroundTruth();
    info_.name = request.name;
    info_.is_preset = true;
    info_.frames = scenario_.num_frames();
    info_.imu_samples = static_cast<int64_t>(imu_.size());
    info_.start_t_ns = scenario_.FrameTimeNs(0);
    info_.end_t_ns = scenario_.FrameTimeNs(info_.frames - 1);
    info_.camera_rate_hz = scenario_.camera_rate_hz();
    info_.imu_rate_hz = scenario_.imu_rate_hz();
    info_.rectified = request.rectified;
    info_.seed = request.seed;
    info_.has_ground_truth = true;
    info_.has_ground_truth_occupancy = true;
    info_.width = scenario_.calibration().cam0.width;
    info_.height = scenario_.calibration().cam0.height;
  }

  const ScenarioInfo& info() const override { return info_; }
  int64_t FrameTimeNs(int64_t frame) const override { return scenario_.FrameTimeNs(frame); }
  Status ReadStereo(int64_t frame, cv::Mat* left, cv::Mat* right) const override {
    if (frame < 0 || frame >= info_.frames) {
      return Status::OutOfRange("frame " + std::to_string(frame) + " outside [0, " +
                                std::to_string(info_.frames) + ")");
    }
    scenario_.RenderStereo(frame, left, right);
    return Status::Ok();
  }
  const std::vector<dataset::ImuSample>& imu() const override { return imu_; }
  const std::vector<dataset::GroundTruthState>& ground_truth() const override {
    return ground_truth_;
  }
  const camera::StereoCalibration& calibration() const override { return scenario_.calibration(); }
  const dataset::ImuNoise& imu_noise() const override { return scenario_.imu_noise(); }
  Result<dataset::GridGeometry> OccupancyGeometry(double resolution_m) const override {
    MAV_RETURN_IF_ERROR(CheckResolution(resolution_m));
    return scenario_.OccupancyGeometry(resolution_m);
  }
  Result<dataset::OccupancyGrid> Occupancy(double resolution_m,
                                           const Termination& termination) const override {
    MAV_RETURN_IF_ERROR(CheckResolution(resolution_m));
    return ComputeOccupancy(scenario_.world(), resolution_m, termination);
  }

 private:
  Scenario scenario_;
  ScenarioInfo info_;
  std::vector<dataset::ImuSample> imu_;
  std::vector<dataset::GroundTruthState> ground_truth_;
};

class EurocScenarioSource : public ScenarioSource {
 public:
  EurocScenarioSource(dataset::EurocReader reader, const std::string& directory,
                      std::optional<dataset::OccupancyGrid> occupancy)
      : reader_(std::move(reader)), occupancy_(std::move(occupancy)) {
    const camera::StereoCalibration& calibration = reader_.calibration();
    info_.name = directory;
    info_.is_preset = false;
    info_.frames = reader_.num_frames();
    info_.imu_samples = static_cast<int64_t>(reader_.imu().size());
    info_.start_t_ns = reader_.frame_times().front();
    info_.end_t_ns = reader_.frame_times().back();
    info_.camera_rate_hz = reader_.camera_rate_hz();
    info_.imu_rate_hz = reader_.imu_rate_hz();
    const double angle =
        calibration.T_cam0_cam1().Rotation().angularDistance(Eigen::Quaterniond::Identity());
    info_.rectified =
        !calibration.cam0.HasDistortion() && !calibration.cam1.HasDistortion() && angle < 1e-9;
    info_.has_ground_truth = reader_.has_ground_truth();
    info_.has_ground_truth_occupancy = occupancy_.has_value();
    info_.occupancy_resolution_m = occupancy_ ? occupancy_->resolution() : 0.0;
    info_.width = calibration.cam0.width;
    info_.height = calibration.cam0.height;
  }

  const ScenarioInfo& info() const override { return info_; }
  int64_t FrameTimeNs(int64_t frame) const override { return reader_.frame_times()[frame]; }
  Status ReadStereo(int64_t frame, cv::Mat* left, cv::Mat* right) const override {
    return reader_.ReadStereo(frame, left, right);
  }
  const std::vector<dataset::ImuSample>& imu() const override { return reader_.imu(); }
  const std::vector<dataset::GroundTruthState>& ground_truth() const override {
    return reader_.ground_truth();
  }
  const camera::StereoCalibration& calibration() const override { return reader_.calibration(); }
  const dataset::ImuNoise& imu_noise() const override { return reader_.imu_noise(); }
  Result<dataset::GridGeometry> OccupancyGeometry(double resolution_m) const override {
    if (!occupancy_) {
      return Status::NotFound("the EuRoC directory " + info_.name +
                              " has no ground-truth occupancy (no ground_truth/occupancy.mavocc)");
    }
    if (std::abs(resolution_m - occupancy_->resolution()) > 1e-9 * occupancy_->resolution()) {
      return Status::InvalidArgument("resolution_m: the recorded ground truth of " + info_.name +
                                     " is at " + std::to_string(occupancy_->resolution()) +
                                     " m; ask for that resolution (or 0)");
    }
    return occupancy_->geometry();
  }
  Result<dataset::OccupancyGrid> Occupancy(double resolution_m, const Termination&) const override {
    MAV_RETURN_IF_ERROR(OccupancyGeometry(resolution_m).status());
    return *occupancy_;
  }

 private:
  dataset::EurocReader reader_;
  std::optional<dataset::OccupancyGrid> occupancy_;
  ScenarioInfo info_;
};

}  // namespace

Result<std::unique_ptr<ScenarioSource>> OpenPreset(const PresetRequest& request) {
  const std::vector<std::string>& names = PresetNames();
  if (std::find(names.begin(), names.end(), request.name) == names.end()) {
    return Status::InvalidArgument("preset.name: unknown preset '" + request.name +
                                   "' (known: " + JoinNames(names) + ")");
  }
  if (request.frames < 0) {
    return Status::InvalidArgument("preset.frames: must be >= 0 (0 = the full preset), got " +
                                   std::to_string(request.frames));
  }
  ScenarioOptions options;
  options.preset = request.name;
  options.frames = request.frames;
  options.seed = request.seed;
  options.rectified = request.rectified;
  MAV_ASSIGN_OR_RETURN(Scenario scenario, Scenario::Create(options));
  if (scenario.num_frames() <= 0) {
    return Status::InvalidArgument("preset.frames: the scenario has no frames");
  }
  return std::unique_ptr<ScenarioSource>(
      std::make_unique<PresetScenarioSource>(std::move(scenario), request));
}

Result<std::unique_ptr<ScenarioSource>> OpenEuroc(const std::string& directory) {
  if (directory.empty()) return Status::InvalidArgument("euroc.directory: empty");
  std::error_code error;
  if (!std::filesystem::is_directory(directory, error)) {
    return Status::NotFound("euroc.directory: '" + directory + "' is not a directory");
  }
  MAV_ASSIGN_OR_RETURN(dataset::EurocReader reader, dataset::EurocReader::Open(directory));
  if (reader.num_frames() == 0) {
    return Status::InvalidArgument("euroc.directory: '" + directory +
                                   "' has no stereo frames (cam0 and cam1 share no timestamp)");
  }
  std::optional<dataset::OccupancyGrid> occupancy;
  const std::string occupancy_path = directory + "/ground_truth/occupancy.mavocc";
  if (std::filesystem::exists(occupancy_path, error)) {
    MAV_ASSIGN_OR_RETURN(occupancy, dataset::ReadMavocc(occupancy_path));
  }
  return std::unique_ptr<ScenarioSource>(
      std::make_unique<EurocScenarioSource>(std::move(reader), directory, std::move(occupancy)));
}

// ---- FramePrefetcher --------------------------------------------------------------------------

FramePrefetcher::FramePrefetcher(const std::shared_ptr<const ScenarioSource>& source, int threads,
                                 int depth, OnRendered on_rendered, Priority priority)
    : FramePrefetcher(
          Frames{source->info().frames, [source](int64_t k) { return source->FrameTimeNs(k); },
                 [source](int64_t k, cv::Mat* left, cv::Mat* right) {
                   return source->ReadStereo(k, left, right);
                 }},
          threads, depth, std::move(on_rendered), priority) {}

FramePrefetcher::FramePrefetcher(Frames frames, int threads, int depth, OnRendered on_rendered,
                                 Priority priority)
    : frames_(std::move(frames)), depth_(std::max(1, depth)), on_rendered_(std::move(on_rendered)) {
  MAV_CHECK(threads >= 1);
  for (int i = 0; i < threads; ++i) threads_.emplace_back([this, priority] { Work(priority); });
}

FramePrefetcher::~FramePrefetcher() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  work_cv_.notify_all();
  for (std::thread& thread : threads_) thread.join();
}

void FramePrefetcher::ScheduleLocked(int64_t index) {
  // Drop what lies outside the window [index, index + depth): frames already being rendered
  // finish and are discarded when their thread finds their slot gone.
  for (auto it = slots_.begin(); it != slots_.end();) {
    if (it->first < index || it->first >= index + depth_) {
      it = slots_.erase(it);
    } else {
      ++it;
    }
  }
  const int64_t end = std::min<int64_t>(index + depth_, frames_.frames);
  for (int64_t k = index; k < end; ++k) slots_.try_emplace(k);
  work_cv_.notify_all();
}

Result<RenderedFrame> FramePrefetcher::Get(int64_t index) {
  std::unique_lock<std::mutex> lock(mutex_);
  ScheduleLocked(index);
  done_cv_.wait(lock, [&] {
    auto it = slots_.find(index);
    return it == slots_.end() || it->second.done;
  });
  auto it = slots_.find(index);
  if (it == slots_.end()) {
    return Status::OutOfRange("frame " + std::to_string(index) + " outside [0, " +
                              std::to_string(frames_.frames) + ")");
  }
  Slot slot = std::move(it->second);
  slots_.erase(it);
  if (!slot.status.ok()) return slot.status;
  return std::move(slot.frame);
}

void FramePrefetcher::Work(Priority priority) {
  // Named, so that profiles and `top -H` tell it from the thread that started it (a gRPC
  // handler's name is otherwise inherited).
  pthread_setname_np(pthread_self(), "render");
  if (priority == Priority::kIdle) {
    // Lowering a thread's own policy needs no privilege; 0 is the calling thread.
    const sched_param param{};
    if (sched_setscheduler(0, SCHED_IDLE, &param) != 0) {
      MAV_LOG(kWarning) << "rendering thread: SCHED_IDLE refused (" << std::strerror(errno)
                        << "); it renders at normal priority";
    }
  }
  std::unique_lock<std::mutex> lock(mutex_);
  while (true) {
    auto next = slots_.end();
    work_cv_.wait(lock, [&] {
      if (stop_) return true;
      next = std::find_if(slots_.begin(), slots_.end(),
                          [](const auto& entry) { return !entry.second.started; });
      return next != slots_.end();
    });
    if (stop_) return;
    const int64_t index = next->first;
    next->second.started = true;
    lock.unlock();

    RenderedFrame frame;
    frame.index = index;
    frame.t_ns = frames_.time_ns(index);
    const int64_t start_ns = MonotonicNowNs();
    Status status = frames_.read(index, &frame.left, &frame.right);
    frame.render_ms = MsSince(start_ns);
    if (status.ok() && on_rendered_) status = on_rendered_(frame);

    lock.lock();
    auto it = slots_.find(index);
    if (it != slots_.end() && it->second.started && !it->second.done) {
      it->second.done = true;
      it->second.status = std::move(status);
      it->second.frame = std::move(frame);
      done_cv_.notify_all();
    }
  }
}

}  // namespace mav::sim
