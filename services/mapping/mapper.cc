#include "services/mapping/mapper.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <utility>

#include "mav/common/log.h"
#include "mav/common/time.h"

namespace mav::mapping_service {

namespace {

constexpr size_t kStatsWindow = 1000;

bool Finite(const geometry::SE3& pose) {
  return pose.Translation().allFinite() && pose.Rotation().coeffs().allFinite();
}

WorkQueueOptions QueueOptions() {
  WorkQueueOptions o = WorkQueueOptions::Named("mapping", 16);
  o.stats_window = kStatsWindow;
  return o;
}

mapping::PoseMatcherOptions MatcherOptions(const SessionConfig& config) {
  mapping::PoseMatcherOptions o;
  o.mode = config.pose_source == PoseSource::kLocalization
               ? mapping::PoseMatcherOptions::Mode::kExact
               : mapping::PoseMatcherOptions::Mode::kInterpolate;
  o.wait_ns = config.pose_wait_ms * 1'000'000;
  return o;
}

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
  if (!(max_depth_m >= 0.5 && max_depth_m <= 100)) {
    return fail("keyframes.max_depth_m: must be in [0.5, 100], got " + std::to_string(max_depth_m));
  }
  return true;
}

struct Mapper::Engine {
  camera::RigRectification rectification;
  std::optional<mapping::MappingPipeline> pipeline;

  static Result<std::unique_ptr<Engine>> Create(const SessionConfig& config) {
    std::string why;
    if (!config.IsValid(&why)) return Status::InvalidArgument(why);
    auto engine = std::make_unique<Engine>();
    MAV_ASSIGN_OR_RETURN(
        engine->rectification,
        camera::RigRectification::Create(config.calibration, config.calibration_rectified));
    mapping::MappingPipelineOptions options;
    options.keyframes = config.keyframes;
    options.sparse.target_points_per_keyframe = config.features_per_keyframe;
    options.sparse.max_depth_m = config.max_depth_m;
    options.run_octomap = !config.sparse_mesh_only;
    Result<mapping::MappingPipeline> pipeline =
        mapping::MappingPipeline::Create(engine->rectification.rig, options);
    if (!pipeline.ok()) return Status::InvalidArgument("session: " + pipeline.status().message());
    engine->pipeline.emplace(std::move(*pipeline));
    return engine;
  }
};

Mapper::Mapper() : queue_(QueueOptions()), keyframe_ms_(kStatsWindow) {}

Mapper::~Mapper() { Shutdown(); }

void Mapper::Shutdown() { queue_.Stop("the mapping service is shutting down"); }

void Mapper::set_max_voxels(int64_t max_voxels) {
  std::lock_guard<std::mutex> lock(mutex_);
  max_voxels_ = max_voxels;
}

void Mapper::ClearLocked() {
  if (matcher_) matcher_->Clear();
  if (selector_) selector_->Reset();
  frames_seen_ = frames_without_pose_ = frames_dropped_ = frames_rejected_ = 0;
  keyframes_selected_ = keyframes_done_ = 0;
  have_keyframe_ = false;
  last_keyframe_t_ns_ = 0;
  points_ = 0;
  building_ = false;
  build_stage_.clear();
  build_fraction_ = 0;
  keyframe_ms_.Clear();
  sparse_mesh_map_.reset();
  octomap_map_.reset();
  last_built_.reset();
}

Status Mapper::StartSession(const SessionConfig& config, const Termination& deadline) {
  // Rectification maps and the pipeline are built before the worker is interrupted.
  MAV_ASSIGN_OR_RETURN(std::unique_ptr<Engine> built, Engine::Create(config));
  MAV_RETURN_IF_ERROR(deadline.Check("StartSession"));
  auto engine = std::make_shared<std::unique_ptr<Engine>>(std::move(built));
  Ticket<Status> ticket = queue_.SubmitAfterReset<Status>(
      [this, engine, config](const TaskContext&) {
        engine_ = std::move(*engine);
        std::lock_guard<std::mutex> lock(mutex_);
        ClearLocked();
        rig_ = engine_->rectification.rig;
        T_body_rect0_ = engine_->rectification.T_body_rect0;
        config_ = config;
        matcher_.emplace(MatcherOptions(config));
        selector_.emplace(config.keyframes);
        return Status::Ok();
      },
      "a new session was started", deadline);
  MAV_RETURN_IF_ERROR(ticket.Wait());
  queue_.SetCapacity(static_cast<size_t>(config.queue_length));
  MAV_LOG(kInfo) << "mapping session: " << rig_.width << "x" << rig_.height << " rig, poses from "
                 << PoseSourceName(config.pose_source) << ", keyframes every "
                 << config.keyframes.min_translation_m << " m / "
                 << config.keyframes.min_rotation_rad * 180.0 / M_PI << " deg";
  return Status::Ok();
}

Status Mapper::Reset(const Termination& deadline) {
  if (!session_active()) return Status::FailedPrecondition("no session: call StartSession first");
  MAV_RETURN_IF_ERROR(deadline.Check("Reset"));
  Ticket<Status> ticket = queue_.SubmitAfterReset<Status>(
      [this](const TaskContext&) {
        if (engine_ != nullptr) engine_->pipeline->Reset();
        std::lock_guard<std::mutex> lock(mutex_);
        ClearLocked();
        return Status::Ok();
      },
      "the session was reset", deadline);
  return ticket.Wait();
}

bool Mapper::session_active() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return config_.has_value();
}

