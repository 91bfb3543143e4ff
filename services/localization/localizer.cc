#include "services/localization/localizer.h"

#include <algorithm>
#include <utility>

#include "mav/common/log.h"
#include "mav/common/time.h"

namespace mav::localization_service {

namespace {

constexpr int64_t kFpsWindowNs = 2'000'000'000;
constexpr size_t kStatsWindow = 1000;

std::string SizeText(int width, int height) {
  return std::to_string(width) + "x" + std::to_string(height);
}

WorkQueueOptions QueueOptions() {
  WorkQueueOptions o = WorkQueueOptions::Named("localization", 2);
  o.stats_window = kStatsWindow;
  return o;
}

}  // namespace

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

bool LocalizerConfig::IsValid(std::string* why) const {
  if (queue_length < 1 || queue_length > 100) {
    if (why != nullptr) {
      *why = "queue_length: must be in [1, 100], got " + std::to_string(queue_length);
    }
    return false;
  }
  return odometry.IsValid(why);
}

Localizer::Localizer(PoseSink* sink, size_t max_trajectory_poses)
    : sink_(sink),
      max_trajectory_poses_(std::max<size_t>(1, max_trajectory_poses)),
      queue_(QueueOptions()),
      processing_ms_(kStatsWindow) {}

Localizer::~Localizer() { Shutdown(); }

void Localizer::Shutdown() { queue_.Stop("the localization service is shutting down"); }

void Localizer::ClearHistoryLocked() {
  have_accepted_ = false;
  last_accepted_t_ns_ = 0;
  trajectory_.clear();
  frames_processed_ = frames_dropped_ = frames_lost_ = frames_rejected_ = 0;
  frames_degraded_ = gyro_samples_ = 0;
  poses_forgotten_ = keyframes_ = 0;
  done_wall_ns_.clear();
  processing_ms_.Clear();
}

Status Localizer::Configure(const LocalizerConfig& config, const Termination& deadline) {
  std::string why;
  if (!config.IsValid(&why)) return Status::InvalidArgument(why);
  // Rectification maps and the VO are built before the worker is interrupted.
  MAV_ASSIGN_OR_RETURN(std::unique_ptr<localization::RigOdometry> built,
                       localization::RigOdometry::Create(config.odometry));
  MAV_RETURN_IF_ERROR(deadline.Check("Configure"));
  auto odometry = std::make_shared<std::unique_ptr<localization::RigOdometry>>(std::move(built));
  Ticket<Status> ticket = queue_.SubmitAfterReset<Status>(
      [this, odometry, config](const TaskContext&) {
        odometry_ = std::move(*odometry);
        const camera::RectifiedStereo& rig = odometry_->rig();
        MAV_LOG(kInfo) << "configured " << localization::MethodName(config.odometry.method) << ", "
                       << SizeText(rig.width, rig.height) << " rectified rig, fx " << rig.fx
                       << ", baseline " << rig.baseline << " m, queue " << config.queue_length;
        std::lock_guard<std::mutex> lock(mutex_);
        config_ = config;
        ClearHistoryLocked();
        return Status::Ok();
      },
      "the service was reconfigured", deadline);
  MAV_RETURN_IF_ERROR(ticket.Wait());
  queue_.SetCapacity(static_cast<size_t>(config.queue_length));
  return Status::Ok();
}

Status Localizer::Reset(const std::optional<geometry::SE3>& T_world_body0,
                        const Termination& deadline) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!config_.has_value())
      return Status::FailedPrecondition("not configured: call Configure first");
    have_accepted_ = false;
  }
  MAV_RETURN_IF_ERROR(deadline.Check("Reset"));
  Ticket<Status> ticket = queue_.SubmitAfterReset<Status>(
      [this, T_world_body0](const TaskContext&) {
        if (odometry_ != nullptr) odometry_->Reset(T_world_body0);
        std::lock_guard<std::mutex> lock(mutex_);
        ClearHistoryLocked();
        return Status::Ok();
      },
      "the service was reset", deadline);
  return ticket.Wait();
}

Status Localizer::CheckInput(const StereoInput& input, const std::string& field_prefix) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return CheckInputLocked(input, field_prefix);
}

Status Localizer::CheckInputLocked(const StereoInput& input,
                                   const std::string& field_prefix) const {
  if (!config_.has_value())
    return Status::FailedPrecondition("not configured: call Configure first");
  const int width = config_->odometry.calibration.cam0.width;
  const int height = config_->odometry.calibration.cam0.height;
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

Ticket<Result<RigPose>> Localizer::Submit(StereoInput input, QueuePolicy policy,
                                          const Termination& deadline) {
  const int64_t t_ns = input.t_ns;
  Ticket<Result<RigPose>> ticket = queue_.Submit<Result<RigPose>>(
      [this, input = std::move(input)](const TaskContext&) { return ProcessOnWorker(input); },
      policy, deadline);
  if (ticket.accepted()) {
    std::lock_guard<std::mutex> lock(mutex_);
    have_accepted_ = true;
    last_accepted_t_ns_ = std::max(last_accepted_t_ns_, t_ns);
  }
  return ticket;
}

Status Localizer::SubmitLive(StereoInput input) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    Status check = CheckInputLocked(input, "stereo");
    if (!check.ok()) {
      if (!config_.has_value()) return check;
      ++frames_rejected_;
      MAV_LOG(kWarning) << "rejected a DDS frame: " << check.message();
      return check;
    }
  }
  const Ticket<Result<RigPose>> ticket =
      Submit(std::move(input), QueuePolicy::kDropOldest, Termination::Never());
  if (!ticket.accepted() || ticket.dropped_oldest()) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++frames_dropped_;
  }
  return ticket.submit_status();
}

