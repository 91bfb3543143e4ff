#include "services/simulator/player.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "mav/common/check.h"
#include "mav/common/log.h"
#include "mav/common/time.h"

namespace mav::simulator_service {

namespace {

constexpr int64_t kNoTime = std::numeric_limits<int64_t>::max();
// Fast mode: how long one frame may wait for its acknowledgements before we move on (a reader
// that died keeps its match until its lease expires).
constexpr int64_t kAckTimeoutNs = 2'000'000'000;
constexpr size_t kStatsWindow = 1000;

WorkQueueOptions QueueOptions() {
  WorkQueueOptions o = WorkQueueOptions::Named("simulator playback", 2);
  o.stats_window = kStatsWindow;
  return o;
}

}  // namespace

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

bool Pacing::IsValid(std::string* why) const {
  if (as_fast_as_subscribers) return true;
  if (!std::isfinite(real_time_factor) || real_time_factor < kMinRealTimeFactor ||
      real_time_factor > kMaxRealTimeFactor) {
    if (why != nullptr) {
      *why = "real_time_factor: must be in [0.001, 1000], got " + std::to_string(real_time_factor);
    }
    return false;
  }
  if (!std::isfinite(wait_timeout_s) || wait_timeout_s < 0) {
    if (why != nullptr) *why = "wait_timeout_s: must be >= 0 and finite";
    return false;
  }
  return true;
}

Player::Player(StreamSink* sink, sim::FramePrefetcher::Priority render_priority)
    : sink_(sink),
      render_priority_(render_priority),
      queue_(QueueOptions()),
      render_ms_(kStatsWindow),
      publish_ms_(kStatsWindow) {
  MAV_CHECK(sink_ != nullptr);
}

Player::~Player() { Shutdown(); }

void Player::Shutdown() { queue_.Stop("the simulator is shutting down"); }

void Player::RewindLocked() {
  next_frame_ = 0;
  next_imu_ = 0;
  next_gt_ = 0;
}

Status Player::Load(std::shared_ptr<const ScenarioSource> source, const Termination& deadline) {
  MAV_CHECK(source != nullptr);
  std::lock_guard<std::mutex> command(command_mutex_);
  MAV_RETURN_IF_ERROR(deadline.Check("LoadScenario"));
  queue_.Reset("a new scenario was loaded");
  StreamSink* sink = sink_;
  auto prefetcher = std::make_shared<sim::FramePrefetcher>(
      source, /*threads=*/2, /*depth=*/4,
      [sink](RenderedFrame& frame) {
        sink->PrepareStereo(&frame);
        return Status::Ok();
      },
      render_priority_);
  std::shared_ptr<sim::FramePrefetcher> old;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    old = std::move(prefetcher_);  // joined outside the lock
    source_ = std::move(source);
    prefetcher_ = std::move(prefetcher);
    state_ = PlayerState::kLoaded;
    RewindLocked();
    frames_published_ = imu_published_ = gt_published_ = 0;
    current_t_ns_ = 0;
    publish_rate_.Clear();
    render_ms_.Clear();
    publish_ms_.Clear();
    last_error_.clear();
    MAV_LOG(kInfo) << "loaded " << source_->info().name << ": " << source_->info().frames
                   << " frames, " << source_->info().imu_samples << " IMU samples";
  }
  return Status::Ok();
}

Result<PlayerStatus> Player::Start(const Pacing& pacing) {
  std::string why;
  if (!pacing.IsValid(&why)) return Status::InvalidArgument(why);
  std::lock_guard<std::mutex> command(command_mutex_);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (state_ == PlayerState::kIdle) {
      return Status::FailedPrecondition("no scenario loaded: call LoadScenario first");
    }
    if (state_ == PlayerState::kRunning) {
      return Status::FailedPrecondition("already running: Pause first to change the pacing");
    }
    if (state_ == PlayerState::kFinished) RewindLocked();
    pacing_ = pacing;
    state_ = PlayerState::kRunning;
  }
  const bool paced = !pacing.as_fast_as_subscribers;
  // The playback runs until it ends or Pause/Load interrupt it; nobody waits for its result.
  const Ticket<Status> ticket = queue_.Submit<Status>(
      [this, paced](const TaskContext& context) { return Run(context, paced, -1); });
  if (!ticket.accepted()) return ticket.submit_status();
  std::lock_guard<std::mutex> lock(mutex_);
  return StatusLocked();
}

