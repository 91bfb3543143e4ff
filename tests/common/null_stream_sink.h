#pragma once
// A simulator stream sink (services/simulator/player.h) that publishes nothing and has no
// subscribers: for tests that use a simulator service for its RPCs alone (a calibration source,
// a flight replay).

#include <cstdint>

#include "services/simulator/player.h"

namespace mav::test_support {

class NullStreamSink : public simulator_service::StreamSink {
 public:
  Status PublishStereo(uint64_t, const simulator_service::RenderedFrame&, bool) override {
    return Status::Ok();
  }
  Status PublishImu(uint64_t, const dataset::ImuSample&) override { return Status::Ok(); }
  Status PublishGroundTruth(uint64_t, const dataset::GroundTruthState&) override {
    return Status::Ok();
  }
  Status WaitForStereoAcks(int64_t) override { return Status::Ok(); }
  uint32_t StereoSubscribers() override { return 0; }
  uint32_t ImuSubscribers() override { return 0; }
  uint32_t domain() const override { return 0; }
};

}  // namespace mav::test_support
