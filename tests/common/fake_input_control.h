#pragma once
// The live-input switch of a service (services/common/input_control.h) without DDS: it only
// remembers what the service asked for, which is what the contract tests check.

#include "mav/common/status.h"
#include "services/common/input_control.h"

namespace mav::test_support {

class FakeInputControl : public service_common::InputControl {
 public:
  Status SetInput(bool enabled) override {
    enabled_ = enabled;
    return Status::Ok();
  }
  bool input_enabled() const override { return enabled_; }

 private:
  bool enabled_ = false;
};

}  // namespace mav::test_support