Result<RigPose> Localizer::Process(StereoInput input, const Termination& deadline) {
  MAV_RETURN_IF_ERROR(CheckInput(input, "stereo"));
  MAV_RETURN_IF_ERROR(deadline.Check("ProcessStereoPair"));
  const int64_t t_ns = input.t_ns;
  bool had_accepted = false;
  int64_t previous_t_ns = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    had_accepted = have_accepted_;
    previous_t_ns = last_accepted_t_ns_;
  }
  Ticket<Result<RigPose>> ticket = Submit(std::move(input), QueuePolicy::kReject, deadline);
  Result<RigPose> pose = ticket.Wait(deadline);
  if (ticket.accepted() && !ticket.ran()) {
    // Withdrawn: the frame changed nothing, so a retry of the same time stamp is welcome.
    std::lock_guard<std::mutex> lock(mutex_);
    if (have_accepted_ && last_accepted_t_ns_ == t_ns) {
      have_accepted_ = had_accepted;
      last_accepted_t_ns_ = previous_t_ns;
    }
  }
  return pose;
}

void Localizer::AddGyro(int64_t t_ns, const Eigen::Vector3d& omega_imu) {
  std::lock_guard<std::mutex> lock(mutex_);
  const Eigen::Quaterniond R_body_imu =
      config_.has_value() ? config_->R_body_imu : Eigen::Quaterniond::Identity();
  pending_gyro_.push_back({t_ns, R_body_imu * omega_imu});
  while (pending_gyro_.size() > localization::RigOdometry::kGyroHistory) pending_gyro_.pop_front();
}

// On the worker: the odometry is ours.
Result<RigPose> Localizer::ProcessOnWorker(const StereoInput& input) {
  if (odometry_ == nullptr)
    return Status::FailedPrecondition("not configured: call Configure first");
  std::deque<localization::GyroSample> gyro;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    gyro.swap(pending_gyro_);
  }
  for (const localization::GyroSample& g : gyro) odometry_->AddGyro(g.t_ns, g.omega);
  Result<RigPose> pose = odometry_->Process(input.t_ns, input.left, input.right, input.rectified);
  if (!pose.ok()) {
    MAV_LOG(kWarning) << "frame " << input.t_ns << ": " << pose.status().ToString();
    return pose;
  }
  // Logged when tracking enters LOST or DEGRADED (not for every frame of a long loss).
  if (pose->state != last_logged_state_ &&
      (pose->state == ReportedState::kDegraded || pose->state == ReportedState::kLost)) {
    MAV_LOG(kInfo) << "frame " << input.t_ns << " " << localization::ReportedStateName(pose->state)
                   << (pose->gyro_used ? " (gyro)" : " (no gyro)") << ": " << pose->lost_reason;
  }
  last_logged_state_ = pose->state;
  // Recorded before it is published, so that whoever receives the pose on DDS finds it in
  // GetStatus/GetTrajectory.
  {
    std::lock_guard<std::mutex> lock(mutex_);
    trajectory_.push_back(*pose);
    if (trajectory_.size() > max_trajectory_poses_) {
      trajectory_.pop_front();
      ++poses_forgotten_;
    }
    ++frames_processed_;
    processing_ms_.Add(pose->timing.total_ms);
    if (pose->state == ReportedState::kLost) ++frames_lost_;
    if (pose->state == ReportedState::kDegraded) ++frames_degraded_;
    gyro_samples_ += gyro.size();
    if (pose->keyframe) ++keyframes_;
    const int64_t now = MonotonicNowNs();
    done_wall_ns_.push_back(now);
    while (!done_wall_ns_.empty() && now - done_wall_ns_.front() > kFpsWindowNs) {
      done_wall_ns_.pop_front();
    }
  }
  if (input.publish && sink_ != nullptr) {
    const Status published = sink_->PublishPose(*pose, odometry_->options().output_frame);
    if (!published.ok()) {
      MAV_LOG(kWarning) << "publishing a pose: " << published.message();
    }
  }
  return pose;
}

bool Localizer::configured() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return config_.has_value();
}

LocalizerStatus Localizer::GetStatus() const {
  const WorkQueueStats queue = queue_.GetStats();
  std::lock_guard<std::mutex> lock(mutex_);
  LocalizerStatus out;
  if (!config_.has_value()) return out;
  out.config = config_;
  out.state = frames_processed_ == 0 && !queue.busy && queue.depth == 0 ? LocalizerState::kReady
                                                                        : LocalizerState::kRunning;
  out.frames_processed = frames_processed_;
  out.frames_dropped = frames_dropped_;
  out.frames_lost = frames_lost_;
  out.frames_degraded = frames_degraded_;
  out.gyro_samples = gyro_samples_;
  out.frames_rejected = frames_rejected_;
  out.poses_forgotten = poses_forgotten_;
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
  if (recent >= 2 && now > oldest) {
    out.fps = static_cast<double>(recent - 1) / NsToSeconds(now - oldest);
  }
  if (!trajectory_.empty()) out.last = trajectory_.back();
  out.processing_ms = processing_ms_.Summary();
  out.keyframes = keyframes_;
  out.queue_depth = static_cast<uint32_t>(queue.depth);
  return out;
}

std::vector<RigPose> Localizer::Trajectory(int64_t start_t_ns, int64_t end_t_ns) const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<RigPose> out;
  for (const RigPose& p : trajectory_) {
    if (start_t_ns != 0 && p.t_ns < start_t_ns) continue;
    if (end_t_ns != 0 && p.t_ns > end_t_ns) continue;
    out.push_back(p);
  }
  return out;
}

}  // namespace mav::localization_service
