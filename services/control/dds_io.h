#pragma once
// The control service's data plane (docs/contracts.md):
//   in   mav/sensors/imu          mav_dds_ImuSample           Qos::HighRate() (wakes the loop)
//   in   mav/localization/pose    mav_dds_PoseWithCovariance  Qos::State() (drained first)
//   out  mav/control/actuators    mav_dds_ActuatorCommand     Qos::Command() (reliable,
//                                                             keep-last 1)
// The readers exist only while DDS input is enabled (Configure without disable_dds_input), so an
// unconfigured service is no subscriber. One transport::DdsReadLoop thread drains the poses, then
// the IMU sample that woke it, and calls ControlCore::OnPose / OnImu on that thread (the core's
// header says why); its poll period (20 ms) drives the IMU watchdog (ControlCore::OnPoll).
// Samples are checked here: a non-finite IMU reading, a pose with a non-finite position or a
// quaternion that is not unit, or a pose not tracking (LOST, UNSPECIFIED) is rejected (counted
// by the core) and never reaches the autopilot.
// Life cycle: create the DdsIo, then the core with the DdsIo as its CommandSink, then Attach();
// on shutdown switch the input off before destroying the core.

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>

#include "mav_control.h"
#include "mav_sensors.h"
#include "mav_state.h"

#include "mav/transport/dds.h"
#include "mav/transport/dds_read_loop.h"
#include "services/common/dds_codec.h"
#include "services/common/input_control.h"
#include "services/control/control_core.h"

namespace mav::control_service {

// The sample for `command`: its rotor_speeds sequence BORROWS `speeds` (filled here with at most
// kMaxRotors values), so the sample is valid while `speeds` lives and must not be freed.
mav_dds_ActuatorCommand ToDds(const ActuatorOutput& command, int64_t publish_t_ns,
                              double (&speeds)[mav_dds_kMaxRotors]);
// OK with the reading, or InvalidArgument naming the field ("gyro.y: not finite").
Result<control::ImuMeasurement> FromDds(const mav_dds_ImuSample& sample);
struct PoseInput {
  std::string frame_id;
  int64_t t_ns = 0;
  geometry::SE3 T_world_sensor;
};
// InvalidArgument naming the field for a pose that cannot be used.
Result<PoseInput> FromDds(const mav_dds_PoseWithCovariance& pose);

using service_common::InputControl;

class DdsIo : public CommandSink, public InputControl {
 public:
  static Result<std::unique_ptr<DdsIo>> Create(const transport::DdsOptions& options);
  ~DdsIo() override;

  // The core that receives the samples (not owned). Call once, before SetInput(true); stop the
  // input before the core is destroyed.
  void Attach(ControlCore* core) { core_ = core; }

  Status PublishCommand(const ActuatorOutput& command) override;
  uint32_t ActuatorSubscribers() override;
  Status SetInput(bool enabled) override;
  bool input_enabled() const override;

  uint64_t imu_received() const { return imu_received_.load(); }
  uint64_t poses_received() const { return poses_received_.load(); }
  uint32_t domain() const { return static_cast<uint32_t>(participant_.domain()); }

 private:
  using ImuTopic = transport::Topic<mav_dds_ImuSample>;
  using PoseTopic = transport::Topic<mav_dds_PoseWithCovariance>;
  using ActuatorTopic = transport::Topic<mav_dds_ActuatorCommand>;
  DdsIo(transport::Participant participant, ImuTopic imu_topic, PoseTopic pose_topic,
        ActuatorTopic actuator_topic, transport::Writer<mav_dds_ActuatorCommand> writer);
  void StopInputLocked();
  // On the read loop's thread: one pose sample to the core (a LOST one still answers its frame).
  void OnPoseSample(const mav_dds_PoseWithCovariance& sample);
  // Lock-step pose sources: drains the pose reader until every frame due by imu_t_ns is answered
  // or the core's wait runs out (ControlCore::AwaitingPose / GiveUpWaiting).
  void WaitForPoses(int64_t imu_t_ns);

  ControlCore* core_ = nullptr;
  // Declaration order = reverse destruction order: readers/writer, topics, participant.
  transport::Participant participant_;
  ImuTopic imu_topic_;
  PoseTopic pose_topic_;
  ActuatorTopic actuator_topic_;
  transport::Writer<mav_dds_ActuatorCommand> writer_;

  mutable std::mutex control_mutex_;  // serialises SetInput
  std::optional<transport::Reader<mav_dds_ImuSample>> imu_reader_;
  std::optional<transport::Reader<mav_dds_PoseWithCovariance>> pose_reader_;
  std::optional<transport::DdsReadLoop> read_loop_;

  std::atomic<uint64_t> imu_received_{0};
  std::atomic<uint64_t> poses_received_{0};
};

}  // namespace mav::control_service
