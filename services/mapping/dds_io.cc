#include "services/mapping/dds_io.h"

#include <cstring>

#include "mav/common/log.h"
#include "services/common/dds_codec.h"
#include "services/common/dds_topics.h"

namespace mav::mapping_service {

namespace {

constexpr int32_t kPoseBatch = 512;

}  // namespace

Result<geometry::SE3> PoseFromDds(const mav_dds_GroundTruthState& state) {
  return service_common::PoseFromDds(state.position, state.orientation);
}

Result<std::optional<geometry::SE3>> BodyPoseFromDds(const mav_dds_PoseWithCovariance& pose,
                                                     const geometry::SE3& T_body_cam0) {
  if (pose.tracking_state != mav_dds_TRACKING_STATE_OK &&
      pose.tracking_state != mav_dds_TRACKING_STATE_INITIALIZING) {
    return std::optional<geometry::SE3>();
  }
  MAV_ASSIGN_OR_RETURN(const geometry::SE3 T_world_child,
                       service_common::PoseFromDds(pose.position, pose.orientation));
  if (std::strcmp(pose.child_frame_id, "cam0") == 0) {
    return std::optional<geometry::SE3>(
        geometry::BodyPoseFromSensorPose(T_world_child, T_body_cam0));
  }
  return std::optional<geometry::SE3>(T_world_child);
}

// ---- DdsIo --------------------------------------------------------------------------------------

Result<std::unique_ptr<DdsIo>> DdsIo::Create(const transport::DdsOptions& options) {
  MAV_ASSIGN_OR_RETURN(transport::Participant participant, transport::Participant::Create(options));
  MAV_ASSIGN_OR_RETURN(StereoTopic stereo_topic,
                       service_common::OpenTopic<mav_dds_StereoFrame>(participant));
  MAV_ASSIGN_OR_RETURN(GroundTruthTopic ground_truth_topic,
                       service_common::OpenTopic<mav_dds_GroundTruthState>(participant));
  MAV_ASSIGN_OR_RETURN(PoseTopic pose_topic,
                       service_common::OpenTopic<mav_dds_PoseWithCovariance>(participant));
  return std::unique_ptr<DdsIo>(new DdsIo(std::move(participant), std::move(stereo_topic),
                                          std::move(ground_truth_topic), std::move(pose_topic)));
}

DdsIo::DdsIo(transport::Participant participant, StereoTopic stereo_topic,
             GroundTruthTopic ground_truth_topic, PoseTopic pose_topic)
    : participant_(std::move(participant)),
      stereo_topic_(std::move(stereo_topic)),
      ground_truth_topic_(std::move(ground_truth_topic)),
      pose_topic_(std::move(pose_topic)) {}

DdsIo::~DdsIo() {
  std::lock_guard<std::mutex> lock(control_mutex_);
  StopReaderLocked();
}

bool DdsIo::input_enabled() const {
  std::lock_guard<std::mutex> lock(control_mutex_);
  return stereo_reader_.has_value();
}

void DdsIo::StopReaderLocked() {
  read_loop_.reset();  // joins the loop before its readers go
  stereo_reader_.reset();
  ground_truth_reader_.reset();
  pose_reader_.reset();
}

Status DdsIo::SetInput(bool enabled) {
  std::lock_guard<std::mutex> lock(control_mutex_);
  if (enabled && mapper_ == nullptr) return Status::FailedPrecondition("DDS input: no mapper");
  const std::optional<SessionConfig> session =
      mapper_ != nullptr ? mapper_->config() : std::nullopt;
  if (enabled && !session) return Status::FailedPrecondition("DDS input: no session");
  // Always rebuilt on enable: the session's pose source may have changed.
  StopReaderLocked();
  if (!enabled) {
    MAV_LOG(kInfo) << "DDS input off (" << frames_received_.load() << " frames, "
                   << poses_received_.load() << " poses received, " << poses_rejected_.load()
                   << " rejected)";
    return Status::Ok();
  }
  // All or nothing: a reader or the loop that fails to start leaves the input off.
  Status started = StartInputLocked(*session);
  if (!started.ok()) StopReaderLocked();
  return started;
}

Status DdsIo::StartInputLocked(const SessionConfig& session) {
  const PoseSource source = session.pose_source;
  using transport::Qos;
  MAV_ASSIGN_OR_RETURN(auto stereo, transport::Reader<mav_dds_StereoFrame>::Create(
                                        participant_, stereo_topic_, Qos::SensorStream()));
  stereo_reader_.emplace(std::move(stereo));
  if (source == PoseSource::kGroundTruth) {
    MAV_ASSIGN_OR_RETURN(auto reader, transport::Reader<mav_dds_GroundTruthState>::Create(
                                          participant_, ground_truth_topic_, Qos::State()));
    ground_truth_reader_.emplace(std::move(reader));
  } else if (source == PoseSource::kLocalization) {
    MAV_ASSIGN_OR_RETURN(auto reader, transport::Reader<mav_dds_PoseWithCovariance>::Create(
                                          participant_, pose_topic_, Qos::State()));
    pose_reader_.emplace(std::move(reader));
  }
  read_loop_.emplace("mapping input");
  // Poses first, so that a frame finds the poses published before it.
  if (ground_truth_reader_) {
    read_loop_->AddReader<mav_dds_GroundTruthState>(
        &*ground_truth_reader_,
        [this](const mav_dds_GroundTruthState& state) {
          ++poses_received_;
          Result<geometry::SE3> T_world_body = PoseFromDds(state);
          if (!T_world_body.ok()) {
            RejectPose(T_world_body.status());
            return;
          }
          mapper_->SubmitPose(state.t_ns, *T_world_body);
        },
        kPoseBatch);
  }
  if (pose_reader_) {
    // The same session as the pose source: its rig.
    const geometry::SE3 T_body_cam0 = session.calibration.T_body_cam0;
    read_loop_->AddReader<mav_dds_PoseWithCovariance>(
        &*pose_reader_,
        [this, T_body_cam0](const mav_dds_PoseWithCovariance& pose) {
          ++poses_received_;
          // A LOST pose is the last good one held, not the pose at its t_ns: ignored.
          Result<std::optional<geometry::SE3>> T_world_body = BodyPoseFromDds(pose, T_body_cam0);
          if (!T_world_body.ok()) {
            RejectPose(T_world_body.status());
          } else if (T_world_body->has_value()) {
            mapper_->SubmitPose(pose.t_ns, **T_world_body);
          }
        },
        kPoseBatch);
  }
  read_loop_->SetWakeReader<mav_dds_StereoFrame>(
      &*stereo_reader_, [this](const mav_dds_StereoFrame& frame) { OnFrame(frame); }, 4);
  read_loop_->SetOnPoll([this] { mapper_->Tick(); });
  MAV_RETURN_IF_ERROR(read_loop_->Start());
  MAV_LOG(kInfo) << "DDS input on: " << transport::kStereoTopic << " + poses from "
                 << PoseSourceName(source);
  return Status::Ok();
}

void DdsIo::RejectPose(const Status& why) {
  const uint64_t n = ++poses_rejected_;
  // The first and then every 100th: a publisher with a bug sends hundreds a second.
  if (n == 1 || n % 100 == 0) {
    MAV_LOG(kWarning) << "pose rejected (" << n << " so far): " << why.message();
  }
}

void DdsIo::OnFrame(const mav_dds_StereoFrame& frame) {
  ++frames_received_;
  const Status check = service_common::CheckStereoFrame(frame);
  if (!check.ok()) {
    MAV_LOG(kWarning) << "rejected: " << check.message();
    mapper_->CountRejected();
    return;
  }
  mapper_->SubmitLiveFrame(service_common::StereoFromDds(frame));
}

}  // namespace mav::mapping_service