std::optional<SessionConfig> Mapper::config() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return config_;
}

Status Mapper::CheckInput(const FrameInput& frame, const std::string& field) const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!config_) return Status::FailedPrecondition("no session: call StartSession first");
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
  if (have_keyframe_ && frame.t_ns <= last_keyframe_t_ns_) {
    return Status::InvalidArgument(field + ".t_ns: " + std::to_string(frame.t_ns) +
                                   " is not after the previous frame's " +
                                   std::to_string(last_keyframe_t_ns_));
  }
  return Status::Ok();
}

bool Mapper::SelectLocked(const geometry::SE3& T_world_body, bool force) {
  const geometry::SE3 T_world_cam = T_world_body * T_body_rect0_;
  // A forced keyframe becomes the rule's reference, as a selected one would.
  if (force) selector_->Reset();
  return selector_->Consider(T_world_cam);
}

Ticket<Result<KeyframeResult>> Mapper::SubmitKeyframe(FrameInput frame,
                                                      const geometry::SE3& T_world_body,
                                                      QueuePolicy policy,
                                                      const Termination& deadline) {
  return queue_.Submit<Result<KeyframeResult>>(
      [this, frame = std::move(frame), T_world_body](const TaskContext&) {
        return ProcessKeyframe(frame, T_world_body);
      },
      policy, deadline);
}

void Mapper::EnqueueLive(std::vector<mapping::PoseMatcher<FrameInput>::Matched> matched) {
  for (auto& m : matched) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
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
    }
    const Ticket<Result<KeyframeResult>> ticket =
        SubmitKeyframe(std::move(m.frame), m.T_world_body, QueuePolicy::kDropOldest, {});
    if (!ticket.accepted() || ticket.dropped_oldest()) {
      std::lock_guard<std::mutex> lock(mutex_);
      ++frames_dropped_;
      --keyframes_selected_;
    }
  }
}

void Mapper::SubmitLiveFrame(FrameInput frame) {
  std::vector<mapping::PoseMatcher<FrameInput>::Matched> matched;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!config_) return;
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
    matched = matcher_->AddFrame(std::move(frame), MonotonicNowNs(), &frames_without_pose_);
  }
  EnqueueLive(std::move(matched));
}

