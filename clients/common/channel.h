#pragma once
// The gRPC channel of the command-line clients (mav-load, mavctl): one server as HOST:PORT, or a
// target naming several backends, which is then balanced call by call (round_robin). Every
// channel retries calls that found their server gone and reconnects to a restarted server within
// half a second.
//
//   127.0.0.1:50054                                  one server, pick_first: as grpc::CreateChannel
//   ipv4:127.0.0.1:50054,127.0.0.1:50064             a gRPC target URI (ipv4:, ipv6:, dns:, unix:)
//   127.0.0.1:50054,127.0.0.1:50064,127.0.0.1:50074  a list of IP literals: "ipv4:" is put in front
//   dns:///planning.local:50054                      every address the name resolves to
//
// Every channel carries the service config of ServiceConfig(): up to 3 attempts of a call that
// failed UNAVAILABLE (10 ms backoff doubling to 100 ms; gRPC retries only calls the server has
// not answered, and only requests that fit the 256 KiB retry buffer: not a 722 KB stereo pair),
// and for a balanced target the round_robin policy. Its reconnect backoff is 100 ms growing to
// 500 ms (kReconnectBackoffMs) instead of gRPC's 1 s growing to 120 s: a server back after a
// minute away is used again within half a second, not after up to two minutes.

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <grpcpp/channel.h>

#include "mav/common/status.h"

namespace mav::client {

struct ChannelTarget {
  std::string target;     // what grpc is given
  bool balanced = false;  // a scheme or a list: round_robin + retries
};

// True when `address` is a whole target by itself (a scheme or a comma), so a separate port
// flag does not apply.
bool IsTargetUri(const std::string& address);

// The target of `address` (the forms above). InvalidArgument (message without a flag name) for
// an empty address or list item, or a list without a scheme whose items are not IP literals
// (a.b.c.d:port, or [v6]:port: one kind for the whole list).
Result<ChannelTarget> ParseTarget(const std::string& address);

// The first and the longest wait before reconnecting to a server that went away, ms.
inline constexpr std::pair<int, int> kReconnectBackoffMs = {100, 500};

// The service config of a channel: the retry policy for the methods of `services` (full names,
// e.g. "mav.v1.Planning"), and round_robin when `balanced`.
std::string ServiceConfig(const std::vector<std::string>& services, bool balanced);

// The five services of protos/mav/v1 and the health service.
const std::vector<std::string>& StackServices();

// An insecure channel to `target` with ServiceConfig(services, target.balanced) and the reconnect
// backoff above.
std::shared_ptr<grpc::Channel> MakeChannel(const ChannelTarget& target,
                                           const std::vector<std::string>& services);

// ParseTarget + MakeChannel, with the retry policy for StackServices().
Result<std::shared_ptr<grpc::Channel>> MakeChannel(const std::string& address);

// MakeChannel(address) for an address its caller has already checked with ParseTarget; one that
// does not parse is given to gRPC as it is (which reports it at the first call).
std::shared_ptr<grpc::Channel> MakeCheckedChannel(const std::string& address);

// "127.0.0.1:50054" for a peer string "ipv4:127.0.0.1:50054" (ClientContext::peer()); "[::1]:1"
// for "ipv6:[::1]:1"; other strings as they are.
std::string PeerAddress(const std::string& peer);

}  // namespace mav::client
