#include "services/localization/pipeline.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <utility>

#include "mav/camera/rectifier.h"
#include "mav/common/check.h"
#include "mav/common/log.h"
#include "mav/common/time.h"

namespace mav::localization_service {

namespace {

// Covariance heuristic (pipeline.h).
constexpr double kDriftFraction = 0.02;
constexpr double kPositionFloorM = 0.001;
constexpr double kRotationFloorRad = 0.0005;
constexpr double kLostPositionSigmaM = 0.25;
constexpr double kLostRotationSigmaRad = 0.05;
constexpr double kSparseNominalSupport = 100.0;
constexpr double kSparseNominalResidualPx = 0.5;
constexpr double kDenseNominalSupport = 2000.0;
constexpr double kDenseNominalResidual = 10.0;

constexpr int64_t kFpsWindowNs = 2'000'000'000;

double MsSince(int64_t start_ns) { return (MonotonicNowNs() - start_ns) * 1e-6; }

RuntimeSummary Summarise(std::vector<double> values) {
  RuntimeSummary out;
  out.count = values.size();
  if (values.empty()) return out;
  std::sort(values.begin(), values.end());
  double sum = 0;
  for (double v : values) sum += v;
  out.mean_ms = sum / values.size();
  out.median_ms = values[values.size() / 2];
  out.p95_ms = values[std::min(values.size() - 1, static_cast<size_t>(0.95 * values.size()))];
  out.max_ms = values.back();
  return out;
}

std::string SizeText(int width, int height) {
  return std::to_string(width) + "x" + std::to_string(height);
}

}  // namespace

const char* OutputFrameName(OutputFrame frame) {
  return frame == OutputFrame::kCam0 ? "cam0" : "body";
}

const char* LocalizerStateName(LocalizerState state) {
  switch (state) {
    case LocalizerState::kUnconfigured:
      return "UNCONFIGURED";
    case LocalizerState::kReady:
      return "READY";
    case LocalizerState::kRunning:
      return "RUNNING";
  }
  return "UNSPECIFIED";
}

const char* ReportedStateName(ReportedState state) {
  switch (state) {
    case ReportedState::kUnspecified:
      return "UNSPECIFIED";
    case ReportedState::kInitializing:
      return "INITIALIZING";
    case ReportedState::kOk:
      return "OK";
    case ReportedState::kLost:
      return "LOST";
  }
  return "UNSPECIFIED";
}

bool LocalizerConfig::IsValid(std::string* why) const {
  std::string inner;
  if (!calibration.IsValid(&inner)) {
    if (why != nullptr) *why = "calibration: " + inner;
    return false;
  }
  if (calibration_rectified &&
      (calibration.cam0.HasDistortion() || calibration.cam1.HasDistortion())) {
    if (why != nullptr) *why = "calibration: a rectified rig must have no distortion";
    return false;
  }
  if (queue_length < 1 || queue_length > 100) {
    if (why != nullptr)
      *why = "queue_length: must be in [1, 100], got " + std::to_string(queue_length);
    return false;
  }
  if (method == Method::kDense) {
    if (!dense.IsValid(&inner)) {
      if (why != nullptr) *why = "dense: " + inner;
      return false;
    }
  } else if (!sparse.IsValid(&inner)) {
    if (why != nullptr) *why = "sparse: " + inner;
    return false;
  }
  return true;
}

// ---- Engine -------------------------------------------------------------------------------------

struct Localizer::Engine {
  LocalizerConfig config;
  std::optional<camera::StereoRectifier> rectifier;  // null for a rectified calibration
  camera::RectifiedStereo rig;
  geometry::SE3 T_body_rect0;
  std::unique_ptr<localization::SparseVo> sparse;
  std::unique_ptr<localization::DenseVo> dense;

  // Trajectory state, restarted by Reset.
  geometry::SE3 T_world_body0;
  uint64_t next_index = 0;
  bool have_previous = false;
  geometry::SE3 T_world_out_previous;
  Eigen::Matrix<double, 6, 1> variance = Eigen::Matrix<double, 6, 1>::Zero();

  void ResetTrajectory(const geometry::SE3& initial) {
    if (sparse != nullptr) sparse->Reset();
    if (dense != nullptr) dense->Reset();
    T_world_body0 = initial;
    next_index = 0;
    have_previous = false;
    variance.setZero();
  }

