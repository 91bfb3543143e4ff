#include "services/mapping/mapper.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "mav/camera/rectifier.h"
#include "mav/common/log.h"
#include "mav/common/time.h"
#include "mav/mapping/mesh_to_grid.h"

namespace mav::mapping_service {

namespace {

constexpr int64_t kDefaultWaitNs = 30'000'000'000;

double MsSince(int64_t start_ns) { return static_cast<double>(MonotonicNowNs() - start_ns) * 1e-6; }

bool Finite(const geometry::SE3& pose) {
  return pose.Translation().allFinite() && pose.Rotation().coeffs().allFinite();
}

RuntimeSummary Summarise(std::vector<double> values) {
  RuntimeSummary out;
  out.count = values.size();
  if (values.empty()) return out;
  std::sort(values.begin(), values.end());
  double sum = 0;
  for (double v : values) sum += v;
  out.mean_ms = sum / static_cast<double>(values.size());
  out.median_ms = values[values.size() / 2];
  out.p95_ms = values[std::min(values.size() - 1, (values.size() * 95) / 100)];
  out.max_ms = values.back();
  return out;
}

// The grid covering `box`, its origin snapped down to a multiple of the resolution so that voxel
// boundaries coincide with OctoMap's.
dataset::GridGeometry GeometryOfBox(const Eigen::AlignedBox3d& box, double resolution) {
  dataset::GridGeometry g;
  g.resolution = resolution;
  g.origin = (box.min() / resolution).array().floor().matrix() * resolution;
  const Eigen::Vector3d extent = (box.max() - g.origin) / resolution;
  for (int i = 0; i < 3; ++i) {
    g.size[i] = std::max(1, static_cast<int>(std::ceil(extent[i] - 1e-9)));
  }
  return g;
}

bool Expired(int64_t deadline_ns) { return deadline_ns != 0 && MonotonicNowNs() > deadline_ns; }

}  // namespace

const char* PoseSourceName(PoseSource source) {
  switch (source) {
    case PoseSource::kNone:
      return "none";
    case PoseSource::kLocalization:
      return "localization";
    case PoseSource::kGroundTruth:
      return "ground-truth";
  }
  return "?";
}

bool SessionConfig::IsValid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why != nullptr) *why = m;
    return false;
  };
  std::string sub;
  if (!calibration.IsValid(&sub)) return fail("calibration: " + sub);
  if (!keyframes.IsValid(&sub)) return fail("keyframes." + sub);
  if (max_keyframes < 1 || max_keyframes > 100000) {
    return fail("max_keyframes: must be in [1, 100000], got " + std::to_string(max_keyframes));
  }
  if (features_per_keyframe < 1 || features_per_keyframe > 10000) {
    return fail("features_per_keyframe: must be in [1, 10000], got " +
                std::to_string(features_per_keyframe));
  }
  if (queue_length < 1 || queue_length > 1000) {
    return fail("queue_length: must be in [1, 1000], got " + std::to_string(queue_length));
  }
  if (pose_wait_ms <= 0) return fail("pose_wait_ms: must be > 0");
  return true;
}

// ---- PoseMatcher --------------------------------------------------------------------------------

PoseMatcher::Decision PoseMatcher::Lookup(int64_t t_ns, geometry::SE3* T_world_body) const {
  if (poses_.empty()) return Decision::kWait;
  const auto after = std::lower_bound(
      poses_.begin(), poses_.end(), t_ns,
      [](const std::pair<int64_t, geometry::SE3>& p, int64_t t) { return p.first < t; });
  if (source_ == PoseSource::kLocalization) {
    if (after != poses_.end() && after->first == t_ns) {
      *T_world_body = after->second;
      return Decision::kPose;
    }
    // One writer, reliable and in order: a newer pose means this frame's pose will not come
    // (the estimator skipped the frame).
    return poses_.back().first > t_ns ? Decision::kNoPose : Decision::kWait;
  }
  if (after == poses_.end()) return Decision::kWait;  // nothing at or after t yet
  if (after->first == t_ns) {
    *T_world_body = after->second;
    return Decision::kPose;
  }
  if (after == poses_.begin()) return Decision::kNoPose;  // history starts after the frame
  const auto before = std::prev(after);
  if (t_ns - before->first > kMaxPoseGapNs || after->first - t_ns > kMaxPoseGapNs) {
    return Decision::kNoPose;
  }
  const double alpha =
      static_cast<double>(t_ns - before->first) / static_cast<double>(after->first - before->first);
  *T_world_body = geometry::InterpolatePose(before->second, after->second, alpha);
  return Decision::kPose;
}

