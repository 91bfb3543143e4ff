#include "services/simulator/playback.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>

#include "mav/common/check.h"
#include "mav/common/log.h"
#include "mav/common/time.h"
#include "mav/dataset/euroc.h"
#include "mav/sim/occupancy.h"
#include "mav/sim/scenario.h"
#include "mav/sim/world.h"

namespace mav::simulator_service {

namespace {

constexpr int64_t kNoTime = std::numeric_limits<int64_t>::max();
// Fast mode: how long one frame may wait for its acknowledgements before we move on (a reader
// that died keeps its match until its lease expires).
constexpr int64_t kAckTimeoutNs = 2'000'000'000;
// Real-time mode: when publishing falls this far behind the schedule, the schedule is reset
// instead of bursting to catch up.
constexpr int64_t kMaxLatenessNs = 200'000'000;
constexpr size_t kStatsWindow = 1000;

class PresetScenarioSource : public ScenarioSource {
 public:
  explicit PresetScenarioSource(sim::Scenario scenario, const PresetRequest& request)
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
  Result<dataset::OccupancyGrid> Occupancy(double resolution_m) const override {
    return scenario_.ComputeOccupancy(resolution_m);
  }
  int64_t EstimateVoxels(double resolution_m) const override {
    const Eigen::Vector3d extent = scenario_.world().bounds().sizes();
    double voxels = 1.0;
    for (int i = 0; i < 3; ++i) voxels *= std::ceil(extent[i] / resolution_m) + 1.0;
    return voxels > 9e18 ? std::numeric_limits<int64_t>::max() : static_cast<int64_t>(voxels);
  }

