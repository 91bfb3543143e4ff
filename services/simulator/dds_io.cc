#include "services/simulator/dds_io.h"

#include <algorithm>
#include <cstring>
#include <limits>

#include "mav/common/check.h"
#include "mav/common/log.h"
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
  out->crc32 = frame.crc32.has_value() ? *frame.crc32
                                       : StereoCrc32(out->left._buffer, n, out->right._buffer, n);
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

mav_dds_PoseWithCovariance ToDds(uint64_t sequence, const sim::PoseSample& pose,
                                 const std::string& frame_id, double position_sigma_m,
                                 double orientation_sigma_rad, int64_t publish_t_ns) {
  mav_dds_PoseWithCovariance out = service_common::PoseToDds(sequence, pose.t_ns, publish_t_ns,
                                                             frame_id.c_str(), pose.T_world_sensor);
  for (int i = 0; i < 3; ++i) {
    out.covariance[i * 7] = position_sigma_m * position_sigma_m;
    out.covariance[(i + 3) * 7] = orientation_sigma_rad * orientation_sigma_rad;
  }
  out.tracking_state = mav_dds_TRACKING_STATE_OK;
  return out;
}

ActuatorInput FromDds(const mav_dds_ActuatorCommand& command) {
  ActuatorInput out;
  out.t_ns = command.t_ns;
  out.sequence = command.sequence_number;
  out.armed = command.armed;
  const uint32_t n = std::min<uint32_t>(command.rotor_speeds._length, mav_dds_kMaxRotors);
  out.rotor_speeds_radps.assign(command.rotor_speeds._buffer, command.rotor_speeds._buffer + n);
  return out;
}

// ---- DdsStreamSink ----------------------------------------------------------------------------

Result<std::unique_ptr<DdsStreamSink>> DdsStreamSink::Create(const transport::DdsOptions& options) {
  using transport::Qos;
  MAV_ASSIGN_OR_RETURN(transport::Participant participant, transport::Participant::Create(options));
  std::unique_ptr<DdsStreamSink> sink(new DdsStreamSink(std::move(participant)));
  const transport::Participant& p = sink->participant_;
  MAV_ASSIGN_OR_RETURN(sink->stereo_topic_, service_common::OpenTopic<mav_dds_StereoFrame>(p));
  MAV_ASSIGN_OR_RETURN(sink->imu_topic_, service_common::OpenTopic<mav_dds_ImuSample>(p));
  MAV_ASSIGN_OR_RETURN(sink->gt_topic_, service_common::OpenTopic<mav_dds_GroundTruthState>(p));
  MAV_ASSIGN_OR_RETURN(sink->pose_topic_, service_common::OpenTopic<mav_dds_PoseWithCovariance>(p));
  MAV_ASSIGN_OR_RETURN(sink->actuator_topic_,
                       service_common::OpenTopic<mav_dds_ActuatorCommand>(p));
  MAV_ASSIGN_OR_RETURN(sink->stereo_, transport::Writer<mav_dds_StereoFrame>::Create(
                                          p, *sink->stereo_topic_, Qos::SensorStream()));
  // A short liveliness lease: mav-control tells a vanished simulator from a paused one by it.
  MAV_ASSIGN_OR_RETURN(sink->imu_,
                       transport::Writer<mav_dds_ImuSample>::Create(
                           p, *sink->imu_topic_, Qos::HighRate().Liveliness(kImuLivelinessNs)));
  MAV_ASSIGN_OR_RETURN(sink->gt_, transport::Writer<mav_dds_GroundTruthState>::Create(
                                      p, *sink->gt_topic_, Qos::State()));
  MAV_ASSIGN_OR_RETURN(sink->pose_, transport::Writer<mav_dds_PoseWithCovariance>::Create(
                                        p, *sink->pose_topic_, Qos::State()));
  MAV_ASSIGN_OR_RETURN(sink->actuators_, transport::Reader<mav_dds_ActuatorCommand>::Create(
                                             p, *sink->actuator_topic_, Qos::Command()));
  return sink;
}

Status DdsStreamSink::PublishStereo(uint64_t sequence, const RenderedFrame& frame, bool rectified) {
  mav_dds_StereoFrame sample;
  FillStereoFrame(sequence, frame, rectified, WallNowNs(), &sample);
  return stereo_->Write(sample);
}