std::vector<PoseMatcher::Matched> PoseMatcher::Resolve(uint64_t* dropped) {
  std::vector<Matched> out;
  for (auto it = pending_.begin(); it != pending_.end();) {
    geometry::SE3 pose;
    const Decision decision = Lookup(it->frame.t_ns, &pose);
    if (decision == Decision::kWait) {
      ++it;
      continue;
    }
    if (decision == Decision::kPose) {
      out.push_back({std::move(it->frame), pose});
    } else if (dropped != nullptr) {
      ++*dropped;
    }
    it = pending_.erase(it);
  }
  std::sort(out.begin(), out.end(),
            [](const Matched& a, const Matched& b) { return a.frame.t_ns < b.frame.t_ns; });
  return out;
}

std::vector<PoseMatcher::Matched> PoseMatcher::AddPose(int64_t t_ns,
                                                       const geometry::SE3& T_world_body,
                                                       uint64_t* dropped) {
  if (poses_.empty() || poses_.back().first < t_ns) {
    poses_.emplace_back(t_ns, T_world_body);
  } else {
    const auto at = std::lower_bound(
        poses_.begin(), poses_.end(), t_ns,
        [](const std::pair<int64_t, geometry::SE3>& p, int64_t t) { return p.first < t; });
    if (at != poses_.end() && at->first == t_ns) {
      at->second = T_world_body;  // a repeated sample (e.g. a replay) replaces the old one
    } else {
      poses_.insert(at, {t_ns, T_world_body});
    }
  }
  while (poses_.size() > kMaxHistory) poses_.pop_front();
  if (pending_.empty()) return {};
  return Resolve(dropped);
}

std::vector<PoseMatcher::Matched> PoseMatcher::AddFrame(FrameInput frame, int64_t now_ns,
                                                        uint64_t* dropped) {
  pending_.push_back({std::move(frame), now_ns});
  while (pending_.size() > static_cast<size_t>(kMaxPendingFrames)) {
    pending_.pop_front();
    if (dropped != nullptr) ++*dropped;
  }
  return Resolve(dropped);
}

uint64_t PoseMatcher::Expire(int64_t now_ns) {
  uint64_t n = 0;
  while (!pending_.empty() && now_ns - pending_.front().arrived_ns > wait_ns_) {
    pending_.pop_front();
    ++n;
  }
  return n;
}

void PoseMatcher::Clear() {
  poses_.clear();
  pending_.clear();
}

// ---- Mapper internals ---------------------------------------------------------------------------

struct Mapper::Engine {
  SessionConfig config;
  std::optional<camera::StereoRectifier> rectifier;  // null for a rectified calibration
  camera::RectifiedStereo rig;
  geometry::SE3 T_body_rect0;
  std::optional<mapping::MappingPipeline> pipeline;

  static Result<std::unique_ptr<Engine>> Create(const SessionConfig& config) {
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
    mapping::MappingPipelineOptions options;
    options.keyframes = config.keyframes;
    options.sparse.target_points_per_keyframe = config.features_per_keyframe;
    Result<mapping::MappingPipeline> pipeline =
        mapping::MappingPipeline::Create(engine->rig, options);
    if (!pipeline.ok()) return Status::InvalidArgument("session: " + pipeline.status().message());
    engine->pipeline.emplace(std::move(*pipeline));
    return engine;
  }
};

struct Mapper::KeyframeJob {
  FrameInput frame;
  geometry::SE3 T_world_body;
  // Null for live frames.
  std::shared_ptr<std::promise<Result<KeyframeResult>>> promise;
};