 private:
  sim::Scenario scenario_;
  ScenarioInfo info_;
  std::vector<dataset::ImuSample> imu_;
  std::vector<dataset::GroundTruthState> ground_truth_;
};

class EurocScenarioSource : public ScenarioSource {
 public:
  EurocScenarioSource(dataset::EurocReader reader, const std::string& directory)
      : reader_(std::move(reader)) {
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
    info_.has_ground_truth_occupancy = false;
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
  Result<dataset::OccupancyGrid> Occupancy(double) const override {
    return Status::NotFound("the EuRoC directory " + info_.name +
                            " has no ground-truth occupancy (only rendered presets do)");
  }
  int64_t EstimateVoxels(double) const override { return 0; }

 private:
  dataset::EurocReader reader_;
  ScenarioInfo info_;
};

Stats ComputeStats(std::vector<double> values) {
  Stats stats;
  if (values.empty()) return stats;
  stats.count = values.size();
  double sum = 0;
  for (double v : values) sum += v;
  stats.mean_ms = sum / static_cast<double>(values.size());
  std::sort(values.begin(), values.end());
  stats.median_ms = values[values.size() / 2];
  stats.p95_ms = values[std::min(values.size() - 1, values.size() * 95 / 100)];
  stats.max_ms = values.back();
  return stats;
}

void PushWindow(std::vector<double>* values, double v) {
  if (values->size() >= kStatsWindow) values->erase(values->begin());
  values->push_back(v);
}

std::string JoinNames(const std::vector<std::string>& names) {
  std::string out;
  for (const std::string& name : names) out += (out.empty() ? "" : ", ") + name;
  return out;
}

}  // namespace

Result<std::unique_ptr<ScenarioSource>> OpenPreset(const PresetRequest& request) {
  const std::vector<std::string>& names = sim::PresetNames();
  if (std::find(names.begin(), names.end(), request.name) == names.end()) {
    return Status::InvalidArgument("preset.name: unknown preset '" + request.name +
                                   "' (known: " + JoinNames(names) + ")");
  }
  if (request.frames < 0) {
    return Status::InvalidArgument("preset.frames: must be >= 0 (0 = the full preset), got " +
                                   std::to_string(request.frames));
  }
  sim::ScenarioOptions options;
  options.preset = request.name;
  options.frames = request.frames;
  options.seed = request.seed;
  options.rectified = request.rectified;
  MAV_ASSIGN_OR_RETURN(sim::Scenario scenario, sim::Scenario::Create(options));
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
  return std::unique_ptr<ScenarioSource>(
      std::make_unique<EurocScenarioSource>(std::move(reader), directory));
}

// ---- RenderPipeline ---------------------------------------------------------------------------

RenderPipeline::RenderPipeline(std::shared_ptr<const ScenarioSource> source, int threads, int depth)
    : source_(std::move(source)), depth_(std::max(1, depth)) {
  MAV_CHECK(threads >= 1);
  for (int i = 0; i < threads; ++i) threads_.emplace_back([this] { Work(); });
}

RenderPipeline::~RenderPipeline() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  work_cv_.notify_all();
  for (std::thread& thread : threads_) thread.join();
}

void RenderPipeline::ScheduleLocked(int64_t index) {
  // Drop what lies outside the window [index, index + depth): frames already being rendered
  // finish and are discarded when their thread finds their slot gone.
  for (auto it = slots_.begin(); it != slots_.end();) {
    if (it->first < index || it->first >= index + depth_) {
      it = slots_.erase(it);
    } else {
      ++it;
    }
  }
  const int64_t end = std::min<int64_t>(index + depth_, source_->info().frames);
  for (int64_t k = index; k < end; ++k) slots_.try_emplace(k);
  work_cv_.notify_all();
}

Result<RenderedFrame> RenderPipeline::Get(int64_t index) {
  std::unique_lock<std::mutex> lock(mutex_);
  ScheduleLocked(index);
  done_cv_.wait(lock, [&] {
    auto it = slots_.find(index);
    return it == slots_.end() || it->second.done;
  });
  auto it = slots_.find(index);
  MAV_CHECK(it != slots_.end()) << "frame " << index << " left the window while awaited";
  Slot slot = std::move(it->second);
  slots_.erase(it);
  if (!slot.status.ok()) return slot.status;
  return std::move(slot.frame);
}

void RenderPipeline::Work() {
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
    frame.t_ns = source_->FrameTimeNs(index);
    const int64_t start_ns = MonotonicNowNs();
    Status status = source_->ReadStereo(index, &frame.left, &frame.right);
    frame.render_ms = static_cast<double>(MonotonicNowNs() - start_ns) * 1e-6;

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

// ---- Player -----------------------------------------------------------------------------------

const char* PlayerStateName(PlayerState state) {
  switch (state) {
    case PlayerState::kIdle:
      return "IDLE";
    case PlayerState::kLoaded:
      return "LOADED";
    case PlayerState::kRunning:
      return "RUNNING";
    case PlayerState::kPaused:
      return "PAUSED";
    case PlayerState::kFinished:
      return "FINISHED";
  }
  return "?";
}

Player::Player(StreamSink* sink) : sink_(sink) {
  MAV_CHECK(sink_ != nullptr);
  worker_ = std::thread([this] { WorkerLoop(); });
}

Player::~Player() {
  {
    std::unique_lock<std::mutex> lock(mutex_);
    StopLocked(&lock);
    shutdown_ = true;
  }
  cv_.notify_all();
  worker_.join();
}

void Player::StopLocked(std::unique_lock<std::mutex>* lock) {
  command_ = Command::kNone;
  ++generation_;
  cv_.notify_all();
  done_cv_.wait(*lock, [&] { return !busy_; });
}

void Player::Load(std::shared_ptr<const ScenarioSource> source) {
  MAV_CHECK(source != nullptr);
  std::unique_lock<std::mutex> lock(mutex_);
  StopLocked(&lock);
  pipeline_.reset();  // joins its threads; nothing renders for the old source afterwards
  source_ = std::move(source);
  pipeline_ = std::make_unique<RenderPipeline>(source_, /*threads=*/2, /*depth=*/4);
  state_ = PlayerState::kLoaded;
  next_frame_ = 0;
  next_imu_ = 0;
  next_gt_ = 0;
  frames_published_ = 0;
  imu_published_ = 0;
  gt_published_ = 0;
  current_t_ns_ = 0;
  publish_wall_ns_.clear();
  render_ms_.clear();
  publish_ms_.clear();
  last_error_.clear();
  MAV_LOG(kInfo) << "loaded " << source_->info().name << ": " << source_->info().frames
                 << " frames, " << source_->info().imu_samples << " IMU samples";
}

Result<PlayerStatus> Player::Start(const Pacing& pacing) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (state_ == PlayerState::kIdle) {
    return Status::FailedPrecondition("no scenario loaded: call LoadScenario first");
  }
  if (state_ == PlayerState::kRunning) {
    return Status::FailedPrecondition("already running: Pause first to change the pacing");
  }
  done_cv_.wait(lock, [&] { return !busy_; });
  if (state_ == PlayerState::kFinished) {
    next_frame_ = 0;
    next_imu_ = 0;
    next_gt_ = 0;
  }
  pacing_ = pacing;
  need_subscriber_wait_ = pacing.wait_for_subscribers > 0;
  state_ = PlayerState::kRunning;
  command_ = Command::kRun;
  anchor_wall_ns_ = 0;  // the worker anchors the schedule when it starts
  cv_.notify_all();
  return StatusLocked();
}

Result<PlayerStatus> Player::Pause() {
  std::unique_lock<std::mutex> lock(mutex_);
  if (state_ != PlayerState::kRunning) {
    return Status::FailedPrecondition(std::string("not running (state ") + PlayerStateName(state_) +
                                      ")");
  }
  command_ = Command::kNone;
  state_ = PlayerState::kPaused;
  cv_.notify_all();
  done_cv_.wait(lock, [&] { return !busy_; });
  // The worker may have reached the end while we waited.
  return StatusLocked();
}

Result<PlayerStatus> Player::Step(int64_t frames) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (state_ == PlayerState::kIdle) {
    return Status::FailedPrecondition("no scenario loaded: call LoadScenario first");
  }
  if (state_ == PlayerState::kRunning) {
    return Status::FailedPrecondition("running: Pause before stepping");
  }
  if (frames <= 0)
    return Status::InvalidArgument("frames: must be >= 1, got " + std::to_string(frames));
  done_cv_.wait(lock, [&] { return !busy_; });
  if (state_ == PlayerState::kFinished) {
    next_frame_ = 0;
    next_imu_ = 0;
    next_gt_ = 0;
  }
  const int64_t left = source_->info().frames - next_frame_;
  if (frames > left) {
    return Status::OutOfRange("frames: " + std::to_string(frames) + " requested but only " +
                              std::to_string(left) + " left (next frame " +
                              std::to_string(next_frame_) + " of " +
                              std::to_string(source_->info().frames) + ")");
  }
  state_ = PlayerState::kRunning;
  command_ = Command::kStep;
  step_remaining_ = frames;
  cv_.notify_all();
  done_cv_.wait(lock, [&] { return command_ != Command::kStep && !busy_; });
  return StatusLocked();
}

