// mav-load against three mav-control replicas (build/bin, loopback) through one balanced target
// ("ipv4:127.0.0.1:A,127.0.0.1:B,127.0.0.1:C": round_robin with retries, clients/common/
// channel.h), Control.GetState back to back for 3 s with 3 clients: the calls spread evenly
// (each replica within 10 % of a third, read from --json's per_backend), none fails; and with one
// replica killed (SIGKILL) a second into a 4 s run, no call is lost but those that were in flight
// on it (at most one per client; the retry policy usually saves them too). Both with mav-load's
// synchronous client threads and with its asynchronous client (--client async: gRPC's callback
// API, refused calls wait on its pause line).

#include <gtest/gtest.h>

#include <signal.h>

#include <chrono>
#include <map>
#include <memory>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include "mav/common/file.h"
#include "tests/common/build_paths.h"
#include "tests/common/stack_fixture.h"

namespace mav {
namespace {

constexpr int kReplicas = 3;

class RoundRobinLoadTest : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    for (int r = 0; r < kReplicas; ++r) {
      stacks_.push_back(std::make_unique<test_support::Stack>(/*domain_key=*/63));
      const std::string target = stacks_.back()->Start("mav-control", "mav.v1.Control");
      ASSERT_FALSE(target.empty()) << *ReadFileToString(stacks_.back()->Log("mav-control"));
      targets_.push_back(target);
    }
  }

  std::string BalancedTarget() const {
    std::string out = "ipv4:";
    for (const std::string& t : targets_) out += (out.size() > 5 ? "," : "") + t;
    return out;
  }

  // Runs mav-load control; returns its exit status (-1: did not finish) and fills the log and
  // the JSON totals.
  int RunLoad(const std::string& name, double duration_s, std::string* log, std::string* json) {
    const std::string dir = mav::testing::BinaryDir() + "/Testing/";
    const std::string log_path = dir + name + ".log", json_path = dir + name + ".json";
    test_support::Child load(
        {mav::testing::BinaryDir() + "/bin/mav-load", "control", "--address", BalancedTarget(),
         "--concurrency", "3", "--duration", std::to_string(duration_s), "--client", GetParam(),
         "--json", json_path},
        log_path);
    if (on_started_) on_started_();
    const std::optional<int> rc = load.Wait(std::chrono::seconds(60));
    *log = ReadFileToString(log_path).ok() ? *ReadFileToString(log_path) : "";
    *json = ReadFileToString(json_path).ok() ? *ReadFileToString(json_path) : "";
    return rc.value_or(-1);
  }

  // "per_backend": {"127.0.0.1:1": 10, ...} -> calls by address.
  static std::map<std::string, double> PerBackend(const std::string& json) {
    std::map<std::string, double> out;
    const size_t start = json.find("\"per_backend\": {");
    if (start == std::string::npos) return out;
    const std::string object = json.substr(start, json.find('}', start) - start);
    const std::regex entry("\"([^\"]+)\": ([0-9]+)");
    for (auto it = std::sregex_iterator(object.begin(), object.end(), entry);
         it != std::sregex_iterator(); ++it) {
      out[(*it)[1]] = std::stod((*it)[2]);
    }
    return out;
  }

  static int64_t ErrorCount(const std::string& json) {
    std::smatch m;
    return std::regex_search(json, m, std::regex("\"error_count\": ([0-9]+)")) ? std::stoll(m[1])
                                                                               : -1;
  }

  std::vector<std::unique_ptr<test_support::Stack>> stacks_;
  std::vector<std::string> targets_;
  std::function<void()> on_started_;
};

TEST_P(RoundRobinLoadTest, CallsSpreadEvenlyOverTheReplicas) {
  std::string log, json;
  ASSERT_EQ(RunLoad("round_robin_load_test_" + GetParam(), 3, &log, &json), 0) << log;
  std::cout << log;
  EXPECT_EQ(ErrorCount(json), 0) << json;
  const std::map<std::string, double> calls = PerBackend(json);
  ASSERT_EQ(calls.size(), static_cast<size_t>(kReplicas)) << json;
  double total = 0;
  for (const auto& [address, n] : calls) total += n;
  ASSERT_GT(total, 300) << json;
  for (const std::string& target : targets_) {
    ASSERT_EQ(calls.count(target), 1u) << target << "\n" << json;
    EXPECT_NEAR(calls.at(target) / total, 1.0 / kReplicas, 0.1 / kReplicas) << target << "\n"
                                                                            << json;
  }
}

TEST_P(RoundRobinLoadTest, AKilledReplicaLosesOnlyTheCallsInFlightOnIt) {
  std::thread killer;
  on_started_ = [&] {
    killer = std::thread([this] {
      std::this_thread::sleep_for(std::chrono::seconds(1) + std::chrono::milliseconds(500));
      stacks_[1]->Process("mav-control")->Signal(SIGKILL);
    });
  };
  std::string log, json;
  const int rc = RunLoad("round_robin_kill_load_test_" + GetParam(), 4, &log, &json);
  killer.join();
  std::cout << log;
  ASSERT_EQ(rc, 0) << log;
  EXPECT_LE(ErrorCount(json), 3) << json;  // one call in flight per client at most
  const std::map<std::string, double> calls = PerBackend(json);
  for (const std::string& target : {targets_[0], targets_[2]}) {
    ASSERT_EQ(calls.count(target), 1u) << target << "\n" << json;
    EXPECT_GT(calls.at(target), calls.at(targets_[1])) << json;
  }
}

INSTANTIATE_TEST_SUITE_P(Clients, RoundRobinLoadTest, ::testing::Values("sync", "async"),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           return info.param;
                         });

// The flag's own errors, before anything connects: exit 2 naming --client.
TEST(MavLoadClientFlag, RefusesAnUnknownModeAndAsyncLocalization) {
  const std::string log = mav::testing::BinaryDir() + "/Testing/mav_load_client_flag.log";
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"control", "--client", "threads"},
        std::vector<std::string>{"localization", "--client", "async"}}) {
    std::vector<std::string> argv = {mav::testing::BinaryDir() + "/bin/mav-load"};
    argv.insert(argv.end(), args.begin(), args.end());
    test_support::Child load(argv, log);
    EXPECT_EQ(load.Wait(std::chrono::seconds(30)).value_or(-1), 2) << args[0];
    const std::string text = ReadFileToString(log).ok() ? *ReadFileToString(log) : "";
    EXPECT_NE(text.find("mav-load: --client"), std::string::npos) << text;
  }
}

}  // namespace
}  // namespace mav
