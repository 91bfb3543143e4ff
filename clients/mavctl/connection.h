#pragma once
// The connection flags every mavctl subcommand shares: --address, --port (with the service's
// port environment variable as the fallback) and --timeout (each RPC's deadline). --address is a
// host (then --port gives the port) or a whole gRPC target naming several backends
// (clients/common/channel.h: "ipv4:H:P,H:P", "H:P,H:P" of IP literals, "dns:///host:port"),
// whose calls are balanced round_robin with retries of UNAVAILABLE calls; --port is then refused.

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <grpcpp/channel.h>
#include <grpcpp/client_context.h>
#include <grpcpp/support/status.h>
#include <grpcpp/support/sync_stream.h>

#include "mav/v1/common.pb.h"

#include "clients/common/channel.h"
#include "mav/common/flags.h"
#include "mav/common/status.h"

namespace mav::mavctl {

struct Connection {
  Connection(int64_t default_port, std::string port_env_name)
      : port(default_port), port_env(std::move(port_env_name)) {}

  std::string address = "127.0.0.1";
  int64_t port;
  double timeout_s = 10.0;
  std::string port_env;  // consulted when --port is not given, e.g. MAV_SIMULATOR_PORT

  // "address:port", or the address itself when it is a whole target.
  std::string Target() const {
    return client::IsTargetUri(address) ? address : address + ":" + std::to_string(port);
  }
};

void AddConnectionFlags(FlagParser* flags, Connection* connection);

// Parses a subcommand's flags: --help prints the usage and exits 0; a usage error (bad flag,
// port outside [1, 65535], non-positive timeout, malformed port variable, a target list
// client::ParseTarget refuses, --port with a target) prints "mavctl: ..." and exits 2. `connection`
// may be null for subcommands without a server. Returns the positional arguments when
// `allow_positional`, otherwise they are an error.
std::vector<std::string> ParseOrExit(FlagParser* flags, Connection* connection,
                                     const std::vector<std::string>& args,
                                     bool allow_positional = false);

// The channel to Target() (client::MakeChannel: balanced for a target naming several backends).
std::shared_ptr<grpc::Channel> MakeChannel(const Connection& connection);

// "a,b,c,..." with exactly `n` finite numbers (a flag's value); InvalidArgument naming the flag.
Result<std::vector<double>> ParseNumbers(const std::string& text, size_t n,
                                         const std::string& flag);

// Sets the RPC deadline from --timeout.
void SetDeadline(const Connection& connection, grpc::ClientContext* context);

// Prints a failed RPC in words (cannot connect / no answer within --timeout / the status with
// its code) and returns the exit code 1.
int ReportRpcError(const Connection& connection, const std::string& rpc,
                   const grpc::Status& status);

// Prints "mavctl: <rpc> at <target>: the download is broken: ..." for a non-OK status; returns
// 0 for OK, else 1.
int ReportDownloadError(const Connection& connection, const std::string& rpc, const Status& s);

// One unary call with the --timeout deadline: `call(context)` makes it. Returns 0, or prints
// the failure (ReportRpcError) and returns 1, so that a subcommand reads
//   if (int rc = CallUnary(connection, "Reset", [&](grpc::ClientContext* c) {
//         return stub->Reset(c, request, &response); })) return rc;
int CallUnary(const Connection& connection, const std::string& rpc,
              const std::function<grpc::Status(grpc::ClientContext*)>& call);

// A server-streamed file (FileChunk or a message carrying one): reads every message with the
// --timeout deadline, checks that the chunks follow each other (offset = bytes so far) and add
// up to the announced total size, and appends the bytes to *bytes. `chunk_of` picks the
// FileChunk of a message; `on_message` (optional) sees each message (e.g. the first one's
// metadata). Returns 0, or prints the failure and returns 1.
template <typename Message>
int DownloadChunks(
    const Connection& connection, const std::string& rpc,
    const std::function<std::unique_ptr<grpc::ClientReader<Message>>(grpc::ClientContext*)>& open,
    const std::function<const v1::FileChunk&(const Message&)>& chunk_of, std::string* bytes,
    const std::function<void(const Message&)>& on_message = {}) {
  grpc::ClientContext context;
  SetDeadline(connection, &context);
  std::unique_ptr<grpc::ClientReader<Message>> reader = open(&context);
  Message message;
  uint64_t total = 0;
  bool have_total = false;
  Status broken;
  while (reader->Read(&message)) {
    if (on_message) on_message(message);
    const v1::FileChunk& chunk = chunk_of(message);
    if (broken.ok() && chunk.offset() != bytes->size()) {
      broken = Status::DataLoss("chunk at offset " + std::to_string(chunk.offset()) + " after " +
                                std::to_string(bytes->size()) + " bytes");
    }
    if (!have_total) {
      total = chunk.total_size();
      have_total = true;
    }
    bytes->append(chunk.data());
  }
  const grpc::Status status = reader->Finish();
  if (!status.ok()) return ReportRpcError(connection, rpc, status);
  if (broken.ok() && have_total && bytes->size() != total) {
    broken = Status::DataLoss(std::to_string(bytes->size()) + " bytes received, " +
                              std::to_string(total) + " announced");
  }
  return ReportDownloadError(connection, rpc, broken);
}

}  // namespace mav::mavctl