PlayerStatus Player::GetStatus() {
  std::unique_lock<std::mutex> lock(mutex_);
  return StatusLocked();
}

std::shared_ptr<const ScenarioSource> Player::source() {
  std::lock_guard<std::mutex> lock(mutex_);
  return source_;
}

PlayerStatus Player::StatusLocked() {
  PlayerStatus status;
  status.state = state_;
  if (source_ != nullptr) status.scenario = source_->info();
  status.next_frame = next_frame_;
  status.frames_published = frames_published_;
  status.imu_samples_published = imu_published_;
  status.ground_truth_published = gt_published_;
  status.current_t_ns = current_t_ns_;
  if (publish_wall_ns_.size() >= 2) {
    const double span_s = NsToSeconds(publish_wall_ns_.back() - publish_wall_ns_.front());
    if (span_s > 0) {
      status.achieved_rate_hz = static_cast<double>(publish_wall_ns_.size() - 1) / span_s;
    }
  }
  status.pacing = pacing_;
  status.stereo_subscribers = sink_->StereoSubscribers();
  status.imu_subscribers = sink_->ImuSubscribers();
  status.render_ms = ComputeStats(render_ms_);
  status.publish_ms = ComputeStats(publish_ms_);
  status.dds_domain = sink_->domain();
  status.last_error = last_error_;
  return status;
}

