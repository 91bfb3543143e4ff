#pragma once
// Each data-plane type with its topic (docs/contracts.md, "Data plane"), so that a service opens
// a topic by type alone:
//   MAV_ASSIGN_OR_RETURN(auto stereo, OpenTopic<mav_dds_StereoFrame>(participant));

#include "mav_control.h"
#include "mav_sensors.h"
#include "mav_state.h"

#include "mav/common/status.h"
#include "mav/transport/dds.h"

namespace mav::service_common {

template <typename T>
struct TopicOf;

template <>
struct TopicOf<mav_dds_StereoFrame> {
  static constexpr const char* kName = transport::kStereoTopic;
  static const dds_topic_descriptor_t* Descriptor() { return &mav_dds_StereoFrame_desc; }
};
template <>
struct TopicOf<mav_dds_ImuSample> {
  static constexpr const char* kName = transport::kImuTopic;
  static const dds_topic_descriptor_t* Descriptor() { return &mav_dds_ImuSample_desc; }
};
template <>
struct TopicOf<mav_dds_PoseWithCovariance> {
  static constexpr const char* kName = transport::kPoseTopic;
  static const dds_topic_descriptor_t* Descriptor() { return &mav_dds_PoseWithCovariance_desc; }
};
template <>
struct TopicOf<mav_dds_GroundTruthState> {
  static constexpr const char* kName = transport::kGroundTruthTopic;
  static const dds_topic_descriptor_t* Descriptor() { return &mav_dds_GroundTruthState_desc; }
};
template <>
struct TopicOf<mav_dds_ActuatorCommand> {
  static constexpr const char* kName = transport::kActuatorTopic;
  static const dds_topic_descriptor_t* Descriptor() { return &mav_dds_ActuatorCommand_desc; }
};

template <typename T>
Result<transport::Topic<T>> OpenTopic(const transport::Participant& participant) {
  return transport::Topic<T>::Create(participant, TopicOf<T>::kName, TopicOf<T>::Descriptor());
}

}  // namespace mav::service_common