struct BuildOutcome {
  Status status;
  Refusal refusal = Refusal::kNone;
  MapStats stats;
};

struct Mapper::BuildJob {
  BuildRequest request;
  std::shared_ptr<std::promise<BuildOutcome>> promise;
};

struct Mapper::Item {
  uint64_t generation = 0;
  std::optional<KeyframeJob> keyframe;
  std::optional<BuildJob> build;
  bool live() const { return keyframe.has_value() && keyframe->promise == nullptr; }
  void Fail(const std::string& why) {
    if (keyframe && keyframe->promise) keyframe->promise->set_value(Status::Unavailable(why));
    if (build) build->promise->set_value({Status::Unavailable(why), Refusal::kNone, {}});
  }
};

// The thread starts after every member is constructed.
Mapper::Mapper() {
  worker_ = std::thread([this] { WorkerLoop(); });
}

Mapper::~Mapper() { Shutdown(); }

void Mapper::Shutdown() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (shutdown_) return;
    shutdown_ = true;
  }
  work_cv_.notify_all();
  if (worker_.joinable()) worker_.join();
  std::lock_guard<std::mutex> lock(mutex_);
  for (auto& item : queue_) item->Fail("the mapping service is shutting down");
  queue_.clear();
}

void Mapper::set_max_voxels(int64_t max_voxels) {
  std::lock_guard<std::mutex> lock(mutex_);
  max_voxels_ = max_voxels;
}

void Mapper::ClearLocked() {
  for (auto& item : queue_) item->Fail("the session was restarted or reset");
  queue_.clear();
  if (matcher_) matcher_->Clear();
  if (selector_) selector_->Reset();
  frames_seen_ = frames_without_pose_ = frames_dropped_ = frames_rejected_ = 0;
  keyframes_selected_ = keyframes_done_ = 0;
  points_ = 0;
  building_ = false;
  build_stage_.clear();
  build_fraction_ = 0;
  keyframe_ms_.clear();
  sparse_mesh_map_.reset();
  octomap_map_.reset();
  last_built_.reset();
}

Status Mapper::StartSession(const SessionConfig& config) {
  // Rectification maps and the pipeline are built outside the lock: the worker keeps running.
  MAV_ASSIGN_OR_RETURN(std::unique_ptr<Engine> engine, Engine::Create(config));
  std::unique_lock<std::mutex> lock(mutex_);
  if (shutdown_) return Status::Unavailable("the mapping service is shutting down");
  ++generation_;
  idle_cv_.wait(lock, [this] { return !busy_; });
  ClearLocked();
  rig_ = engine->rig;
  T_body_rect0_ = engine->T_body_rect0;
  engine_ = std::move(engine);
  config_ = config;
  matcher_.emplace(config.pose_source, config.pose_wait_ms * 1'000'000);
  selector_.emplace(config.keyframes);
  MAV_LOG(kInfo) << "mapping session: " << rig_.width << "x" << rig_.height << " rig, poses from "
                 << PoseSourceName(config.pose_source) << ", keyframes every "
                 << config.keyframes.min_translation_m << " m / "
                 << config.keyframes.min_rotation_rad * 180.0 / M_PI << " deg";
  return Status::Ok();
}

Status Mapper::Reset() {
  std::unique_lock<std::mutex> lock(mutex_);
  if (!engine_) return Status::FailedPrecondition("no session: call StartSession first");
  ++generation_;
  idle_cv_.wait(lock, [this] { return !busy_; });
  ClearLocked();
  engine_->pipeline->Reset();  // the worker is idle and takes no item of the old generation
  return Status::Ok();
}

bool Mapper::session_active() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return engine_ != nullptr;
}

std::optional<SessionConfig> Mapper::config() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return config_;
}

