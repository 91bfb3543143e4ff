#include "services/localization/dds_io.h"

#include <cstring>

#include "mav/common/log.h"
#include "mav/common/time.h"

namespace mav::localization_service {

using services::CopyId;

namespace {

constexpr int64_t kReaderPollNs = 100'000'000;

}  // namespace

StereoInput FromDds(const mav_dds_StereoFrame& frame) {
  services::StereoImages images = services::StereoFromDds(frame);
  StereoInput out;
  out.t_ns = images.t_ns;
  out.rectified = images.rectified;
  out.left = std::move(images.left);
  out.right = std::move(images.right);
  return out;
}

mav_dds_PoseWithCovariance ToDds(uint64_t sequence, const PoseOutput& pose, OutputFrame frame,
                                 int64_t publish_t_ns) {
  mav_dds_PoseWithCovariance out{};
  out.vehicle_id = mav_dds_kDefaultVehicleId;
  out.sequence_number = sequence;
  out.t_ns = pose.t_ns;
  out.publish_t_ns = publish_t_ns;
  CopyId("world", out.frame_id);
  CopyId(OutputFrameName(frame), out.child_frame_id);
  const Eigen::Vector3d& t = pose.T_world_out.Translation();
  out.position = {t.x(), t.y(), t.z()};
  const Eigen::Quaterniond& q = pose.T_world_out.Rotation();
  out.orientation = {q.w(), q.x(), q.y(), q.z()};
  for (int i = 0; i < 36; ++i) out.covariance[i] = pose.covariance[i];
  out.tracking_state = static_cast<mav_dds_TrackingState>(static_cast<int>(pose.state));
  out.inliers = pose.inliers;
  out.processing_ms = pose.timing.total_ms;
  return out;
}

// ---- DdsIo --------------------------------------------------------------------------------------

Result<std::unique_ptr<DdsIo>> DdsIo::Create(const transport::DdsOptions& options) {
  using transport::Qos;
  MAV_ASSIGN_OR_RETURN(transport::Participant participant, transport::Participant::Create(options));
  MAV_ASSIGN_OR_RETURN(
      StereoTopic stereo_topic,
      StereoTopic::Create(participant, transport::kStereoTopic, &mav_dds_StereoFrame_desc));
  MAV_ASSIGN_OR_RETURN(ImuTopic imu_topic, ImuTopic::Create(participant, transport::kImuTopic,
                                                            &mav_dds_ImuSample_desc));
  MAV_ASSIGN_OR_RETURN(PoseTopic pose_topic, PoseTopic::Create(participant, transport::kPoseTopic,
                                                               &mav_dds_PoseWithCovariance_desc));
  MAV_ASSIGN_OR_RETURN(auto pose_writer, transport::Writer<mav_dds_PoseWithCovariance>::Create(
                                             participant, pose_topic, Qos::State()));
  return std::unique_ptr<DdsIo>(new DdsIo(std::move(participant), std::move(stereo_topic),
                                          std::move(imu_topic), std::move(pose_topic),
                                          std::move(pose_writer)));
}

DdsIo::DdsIo(transport::Participant participant, StereoTopic stereo_topic, ImuTopic imu_topic,
             PoseTopic pose_topic, transport::Writer<mav_dds_PoseWithCovariance> pose_writer)
    : participant_(std::move(participant)),
      stereo_topic_(std::move(stereo_topic)),
      imu_topic_(std::move(imu_topic)),
      pose_topic_(std::move(pose_topic)),
      pose_writer_(std::move(pose_writer)) {}

DdsIo::~DdsIo() {
  std::lock_guard<std::mutex> lock(control_mutex_);
  StopReaderLocked();
}

Status DdsIo::PublishPose(const PoseOutput& pose, OutputFrame frame) {
  const uint64_t sequence = pose_sequence_.fetch_add(1);
  return pose_writer_.Write(ToDds(sequence, pose, frame, WallNowNs()));
}

uint32_t DdsIo::PoseSubscribers() {
  Result<uint32_t> n = pose_writer_.MatchedReaders();
  return n.ok() ? *n : 0;
}

bool DdsIo::stereo_input() const {
  std::lock_guard<std::mutex> lock(control_mutex_);
  return stereo_reader_.has_value();
}

void DdsIo::StopReaderLocked() {
  if (reader_thread_.joinable()) {
    stop_reader_ = true;
    reader_thread_.join();
  }
  stereo_reader_.reset();
  imu_reader_.reset();
}

Status DdsIo::SetStereoInput(bool enabled) {
  std::lock_guard<std::mutex> lock(control_mutex_);
  if (enabled == stereo_reader_.has_value()) return Status::Ok();
  if (enabled && localizer_ == nullptr) {
    return Status::FailedPrecondition("DDS input: no localizer attached");
  }
  if (!enabled) {
    StopReaderLocked();
    MAV_LOG(kInfo) << "DDS input off (" << frames_received_.load() << " frames, "
                   << imu_received_.load() << " IMU samples received)";
    return Status::Ok();
  }
  using transport::Qos;
  MAV_ASSIGN_OR_RETURN(auto stereo, transport::Reader<mav_dds_StereoFrame>::Create(
                                        participant_, stereo_topic_, Qos::SensorStream()));
  MAV_ASSIGN_OR_RETURN(auto imu, transport::Reader<mav_dds_ImuSample>::Create(
                                     participant_, imu_topic_, Qos::HighRate()));
  stereo_reader_.emplace(std::move(stereo));
  imu_reader_.emplace(std::move(imu));
  stop_reader_ = false;
  reader_thread_ = std::thread([this] { ReadLoop(); });
  MAV_LOG(kInfo) << "DDS input on: " << transport::kStereoTopic << ", " << transport::kImuTopic;
  return Status::Ok();
}

// The readers are not replaced while this thread runs (SetStereoInput joins it first).
void DdsIo::ReadLoop() {
  while (!stop_reader_) {
    Result<bool> ready = stereo_reader_->WaitForData(kReaderPollNs);
    if (!ready.ok()) {
      MAV_LOG(kWarning) << ready.status().ToString();
      continue;
    }
    // IMU: counted (the VO is vision-only); the history (2 s) outlasts the poll period.
    Result<transport::LoanedSamples<mav_dds_ImuSample>> imu = imu_reader_->Take(256);
    if (imu.ok()) {
      for (int32_t i = 0; i < imu->size(); ++i) {
        if (imu->valid(i)) ++imu_received_;
      }
    }
    if (!*ready) continue;
    Result<transport::LoanedSamples<mav_dds_StereoFrame>> frames = stereo_reader_->Take(4);
    if (!frames.ok()) {
      MAV_LOG(kWarning) << frames.status().ToString();
      continue;
    }
    for (int32_t i = 0; i < frames->size(); ++i) {
      if (!frames->valid(i)) continue;
      ++frames_received_;
      const mav_dds_StereoFrame& frame = (*frames)[i];
      const Status check = CheckStereoFrame(frame);
      if (!check.ok()) {
        MAV_LOG(kWarning) << "rejected: " << check.message();
        localizer_->CountRejected();
        continue;
      }
      const SubmitOutcome outcome = localizer_->SubmitLive(FromDds(frame));
      if (outcome == SubmitOutcome::kQueuedDroppedOldest || outcome == SubmitOutcome::kDropped) {
        MAV_LOG(kDebug) << "queue full: dropped a frame";
      }
    }
  }
}

}  // namespace mav::localization_service
