#include "services/localization/dds_io.h"

#include <cstring>

#include "mav/common/log.h"
#include "mav/common/time.h"
#include "services/common/dds_topics.h"

namespace mav::localization_service {

using service_common::CopyId;

mav_dds_PoseWithCovariance ToDds(uint64_t sequence, const RigPose& pose, OutputFrame frame,
                                 int64_t publish_t_ns) {
  mav_dds_PoseWithCovariance out = service_common::PoseToDds(
      sequence, pose.t_ns, publish_t_ns, localization::OutputFrameName(frame), pose.T_world_out);
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
  MAV_ASSIGN_OR_RETURN(StereoTopic stereo_topic,
                       service_common::OpenTopic<mav_dds_StereoFrame>(participant));
  MAV_ASSIGN_OR_RETURN(ImuTopic imu_topic,
                       service_common::OpenTopic<mav_dds_ImuSample>(participant));
  MAV_ASSIGN_OR_RETURN(PoseTopic pose_topic,
                       service_common::OpenTopic<mav_dds_PoseWithCovariance>(participant));
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

Status DdsIo::PublishPose(const RigPose& pose, OutputFrame frame) {
  const uint64_t sequence = pose_sequence_.fetch_add(1);
  mav_dds_PoseWithCovariance sample = ToDds(sequence, pose, frame, WallNowNs());
  {
    std::lock_guard<std::mutex> lock(stamps_mutex_);
    for (const FrameStamps& s : stamps_) {
      if (s.t_ns == pose.t_ns) {
        sample.frame_publish_t_ns = s.publish_ns;
        sample.frame_receive_t_ns = s.receive_ns;
        break;
      }
    }
  }
  return pose_writer_.Write(sample);
}

uint32_t DdsIo::PoseSubscribers() {
  Result<uint32_t> n = pose_writer_.MatchedReaders();
  return n.ok() ? *n : 0;
}

bool DdsIo::input_enabled() const {
  std::lock_guard<std::mutex> lock(control_mutex_);
  return stereo_reader_.has_value();
}

void DdsIo::StopReaderLocked() {
  read_loop_.reset();  // joins the loop before its readers go
  stereo_reader_.reset();
  imu_reader_.reset();
}

Status DdsIo::SetInput(bool enabled) {
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
  read_loop_.emplace("localization input");
  // IMU: the gyro goes to the localizer (dense VO); its history (2 s) outlasts the poll period.
  read_loop_->AddReader<mav_dds_ImuSample>(&*imu_reader_, [this](const mav_dds_ImuSample& s) {
    ++imu_received_;
    if (localizer_ != nullptr) {
      localizer_->AddGyro(s.t_ns, Eigen::Vector3d(s.gyro.x, s.gyro.y, s.gyro.z));
    }
  });
  read_loop_->SetWakeReader<mav_dds_StereoFrame>(
      &*stereo_reader_, [this](const mav_dds_StereoFrame& frame) { OnFrame(frame); }, 4);
  MAV_RETURN_IF_ERROR(read_loop_->Start());
  MAV_LOG(kInfo) << "DDS input on: " << transport::kStereoTopic << ", " << transport::kImuTopic;
  return Status::Ok();
}

void DdsIo::OnFrame(const mav_dds_StereoFrame& frame) {
  const int64_t receive_ns = WallNowNs();
  ++frames_received_;
  const Status check = CheckStereoFrame(frame);
  if (!check.ok()) {
    MAV_LOG(kWarning) << "rejected: " << check.message();
    localizer_->CountRejected();
    return;
  }
  {
    std::lock_guard<std::mutex> lock(stamps_mutex_);
    stamps_[next_stamp_] = FrameStamps{frame.t_ns, frame.publish_t_ns, receive_ns};
    next_stamp_ = (next_stamp_ + 1) % kStampedFrames;
  }
  const Status queued = localizer_->SubmitLive(StereoInput(service_common::StereoFromDds(frame)));
  if (!queued.ok()) {
    MAV_LOG(kDebug) << "live frame not queued: " << queued.message();
  }
}

}  // namespace mav::localization_service
