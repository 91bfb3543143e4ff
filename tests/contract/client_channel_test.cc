// The clients' channel targets (clients/common/channel.h): which addresses are one server and
// which are balanced, the refusals in words, and a balanced channel that really reaches a server
// named in a list (the service config is accepted by gRPC; a bad one would leave the channel in
// TRANSIENT_FAILURE).

#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <string>

#include <grpcpp/grpcpp.h>

#include "mav/v1/control.grpc.pb.h"

#include "clients/common/channel.h"

namespace mav::client {
namespace {

TEST(ClientChannelTest, HostPortIsOneServer) {
  Result<ChannelTarget> t = ParseTarget("127.0.0.1:50054");
  ASSERT_TRUE(t.ok()) << t.status().ToString();
  EXPECT_EQ(t->target, "127.0.0.1:50054");
  EXPECT_FALSE(t->balanced);
  EXPECT_FALSE(IsTargetUri("localhost:50054"));
}

TEST(ClientChannelTest, SchemesAndListsAreBalanced) {
  for (const char* uri : {"ipv4:127.0.0.1:1,127.0.0.1:2", "dns:///planning:50054",
                          "ipv6:[::1]:50054", "unix:/tmp/mav.sock"}) {
    Result<ChannelTarget> t = ParseTarget(uri);
    ASSERT_TRUE(t.ok()) << uri << ": " << t.status().ToString();
    EXPECT_EQ(t->target, uri);
    EXPECT_TRUE(t->balanced) << uri;
  }
  Result<ChannelTarget> list = ParseTarget("127.0.0.1:50054,127.0.0.1:50064");
  ASSERT_TRUE(list.ok());
  EXPECT_EQ(list->target, "ipv4:127.0.0.1:50054,127.0.0.1:50064");
  Result<ChannelTarget> v6 = ParseTarget("[::1]:1,[::1]:2");
  ASSERT_TRUE(v6.ok());
  EXPECT_EQ(v6->target, "ipv6:[::1]:1,[::1]:2");
}

TEST(ClientChannelTest, BadTargetsAreRefusedInWords) {
  const auto message = [](const std::string& address) {
    Result<ChannelTarget> t = ParseTarget(address);
    EXPECT_FALSE(t.ok()) << address;
    return t.ok() ? std::string() : t.status().message();
  };
  EXPECT_EQ(message(""), "empty address");
  EXPECT_NE(message("ipv4:").find("no address after the scheme"), std::string::npos);
  EXPECT_NE(message("127.0.0.1:1,,127.0.0.1:2").find("an empty list item"), std::string::npos);
  EXPECT_NE(message("a:1,b:2").find("name hosts with dns:///host:port"), std::string::npos);
  EXPECT_NE(message("127.0.0.1:1,[::1]:2").find("of one kind"), std::string::npos);
  EXPECT_NE(message("300.0.0.1:1,127.0.0.1:2").find("IP literals"), std::string::npos);
}

TEST(ClientChannelTest, PeerAddressDropsTheScheme) {
  EXPECT_EQ(PeerAddress("ipv4:127.0.0.1:50054"), "127.0.0.1:50054");
  EXPECT_EQ(PeerAddress("ipv6:[::1]:1"), "[::1]:1");
  EXPECT_EQ(PeerAddress("unix:/tmp/x"), "unix:/tmp/x");
}

TEST(ClientChannelTest, ABalancedChannelReachesAServerOfItsList) {
  v1::Control::Service unimplemented;  // a server needs one service; its calls do not matter
  grpc::ServerBuilder builder;
  builder.RegisterService(&unimplemented);
  int port = 0;
  builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  ASSERT_NE(server, nullptr);
  // The list's other address has no server: round_robin skips it.
  Result<std::shared_ptr<grpc::Channel>> channel =
      MakeChannel("127.0.0.1:" + std::to_string(port) + ",127.0.0.1:1");
  ASSERT_TRUE(channel.ok()) << channel.status().ToString();
  EXPECT_TRUE(
      (*channel)->WaitForConnected(std::chrono::system_clock::now() + std::chrono::seconds(5)));
  server->Shutdown();
}

}  // namespace
}  // namespace mav::client
