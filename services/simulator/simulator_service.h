#pragma once
// The gRPC Simulator service (protos/mav/v1/simulator.proto): a thin adapter from RPCs to the
// Player (playback.h). Status codes follow docs/contracts.md: INVALID_ARGUMENT naming the field,
// NOT_FOUND for a missing EuRoC directory, FAILED_PRECONDITION for calls in the wrong state,
// OUT_OF_RANGE for steps beyond the end, RESOURCE_EXHAUSTED for occupancy grids over the limit.

#include <cstdint>
#include <memory>

#include "mav/v1/simulator.grpc.pb.h"

#include "services/simulator/playback.h"

namespace mav::simulator_service {

struct SimulatorServiceOptions {
  // Largest ground-truth occupancy grid GetGroundTruthOccupancy computes (voxels, one byte each
  // in memory). The default covers the rooms (~8x8x3 m) down to 1 cm and the plant (50x50x40 m)
  // down to ~7 cm; finer requests get RESOURCE_EXHAUSTED.
  int64_t max_occupancy_voxels = 400'000'000;

  bool IsValid(std::string* why) const;
};

class SimulatorService final : public v1::Simulator::Service {
 public:
  // `sink` is not owned and must outlive the service.
  SimulatorService(StreamSink* sink, SimulatorServiceOptions options = {});

  grpc::Status LoadScenario(grpc::ServerContext* context, const v1::LoadScenarioRequest* request,
                            v1::LoadScenarioResponse* response) override;
  grpc::Status Start(grpc::ServerContext* context, const v1::SimulatorStartRequest* request,
                     v1::SimulatorStatus* response) override;
  grpc::Status Pause(grpc::ServerContext* context, const v1::SimulatorPauseRequest* request,
                     v1::SimulatorStatus* response) override;
  grpc::Status Step(grpc::ServerContext* context, const v1::SimulatorStepRequest* request,
                    v1::SimulatorStatus* response) override;
  grpc::Status GetStatus(grpc::ServerContext* context, const v1::SimulatorGetStatusRequest* request,
                         v1::SimulatorStatus* response) override;
  grpc::Status GetCalibration(grpc::ServerContext* context,
                              const v1::GetCalibrationRequest* request,
                              v1::GetCalibrationResponse* response) override;
  grpc::Status GetGroundTruthOccupancy(grpc::ServerContext* context,
                                       const v1::GetGroundTruthOccupancyRequest* request,
                                       grpc::ServerWriter<v1::OccupancyChunk>* writer) override;

  Player& player() { return player_; }

 private:
  SimulatorServiceOptions options_;
  Player player_;
};

}  // namespace mav::simulator_service