Result<PlayerStatus> Player::Pause() {
  std::lock_guard<std::mutex> command(command_mutex_);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (state_ != PlayerState::kRunning) {
      return Status::FailedPrecondition(std::string("not running (state ") +
                                        PlayerStateName(state_) + ")");
    }
  }
  queue_.Reset("paused");  // returns after the frame in flight
  std::lock_guard<std::mutex> lock(mutex_);
  // The playback may have reached the end meanwhile (FINISHED stays).
  if (state_ == PlayerState::kRunning) state_ = PlayerState::kPaused;
  return StatusLocked();
}

Result<PlayerStatus> Player::Step(int64_t frames, const Termination& deadline) {
  std::lock_guard<std::mutex> command(command_mutex_);
  int64_t first_frame = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (state_ == PlayerState::kIdle) {
      return Status::FailedPrecondition("no scenario loaded: call LoadScenario first");
    }
    if (state_ == PlayerState::kRunning) {
      return Status::FailedPrecondition("running: Pause before stepping");
    }
    if (frames <= 0) {
      return Status::InvalidArgument("frames: must be >= 1, got " + std::to_string(frames));
    }
    if (state_ == PlayerState::kFinished) RewindLocked();
    first_frame = next_frame_;
    const int64_t left = source_->info().frames - next_frame_;
    if (frames > left) {
      return Status::OutOfRange("frames: " + std::to_string(frames) + " requested but only " +
                                std::to_string(left) + " left (next frame " +
                                std::to_string(next_frame_) + " of " +
                                std::to_string(source_->info().frames) + ")");
    }
    state_ = PlayerState::kRunning;
  }
  Ticket<Status> ticket = queue_.Submit<Status>(
      [this, frames](const TaskContext& context) { return Run(context, false, frames); },
      QueuePolicy::kReject, deadline);
  const Status stepped = ticket.Wait();
  std::lock_guard<std::mutex> lock(mutex_);
  if (state_ == PlayerState::kRunning) state_ = PlayerState::kPaused;
  if (!stepped.ok() && stepped.code() != StatusCode::kCancelled) return stepped;
  // The playback loop stops quietly when the deadline passes; the caller must still hear that the
  // step was cut short (a Pause or a Load cancels it instead, and that is not an error).
  const int64_t published = next_frame_ - first_frame;
  if (published < frames && deadline.expired()) {
    return Status::DeadlineExceeded("Step: the deadline passed after " + std::to_string(published) +
                                    " of " + std::to_string(frames) +
                                    " frames (those stay published)");
  }
  return StatusLocked();
}

PlayerStatus Player::GetStatus() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return StatusLocked();
}

std::shared_ptr<const ScenarioSource> Player::source() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return source_;
}

PlayerStatus Player::StatusLocked() const {
  PlayerStatus status;
  status.state = state_;
  if (source_ != nullptr) status.scenario = source_->info();
  status.next_frame = next_frame_;
  status.frames_published = frames_published_;
  status.imu_samples_published = imu_published_;
  status.ground_truth_published = gt_published_;
  status.current_t_ns = current_t_ns_;
  status.achieved_rate_hz = publish_rate_.Rate(MonotonicNowNs());
  status.pacing = pacing_;
  status.stereo_subscribers = sink_->StereoSubscribers();
  status.imu_subscribers = sink_->ImuSubscribers();
  status.render_ms = render_ms_.Summary();
  status.publish_ms = publish_ms_.Summary();
  status.dds_domain = sink_->domain();
  status.dds_shared_memory = sink_->SharedMemory();
  status.last_error = last_error_;
  return status;
}

// ---- On the worker ------------------------------------------------------------------------------