Status Mapper::CheckInput(const FrameInput& frame, const std::string& field) const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!engine_) return Status::FailedPrecondition("no session: call StartSession first");
  for (const auto& [name, image] :
       {std::pair<const char*, const cv::Mat*>{"left", &frame.left},
        std::pair<const char*, const cv::Mat*>{"right", &frame.right}}) {
    if (image->empty() || image->type() != CV_8UC1 || image->cols != rig_.width ||
        image->rows != rig_.height) {
      return Status::InvalidArgument(
          field + "." + name + ": " + std::to_string(image->cols) + "x" +
          std::to_string(image->rows) + " differs from the calibration's " +
          std::to_string(rig_.width) + "x" + std::to_string(rig_.height));
    }
  }
  return Status::Ok();
}

bool Mapper::SelectLocked(const geometry::SE3& T_world_body, bool force) {
  const geometry::SE3 T_world_cam = T_world_body * T_body_rect0_;
  if (force) {
    // The forced keyframe becomes the rule's reference, as a selected one would.
    selector_->Reset();
  }
  return selector_->Consider(T_world_cam);
}

void Mapper::EnqueueMatchedLocked(std::vector<PoseMatcher::Matched> matched) {
  bool queued = false;
  for (PoseMatcher::Matched& m : matched) {
    if (!Finite(m.T_world_body)) {
      ++frames_without_pose_;
      continue;
    }
    if (!SelectLocked(m.T_world_body, false)) continue;
    if (keyframes_selected_ >= static_cast<uint32_t>(config_->max_keyframes)) {
      ++frames_dropped_;
      continue;
    }
    ++keyframes_selected_;
    auto item = std::make_unique<Item>();
    item->generation = generation_;
    item->keyframe = KeyframeJob{std::move(m.frame), m.T_world_body, nullptr};
    queue_.push_back(std::move(item));
    queued = true;
    // Drop-oldest among live keyframes when the queue is over its length.
    size_t live = 0;
    for (const auto& q : queue_) live += q->live() ? 1 : 0;
    if (live > static_cast<size_t>(config_->queue_length)) {
      for (auto it = queue_.begin(); it != queue_.end(); ++it) {
        if ((*it)->live()) {
          queue_.erase(it);
          ++frames_dropped_;
          --keyframes_selected_;
          break;
        }
      }
    }
  }
  if (queued) work_cv_.notify_one();
}

void Mapper::SubmitLiveFrame(FrameInput frame) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!engine_ || shutdown_) return;
  ++frames_seen_;
  if (frame.left.cols != rig_.width || frame.left.rows != rig_.height ||
      frame.right.size() != frame.left.size()) {
    ++frames_rejected_;
    return;
  }
  if (config_->pose_source == PoseSource::kNone) {
    ++frames_without_pose_;
    return;
  }
  EnqueueMatchedLocked(
      matcher_->AddFrame(std::move(frame), MonotonicNowNs(), &frames_without_pose_));
}

void Mapper::SubmitPose(int64_t t_ns, const geometry::SE3& T_world_body) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!engine_ || shutdown_ || !matcher_) return;
  EnqueueMatchedLocked(matcher_->AddPose(t_ns, T_world_body, &frames_without_pose_));
}

void Mapper::Tick() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (matcher_) frames_without_pose_ += matcher_->Expire(MonotonicNowNs());
}

void Mapper::CountRejected() {
  std::lock_guard<std::mutex> lock(mutex_);
  ++frames_seen_;
  ++frames_rejected_;
}

