#pragma once
// The simulator service's domain core, free of gRPC and protobuf: a ScenarioSource (a rendered
// preset or a recorded EuRoC directory, same interface), a small render-ahead pipeline, and the
// Player state machine whose worker thread owns the playback and publishes through a
// StreamSink (DDS in production, dds_io.h; a fake in tests).
//
// State machine (simulator.proto):
//   IDLE --Load--> LOADED --Start--> RUNNING --Pause--> PAUSED --Start--> RUNNING
//   RUNNING --(last frame, loop=false)--> FINISHED --Start--> RUNNING (from frame 0)
//   LOADED/PAUSED/FINISHED --Step--> PAUSED
//   any --Load--> LOADED (a running playback is stopped first)
//
// Time order: every IMU sample and ground-truth state with t <= a frame's t_ns is published
// before that frame, so a subscriber sees one merged, time-ordered stream per topic.

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "mav/camera/stereo.h"
#include "mav/common/status.h"
#include "mav/dataset/occupancy_grid.h"
#include "mav/dataset/types.h"

namespace mav::simulator_service {

// What a loaded scenario is (ScenarioSummary in the proto).
struct ScenarioInfo {
  std::string name;  // preset name, or the EuRoC directory
  bool is_preset = false;
  int64_t frames = 0;
  int64_t imu_samples = 0;
  int64_t start_t_ns = 0;
  int64_t end_t_ns = 0;
  double camera_rate_hz = 20.0;
  double imu_rate_hz = 200.0;
  bool rectified = false;
  uint64_t seed = 0;
  bool has_ground_truth = false;
  bool has_ground_truth_occupancy = false;
  int width = 0;
  int height = 0;
};

// A data set that can be replayed: frames by index, IMU and ground truth in time order.
class ScenarioSource {
 public:
  virtual ~ScenarioSource() = default;
  virtual const ScenarioInfo& info() const = 0;
  virtual int64_t FrameTimeNs(int64_t frame) const = 0;
  // Renders or reads frame `frame` as two CV_8UC1 images. Thread-safe.
  virtual Status ReadStereo(int64_t frame, cv::Mat* left, cv::Mat* right) const = 0;
  virtual const std::vector<dataset::ImuSample>& imu() const = 0;
  virtual const std::vector<dataset::GroundTruthState>& ground_truth() const = 0;
  virtual const camera::StereoCalibration& calibration() const = 0;
  virtual const dataset::ImuNoise& imu_noise() const = 0;
  // Ground-truth occupancy (presets only; NotFound otherwise).
  virtual Result<dataset::OccupancyGrid> Occupancy(double resolution_m) const = 0;
  // Voxels a grid at this resolution would have (to refuse huge requests before computing).
  virtual int64_t EstimateVoxels(double resolution_m) const = 0;
};

struct PresetRequest {
  std::string name;
  int64_t frames = 0;  // 0 = full length
  uint64_t seed = 1;
  bool rectified = false;
};

// InvalidArgument naming "preset.name" / "preset.frames".
Result<std::unique_ptr<ScenarioSource>> OpenPreset(const PresetRequest& request);
// InvalidArgument "euroc.directory: empty"; NotFound naming the path (directory or data.csv);
// InvalidArgument naming file:line:field for a corrupt data set.
Result<std::unique_ptr<ScenarioSource>> OpenEuroc(const std::string& directory);

// One rendered stereo pair.
struct RenderedFrame {
  int64_t index = 0;
  int64_t t_ns = 0;
  cv::Mat left;
  cv::Mat right;
  double render_ms = 0.0;
};

// Renders frames ahead of the publisher on `threads` threads, at most `depth` frames ahead of the
// last requested one, so rendering (tens of ms per pair) overlaps publishing.
class RenderPipeline {
 public:
  RenderPipeline(std::shared_ptr<const ScenarioSource> source, int threads = 2, int depth = 4);
  ~RenderPipeline();
  RenderPipeline(const RenderPipeline&) = delete;
  RenderPipeline& operator=(const RenderPipeline&) = delete;

  // Frame `index` (blocks until rendered), and schedules index+1 .. index+depth-1.
  Result<RenderedFrame> Get(int64_t index);

 private:
  struct Slot {
    bool started = false;
    bool done = false;
    Status status;
    RenderedFrame frame;
  };
  void Work();
  void ScheduleLocked(int64_t index);

