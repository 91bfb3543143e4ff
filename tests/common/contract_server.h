#pragma once
// The server of a contract test's fixture: the service under test on a free loopback port,
// reporting SERVING under its gRPC service name; the fixture talks to it in process.

#include <memory>
#include <string>

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include "mav/transport/grpc_server.h"

namespace mav::test_support {

// `Api` is the generated service class (v1::Simulator, ...) whose name the health check uses.
// Null (and a test failure) when the server cannot start; ASSERT_NE(server, nullptr) after it.
template <typename Api>
std::unique_ptr<transport::GrpcServer> StartOnFreePort(grpc::Service* service) {
  transport::ServerOptions options;
  options.port = 0;  // the kernel picks a free port
  auto server = transport::GrpcServer::Start(options, {service}, {Api::service_full_name()});
  if (!server.ok()) {
    ADD_FAILURE() << "cannot start " << Api::service_full_name() << ": "
                  << server.status().ToString();
    return nullptr;
  }
  return std::move(*server);
}

}  // namespace mav::test_support