Result<KeyframeResult> Mapper::SubmitKeyframeAndWait(FrameInput frame,
                                                     const geometry::SE3& T_world_body, bool force,
                                                     int64_t deadline_monotonic_ns,
                                                     Refusal* refusal) {
  *refusal = Refusal::kNone;
  MAV_RETURN_IF_ERROR(CheckInput(frame, "stereo"));
  if (!Finite(T_world_body)) return Status::InvalidArgument("t_world_body: not finite");
  std::future<Result<KeyframeResult>> future;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!engine_) return Status::FailedPrecondition("no session: call StartSession first");
    if (building_) {
      *refusal = Refusal::kResourceExhausted;
      return Status::Unavailable("a BuildMap is running; insert keyframes after it");
    }
    if (keyframes_selected_ >= static_cast<uint32_t>(config_->max_keyframes)) {
      *refusal = Refusal::kResourceExhausted;
      return Status::Unavailable("keyframes.max_keyframes: the session holds its limit of " +
                                 std::to_string(config_->max_keyframes) + " keyframes");
    }
    if (queue_.size() >= static_cast<size_t>(config_->queue_length) + 16) {
      *refusal = Refusal::kResourceExhausted;
      return Status::Unavailable("the keyframe queue is full (" + std::to_string(queue_.size()) +
                                 " waiting); retry later");
    }
    ++frames_seen_;
    if (!SelectLocked(T_world_body, force)) {
      KeyframeResult skipped;
      skipped.points_total = points_;
      return skipped;
    }
    ++keyframes_selected_;
    auto promise = std::make_shared<std::promise<Result<KeyframeResult>>>();
    future = promise->get_future();
    auto item = std::make_unique<Item>();
    item->generation = generation_;
    item->keyframe = KeyframeJob{std::move(frame), T_world_body, promise};
    queue_.push_back(std::move(item));
  }
  work_cv_.notify_one();
  const int64_t deadline =
      deadline_monotonic_ns != 0 ? deadline_monotonic_ns : MonotonicNowNs() + kDefaultWaitNs;
  const int64_t wait_ns = std::max<int64_t>(0, deadline - MonotonicNowNs());
  if (future.wait_for(std::chrono::nanoseconds(wait_ns)) != std::future_status::ready) {
    *refusal = Refusal::kDeadlineExceeded;
    return Status::Unavailable(
        "the keyframe was not integrated before the deadline (it still "
        "will be)");
  }
  return future.get();
}

Result<MapStats> Mapper::BuildAndWait(const BuildRequest& request, Refusal* refusal) {
  *refusal = Refusal::kNone;
  if (!std::isfinite(request.resolution_m) || request.resolution_m < 0.01 ||
      request.resolution_m > 2.0) {
    return Status::InvalidArgument("resolution_m: must be in [0.01, 2] m, got " +
                                   std::to_string(request.resolution_m));
  }
  if (request.min_visibility < 1 || request.min_visibility > 100) {
    return Status::InvalidArgument("sparse_mesh.min_visibility: must be in [1, 100], got " +
                                   std::to_string(request.min_visibility));
  }
  std::string why;
  if (!request.meshing.IsValid(&why)) return Status::InvalidArgument("sparse_mesh: " + why);
  std::future<BuildOutcome> future;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!engine_) return Status::FailedPrecondition("no session: call StartSession first");
    if (building_) {
      *refusal = Refusal::kResourceExhausted;
      return Status::Unavailable("another BuildMap is running; retry when it is done");
    }
    building_ = true;
    build_stage_ = "waiting for queued keyframes";
    build_fraction_ = 0;
    build_start_ns_ = MonotonicNowNs();
    auto promise = std::make_shared<std::promise<BuildOutcome>>();
    future = promise->get_future();
    auto item = std::make_unique<Item>();
    item->generation = generation_;
    item->build = BuildJob{request, promise};
    queue_.push_back(std::move(item));
  }
  work_cv_.notify_one();
  if (request.deadline_monotonic_ns != 0) {
    // A little past the deadline: the worker notices it between stages and answers itself.
    const int64_t wait_ns =
        std::max<int64_t>(0, request.deadline_monotonic_ns - MonotonicNowNs()) + 200'000'000;
    if (future.wait_for(std::chrono::nanoseconds(wait_ns)) != std::future_status::ready) {
      *refusal = Refusal::kDeadlineExceeded;
      return Status::Unavailable("BuildMap: the deadline passed (the partial map is discarded)");
    }
  }
  BuildOutcome outcome = future.get();
  *refusal = outcome.refusal;
  if (!outcome.status.ok()) return outcome.status;
  return outcome.stats;
}

std::shared_ptr<const BuiltMap> Mapper::Map(std::optional<MappingMethod> method) const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!method.has_value()) method = last_built_;
  if (!method.has_value()) return nullptr;
  return *method == MappingMethod::kSparseMesh ? sparse_mesh_map_ : octomap_map_;
}