  std::shared_ptr<const ScenarioSource> source_;
  const int depth_;
  std::mutex mutex_;
  std::condition_variable work_cv_;
  std::condition_variable done_cv_;
  std::map<int64_t, Slot> slots_;
  bool stop_ = false;
  std::vector<std::thread> threads_;
};

// Where the player publishes. Implementations must be safe to call from the worker thread.
class StreamSink {
 public:
  virtual ~StreamSink() = default;
  virtual Status PublishStereo(uint64_t sequence, const RenderedFrame& frame, bool rectified) = 0;
  virtual Status PublishImu(uint64_t sequence, const dataset::ImuSample& sample) = 0;
  virtual Status PublishGroundTruth(uint64_t sequence, const dataset::GroundTruthState& state) = 0;
  // Waits until every matched reliable stereo reader acknowledged what was written (back-
  // pressure for the as-fast-as-subscribers mode). Unavailable on timeout.
  virtual Status WaitForStereoAcks(int64_t timeout_ns) = 0;
  virtual uint32_t StereoSubscribers() = 0;
  virtual uint32_t ImuSubscribers() = 0;
  virtual uint32_t domain() const = 0;
};

enum class PlayerState { kIdle, kLoaded, kRunning, kPaused, kFinished };
const char* PlayerStateName(PlayerState state);

struct Pacing {
  // Exactly one: a real-time factor > 0, or as fast as subscribers acknowledge.
  double real_time_factor = 1.0;
  bool as_fast_as_subscribers = false;
  bool loop = false;
  uint32_t wait_for_subscribers = 0;
  double wait_timeout_s = 5.0;
};

struct Stats {
  uint64_t count = 0;
  double mean_ms = 0, median_ms = 0, p95_ms = 0, max_ms = 0;
};

struct PlayerStatus {
  PlayerState state = PlayerState::kIdle;
  std::optional<ScenarioInfo> scenario;
  int64_t next_frame = 0;
  uint64_t frames_published = 0;
  uint64_t imu_samples_published = 0;
  uint64_t ground_truth_published = 0;
  int64_t current_t_ns = 0;
  double achieved_rate_hz = 0.0;
  Pacing pacing;
  uint32_t stereo_subscribers = 0;
  uint32_t imu_subscribers = 0;
  Stats render_ms;
  Stats publish_ms;
  uint32_t dds_domain = 0;
  std::string last_error;
};

class Player {
 public:
  // `sink` is not owned and must outlive the player.
  explicit Player(StreamSink* sink);
  ~Player();
  Player(const Player&) = delete;
  Player& operator=(const Player&) = delete;

  // Stops a running playback, replaces the scenario, state LOADED.
  void Load(std::shared_ptr<const ScenarioSource> source);
  // FailedPrecondition when IDLE or RUNNING.
  Result<PlayerStatus> Start(const Pacing& pacing);
  // FailedPrecondition unless RUNNING. Returns after the frame in flight.
  Result<PlayerStatus> Pause();
  // Publishes `frames` frames as fast as possible, then PAUSED. FailedPrecondition when IDLE or
  // RUNNING; InvalidArgument for 0; OutOfRange when fewer frames are left. Blocks until done.
  Result<PlayerStatus> Step(int64_t frames);
  PlayerStatus GetStatus();
  // The loaded source (null when IDLE).
  std::shared_ptr<const ScenarioSource> source();

 private:
  enum class Command { kNone, kRun, kStep };
  void WorkerLoop();
  // Publishes events up to and including frame `next_frame_`; returns false if interrupted.
  Status PublishNextFrame(std::unique_lock<std::mutex>* lock, bool paced);
  PlayerStatus StatusLocked();
  void StopLocked(std::unique_lock<std::mutex>* lock);

  StreamSink* sink_;
  std::mutex mutex_;
  std::condition_variable cv_;       // wakes the worker (commands) and pacing sleeps
  std::condition_variable done_cv_;  // wakes callers waiting for the worker
  std::thread worker_;
  bool shutdown_ = false;

  // Guarded by mutex_.
  PlayerState state_ = PlayerState::kIdle;
  Command command_ = Command::kNone;
  bool busy_ = false;  // the worker is inside a frame
  int64_t step_remaining_ = 0;
  uint64_t generation_ = 0;  // bumped by Load/Pause to interrupt the worker
  std::shared_ptr<const ScenarioSource> source_;
  std::unique_ptr<RenderPipeline> pipeline_;
  Pacing pacing_;
  int64_t next_frame_ = 0;
  size_t next_imu_ = 0;
  size_t next_gt_ = 0;
  uint64_t frames_published_ = 0;
  uint64_t imu_published_ = 0;
  uint64_t gt_published_ = 0;
  int64_t current_t_ns_ = 0;
  // Pacing anchor: wall (steady) time at which data time anchor_t_ns_ is due.
  int64_t anchor_wall_ns_ = 0;
  int64_t anchor_t_ns_ = 0;
  bool need_subscriber_wait_ = false;
  std::deque<int64_t> publish_wall_ns_;  // recent frame publish times for the achieved rate
  std::vector<double> render_ms_;
  std::vector<double> publish_ms_;
  std::string last_error_;
};

}  // namespace mav::simulator_service
