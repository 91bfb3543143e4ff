#pragma once
// The mapping service's core, free of gRPC, protobuf and DDS: the Mapper, whose one worker (a
// WorkQueue) owns a mapping::MappingPipeline (libs/mapping/pipeline.h: the sparse multi-view
// mesher of Labatut et al. 2007 and the OctoMap + dense stereo baseline on the same keyframes).
//
//   DDS stereo --SubmitLiveFrame--> mapping::PoseMatcher (pending frames, pose history)
//   DDS poses  --SubmitPose-------^      | frame + T_world_body
//                                        v
//                          keyframe rule (KeyframeSelector)   <--InsertKeyframe (unary)
//                                        | keyframes only
//                                        v
//                      [WorkQueue: drop-oldest for live, reject for unary]  --> worker:
//   Build -------------------------------^                 rectify, pipeline.InsertKeyframe / Build
//
// Poses. Poses on the input are T_world_body (EuRoC's body = IMU frame). The camera pose used by
// the mappers is the rectified left camera's, T_world_rect0 = T_world_body * T_body_rect0
// (camera::RigRectification).
//
// Keyframes. The keyframe rule runs when a frame gets its pose, before the queue, so only
// keyframes' images are queued and processed. Both methods integrate every keyframe as it
// arrives; Build runs MappingPipeline::Build (the code mav-eval runs) for the requested method on
// the keyframes integrated so far.
//
// Memory: at most queue_length keyframes wait (a stereo pair each); the pose matcher keeps 4000
// poses and 32 pending frames; the pipeline's per-keyframe memory is the keyframe's data (its
// sparse points and lines of sight, its OctoMap voxels); the last map of each method is kept;
// a build whose grid exceeds max_voxels is refused before allocating.
//
// Thread-safety: every public method may be called from any thread.

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "mav/camera/rectifier.h"
#include "mav/camera/stereo.h"
#include "mav/common/stats.h"
#include "mav/common/status.h"
#include "mav/common/termination.h"
#include "mav/common/work_queue.h"
#include "mav/dataset/stereo_pair.h"
#include "mav/geometry/se3.h"
#include "mav/mapping/collision_eval.h"
#include "mav/mapping/keyframes.h"
#include "mav/mapping/mesh.h"
#include "mav/mapping/pipeline.h"
#include "mav/mapping/pose_matcher.h"

namespace mav::mapping_service {

using mapping::MappingMethod;

// Where DDS poses come from (same meaning as mav.v1.PoseSource).
enum class PoseSource { kNone, kLocalization, kGroundTruth };
const char* PoseSourceName(PoseSource source);  // "none", "localization", "ground-truth"

struct SessionConfig {
  // The raw rig; with calibration_rectified an ideal rectified pair used as it is.
  camera::StereoCalibration calibration;
  bool calibration_rectified = false;
  mapping::KeyframeOptions keyframes;
  int max_keyframes = 5000;         // [1, 100000]
  int features_per_keyframe = 100;  // sparse points per keyframe, [1, 10000]
  PoseSource pose_source = PoseSource::kNone;
  // Live keyframes waiting for the worker, [1, 1000]; when full the oldest is dropped (counted).
  int queue_length = 16;
  // Longest a live frame waits for its pose, ms, > 0.
  int64_t pose_wait_ms = 2000;
  // Sparse points deeper than this are not matched, [0.5, 100] m.
  double max_depth_m = 6.0;
  // Only the sparse mesher runs per keyframe (no dense stereo + OctoMap).
  bool sparse_mesh_only = false;

  bool IsValid(std::string* why) const;
};

// One stereo pair. Images CV_8UC1 of the calibration's size; `rectified`: already in the
// rectified geometry (not remapped).
using FrameInput = dataset::StereoPair;

struct KeyframeResult {
  bool accepted = false;        // false: skipped by the keyframe rule
  uint32_t keyframe_index = 0;  // 0-based, when accepted
  uint32_t features = 0;        // sparse points selected from this keyframe
  uint64_t points_total = 0;    // global sparse cloud after merging
  double processing_ms = 0;     // rectification + both mappers' per-keyframe work
};

// How voxels that no ray or surface explained are labelled in a built grid (applied by
// MappingPipeline::Build).
using mapping::UnknownHandling;

struct BuildRequest {
  MappingMethod method = MappingMethod::kSparseMesh;
  double resolution_m = 0.05;  // [0.01, 2]
  // World box of the grid; unset = the keyframe camera centres and the sparse points, grown by
  // kDefaultPaddingM.
  std::optional<Eigen::AlignedBox3d> bounds;
  UnknownHandling unknown = UnknownHandling::kKeepUnknown;
  // SPARSE_MESH: the mesher's options, the grid rules, whether unchecked single-view points are
  // meshed, the occlusion check of far single-view points (all four from the map preference,
  // mapping::BuildOptions::For) and the minimum number of keyframes that saw a point.
  mapping::MeshingOptions meshing = mapping::MeshingOptionsFor(mapping::MapPreference::kSafety);
  mapping::MeshToGridOptions mesh_to_grid =
      mapping::MeshToGridOptionsFor(mapping::MapPreference::kSafety);
  bool keep_unchecked_points = mapping::KeepUncheckedPointsFor(mapping::MapPreference::kSafety);
  mapping::OcclusionCheckOptions occlusion_check =
      mapping::OcclusionCheckFor(mapping::MapPreference::kSafety);
  int min_visibility = 1;

