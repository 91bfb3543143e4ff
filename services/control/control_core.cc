#include "services/control/control_core.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "mav/common/check.h"
#include "mav/common/log.h"
#include "mav/common/text.h"
#include "mav/common/time.h"

namespace mav::control_service {

ControlCore::ControlCore(CommandSink* sink) : sink_(sink) { MAV_CHECK(sink_ != nullptr); }

Status ControlCore::Configure(const ControlConfig& config, const Termination& deadline) {
  if (std::string why; !config.IsValid(&why)) return Status::InvalidArgument(why);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (autopilot_.has_value() && autopilot_->armed()) {
      return Status::FailedPrecondition("armed: Disarm before Configure");
    }
  }
  // The weights are computed here, outside the mutex: the steps go on meanwhile.
  MAV_ASSIGN_OR_RETURN(control::Autopilot built, control::Autopilot::Create(config.autopilot));
  MAV_RETURN_IF_ERROR(deadline.Check("Configure"));
  std::lock_guard<std::mutex> lock(mutex_);
  if (autopilot_.has_value() && autopilot_->armed()) {
    return Status::FailedPrecondition("armed: Disarm before Configure");
  }
  autopilot_.emplace(std::move(built));
  config_ = config;
  have_imu_ = false;
  last_imu_t_ns_ = last_imu_wall_ns_ = 0;
  last_command_ = control::RotorVector::Zero(config.autopilot.vehicle.rotor_count);
  last_armed_ = false;
  last_pose_delay_ns_ = 0;
  pending_pose_t_ns_ = -1;
  imu_rejected_ = imu_repeated_ = poses_rejected_ = commands_ = 0;
  lockstep_.assign(config.pose_frames.size(), LockstepSource());
  for (size_t i = 0; i < config.lockstep_poses.size(); ++i) {
    const LockstepPoseOptions& l = config.lockstep_poses[i];
    if (l.latency_s == 0) continue;
    LockstepSource& s = lockstep_[i];
    s.enabled = true;
    s.latency_ns = SecondsToNs(l.latency_s);
    s.period_ns = PeriodNs(config.autopilot.estimator.pose_sources[i].rate_hz);
    s.wait_ns = SecondsToNs(l.wait_s);
  }
  lockstep_frames_missed_ = 0;
  imu_rate_.Clear();
  pose_rate_.Clear();
  loop_ms_.Clear();
  pose_latency_.Clear();
  last_error_.clear();
  takeover_pending_ = false;
  MAV_LOG(kInfo) << "configured: " << control::ControllerTypeName(config.autopilot.controller)
                 << " controller, " << config.autopilot.estimator.pose_sources.size()
                 << " pose source(s), IMU " << config.autopilot.estimator.imu_rate_hz << " Hz"
                 << (config.lockstep ? ", lock-step" : "");
  return Status::Ok();
}

bool ControlCore::configured() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return autopilot_.has_value();
}

Status ControlCore::CheckConfiguredLocked() const {
  return autopilot_.has_value()
             ? Status::Ok()
             : Status::FailedPrecondition("not configured: call Configure first");
}

Status ControlCore::PublishLocked(int64_t t_ns, bool armed, const control::RotorVector& speeds) {
  ActuatorOutput out;
  out.sequence = sequence_++;
  ++commands_;
  out.t_ns = t_ns;
  out.armed = armed;
  out.rotor_speeds_radps = speeds;
  Status s = sink_->PublishCommand(out);
  if (!s.ok()) last_error_ = "publishing a command: " + s.ToString();
  return s;
}

void ControlCore::OnImu(const control::ImuMeasurement& imu) {
  const int64_t start_ns = MonotonicNowNs();
  std::lock_guard<std::mutex> lock(mutex_);
  if (!autopilot_.has_value()) return;
  if (have_imu_ && imu.t_ns == last_imu_t_ns_) {
    ++imu_repeated_;
    (void)PublishLocked(imu.t_ns, last_armed_, last_command_);
    return;
  }
  if (have_imu_ && imu.t_ns < last_imu_t_ns_) {
    ++imu_rejected_;
    last_error_ = "imu: t_ns " + std::to_string(imu.t_ns) + " is older than the previous " +
                  std::to_string(last_imu_t_ns_);
    return;
  }
  ReleaseHeldLocked(imu.t_ns);
  last_command_ = autopilot_->FeedImu(imu);
  last_armed_ = autopilot_->armed();
  if (pending_pose_t_ns_ >= 0) {
    last_pose_delay_ns_ = imu.t_ns - pending_pose_t_ns_;
    pending_pose_t_ns_ = -1;
  }
  have_imu_ = true;
  last_imu_t_ns_ = imu.t_ns;
  last_imu_wall_ns_ = start_ns;
  imu_rate_.Add(start_ns);
  (void)PublishLocked(imu.t_ns, last_armed_, last_command_);
  loop_ms_.Add(MsSince(start_ns));
  if (takeover_pending_) TryTakeoverLocked();
}