void Mapper::SubmitPose(int64_t t_ns, const geometry::SE3& T_world_body) {
  std::vector<mapping::PoseMatcher<FrameInput>::Matched> matched;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!matcher_) return;
    matched = matcher_->AddPose(t_ns, T_world_body, &frames_without_pose_);
  }
  EnqueueLive(std::move(matched));
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

Result<KeyframeResult> Mapper::InsertKeyframe(FrameInput frame, const geometry::SE3& T_world_body,
                                              bool force, const Termination& deadline) {
  MAV_RETURN_IF_ERROR(CheckInput(frame, "stereo"));
  if (!Finite(T_world_body)) return Status::InvalidArgument("t_world_body: not finite");
  MAV_RETURN_IF_ERROR(deadline.Check("InsertKeyframe"));
  // What this call changes before the worker integrates the keyframe, to undo if it never does.
  struct Before {
    bool have_keyframe;
    int64_t last_keyframe_t_ns;
    mapping::KeyframeSelector selector;
  };
  std::optional<Before> before;
  const int64_t t_ns = frame.t_ns;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (building_) {
      return Status::ResourceExhausted("a BuildMap is running; insert keyframes after it");
    }
    if (keyframes_selected_ >= static_cast<uint32_t>(config_->max_keyframes)) {
      return Status::ResourceExhausted("max_keyframes: the session holds its limit of " +
                                       std::to_string(config_->max_keyframes) + " keyframes");
    }
    ++frames_seen_;
    before = Before{have_keyframe_, last_keyframe_t_ns_, *selector_};
    have_keyframe_ = true;
    last_keyframe_t_ns_ = t_ns;
    if (!SelectLocked(T_world_body, force)) {
      KeyframeResult skipped;
      skipped.points_total = points_;
      return skipped;
    }
    ++keyframes_selected_;
  }
  Ticket<Result<KeyframeResult>> ticket =
      SubmitKeyframe(std::move(frame), T_world_body, QueuePolicy::kReject, deadline);
  Result<KeyframeResult> result = ticket.Wait(deadline);
  if (!ticket.ran()) {
    // Refused, withdrawn or discarded: the keyframe was never integrated, so the call changes
    // nothing (a retry of the same frame is welcome). A keyframe that ran and failed was
    // uncounted by ProcessKeyframe.
    std::lock_guard<std::mutex> lock(mutex_);
    --keyframes_selected_;
    if (have_keyframe_ && last_keyframe_t_ns_ == t_ns) {
      have_keyframe_ = before->have_keyframe;
      last_keyframe_t_ns_ = before->last_keyframe_t_ns;
      selector_ = before->selector;
    }
  }
  return result;
}

Result<MapStats> Mapper::Build(const BuildRequest& request, const Termination& deadline) {
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
  MAV_RETURN_IF_ERROR(deadline.Check("BuildMap"));
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!config_) return Status::FailedPrecondition("no session: call StartSession first");
    if (building_) {
      return Status::ResourceExhausted("another BuildMap is running; retry when it is done");
    }
    building_ = true;
    build_stage_ = "waiting for queued keyframes";
    build_fraction_ = 0;
    build_start_ns_ = MonotonicNowNs();
  }
  // The build waits behind the queued keyframes; in a full queue it takes the oldest live
  // keyframe's place.
  Ticket<Result<std::shared_ptr<BuiltMap>>> ticket =
      queue_.Submit<Result<std::shared_ptr<BuiltMap>>>(
          [this, request, deadline](const TaskContext&) { return RunBuild(request, deadline); },
          QueuePolicy::kMakeRoom, deadline);
  if (ticket.dropped_oldest()) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++frames_dropped_;
    --keyframes_selected_;
  }
  Result<std::shared_ptr<BuiltMap>> built = ticket.Wait(deadline);
  std::lock_guard<std::mutex> lock(mutex_);
  building_ = false;
  build_stage_.clear();
  if (!built.ok()) return built.status();
  const MapStats stats = (*built)->stats;
  if (stats.method == MappingMethod::kSparseMesh) {
    sparse_mesh_map_ = std::move(*built);
  } else {
    octomap_map_ = std::move(*built);
  }
  last_built_ = stats.method;
  return stats;
}

