#pragma once
// The simulator service's replay, free of gRPC and protobuf: the Player plays a
// sim::ScenarioSource (a rendered preset or a recorded EuRoC directory, libs/sim/scenario_source.h)
// on the one worker of a WorkQueue and publishes through a StreamSink (DDS in production,
// dds_io.h; a fake in tests). Frames are rendered ahead by a sim::FramePrefetcher.
//
// State machine (simulator.proto):
//   IDLE --Load--> LOADED --Start--> RUNNING --Pause--> PAUSED --Start--> RUNNING
//   RUNNING --(last frame, loop=false)--> FINISHED --Start--> RUNNING (from frame 0)
//   LOADED/PAUSED/FINISHED --Step--> PAUSED
//   any --Load--> LOADED (a running playback is stopped first)
// Commands are serialised; the playback itself is one long task of the queue that Pause and
// Load interrupt (a reset of the queue) and that sleeps for its pacing in TaskContext::SleepUntil.
//
// Time order: every IMU sample and ground-truth state with t <= a frame's t_ns is published
// before that frame, so a subscriber sees one merged, time-ordered stream per topic.
//
// Memory: the prefetcher holds at most 4 rendered pairs; the runtime statistics the last 1000
// frames.

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "mav/common/pacing.h"
#include "mav/common/stats.h"
#include "mav/common/status.h"
#include "mav/common/termination.h"
#include "mav/common/work_queue.h"
#include "mav/dataset/types.h"
#include "mav/sim/scenario_source.h"

namespace mav::simulator_service {

using sim::RenderedFrame;
using sim::ScenarioInfo;
using sim::ScenarioSource;

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
  // The stereo writer is in shared memory (transport::Entity::UsesSharedMemory).
  virtual bool SharedMemory() const { return false; }
  // Work on a frame that can be done before its turn, on the rendering thread (the DDS sink
  // computes the sample's CRC-32 there, off the publishing path). Must be thread-safe.
  virtual void PrepareStereo(RenderedFrame* frame) { (void)frame; }
};

enum class PlayerState { kIdle, kLoaded, kRunning, kPaused, kFinished };
const char* PlayerStateName(PlayerState state);

struct Pacing {
  // Data seconds per wall second, in [kMinRealTimeFactor, kMaxRealTimeFactor]; or as fast as
  // the subscribers acknowledge (real_time_factor ignored).
  static constexpr double kMinRealTimeFactor = 1e-3;
  static constexpr double kMaxRealTimeFactor = 1e3;
  double real_time_factor = 1.0;
  bool as_fast_as_subscribers = false;
  bool loop = false;
  uint32_t wait_for_subscribers = 0;
  double wait_timeout_s = 5.0;

  // InvalidArgument naming the field ("real_time_factor: must be in [0.001, 1000], got 1e-15").
  bool IsValid(std::string* why) const;
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
  RuntimeStats render_ms;
  RuntimeStats publish_ms;
  uint32_t dds_domain = 0;
  bool dds_shared_memory = false;
  std::string last_error;
};

class Player {
 public:
  // `sink` is not owned and must outlive the player. `render_priority`: the rendering threads'
  // (sim::FramePrefetcher; kIdle for real-time playback beside its subscribers).
  explicit Player(StreamSink* sink, sim::FramePrefetcher::Priority render_priority =
                                        sim::FramePrefetcher::Priority::kNormal);
  ~Player();
  Player(const Player&) = delete;
  Player& operator=(const Player&) = delete;

  // Stops a running playback, replaces the scenario, state LOADED. DEADLINE_EXCEEDED (the old
  // scenario stays) when `deadline` stops while an earlier command (a long Step) holds the
  // player.
  Status Load(std::shared_ptr<const ScenarioSource> source, const Termination& deadline = {});
  // FailedPrecondition when IDLE or RUNNING; InvalidArgument for a bad pacing.
  Result<PlayerStatus> Start(const Pacing& pacing);
  // FailedPrecondition unless RUNNING. Returns after the frame in flight.
  Result<PlayerStatus> Pause();
  // Publishes `frames` frames as fast as possible, then PAUSED. FailedPrecondition when IDLE or
  // RUNNING; InvalidArgument for 0; OutOfRange when fewer frames are left; DEADLINE_EXCEEDED
  // when `deadline` stops it (the frames published so far stay published).
  Result<PlayerStatus> Step(int64_t frames, const Termination& deadline = {});
  PlayerStatus GetStatus() const;
  // The loaded source (null when IDLE).
  std::shared_ptr<const ScenarioSource> source() const;

  // Stops the worker (a running playback ends). Idempotent.
  void Shutdown();

 private:
  // On the worker: publishes frames (paced or not) until `frames` are out (-1: to the end,
  // looping if asked), the task goes stale or an error stops it.
  Status Run(const TaskContext& context, bool paced, int64_t frames);
  Status PublishNextFrame(const TaskContext& context, bool paced);
  PlayerStatus StatusLocked() const;
  void RewindLocked();

  StreamSink* sink_;
  const sim::FramePrefetcher::Priority render_priority_;
  WorkQueue queue_;
  std::mutex command_mutex_;  // one command at a time (Load, Start, Pause, Step)

  mutable std::mutex mutex_;
  // Guarded by mutex_ (the worker updates them between frames).
  PlayerState state_ = PlayerState::kIdle;
  std::shared_ptr<const ScenarioSource> source_;
  std::shared_ptr<sim::FramePrefetcher> prefetcher_;
  Pacing pacing_;
  int64_t next_frame_ = 0;
  size_t next_imu_ = 0;
  size_t next_gt_ = 0;
  uint64_t frames_published_ = 0;
  uint64_t imu_published_ = 0;
  uint64_t gt_published_ = 0;
  int64_t current_t_ns_ = 0;
  RateMeter publish_rate_;  // frames published per wall second
  RuntimeWindow render_ms_;
  RuntimeWindow publish_ms_;
  std::string last_error_;

  // Real-time mode: when publishing falls this far behind the schedule, the schedule is reset
  // instead of bursting to catch up.
  static constexpr int64_t kMaxLatenessNs = 200'000'000;
  // Worker only: when each data time is due (anchored at the start, a rewind, a stall).
  RealTimePacer pacer_{1.0, kMaxLatenessNs};
};

}  // namespace mav::simulator_service