MapperStatus Mapper::GetStatus() const {
  std::lock_guard<std::mutex> lock(mutex_);
  MapperStatus s;
  s.session_active = engine_ != nullptr;
  if (config_) s.pose_source = config_->pose_source;
  s.frames_seen = frames_seen_;
  s.keyframes = keyframes_done_;
  s.keyframes_selected = keyframes_selected_;
  s.points = points_;
  s.frames_without_pose = frames_without_pose_;
  s.frames_dropped = frames_dropped_;
  s.frames_rejected = frames_rejected_;
  s.queue_depth = static_cast<uint32_t>(queue_.size());
  s.pending_frames = matcher_ ? static_cast<uint32_t>(matcher_->pending()) : 0;
  s.building = building_;
  if (building_) {
    s.build_stage = build_stage_;
    s.build_fraction = build_fraction_;
    s.build_elapsed_s = static_cast<double>(MonotonicNowNs() - build_start_ns_) * 1e-9;
  }
  if (sparse_mesh_map_) s.maps.push_back(sparse_mesh_map_->stats);
  if (octomap_map_) s.maps.push_back(octomap_map_->stats);
  s.keyframe_ms = Summarise(keyframe_ms_);
  return s;
}

void Mapper::SetProgress(const std::string& stage, double fraction) {
  std::lock_guard<std::mutex> lock(mutex_);
  build_stage_ = stage;
  build_fraction_ = fraction;
}

// ---- The worker ---------------------------------------------------------------------------------

void Mapper::WorkerLoop() {
  std::unique_lock<std::mutex> lock(mutex_);
  while (true) {
    work_cv_.wait(lock, [this] { return shutdown_ || !queue_.empty(); });
    if (shutdown_) return;
    std::unique_ptr<Item> item = std::move(queue_.front());
    queue_.pop_front();
    if (item->generation != generation_ || !engine_) {
      item->Fail("the session was restarted or reset");
      continue;
    }
    busy_ = true;
    Engine* engine = engine_.get();
    const uint64_t generation = item->generation;
    lock.unlock();

    if (item->keyframe) {
      const int64_t start = MonotonicNowNs();
      Result<KeyframeResult> result =
          ProcessKeyframe(engine, item->keyframe->frame, item->keyframe->T_world_body);
      const double ms = MsSince(start);
      lock.lock();
      busy_ = false;
      if (generation == generation_) {
        if (result.ok()) {
          ++keyframes_done_;
          points_ = result->points_total;
          keyframe_ms_.push_back(ms);
        } else {
          --keyframes_selected_;
          if (item->live()) {
            ++frames_rejected_;
            MAV_LOG(kWarning) << "live keyframe at t_ns " << item->keyframe->frame.t_ns
                              << " rejected: " << result.status().message();
          }
        }
      }
      idle_cv_.notify_all();
      if (item->keyframe->promise) {
        if (generation != generation_) {
          item->keyframe->promise->set_value(
              Status::Unavailable("the session was restarted or reset"));
        } else {
          item->keyframe->promise->set_value(std::move(result));
        }
      }
    } else if (item->build) {
      Refusal refusal = Refusal::kNone;
      Result<std::shared_ptr<BuiltMap>> built = RunBuild(engine, item->build->request, &refusal);
      lock.lock();
      busy_ = false;
      BuildOutcome outcome;
      if (generation != generation_) {
        outcome.status = Status::Unavailable("the session was restarted or reset during the build");
      } else {
        building_ = false;
        build_stage_.clear();
        if (built.ok()) {
          outcome.stats = (*built)->stats;
          if (outcome.stats.method == MappingMethod::kSparseMesh) {
            sparse_mesh_map_ = std::move(*built);
          } else {
            octomap_map_ = std::move(*built);
          }
          last_built_ = outcome.stats.method;
        } else {
          outcome.status = built.status();
          outcome.refusal = refusal;
        }
      }
      idle_cv_.notify_all();
      item->build->promise->set_value(std::move(outcome));
    } else {
      lock.lock();
      busy_ = false;
      idle_cv_.notify_all();
    }
  }
}

