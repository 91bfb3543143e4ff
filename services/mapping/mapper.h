#pragma once
// The mapping service's domain core, free of gRPC, protobuf and DDS: the Mapper, whose one worker
// thread owns a mapping::MappingPipeline (libs/mapping/pipeline.h: the sparse multi-view mesher
// of Labatut et al. 2007 and the OctoMap + dense stereo baseline on the same keyframes).
//
//   DDS stereo --SubmitLiveFrame--> PoseMatcher (pending frames, pose history)
//   DDS poses  --SubmitPose-------^      | frame + T_world_body
//                                        v
//                          keyframe rule (KeyframeSelector)   <--SubmitKeyframeAndWait (unary)
//                                        | keyframes only
//                                        v
//                      [bounded queue, drop-oldest for live]  --> worker: rectify,
//   SubmitBuildAndWait ------------------^                        pipeline.InsertKeyframe / build
//
// Poses. Poses on the input are T_world_body (EuRoC's body = IMU frame). The camera pose used by
// the mappers is the rectified left camera's, T_world_rect0 = T_world_body * T_body_rect0, with
// T_body_rect0 = StereoRectifier::T_body_rect0() (T_body_cam0 for a calibration flagged
// rectified).
//
// Pairing frames with poses (PoseMatcher):
//  * ground truth (200 Hz): the pose at the frame's t_ns is interpolated (SE3 geodesic,
//    geometry::InterpolatePose) between the last sample <= t and the first sample >= t; each must
//    be within kMaxPoseGapNs (25 ms) of t, else the frame is dropped as "without pose";
//  * localization (one pose per processed frame): the pose with exactly the frame's t_ns.
//  A frame waits (pending, at most kMaxPendingFrames) until its pose can be decided; it is dropped
//  as "without pose" when the pose stream has moved more than 25 ms past it without a match,
//  when the history no longer reaches back to it, or after `pose_wait_ms` of wall time.
//
// Keyframes. The keyframe rule (mapping::KeyframeSelector) runs when a frame gets its pose, before
// the queue, so only keyframes' images are queued and processed (rectification, ~100 sparse
// stereo points, dense stereo + OctoMap ray casting). Both methods integrate every keyframe as it
// arrives; BuildMap runs only the whole-data-set stage of the requested method (meshing + mesh ->
// grid, or octree -> grid) on a snapshot of the keyframes integrated so far.
//
// Thread-safety: every public method may be called from any thread.

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <future>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "mav/camera/stereo.h"
#include "mav/common/status.h"
#include "mav/dataset/occupancy_grid.h"
#include "mav/geometry/se3.h"
#include "mav/mapping/collision_eval.h"
#include "mav/mapping/delaunay_graph_cut.h"
#include "mav/mapping/keyframes.h"
#include "mav/mapping/mesh.h"
#include "mav/mapping/pipeline.h"

namespace mav::mapping_service {

using mapping::MappingMethod;

// Where DDS poses come from (same meaning as mav.v1.PoseSource).
enum class PoseSource { kNone, kLocalization, kGroundTruth };
const char* PoseSourceName(PoseSource source);  // "none", "localization", "ground-truth"

inline constexpr int64_t kMaxPoseGapNs = 25'000'000;
inline constexpr int kMaxPendingFrames = 32;

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

  bool IsValid(std::string* why) const;
};

// One stereo pair. Images CV_8UC1 of the calibration's size; `rectified`: already in the
// rectified geometry (not remapped).
struct FrameInput {
  int64_t t_ns = 0;
  cv::Mat left;
  cv::Mat right;
  bool rectified = false;
};

struct KeyframeResult {
  bool accepted = false;        // false: skipped by the keyframe rule
  uint32_t keyframe_index = 0;  // 0-based, when accepted
  uint32_t features = 0;        // sparse points selected from this keyframe
  uint64_t points_total = 0;    // global sparse cloud after merging
  double processing_ms = 0;     // rectification + both mappers' per-keyframe work
};

// How voxels that no ray or surface explained are labelled in a built grid.
enum class UnknownHandling { kKeepUnknown, kAsOccupied, kAsFree };

