#pragma once
// The gRPC Simulator service (protos/mav/v1/simulator.proto): a thin adapter from RPCs to the
// Player (player.h). Status codes follow docs/contracts.md: INVALID_ARGUMENT naming the field,
// NOT_FOUND for a missing EuRoC directory, FAILED_PRECONDITION for calls in the wrong state,
// OUT_OF_RANGE for steps beyond the end, RESOURCE_EXHAUSTED for occupancy grids over the limit.

#include <cstdint>
#include <memory>

#include "mav/v1/simulator.grpc.pb.h"

#include "services/simulator/player.h"

namespace mav::simulator_service {

struct SimulatorServiceOptions {
  // Memory GetGroundTruthOccupancy calls may use at once, MiB. A call's need is estimated before
  // anything is allocated: one byte per voxel for the grid, plus OctoMap's tree for a .bt answer
  // (kOctomapBytesPerVoxel per known voxel before pruning); a call that would take the total over
  // the limit is refused with RESOURCE_EXHAUSTED. The default (1 GiB) allows a room (~8x8x3 m) at
  // 2.5 cm as .bt or 1 cm as .mavocc, and the plant (50x50x40 m) at 20 cm as .bt.
  int64_t max_occupancy_memory_mb = 1024;

  static constexpr double kOctomapBytesPerVoxel = 64.0;
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
  std::mutex occupancy_mutex_;
  int64_t occupancy_reserved_bytes_ = 0;  // estimated need of the calls in flight
};

}  // namespace mav::simulator_service