std::shared_ptr<const BuiltMap> Mapper::Map(std::optional<MappingMethod> method) const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!method.has_value()) method = last_built_;
  if (!method.has_value()) return nullptr;
  return *method == MappingMethod::kSparseMesh ? sparse_mesh_map_ : octomap_map_;
}

MapperStatus Mapper::GetStatus() const {
  const WorkQueueStats queue = queue_.GetStats();
  std::lock_guard<std::mutex> lock(mutex_);
  MapperStatus s;
  s.session_active = config_.has_value();
  if (config_) s.pose_source = config_->pose_source;
  s.frames_seen = frames_seen_;
  s.keyframes = keyframes_done_;
  s.keyframes_selected = keyframes_selected_;
  s.points = points_;
  s.frames_without_pose = frames_without_pose_;
  s.frames_dropped = frames_dropped_;
  s.frames_rejected = frames_rejected_;
  s.queue_depth = static_cast<uint32_t>(queue.depth);
  s.worker_busy = queue.busy;
  s.pending_frames = matcher_ ? static_cast<uint32_t>(matcher_->pending()) : 0;
  s.building = building_;
  if (building_) {
    s.build_stage = build_stage_;
    s.build_fraction = build_fraction_;
    s.build_elapsed_s = SecondsSince(build_start_ns_);
  }
  if (sparse_mesh_map_) s.maps.push_back(sparse_mesh_map_->stats);
  if (octomap_map_) s.maps.push_back(octomap_map_->stats);
  s.keyframe_ms = keyframe_ms_.Summary();
  return s;
}

// ---- On the worker ------------------------------------------------------------------------------

Result<KeyframeResult> Mapper::ProcessKeyframe(const FrameInput& frame,
                                               const geometry::SE3& T_world_body) {
  if (engine_ == nullptr) return Status::FailedPrecondition("no session: call StartSession first");
  const int64_t start = MonotonicNowNs();
  cv::Mat left, right;
  Status status =
      engine_->rectification.Rectify(frame.left, frame.right, frame.rectified, &left, &right);
  mapping::MappingPipeline& pipeline = *engine_->pipeline;
  if (status.ok()) {
    status =
        pipeline.InsertKeyframe(left, right, T_world_body * engine_->rectification.T_body_rect0);
  }
  if (!status.ok()) {
    std::lock_guard<std::mutex> lock(mutex_);
    --keyframes_selected_;
    ++frames_rejected_;
    MAV_LOG(kWarning) << "keyframe at t_ns " << frame.t_ns << " rejected: " << status.message();
    return status;
  }
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
  std::lock_guard<std::mutex> lock(mutex_);
  ++keyframes_done_;
  points_ = out.points_total;
  keyframe_ms_.Add(out.processing_ms);
  return out;
}

