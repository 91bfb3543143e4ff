#include "services/control/dds_io.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>

#include "mav/common/log.h"
#include "mav/common/time.h"
#include "services/common/dds_codec.h"

namespace mav::control_service {

namespace {

constexpr int64_t kPollNs = 20'000'000;  // IMU watchdog granularity (the timeout is 100 ms)

}  // namespace

mav_dds_ActuatorCommand ToDds(const ActuatorOutput& command, int64_t publish_t_ns,
                              double (&speeds)[mav_dds_kMaxRotors]) {
  mav_dds_ActuatorCommand out{};
  out.vehicle_id = mav_dds_kDefaultVehicleId;
  out.sequence_number = command.sequence;
  out.t_ns = command.t_ns;
  out.publish_t_ns = publish_t_ns;
  out.armed = command.armed;
  const int n = std::min<int>(static_cast<int>(command.rotor_speeds_radps.size()),
                              static_cast<int>(mav_dds_kMaxRotors));
  for (int i = 0; i < n; ++i) speeds[i] = command.rotor_speeds_radps[i];
  out.rotor_speeds._buffer = speeds;
  out.rotor_speeds._length = out.rotor_speeds._maximum = static_cast<uint32_t>(n);
  out.rotor_speeds._release = false;
  return out;
}

Result<control::ImuMeasurement> FromDds(const mav_dds_ImuSample& sample) {
  MAV_RETURN_IF_ERROR(service_common::CheckFinite(sample.gyro, "gyro"));
  MAV_RETURN_IF_ERROR(service_common::CheckFinite(sample.accel, "accel"));
  control::ImuMeasurement out;
  out.t_ns = sample.t_ns;
  out.gyro = Eigen::Vector3d(sample.gyro.x, sample.gyro.y, sample.gyro.z);
  out.accel = Eigen::Vector3d(sample.accel.x, sample.accel.y, sample.accel.z);
  return out;
}

Result<PoseInput> FromDds(const mav_dds_PoseWithCovariance& pose) {
  if (pose.tracking_state != mav_dds_TRACKING_STATE_OK &&
      pose.tracking_state != mav_dds_TRACKING_STATE_INITIALIZING) {
    return Status::InvalidArgument(
        "tracking_state: " + std::to_string(static_cast<int>(pose.tracking_state)) +
        " is not OK/INITIALIZING");
  }
  MAV_ASSIGN_OR_RETURN(const geometry::SE3 T_world_sensor,
                       service_common::PoseFromDds(pose.position, pose.orientation));
  PoseInput out;
  out.frame_id = std::string(pose.child_frame_id, strnlen(pose.child_frame_id, 32));
  out.t_ns = pose.t_ns;
  out.T_world_sensor = T_world_sensor;
  return out;
}

// ---- DdsIo --------------------------------------------------------------------------------------

Result<std::unique_ptr<DdsIo>> DdsIo::Create(const transport::DdsOptions& options) {
  using transport::Qos;
  MAV_ASSIGN_OR_RETURN(transport::Participant participant, transport::Participant::Create(options));
  MAV_ASSIGN_OR_RETURN(ImuTopic imu_topic, ImuTopic::Create(participant, transport::kImuTopic,
                                                            &mav_dds_ImuSample_desc));
  MAV_ASSIGN_OR_RETURN(PoseTopic pose_topic, PoseTopic::Create(participant, transport::kPoseTopic,
                                                               &mav_dds_PoseWithCovariance_desc));
  MAV_ASSIGN_OR_RETURN(
      ActuatorTopic actuator_topic,
      ActuatorTopic::Create(participant, transport::kActuatorTopic, &mav_dds_ActuatorCommand_desc));
  MAV_ASSIGN_OR_RETURN(auto writer, transport::Writer<mav_dds_ActuatorCommand>::Create(
                                        participant, actuator_topic, Qos::Command()));
  return std::unique_ptr<DdsIo>(new DdsIo(std::move(participant), std::move(imu_topic),
                                          std::move(pose_topic), std::move(actuator_topic),
                                          std::move(writer)));
}

DdsIo::DdsIo(transport::Participant participant, ImuTopic imu_topic, PoseTopic pose_topic,
             ActuatorTopic actuator_topic, transport::Writer<mav_dds_ActuatorCommand> writer)
    : participant_(std::move(participant)),
      imu_topic_(std::move(imu_topic)),
      pose_topic_(std::move(pose_topic)),
      actuator_topic_(std::move(actuator_topic)),
      writer_(std::move(writer)) {}

DdsIo::~DdsIo() {
  std::lock_guard<std::mutex> lock(control_mutex_);
  StopInputLocked();
}

Status DdsIo::PublishCommand(const ActuatorOutput& command) {
  double speeds[mav_dds_kMaxRotors] = {};  // borrowed by the sample: no allocation per command
  return writer_.Write(ToDds(command, WallNowNs(), speeds));
}

uint32_t DdsIo::ActuatorSubscribers() {
  Result<uint32_t> n = writer_.MatchedReaders();
  return n.ok() ? *n : 0;
}

bool DdsIo::input_enabled() const {
  std::lock_guard<std::mutex> lock(control_mutex_);
  return imu_reader_.has_value();
}

void DdsIo::StopInputLocked() {
  read_loop_.reset();  // joins the loop before its readers go
  imu_reader_.reset();
  pose_reader_.reset();
}

void DdsIo::OnPoseSample(const mav_dds_PoseWithCovariance& sample) {
  const int64_t take_ns = WallNowNs();
  ++poses_received_;
  Result<PoseInput> pose = FromDds(sample);
  if (!pose.ok()) {
    // A LOST answer still answers its frame (a lock-step source).
    core_->OnPoseAnswer(std::string(sample.child_frame_id, strnlen(sample.child_frame_id, 32)),
                        sample.t_ns, pose.status().message());
    return;
  }
  core_->OnPose(pose->frame_id, pose->t_ns, pose->T_world_sensor,
                PoseStamps{sample.frame_publish_t_ns, sample.frame_receive_t_ns,
                           sample.publish_t_ns, take_ns});
}

void DdsIo::WaitForPoses(int64_t imu_t_ns) {
  constexpr int64_t kSliceNs = 5'000'000;
  const int64_t give_up_ns = MonotonicNowNs() + core_->LockstepWaitNs();
  while (true) {
    for (;;) {  // drain what arrived
      Result<transport::LoanedSamples<mav_dds_PoseWithCovariance>> samples = pose_reader_->Take(64);
      if (!samples.ok() || samples->size() == 0) break;
      for (int32_t i = 0; i < samples->size(); ++i) {
        if (samples->valid(i)) OnPoseSample((*samples)[i]);
      }
    }
    if (!core_->AwaitingPose(imu_t_ns)) return;
    const int64_t remaining = give_up_ns - MonotonicNowNs();
    if (remaining <= 0) {
      core_->GiveUpWaiting(imu_t_ns);
      return;
    }
    (void)pose_reader_->WaitForData(std::min(remaining, kSliceNs));
  }
}

Status DdsIo::SetInput(bool enabled) {
  std::lock_guard<std::mutex> lock(control_mutex_);
  if (enabled == imu_reader_.has_value()) return Status::Ok();
  if (enabled && core_ == nullptr) return Status::FailedPrecondition("DDS input: no core attached");
  if (!enabled) {
    StopInputLocked();
    MAV_LOG(kInfo) << "DDS input off (" << imu_received_.load() << " IMU samples, "
                   << poses_received_.load() << " poses received)";
    return Status::Ok();
  }
  using transport::Qos;
  MAV_ASSIGN_OR_RETURN(auto imu, transport::Reader<mav_dds_ImuSample>::Create(
                                     participant_, imu_topic_, Qos::HighRate()));
  MAV_ASSIGN_OR_RETURN(auto pose, transport::Reader<mav_dds_PoseWithCovariance>::Create(
                                      participant_, pose_topic_, Qos::State()));
  imu_reader_.emplace(std::move(imu));
  pose_reader_.emplace(std::move(pose));
  read_loop_.emplace("control input", kPollNs);
  read_loop_->AddReader<mav_dds_PoseWithCovariance>(
      &*pose_reader_, [this](const mav_dds_PoseWithCovariance& sample) { OnPoseSample(sample); });
  read_loop_->SetWakeReader<mav_dds_ImuSample>(&*imu_reader_, [this](const mav_dds_ImuSample& s) {
    ++imu_received_;
    Result<control::ImuMeasurement> imu = FromDds(s);
    if (!imu.ok()) {
      core_->RejectImu(imu.status().message());
      return;
    }
    if (core_->AwaitingPose(imu->t_ns)) WaitForPoses(imu->t_ns);
    core_->OnImu(*imu);
  });
  // Called after every wake (each IMU sample) too: the liveliness is read once per poll period.
  read_loop_->SetOnPoll([this, alive = uint32_t{0}, next_ns = int64_t{0}]() mutable {
    const int64_t now_ns = MonotonicNowNs();
    if (now_ns >= next_ns) {
      // The reader lives while the loop runs (StopInputLocked joins the loop first).
      Result<uint32_t> n = imu_reader_->AliveWriters();
      alive = n.ok() ? *n : 0;
      next_ns = now_ns + kPollNs;
    }
    core_->OnPoll(now_ns, alive);
  });
  MAV_RETURN_IF_ERROR(read_loop_->Start());
  MAV_LOG(kInfo) << "DDS input on: " << transport::kImuTopic << ", " << transport::kPoseTopic;
  return Status::Ok();
}

}  // namespace mav::control_service
