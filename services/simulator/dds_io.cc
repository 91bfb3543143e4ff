#include "services/simulator/dds_io.h"

#include <cstring>

#include "mav/common/check.h"
#include "mav/common/time.h"
#include "services/common/dds_topics.h"

namespace mav::simulator_service {

using service_common::CopyId;

namespace {

mav_dds_Vector3 ToDds(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
Eigen::Vector3d FromDds(const mav_dds_Vector3& v) { return {v.x, v.y, v.z}; }

}  // namespace

void FillStereoFrame(uint64_t sequence, const RenderedFrame& frame, bool rectified,
                     int64_t publish_t_ns, mav_dds_StereoFrame* out) {
  MAV_CHECK(frame.left.type() == CV_8UC1 && frame.right.type() == CV_8UC1)
      << "stereo images must be CV_8UC1";
  MAV_CHECK(frame.left.size() == frame.right.size()) << "left and right sizes differ";
  MAV_CHECK(frame.left.isContinuous() && frame.right.isContinuous());
  std::memset(out, 0, sizeof(*out));
  out->rig_id = mav_dds_kDefaultRigId;
  out->sequence_number = sequence;
  out->t_ns = frame.t_ns;
  out->publish_t_ns = publish_t_ns;
  CopyId("cam0", out->left_camera_id);
  CopyId("cam1", out->right_camera_id);
  out->width = static_cast<uint32_t>(frame.left.cols);
  out->height = static_cast<uint32_t>(frame.left.rows);
  out->encoding = mav_dds_PIXEL_FORMAT_MONO8;
  out->rectified = rectified;
  const uint32_t n = out->width * out->height;
  out->left._buffer = const_cast<uint8_t*>(frame.left.ptr<uint8_t>());
  out->left._length = out->left._maximum = n;
  out->left._release = false;
  out->right._buffer = const_cast<uint8_t*>(frame.right.ptr<uint8_t>());
  out->right._length = out->right._maximum = n;
  out->right._release = false;
  out->crc32 = StereoCrc32(out->left._buffer, n, out->right._buffer, n);
}

mav_dds_ImuSample ToDds(uint64_t sequence, const dataset::ImuSample& sample, int64_t publish_t_ns) {
  mav_dds_ImuSample out{};
  out.imu_id = mav_dds_kDefaultImuId;
  out.sequence_number = sequence;
  out.t_ns = sample.t_ns;
  out.publish_t_ns = publish_t_ns;
  out.gyro = ToDds(sample.gyro);
  out.accel = ToDds(sample.accel);
  return out;
}

mav_dds_GroundTruthState ToDds(uint64_t sequence, const dataset::GroundTruthState& state,
                               int64_t publish_t_ns) {
  mav_dds_GroundTruthState out{};
  out.vehicle_id = mav_dds_kDefaultVehicleId;
  out.sequence_number = sequence;
  out.t_ns = state.t_ns;
  out.publish_t_ns = publish_t_ns;
  out.position = ToDds(state.T_world_body.Translation());
  const Eigen::Quaterniond& q = state.T_world_body.Rotation();
  out.orientation = {q.w(), q.x(), q.y(), q.z()};
  out.velocity = ToDds(state.v_world);
  out.gyro_bias = ToDds(state.gyro_bias);
  out.accel_bias = ToDds(state.accel_bias);
  return out;
}

dataset::ImuSample FromDds(const mav_dds_ImuSample& sample) {
  dataset::ImuSample out;
  out.t_ns = sample.t_ns;
  out.gyro = FromDds(sample.gyro);
  out.accel = FromDds(sample.accel);
  return out;
}

dataset::GroundTruthState FromDds(const mav_dds_GroundTruthState& state) {
  dataset::GroundTruthState out;
  out.t_ns = state.t_ns;
  const Eigen::Quaterniond q(state.orientation.w, state.orientation.x, state.orientation.y,
                             state.orientation.z);
  out.T_world_body = geometry::SE3(q, FromDds(state.position));
  out.v_world = FromDds(state.velocity);
  out.gyro_bias = FromDds(state.gyro_bias);
  out.accel_bias = FromDds(state.accel_bias);
  return out;
}

// ---- DdsStreamSink ----------------------------------------------------------------------------

Result<std::unique_ptr<DdsStreamSink>> DdsStreamSink::Create(const transport::DdsOptions& options) {
  using transport::Qos;
  MAV_ASSIGN_OR_RETURN(transport::Participant participant, transport::Participant::Create(options));
  MAV_ASSIGN_OR_RETURN(StereoTopic stereo_topic,
                       service_common::OpenTopic<mav_dds_StereoFrame>(participant));
  MAV_ASSIGN_OR_RETURN(ImuTopic imu_topic,
                       service_common::OpenTopic<mav_dds_ImuSample>(participant));
  MAV_ASSIGN_OR_RETURN(GtTopic gt_topic,
                       service_common::OpenTopic<mav_dds_GroundTruthState>(participant));
  MAV_ASSIGN_OR_RETURN(auto stereo, transport::Writer<mav_dds_StereoFrame>::Create(
                                        participant, stereo_topic, Qos::SensorStream()));
  MAV_ASSIGN_OR_RETURN(auto imu, transport::Writer<mav_dds_ImuSample>::Create(
                                     participant, imu_topic, Qos::HighRate()));
  MAV_ASSIGN_OR_RETURN(auto gt, transport::Writer<mav_dds_GroundTruthState>::Create(
                                    participant, gt_topic, Qos::State()));
  return std::unique_ptr<DdsStreamSink>(
      new DdsStreamSink(std::move(participant), std::move(stereo_topic), std::move(imu_topic),
                        std::move(gt_topic), std::move(stereo), std::move(imu), std::move(gt)));
}

Status DdsStreamSink::PublishStereo(uint64_t sequence, const RenderedFrame& frame, bool rectified) {
  mav_dds_StereoFrame sample;
  FillStereoFrame(sequence, frame, rectified, WallNowNs(), &sample);
  return stereo_.Write(sample);
}

Status DdsStreamSink::PublishImu(uint64_t sequence, const dataset::ImuSample& sample) {
  return imu_.Write(ToDds(sequence, sample, WallNowNs()));
}

Status DdsStreamSink::PublishGroundTruth(uint64_t sequence,
                                         const dataset::GroundTruthState& state) {
  return gt_.Write(ToDds(sequence, state, WallNowNs()));
}

Status DdsStreamSink::WaitForStereoAcks(int64_t timeout_ns) {
  return stereo_.WaitForAcks(timeout_ns);
}

uint32_t DdsStreamSink::StereoSubscribers() {
  Result<uint32_t> n = stereo_.MatchedReaders();
  return n.ok() ? *n : 0;
}

uint32_t DdsStreamSink::ImuSubscribers() {
  Result<uint32_t> n = imu_.MatchedReaders();
  return n.ok() ? *n : 0;
}

}  // namespace mav::simulator_service