Result<std::shared_ptr<BuiltMap>> Mapper::RunBuild(const BuildRequest& request,
                                                   const Termination& deadline) {
  if (engine_ == nullptr) return Status::FailedPrecondition("no session: call StartSession first");
  const int64_t start = MonotonicNowNs();
  mapping::MappingPipeline& pipeline = *engine_->pipeline;
  if (pipeline.num_keyframes() == 0) {
    return Status::FailedPrecondition(
        "empty map: no keyframes yet (stream frames with poses or call InsertKeyframe first)");
  }
  const mapping::GridGeometry geometry =
      request.bounds.has_value()
          ? mapping::GridGeometry::Covering(request.bounds->min(), request.bounds->max(),
                                            request.resolution_m)
          : pipeline.GeometryAround(request.resolution_m, BuildRequest::kDefaultPaddingM,
                                    request.min_visibility);
  if (request.method == MappingMethod::kOctomap && request.bounds.has_value()) {
    const double limit = pipeline.options().octomap.MaxAbsCoordinateM();
    if (request.bounds->min().cwiseAbs().maxCoeff() > limit ||
        request.bounds->max().cwiseAbs().maxCoeff() > limit) {
      std::ostringstream message;
      message << "bounds: outside the OctoMap baseline's addressable volume, +-" << limit
              << " m on each axis around the world origin (2^15 voxels of "
              << pipeline.options().octomap.resolution << " m)";
      return Status::InvalidArgument(message.str());
    }
  }
  int64_t max_voxels = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    max_voxels = max_voxels_;
  }
  if (geometry.num_voxels() > max_voxels) {
    return Status::ResourceExhausted(
        std::string(request.bounds.has_value() ? "bounds" : "resolution_m") +
        ": the grid would have " + std::to_string(geometry.num_voxels()) +
        " voxels, over the server's limit of " + std::to_string(max_voxels));
  }
  mapping::BuildOptions options;
  options.meshing = request.meshing;
  options.mesh_to_grid = request.mesh_to_grid;
  options.keep_unchecked_points = request.keep_unchecked_points;
  options.occlusion_check = request.occlusion_check;
  options.min_visibility = request.min_visibility;
  options.unknown = request.unknown;
  auto progress = [this](std::string_view stage, double fraction) {
    std::lock_guard<std::mutex> lock(mutex_);
    build_stage_ = std::string(stage);
    build_fraction_ = fraction;
  };
  MAV_ASSIGN_OR_RETURN(mapping::MethodMap built,
                       pipeline.Build(request.method, geometry, options, deadline, progress));

  auto map = std::make_shared<BuiltMap>();
  MapStats& stats = map->stats;
  stats.method = request.method;
  stats.keyframes = static_cast<uint32_t>(built.keyframes);
  BuildTiming& timing = stats.timing;
  if (request.method == MappingMethod::kSparseMesh) {
    const mapping::MeshingStats& m = built.meshing.stats;
    timing.features_ms = built.per_keyframe_ms;
    timing.delaunay_ms = m.triangulation_s * 1e3;
    timing.graph_cut_ms = (m.visibility_s + m.graph_cut_s) * 1e3;
    timing.surface_ms = m.extraction_s * 1e3;
    stats.points = built.points.size();
    stats.tetrahedra = built.meshing.tetrahedra.size();
    stats.mesh_vertices = built.meshing.mesh.vertices.size();
    stats.mesh_faces = built.meshing.mesh.triangles.size();
    map->mesh = std::move(built.meshing.mesh);
  } else {
    const mapping::OctomapMapperStats& o = pipeline.octomap_mapper()->stats();
    timing.dense_stereo_ms = o.TotalDisparityMs();
    timing.insertion_ms = o.TotalInsertionMs();
    stats.points = static_cast<uint64_t>(built.range_points);
  }
  timing.rasterize_ms = built.to_grid_ms;
  map->grid = std::move(built.grid);
  stats.geometry = map->grid.geometry();
  stats.occupied_voxels = built.occupied_voxels;
  stats.free_voxels = built.free_voxels;
  stats.unknown_voxels = built.unknown_voxels;
  progress("collision index", 0.9);
  map->query = std::make_unique<mapping::BoxQuery>(map->grid);
  MAV_RETURN_IF_ERROR(deadline.Check("BuildMap"));
  timing.build_ms = MsSince(start);
  timing.total_ms = built.per_keyframe_ms + timing.build_ms;
  MAV_LOG(kInfo) << "built " << mapping::MappingMethodName(stats.method)
                 << " map: " << stats.keyframes << " keyframes, " << stats.points << " points, "
                 << stats.occupied_voxels << " occupied / " << stats.free_voxels << " free / "
                 << stats.unknown_voxels << " unknown voxels in " << timing.build_ms << " ms";
  return map;
}

}  // namespace mav::mapping_service