void ControlCore::TryTakeoverLocked() {
  if (autopilot_->armed()) {  // armed by a client meanwhile
    takeover_pending_ = false;
    return;
  }
  if (!autopilot_->ReadyForTakeover()) return;
  takeover_pending_ = false;
  const Eigen::Vector3d p = autopilot_->estimator().state().p_world;
  if (Status s = autopilot_->ArmInAir(); !s.ok()) {
    last_error_ = "takeover: " + s.message();
    MAV_LOG(kWarning) << last_error_.text() << " (staying disarmed)";
    return;
  }
  char text[160];
  std::snprintf(text, sizeof(text),
                "took over the vehicle in the air at (%.2f, %.2f, %.2f) m, IMU time %.2f s: "
                "holding there",
                p.x(), p.y(), p.z(), NsToSeconds(last_imu_t_ns_));
  MAV_LOG(kWarning) << text;
}

void PoseLatencyWindows::Add(const PoseStamps& s, int64_t merged_ns) {
  if (s.frame_publish_ns <= 0 || s.frame_receive_ns <= 0 || s.pose_publish_ns <= 0 ||
      s.pose_take_ns <= 0) {
    return;
  }
  auto ms = [](int64_t from, int64_t to) { return static_cast<double>(to - from) * 1e-6; };
  total_.Add(ms(s.frame_publish_ns, merged_ns));
  frame_transport_.Add(ms(s.frame_publish_ns, s.frame_receive_ns));
  localization_.Add(ms(s.frame_receive_ns, s.pose_publish_ns));
  pose_transport_.Add(ms(s.pose_publish_ns, s.pose_take_ns));
  merge_.Add(ms(s.pose_take_ns, merged_ns));
}

PoseLatency PoseLatencyWindows::Summary() const {
  return {total_.Summary(), frame_transport_.Summary(), localization_.Summary(),
          pose_transport_.Summary(), merge_.Summary()};
}

void PoseLatencyWindows::Clear() {
  for (RuntimeWindow* w : {&total_, &frame_transport_, &localization_, &pose_transport_, &merge_}) {
    w->Clear();
  }
}

void ControlCore::OnPose(const std::string& frame_id, int64_t t_ns,
                         const geometry::SE3& T_world_sensor, const PoseStamps& stamps) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (OnPoseLocked(frame_id, t_ns, T_world_sensor)) pose_latency_.Add(stamps, WallNowNs());
}

bool ControlCore::OnPoseLocked(const std::string& frame_id, int64_t t_ns,
                               const geometry::SE3& T_world_sensor) {
  if (!autopilot_.has_value()) return false;
  const std::vector<std::string>& frames = config_->pose_frames;
  const auto it = std::find(frames.begin(), frames.end(), frame_id);
  if (it == frames.end()) {
    ++poses_rejected_;
    last_error_ = "pose: unknown child_frame_id " + QuoteForError(frame_id) +
                  " (configured: " + frames[0] + (frames.size() > 1 ? ", ..." : "") + ")";
    return false;
  }
  control::PoseMeasurement pose;
  pose.t_ns = t_ns;
  pose.source = static_cast<int>(it - frames.begin());
  pose.T_world_sensor = T_world_sensor;
  if (LockstepSource& l = lockstep_[static_cast<size_t>(pose.source)]; l.enabled) {
    // Held until the IMU's time reaches its stamp + latency (ReleaseHeldLocked).
    l.answered_ns = std::max(l.answered_ns, t_ns);
    l.silent = false;
    if (l.held.size() >= kMaxHeldPoses) {
      l.held.erase(l.held.begin());
      ++poses_rejected_;
      last_error_ = "pose: " + frame_id + ": more than " + std::to_string(kMaxHeldPoses) +
                    " lock-step poses waiting; the oldest was dropped";
    }
    auto at = std::upper_bound(l.held.begin(), l.held.end(), t_ns,
                               [](int64_t t, const Held& h) { return t < h.t_ns; });
    l.held.insert(at, Held{t_ns, T_world_sensor});
    return true;
  }
  // Refusals (too old, before the first IMU) are counted by the autopilot (poses_dropped).
  if (autopilot_->FeedPose(pose).ok()) pending_pose_t_ns_ = t_ns;
  pose_rate_.Add(MonotonicNowNs());
  return true;
}

