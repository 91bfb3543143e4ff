#pragma once
// The stack for integration tests: starts the service binaries of build/bin as child processes,
// each on a free loopback port, all on one DDS domain of the test's own (test_domain.h), each
// logging to build/Testing/<binary>-<pid>.log, and waits until each reports SERVING.
//
//   Stack stack(/*domain_key=*/37);
//   const std::string sim = stack.Start("mav-simulator", "mav.v1.Simulator");
//   ASSERT_FALSE(sim.empty()) << stack.Log("mav-simulator");
//   auto stub = v1::Simulator::NewStub(stack.Channel("mav-simulator"));
//
// The children are killed (SIGKILL) when the Stack goes; Process() gives access for signals.

#include <cstdint>
#include <cstdlib>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>

#include "tests/common/build_paths.h"
#include "tests/common/stack_process.h"
#include "tests/common/test_domain.h"

namespace mav::test_support {

class Stack {
 public:
  explicit Stack(int domain_key) : domain_(TestDomain(domain_key)) {
    std::system(("mkdir -p " + LogDir()).c_str());
  }

  int64_t domain() const { return domain_; }

  // Starts `binary` with --port, --dds-domain and `extra`; returns its "127.0.0.1:PORT", or ""
  // when it did not start or did not report `health_name` SERVING within 20 s.
  std::string Start(const std::string& binary, const std::string& health_name,
                    const std::vector<std::string>& extra = {}) {
    int port = FreeTcpPort();
    for (const auto& [name, target] : targets_) {
      while (target == "127.0.0.1:" + std::to_string(port)) port = FreeTcpPort();
    }
    std::string target = "127.0.0.1:" + std::to_string(port);
    if (!Launch(binary, std::to_string(port), extra, Log(binary))) return "";
    if (!WaitServing(target, health_name)) return "";
    targets_[binary] = target;
    return target;
  }

  // Kills `binary` (SIGKILL, if it still runs) and starts it again on the same port with `extra`;
  // returns its target, or "" as Start does.
  std::string Restart(const std::string& binary, const std::string& health_name,
                      const std::vector<std::string>& extra = {}) {
    const std::string target = targets_.at(binary);
    children_.erase(binary);  // ~Child: SIGKILL and reap
    const std::string port = target.substr(target.rfind(':') + 1);
    if (!Launch(binary, port, extra, Log(binary) + ".restarted")) return "";
    return WaitServing(target, health_name) ? target : "";
  }

  const std::string& Target(const std::string& binary) { return targets_[binary]; }
  std::shared_ptr<grpc::Channel> Channel(const std::string& binary) {
    return grpc::CreateChannel(Target(binary), grpc::InsecureChannelCredentials());
  }
  Child* Process(const std::string& binary) { return children_.at(binary).get(); }
  std::string Log(const std::string& binary) const {
    return LogDir() + "/" + binary + "-" + std::to_string(::getpid()) + ".log";
  }

 private:
  static std::string LogDir() { return mav::testing::BinaryDir() + "/Testing"; }

  // Starts build/bin/`binary` --port `port` --dds-domain ... `extra`, logging to `log`; false
  // when it did not start.
  bool Launch(const std::string& binary, const std::string& port,
              const std::vector<std::string>& extra, const std::string& log) {
    std::vector<std::string> argv = {mav::testing::BinaryDir() + "/bin/" + binary, "--port", port,
                                     "--dds-domain", std::to_string(domain_)};
    argv.insert(argv.end(), extra.begin(), extra.end());
    auto child = std::make_unique<Child>(argv, log);
    if (!child->running()) return false;
    children_[binary] = std::move(child);
    return true;
  }

  int64_t domain_;
  std::map<std::string, std::unique_ptr<Child>> children_;
  std::map<std::string, std::string> targets_;
};

}  // namespace mav::test_support