  static Result<std::unique_ptr<Engine>> Create(const LocalizerConfig& config) {
    std::string why;
    if (!config.IsValid(&why)) return Status::InvalidArgument(why);
    auto engine = std::make_unique<Engine>();
    engine->config = config;
    if (config.calibration_rectified) {
      const camera::PinholeRadTan& cam0 = config.calibration.cam0;
      engine->rig.width = cam0.width;
      engine->rig.height = cam0.height;
      engine->rig.fx = cam0.fx;
      engine->rig.fy = cam0.fy;
      engine->rig.cx = cam0.cx;
      engine->rig.cy = cam0.cy;
      engine->rig.baseline = config.calibration.Baseline();
      engine->T_body_rect0 = config.calibration.T_body_cam0;
    } else {
      Result<camera::StereoRectifier> rectifier =
          camera::StereoRectifier::Create(config.calibration);
      if (!rectifier.ok()) {
        return Status::InvalidArgument("calibration: " + rectifier.status().message());
      }
      engine->rig = rectifier->rectified();
      engine->T_body_rect0 = rectifier->T_body_rect0();
      engine->rectifier.emplace(std::move(*rectifier));
    }
    if (config.method == Method::kDense) {
      Result<localization::DenseVo> vo = localization::DenseVo::Create(engine->rig, config.dense);
      if (!vo.ok()) return Status::InvalidArgument("dense: " + vo.status().message());
      engine->dense = std::make_unique<localization::DenseVo>(std::move(*vo));
    } else {
      localization::SparseVoOptions options = config.sparse;
      options.mode = config.method == Method::kSparsePixel ? localization::SparseVoMode::kPixel
                                                           : localization::SparseVoMode::kSubpixel;
      Result<localization::SparseVo> vo = localization::SparseVo::Create(engine->rig, options);
      if (!vo.ok()) return Status::InvalidArgument("sparse: " + vo.status().message());
      engine->sparse = std::make_unique<localization::SparseVo>(std::move(*vo));
    }
    engine->T_world_body0 = config.T_world_body0;
    return engine;
  }
};

struct Localizer::Pending {
  bool done = false;
  Result<PoseOutput> result = Status::Unavailable("not processed");
  std::condition_variable cv;
};

// ---- Localizer ----------------------------------------------------------------------------------

Localizer::Localizer(PoseSink* sink) : sink_(sink) {
  worker_ = std::thread([this] { WorkerLoop(); });
}

Localizer::~Localizer() { Shutdown(); }

void Localizer::Shutdown() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (shutdown_) return;
    shutdown_ = true;
    ClearQueueLocked("the service is shutting down");
  }
  work_cv_.notify_all();
  if (worker_.joinable()) worker_.join();
}

void Localizer::ClearQueueLocked(const std::string& why) {
  for (Item& item : queue_) {
    if (item.pending != nullptr) {
      item.pending->result = Status::Unavailable("frame discarded: " + why);
      item.pending->done = true;
      item.pending->cv.notify_all();
    }
  }
  queue_.clear();
}

Status Localizer::Configure(const LocalizerConfig& config) {
  // Rectification maps and the VO are built outside the lock: the worker keeps running.
  MAV_ASSIGN_OR_RETURN(std::unique_ptr<Engine> engine, Engine::Create(config));
  std::unique_lock<std::mutex> lock(mutex_);
  idle_cv_.wait(lock, [this] { return !busy_; });
  ClearQueueLocked("the service was reconfigured");
  engine_ = std::move(engine);
  ++generation_;
  have_accepted_ = false;
  last_accepted_t_ns_ = 0;
  trajectory_.clear();
  frames_dropped_ = frames_lost_ = frames_rejected_ = keyframes_ = 0;
  done_wall_ns_.clear();
  processing_ms_.clear();
  MAV_LOG(kInfo) << "configured " << localization::MethodName(config.method) << ", "
                 << SizeText(engine_->rig.width, engine_->rig.height) << " rectified rig, fx "
                 << engine_->rig.fx << ", baseline " << engine_->rig.baseline << " m, queue "
                 << config.queue_length;
  return Status::Ok();
}

void Localizer::Reset(const std::optional<geometry::SE3>& T_world_body0) {
  std::unique_lock<std::mutex> lock(mutex_);
  idle_cv_.wait(lock, [this] { return !busy_; });
  ClearQueueLocked("the service was reset");
  ++generation_;
  have_accepted_ = false;
  last_accepted_t_ns_ = 0;
  trajectory_.clear();
  frames_dropped_ = frames_lost_ = frames_rejected_ = keyframes_ = 0;
  done_wall_ns_.clear();
  processing_ms_.clear();
  if (engine_ != nullptr) {
    engine_->ResetTrajectory(T_world_body0.value_or(engine_->config.T_world_body0));
  }
}