void ControlCore::OnPoseAnswer(const std::string& frame_id, int64_t t_ns, const std::string& why) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++poses_rejected_;
  last_error_ = "pose: " + why;
  if (!autopilot_.has_value()) return;
  const std::vector<std::string>& frames = config_->pose_frames;
  const auto it = std::find(frames.begin(), frames.end(), frame_id);
  if (it == frames.end()) return;
  LockstepSource& l = lockstep_[static_cast<size_t>(it - frames.begin())];
  if (!l.enabled) return;
  l.answered_ns = std::max(l.answered_ns, t_ns);
  l.silent = false;
}

std::optional<int64_t> ControlCore::DueUnanswered(const LockstepSource& s, int64_t imu_t_ns) {
  if (!s.enabled || s.silent) return std::nullopt;
  // Frames are stamped at multiples of the period; the first awaited is the first at or after
  // the first IMU sample (set then; before it, this one).
  const int64_t first = s.first_frame_ns >= 0
                            ? s.first_frame_ns
                            : (imu_t_ns + s.period_ns - 1) / s.period_ns * s.period_ns;
  const int64_t next =
      std::max(first, s.answered_ns >= 0 ? (s.answered_ns / s.period_ns + 1) * s.period_ns : first);
  if (next + s.latency_ns > imu_t_ns) return std::nullopt;
  return next;
}

bool ControlCore::AwaitingPose(int64_t imu_t_ns) const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!autopilot_.has_value()) return false;
  for (const LockstepSource& s : lockstep_) {
    if (DueUnanswered(s, imu_t_ns)) return true;
  }
  return false;
}

void ControlCore::GiveUpWaiting(int64_t imu_t_ns) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!autopilot_.has_value()) return;
  for (size_t i = 0; i < lockstep_.size(); ++i) {
    LockstepSource& s = lockstep_[i];
    const std::optional<int64_t> due = DueUnanswered(s, imu_t_ns);
    if (!due) continue;
    s.silent = true;
    ++lockstep_frames_missed_;
    last_error_ = "lock-step: no answer from " + config_->pose_frames[i] + " for the frame at " +
                  std::to_string(NsToSeconds(*due)) + " s within " +
                  std::to_string(NsToSeconds(s.wait_ns)) +
                  " s: flying on without it until it answers again";
    MAV_LOG(kWarning) << last_error_.text();
  }
}

int64_t ControlCore::LockstepWaitNs() const {
  std::lock_guard<std::mutex> lock(mutex_);
  int64_t wait = 0;
  for (const LockstepSource& s : lockstep_) {
    if (s.enabled) wait = std::max(wait, s.wait_ns);
  }
  return wait;
}

void ControlCore::ReleaseHeldLocked(int64_t imu_t_ns) {
  for (size_t i = 0; i < lockstep_.size(); ++i) {
    LockstepSource& s = lockstep_[i];
    if (!s.enabled) continue;
    if (s.first_frame_ns < 0) {
      s.first_frame_ns = (imu_t_ns + s.period_ns - 1) / s.period_ns * s.period_ns;
    }
    size_t n = 0;
    for (; n < s.held.size() && s.held[n].t_ns + s.latency_ns <= imu_t_ns; ++n) {
      const control::PoseMeasurement pose{s.held[n].t_ns, static_cast<int>(i),
                                          s.held[n].T_world_sensor};
      // Refusals (too old, the gate) are counted by the autopilot.
      if (autopilot_->FeedPose(pose).ok()) last_pose_delay_ns_ = imu_t_ns - pose.t_ns;
      pose_rate_.Add(MonotonicNowNs());
    }
    s.held.erase(s.held.begin(), s.held.begin() + static_cast<std::ptrdiff_t>(n));
  }
}

