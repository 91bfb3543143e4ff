#pragma once
// The localization service's data plane (docs/contracts.md):
//   in   mav/sensors/stereo       mav_dds_StereoFrame        Qos::SensorStream() (keep-last 4)
//   in   mav/sensors/imu          mav_dds_ImuSample          Qos::HighRate() (the gyro goes to
//                                                            the dense VO; sparse ignores it)
//   out  mav/localization/pose    mav_dds_PoseWithCovariance Qos::State()
// The stereo reader exists only while DDS input is enabled (Configure without
// disable_dds_input): an unconfigured service is no subscriber, so a simulator waiting for its
// subscribers does not count it.
// Life cycle: create the DdsIo, then the Localizer with the DdsIo as its PoseSink, then Attach();
// on shutdown switch the input off before destroying the Localizer. The read loop
// (transport::DdsReadLoop) waits for frames, checks them (size, CRC-32), copies the pixels and
// hands them to Localizer::SubmitLive, which never blocks (drop-oldest).

#include <array>
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
#include "services/common/dds_codec.h"
#include "services/common/input_control.h"
#include "services/localization/localizer.h"

namespace mav::localization_service {

using service_common::CheckStereoFrame;
using service_common::StereoCrc32;

// The pose sample for `pose` (frame_id "world", child_frame_id from `frame`).
mav_dds_PoseWithCovariance ToDds(uint64_t sequence, const RigPose& pose, OutputFrame frame,
                                 int64_t publish_t_ns);

using service_common::InputControl;

class DdsIo : public PoseSink, public InputControl {
 public:
  static Result<std::unique_ptr<DdsIo>> Create(const transport::DdsOptions& options);
  ~DdsIo() override;

  // The localizer that receives live frames (not owned). Call once, before SetInput(true);
  // stop the input (SetInput(false)) before the localizer is destroyed.
  void Attach(Localizer* localizer) { localizer_ = localizer; }

  Status PublishPose(const RigPose& pose, OutputFrame frame) override;
  Status SetInput(bool enabled) override;
  bool input_enabled() const override;

  uint64_t frames_received() const { return frames_received_.load(); }
  uint64_t imu_samples_received() const { return imu_received_.load(); }
  uint64_t poses_published() const { return pose_sequence_.load(); }
  uint32_t PoseSubscribers();
  uint32_t domain() const { return static_cast<uint32_t>(participant_.domain()); }

 private:
  using StereoTopic = transport::Topic<mav_dds_StereoFrame>;
  using ImuTopic = transport::Topic<mav_dds_ImuSample>;
  using PoseTopic = transport::Topic<mav_dds_PoseWithCovariance>;
  DdsIo(transport::Participant participant, StereoTopic stereo_topic, ImuTopic imu_topic,
        PoseTopic pose_topic, transport::Writer<mav_dds_PoseWithCovariance> pose_writer);
  void OnFrame(const mav_dds_StereoFrame& frame);
  void StopReaderLocked();

  Localizer* localizer_ = nullptr;
  // Declaration order = reverse destruction order: readers/writer, topics, participant.
  transport::Participant participant_;
  StereoTopic stereo_topic_;
  ImuTopic imu_topic_;
  PoseTopic pose_topic_;
  transport::Writer<mav_dds_PoseWithCovariance> pose_writer_;

  mutable std::mutex control_mutex_;  // serialises SetInput
  std::optional<transport::Reader<mav_dds_StereoFrame>> stereo_reader_;
  std::optional<transport::Reader<mav_dds_ImuSample>> imu_reader_;
  std::optional<transport::DdsReadLoop> read_loop_;

  std::atomic<uint64_t> frames_received_{0};
  std::atomic<uint64_t> imu_received_{0};
  std::atomic<uint64_t> pose_sequence_{0};

  // The wall-clock stamps of the newest frames (its publish, our take), found by the frame's
  // t_ns when its pose is published (PoseWithCovariance.frame_publish_t_ns/frame_receive_t_ns).
  struct FrameStamps {
    int64_t t_ns = -1;
    int64_t publish_ns = 0;
    int64_t receive_ns = 0;
  };
  static constexpr size_t kStampedFrames = 128;  // > the longest input queue (100 frames)
  std::mutex stamps_mutex_;
  std::array<FrameStamps, kStampedFrames> stamps_{};
  size_t next_stamp_ = 0;
};

}  // namespace mav::localization_service
