#include "clients/common/channel.h"

#include <cctype>
#include <string_view>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>
#include <grpcpp/support/channel_arguments.h>

#include "mav/common/parse.h"

namespace mav::client {

namespace {

constexpr std::string_view kSchemes[] = {"ipv4:", "ipv6:", "dns:", "unix:", "unix-abstract:"};

bool StartsWith(std::string_view text, std::string_view prefix) {
  return text.substr(0, prefix.size()) == prefix;
}

bool AllDigits(std::string_view text, size_t max_digits) {
  if (text.empty() || text.size() > max_digits) return false;
  for (char c : text) {
    if (!std::isdigit(static_cast<unsigned char>(c))) return false;
  }
  return true;
}

// "a.b.c.d:port" with each part a number.
bool IsIpv4HostPort(std::string_view item) {
  const size_t colon = item.rfind(':');
  if (colon == std::string_view::npos || !AllDigits(item.substr(colon + 1), 5)) return false;
  const std::vector<std::string_view> parts = SplitFields(item.substr(0, colon), '.');
  if (parts.size() != 4) return false;
  for (std::string_view part : parts) {
    if (!AllDigits(part, 3) || std::stoi(std::string(part)) > 255) return false;
  }
  return true;
}

// "[v6]:port".
bool IsIpv6HostPort(std::string_view item) {
  const size_t close = item.rfind("]:");
  return StartsWith(item, "[") && close != std::string_view::npos && close > 1 &&
         AllDigits(item.substr(close + 2), 5);
}

}  // namespace

bool IsTargetUri(const std::string& address) {
  if (address.find(',') != std::string::npos) return true;
  for (std::string_view scheme : kSchemes) {
    if (StartsWith(address, scheme)) return true;
  }
  return false;
}

Result<ChannelTarget> ParseTarget(const std::string& address) {
  if (address.empty()) return Status::InvalidArgument("empty address");
  if (!IsTargetUri(address)) return ChannelTarget{address, false};
  for (std::string_view scheme : kSchemes) {
    if (StartsWith(address, scheme)) {
      if (address.size() == scheme.size()) {
        return Status::InvalidArgument("'" + address + "': no address after the scheme");
      }
      return ChannelTarget{address, true};
    }
  }
  const std::vector<std::string_view> items = SplitFields(address, ',');
  bool ipv4 = true, ipv6 = true;
  for (std::string_view item : items) {
    if (item.empty()) return Status::InvalidArgument("'" + address + "': an empty list item");
    ipv4 = ipv4 && IsIpv4HostPort(item);
    ipv6 = ipv6 && IsIpv6HostPort(item);
  }
  if (!ipv4 && !ipv6) {
    return Status::InvalidArgument(
        "'" + address +
        "': a list without a scheme takes IP literals of one kind (a.b.c.d:port or "
        "[v6]:port); name hosts with dns:///host:port or give ipv4:/ipv6: yourself");
  }
  return ChannelTarget{(ipv4 ? "ipv4:" : "ipv6:") + address, true};
}

std::string ServiceConfig(const std::vector<std::string>& services, bool balanced) {
  std::string config = balanced ? R"({"loadBalancingConfig":[{"round_robin":{}}],)" : "{";
  config += R"("methodConfig":[{"name":[)";
  for (size_t i = 0; i < services.size(); ++i) {
    config.append(i == 0 ? "" : ",").append(R"({"service":")").append(services[i]).append("\"}");
  }
  config.append(R"(],"retryPolicy":{"maxAttempts":3,"initialBackoff":"0.01s","maxBackoff":"0.1s",)"
                R"("backoffMultiplier":2,"retryableStatusCodes":["UNAVAILABLE"]}}]})");
  return config;
}

const std::vector<std::string>& StackServices() {
  static const std::vector<std::string> kServices = {"mav.v1.Simulator", "mav.v1.Localization",
                                                     "mav.v1.Mapping",   "mav.v1.Planning",
                                                     "mav.v1.Control",   "grpc.health.v1.Health"};
  return kServices;
}

std::shared_ptr<grpc::Channel> MakeChannel(const ChannelTarget& target,
                                           const std::vector<std::string>& services) {
  grpc::ChannelArguments arguments;
  if (target.balanced) arguments.SetLoadBalancingPolicyName("round_robin");
  arguments.SetServiceConfigJSON(ServiceConfig(services, target.balanced));
  arguments.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, kReconnectBackoffMs.first);
  arguments.SetInt(GRPC_ARG_MIN_RECONNECT_BACKOFF_MS, kReconnectBackoffMs.first);
  arguments.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, kReconnectBackoffMs.second);
  return grpc::CreateCustomChannel(target.target, grpc::InsecureChannelCredentials(), arguments);
}

Result<std::shared_ptr<grpc::Channel>> MakeChannel(const std::string& address) {
  MAV_ASSIGN_OR_RETURN(const ChannelTarget target, ParseTarget(address));
  return MakeChannel(target, StackServices());
}

std::shared_ptr<grpc::Channel> MakeCheckedChannel(const std::string& address) {
  Result<ChannelTarget> target = ParseTarget(address);
  return MakeChannel(target.ok() ? *target : ChannelTarget{address}, StackServices());
}

std::string PeerAddress(const std::string& peer) {
  for (std::string_view scheme : {"ipv4:", "ipv6:"}) {
    if (StartsWith(peer, scheme)) return peer.substr(scheme.size());
  }
  return peer;
}

}  // namespace mav::client