void ControlCore::RejectImu(const std::string& why) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++imu_rejected_;
  last_error_ = "imu: " + why;
}

void ControlCore::RejectPose(const std::string& why) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++poses_rejected_;
  last_error_ = "pose: " + why;
}

void ControlCore::OnPoll(int64_t now_wall_ns, uint32_t imu_publishers_alive) {
  std::lock_guard<std::mutex> lock(mutex_);
  const bool lost = imu_publishers_alive == 0 && imu_publishers_alive_ > 0;  // was alive
  imu_publishers_alive_ = imu_publishers_alive;
  if (imu_publishers_alive > 0) imu_publisher_seen_ = true;
  if (lost) {
    last_error_ = "the IMU's publisher (the simulator) is gone: its DDS liveliness lapsed";
    MAV_LOG(kWarning) << last_error_.text() << "; the estimate is stale";
  }
  if (!autopilot_.has_value() || !have_imu_) return;
  control::RotorVector command;
  if (config_->lockstep) {
    // A paused simulation is not a lost IMU, a vanished simulator is: the ImuLossPolicy.
    if (!lost) return;
    const int64_t after_ns = last_imu_t_ns_ + SecondsToNs(config_->autopilot.imu_timeout_s) + 1;
    if (!autopilot_->CheckImuTimeout(after_ns, &command)) return;
    last_error_ =
        last_error_.text() + (autopilot_->armed() ? ": holding the last command" : ": disarmed");
    MAV_LOG(kWarning) << last_error_.text();
    (void)PublishLocked(after_ns, autopilot_->armed(), command);
    return;
  }
  // The IMU's time line advanced by the wall time since the last sample.
  const int64_t now_imu_ns = last_imu_t_ns_ + (now_wall_ns - last_imu_wall_ns_);
  if (!autopilot_->CheckImuTimeout(now_imu_ns, &command)) return;
  last_error_ = "no IMU sample for " + std::to_string((now_wall_ns - last_imu_wall_ns_) / 1000000) +
                " ms: " + (autopilot_->armed() ? "holding the last command" : "disarmed");
  (void)PublishLocked(now_imu_ns, autopilot_->armed(), command);
}

Status ControlCore::SetTakeover(bool enabled) {
  std::lock_guard<std::mutex> lock(mutex_);
  MAV_RETURN_IF_ERROR(CheckConfiguredLocked());
  if (enabled && !autopilot_->options().rest_z_m) {
    return Status::FailedPrecondition(
        "takeover: the configuration does not say where the ground is (rest_z_m)");
  }
  takeover_pending_ = enabled;
  return Status::Ok();
}

Status ControlCore::Arm(bool in_air) {
  std::lock_guard<std::mutex> lock(mutex_);
  MAV_RETURN_IF_ERROR(CheckConfiguredLocked());
  return in_air ? autopilot_->ArmInAir() : autopilot_->Arm();
}

void ControlCore::Disarm() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (autopilot_.has_value()) autopilot_->Disarm();
}

Status ControlCore::Hover(const Eigen::Vector3d& position, double yaw_rad,
                          const std::optional<control::GoToLimits>& limits, bool immediate) {
  std::lock_guard<std::mutex> lock(mutex_);
  MAV_RETURN_IF_ERROR(CheckConfiguredLocked());
  if (immediate) return autopilot_->HoldPosition(position, yaw_rad);
  return autopilot_->Hover(position, yaw_rad, limits.has_value() ? &*limits : nullptr);
}

Status ControlCore::SetTrajectory(const geometry::PolynomialTrajectory& trajectory,
                                  int64_t start_t_ns, const Eigen::Vector3d& offset,
                                  bool allow_jump) {
  std::lock_guard<std::mutex> lock(mutex_);
  MAV_RETURN_IF_ERROR(CheckConfiguredLocked());
  return autopilot_->SetTrajectory(trajectory, start_t_ns, offset, allow_jump);
}