Status Player::PublishNextFrame(std::unique_lock<std::mutex>* lock, bool paced) {
  const ScenarioSource& source = *source_;
  const int64_t frame_index = next_frame_;
  const int64_t t_frame = source.FrameTimeNs(frame_index);
  const Command command = command_;
  const uint64_t generation = generation_;
  auto interrupted = [&] { return shutdown_ || command_ != command || generation_ != generation; };
  // Sleeps until data time t is due; false when interrupted (pause, load, shutdown).
  auto wait_due = [&](int64_t t_ns) {
    if (!paced) return !interrupted();
    const double factor = pacing_.real_time_factor;
    int64_t due =
        anchor_wall_ns_ + static_cast<int64_t>(static_cast<double>(t_ns - anchor_t_ns_) / factor);
    const int64_t now = MonotonicNowNs();
    if (now - due > kMaxLatenessNs) {
      anchor_wall_ns_ = now;
      anchor_t_ns_ = t_ns;
      due = now;
    }
    const auto deadline = std::chrono::steady_clock::time_point(std::chrono::nanoseconds(due));
    cv_.wait_until(*lock, deadline, interrupted);
    return !interrupted();
  };

  // Render (or fetch the pre-rendered) frame first so that the IMU and the frame go out together.
  RenderPipeline* pipeline = pipeline_.get();
  lock->unlock();
  Result<RenderedFrame> frame = pipeline->Get(frame_index);
  lock->lock();
  if (!frame.ok()) return frame.status().WithContext("frame " + std::to_string(frame_index));
  PushWindow(&render_ms_, frame->render_ms);

  const std::vector<dataset::ImuSample>& imu = source.imu();
  const std::vector<dataset::GroundTruthState>& gt = source.ground_truth();
  while (true) {
    const int64_t t_imu = next_imu_ < imu.size() ? imu[next_imu_].t_ns : kNoTime;
    const int64_t t_gt = next_gt_ < gt.size() ? gt[next_gt_].t_ns : kNoTime;
    const int64_t t_next = std::min(t_imu, t_gt);
    if (t_next > t_frame) break;
    if (!wait_due(t_next)) return Status::Ok();
    lock->unlock();
    Status status;
    if (t_imu <= t_gt) {
      status = sink_->PublishImu(imu_published_, imu[next_imu_]);
    } else {
      status = sink_->PublishGroundTruth(gt_published_, gt[next_gt_]);
    }
    lock->lock();
    if (t_imu <= t_gt) {
      ++next_imu_;
      ++imu_published_;
    } else {
      ++next_gt_;
      ++gt_published_;
    }
    if (!status.ok()) last_error_ = status.ToString();
  }
  if (!wait_due(t_frame)) return Status::Ok();

  lock->unlock();
  const int64_t start_ns = MonotonicNowNs();
  Status status = sink_->PublishStereo(frames_published_, *frame, source.info().rectified);
  if (status.ok() && !paced) status = sink_->WaitForStereoAcks(kAckTimeoutNs);
  const int64_t end_ns = MonotonicNowNs();
  lock->lock();
  if (!status.ok()) {
    last_error_ = status.ToString();
    MAV_LOG(kWarning) << "frame " << frame_index << ": " << last_error_;
  }
  PushWindow(&publish_ms_, static_cast<double>(end_ns - start_ns) * 1e-6);
  ++frames_published_;
  ++next_frame_;
  current_t_ns_ = t_frame;
  publish_wall_ns_.push_back(end_ns);
  while (publish_wall_ns_.size() > 2 && end_ns - publish_wall_ns_.front() > 2 * kNsPerSecond) {
    publish_wall_ns_.pop_front();
  }
  return Status::Ok();
}

void Player::WorkerLoop() {
  std::unique_lock<std::mutex> lock(mutex_);
  while (true) {
    cv_.wait(lock, [&] { return shutdown_ || command_ != Command::kNone; });
    if (shutdown_) return;
    busy_ = true;
    const uint64_t generation = generation_;
    if (command_ == Command::kRun) {
      if (need_subscriber_wait_) {
        need_subscriber_wait_ = false;
        const auto deadline = std::chrono::steady_clock::now() +
                              std::chrono::nanoseconds(SecondsToNs(pacing_.wait_timeout_s));
        while (command_ == Command::kRun && generation_ == generation && !shutdown_ &&
               sink_->StereoSubscribers() < pacing_.wait_for_subscribers &&
               std::chrono::steady_clock::now() < deadline) {
          cv_.wait_for(lock, std::chrono::milliseconds(10));
        }
      }
      anchor_wall_ns_ = MonotonicNowNs();
      anchor_t_ns_ = source_->FrameTimeNs(next_frame_);
      if (!source_->imu().empty() && next_imu_ < source_->imu().size()) {
        anchor_t_ns_ = std::min(anchor_t_ns_, source_->imu()[next_imu_].t_ns);
      }
      const bool paced = !pacing_.as_fast_as_subscribers;
      while (command_ == Command::kRun && generation_ == generation && !shutdown_) {
        const Status status = PublishNextFrame(&lock, paced);
        if (!status.ok()) {
          last_error_ = status.ToString();
          MAV_LOG(kError) << "playback stopped: " << last_error_;
          state_ = PlayerState::kPaused;
          command_ = Command::kNone;
          break;
        }
        if (next_frame_ >= source_->info().frames) {
          if (pacing_.loop) {
            next_frame_ = 0;
            next_imu_ = 0;
            next_gt_ = 0;
            anchor_wall_ns_ = MonotonicNowNs();
            anchor_t_ns_ = source_->FrameTimeNs(0);
          } else {
            state_ = PlayerState::kFinished;
            command_ = Command::kNone;
          }
        }
      }
    } else if (command_ == Command::kStep) {
      while (step_remaining_ > 0 && generation_ == generation && !shutdown_) {
        const Status status = PublishNextFrame(&lock, /*paced=*/false);
        if (!status.ok()) {
          last_error_ = status.ToString();
          break;
        }
        --step_remaining_;
      }
      if (generation_ == generation) {
        state_ = PlayerState::kPaused;
        command_ = Command::kNone;
      }
      step_remaining_ = 0;
    }
    busy_ = false;
    done_cv_.notify_all();
  }
}

}  // namespace mav::simulator_service