Status Localizer::CheckInput(const StereoInput& input, const std::string& field_prefix) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return CheckInputLocked(input, field_prefix);
}

Status Localizer::CheckInputLocked(const StereoInput& input,
                                   const std::string& field_prefix) const {
  if (engine_ == nullptr) {
    return Status::FailedPrecondition("not configured: call Configure first");
  }
  const int width = engine_->config.calibration.cam0.width;
  const int height = engine_->config.calibration.cam0.height;
  for (const auto& [name, image] :
       {std::pair<const char*, const cv::Mat*>{"left", &input.left},
        std::pair<const char*, const cv::Mat*>{"right", &input.right}}) {
    const std::string field = field_prefix + "." + name;
    if (image->empty()) return Status::InvalidArgument(field + ": empty image");
    if (image->type() != CV_8UC1) return Status::InvalidArgument(field + ": not 8-bit grey");
    if (image->cols != width || image->rows != height) {
      return Status::InvalidArgument(field + ": " + SizeText(image->cols, image->rows) +
                                     ", expected " + SizeText(width, height) +
                                     " (the calibration's size)");
    }
  }
  if (have_accepted_ && input.t_ns <= last_accepted_t_ns_) {
    return Status::InvalidArgument(field_prefix + ".t_ns: " + std::to_string(input.t_ns) +
                                   " is not after the previous frame's " +
                                   std::to_string(last_accepted_t_ns_));
  }
  return Status::Ok();
}

void Localizer::CountRejected() {
  std::lock_guard<std::mutex> lock(mutex_);
  ++frames_rejected_;
}

SubmitOutcome Localizer::SubmitLive(StereoInput input) {
  SubmitOutcome outcome = SubmitOutcome::kQueued;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (shutdown_ || engine_ == nullptr) return SubmitOutcome::kNotConfigured;
    const Status check = CheckInputLocked(input, "stereo");
    if (!check.ok()) {
      ++frames_rejected_;
      MAV_LOG(kWarning) << "rejected a DDS frame: " << check.message();
      return SubmitOutcome::kRejected;
    }
    if (static_cast<int>(queue_.size()) >= engine_->config.queue_length) {
      auto oldest_live = std::find_if(queue_.begin(), queue_.end(),
                                      [](const Item& item) { return item.pending == nullptr; });
      ++frames_dropped_;
      if (oldest_live == queue_.end()) return SubmitOutcome::kDropped;
      queue_.erase(oldest_live);
      outcome = SubmitOutcome::kQueuedDroppedOldest;
    }
    have_accepted_ = true;
    last_accepted_t_ns_ = input.t_ns;
    queue_.push_back(Item{std::move(input), nullptr, generation_});
  }
  work_cv_.notify_one();
  return outcome;
}

Result<PoseOutput> Localizer::SubmitAndWait(StereoInput input, int64_t timeout_ns,
                                            SubmitOutcome* outcome) {
  auto pending = std::make_shared<Pending>();
  std::unique_lock<std::mutex> lock(mutex_);
  auto set_outcome = [outcome](SubmitOutcome o) {
    if (outcome != nullptr) *outcome = o;
  };
  if (shutdown_) {
    set_outcome(SubmitOutcome::kNotConfigured);
    return Status::Unavailable("the service is shutting down");
  }
  const Status check = CheckInputLocked(input, "stereo");
  if (!check.ok()) {
    set_outcome(engine_ == nullptr ? SubmitOutcome::kNotConfigured : SubmitOutcome::kRejected);
    return check;
  }
  if (static_cast<int>(queue_.size()) >= engine_->config.queue_length) {
    set_outcome(SubmitOutcome::kQueueFull);
    return Status::Unavailable("input queue full (" + std::to_string(queue_.size()) +
                               " frames, queue_length " +
                               std::to_string(engine_->config.queue_length) + ")");
  }
  set_outcome(SubmitOutcome::kQueued);
  have_accepted_ = true;
  last_accepted_t_ns_ = input.t_ns;
  queue_.push_back(Item{std::move(input), pending, generation_});
  work_cv_.notify_one();
  if (!pending->cv.wait_for(lock, std::chrono::nanoseconds(timeout_ns),
                            [&pending] { return pending->done; })) {
    return Status::Unavailable("timed out waiting for the frame to be processed");
  }
  return pending->result;
}

