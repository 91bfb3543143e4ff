#pragma once
// The main() every service shares: flags (--address, --port, --dds-domain, --dds-config,
// --shutdown-grace-ms, and the service's own), environment (MAV_<SERVICE>_PORT, MAV_DDS_DOMAIN),
// the gRPC server with health and reflection, SIGINT/SIGTERM handling and a graceful drain.
//
//   int main(int argc, char** argv) {
//     transport::ServiceRunner runner({"mav-mapping", "Serves mav.v1.Mapping ...", 50053,
//                                      "MAV_MAPPING_PORT"});
//     runner.flags().AddInt("max-voxels", &max_voxels, "...");
//     runner.ParseFlagsOrExit(argc, argv);            // exit 2 with a message on bad usage
//     ... build the DDS side and the service from runner.dds_options() ...
//     return runner.Serve({&service}, {v1::Mapping::service_full_name()},
//                         /*on_drained=*/[&] { dds->SetInput(false); mapper.Shutdown(); });
//   }
//
// Shutdown order (Serve): the signal arrives -> health NOT_SERVING -> the server stops accepting
// calls and lets the ones in flight finish for up to --shutdown-grace-ms (default 5 s; a BuildMap
// or a PlanPath answered during the drain reaches its client) -> the rest are cancelled ->
// `on_drained` stops the workers and the data plane -> exit 0.

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <grpcpp/impl/codegen/service_type.h>

#include "mav/common/status.h"
#include "mav/transport/dds.h"
#include "mav/transport/flags.h"
#include "mav/transport/grpc_server.h"

namespace mav::transport {

// Makes glibc's malloc serve every block of 128 KiB or more (an image, a message) with its own
// mapping that goes back to the system when freed. glibc otherwise raises that threshold after
// the first such free and carves later images from its per-thread heaps, which then grow with
// fragmentation (a mapping service took ~0.15 MB a keyframe that way). Called by ServiceRunner;
// tests that measure a service's memory call it too.
void UseMappedLargeBlocks();

// The opposite choice, for a process whose large blocks are few fixed-size buffers recycled at
// frame rate and whose latency matters (the simulator, `mavctl listen`): blocks up to 4 MiB come
// from the heap and up to 32 MiB of free heap is kept (trim threshold; top pad 4 MiB). Mapping a
// fresh 722 KB stereo sample for each copy (Cyclone's serialised form, the sequences of a take)
// costs ~180 page faults, and halved the stream's one-way latency without it (p50 0.7 -> 0.35 ms;
// docs/benchmarks.md, "DDS stereo stream"). Call it after ServiceRunner's constructor.
void KeepLargeSampleBuffers();

struct ServiceInfo {
  std::string program;      // "mav-mapping": names the process in messages and logs
  std::string description;  // --help text
  int64_t default_port = 0;
  std::string port_env;  // "MAV_MAPPING_PORT"
};

class ServiceRunner {
 public:
  // Blocks SIGINT/SIGTERM in the calling thread first (before any other thread exists, so every
  // thread inherits the mask and the signals wait for Serve's sigwait).
  explicit ServiceRunner(ServiceInfo info);

  FlagParser& flags() { return flags_; }
  // Parses the command line and applies the environment (flag > environment > default).
  // Bad usage: the message and exit(2).
  void ParseFlagsOrExit(int argc, char** argv);

  const ServerOptions& server_options() const { return server_options_; }
  const DdsOptions& dds_options() const { return dds_options_; }
  const std::string& program() const { return info_.program; }

  // Prints "<program>: <status>" and returns 1 (a failure of the work, not of the usage).
  int Fail(const Status& status) const;
  // Prints "<program>: <message>" and returns 2 (bad usage).
  int Usage(const std::string& message) const;

  // Serves `services` (not owned) until SIGINT/SIGTERM, then drains and calls `on_drained`.
  // Returns the process exit code: 0, or 1 when the port cannot be bound.
  int Serve(const std::vector<grpc::Service*>& services,
            const std::vector<std::string>& health_names,
            const std::function<void()>& on_drained = {});

 private:
  ServiceInfo info_;
  FlagParser flags_;
  ServerOptions server_options_;
  DdsOptions dds_options_;
};

}  // namespace mav::transport
