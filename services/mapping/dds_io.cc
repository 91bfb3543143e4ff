#include "services/mapping/dds_io.h"

#include <cstring>

#include "mav/common/log.h"
#include "services/common/dds_codec.h"

namespace mav::mapping_service {

namespace {

constexpr int64_t kReaderPollNs = 100'000'000;
constexpr int32_t kPoseBatch = 512;

}  // namespace

FrameInput FromDds(const mav_dds_StereoFrame& frame) {
  service_common::StereoImages images = service_common::StereoFromDds(frame);
  FrameInput out;
  out.t_ns = images.t_ns;
  out.rectified = images.rectified;
  out.left = std::move(images.left);
  out.right = std::move(images.right);
  return out;
}

geometry::SE3 PoseFromDds(const mav_dds_GroundTruthState& state) {
  const auto& q = state.orientation;
  const auto& p = state.position;
  return geometry::SE3(Eigen::Quaterniond(q.w, q.x, q.y, q.z), Eigen::Vector3d(p.x, p.y, p.z));
}

geometry::SE3 PoseFromDds(const mav_dds_PoseWithCovariance& pose) {
  const auto& q = pose.orientation;
  const auto& p = pose.position;
  return geometry::SE3(Eigen::Quaterniond(q.w, q.x, q.y, q.z), Eigen::Vector3d(p.x, p.y, p.z));
}

// ---- DdsIo --------------------------------------------------------------------------------------

Result<std::unique_ptr<DdsIo>> DdsIo::Create(const transport::DdsOptions& options) {
  MAV_ASSIGN_OR_RETURN(transport::Participant participant, transport::Participant::Create(options));
  MAV_ASSIGN_OR_RETURN(
      StereoTopic stereo_topic,
      StereoTopic::Create(participant, transport::kStereoTopic, &mav_dds_StereoFrame_desc));
  MAV_ASSIGN_OR_RETURN(GroundTruthTopic ground_truth_topic,
                       GroundTruthTopic::Create(participant, transport::kGroundTruthTopic,
                                                &mav_dds_GroundTruthState_desc));
  MAV_ASSIGN_OR_RETURN(PoseTopic pose_topic, PoseTopic::Create(participant, transport::kPoseTopic,
                                                               &mav_dds_PoseWithCovariance_desc));
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
  if (reader_thread_.joinable()) {
    stop_reader_ = true;
    reader_thread_.join();
  }
  stereo_reader_.reset();
  ground_truth_reader_.reset();
  pose_reader_.reset();
}

Status DdsIo::SetInput(bool enabled, PoseSource source) {
  std::lock_guard<std::mutex> lock(control_mutex_);
  if (enabled && mapper_ == nullptr) return Status::FailedPrecondition("DDS input: no mapper");
  // Always rebuilt on enable: the pose source may have changed.
  StopReaderLocked();
  if (!enabled) {
    MAV_LOG(kInfo) << "DDS input off (" << frames_received_.load() << " frames, "
                   << poses_received_.load() << " poses received)";
    return Status::Ok();
  }
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
  stop_reader_ = false;
  reader_thread_ = std::thread([this] { ReadLoop(); });
  MAV_LOG(kInfo) << "DDS input on: " << transport::kStereoTopic << " + poses from "
                 << PoseSourceName(source);
  return Status::Ok();
}

void DdsIo::TakePoses() {
  if (ground_truth_reader_) {
    while (true) {
      auto samples = ground_truth_reader_->Take(kPoseBatch);
      if (!samples.ok() || samples->size() == 0) break;
      for (int32_t i = 0; i < samples->size(); ++i) {
        if (!samples->valid(i)) continue;
        ++poses_received_;
        mapper_->SubmitPose((*samples)[i].t_ns, PoseFromDds((*samples)[i]));
      }
      if (samples->size() < kPoseBatch) break;
    }
  }
  if (pose_reader_) {
    std::optional<geometry::SE3> T_body_cam0;
    while (true) {
      auto samples = pose_reader_->Take(kPoseBatch);
      if (!samples.ok() || samples->size() == 0) break;
      for (int32_t i = 0; i < samples->size(); ++i) {
        if (!samples->valid(i)) continue;
        const mav_dds_PoseWithCovariance& pose = (*samples)[i];
        ++poses_received_;
        if (pose.tracking_state != mav_dds_TRACKING_STATE_OK &&
            pose.tracking_state != mav_dds_TRACKING_STATE_INITIALIZING) {
          continue;
        }
        geometry::SE3 T_world_body = PoseFromDds(pose);
        if (std::strcmp(pose.child_frame_id, "cam0") == 0) {
          if (!T_body_cam0) {
            const std::optional<SessionConfig> config = mapper_->config();
            if (!config) continue;
            T_body_cam0 = config->calibration.T_body_cam0;
          }
          T_world_body = T_world_body * T_body_cam0->Inverse();
        }
        mapper_->SubmitPose(pose.t_ns, T_world_body);
      }
      if (samples->size() < kPoseBatch) break;
    }
  }
}

// The readers are not replaced while this thread runs (SetInput joins it first).
void DdsIo::ReadLoop() {
  while (!stop_reader_) {
    Result<bool> ready = stereo_reader_->WaitForData(kReaderPollNs);
    TakePoses();
    mapper_->Tick();
    if (!ready.ok()) {
      MAV_LOG(kWarning) << ready.status().ToString();
      continue;
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
      const Status check = service_common::CheckStereoFrame(frame);
      if (!check.ok()) {
        MAV_LOG(kWarning) << "rejected: " << check.message();
        mapper_->CountRejected();
        continue;
      }
      mapper_->SubmitLiveFrame(FromDds(frame));
    }
  }
}

}  // namespace mav::mapping_service