void Localizer::WorkerLoop() {
  std::unique_lock<std::mutex> lock(mutex_);
  while (true) {
    work_cv_.wait(lock, [this] { return shutdown_ || !queue_.empty(); });
    if (shutdown_) return;
    Item item = std::move(queue_.front());
    queue_.pop_front();
    if (item.generation != generation_ || engine_ == nullptr) continue;
    Engine* engine = engine_.get();
    const uint64_t index = engine->next_index++;
    busy_ = true;
    lock.unlock();
    // The engine is used without the lock: Configure/Reset wait for busy_ to clear.
    Result<PoseOutput> result = ProcessFrame(engine, item.input, index);
    // Recorded before it is published, so that whoever receives the pose on DDS finds it in
    // GetStatus/GetTrajectory. The engine stays ours (busy_) until the pose is out.
    lock.lock();
    if (result.ok()) {
      trajectory_.push_back(*result);
      processing_ms_.push_back(result->timing.total_ms);
      if (result->state == ReportedState::kLost) ++frames_lost_;
      if (result->keyframe) ++keyframes_;
      const int64_t now = MonotonicNowNs();
      done_wall_ns_.push_back(now);
      while (!done_wall_ns_.empty() && now - done_wall_ns_.front() > kFpsWindowNs) {
        done_wall_ns_.pop_front();
      }
    } else {
      MAV_LOG(kWarning) << "frame " << item.input.t_ns << ": " << result.status().ToString();
    }
    lock.unlock();
    if (result.ok() && item.input.publish && sink_ != nullptr) {
      const Status published = sink_->PublishPose(*result, engine->config.output_frame);
      if (!published.ok()) {
        MAV_LOG(kWarning) << "publishing a pose: " << published.message();
      }
    }
    lock.lock();
    busy_ = false;
    if (item.pending != nullptr) {
      item.pending->result = std::move(result);
      item.pending->done = true;
      item.pending->cv.notify_all();
    }
    idle_cv_.notify_all();
  }
}

