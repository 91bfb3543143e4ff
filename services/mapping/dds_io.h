#pragma once
// The mapping service's data plane (docs/contracts.md), input only:
//   in  mav/sensors/stereo     mav_dds_StereoFrame        Qos::SensorStream() (keep-last 4)
//   in  mav/sim/ground_truth   mav_dds_GroundTruthState   Qos::State() (pose source GROUND_TRUTH)
//   in  mav/localization/pose  mav_dds_PoseWithCovariance Qos::State() (pose source LOCALIZATION)
// The readers exist only while a session with DDS input is active (StartSession with a pose
// source and without disable_dds_input): an idle service is no subscriber, so a simulator waiting
// for its subscribers does not count it.
// The read loop (transport::DdsReadLoop) waits for frames (100 ms polls), takes every pose sample
// first (so a frame finds the poses published before it), then the frames; checks each frame
// (size, CRC-32), copies its pixels and hands it to Mapper::SubmitLiveFrame, which never blocks.
// Localization poses with child_frame_id "cam0" are turned into body poses with the session's
// T_body_cam0; poses whose tracking state is not OK/INITIALIZING are ignored (a LOST pose is the
// last good one held, not the pose at its t_ns).

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>

#include "mav_sensors.h"
#include "mav_state.h"

#include "mav/transport/dds.h"
#include "mav/transport/dds_read_loop.h"
#include "services/common/input_control.h"
#include "services/mapping/mapper.h"

namespace mav::mapping_service {

// The ground truth's T_world_body; InvalidArgument as service_common::PoseFromDds says (a
// position not finite, a quaternion not unit).
Result<geometry::SE3> PoseFromDds(const mav_dds_GroundTruthState& state);
// A localization pose as T_world_body (a cam0 pose through T_body_cam0); nullopt for a pose
// whose tracking state is not OK/INITIALIZING; InvalidArgument as above.
Result<std::optional<geometry::SE3>> BodyPoseFromDds(const mav_dds_PoseWithCovariance& pose,
                                                     const geometry::SE3& T_body_cam0);

using service_common::InputControl;

class DdsIo : public InputControl {
 public:
  static Result<std::unique_ptr<DdsIo>> Create(const transport::DdsOptions& options);
  ~DdsIo() override;

  // The mapper that receives live frames and poses (not owned). Call once, before SetInput(true);
  // switch the input off before the mapper is destroyed.
  void Attach(Mapper* mapper) { mapper_ = mapper; }

  // enabled: subscribes to the stereo frames and to the poses of the mapper's session (its
  // pose source; kNone: stereo only).
  Status SetInput(bool enabled) override;
  bool input_enabled() const override;

  uint64_t frames_received() const { return frames_received_.load(); }
  uint64_t poses_received() const { return poses_received_.load(); }
  uint64_t poses_rejected() const { return poses_rejected_.load(); }

 private:
  using StereoTopic = transport::Topic<mav_dds_StereoFrame>;
  using GroundTruthTopic = transport::Topic<mav_dds_GroundTruthState>;
  using PoseTopic = transport::Topic<mav_dds_PoseWithCovariance>;
  DdsIo(transport::Participant participant, StereoTopic stereo_topic,
        GroundTruthTopic ground_truth_topic, PoseTopic pose_topic);
  void OnFrame(const mav_dds_StereoFrame& frame);
  // Counts a pose sample that fails the codec's checks and logs the first and every 100th.
  void RejectPose(const Status& why);
  void StopReaderLocked();
  // Creates the readers of `session`'s input and starts the loop (control_mutex_ held).
  Status StartInputLocked(const SessionConfig& session);

  Mapper* mapper_ = nullptr;
  // Declaration order = reverse destruction order: readers, topics, participant.
  transport::Participant participant_;
  StereoTopic stereo_topic_;
  GroundTruthTopic ground_truth_topic_;
  PoseTopic pose_topic_;

  mutable std::mutex control_mutex_;  // serialises SetInput
  std::optional<transport::Reader<mav_dds_StereoFrame>> stereo_reader_;
  std::optional<transport::Reader<mav_dds_GroundTruthState>> ground_truth_reader_;
  std::optional<transport::Reader<mav_dds_PoseWithCovariance>> pose_reader_;
  std::optional<transport::DdsReadLoop> read_loop_;

  std::atomic<uint64_t> frames_received_{0};
  std::atomic<uint64_t> poses_received_{0};
  std::atomic<uint64_t> poses_rejected_{0};
};

}  // namespace mav::mapping_service