Status ControlCore::SetPaperGains(const control::PaperControllerGains& gains) {
  std::lock_guard<std::mutex> lock(mutex_);
  MAV_RETURN_IF_ERROR(CheckConfiguredLocked());
  if (autopilot_->options().controller != control::ControllerType::kPaper) {
    return Status::FailedPrecondition(
        "gains: the configured controller is lee: give lee_gains (or Configure the paper one)");
  }
  MAV_RETURN_IF_ERROR(autopilot_->SetPaperGains(gains));
  config_->autopilot.paper_gains = gains;
  return Status::Ok();
}

Status ControlCore::SetLeeGains(const control::LeeControllerGains& gains) {
  std::lock_guard<std::mutex> lock(mutex_);
  MAV_RETURN_IF_ERROR(CheckConfiguredLocked());
  if (autopilot_->options().controller != control::ControllerType::kLee) {
    return Status::FailedPrecondition(
        "lee_gains: the configured controller is paper: give gains (or Configure lee)");
  }
  MAV_RETURN_IF_ERROR(autopilot_->SetLeeGains(gains));
  config_->autopilot.lee_gains = gains;
  return Status::Ok();
}

ControlCoreStatus ControlCore::GetStatus() const {
  const int64_t now_ns = MonotonicNowNs();
  ControlCoreStatus s;
  s.actuator_subscribers = sink_->ActuatorSubscribers();
  std::lock_guard<std::mutex> lock(mutex_);
  s.configured = autopilot_.has_value();
  s.config = config_;
  if (autopilot_.has_value()) s.autopilot = autopilot_->status();
  s.commands_published = commands_;
  s.imu_rejected = imu_rejected_;
  s.imu_repeated = imu_repeated_;
  s.poses_rejected = poses_rejected_;
  s.imu_rate_hz = imu_rate_.Rate(now_ns);
  s.pose_rate_hz = pose_rate_.Rate(now_ns);
  s.lockstep_frames_missed = lockstep_frames_missed_;
  for (const LockstepSource& l : lockstep_) s.lockstep_source_silent |= l.enabled && l.silent;
  s.loop_ms = loop_ms_.Summary();
  s.pose_latency = pose_latency_.Summary();
  s.last_error = last_error_.text();
  s.last_error_age_s = last_error_.AgeS(now_ns);
  s.imu_publishers_alive = imu_publishers_alive_;
  s.takeover_pending = takeover_pending_;
  if (have_imu_) s.imu_age_s = NsToSeconds(now_ns - last_imu_wall_ns_);
  if (autopilot_.has_value() && autopilot_->estimator().initialized()) {
    s.pose_age_s = NsToSeconds(last_imu_t_ns_ - autopilot_->last_pose_arrival_ns());
  }
  s.estimator_stale = StaleLocked(now_ns);
  if (s.estimator_stale) s.autopilot.estimator_converged = false;
  return s;
}

bool ControlCore::StaleLocked(int64_t now_wall_ns) const {
  if (!autopilot_.has_value() || !have_imu_) return false;  // never fed: not converged anyway
  if (imu_publisher_seen_ && imu_publishers_alive_ == 0) return true;
  if (!config_->lockstep && now_wall_ns - last_imu_wall_ns_ > SecondsToNs(kStaleImuS)) return true;
  return autopilot_->estimator().initialized() &&
         last_imu_t_ns_ - autopilot_->last_pose_arrival_ns() >
             SecondsToNs(config_->autopilot.pose_timeout_s);
}

ControlCoreState ControlCore::GetState() const {
  std::lock_guard<std::mutex> lock(mutex_);
  ControlCoreState s;
  s.configured = autopilot_.has_value();
  if (!autopilot_.has_value()) return s;
  s.armed = autopilot_->armed();
  s.autopilot = autopilot_->state();
  s.last_pose_t_ns = autopilot_->estimator().counters().last_pose_t_ns;
  s.last_pose_delay_ms = static_cast<double>(last_pose_delay_ns_) * 1e-6;
  s.estimator_initialized = autopilot_->estimator().initialized();
  s.last_pose_arrival_ns = autopilot_->last_pose_arrival_ns();
  s.poses_gated = autopilot_->estimator().counters().poses_rejected;
  const control::Estimator& estimator = autopilot_->estimator();
  for (size_t i = 0; i < estimator.options().pose_sources.size(); ++i) {
    s.source_frames.push_back(estimator.source_frame(static_cast<int>(i)));
  }
  s.moving = autopilot_->moving();
  return s;
}

}  // namespace mav::control_service