// Runs on the worker thread without the lock; the worker holds the engine exclusively (busy_).
Result<PoseOutput> Localizer::ProcessFrame(Engine* engine, const StereoInput& input,
                                           uint64_t index) {
  const int64_t start_ns = MonotonicNowNs();
  PoseOutput out;
  out.t_ns = input.t_ns;
  out.frame_index = index;

  cv::Mat left = input.left;
  cv::Mat right = input.right;
  if (!input.rectified && engine->rectifier.has_value()) {
    const int64_t rectify_start = MonotonicNowNs();
    cv::Mat rect_left, rect_right;
    MAV_RETURN_IF_ERROR(
        engine->rectifier->Rectify(input.left, input.right, &rect_left, &rect_right));
    left = rect_left;
    right = rect_right;
    out.timing.rectify_ms = MsSince(rectify_start);
  }

  geometry::SE3 T_rect00_rect0k;
  bool lost = false;
  bool reinitialised = false;
  double support = 0, nominal_support = 1, residual = 0, nominal_residual = 1;
  if (engine->sparse != nullptr) {
    MAV_ASSIGN_OR_RETURN(const localization::VoFrameResult r,
                         engine->sparse->ProcessFrame(input.t_ns, left, right));
    T_rect00_rect0k = r.T_world_cam;
    lost = r.state == localization::TrackingState::kLost;
    reinitialised = r.reference_reset;
    out.lost_reason = r.lost_reason;
    out.matches = static_cast<uint32_t>(std::max(0, r.num_matches));
    out.inliers = static_cast<uint32_t>(std::max(0, r.num_inliers));
    out.residual = r.mean_reprojection_error_px;
    out.timing.features_ms = r.timing.features_ms;
    out.timing.matching_ms = r.timing.matching_ms;
    out.timing.motion_ms = r.timing.estimation_ms;
    support = r.num_inliers;
    nominal_support = kSparseNominalSupport;
    residual = r.mean_reprojection_error_px;
    nominal_residual = kSparseNominalResidualPx;
  } else {
    MAV_CHECK(engine->dense != nullptr);
    MAV_ASSIGN_OR_RETURN(const localization::DenseFrameResult r,
                         engine->dense->ProcessFrame(input.t_ns, left, right));
    T_rect00_rect0k = r.T_world_cam;
    lost = r.state == localization::TrackingState::kLost;
    reinitialised = r.reference_reset;
    out.lost_reason = r.lost_reason;
    out.matches = static_cast<uint32_t>(std::max(0, r.num_keyframe_pixels));
    out.inliers = static_cast<uint32_t>(std::max(0, r.num_pixels_used));
    out.residual = r.rms_error;
    out.keyframe = r.new_keyframe;
    out.timing.features_ms = r.timing.keyframe_ms;
    out.timing.motion_ms = r.timing.pyramid_ms + r.timing.tracking_ms;
    support = r.num_pixels_used;
    nominal_support = kDenseNominalSupport;
    residual = r.rms_error;
    nominal_residual = kDenseNominalResidual;
  }

  const geometry::SE3 T_world_body = engine->T_world_body0 * engine->T_body_rect0 *
                                     T_rect00_rect0k * engine->T_body_rect0.Inverse();
  out.T_world_out = engine->config.output_frame == OutputFrame::kCam0
                        ? T_world_body * engine->config.calibration.T_body_cam0
                        : T_world_body;
  out.T_prev_cur = engine->have_previous ? engine->T_world_out_previous.Inverse() * out.T_world_out
                                         : geometry::SE3::Identity();
  engine->T_world_out_previous = out.T_world_out;
  engine->have_previous = true;

  if (lost) {
    out.state = ReportedState::kLost;
  } else if (index == 0 || reinitialised) {
    out.state = ReportedState::kInitializing;
  } else {
    out.state = ReportedState::kOk;
  }

  // The covariance heuristic of pipeline.h.
  double sigma_p = 0, sigma_r = 0;
  if (lost) {
    sigma_p = kLostPositionSigmaM;
    sigma_r = kLostRotationSigmaRad;
  } else if (index > 0) {
    const double scale = std::sqrt(nominal_support / std::max(support, 1.0)) *
                         std::max(1.0, residual / nominal_residual);
    const Eigen::Matrix<double, 6, 1> xi = out.T_prev_cur.Log();
    sigma_p = scale * (kDriftFraction * xi.head<3>().norm() + kPositionFloorM);
    sigma_r = scale * (kDriftFraction * xi.tail<3>().norm() + kRotationFloorRad);
  }
  engine->variance.head<3>().array() += sigma_p * sigma_p;
  engine->variance.tail<3>().array() += sigma_r * sigma_r;
  out.covariance.fill(0.0);
  for (int i = 0; i < 6; ++i) out.covariance[i * 6 + i] = engine->variance[i];

  out.timing.total_ms = MsSince(start_ns);
  return out;
}

bool Localizer::configured() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return engine_ != nullptr;
}

LocalizerStatus Localizer::GetStatus() {
  std::lock_guard<std::mutex> lock(mutex_);
  LocalizerStatus out;
  if (engine_ == nullptr) return out;
  out.config = engine_->config;
  out.state = trajectory_.empty() && !busy_ && queue_.empty() ? LocalizerState::kReady
                                                              : LocalizerState::kRunning;
  out.frames_processed = trajectory_.size();
  out.frames_dropped = frames_dropped_;
  out.frames_lost = frames_lost_;
  out.frames_rejected = frames_rejected_;
  const int64_t now = MonotonicNowNs();
  size_t recent = 0;
  int64_t oldest = now;
  for (int64_t t : done_wall_ns_) {
    if (now - t <= kFpsWindowNs) {
      ++recent;
      oldest = std::min(oldest, t);
    }
  }
  // Frames per second over the window; with fewer than 2 frames there is no rate.
  if (recent >= 2 && now > oldest) out.fps = (recent - 1) / NsToSeconds(now - oldest);
  if (!trajectory_.empty()) out.last = trajectory_.back();
  out.processing_ms = Summarise(processing_ms_);
  out.keyframes = keyframes_;
  out.queue_depth = static_cast<uint32_t>(queue_.size());
  return out;
}

std::vector<PoseOutput> Localizer::Trajectory(int64_t start_t_ns, int64_t end_t_ns) {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<PoseOutput> out;
  for (const PoseOutput& p : trajectory_) {
    if (start_t_ns != 0 && p.t_ns < start_t_ns) continue;
    if (end_t_ns != 0 && p.t_ns > end_t_ns) continue;
    out.push_back(p);
  }
  return out;
}

}  // namespace mav::localization_service
