#include "mav/transport/service_main.h"

#include <malloc.h>

#include <cstdlib>
#include <iostream>

#include "mav/common/log.h"

namespace mav::transport {

namespace {
// Long enough for the slowest unary call the stack serves (a full-preset BuildMap takes ~5 s, a
// roadmap build runs under its own deadline) to reach its client during a drain.
constexpr int64_t kDefaultShutdownGraceMs = 5000;
}  // namespace

void UseMappedLargeBlocks() { mallopt(M_MMAP_THRESHOLD, 128 * 1024); }

void KeepLargeSampleBuffers() {
  constexpr int kMmapThreshold = 4 << 20;
  constexpr int kTrimThreshold = 32 << 20;
  constexpr int kTopPad = 4 << 20;
  if (mallopt(M_MMAP_THRESHOLD, kMmapThreshold) != 1 ||
      mallopt(M_TRIM_THRESHOLD, kTrimThreshold) != 1 || mallopt(M_TOP_PAD, kTopPad) != 1) {
    MAV_LOG(kWarning) << "mallopt refused the large-sample settings; DDS latency will be higher";
  }
}

ServiceRunner::ServiceRunner(ServiceInfo info)
    : info_(std::move(info)), flags_(info_.program, info_.description) {
  BlockShutdownSignals();
  UseMappedLargeBlocks();
  server_options_.port = info_.default_port;
  server_options_.shutdown_grace_ms = kDefaultShutdownGraceMs;
  AddServerFlags(&flags_, &server_options_, info_.port_env);
  flags_.AddInt("shutdown-grace-ms", &server_options_.shutdown_grace_ms,
                "on SIGINT/SIGTERM, how long calls in flight may finish before they are cancelled");
  AddDdsFlags(&flags_, &dds_options_);
}

void ServiceRunner::ParseFlagsOrExit(int argc, char** argv) {
  flags_.ParseOrExit(argc, argv);
  for (const Status& s : {ApplyPortEnv(flags_, info_.port_env, &server_options_),
                          ApplyDdsEnv(flags_, &dds_options_)}) {
    if (!s.ok()) std::exit(Usage(s.message()));
  }
  std::string why;
  if (!server_options_.IsValid(&why)) std::exit(Usage(why));
  if (!dds_options_.IsValid(&why)) std::exit(Usage(why));
}

int ServiceRunner::Fail(const Status& status) const {
  std::cerr << info_.program << ": " << status.ToString() << "\n";
  return 1;
}

int ServiceRunner::Usage(const std::string& message) const {
  std::cerr << info_.program << ": " << message << "\n";
  return 2;
}

int ServiceRunner::Serve(const std::vector<grpc::Service*>& services,
                         const std::vector<std::string>& health_names,
                         const std::function<void()>& on_drained) {
  Result<std::unique_ptr<GrpcServer>> server =
      GrpcServer::Start(server_options_, services, health_names);
  if (!server.ok()) {
    if (on_drained) on_drained();
    return Fail(server.status());
  }
  MAV_LOG(kInfo) << info_.program << " ready: gRPC " << (*server)->target() << ", DDS domain "
                 << dds_options_.domain;
  const int sig = WaitForShutdownSignal();
  MAV_LOG(kInfo) << "signal " << sig << ": draining calls in flight (up to "
                 << server_options_.shutdown_grace_ms << " ms), then shutting down";
  (*server)->Shutdown();
  if (on_drained) on_drained();
  MAV_LOG(kInfo) << info_.program << " stopped";
  return 0;
}

}  // namespace mav::transport