Status DdsStreamSink::PublishImu(uint64_t sequence, const dataset::ImuSample& sample) {
  return imu_->Write(ToDds(sequence, sample, WallNowNs()));
}

Status DdsStreamSink::PublishGroundTruth(uint64_t sequence,
                                         const dataset::GroundTruthState& state) {
  return gt_->Write(ToDds(sequence, state, WallNowNs()));
}

Status DdsStreamSink::WaitForStereoAcks(int64_t timeout_ns) {
  return stereo_->WaitForAcks(timeout_ns);
}

uint32_t DdsStreamSink::StereoSubscribers() {
  Result<uint32_t> n = stereo_->MatchedReaders();
  return n.ok() ? *n : 0;
}

void DdsStreamSink::PrepareStereo(RenderedFrame* frame) {
  if (frame->left.type() != CV_8UC1 || frame->right.type() != CV_8UC1 ||
      !frame->left.isContinuous() || !frame->right.isContinuous()) {
    return;  // FillStereoFrame checks the images and computes the CRC itself
  }
  frame->crc32 = StereoCrc32(frame->left.ptr<uint8_t>(), frame->left.total(),
                             frame->right.ptr<uint8_t>(), frame->right.total());
}

uint32_t DdsStreamSink::ImuSubscribers() {
  Result<uint32_t> n = imu_->MatchedReaders();
  return n.ok() ? *n : 0;
}

Status DdsStreamSink::PublishFlightImu(uint64_t sequence, const dataset::ImuSample& sample) {
  return PublishImu(sequence, sample);
}

Status DdsStreamSink::PublishFlightPose(uint64_t sequence, const sim::PoseSample& pose,
                                        const std::string& frame_id, double position_sigma_m,
                                        double orientation_sigma_rad) {
  return pose_->Write(
      ToDds(sequence, pose, frame_id, position_sigma_m, orientation_sigma_rad, WallNowNs()));
}

Status DdsStreamSink::PublishFlightGroundTruth(uint64_t sequence,
                                               const dataset::GroundTruthState& state) {
  return PublishGroundTruth(sequence, state);
}

void DdsStreamSink::TakeCommands(int64_t min_t_ns, int64_t max_t_ns,
                                 std::optional<ActuatorInput>* best, uint64_t* received) {
  while (true) {
    Result<transport::LoanedSamples<mav_dds_ActuatorCommand>> samples = actuators_->Take(16);
    if (!samples.ok()) {
      MAV_LOG(kWarning) << samples.status().ToString();
      return;
    }
    for (int32_t i = 0; i < samples->size(); ++i) {
      if (!samples->valid(i)) continue;
      ++*received;
      const mav_dds_ActuatorCommand& c = (*samples)[i];
      if (c.t_ns >= min_t_ns && c.t_ns <= max_t_ns &&
          (!best->has_value() || c.t_ns >= (*best)->t_ns)) {
        *best = FromDds(c);
      }
    }
    if (samples->size() < 16) return;
  }
}

void DdsStreamSink::DiscardCommands() {
  std::optional<ActuatorInput> ignored;
  uint64_t received = 0;
  TakeCommands(std::numeric_limits<int64_t>::min(), std::numeric_limits<int64_t>::max(), &ignored,
               &received);
}

std::optional<ActuatorInput> DdsStreamSink::WaitForCommand(int64_t min_t_ns, int64_t max_t_ns,
                                                           int64_t timeout_ns, uint64_t* received) {
  std::optional<ActuatorInput> best;
  TakeCommands(min_t_ns, max_t_ns, &best, received);
  const int64_t until_ns = MonotonicNowNs() + std::max<int64_t>(timeout_ns, 0);
  while (!best.has_value()) {
    const int64_t remaining = until_ns - MonotonicNowNs();
    if (remaining <= 0) break;
    Result<bool> ready = actuators_->WaitForData(remaining);
    if (!ready.ok()) {
      MAV_LOG(kWarning) << ready.status().ToString();
      break;
    }
    if (!*ready) break;
    TakeCommands(min_t_ns, max_t_ns, &best, received);
  }
  return best;
}

uint32_t DdsStreamSink::ActuatorWriters() {
  Result<uint32_t> n = actuators_->MatchedWriters();
  return n.ok() ? *n : 0;
}

}  // namespace mav::simulator_service