Result<KeyframeResult> Mapper::ProcessKeyframe(Engine* engine, const FrameInput& frame,
                                               const geometry::SE3& T_world_body) {
  const int64_t start = MonotonicNowNs();
  cv::Mat left = frame.left;
  cv::Mat right = frame.right;
  if (!frame.rectified && engine->rectifier.has_value()) {
    MAV_RETURN_IF_ERROR(engine->rectifier->Rectify(frame.left, frame.right, &left, &right));
  }
  const geometry::SE3 T_world_cam = T_world_body * engine->T_body_rect0;
  mapping::MappingPipeline& pipeline = *engine->pipeline;
  MAV_RETURN_IF_ERROR(pipeline.InsertKeyframe(left, right, T_world_cam));
  KeyframeResult out;
  out.accepted = true;
  out.keyframe_index = static_cast<uint32_t>(pipeline.num_keyframes() - 1);
  if (const mapping::SparsePointCloud* sparse = pipeline.sparse_points(); sparse != nullptr) {
    if (!sparse->stats().keyframes.empty()) {
      out.features = static_cast<uint32_t>(sparse->stats().keyframes.back().selected);
    }
    out.points_total = static_cast<uint64_t>(sparse->num_points());
  }
  out.processing_ms = MsSince(start);
  return out;
}