  static constexpr double kDefaultPaddingM = 1.0;
};

struct BuildTiming {
  double total_ms = 0;  // per-keyframe work of the method over all keyframes + the build stages
  double features_ms = 0;
  double dense_stereo_ms = 0;
  double delaunay_ms = 0;
  double graph_cut_ms = 0;  // visibility (ray walks) + max-flow
  double surface_ms = 0;
  double insertion_ms = 0;
  double rasterize_ms = 0;  // mesh/octree -> grid
  double build_ms = 0;      // wall time of the build itself (the BuildMap call)
};

struct MapStats {
  MappingMethod method = MappingMethod::kSparseMesh;
  uint32_t keyframes = 0;
  uint64_t points = 0;  // sparse points used (SPARSE_MESH) or range points inserted (OCTOMAP)
  uint64_t tetrahedra = 0;
  uint64_t mesh_vertices = 0;
  uint64_t mesh_faces = 0;
  mapping::GridGeometry geometry;
  int64_t occupied_voxels = 0;
  int64_t free_voxels = 0;
  int64_t unknown_voxels = 0;
  BuildTiming timing;
};

// The last build of a method: immutable once published, shared with readers.
struct BuiltMap {
  MapStats stats;
  dataset::OccupancyGrid grid;
  std::unique_ptr<mapping::BoxQuery> query;  // over `grid`
  mapping::TriangleMesh mesh;                // SPARSE_MESH only
};

struct MapperStatus {
  bool session_active = false;
  PoseSource pose_source = PoseSource::kNone;
  uint64_t frames_seen = 0;          // live + unary frames offered
  uint32_t keyframes = 0;            // integrated by the worker
  uint32_t keyframes_selected = 0;   // accepted by the keyframe rule (integrated or queued)
  uint64_t points = 0;               // global sparse cloud
  uint64_t frames_without_pose = 0;  // live frames dropped: no pose (see PoseMatcher)
  uint64_t frames_dropped = 0;       // live keyframes dropped: queue full / keyframe limit
  uint64_t frames_rejected = 0;      // live frames of the wrong size / failed rectification
  uint32_t queue_depth = 0;          // tasks waiting for the worker (keyframes, a build)
  bool worker_busy = false;          // the worker runs a task (a keyframe, a build, a reset)
  uint32_t pending_frames = 0;       // live frames waiting for their pose
  bool building = false;
  std::string build_stage;
  double build_fraction = 0;
  double build_elapsed_s = 0;
  std::vector<MapStats> maps;  // the last build of each method (sparse-mesh first)
  RuntimeStats keyframe_ms;    // the last 1000 keyframes
};

class Mapper {
 public:
  Mapper();
  ~Mapper();
  Mapper(const Mapper&) = delete;
  Mapper& operator=(const Mapper&) = delete;

  // Builds the rectifier and a fresh pipeline for `config` (InvalidArgument naming the field),
  // then replaces any previous session: queued frames are discarded, keyframes, maps and counters
  // restart. Waits for the work in flight (a running build finishes first). DEADLINE_EXCEEDED
  // (nothing changed) when `deadline` stops before the new session is in place.
  Status StartSession(const SessionConfig& config, const Termination& deadline = {});
  // Drops keyframes, maps, queued and pending frames and counters; keeps the configuration.
  // FailedPrecondition without a session.
  Status Reset(const Termination& deadline = {});

  bool session_active() const;
  // The session's configuration (nullopt without one).
  std::optional<SessionConfig> config() const;