struct BuildRequest {
  MappingMethod method = MappingMethod::kSparseMesh;
  double resolution_m = 0.05;  // [0.01, 2]
  // World box of the grid; unset = the keyframe camera centres and the sparse points, grown by
  // kDefaultPaddingM.
  std::optional<Eigen::AlignedBox3d> bounds;
  UnknownHandling unknown = UnknownHandling::kKeepUnknown;
  // SPARSE_MESH: the mesher's options and the minimum number of keyframes that saw a point.
  mapping::MeshingOptions meshing;
  int min_visibility = 1;
  // The build is abandoned (DEADLINE_EXCEEDED, nothing kept) when this monotonic time passes;
  // checked between stages. 0 = none.
  int64_t deadline_monotonic_ns = 0;

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
  dataset::GridGeometry geometry;
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

struct RuntimeSummary {
  uint64_t count = 0;
  double mean_ms = 0, median_ms = 0, p95_ms = 0, max_ms = 0;
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
  uint32_t queue_depth = 0;
  uint32_t pending_frames = 0;  // live frames waiting for their pose
  bool building = false;
  std::string build_stage;
  double build_fraction = 0;
  double build_elapsed_s = 0;
  std::vector<MapStats> maps;  // the last build of each method (sparse-mesh first)
  RuntimeSummary keyframe_ms;
};

// Why a call failed when the library Status has no code for it.
enum class Refusal {
  kNone,
  kResourceExhausted,  // queue full, keyframe limit, a build running, voxel limit
  kDeadlineExceeded,   // the caller's deadline passed
};

// Pairs frames with poses (see the header comment). Not thread-safe (the Mapper locks it).
class PoseMatcher {
 public:
  PoseMatcher(PoseSource source, int64_t pose_wait_ns) : source_(source), wait_ns_(pose_wait_ns) {}

  struct Matched {
    FrameInput frame;
    geometry::SE3 T_world_body;
  };
  // Adds a pose sample (T_world_body at t_ns); returns the pending frames it resolves, in time
  // order. *dropped counts frames decided to have no pose.
  std::vector<Matched> AddPose(int64_t t_ns, const geometry::SE3& T_world_body, uint64_t* dropped);
  // Adds a frame; returns it (and any other resolved frames) when its pose is known now.
  std::vector<Matched> AddFrame(FrameInput frame, int64_t now_ns, uint64_t* dropped);
  // Drops frames that waited longer than the pose wait. Returns how many.
  uint64_t Expire(int64_t now_ns);
  // Whether the pose at t_ns can be decided from the history now: kPose (written to
  // *T_world_body), kWait (may come later) or kNoPose (never: drop the frame).
  enum class Decision { kPose, kWait, kNoPose };
  Decision Lookup(int64_t t_ns, geometry::SE3* T_world_body) const;

  size_t pending() const { return pending_.size(); }
  size_t history() const { return poses_.size(); }
  void Clear();

  static constexpr size_t kMaxHistory = 4000;  // 20 s of 200 Hz ground truth

 private:
  struct Pending {
    FrameInput frame;
    int64_t arrived_ns = 0;
  };
  std::vector<Matched> Resolve(uint64_t* dropped);

  PoseSource source_;
  int64_t wait_ns_;
  std::deque<std::pair<int64_t, geometry::SE3>> poses_;  // ascending t_ns
  std::deque<Pending> pending_;                          // ascending arrival
};

class Mapper {
 public:
  Mapper();
  ~Mapper();
  Mapper(const Mapper&) = delete;
  Mapper& operator=(const Mapper&) = delete;

  // Builds the rectifier and a fresh pipeline for `config` (InvalidArgument naming the field),
  // then replaces any previous session: queued frames are discarded, keyframes, maps and counters
  // restart. Waits for the work in flight (a running build finishes first).
  Status StartSession(const SessionConfig& config);
  // Drops keyframes, maps, queued and pending frames and counters; keeps the configuration.
  // FailedPrecondition without a session.
  Status Reset();

  bool session_active() const;
  // The session's configuration (nullopt without one) and its rectified rig.
  std::optional<SessionConfig> config() const;

  // Checks a unary frame against the session: InvalidArgument naming `field`.left/right (size
  // differs from the calibration); FailedPrecondition without a session.
  Status CheckInput(const FrameInput& frame, const std::string& field) const;

