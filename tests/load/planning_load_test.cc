// mav-load against mav-planning (both from build/bin, on loopback, on the machine's cores) for
// 8 s: 4 concurrent clients planning the queries of tests/data/planning/power_plant_queries.txt
// (the t4_3 legs and 30 random 20-40 m queries) on maps/power_plant.bt with a 20 000-
// milestone roadmap (built once into build/Testing, then loaded). Asserts zero errors, every
// reply SUCCESS and p99 <= 250 ms (the target, >= 200 plans/s at p99 <= 100 ms pinned to two
// cores with the default roadmap, is measured as docs/benchmarks.md says; this bound leaves room
// for a machine shared with other tests). And clients that back off: the server killed mid-load
// and started again 3 s later on its port costs fewer than 50 failed calls a second while it is
// gone, and calls succeed again within 2 s of its return (issue 31).

#include <gtest/gtest.h>

#include <chrono>
#include <regex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "mav/common/file.h"
#include "tests/common/build_paths.h"
#include "tests/common/stack_fixture.h"

namespace mav {
namespace {

std::vector<std::string> PlanningFlags() {
  return {"--map",
          mav::testing::SourceDir() + "/maps/power_plant.bt",
          "--roadmap",
          mav::testing::BinaryDir() + "/Testing/planning_load_20k.mavprm",
          "--roadmap-milestones",
          "20000"};
}

// "per_second": [[answered, failed], ...] of mav-load's --json.
std::vector<std::pair<int64_t, int64_t>> PerSecond(const std::string& json) {
  std::vector<std::pair<int64_t, int64_t>> out;
  const size_t start = json.find("\"per_second\": [");
  if (start == std::string::npos) return out;
  const std::string list = json.substr(start, json.find("]]", start) + 2 - start);
  const std::regex pair("\\[([0-9]+), ([0-9]+)\\]");
  for (auto it = std::sregex_iterator(list.begin(), list.end(), pair); it != std::sregex_iterator();
       ++it) {
    out.emplace_back(std::stoll((*it)[1]), std::stoll((*it)[2]));
  }
  return out;
}

TEST(PlanningLoadTest, NoErrorsAndABoundedP99) {
  test_support::Stack stack(/*domain_key=*/62);
  const std::string target = stack.Start("mav-planning", "mav.v1.Planning", PlanningFlags());
  ASSERT_FALSE(target.empty()) << *ReadFileToString(stack.Log("mav-planning"));
  const std::string log_path = mav::testing::BinaryDir() + "/Testing/planning_load_test.log";
  test_support::Child load(
      {mav::testing::BinaryDir() + "/bin/mav-load", "planning", "--address", target,
       "--concurrency", "4", "--duration", "8", "--queries",
       mav::testing::SourceDir() + "/tests/data/planning/power_plant_queries.txt", "--deadline-ms",
       "2000", "--fail-on-errors", "--require-success", "--max-p99-ms", "250"},
      log_path);
  const std::optional<int> rc = load.Wait(std::chrono::seconds(60));
  const std::string log = ReadFileToString(log_path).ok() ? *ReadFileToString(log_path) : "";
  std::cout << log;
  ASSERT_TRUE(rc.has_value()) << "mav-load did not finish";
  EXPECT_EQ(*rc, 0) << log;
  EXPECT_NE(log.find("errors:   0"), std::string::npos) << log;
}

TEST(PlanningLoadTest, AKilledServerIsWaitedForAndUsedAgainWhenBack) {
  test_support::Stack stack(/*domain_key=*/62);
  const std::string target = stack.Start("mav-planning", "mav.v1.Planning", PlanningFlags());
  ASSERT_FALSE(target.empty()) << *ReadFileToString(stack.Log("mav-planning"));
  const std::string dir = mav::testing::BinaryDir() + "/Testing/";
  const std::string log_path = dir + "planning_restart_load_test.log";
  const std::string json_path = dir + "planning_restart_load_test.json";
  const auto launched = std::chrono::steady_clock::now();
  test_support::Child load(
      {mav::testing::BinaryDir() + "/bin/mav-load", "planning", "--address", target,
       "--concurrency", "4", "--duration", "10", "--queries",
       mav::testing::SourceDir() + "/tests/data/planning/power_plant_queries.txt", "--deadline-ms",
       "2000", "--json", json_path},
      log_path);
  std::this_thread::sleep_for(std::chrono::seconds(2));
  stack.Process("mav-planning")->Signal(SIGKILL);
  std::this_thread::sleep_for(std::chrono::seconds(3));
  ASSERT_EQ(stack.Restart("mav-planning", "mav.v1.Planning", PlanningFlags()), target)
      << *ReadFileToString(stack.Log("mav-planning") + ".restarted");
  const double back_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - launched).count();
  const std::optional<int> rc = load.Wait(std::chrono::seconds(60));
  const std::string log = ReadFileToString(log_path).ok() ? *ReadFileToString(log_path) : "";
  const std::string json = ReadFileToString(json_path).ok() ? *ReadFileToString(json_path) : "";
  std::cout << log << "server back (health SERVING) " << back_s << " s after mav-load started\n";
  ASSERT_EQ(rc.value_or(-1), 0) << log;
  const std::vector<std::pair<int64_t, int64_t>> seconds = PerSecond(json);
  ASSERT_GE(seconds.size(), 9u) << json;
  for (size_t s = 0; s < seconds.size(); ++s) {
    EXPECT_LT(seconds[s].second, 50) << "second " << s << "\n" << log;
  }
  // mav-load's seconds start after its launch, so its second k began at or before k s after the
  // launch: the first answered second after the gap must start within 2 s of the return.
  size_t gap = 3;  // a second wholly inside the gap (killed at 2 s, back after 5 s)
  EXPECT_EQ(seconds[gap].first, 0) << "answered calls while the server was gone?\n" << log;
  size_t first_back = gap;
  while (first_back < seconds.size() && seconds[first_back].first == 0) ++first_back;
  ASSERT_LT(first_back, seconds.size()) << "no call answered after the restart\n" << log;
  EXPECT_LE(static_cast<double>(first_back), back_s + 2.0) << log;
}

}  // namespace
}  // namespace mav