Result<std::shared_ptr<BuiltMap>> Mapper::RunBuild(Engine* engine, const BuildRequest& request,
                                                   Refusal* refusal) {
  const int64_t start = MonotonicNowNs();
  mapping::MappingPipeline& pipeline = *engine->pipeline;
  const mapping::SparsePointCloud* sparse = pipeline.sparse_points();
  const mapping::OctomapMapper* octomap = pipeline.octomap_mapper();
  if (pipeline.num_keyframes() == 0) {
    return Status::FailedPrecondition(
        "empty map: no keyframes yet (stream frames with poses or call InsertKeyframe first)");
  }
  auto deadline = [&]() -> Status {
    if (!Expired(request.deadline_monotonic_ns)) return Status::Ok();
    *refusal = Refusal::kDeadlineExceeded;
    return Status::Unavailable("BuildMap: the deadline passed (the partial map is discarded)");
  };

  std::vector<mapping::MapPoint> points;
  std::vector<mapping::KeyframeView> views;
  if (sparse != nullptr) {
    points = sparse->Points();
    views = sparse->keyframes();
    if (request.min_visibility > 1) {
      std::erase_if(points, [&](const mapping::MapPoint& p) {
        return static_cast<int>(p.keyframes.size()) < request.min_visibility;
      });
    }
  }
  dataset::GridGeometry geometry;
  if (request.bounds.has_value()) {
    geometry = GeometryOfBox(*request.bounds, request.resolution_m);
  } else {
    geometry = mapping::GridGeometryAround(points, views, request.resolution_m,
                                           BuildRequest::kDefaultPaddingM);
  }
  int64_t max_voxels = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    max_voxels = max_voxels_;
  }
  if (geometry.num_voxels() > max_voxels) {
    *refusal = Refusal::kResourceExhausted;
    return Status::Unavailable("bounds/resolution_m: the grid would have " +
                               std::to_string(geometry.num_voxels()) +
                               " voxels, over the server's limit of " + std::to_string(max_voxels));
  }

  auto map = std::make_shared<BuiltMap>();
  MapStats& stats = map->stats;
  stats.method = request.method;
  stats.keyframes = static_cast<uint32_t>(pipeline.num_keyframes());
  BuildTiming& timing = stats.timing;
  double per_keyframe_ms = 0;
  if (request.method == MappingMethod::kSparseMesh) {
    if (sparse == nullptr) return Status::FailedPrecondition("the session runs no sparse mesher");
    if (points.size() < 4) {
      return Status::FailedPrecondition(
          "empty map: " + std::to_string(points.size()) +
          " sparse points (after sparse_mesh.min_visibility), the Delaunay triangulation needs 4");
    }
    timing.features_ms = sparse->stats().TotalMs();
    per_keyframe_ms = timing.features_ms;
    SetProgress("meshing (Delaunay, visibility, graph cut)", 0.1);
    Result<mapping::MeshingResult> meshing = mapping::BuildMesh(points, views, request.meshing);
    if (!meshing.ok()) {
      return Status(meshing.status().code(), "sparse-mesh: " + meshing.status().message());
    }
    MAV_RETURN_IF_ERROR(deadline());
    const mapping::MeshingStats& m = meshing->stats;
    timing.delaunay_ms = m.seconds_triangulation * 1e3;
    timing.graph_cut_ms = (m.seconds_visibility + m.seconds_graph_cut) * 1e3;
    timing.surface_ms = m.seconds_extraction * 1e3;
    SetProgress("mesh to occupancy grid", 0.7);
    const int64_t rasterize_start = MonotonicNowNs();
    // Free space from every line of sight, not only those of the meshed points.
    Result<dataset::OccupancyGrid> grid = mapping::MeshToOccupancy(
        *meshing, sparse->SightPoints(), views, geometry, pipeline.options().mesh_to_grid);
    if (!grid.ok()) return Status(grid.status().code(), "sparse-mesh: " + grid.status().message());
    timing.rasterize_ms = MsSince(rasterize_start);
    map->grid = std::move(*grid);
    stats.points = points.size();
    stats.tetrahedra = meshing->tetrahedra.size();
    stats.mesh_vertices = meshing->mesh.vertices.size();
    stats.mesh_faces = meshing->mesh.triangles.size();
    map->mesh = std::move(meshing->mesh);
  } else {
    if (octomap == nullptr) return Status::FailedPrecondition("the session runs no OctoMap mapper");
    const mapping::OctomapMapperStats& o = octomap->stats();
    timing.dense_stereo_ms = o.TotalDisparityMs();
    timing.insertion_ms = o.TotalInsertionMs();
    per_keyframe_ms = o.TotalMs();
    stats.points = static_cast<uint64_t>(o.TotalPoints());
    SetProgress("octree to occupancy grid", 0.2);
    const int64_t rasterize_start = MonotonicNowNs();
    Result<dataset::OccupancyGrid> grid = octomap->ToGrid(geometry);
    if (!grid.ok()) return Status(grid.status().code(), "octomap: " + grid.status().message());
    timing.rasterize_ms = MsSince(rasterize_start);
    map->grid = std::move(*grid);
  }
  MAV_RETURN_IF_ERROR(deadline());

  SetProgress("collision index", 0.9);
  if (request.unknown != UnknownHandling::kKeepUnknown) {
    const dataset::VoxelState to = request.unknown == UnknownHandling::kAsOccupied
                                       ? dataset::VoxelState::kOccupied
                                       : dataset::VoxelState::kFree;
    for (int64_t i = 0; i < map->grid.num_voxels(); ++i) {
      if (map->grid[i] == dataset::VoxelState::kUnknown) map->grid[i] = to;
    }
  }
  stats.geometry = map->grid.geometry();
  stats.occupied_voxels = map->grid.Count(dataset::VoxelState::kOccupied);
  stats.free_voxels = map->grid.Count(dataset::VoxelState::kFree);
  stats.unknown_voxels = map->grid.Count(dataset::VoxelState::kUnknown);
  map->query = std::make_unique<mapping::BoxQuery>(map->grid);
  MAV_RETURN_IF_ERROR(deadline());
  timing.build_ms = MsSince(start);
  timing.total_ms = per_keyframe_ms + timing.build_ms;
  MAV_LOG(kInfo) << "built " << mapping::MappingMethodName(stats.method)
                 << " map: " << stats.keyframes << " keyframes, " << stats.points << " points, "
                 << stats.occupied_voxels << " occupied / " << stats.free_voxels << " free / "
                 << stats.unknown_voxels << " unknown voxels in " << timing.build_ms << " ms";
  return map;
}

}  // namespace mav::mapping_service
