#pragma once
// The gRPC Simulator service (protos/mav/v1/simulator.proto): a thin adapter from RPCs to the
// Player (player.h, replay) and the Flight (flight.h, flight mode). Status codes follow
// docs/contracts.md: INVALID_ARGUMENT naming the field, NOT_FOUND for a missing EuRoC directory,
// task file or map, FAILED_PRECONDITION for calls in the wrong state, OUT_OF_RANGE for steps
// beyond the end, RESOURCE_EXHAUSTED for occupancy grids over the limit. The replay and the
// flight share the IMU and ground-truth topics: starting one pauses the other.

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>

#include "mav/v1/simulator.grpc.pb.h"

#include "mav/sim/collision_world.h"
#include "mav/sim/flight_task.h"
#include "services/simulator/convert.h"
#include "services/simulator/flight.h"
#include "services/simulator/player.h"

namespace mav::simulator_service {

struct SimulatorServiceOptions {
  // Memory GetGroundTruthOccupancy calls may use at once, MiB. A call's need is estimated before
  // anything is allocated: one byte per voxel for the grid, plus OctoMap's tree for a .bt answer
  // (kOctomapBytesPerVoxel per known voxel before pruning); a call that would take the total over
  // the limit is refused with RESOURCE_EXHAUSTED. The default (1 GiB) allows a room (~8x8x3 m) at
  // 2.5 cm as .bt or 1 cm as .mavocc, and the plant (50x50x40 m) at 20 cm as .bt.
  int64_t max_occupancy_memory_mb = 1024;
  // The OctoMap of the built-in t4_3 (the power plant).
  std::string plant_map_path = sim::DefaultPlantMapPath();
  // The replay's rendering threads (Player): kIdle yields the CPU to every other thread
  // (mav-simulator --render-priority idle; the compose stack's setting).
  sim::FramePrefetcher::Priority render_priority = sim::FramePrefetcher::Priority::kNormal;

  static constexpr double kOctomapBytesPerVoxel = 64.0;
  bool IsValid(std::string* why) const;
};

class SimulatorService final : public v1::Simulator::Service {
 public:
  // `sink` and `flight_io` are not owned and must outlive the service; without a flight I/O the
  // flight mode publishes nowhere and receives no commands.
  SimulatorService(StreamSink* sink, SimulatorServiceOptions options = {},
                   FlightIo* flight_io = nullptr);

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

  grpc::Status LoadFlightTask(grpc::ServerContext* context,
                              const v1::LoadFlightTaskRequest* request,
                              v1::FlightStatus* response) override;
  grpc::Status StartFlight(grpc::ServerContext* context, const v1::StartFlightRequest* request,
                           v1::FlightStatus* response) override;
  grpc::Status PauseFlight(grpc::ServerContext* context, const v1::PauseFlightRequest* request,
                           v1::FlightStatus* response) override;
  grpc::Status GetFlightStatus(grpc::ServerContext* context,
                               const v1::GetFlightStatusRequest* request,
                               v1::FlightStatus* response) override;

  // LoadFlightTask without an RPC (main.cc's start-up flags) or with the call's deadline.
  grpc::Status ApplyLoadFlightTask(const v1::LoadFlightTaskRequest& request,
                                   const Termination& deadline, v1::FlightStatus* response);

  Player& player() { return player_; }
  Flight& flight() { return *flight_; }
  // Stops both workers (main.cc's drain).
  void Shutdown();

 private:
  // The task a request names (builtin / YAML text / a file), with map_path applied.
  Result<dataset::FlightTask> ResolveFlightTask(const FlightLoadRequest& load) const;
  // The task's collision world, read once per map file (the last one is kept: one map in memory).
  Result<std::shared_ptr<const sim::CollisionWorld>> WorldFor(const std::string& map_path);
  // The loaded mission flight's world and camera (null unless the last load was a mission flight
  // and no scenario was loaded since): GetCalibration and GetGroundTruthOccupancy answer for it.
  std::shared_ptr<const MissionScene> mission_scene() const;
  void set_mission_scene(std::shared_ptr<const MissionScene> scene);

  SimulatorServiceOptions options_;
  Player player_;
  std::unique_ptr<FlightIo> null_flight_io_;  // when no flight I/O was given
  std::unique_ptr<Flight> flight_;
  std::mutex world_mutex_;
  std::string world_path_;
  std::shared_ptr<const sim::CollisionWorld> world_;
  std::mutex occupancy_mutex_;
  int64_t occupancy_reserved_bytes_ = 0;  // estimated need of the calls in flight
  mutable std::mutex mission_mutex_;
  std::shared_ptr<const MissionScene> mission_;
};

}  // namespace mav::simulator_service