Status Player::Run(const TaskContext& context, bool paced, int64_t frames) {
  Pacing pacing;
  std::shared_ptr<const ScenarioSource> source;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    pacing = pacing_;
    source = source_;
  }
  if (frames < 0 && pacing.wait_for_subscribers > 0) {
    const int64_t until = MonotonicNowNs() + SecondsToNs(pacing.wait_timeout_s);
    while (sink_->StereoSubscribers() < pacing.wait_for_subscribers && MonotonicNowNs() < until) {
      if (!context.SleepUntil(MonotonicNowNs() + 10'000'000)) return Status::Ok();
    }
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    int64_t t_first = source->FrameTimeNs(next_frame_);
    if (next_imu_ < source->imu().size()) {
      t_first = std::min(t_first, source->imu()[next_imu_].t_ns);
    }
    pacer_.Anchor(t_first, context.NowNs());
  }
  int64_t published = 0;
  while (!context.ShouldStop() && (frames < 0 || published < frames)) {
    Status status = PublishNextFrame(context, paced);
    std::lock_guard<std::mutex> lock(mutex_);
    if (!status.ok()) {
      last_error_ = status.ToString();
      MAV_LOG(kError) << "playback stopped: " << last_error_;
      state_ = PlayerState::kPaused;
      return status;
    }
    ++published;
    if (next_frame_ >= source->info().frames) {
      if (frames < 0 && pacing.loop) {
        RewindLocked();
        pacer_.Anchor(source->FrameTimeNs(0), context.NowNs());
      } else {
        if (frames < 0) state_ = PlayerState::kFinished;  // a Step ends PAUSED
        return Status::Ok();
      }
    }
  }
  return Status::Ok();
}

// Publishes the IMU and ground truth up to the next frame, then the frame. Returns OK without
// publishing the frame when the task is interrupted (Pause, Load, shutdown).
Status Player::PublishNextFrame(const TaskContext& context, bool paced) {
  std::shared_ptr<const ScenarioSource> source;
  std::shared_ptr<sim::FramePrefetcher> prefetcher;
  int64_t frame_index = 0;
  double factor = 1.0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    source = source_;
    prefetcher = prefetcher_;
    frame_index = next_frame_;
    factor = pacing_.real_time_factor;
  }
  const int64_t t_frame = source->FrameTimeNs(frame_index);
  // Sleeps until data time t is due; false when interrupted. (Fast mode has no factor.)
  if (paced) pacer_.set_factor(factor);
  auto wait_due = [&](int64_t t_ns) {
    if (!paced) return !context.ShouldStop();
    return context.SleepUntil(pacer_.DueNs(t_ns, context.NowNs()));
  };

  // Render (or fetch the pre-rendered) frame first so that the IMU and the frame go out together.
  Result<RenderedFrame> frame = prefetcher->Get(frame_index);
  if (!frame.ok()) return frame.status().WithContext("frame " + std::to_string(frame_index));
  {
    std::lock_guard<std::mutex> lock(mutex_);
    render_ms_.Add(frame->render_ms);
  }
  const std::vector<dataset::ImuSample>& imu = source->imu();
  const std::vector<dataset::GroundTruthState>& gt = source->ground_truth();
  while (true) {
    size_t next_imu = 0, next_gt = 0;
    uint64_t imu_seq = 0, gt_seq = 0;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      next_imu = next_imu_;
      next_gt = next_gt_;
      imu_seq = imu_published_;
      gt_seq = gt_published_;
    }
    const int64_t t_imu = next_imu < imu.size() ? imu[next_imu].t_ns : kNoTime;
    const int64_t t_gt = next_gt < gt.size() ? gt[next_gt].t_ns : kNoTime;
    const int64_t t_next = std::min(t_imu, t_gt);
    if (t_next > t_frame) break;
    if (!wait_due(t_next)) return Status::Ok();
    const bool is_imu = t_imu <= t_gt;
    const Status status = is_imu ? sink_->PublishImu(imu_seq, imu[next_imu])
                                 : sink_->PublishGroundTruth(gt_seq, gt[next_gt]);
    std::lock_guard<std::mutex> lock(mutex_);
    if (is_imu) {
      ++next_imu_;
      ++imu_published_;
    } else {
      ++next_gt_;
      ++gt_published_;
    }
    if (!status.ok()) last_error_ = status.ToString();
  }
  if (!wait_due(t_frame)) return Status::Ok();

  uint64_t sequence = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    sequence = frames_published_;
  }
  const int64_t start_ns = MonotonicNowNs();
  Status status = sink_->PublishStereo(sequence, *frame, source->info().rectified);
  if (status.ok() && !paced) status = sink_->WaitForStereoAcks(kAckTimeoutNs);
  const int64_t end_ns = MonotonicNowNs();
  std::lock_guard<std::mutex> lock(mutex_);
  if (!status.ok()) {
    last_error_ = status.ToString();
    MAV_LOG(kWarning) << "frame " << frame_index << ": " << last_error_;
  }
  publish_ms_.Add(NsToSeconds(end_ns - start_ns) * 1e3);
  ++frames_published_;
  ++next_frame_;
  current_t_ns_ = t_frame;
  publish_rate_.Add(end_ns);
  return Status::Ok();
}

}  // namespace mav::simulator_service
