#pragma once
// What a service's RPCs switch when a client turns its live input on or off: the DDS
// subscriptions of mav-localization (stereo + IMU), mav-mapping (stereo + the session's pose
// source) and mav-control (IMU + poses). The DdsIo of each implements it in production; a
// contract test gives a fake, or nothing.

#include "mav/common/status.h"

namespace mav::service_common {

class InputControl {
 public:
  virtual ~InputControl() = default;
  // Subscribes (true) or unsubscribes (false); what to read is the service's own configuration
  // (mapping: the session's pose source).
  virtual Status SetInput(bool enabled) = 0;
  virtual bool input_enabled() const = 0;
};

}  // namespace mav::service_common