  // Checks a unary frame against the session: InvalidArgument naming `field`.left/right (size
  // differs from the calibration) or `field`.t_ns (older than the last keyframe's);
  // FailedPrecondition without a session.
  Status CheckInput(const FrameInput& frame, const std::string& field) const;

  // Live input (DDS): never blocks.
  void SubmitLiveFrame(FrameInput frame);
  void SubmitPose(int64_t t_ns, const geometry::SE3& T_world_body);
  // Expires frames that waited too long for their pose (call periodically).
  void Tick();
  // Counts a live frame that was malformed before it became a FrameInput (bad checksum).
  void CountRejected();

  // Unary input: validates like CheckInput (and a non-finite pose), applies the keyframe rule
  // (force skips it) and waits until the worker has integrated the keyframe, at most until
  // `deadline` (DEADLINE_EXCEEDED; a keyframe not yet started is withdrawn and changes nothing).
  // FailedPrecondition without a session; RESOURCE_EXHAUSTED when a build is running, the
  // keyframe limit is reached or the queue is full.
  Result<KeyframeResult> InsertKeyframe(FrameInput frame, const geometry::SE3& T_world_body,
                                        bool force, const Termination& deadline);

  // Builds the map of `request.method` from the keyframes integrated so far (queued keyframes
  // first) with MappingPipeline::Build, publishes it as the method's last map and returns its
  // stats. FailedPrecondition without a session or without keyframes ("empty map");
  // InvalidArgument naming the field (resolution_m, bounds, sparse_mesh options);
  // RESOURCE_EXHAUSTED when a build is running or the grid exceeds max_voxels (before any
  // allocation); DEADLINE_EXCEEDED when `deadline` stops the build (nothing kept). The
  // library's errors are passed on.
  Result<MapStats> Build(const BuildRequest& request, const Termination& deadline);

  // The last built map of a method; nullopt method = the most recent build of any method.
  // Null when there is none.
  std::shared_ptr<const BuiltMap> Map(std::optional<MappingMethod> method) const;

  MapperStatus GetStatus() const;

  // Limit on the voxels of a built grid (RESOURCE_EXHAUSTED above it).
  void set_max_voxels(int64_t max_voxels);

  // Stops the worker (waiting calls fail with Unavailable). Idempotent.
  void Shutdown();

 private:
  struct Engine;  // rectification + pipeline; owned by the worker

  // Queues the keyframes the rule selects among `matched` (live input, drop-oldest).
  void EnqueueLive(std::vector<mapping::PoseMatcher<FrameInput>::Matched> matched);
  // With mutex_ held: the keyframe rule (force: the frame becomes the rule's new reference).
  bool SelectLocked(const geometry::SE3& T_world_body, bool force);
  Ticket<Result<KeyframeResult>> SubmitKeyframe(FrameInput frame, const geometry::SE3& T_world_body,
                                                QueuePolicy policy, const Termination& deadline);
  // On the worker.
  Result<KeyframeResult> ProcessKeyframe(const FrameInput& frame,
                                         const geometry::SE3& T_world_body);
  Result<std::shared_ptr<BuiltMap>> RunBuild(const BuildRequest& request,
                                             const Termination& deadline);
  void ClearLocked();

  WorkQueue queue_;
  std::unique_ptr<Engine> engine_;  // worker only

  mutable std::mutex mutex_;
  // Guarded by mutex_.
  std::optional<SessionConfig> config_;
  camera::RectifiedStereo rig_;  // the session's rectified rig (image size checks)
  geometry::SE3 T_body_rect0_;   // for the keyframe rule
  std::optional<mapping::KeyframeSelector> selector_;
  std::optional<mapping::PoseMatcher<FrameInput>> matcher_;
  uint64_t frames_seen_ = 0;
  uint64_t frames_without_pose_ = 0;
  uint64_t frames_dropped_ = 0;
  uint64_t frames_rejected_ = 0;
  uint32_t keyframes_selected_ = 0;  // accepted by the rule (queued or integrated)
  uint32_t keyframes_done_ = 0;
  int64_t last_keyframe_t_ns_ = 0;
  bool have_keyframe_ = false;
  uint64_t points_ = 0;
  bool building_ = false;
  std::string build_stage_;
  double build_fraction_ = 0;
  int64_t build_start_ns_ = 0;
  RuntimeWindow keyframe_ms_;
  std::shared_ptr<const BuiltMap> sparse_mesh_map_;
  std::shared_ptr<const BuiltMap> octomap_map_;
  std::optional<MappingMethod> last_built_;
  int64_t max_voxels_ = 50'000'000;
};

}  // namespace mav::mapping_service