  // Live input (DDS): never blocks.
  void SubmitLiveFrame(FrameInput frame);
  void SubmitPose(int64_t t_ns, const geometry::SE3& T_world_body);
  // Expires frames that waited too long for their pose (call periodically).
  void Tick();
  // Counts a live frame that was malformed before it became a FrameInput (bad checksum).
  void CountRejected();

  // Unary input: applies the keyframe rule (force skips it) and waits until the worker has
  // integrated the keyframe, at most until `deadline_monotonic_ns` (0 = 30 s).
  // FailedPrecondition without a session; InvalidArgument as CheckInput / a non-finite pose;
  // *refusal = kResourceExhausted when a build is running, the keyframe limit is reached or the
  // queue is full, kDeadlineExceeded when the deadline passed.
  Result<KeyframeResult> SubmitKeyframeAndWait(FrameInput frame, const geometry::SE3& T_world_body,
                                               bool force, int64_t deadline_monotonic_ns,
                                               Refusal* refusal);

  // Builds the map of `request.method` from the keyframes integrated so far (queued keyframes
  // first), publishes it as the method's last map and returns its stats. FailedPrecondition
  // without a session or without keyframes ("empty map"); InvalidArgument naming the field
  // (resolution_m, bounds, meshing options); *refusal = kResourceExhausted when a build is
  // running or the grid exceeds `max_voxels`, kDeadlineExceeded when the deadline passed
  // (nothing kept). The library's errors are passed on.
  Result<MapStats> BuildAndWait(const BuildRequest& request, Refusal* refusal);

  // The last built map of a method; nullopt method = the most recent build of any method.
  // Null when there is none.
  std::shared_ptr<const BuiltMap> Map(std::optional<MappingMethod> method) const;

  MapperStatus GetStatus() const;

  // Limit on the voxels of a built grid (RESOURCE_EXHAUSTED above it).
  void set_max_voxels(int64_t max_voxels);

  // Stops the worker (waiting calls fail with Unavailable). Idempotent.
  void Shutdown();

 private:
  struct Engine;  // rectifier + pipeline; used by the worker
  struct KeyframeJob;
  struct BuildJob;
  struct Item;

  void WorkerLoop();
  void EnqueueMatchedLocked(std::vector<PoseMatcher::Matched> matched);
  bool SelectLocked(const geometry::SE3& T_world_body, bool force);
  void ClearLocked();
  Result<KeyframeResult> ProcessKeyframe(Engine* engine, const FrameInput& frame,
                                         const geometry::SE3& T_world_body);
  Result<std::shared_ptr<BuiltMap>> RunBuild(Engine* engine, const BuildRequest& request,
                                             Refusal* refusal);
  void SetProgress(const std::string& stage, double fraction);

  mutable std::mutex mutex_;
  std::condition_variable work_cv_;
  std::condition_variable idle_cv_;
  std::thread worker_;
  bool shutdown_ = false;

  // Guarded by mutex_.
  std::unique_ptr<Engine> engine_;
  std::optional<SessionConfig> config_;
  camera::RectifiedStereo rig_;  // the session's rectified rig (image size checks)
  geometry::SE3 T_body_rect0_;   // for the keyframe rule
  std::optional<mapping::KeyframeSelector> selector_;
  bool busy_ = false;
  uint64_t generation_ = 0;
  std::deque<std::unique_ptr<Item>> queue_;
  std::optional<PoseMatcher> matcher_;
  uint64_t frames_seen_ = 0;
  uint64_t frames_without_pose_ = 0;
  uint64_t frames_dropped_ = 0;
  uint64_t frames_rejected_ = 0;
  uint32_t keyframes_selected_ = 0;  // accepted by the rule (queued or integrated)
  uint32_t keyframes_done_ = 0;
  uint64_t points_ = 0;
  bool building_ = false;
  std::string build_stage_;
  double build_fraction_ = 0;
  int64_t build_start_ns_ = 0;
  std::vector<double> keyframe_ms_;
  std::shared_ptr<const BuiltMap> sparse_mesh_map_;
  std::shared_ptr<const BuiltMap> octomap_map_;
  std::optional<MappingMethod> last_built_;
  int64_t max_voxels_ = 50'000'000;
};

}  // namespace mav::mapping_service
